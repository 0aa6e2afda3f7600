"""The rules about a program's targets that both ``compensate`` and ``check`` apply: one
rule, one place. :func:`findings` returns every finding as a :class:`Diagnostic`;
``compensate`` raises on the first error (and, under ``--strict``, on any warning),
``check`` reports them all.

One function per code family, in the order compensate applies them:

* :func:`stamp_rule` P401 (already compensated, at the stamp's line), :func:`accuracy_rule`
  P408/P409 (a KUKA backup whose controller corrects the error itself: its absolute-accuracy
  model active / suppressed), :func:`fit_rule` P304/P310 (another tool or robot: the one named,
  or the controller the program's dialect is written for) — each lifted by ``force``;
  :func:`demonstration_rule` P340 (a note: a demonstration model of a simulated robot);
  :func:`unit_rule` P517 (a pose list in metres);
* :func:`frame_rule` P103 (a frame that is not finite);
* :func:`known_rule` P212 (position not known), P213 (orientation not known), P216
  (a partial aggregate, refused only with ``fill_partial=False``);
* :func:`finite_rule` P103 (not finite, or beyond float32);
* :func:`reach_rule` P302 (beyond the model's reach), P309 (no IK, with ``reachable``);
* :func:`envelope_rule` P301 (outside the training box / attitude range);
* with the model's commands: :func:`output_rule` P305 (NaN), P303 (too large),
  :func:`joints_rule` P301 (joint angles outside the trained ranges), :func:`std_rule` P336
  (the model's ``error_std`` above ``--max-std``).

:func:`select` says which targets the model takes (their robot-base poses, the nominal
attitude filled in where the program gives none); :class:`Commands` is what the model
returned for them.
"""
from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..core.diagnostics import (
    P103, P212, P213, P216, P218, P230, P231, P235, P236, P301, P302, P303, P304, P305, P309, P310, P313, P321, P336,
    P338, P339, P340, P341, P401,
    P408, P409, P517, Diagnostic, PostprocError, line_col, listed,
)
from ..model.compensator import Compensator
from ..model.settle import Inside, Order
from ..programs import Program
from ..programs.base_poses import robot_base_poses
from ..programs.locate import collect, motion_at, where
from ..robot.description import is_description_file, load_description, robot_name
from ..settings import Settings

__all__ = [
    "Selection", "Commands", "select", "findings", "static_findings", "command_findings",
    "dead_band_notes", "model_bases", "pose_frame_rule", "std_bound", "tool_mismatch", "robot_mismatch",
    "demonstration_rule", "unit_rule",
]

@dataclass
class Selection:
    """The targets the model takes: ``rows`` into Program.targets, ``poses`` [len(rows), 6]
    in the robot base (nominal attitude where the program gives none)."""

    rows: np.ndarray
    poses: np.ndarray
    joints: np.ndarray | None = None  # [len(rows), 6] deg: the model's input ``joints`` (controller.py)
    tool: np.ndarray | None = None  # [len(rows), 6]: the model's input ``tool``
    # targets left as written by a rule of this module (not the reader's): code → rows
    left: dict = field(default_factory=dict)
    # the rows' predecessors in execution order (positions in ``rows``; None: row after row)
    order: Order | None = None
    base_poses: np.ndarray | None = field(default=None, repr=False)  # every row's robot-base pose (order)
    # every program row's payload [N, 4] for a model that takes the load (NaN: its reference load;
    # None: the model takes none, or no row has one): :func:`load_rule`
    loads: np.ndarray | None = field(default=None, repr=False)

    @property
    def load(self) -> np.ndarray | None:
        """[len(rows), 4]: the model's input ``load`` at the selected rows (None: not given)."""
        return None if self.loads is None else self.loads[self.rows]

    def without(self, drop: np.ndarray, code: str) -> "Selection":
        """The selection without the positions ``drop`` (left as written for ``code``)."""
        keep = np.ones(len(self.rows), bool)
        keep[drop] = False
        left = dict(self.left)
        if len(drop):
            left[code] = np.concatenate([left.get(code, np.zeros(0, int)), self.rows[drop]])
        return Selection(self.rows[keep], self.poses[keep], None if self.joints is None else self.joints[keep],
                         None if self.tool is None else self.tool[keep], left, base_poses=self.base_poses,
                         loads=self.loads)


@dataclass
class Commands:
    """The model's commands for a selection: ``commanded`` [M, 3] robot base, ``joints``
    [M, 6] deg or None (only where the model card has joint ranges)."""

    selection: Selection
    commanded: np.ndarray
    joints: np.ndarray | None = None
    inside: Inside | None = None  # targets whose joints stay in their backlash dead band (P321)
    std: np.ndarray | None = None  # [M] mm: the model's error_std at the commands (std_bound: asked for)


# --------------------------------------------------------------------------- helpers


def model_bases(program: Program, model: Compensator | None) -> list[np.ndarray]:
    """Each of the program's frames [4×4] in the model's frame: the frame's base (into the
    controller's robot base) after the model's ``controller_base``, for a program's targets and
    a pose list that states ``# frame: controller``; a pose list's rows are in the model's frame
    where it states ``# frame: model`` or states nothing (where it matters it must state it:
    :func:`pose_frame_rule`)."""
    if model is None or not program.in_controller_base or model.in_controller_base:
        return [f.base for f in program.frames]
    return [model.controller_base @ f.base for f in program.frames]


def pose_frame_rule(program: Program, model: Compensator, use: np.ndarray) -> list[Diagnostic]:
    """P218: a pose list that does not state its frame, for a model whose frame is not the
    controller's base — its rows could be in either (a UR description in ROS's base_link: the
    controller's base is turned 180° about Z). Narrows ``use``: every row left as written."""
    if program.in_controller_base is not None or model.in_controller_base:
        return []
    rows = np.flatnonzero(use)
    use[rows] = False
    pose = [round(float(v), 6) for v in model.metadata.get("controller_base", [])]
    return collect(program, rows[:1], P218,
                   f"the model's frame is not the robot controller's base (controller_base {pose}): say which frame "
                   f"the rows are in with a line '# frame: controller' or '# frame: model' before them; all "
                   f"{len(rows)} left as written")


def tool_mismatch(program: Program, model: Compensator) -> str | None:
    """Why the model's tool does not fit the program's active $TOOL (None: it fits, or unknown)."""
    frame = model.tool.get("frame") if model.tool else None
    if frame is None:
        return None
    tools = {tuple(np.round(f.tool, 3)) for f in program.frames if f.tool is not None}
    for tool in tools:
        d = np.abs(np.asarray(tool) - np.asarray(frame, float))
        if d[:3].max() > 0.5 or np.abs((d[3:] + 180) % 360 - 180).max() > 0.1:
            return f"the program's $TOOL {[float(v) for v in tool]} is not the model's tool {model.tool.get('name', '')} {list(frame)}"
    return None


def robot_mismatch(robot: str | None, model: Compensator, program: Program | None = None) -> str | None:
    """Why the model (trained on its card's robot) does not fit ``robot`` (None: it does, or
    unknown); without ``robot``, why it does not fit the controller ``program`` is written for
    (a model that takes joint angles, of a robot whose controller its description names:
    ``controller.family_mismatch``)."""
    if not robot:
        if program is None:
            return None
        from .inputs import family_mismatch

        return family_mismatch(program, model)
    if not model.robot:
        return f"the model does not say which robot it was trained on (the program is for {robot})"
    if model.robot.casefold() != robot.casefold():
        return f"the model was trained on robot {model.robot}, the program is for {robot}"
    return None


def _joints_away(q_deg: np.ndarray, ranges: np.ndarray) -> str:
    """'A4 -35.2°, trained -20.1…19.8°' for the joint of ``q_deg`` [6] farthest out of its range."""
    lo, hi = ranges[:, 0], ranges[:, 1]
    beyond = np.maximum(lo - q_deg, q_deg - hi) / np.maximum(hi - lo, 1e-9)
    j = int(np.argmax(beyond))
    return f"A{j + 1} {q_deg[j]:.1f}°, trained {lo[j]:.1f}…{hi[j]:.1f}°"


def missing_xyz(program: Program, rows: np.ndarray) -> np.ndarray:
    """[len(rows), 3] bool: the X/Y/Z components these targets' aggregates leave out."""
    return program.targets.spans[rows, :, 0] < 0


# --------------------------------------------------------------------------- rules


def stamp_rule(program: Program, settings: Settings) -> list[Diagnostic]:
    """P401: a stamped program is compensated already."""
    if not program.stamps or settings.rules.force:
        return []
    index, stamp = next(iter(program.stamps.items()))
    text = program.texts[index] if index < len(program.texts) else ""
    line, col = line_col(text, text.find(stamp)) if stamp in text else (1, 1)
    return [Diagnostic(program.files[index], line, col, P401, f"already compensated ({stamp.lstrip(';# ')}); "
                       "use --force to compensate again", "error")]


def accuracy_rule(program: Program, settings: Settings) -> list[Diagnostic]:
    """P408: a KRL program in a controller backup whose machine data switch on the controller's
    own absolute-accuracy model (``$ABS_ACCUR``): the controller corrects the positioning error
    itself, postproc's correction would be a second one. P409 (a warning) where that model is
    suppressed for now. Located at the machine data's line (``programs.krl.machine``)."""
    if settings.rules.force or program.dialect != "krl":
        return []
    from ..programs.krl.machine import backup_accuracy

    try:
        model = backup_accuracy(program.files)
    except PostprocError as exc:
        return [exc.diagnostic()]
    if model is None:
        return []
    if model.state == "active":
        return [Diagnostic(model.path, model.line, model.col, P408,
                           f"{model.value}: the controller's absolute-accuracy model is active for this robot; its "
                           "own correction and postproc's would add up (compensated twice); leave the program as "
                           "written, switch that model off, or --force to compensate anyway", "error")]
    return [Diagnostic(model.path, model.line, model.col, P409,
                        f"{model.value}: the controller's absolute-accuracy model is suppressed for now; where it is "
                        "switched on again this program is corrected twice", "warning")]


def fit_rule(program: Program, model: Compensator, settings: Settings) -> list[Diagnostic]:
    """P304 a model for another tool, P310 for another robot."""
    if settings.rules.force:
        return []
    out = []
    mismatch = None if model.wants_tool else tool_mismatch(program, model)  # (a model with a tool input: any)
    if mismatch:
        out.append(Diagnostic(program.files[0], 1, 1, P304, mismatch + "; use --force to compensate anyway", "error"))
    mismatch = robot_mismatch(robot_name(settings.robot), model, program)
    if mismatch:
        out.append(Diagnostic(str(model.path), 0, 0, P310, mismatch + "; use --force to compensate anyway", "error"))
    return out


def demonstration_rule(model: Compensator) -> list[Diagnostic]:
    """P340 (a note, once per model): a demonstration model of a simulated robot (its card's
    ``demonstration``) knows nothing of a real one."""
    what = model.demonstration
    if what is None:
        return []
    return [Diagnostic(str(model.path), 0, 0, P340, f"model {model.name}: {what} — train one for your robot: postproc "
                       "train MEASURED.csv --robot ROBOT.toml -o MODEL.onnx (models/README.md)", "note")]


def unit_rule(program: Program, model: Compensator) -> list[Diagnostic]:
    """P517 (an error): a pose list whose positions are in another unit than mm
    (``units.unit_problem``: every |x|, |y|, |z| below 5 for a robot that reaches metres), said
    once, naming the unit — not a P309 at every row."""
    from ..core.units import unit_problem

    if program.dialect != "poses" or not len(program.targets):
        return []
    reach = model.metadata.get("reach")
    radius = reach.get("radius_max") if isinstance(reach, dict) else None
    problem = unit_problem(program.targets.poses * program.unit, None if radius is None else float(radius))
    return [] if problem is None else [Diagnostic(*where(program, 0), P517, problem, "error")]


def held_rule(program: Program, use: np.ndarray) -> dict:
    """The rows the analysis leaves as written (``Program.held``: P217, a target whose numbers
    something else reads too; warned by the reader at each): code → rows. Narrows ``use``."""
    out = {}
    for code, rows in getattr(program, "held", {}).items():
        rows = np.asarray(rows, int)
        if len(rows):
            use[rows] = False
            out[code] = rows
    return out


def group_rule(program: Program, selection: Selection) -> tuple[Selection, list[Diagnostic]]:
    """P230: what a target left as written takes with it, to a fixed point:

    * a row that shares its numbers with a row left as written (another run of it, a point it is
      copied from or into): rewriting them would move that row too;
    * the row before a partial target left as written (``LIN {Z 5}``): at run time it takes its
      missing X/Y/Z from that row's command, which, compensated, would move it — where that row
      is a run at an offset from a point (P231: it moves with the point's correction), the
      point's rows.
    """
    t = program.targets
    group = getattr(t, "group", None)
    prev = getattr(t, "prev", None)
    if not len(selection.rows) or (group is None and prev is None):
        return selection, []
    chosen = np.zeros(len(t), bool)
    chosen[selection.rows] = True
    partial = (t.spans[:, :, 0] < 0).any(axis=1) & ~np.isnan(t.poses[:, :3]).any(axis=1)
    # (runs at an offset from a point compensated for its own runs move with it, said: P231)
    with_point = np.zeros(len(t), bool)
    with_point[np.asarray(selection.left.get(P231, []), int)] = True
    why = {}  # row dropped → the row left that takes it with it
    while True:
        left = ~chosen
        drop = np.zeros(len(t), bool)
        if group is not None and (group >= 0).any():
            left_groups = np.unique(group[left & ~with_point & (group >= 0)])
            if len(left_groups):
                tied = chosen & np.isin(group, left_groups) & (group >= 0)
                for r in np.flatnonzero(tied).tolist():
                    why.setdefault(r, int(np.flatnonzero((group == group[r]) & left)[0]))
                drop |= tied
        if prev is not None:
            source = left & partial & (prev >= 0)
            feeds = prev[source]
            fed = chosen[feeds]
            for r, by in zip(feeds[fed].tolist(), np.flatnonzero(source)[fed].tolist()):
                why.setdefault(r, by)
                drop[r] = True
            # a run at an offset from a point (P231) moves with the point's correction, and a partial
            # target left after it would move with it: the point's rows are left with it
            moving = with_point[feeds]
            if moving.any() and group is not None:
                for f, by in zip(feeds[moving].tolist(), np.flatnonzero(source)[moving].tolist()):
                    with_point[f] = False
                    if group[f] >= 0:
                        tied = chosen & (group == group[f])
                        for r in np.flatnonzero(tied).tolist():
                            why.setdefault(r, by)
                        drop |= tied
        if not drop.any():
            break
        chosen &= ~drop
    out = np.flatnonzero(~chosen[selection.rows])
    if not len(out):
        return selection, []
    rows = selection.rows[out]
    places = np.stack([t.file[rows], t.line[rows], t.col[rows]], axis=1)
    said = rows[np.sort(np.unique(places, axis=0, return_index=True)[1])]  # (one warning per target, not per run)
    found = collect(program, said, P230, lambda i: "this target's numbers are also those of a target left as written "
                    "(another run of it, a point it is copied from or into, or a partial target after it that takes "
                    "its X/Y/Z from its command), at {}:{}: left as written too".format(
                        *where(program, why.get(int(said[i]), int(said[i])))[:2]))
    return selection.without(out, P230), found


def execution_order(program: Program, selection: Selection, poses: np.ndarray,
                    model: Compensator | None = None) -> Order | None:
    """The selected rows' predecessors in execution order (``Targets.prev``) as positions in the
    selection; a predecessor left as written is reached at its nominal pose (``poses``: every
    row's in the robot base, NaN where not known: then nothing is known before the row); a row
    after a joint motion to known axis values (``Targets.start``) is reached from where those
    axes put the TCP on the model's robot (:func:`start_poses`, for a model that takes the
    previous pose). None where it is row after row."""
    t = program.targets
    prev = getattr(t, "prev", None)
    rows = selection.rows
    if prev is None or not len(rows):
        return None
    pos = np.full(len(t), -1, np.int64)
    pos[rows] = np.arange(len(rows))
    p = prev[rows]
    out = np.where(p >= 0, pos[np.maximum(p, 0)], -1)
    fixed = None
    outside = np.flatnonzero((p >= 0) & (out < 0))
    if len(outside):
        base = poses[p[outside]]
        known = np.isfinite(base).all(axis=1)
        if known.any():
            fixed = np.full((len(rows), 6), np.nan)
            fixed[outside[known]] = base[known]
            out[outside[known]] = -2
    start = start_poses(program, model, selection) if model is not None else None
    if start is not None:
        from_axes = np.flatnonzero((out == -1) & np.isfinite(start).all(axis=1))
        if len(from_axes):
            fixed = np.full((len(rows), 6), np.nan) if fixed is None else fixed
            fixed[from_axes] = start[from_axes]
            out[from_axes] = -2
    order = Order(out, fixed)
    return None if order.sequential else order


def start_poses(program: Program, model: Compensator, selection: Selection) -> np.ndarray | None:
    """[len(rows), 6] the TCP pose (the model's frame) the robot stands at before each selected
    row that follows a joint motion to known axis values (``Targets.start``: ``PTP HOME``,
    ``movej(home_q)``), by the nominal kinematics of the model's robot with the row's tool (the
    model's where it takes none); NaN elsewhere. None: no such row, a model without a
    ``previous_pose`` input, or no description of its robot."""
    t = program.targets
    start = getattr(t, "start", None)
    if start is None or not model.wants_previous or not len(selection.rows):
        return None
    axes = start[selection.rows]
    known = np.isfinite(axes).all(axis=1)
    if not known.any():
        return None
    from ..robot.arm import Robot
    from ..robot.conventions import DIALECT_CONTROLLERS, controller_of
    from .inputs import model_description, model_tool

    description = model_description(model)
    # (axis values of another controller's arm give no pose on this one)
    if description is None or controller_of(description) != DIALECT_CONTROLLERS.get(program.dialect):
        return None
    tools = selection.tool if selection.tool is not None else \
        np.broadcast_to(model_tool(model, description), (len(axes), 6))
    out = np.full((len(axes), 6), np.nan)
    rows = np.flatnonzero(known)
    for tool in np.unique(tools[rows], axis=0):
        same = rows[(tools[rows] == tool).all(axis=1)]
        out[same] = Robot(description.replace(tool=np.asarray(tool, float))).fk(axes[same])
    return out


def _load_text(load) -> str:
    m, x, y, z = (float(v) for v in load)
    return f"{m:g} kg at ({x:g}, {y:g}, {z:g}) mm"


def payloads(program: Program, reading) -> tuple[np.ndarray, np.ndarray]:
    """The payload at every target as compensate takes it (``verify`` simulates the same): (loads
    [N, 4], cause [N]). The program's (``Targets.load``); a payload schedule its user states
    (``--payload n=…``: Fanuc ``PAYLOAD[n]``, cause then -1); ``--load`` (``reading.load``) where
    the program sets none or its payload is not statically known (its cause kept: said there);
    NaN rows where none of them says (the model's reference load). ``cause`` ≥ 0: an index into
    ``Targets.load_causes``, the payload not statically known."""
    t = program.targets
    loads = np.full((len(t), 4), np.nan) if t.load is None else t.load.copy()
    cause = np.full(len(t), -1, np.int32) if t.load_cause is None else t.load_cause.copy()
    for k, (*_, schedule) in enumerate(t.load_causes):  # (a payload schedule its user states: Fanuc PAYLOAD[n])
        stated = reading.payload(schedule) if schedule is not None else None
        if stated is not None:
            loads[cause == k] = stated
            cause[cause == k] = -1
    if reading.load is not None:
        loads[np.isnan(loads).any(axis=1) | (cause >= 0)] = reading.load
    return loads, cause


def load_rule(program: Program, model: Compensator, settings: Settings,
              use: np.ndarray) -> tuple[np.ndarray | None, list[Diagnostic], dict]:
    """The payload at each target, for the model (one rule for every dialect: the analysis gives
    each row's, ``Targets.load``): (every row's load [N, 4] or None, findings, rows left by code).

    A model without the ``load`` input: nothing changes (every target is compensated for the load
    it was measured with), said once where the program sets a payload (P236, a note). A model that
    takes it: a row whose payload the program sets gets it; one where the program sets none gets
    ``--load`` (settings ``load``), else NaN (the model's reference load: said once, P339); a row
    whose payload is not statically known gets ``--load`` where the user states it (said at each
    cause, P339), else is left as written (P235, at each cause, naming the motions); one the
    model cannot extrapolate to (``load_reach``) too (P338). Narrows ``use``."""
    t = program.targets
    out: list[Diagnostic] = []
    rows = np.flatnonzero(use)
    if not len(rows):
        return None, out, {}
    if not model.takes_load:  # (said where the program changes its payload: two known ones or more)
        if t.load is not None:
            sets = rows[~np.isnan(t.load[rows]).any(axis=1)]
            loads = np.unique(t.load[sets], axis=0)
            if len(loads) > 1:
                said = ", ".join(_load_text(v) for v in loads[:3]) + (" …" if len(loads) > 3 else "")
                out.append(Diagnostic(*where(program, int(sets[0])), P236,
                                      f"the program changes its payload ({said}) but the model does not take a load: "
                                      f"its {len(sets)} target(s) are compensated for the load the model was measured "
                                      "with", "note"))
            # (a card that states the loads measured: a payload it was not measured with is said)
            if len(sets) and len(model.measured_loads):
                other = sets[~np.asarray(model.load_reach(t.load[sets]), bool)]
                if len(other):
                    measured = "; ".join(_load_text(v) for v in model.measured_loads)
                    out += collect(program, other[:1], P341, f"the payload here, {_load_text(t.load[other[0]])}, is "
                                   f"not the one the model was measured with ({measured}), and the model does not "
                                   f"take the load: {len(other)} target(s) with other payloads are compensated for "
                                   "the measured one, their deflection under the payload stays (train with the "
                                   "payloads as load columns: a load-aware model)")
        return None, out, {}
    loads, cause = payloads(program, settings.reading)
    unset = np.isnan(loads).any(axis=1) & (cause < 0)  # (none said: the model's reference)
    stated = settings.reading.load
    if (unset & use).any():
        first = int(np.flatnonzero(unset & use)[0])
        ref = model.reference_load
        ref_text = f" ({_load_text(ref)})" if ref is not None else ""
        out.append(Diagnostic(*where(program, first), P339,
                              f"the program does not set the payload before {int((unset & use).sum())} target(s): "
                              f"compensated for the load the model was measured with{ref_text}; state it with "
                              "--load MASS[,CX,CY,CZ]", "note"))
    left: dict = {}
    unknown = use & (cause >= 0)
    if unknown.any():  # (said at each cause: taken from --load where the user states it, else left, P235)
        where_rows = np.flatnonzero(unknown)
        for k in np.unique(cause[where_rows]).tolist():
            mine = where_rows[cause[where_rows] == k]
            path, line, col, why, _ = t.load_causes[k]
            places = list(dict.fromkeys(motion_at(program, int(r)) for r in mine))
            if stated is not None:
                out.append(Diagnostic(path, line, col, P339, f"payload not statically known ({why}): --load "
                                      f"{_load_text(stated)} taken at {len(mine)} target(s) (at {listed(places)})",
                                      "note"))
                continue
            n = len(np.unique(np.stack([t.file[mine], t.line[mine], t.col[mine]], axis=1), axis=0))
            at = "" if places == [f"{path}:{line}"] else f" (at {listed(places)})"
            out.append(Diagnostic(path, line, col, P235, f"payload not statically known ({why}): {n} target(s) "
                                  f"left as written{at}; the model takes the load"))
        if stated is None:
            use[where_rows] = False
            left[P235] = where_rows
    rows = np.flatnonzero(use)
    if len(rows):
        bad = rows[~np.asarray(model.load_reach(loads[rows]), bool)]
        if len(bad):
            measured = "; ".join(_load_text(v) for v in model.measured_loads) or "not stated"
            out += collect(program, bad, P338, lambda i: f"the payload here, {_load_text(loads[bad[i]])}, is "
                           f"beyond what the model can extrapolate to from the loads it was measured with "
                           f"({measured}): left as written")
            use[bad] = False
            left[P338] = bad
    return loads, out, left


def frame_rule(program: Program, use: np.ndarray) -> list[Diagnostic]:
    """P103: a frame that is not finite (its targets would only be 'not fully known').
    Narrows ``use``."""
    t = program.targets
    broken = [i for i, f in enumerate(program.frames) if not np.isfinite(f.base).all()]
    rows = np.flatnonzero(np.isin(t.frame, broken)) if broken else np.zeros(0, int)
    use[rows] = False
    return collect(program, rows, P103, lambda i: f"the frame of this target ({program.frames[t.frame[rows[i]]].label}) "
                   "is not a finite number", "error")


def known_rule(program: Program, model: Compensator, settings: Settings, poses: np.ndarray,
               use: np.ndarray) -> list[Diagnostic]:
    """P212 position not known (left as written), P213 orientation not known (the model's
    nominal attitude assumed; an error without one), P216 a partial aggregate under
    ``fill_partial=False``. Narrows ``use`` and fills ``poses`` in place."""
    no_position = use & np.isnan(poses[:, :3]).any(axis=1)
    out = collect(program, np.flatnonzero(no_position), P212,
                  "position not fully known (a partial aggregate where the current position is not known: no "
                  "preceding target, or after a relative or axis motion, a call not read, a $TOOL change, or "
                  "where paths from different positions meet): left as it is")
    use &= ~no_position
    no_attitude = use & np.isnan(poses[:, 3:6]).any(axis=1)
    if no_attitude.any():
        nominal = model.nominal_attitude
        rows = np.flatnonzero(no_attitude)
        if nominal is None:
            out += collect(program, rows, P213, "target has no orientation and the model records no nominal "
                           "attitude", "error")
            use &= ~no_attitude
        else:
            poses[no_attitude, 3:6] = nominal
            out += collect(program, rows, P213,
                           f"orientation not known: the model's nominal attitude {list(map(float, nominal))} is assumed")
    if not settings.rules.fill_partial:
        rows = np.flatnonzero(use)
        partial = rows[missing_xyz(program, rows).any(axis=1)]
        out += collect(program, partial, P216, "partial aggregate: the controller takes its missing X/Y/Z from the "
                       "previous commanded (compensated) position, i.e. another target's correction; write the target "
                       "in full, or compensate without --no-fill-partial to have them written in", "error")
    return out


def finite_rule(program: Program, poses: np.ndarray, use: np.ndarray) -> list[Diagnostic]:
    """P103: a target that is not finite or beyond the model's float32. Narrows ``use``."""
    bad = use & ~(np.abs(poses) < np.finfo(np.float32).max).all(axis=1)  # NaN, inf, beyond float32
    use &= ~bad
    return collect(program, np.flatnonzero(bad), P103, "target is not a finite number (or too large for the "
                   "model's float32)", "error")


@functools.lru_cache(maxsize=8)
def nominal_reach(robot: str | None) -> Callable[[np.ndarray], np.ndarray] | None:
    """Where ``--robot`` is a description file: its nominal robot's IK reach (robot-base poses →
    bool mask, P309); a robot given by its name: None (its name is all the rules use)."""
    if not robot or not is_description_file(robot):
        return None
    from ..robot.arm import Robot

    nominal = Robot(load_description(robot))
    return lambda poses: nominal.ik(poses)[1]


def reach_rule(program: Program, model: Compensator, selection: Selection,
               reachable: Callable[[np.ndarray], np.ndarray] | None = None) -> list[Diagnostic]:
    """P302 beyond the model's reach; P309 no IK solution (``reachable``: robot-base poses → a
    bool mask, the nominal robot's IK)."""
    rows, sel = selection.rows, selection.poses
    far = model.beyond_reach(sel[:, :3])
    out = collect(program, rows[far], P302, "target beyond the robot's reach: no model can compensate there", "error")
    if reachable is not None and len(sel):
        no_ik = ~np.asarray(reachable(sel), bool) & ~far
        out += collect(program, rows[no_ik], P309, "the nominal robot has no IK solution for this target", "error")
    return out


def outside_envelope(model: Compensator, selection: Selection) -> np.ndarray:
    envelope = model.envelope
    return envelope.outside(selection.poses) if envelope is not None else np.zeros(len(selection.rows), bool)


def envelope_rule(program: Program, model: Compensator, selection: Selection) -> list[Diagnostic]:
    """P301: outside the model's training box or attitude range (a warning)."""
    return collect(program, selection.rows[outside_envelope(model, selection)], P301,
                   "target outside the model's training envelope")


def output_rule(program: Program, settings: Settings, commands: Commands, model: Compensator | None = None
                ) -> list[Diagnostic]:
    """P305 the model returns NaN or inf; P303 a correction above the bound (worst first), saying
    whether the target is outside the data the model was trained on (it extrapolates there)."""
    rows = commands.selection.rows
    size = np.linalg.norm(commands.commanded - commands.selection.poses[:, :3], axis=1)
    bad = ~np.isfinite(size)
    out = collect(program, rows[bad], P305, "the model returns NaN or inf at this target", "error")
    bound = settings.rules.max_correction_mm
    large = np.flatnonzero(~bad & (size > bound))
    large = large[np.argsort(-size[large], kind="stable")]
    outside = outside_envelope(model, commands.selection) if model is not None else np.zeros(len(rows), bool)
    out += collect(program, rows[large], P303, lambda i: f"correction of {size[large[i]]:.3f} mm exceeds the bound "
                   f"of {bound} mm: " + ("the target is outside the data the model was trained on (P301), where it "
                                         "extrapolates: measure the robot there, or keep the target inside"
                                         if outside[large[i]] else "the model is wrong here, inside its training data"),
                   "error")
    return out


def joints_rule(program: Program, model: Compensator, commands: Commands) -> list[Diagnostic]:
    """P301: joint angles outside those trained on (a wrist turned the other way), for
    targets inside the box and attitude range (those outside are warned already)."""
    envelope = model.envelope
    if envelope is None or commands.joints is None or envelope.joints is None:
        return []
    away = np.flatnonzero(envelope.outside_joints(commands.joints) & ~outside_envelope(model, commands.selection))
    q = commands.joints
    return collect(program, commands.selection.rows[away], P301, lambda i: "target's joint angles outside those the "
                   f"model was trained on ({_joints_away(q[away[i]], envelope.joints)})")


def std_bound(model: Compensator, settings: Settings) -> float | None:
    """The bound :func:`std_rule` holds ``error_std`` to (None: no check, e.g. a model without
    that output): what the model run must supply (``Commands.std``)."""
    bound = settings.rules.max_std_mm if settings.rules.max_std_mm is not None else model.max_std_mm
    return bound if model.has_std and bound is not None and math.isfinite(bound) else None


def std_rule(program: Program, model: Compensator, settings: Settings, commands: Commands) -> list[Diagnostic]:
    """P336 (a warning): the model's own std at a target (output ``error_std`` at its command,
    each reached from the previous one's: ``Compensator.command_std``) above
    ``settings.rules.max_std_mm`` or, without it, the card's ``uncertainty.max_std_mm``: the training
    data did not pin the model down there. A model without ``error_std`` states nothing: no
    finding. The numbers come with the commands (``Commands.std``: onnxruntime computes only the
    outputs asked for, and the run that settles the approach at the commands asks for it too);
    commands without them are run once more here."""
    bound = std_bound(model, settings)
    sel = commands.selection
    if bound is None or not len(sel.rows):
        return []
    std = commands.std
    if std is None:
        # (no previous_joints: the graph solves each previous command on its target's branch)
        std = model.command_std(np.c_[commands.commanded, sel.poses[:, 3:6]], joints=sel.joints, tool=sel.tool,
                                order=sel.order, load=sel.load)
    high = np.flatnonzero(std > bound)
    high = high[np.argsort(-std[high], kind="stable")]
    digits = max(3, 1 - int(np.floor(np.log10(bound))) + 2) if bound > 0 else 3  # (0.0455 > 0.0455, not 0.045 > 0.0455)
    return collect(program, sel.rows[high], P336, lambda i: f"the model's std at this target is "
                   f"{std[high[i]]:.{digits}f} mm, above {bound:.{digits}f} mm (--max-std): its training data did not "
                   "pin it down here")


# --------------------------------------------------------------------------- all


def select_with_findings(program: Program, model: Compensator, settings: Settings, *,
                         reachable: Callable[[np.ndarray], np.ndarray] | None = None,
                         chain=None) -> tuple[Selection, list[Diagnostic]]:
    """The targets the model takes, and every finding that needs no model output. Besides the
    settings: ``reachable`` (robot-base poses → bool mask, P309; default: the IK of the nominal
    robot where ``settings.robot`` is its description file) and ``chain`` (a
    ``compensator.Chain``: a part of a program after the parts before, streaming)."""
    if reachable is None:
        reachable = nominal_reach(settings.robot)
    out = (stamp_rule(program, settings) + accuracy_rule(program, settings) + fit_rule(program, model, settings))
    out += demonstration_rule(model)
    in_metres = unit_rule(program, model)
    out += in_metres
    poses, use = robot_base_poses(program, model_bases(program, model))
    if in_metres:  # (no target is taken: one finding names the unit)
        use[:] = False
    held = held_rule(program, use)
    out += frame_rule(program, use)
    unstated = use.copy()
    out += pose_frame_rule(program, model, use)
    unstated &= ~use
    out += known_rule(program, model, settings, poses, use)
    out += finite_rule(program, poses, use)
    loads, found, load_left = load_rule(program, model, settings, use)
    out += found
    rows = np.flatnonzero(use)
    left = dict(held)
    left.update(load_left)
    if unstated.any():
        left[P218] = np.flatnonzero(unstated)
    selection = Selection(rows, poses[rows], left=left)
    out += reach_rule(program, model, selection, reachable)
    selection.order = execution_order(program, selection, poses, model)
    if model.wants_joints or model.wants_tool:
        selection, found = configuration_rule(program, model, selection, chain)
    else:
        selection, found = stated_configuration_rule(program, model, selection)
    out += found
    selection, found = group_rule(program, selection)
    out += found
    selection.order = execution_order(program, selection, poses, model)
    selection.base_poses = poses
    selection.loads = loads
    out += envelope_rule(program, model, selection)
    return selection, out


def stated_configuration_rule(program: Program, model: Compensator,
                              selection: Selection) -> tuple[Selection, list[Diagnostic]]:
    """P313 (a warning): for a model without the ``joints`` input, a target whose stated S/T
    is another arm configuration than the one the model evaluates is left as written."""
    from .inputs import configuration_mismatch

    bad, found = configuration_mismatch(program, model, selection.rows, selection.poses, collect)
    if not bad.any():
        return selection, found
    left = dict(selection.left)
    left[P313] = selection.rows[bad]
    return Selection(selection.rows[~bad], selection.poses[~bad], None, None, left), found


def configuration_rule(program: Program, model: Compensator, selection: Selection,
                       chain=None) -> tuple[Selection, list[Diagnostic]]:
    """P309 (a warning): a target whose arm configuration has no joint angles on the nominal
    robot, left as written; the others get the model's ``joints`` / ``tool`` inputs."""
    from .inputs import controller_inputs

    rows, poses, q, tool, found = controller_inputs(program, model, selection.rows, selection.poses, collect, chain,
                                                    selection.order)
    left = dict(selection.left)
    dropped = np.setdiff1d(selection.rows, rows) if len(rows) < len(selection.rows) else rows[:0]  # (rows: a subset)
    if len(dropped):
        left[P309] = dropped
    return Selection(rows, poses, q, tool, left), found


def select(program: Program, model: Compensator, settings: Settings = Settings(), *, reachable=None,
           chain=None) -> Selection:
    """The targets the model takes (known position, finite), robot-base poses with the
    nominal attitude filled in (``reachable``, ``chain``: as :func:`select_with_findings`)."""
    return select_with_findings(program, model, settings, reachable=reachable, chain=chain)[0]


def static_findings(program: Program, model: Compensator, settings: Settings, *, reachable=None,
                    chain=None) -> list[Diagnostic]:
    """Every finding that needs no model output."""
    return select_with_findings(program, model, settings, reachable=reachable, chain=chain)[1]


def dead_band_notes(program: Program, commands: Commands) -> list[Diagnostic]:
    """P321 notes (``-v``): targets where a joint barely moves and no command makes its motion
    agree with the side of its lost motion assumed (Compensator's approach settling): the
    joint stays in its dead band; the command sent has the smallest worst case over both sides."""
    inside = commands.inside
    if inside is None or not len(inside.rows):
        return []
    rows = commands.selection.rows[inside.rows]
    out = []
    for row, joints, worst, error in zip(rows.tolist(), inside.joints, inside.worst_mm.tolist(), inside.error_mm.tolist()):
        names = ", ".join(f"A{j + 1}" for j in np.flatnonzero(joints)) or "a joint"
        out.append(Diagnostic(*where(program, row), P321,
                              f"{names} barely moves here and stays in its backlash dead band: no command makes its "
                              f"motion agree with the side assumed; sent the one with the smallest worst case over "
                              f"both sides, {worst:.3f} mm (with the side its motion takes: {error:.3f} mm)", "note"))
    return out


def command_findings(program: Program, commands: Commands, model: Compensator, settings: Settings) -> list[Diagnostic]:
    """Every finding about the model's commands for the selected targets."""
    return (output_rule(program, settings, commands, model) + joints_rule(program, model, commands)
            + std_rule(program, model, settings, commands))


def findings(program: Program, commands: Commands | None, model: Compensator, settings: Settings, *,
             reachable=None) -> list[Diagnostic]:
    """Every finding of these rules about ``program`` (the reader's warnings are not
    repeated). ``commands`` None: only those that need no model output."""
    out = static_findings(program, model, settings, reachable=reachable)
    if commands is not None:
        out += command_findings(program, commands, model, settings)
    return out


def run_model(model: Compensator, selection: Selection, iterations: int | None, std: bool = False) -> Commands:
    """The model's fixed-point commands (and joint angles where the card has joint ranges; with
    ``std``, its ``error_std`` at them: :func:`std_bound`)."""
    envelope = model.envelope
    wanted = model.has_joints and envelope is not None and envelope.joints is not None
    if not len(selection.rows):
        return Commands(selection, np.zeros((0, 3)), np.zeros((0, 6)) if wanted else None, std=np.zeros(0) if std else None)
    commanded = np.empty((len(selection.rows), 3))
    joints = np.empty((len(selection.rows), 6)) if wanted else None
    stds = np.empty(len(selection.rows)) if std else None
    for chunk in model.command_chunks(selection.poses, iterations, joints=selection.joints, tool=selection.tool,
                                      with_joints=True, std=std, order=selection.order, load=selection.load):
        start, part, q = chunk
        commanded[start:start + len(part)] = part
        if joints is not None:
            joints[start:start + len(part)] = q
        if stds is not None:
            stds[start:start + len(part)] = chunk.std
    return Commands(selection, commanded, joints, std=stds)

"""The property "never silently wrong", checked with the IR's interpreter (``programs.interpreter``).

``check(files, texts, dialect, model, …)`` compensates a program, then runs the original and the
compensated texts through the interpreter with the same oracle (the same answers to the same
questions: branches, inputs, what code not read does), for several oracles, and compares the
motions that ran:

* a target whose commanded pose changed must be at P + Ê(C) for its own executed nominal pose
  P, reached from the command that really ran before it (C: its new command; the model's
  ``previous_pose`` the predecessor's command), to the rewrite's agreement (``AGREE_MM``) and
  rounding, or to the worst case compensate named for it (P322: reached from several places);
* a target whose pose did not change was left as written — and then compensate must not have
  said every target was compensated (exit 0).

What compensate assumes where nothing is known before a target (the program's first, after an
axis motion, after a target left with its frame not known): the model's own rule for a target
with no predecessor (``previous_pose`` itself); the check assumes the same there.

A model that takes the controller's joint angles (``joints``) is evaluated at the configuration
the controller really runs along each path (:func:`_controller`): KUKA's rules on the path's
commands — S/T read on PTP, a LIN or CIRC keeping the configuration it is in, a PTP without S/T
nearest the current axes — from the axes a joint motion left, else from the position compensate
assumes before a program's first target (``compensation.inputs.first_joints``).

Returned: the violations found (empty: the property holds), and how many paths and motions were
looked at. Used by ``tests/test_interpreter.py`` (a fast profile) and ``benchmarks/interpreter.py``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..core import frames as fr

__all__ = ["check", "Checked", "lowered"]


@dataclass
class Checked:
    violations: list = field(default_factory=list)
    paths: int = 0
    motions: int = 0
    compensated: int = 0
    untouched: int = 0
    exit_code: int = 0


def lowered(files, texts, dialect: str, config=None, active=None, **read_with):
    """(Unit, Dialect) of a program (``programs.lower``; ``read_with``: a backup's system files
    ``data``, the RAPID ``task``, the ``registers`` setting, as ``Program.read_with``)."""
    from ..programs.io import lower

    return lower(list(files), list(texts), dialect, config=config, active=active, **read_with)


def _at(motion) -> tuple | None:
    """Where a motion's target aggregate stands (file, line, col): what a Targets row says."""
    loc = motion.loc
    return None if loc is None else (loc.file, loc.line, loc.col)


def _key(motion) -> tuple:
    """A motion as the oracle tells rows apart: (its statement's place, its target's place)."""
    site = motion.site
    return (site.file, site.line, site.col), _at(motion)


def _six(m: np.ndarray) -> np.ndarray:
    return fr.matrix_to_frame(m)


# what a compensated target may differ from P + Ê: the runs of one number agree to AGREE_MM per
# coordinate (compensate._agreement), the numbers are written to ROUNDING_MM, the fixed point leaves
# ~1e-6 mm: as a distance, √3 × (0.005 + 0.0005) + a margin
TOL_MM = 0.01
ANY = ("any",)  # (a predecessor place that stands for every one)


def _axes_pose(model, program=None):
    """Axis values (deg) → the TCP pose [6] they give on the model's robot with the model's tool
    (the nominal kinematics: where a joint motion leaves the robot); a function giving None where
    the model takes no previous pose, takes a tool, or has no description."""
    from ..compensation.inputs import model_description, model_tool
    from ..robot.arm import Robot
    from ..robot.conventions import DIALECT_CONTROLLERS, controller_of

    description = model_description(model) if model.wants_previous and not model.wants_tool else None
    if description is None or program is None \
            or controller_of(description) != DIALECT_CONTROLLERS.get(program.dialect):
        return lambda axes: None
    robot = Robot(description.replace(tool=model_tool(model, description)))
    return lambda axes: robot.fk(np.asarray([axes], float))[0]


def _controller(model, program):
    """For a KRL program and a model with the ``joints`` input (and without ``tool``: its tool
    the program's, as the generated programs run with ``--tool model``): a function of a path's
    motions → the joint angles [n, 6] deg the controller runs each commanded Cartesian motion in
    (NaN: none, or not a Cartesian motion); None where the check has no such model."""
    from ..compensation.inputs import first_joints, model_description, model_tool
    from ..robot import configuration, conventions
    from ..robot.arm import Robot

    description = model_description(model) if model.wants_joints and not model.wants_tool else None
    if description is None or program.dialect != "krl":
        return None
    robot = Robot(description.replace(tool=model_tool(model, description)))
    keeps = set(conventions.KUKA_KEEPS)

    def joints(motions) -> np.ndarray:
        q = np.full((len(motions), 6), np.nan)
        run: list[int] = []
        start = None

        def flush():
            if not run:
                return
            poses = np.array([_six(motions[i].base) for i in run])
            config = np.array([(-1, -1) if motions[i].motion in keeps else motions[i].config for i in run], int)
            ptp = np.array([motions[i].motion in ("PTP", "SPTP") for i in run])
            initial = start if start is not None else first_joints(model, robot, poses[:1])[0]
            if not np.isfinite(initial).all():
                return
            got, found = configuration.controller_joints(robot, poses, config[:, 0], config[:, 1], ptp,
                                                         np.asarray(initial, float))
            q[[i for i, f in zip(run, found) if f]] = got[found]

        for i, m in enumerate(motions):
            if m.base is None:  # (a joint motion: the axes it leaves, where known; else what compensate assumes)
                flush()
                run, start = [], (np.asarray(m.axes, float) if m.axes is not None else None)
                continue
            run.append(i)
        flush()
        return q

    return joints


def check(files, texts, dialect: str, model, config=None, active=None, seeds=range(4), tol_mm: float = TOL_MM,
          settings=None, **read_with) -> Checked:
    """Compensate ``texts`` with ``model`` (a Compensator; ``settings``: a Settings, default the
    defaults) and check the property over the oracles of ``seeds`` (see the module text);
    ``read_with``: ``data`` (a backup's system files), ``task``, ``registers`` (``read_program``'s)."""
    from ..compensation.pipeline import compensate_program
    from ..core.diagnostics import P210, P231, P322, PostprocError
    from ..programs.analysis import analyse
    from ..programs.interpreter import Oracle, run
    from ..programs.io import read_program

    out = Checked()
    program = read_program(list(files), list(texts), dialect, config=config, active=active, **read_with)
    try:
        report = compensate_program(program, model, *([settings] if settings is not None else []))
    except PostprocError:
        out.exit_code = 2  # nothing written: nothing to check
        return out
    out.exit_code = 0 if report.complete else 1
    new_texts = [report.outputs[f] for f in files]
    worst = {}
    # points compensated for their own runs whose runs at an offset move with them, said (P231):
    # those runs are not at their own P + Ê, and need not be
    with_point = {(w.path, w.line, w.col) for w in report.warnings if w.code == P231}
    # relative motions left as written whose start is not known (P210): they move with their start's
    # correction, said so
    with_point |= {(w.path, w.line, w.col) for w in report.warnings if w.code == P210}
    for note in report.notes:
        if note.code == P322:
            # "… at most 0.098 mm from each run's own"
            text = note.message.rsplit("at most ", 1)[-1].split(" mm")[0]
            try:
                worst[(note.path, note.line, note.col)] = float(text)
            except ValueError:
                pass
    unit_a, dialect_a = lowered(files, texts, dialect, config, active, **read_with)
    unit_b, dialect_b = lowered(files, new_texts, dialect, config, active, **read_with)
    axes_pose = _axes_pose(model, program)
    stated_load = settings.reading.load if settings is not None else None

    def load_of(motion):
        """The payload the model takes at a motion of the run (its ``load`` input, [1, 4]): the one the run
        carries; where the program sets none, the one stated (``--load``), else NaN (the model's reference)."""
        load = motion.load if motion.load is not None else stated_load
        return np.full((1, 4), np.nan) if load is None else np.asarray(load, float)[None]

    controller = _controller(model, program)
    # targets compensate reached from nothing known: Targets.prev -1, or a predecessor whose pose in
    # the robot base is not known (its frame or its numbers): the model's first-target rule. Kept as
    # pairs (the motion: its statement and its target's place; its predecessor's, or ANY where the
    # analysis knew nothing before it): one declaration runs in several motions, each with its own
    # predecessor (the rows and their statements: the analysis compensate read them from)
    built = analyse(unit_a, dialect_a)
    t = built.targets

    def motion_of(i):
        here = (int(t.file[i]), int(t.line[i]), int(t.col[i]))
        site = built.sites[i] if i < len(built.sites) else None
        return ((site.file, site.line, site.col) if site is not None else here), here

    alone = set()
    if t.prev is not None and len(t):
        first = t.prev < 0
        before = t.prev[~first]
        first[~first] = np.isnan(t.poses[before, :3]).any(axis=1) | (t.frame[before] < 0)
        for i in np.flatnonzero(first).tolist():
            j = int(t.prev[i])
            alone.add((motion_of(i), motion_of(j) if j >= 0 else ANY))
    entries = list(unit_a.entries)
    for seed in seeds:
        for entry in entries:
            oracle = Oracle(seed)
            a = run(unit_a, dialect_a, oracle, entry)
            b = run(unit_b, dialect_b, oracle, entry)
            out.paths += 1
            if [(m.site.file, m.kind) for m in a] != [(m.site.file, m.kind) for m in b]:  # (the stamp moves lines)
                out.violations.append(f"seed {seed} {entry}: the compensated program runs another path")
                continue
            prev = None
            came = None  # (the predecessor motion: its statement and its target's place)
            q_run = controller(b) if controller is not None else None
            for i, (ma, mb) in enumerate(zip(a, b)):
                if ma.base is None or mb.base is None:
                    # (a joint motion to known axis values: the robot comes from the TCP they give)
                    prev = axes_pose(ma.axes) if ma.axes is not None and ma.axes == mb.axes else None
                    came = None
                    continue
                out.motions += 1
                p, c = _six(ma.base), _six(mb.base)
                previous = prev if prev is not None else c
                q = None if q_run is None else q_run[i][None]
                if q is not None and not np.isfinite(q).all():
                    q = None  # (no configuration the controller can run: compensate must leave it)
                    if np.abs(c[:3] - p[:3]).max() > 1e-6:
                        out.violations.append(f"seed {seed} {entry}: motion {i} at {files[ma.site.file]}:"
                                              f"{ma.site.line} is compensated and the controller has no joint "
                                              "angles for it")
                e = model.predict(c[None], previous[None] if model.wants_previous else None, joints=q,
                                  load=load_of(mb))[0]
                moved = np.abs(c[:3] - p[:3]).max() > 1e-6
                if moved:
                    out.compensated += 1
                    where_ = (files[ma.loc.file] if ma.loc and ma.loc.file >= 0 else "", ma.loc.line if ma.loc else 0,
                              ma.loc.col if ma.loc else 0)
                    allowed = tol_mm + 2 * worst.get(where_, 0.0)
                    dev = float(np.linalg.norm(c[:3] - p[:3] - e))
                    if dev > allowed and where_ in with_point and not report.complete:
                        dev = 0.0  # (a run at an offset from its point, or the point: its P231 said so)
                    if dev > allowed and ((_key(ma), came) in alone or (_key(ma), ANY) in alone) \
                            and model.wants_previous:
                        e_alone = model.predict(c[None], c[None], load=load_of(mb))[0]  # (nothing known before: itself)
                        dev = min(dev, float(np.linalg.norm(c[:3] - p[:3] - e_alone)))
                    if dev > allowed:
                        out.violations.append(
                            f"seed {seed} {entry}: motion {i} at {files[ma.site.file]}:{ma.site.line} commanded "
                            f"{np.round(c[:3], 4).tolist()} for {np.round(p[:3], 4).tolist()}: {dev:.4f} mm from "
                            f"P + Ê (allowed {allowed:.4f})")
                else:
                    e0 = model.predict(p[None], (prev if prev is not None else p)[None] if model.wants_previous
                                       else None, joints=q, load=load_of(ma))[0]
                    if np.linalg.norm(e0) > tol_mm:
                        out.untouched += 1
                        if report.complete:
                            out.violations.append(
                                f"seed {seed} {entry}: motion {i} at {files[ma.site.file]}:{ma.site.line} is left as "
                                "written and compensate said every target was compensated (exit 0)")
                prev, came = c, _key(ma)
    return out

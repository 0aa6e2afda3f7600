"""The verify use case: an original and a compensated program run on the simulated robot, the
method's Table 2 before and after, and the verdict against the acceptance limits.

``postproc verify`` (cli/verify.py) maps its arguments to :class:`~postproc.settings.Settings`
(``reading``: how the programs are read, as they were compensated; ``robot``: the simulated
robot's description; ``acceptance``: the limits; ``model``: the model the program was
compensated with, for the verdict) and prints what :func:`verify` returns.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..core.diagnostics import P213, P309, P335, P601, PostprocError
from ..settings import Settings

__all__ = ["Verification", "verify", "execution"]


@dataclass
class Verification:
    """What verify found: ``figures`` (the JSON ``--json`` prints), ``document`` (the verdict),
    ``result`` (the simulator's Table 2s and errors), ``targets`` (how many), ``notes`` (what
    was assumed or skipped), ``sim`` (the simulated robot)."""

    figures: dict
    document: dict
    result: dict
    targets: int
    sim: object
    notes: list[str] = field(default_factory=list)

    @property
    def passed(self) -> bool:
        return bool(self.document["passed"])


def verify(original: str, compensated: str, settings: Settings, *, robot_seed: int | None = None, seed: int = 0,
           noise: bool = True) -> Verification:
    """Run ORIGINAL's targets and COMPENSATED's (the same program with changed numbers) through
    the simulated robot of ``settings.robot`` (drawn with ``robot_seed``; measurement noise
    ``seed``, ``noise``) in execution order; Table 2 before and after and the verdict against
    ``settings.acceptance``. PostprocError P601 where the two are not one program, P335 for a
    target out of reach, P309 for a configuration the robot cannot run."""
    from .verdict import model_entry, verdict
    from ..calibration.simulator import SimulatedRobot
    from ..core.stats import table2
    from ..robot.description import robot_description

    sim = SimulatedRobot(robot_description(settings.robot), robot_seed)
    orig, comp, p_orig, p_comp, rows, skipped, notes = _pair(original, compensated, settings, sim.description)
    attitude = np.asarray(sim.description.workspace.get("attitude", (0.0, 90.0, 0.0)), float)
    p_orig, n1 = _fill(p_orig, orig, attitude, "ORIGINAL")
    p_comp, n2 = _fill(p_comp, comp, attitude, "COMPENSATED")
    notes += n1 + n2
    options = execution(orig, rows, sim)
    stated = _stated_loads(orig, rows, settings.reading)
    if stated is not None:
        options["loads"] = stated
    _check_reach(sim, ((orig, p_orig, "ORIGINAL"), (comp, p_comp, "COMPENSATED")), rows, options)
    result = sim.verify(p_orig, p_comp, rng_seed=seed, noise=noise, **options)
    model = None
    if settings.model is not None:
        from ..model.compensator import load_model

        model = load_model(settings.model)
    limits = settings.acceptance
    document = verdict("verify", limits, {"before": result["before"], "after": result["after"],
                                          "orientation_before": result["orientation_before"],
                                          "orientation_after": result["orientation_after"], "targets": int(len(p_orig))},
                       model_entry(model), {"original": original, "compensated": compensated})
    figures = {
        "targets": int(len(p_orig)),
        "skipped": skipped,
        "robot": sim.robot.name,
        "robot_seed": sim.seed,
        "default_robot": sim.is_default,
        "noise": noise,
        "before": result["before"],
        "after": result["after"],
        "orientation_before_deg": result["orientation_before"],
        "orientation_after_deg": result["orientation_after"],
    }
    # the targets COMPENSATED changes (the others were left as written and keep their error)
    changed = np.abs(p_comp[:, :3] - p_orig[:, :3]).max(axis=1) > 1e-6
    figures["compensated"] = int(changed.sum())
    # position only (compensate without --orientation): the orientation as written, its error unchanged
    figures["orientation_corrected"] = bool(len(p_comp) and np.abs(p_comp[:, 3:6] - p_orig[:, 3:6]).max() > 1e-6)
    figures["after_compensated"] = table2(result["errors_after"][changed])
    if limits.stated:
        figures.update(limits.stated)
        figures["passed"] = bool(document["passed"])
    return Verification(figures, document, result, int(len(p_orig)), sim, notes)


def _fill(poses, program, attitude, name: str):
    """Missing components take the previous target's (KRL: the current position's); a missing
    orientation before any is known takes the working attitude. Returns (poses, notes)."""
    notes = []
    out = poses.copy()
    nan = np.isnan(out)
    if nan.any():
        rows = np.arange(len(out))[:, None]
        last = np.maximum.accumulate(np.where(~nan, rows, -1), axis=0)
        lead = last < 0
        if lead[:, :3].any():
            r = int(np.flatnonzero(lead[:, :3].any(axis=1))[0])
            t = program.targets
            raise PostprocError(f"{name}: target has no X/Y/Z and no earlier target to take them from",
                                program.files[t.file[r]], int(t.line[r]), int(t.col[r]), P213)
        filled = np.take_along_axis(out, np.maximum(last, 0), axis=0)
        filled[:, 3:][lead[:, 3:]] = np.broadcast_to(attitude, (len(out), 3))[lead[:, 3:]]
        if lead[:, 3:].any():
            notes.append(f"{name}: targets without A/B/C before any orientation is known take the working attitude "
                         f"{list(map(float, attitude))}")
        out = filled
    return out, notes


def execution(program, rows, sim) -> dict:
    """How the controller runs targets ``rows`` of ``program``: their stated configuration (S/T,
    RAPID confdata, FANUC CONFIG on the simulated robot's description: configuration.
    stated_configuration; a form the description cannot say is P309, refused), motion kinds
    (conventions.execution_kinds) and $TOOL (the simulated robot's tool where the program's is
    unknown) — the options of SimulatedRobot.verify (``verify`` adds each target's payload:
    ``_stated_loads``). Both runs use the ORIGINAL's."""
    from ..robot.configuration import stated_configuration

    t = program.targets
    stated, unmapped, why = stated_configuration(program, sim.description, rows)
    if unmapped.any():
        r = rows[np.flatnonzero(unmapped)[0]]
        raise PostprocError(f"{why[0]}: the simulated {sim.robot.name} cannot run this program",
                            program.files[t.file[r]], int(t.line[r]), int(t.col[r]), P309)
    tools = np.tile(sim.robot.tool, (len(rows), 1))
    from ..core.frames import frame_groups

    for f, here in frame_groups(t.frame[rows]):
        if program.frames[f].tool is not None:
            tools[here] = program.frames[f].tool
    options = {"config": stated, "tools": tools, "motions": t.motion[rows]}
    if t.prev is not None:  # (in execution order: each row after its predecessor, a row of these or none)
        at = np.full(len(t), -1)
        at[rows] = np.arange(len(rows))
        options["prev"] = np.where(t.prev[rows] >= 0, at[np.maximum(t.prev[rows], 0)], -1)
    if t.start is not None:
        options["axes"] = t.start[rows]
    return options


def _stated_loads(program, rows, reading) -> np.ndarray | None:
    """The payload at targets ``rows`` as compensate took it (``findings.payloads``); None where
    nothing says one (the simulated robot carries its description's payload there)."""
    from ..compensation.findings import payloads

    if program.targets.load is None and reading.load is None:
        return None
    loads = payloads(program, reading)[0][rows]
    return None if np.isnan(loads).all() else loads


def _in_description(program, description):
    """Each frame of ``program`` in the simulated robot's description frame: through the
    description's ``controller_base`` for a program's targets (a UR description in ROS's
    base_link: URScript's base is turned 180° about Z), a pose list's rows unless they say
    '# frame: controller' taken as they are (as findings.model_bases does for a model)."""
    from ..core.frames import frame_to_matrix

    base = frame_to_matrix(np.asarray(description.controller_base, float))
    if not program.in_controller_base or np.array_equal(base, np.eye(4)):
        return None
    return [base @ f.base for f in program.frames]


def _pair(original: str, compensated: str, settings: Settings, description):
    """The two programs read (as ``settings.reading`` says, as they were compensated) and matched
    target by target: (original, compensated, their poses of the targets with a known frame, in
    the simulated robot's description frame, those rows, how many were skipped, notes); P601
    where they are not one program."""
    from ..programs import ActiveFrames
    from ..programs.base_poses import robot_base_poses
    from ..programs.io import load_program
    from ..robot.external import units_of

    reading = settings.reading
    active = reading.active
    units = units_of(description)
    if units:  # the simulated cell's track / turntable: where the robot and the part really are
        active = ActiveFrames(external=units) if active is None else replace(active, external=units)
    orig = load_program(original, reading.config_list, reading.dialect, active)
    comp = load_program(compensated, reading.config_list, reading.dialect, active)
    p_orig, ok_orig = robot_base_poses(orig, _in_description(orig, description))
    p_comp, ok_comp = robot_base_poses(comp, _in_description(comp, description))
    if len(p_orig) != len(p_comp):
        raise PostprocError(f"ORIGINAL has {len(p_orig)} targets, COMPENSATED has {len(p_comp)}: they must be the "
                            "same program with changed numbers", compensated, code=P601)
    if len(p_orig) == 0:
        raise PostprocError("no Cartesian targets in this program", original, code=P601)
    notes = []
    keep = ok_orig & ok_comp
    if not keep.all():
        notes.append(f"{int((~keep).sum())} target(s) skipped: their frame is not known statically "
                     f"(run with --config $config.dat, --base / --tool?)")
    if not keep.any():
        raise PostprocError("no target with a known frame to verify", original, code=P601)
    return orig, comp, p_orig[keep], p_comp[keep], np.flatnonzero(keep), int((~keep).sum()), notes


def _check_reach(sim, programs, rows, options) -> None:
    """P335 at the first target of either program the simulated robot cannot reach."""
    for program, poses, label in programs:
        ok = sim.reachable_in(poses, **{k: v for k, v in options.items() if k != "loads"})  # (reach: no load)
        if not ok.all():
            bad = np.flatnonzero(~ok)
            r, t = rows[bad[0]], program.targets
            more = f" (and {len(bad) - 1} more)" if len(bad) > 1 else ""
            raise PostprocError(f"{label} target out of reach of {sim.robot.name}: "
                                f"{np.round(poses[bad[0]], 3).tolist()}{more}",
                                program.files[t.file[r]], int(t.line[r]), int(t.col[r]), P335)

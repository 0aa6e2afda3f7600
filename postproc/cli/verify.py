"""postproc verify: run an original and a compensated program on the simulated robot, print Table 2."""
from __future__ import annotations

import sys

EXAMPLES = """examples:
  postproc verify part.src out/part.src                       (KRL: .dat beside each .src)
  postproc verify part.src out/part.src --config KRC/R1/System/$config.dat --json
  postproc verify poses.csv poses_comp.csv --robot-seed 3 --max-mean 0.1   (exit 1 if above)
  postproc verify part.src out/part.src --max-mean 0.1 --max-p95 0.2 --verdict verdict.json   (a cell's CI gate)

Error = distance between each target of ORIGINAL (robot base frame) and where the simulated
robot's TCP goes when commanded that target (before) or the corresponding target of
COMPENSATED (after); both programs run in execution order (each target after the one the
program runs before it), from HOME or the axis values a joint motion to known ones left the
robot at (PTP HOME, movej(q)), measured with the tracker's noise and the robot's
repeatability (--no-noise: the exact positions).
"""


def add_parser(sub, common, formatter) -> None:
    from .compensate import add_frame_arguments

    p = sub.add_parser(
        "verify",
        parents=[common],
        formatter_class=formatter,
        help="Table 2 (max/min/mean/std error) of a program before and after compensation, on the simulated robot",
        description="Run the targets of ORIGINAL and of COMPENSATED (the same program with changed numbers; "
        "targets correspond row by row) through the simulated robot and print the method's Table 2: "
        "max / min / mean / std of the positioning error before and after compensation.",
        epilog=EXAMPLES,
    )
    p.add_argument("original", metavar="ORIGINAL", help="the program as written (.src/.dat or pose list)")
    p.add_argument("compensated", metavar="COMPENSATED", help="the same program after `postproc compensate`")
    p.add_argument("--robot", metavar="FILE", help="robot description with [errors] (default models/kr500.toml)")
    p.add_argument("--robot-seed", type=int, metavar="S",
                   help="draw another robot (default: the file's calibrated one)")
    p.add_argument("--config", metavar="CONFIG_DAT", help="$config.dat with BASE_DATA / TOOL_DATA")
    add_frame_arguments(p, settings=False)
    p.add_argument("--seed", type=int, default=0, metavar="S", help="measurement noise seed (default 0)")
    p.add_argument("--no-noise", action="store_true", help="exact positions: no tracker noise, no repeatability")
    p.add_argument("--json", action="store_true", help="print the figures as JSON on stdout")
    from ..acceptance.verdict import add_limit_arguments

    add_limit_arguments(p)
    p.add_argument("--verdict", metavar="VERDICT.json", help="write the pass/fail verdict (limits, checks, figures, "
                   "inputs' sha256; schema postproc/schemas/verdict.schema.json) for a CI job to gate on")
    p.add_argument("--model", metavar="M", help="the model the program was compensated with (its name and sha256 "
                   "go into the verdict; the figures do not depend on it)")
    p.set_defaults(run=run)


def _fill(poses, program, attitude, name: str):
    """Missing components take the previous target's (KRL: the current position's); a missing
    orientation before any is known takes the working attitude. Returns (poses, notes)."""
    import numpy as np

    from ..core.diagnostics import P213, PostprocError

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
    (configuration.execution_kinds) and $TOOL (the simulated robot's tool where the program's is
    unknown) — the options of SimulatedRobot.verify. Both runs use the ORIGINAL's."""
    import numpy as np

    from ..core.diagnostics import P309, PostprocError
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


def _in_description(program, description):
    """Each frame of ``program`` in the simulated robot's description frame: through the
    description's ``controller_base`` for a program's targets (a UR description in ROS's
    base_link: URScript's base is turned 180° about Z), a pose list's rows unless they say
    '# frame: controller' taken as they are (as findings.model_bases does for a model)."""
    import numpy as np

    from ..core.frames import frame_to_matrix

    base = frame_to_matrix(np.asarray(description.controller_base, float))
    if not program.in_controller_base or np.array_equal(base, np.eye(4)):
        return None
    return [base @ f.base for f in program.frames]


def _pair(args, description):
    """The two programs read and matched target by target: (original, compensated, their poses of
    the targets with a known frame, in the simulated robot's description frame, those rows, how
    many were skipped, notes); P601 where they are not one program."""
    import numpy as np

    from ..core.diagnostics import P601, PostprocError
    from ..programs.base_poses import robot_base_poses
    from ..programs.io import load_program
    from .compensate import stated_frames

    active = stated_frames(args)  # (as the program was compensated)
    from ..robot.external import units_of

    units = units_of(description)
    if units:  # the simulated cell's track / turntable: where the robot and the part really are
        from dataclasses import replace

        from ..programs import ActiveFrames

        active = ActiveFrames(external=units) if active is None else replace(active, external=units)
    original = load_program(args.original, args.config, active=active)
    compensated = load_program(args.compensated, args.config, active=active)
    p_orig, ok_orig = robot_base_poses(original, _in_description(original, description))
    p_comp, ok_comp = robot_base_poses(compensated, _in_description(compensated, description))
    if len(p_orig) != len(p_comp):
        raise PostprocError(f"ORIGINAL has {len(p_orig)} targets, COMPENSATED has {len(p_comp)}: they must be the "
                            "same program with changed numbers", args.compensated, code=P601)
    if len(p_orig) == 0:
        raise PostprocError("no Cartesian targets in this program", args.original, code=P601)
    notes = []
    keep = ok_orig & ok_comp
    if not keep.all():
        notes.append(f"{int((~keep).sum())} target(s) skipped: their frame is not known statically "
                     f"(run with --config $config.dat, --base / --tool?)")
    if not keep.any():
        raise PostprocError("no target with a known frame to verify", args.original, code=P601)
    return original, compensated, p_orig[keep], p_comp[keep], np.flatnonzero(keep), int((~keep).sum()), notes


def _check_reach(sim, programs, rows, options) -> None:
    """P335 at the first target of either program the simulated robot cannot reach."""
    import numpy as np

    from ..core.diagnostics import P335, PostprocError

    for program, poses, label in programs:
        ok = sim.reachable_in(poses, **options)
        if not ok.all():
            bad = np.flatnonzero(~ok)
            r, t = rows[bad[0]], program.targets
            more = f" (and {len(bad) - 1} more)" if len(bad) > 1 else ""
            raise PostprocError(f"{label} target out of reach of {sim.robot.name}: "
                                f"{np.round(poses[bad[0]], 3).tolist()}{more}",
                                program.files[t.file[r]], int(t.line[r]), int(t.col[r]), P335)


def _print_table(result: dict, n: int, sim, noise: bool) -> None:
    which = "default robot" if sim.is_default else "drawn robot"
    print(f"Positioning error (mm) of {n} targets on {sim.robot.name}, seed {sim.seed} ({which})"
          f"{'' if noise else ', no noise'}")
    print(f"{'':12s}{'max':>9s}{'min':>9s}{'mean':>9s}{'std':>9s}{'p95':>9s}")
    for label in ("before", "after"):
        s = result[label]
        print(f"{label:12s}{s['max']:9.3f}{s['min']:9.3f}{s['mean']:9.3f}{s['std']:9.3f}{s['p95']:9.3f}")
    print("Orientation error (deg)")
    for label in ("before", "after"):
        s = result["orientation_" + label]
        print(f"{label:12s}{s['max']:9.4f}{s['min']:9.4f}{s['mean']:9.4f}{s['std']:9.4f}{s['p95']:9.4f}")


def run(args) -> int:
    import json

    import numpy as np

    from ..calibration.simulator import SimulatedRobot
    from ..core.diagnostics import EXIT_FINDINGS

    sim = SimulatedRobot.from_file(args.robot, args.robot_seed)
    original, compensated, p_orig, p_comp, rows, skipped, notes = _pair(args, sim.description)
    attitude = np.asarray(sim.description.workspace.get("attitude", (0.0, 90.0, 0.0)), float)
    p_orig, n1 = _fill(p_orig, original, attitude, "ORIGINAL")
    p_comp, n2 = _fill(p_comp, compensated, attitude, "COMPENSATED")
    notes += n1 + n2
    options = execution(original, rows, sim)
    _check_reach(sim, ((original, p_orig, "ORIGINAL"), (compensated, p_comp, "COMPENSATED")), rows, options)
    from ..acceptance.verdict import Limits, failed_lines, model_entry, verdict

    limits = Limits.of(args)
    if args.verdict:
        from ..core.outputs import check_outputs

        check_outputs([args.verdict], [args.original, args.compensated])
    result = sim.verify(p_orig, p_comp, rng_seed=args.seed, noise=not args.no_noise, **options)
    model = None
    if args.model:
        from ..model.compensator import load_model

        model = load_model(args.model)
    document = verdict("verify", limits, {"before": result["before"], "after": result["after"],
                                          "orientation_before": result["orientation_before"],
                                          "orientation_after": result["orientation_after"], "targets": int(len(p_orig))},
                       model_entry(model), {"original": args.original, "compensated": args.compensated})
    failed = not document["passed"]
    figures = {
        "targets": int(len(p_orig)),
        "skipped": skipped,
        "robot": sim.robot.name,
        "robot_seed": sim.seed,
        "default_robot": sim.is_default,
        "noise": not args.no_noise,
        "before": result["before"],
        "after": result["after"],
        "orientation_before_deg": result["orientation_before"],
        "orientation_after_deg": result["orientation_after"],
    }
    # the targets COMPENSATED changes (the others were left as written and keep their error)
    changed = np.abs(p_comp[:, :3] - p_orig[:, :3]).max(axis=1) > 1e-6
    from ..core.stats import table2

    figures["compensated"] = int(changed.sum())
    figures["after_compensated"] = table2(result["errors_after"][changed])
    if limits.stated:
        figures.update(limits.stated)
        figures["passed"] = not failed
    if args.verdict:
        from pathlib import Path

        from ..core.outputs import write

        write([(Path(args.verdict), json.dumps(document, indent=2) + "\n")])
    if not args.quiet:
        for note in notes:
            print(f"postproc: warning: {note}", file=sys.stderr)
    if args.json:
        print(json.dumps(figures, indent=2))
    else:
        _print_table(result, len(p_orig), sim, figures["noise"])
    if not args.quiet:
        gate = "" if not limits.stated else (f"; FAILED: {'; '.join(failed_lines(document))}" if failed
                                             else "; within the limits stated")
        a = result["after"]
        left = len(changed) - figures["compensated"]
        of = "" if not left else (f"; the {figures['compensated']} targets changed: mean "
                                  f"{figures['after_compensated']['mean']:.3f}, max "
                                  f"{figures['after_compensated']['max']:.3f} mm, {left} left as written")
        print(f"postproc: verify: mean error {result['before']['mean']:.3f} → {a['mean']:.3f} mm "
              f"(after: p95 {a['p95']:.3f}, max {a['max']:.3f} mm{of}){gate}", file=sys.stderr)
    return EXIT_FINDINGS if failed else 0

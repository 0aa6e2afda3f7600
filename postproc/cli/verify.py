"""postproc verify: run an original and a compensated program on the simulated robot, print Table 2."""
from __future__ import annotations

import sys

from .settings import ROBOT_HELP, add, settings_of

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
    add(p, "robot", helps={"robot": ROBOT_HELP + ", with [errors] (default models/kr500.toml)"})
    p.add_argument("--robot-seed", type=int, metavar="S",
                   help="draw another robot (default: the file's calibrated one)")
    add(p, "config", "base", "tool", "robroot", "external", "load", "payloads",
        helps={"config": "$config.dat with BASE_DATA / TOOL_DATA (the one the programs were compensated with)"})
    p.add_argument("--seed", type=int, default=0, metavar="S", help="measurement noise seed (default 0)")
    p.add_argument("--no-noise", action="store_true", help="exact positions: no tracker noise, no repeatability")
    p.add_argument("--json", action="store_true", help="print the figures as JSON on stdout")
    add(p, "max_mean", "max_p95", "max_max", "max_orientation_mean")
    p.add_argument("--verdict", metavar="VERDICT.json", help="write the pass/fail verdict (limits, checks, figures, "
                   "inputs' sha256; schema postproc/schemas/verdict.schema.json) for a CI job to gate on")
    add(p, "model", helps={"model": "the model the program was compensated with (its name and sha256 go into the "
                           "verdict; the figures do not depend on it)"})
    p.set_defaults(run=run)


def _print_table(result: dict, n: int, sim, noise: bool, orientation_corrected: bool = True) -> None:
    which = "default robot" if sim.is_default else "drawn robot"
    print(f"Positioning error (mm) of {n} targets on {sim.robot.name}, seed {sim.seed} ({which})"
          f"{'' if noise else ', no noise'}")
    print(f"{'':12s}{'max':>9s}{'min':>9s}{'mean':>9s}{'std':>9s}{'p95':>9s}")
    for label in ("before", "after"):
        s = result[label]
        print(f"{label:12s}{s['max']:9.3f}{s['min']:9.3f}{s['mean']:9.3f}{s['std']:9.3f}{s['p95']:9.3f}")
    print("Orientation error (deg)" + ("" if orientation_corrected else
          ": not corrected — COMPENSATED keeps every orientation as written (position only; compensate "
          "--orientation corrects it with a model that has rotation_error)"))
    for label in ("before", "after"):
        s = result["orientation_" + label]
        print(f"{label:12s}{s['max']:9.4f}{s['min']:9.4f}{s['mean']:9.4f}{s['std']:9.4f}{s['p95']:9.4f}")


def run(args) -> int:
    import json

    from ..acceptance.verdict import failed_lines
    from ..acceptance.verify import verify
    from ..core.diagnostics import EXIT_FINDINGS

    settings = settings_of(args)
    if args.verdict:
        from ..core.outputs import check_outputs

        check_outputs([args.verdict], [args.original, args.compensated])
    found = verify(args.original, args.compensated, settings, robot_seed=args.robot_seed, seed=args.seed,
                   noise=not args.no_noise)
    figures, result, document = found.figures, found.result, found.document
    if args.verdict:
        from pathlib import Path

        from ..core.outputs import write

        write([(Path(args.verdict), json.dumps(document, indent=2) + "\n")])
    if not args.quiet:
        for note in found.notes:
            print(f"postproc: warning: {note}", file=sys.stderr)
    if args.json:
        print(json.dumps(figures, indent=2))
    else:
        _print_table(result, found.targets, found.sim, figures["noise"], figures["orientation_corrected"])
    if not args.quiet:
        gate = "" if not settings.acceptance.stated else (
            f"; FAILED: {'; '.join(failed_lines(document))}" if not found.passed else "; within the limits stated")
        a = result["after"]
        left = figures["targets"] - figures["compensated"]
        of = "" if not left else (f"; the {figures['compensated']} targets changed: mean "
                                  f"{figures['after_compensated']['mean']:.3f}, max "
                                  f"{figures['after_compensated']['max']:.3f} mm, {left} left as written")
        print(f"postproc: verify: mean error {result['before']['mean']:.3f} → {a['mean']:.3f} mm "
              f"(after: p95 {a['p95']:.3f}, max {a['max']:.3f} mm{of}){gate}", file=sys.stderr)
    return 0 if found.passed else EXIT_FINDINGS

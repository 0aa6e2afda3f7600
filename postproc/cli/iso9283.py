"""The ISO 9283 routes of ``postproc plan --iso9283`` and ``postproc report --iso9283``:
argument mapping and output only (the test lives in postproc/acceptance/iso9283.py, the certificate in
postproc/acceptance/certificate.py)."""
from __future__ import annotations

import sys


def run_plan(args, description, box, attitude) -> int:
    from pathlib import Path

    from ..acceptance.iso9283 import IsoCube, iso_plan_csv_text, iso_test
    from ..calibration.planning import krl_measurement_program, round_poses
    from ..core.atomic import write_atomic
    from ..robot.arm import Robot

    robot = Robot(description)

    def reachable(poses):
        return robot.ik(round_poses(poses))[1]

    given = IsoCube(tuple(args.cube[:3]), float(args.cube[3])) if args.cube is not None else None
    cube, poses, numbers = iso_test(box, attitude, reachable, given, args.cycles)
    poses = round_poses(poses)
    outputs = [(Path(args.output), iso_plan_csv_text(poses, numbers))]
    if args.krl is not None:
        src = Path(args.krl)
        comment = (f"ISO 9283 pose test, cube centre {list(cube.centre)} side {cube.side:.3f} mm, "
                   f"{args.cycles} cycles P1 P5 P4 P3 P2")
        outputs.append((src, krl_measurement_program(poses, src.stem, robot, wait_s=args.wait, comment=comment)))
    write_atomic(outputs)
    if not args.quiet:
        written = " + ".join(str(p) for p, _ in outputs)
        print(f"postproc: {written}: ISO 9283 pose test, {args.cycles} cycles x 5 poses, cube centre "
              f"{', '.join(f'{v:g}' for v in cube.centre)} side {cube.side:.1f} mm"
              f"{' (given)' if given else ' (largest reachable in the box)'}, attitude "
              f"{' '.join(f'{v:g}' for v in attitude)}, all reachable by {robot.name}", file=sys.stderr)
    return 0


def run_report(args, model) -> int:
    from ..acceptance.certificate import write_certificate
    from ..acceptance.iso9283 import read_iso_result

    result = read_iso_result(args.measured, args.after)
    files = write_certificate(result, args.output, model)
    if not args.quiet:
        b = result.before
        line = f"postproc report: ISO 9283, {result.poses} poses, n {b.n.min()}..{b.n.max()}; AP max {b.ap.max():.3f} mm"
        if result.after is not None:
            line += f" -> {result.after.ap.max():.3f} mm after"
        print(line + f"; wrote {files['certificate_html']}", file=sys.stderr)
        if args.verbose:
            for role, path in files.items():
                print(f"  {role}: {path}", file=sys.stderr)
    return 0

"""postproc measure: the simulated laser tracker, run over a plan in visiting order."""
from __future__ import annotations

import sys

EXAMPLES = """examples:
  postproc measure plan.csv -o measured.csv                  (the default, calibrated robot)
  postproc measure plan.csv -o measured_s3.csv --robot-seed 3 --seed 1
  postproc measure plan.csv -o measured.csv --robot cell7.toml

Output header: x,y,z,a,b,c,x_meas,y_meas,z_meas (commanded TCP pose and measured TCP
position, mm/deg, robot base frame), rows in visiting order: what `postproc train` reads.
"""


def add_parser(sub, common, formatter) -> None:
    p = sub.add_parser(
        "measure",
        parents=[common],
        formatter_class=formatter,
        help="simulate measuring a plan with a laser tracker on the simulated robot",
        description="Run the poses of a CSV (any CSV with x,y,z,a,b,c columns) in order from HOME through the "
        "simulated robot (controller IK on the nominal model, then the real robot's errors: geometry, "
        "compliance, gear ripple, backlash) and write what the tracker reads (+ tracker noise and "
        "repeatability).",
        epilog=EXAMPLES,
    )
    p.add_argument("plan", metavar="PLAN_CSV", help="poses to visit, in order (header with x,y,z,a,b,c)")
    p.add_argument("-o", "--output", metavar="MEASURED_CSV", required=True, help="measurement CSV to write")
    p.add_argument("--robot", metavar="FILE", help="robot description with [errors] (default models/kr500.toml)")
    p.add_argument("--robot-seed", type=int, metavar="S",
                   help="draw another robot (default: the file's calibrated one)")
    p.add_argument("--seed", type=int, default=0, metavar="S", help="measurement noise seed (default 0)")
    p.set_defaults(run=run)


def run(args) -> int:
    import io
    from pathlib import Path

    import numpy as np

    from ..diagnostics import PostprocError
    from ..planning import read_pose_csv
    from ..progress import stages
    from ..outputs import check_outputs, write as write_atomic
    from ..simulator import CODE_REACH, SimulatedRobot
    from . import show_progress

    check_outputs([args.output], [args.plan, args.robot or "-"])
    with stages(["read plan", "draw robot", "controller IK", "simulate and measure", "write"], "measure",
                show_progress(args)) as stage:
        stage("read plan")
        poses, lines = read_pose_csv(args.plan)
        stage("draw robot")
        sim = SimulatedRobot.from_file(args.robot, args.robot_seed)
        stage("controller IK")
        ok = sim.reachable(poses)
        if not ok.all():
            bad = np.flatnonzero(~ok)
            raise PostprocError(f"pose out of reach of {sim.robot.name}: {poses[bad[0]].tolist()}"
                                + (f" (and {len(bad) - 1} more)" if len(bad) > 1 else ""),
                                args.plan, int(lines[bad[0]]), 1, CODE_REACH)
        stage("simulate and measure")
        measured = sim.measure(poses, rng_seed=args.seed)
        buf = io.StringIO()
        np.savetxt(buf, np.hstack([poses, measured]), fmt=["%.10g"] * 6 + ["%.4f"] * 3, delimiter=",",
                   header="x,y,z,a,b,c,x_meas,y_meas,z_meas", comments="")
        stage("write")
        write_atomic([(Path(args.output), buf.getvalue())])
    if not args.quiet:
        e = np.linalg.norm(poses[:, :3] - measured, axis=1)
        which = "default" if sim.is_default else "drawn"
        print(f"postproc: {args.output}: {len(poses)} poses measured on {sim.robot.name} (robot seed {sim.seed}, "
              f"{which}), noise seed {args.seed}; measured vs commanded (the rows' x,y,z): mean {e.mean():.3f} "
              f"max {e.max():.3f} mm (of a compensated plan: the commands moved on purpose; its error against "
              "the original targets is `postproc report before.csv --after after.csv`)", file=sys.stderr)
    return 0

"""postproc measure: the simulated laser tracker, run over a plan in visiting order."""
from __future__ import annotations

import sys

from .settings import ROBOT_HELP, add

EXAMPLES = """examples:
  postproc measure plan.csv -o measured.csv                  (the default, calibrated robot)
  postproc measure plan.csv -o measured_s3.csv --robot-seed 3 --seed 1
  postproc measure plan.csv -o measured.csv --robot cell7.toml

Output header: x,y,z,a,b,c,x_meas,y_meas,z_meas,a_meas,b_meas,c_meas,q1..q6 (commanded TCP
pose, measured TCP pose (a 6-DOF probe), the controller's joint angles; mm/deg, robot base
frame), rows in visiting order: what `postproc train` reads (after `# simulated: ROBOT` and
`# robot_seed: S` lines: a model trained on them says it is a demonstration model of a simulated
robot). A plan with s,t columns is run in
those configurations (s,t copied to the output); with --tool the output starts with
`# tool: X,Y,Z,A,B,C`. With --tool given two or more times the plan is measured in as many
consecutive parts, one tool each (the tool changed between them), and each row names its TCP
in columns tool_x..tool_c: data that separate the tool mount's rotation (`postproc train`);
a plan with tool_x..tool_c columns (`postproc plan --tool A --tool B`) is measured with them.
A plan's load_mass..load_cz columns (`postproc plan --load`) are the load carried at each row:
simulated (the robot deflects under it) and copied to the output, which `postproc train`
identifies the compliance under; --load MASS[,CX,CY,CZ] given once or more measures the plan
with that load, or in as many parts, one load each. A plan's pose,cycle columns (`postproc plan --iso9283`) are copied to the output, so that
`postproc report --iso9283` names the poses P1..P5 as the plan does.
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
    add(p, "robot", helps={"robot": ROBOT_HELP + ", with [errors] (default models/kr500.toml)"})
    p.add_argument("--robot-seed", type=int, metavar="S",
                   help="draw another robot (default: the file's calibrated one)")
    p.add_argument("--seed", type=int, default=0, metavar="S", help="measurement noise seed (default 0)")
    p.add_argument("--tool", metavar="X,Y,Z,A,B,C", action="append",
                   help="the TCP on the flange measured (default the description's [tool]); give it two or three "
                   "times to measure the plan in as many parts, one per tool")
    p.add_argument("--load", metavar="MASS[,CX,CY,CZ]", action="append",
                   help="the load carried (kg; centre of mass mm in the flange frame, default 0,0,0; default load: the description's [payload]); two or three times: the plan in as "
                   "many parts, one load each (output columns load_mass..load_cz)")
    p.set_defaults(run=run)


def run(args) -> int:
    from pathlib import Path

    import numpy as np

    from ..calibration.planning import in_parts, parse_load, read_plan
    from ..calibration.simulator import SimulatedRobot
    from ..core.diagnostics import P320, P335, PostprocError
    from ..core.outputs import check_outputs, write
    from ..core.progress import stages
    from ..measurements.csv import LOAD_COLUMNS, TOOL_COLUMNS, measurement_csv, parse_tool
    from ..robot.description import robot_description
    from . import show_progress

    check_outputs([args.output], [args.plan, args.robot or "-"])
    with stages(["read plan", "draw robot", "controller IK", "simulate and measure", "write"], "measure",
                show_progress(args)) as stage:
        stage("read plan")
        plan = read_plan(args.plan)
        poses, lines, config, labels = plan.poses, plan.lines, plan.config, plan.labels
        given = [parse_tool(t) for t in args.tool or []]
        planned = plan.metadata.get("tool")  # (plan --tool with one tool: '# tool: X,Y,Z,A,B,C')
        if planned is not None:
            tool = parse_tool(planned)
            if given and not (len(given) == 1 and np.allclose(given[0], tool)):
                raise PostprocError(f"the plan is measured with the tool {planned} ('# tool:' line): --tool "
                                    f"{' '.join(args.tool)} would contradict it", args.plan, 1, 1, P320)
            given = [tool]
        stage("draw robot")
        sim = SimulatedRobot(robot_description(args.robot), args.robot_seed)
        tools = plan.tools
        if tools is not None and given:
            raise PostprocError("the plan names each row's tool (tool_x..tool_c): --tool would contradict it",
                                args.plan, code=P320)
        if given:  # consecutive parts of the plan, one tool each
            tools = in_parts(len(poses), given)
        several = tools is not None and len(np.unique(tools, axis=0)) > 1
        loads = plan.loads
        if loads is not None and args.load:
            raise PostprocError("the plan names each row's load (load_mass..load_cz): --load would contradict it",
                                args.plan, code=P320)
        if args.load:
            loads = in_parts(len(poses), [parse_load(t) for t in args.load])
        stage("controller IK")
        ok = sim.reachable_in(poses, config, tools)
        if not ok.all():
            bad = np.flatnonzero(~ok)
            raise PostprocError(f"pose out of reach of {sim.robot.name}: {poses[bad[0]].tolist()}"
                                + (f" (and {len(bad) - 1} more)" if len(bad) > 1 else ""),
                                args.plan, int(lines[bad[0]]), 1, P335)
        stage("simulate and measure")
        q = sim.joint_angles(poses, config, tools)
        measured = sim.measure(poses, rng_seed=args.seed, orientation=True, q_deg=q, tools=tools, loads=loads)
        extra = {name: measured[:, 3 + k] for k, name in enumerate(("a_meas", "b_meas", "c_meas"))}
        extra |= {f"q{k + 1}": q[:, k] for k in range(6)}
        fmt = ["%.10g"] * 6 + ["%.4f"] * 3 + ["%.5f"] * 3 + ["%.6f"] * 6
        if config is not None:
            extra |= {"s": config[:, 0], "t": config[:, 1]}
            fmt += ["%d", "%d"]
        if several:
            extra |= {name: tools[:, k] for k, name in enumerate(TOOL_COLUMNS)}
            fmt += ["%.10g"] * 6
        if loads is not None:  # (the load at each row: what train identifies the compliance under)
            extra |= {name: loads[:, k] for k, name in enumerate(LOAD_COLUMNS)}
            fmt += ["%.10g"] * 4
        extra |= labels  # an ISO 9283 plan's pose,cycle: the report names the poses as the plan does
        fmt += ["%d"] * len(labels)
        # (what a model trained on these rows is: a demonstration model of a simulated robot, its card says)
        metadata = {"simulated": sim.robot.name, "robot_seed": str(sim.seed)}
        if tools is not None and not several:
            metadata["tool"] = ",".join(f"{v:g}" for v in tools[0])
        text = measurement_csv(poses, measured[:, :3], extra, metadata, fmt)
        measured = measured[:, :3]
        stage("write")
        write([(Path(args.output), text)])
    if not args.quiet:
        e = np.linalg.norm(poses[:, :3] - measured, axis=1)
        which = "default" if sim.is_default else "drawn"
        print(f"postproc: {args.output}: {len(poses)} poses measured on {sim.robot.name} (robot seed {sim.seed}, "
              f"{which}), noise seed {args.seed}; measured vs commanded (the rows' x,y,z): mean {e.mean():.3f} "
              f"max {e.max():.3f} mm (of a compensated plan: the commands moved on purpose; its error against "
              "the original targets is `postproc report before.csv --after after.csv`)", file=sys.stderr)
    return 0

"""postproc plan: a Latin hypercube measurement plan (CSV) and its KRL measurement program."""
from __future__ import annotations

import sys

from .settings import ROBOT_HELP, add

EXAMPLES = """examples:
  postproc plan -n 2000 --seed 0 -o plan.csv --krl measure.src
  postproc plan -n 2000 --robot models/r2000ic.toml --wrist both -o plan.csv --ls measure.ls   (FANUC: CONFIG strings)
  postproc plan -n 500 --box 1800 2200 -400 400 600 1200 --attitude 0 90 0 --range 5 -o small.csv
  postproc plan -n 2000 --robot cell7.toml -o plan.csv        (box/attitude from its [workspace])
  postproc plan --iso9283 -o iso.csv --krl iso.src             (ISO 9283 pose test, 30 cycles)
  postproc plan --iso9283 --cube 2000 0 900 400 --cycles 10 -o iso.csv
  postproc plan -n 600 -o plan.csv --krl m.src --tool 300,0,75,0,0,0 --tool 450,0,75,0,0,0 --tool 300,0,200,0,0,0
                                                               (three tools: the plan in three parts)
  postproc plan -n 600 -o plan.csv --krl m.src --load 0 --load 300,220,0,40
                                                               (two test loads: the plan in two parts)
  postproc plan --for part1.src part2.mod -n 300 -o plan.csv --krl m.src   (for the programs that will run)
  postproc plan --for part1.src --data measured.csv -o more.csv   (what the data does not cover: P337; more poses)

The plan is the visiting order: `postproc measure plan.csv -o measured.csv` simulates it,
the KRL program drives a real robot through it (LIN, settle, $OUT[1] to the tracker, wait
for $IN[1]). Poses the nominal robot cannot reach are refused (exit 2, nothing written).
"""


def add_parser(sub, common, formatter) -> None:
    p = sub.add_parser(
        "plan",
        parents=[common],
        formatter_class=formatter,
        help="Latin hypercube measurement plan (CSV) and KRL measurement program",
        description="Draw N poses by Latin hypercube sampling (scipy.stats.qmc, seeded): positions in a box, "
        "A/B/C within ±range of a working attitude; write them as plan CSV (x,y,z,a,b,c, in visiting order) "
        "and optionally as a runnable KRL measurement program. Defaults: the robot's [workspace] "
        "(KR500-sim: X 1700..2300, Y -600..600, Z 500..1300 mm, A 0 B 90 C 0 ± 10°).",
        epilog=EXAMPLES,
    )
    p.add_argument("-n", "--poses", type=int, default=None, metavar="N",
                   help="number of poses (default 2000; with --for 300)")
    p.add_argument("--seed", type=int, default=0, help="Latin hypercube seed (default 0)")
    p.add_argument("--box", type=float, nargs=6, metavar=("X0", "X1", "Y0", "Y1", "Z0", "Z1"),
                   help="position box in the robot base frame, mm")
    p.add_argument("--attitude", type=float, nargs=3, metavar=("A", "B", "C"), help="working attitude, deg")
    p.add_argument("--range", type=float, metavar="DEG", help="± range of each of A, B, C around the attitude")
    add(p, "robot", "config", "base", "robroot", "external", "registers",
        helps={"robot": ROBOT_HELP + " (default models/kr500.toml)"})
    p.add_argument("-o", "--output", metavar="PLAN_CSV", required=True, help="plan CSV to write")
    p.add_argument("--krl", metavar="SRC", help="also write a KRL measurement program (.src, module named after it)")
    p.add_argument("--ls", metavar="LS", help="also write a FANUC LS measurement program (.ls, program named after it): "
                   "J to each pose with the CONFIG string of its configuration (docs/CONFIGURATIONS.md), UF 0, UT 1 = "
                   "the plan's tool; for a FANUC-type description")
    p.add_argument("--wrist", choices=("home", "both"),
                   help="state each pose's configuration (s,t columns; KRL: PTP with S/T): 'home' = the branch "
                   "nearest HOME, 'both' = half the poses (rows 2, 3 of every four) in the flipped-wrist configuration")
    p.add_argument("--tool", metavar="X,Y,Z,A,B,C", action="append",
                   help="the TCP on the flange the plan is measured with (default the description's [tool]): $TOOL "
                   "of the KRL program and the reach check; two or three times: the plan in as many consecutive "
                   "parts, one tool each (columns tool_x..tool_c; KRL: HOME and HALT to change the tool between "
                   "them), data that separate the tool mount's rotation (README: Any tool); with --for: the $TOOL of "
                   "programs that do not set it, as compensate takes it")
    p.add_argument("--load", metavar="MASS[,CX,CY,CZ]", action="append",
                   help="a test load the plan is measured with (kg; its centre of mass, mm in the flange frame, "
                   "default 0,0,0: at the flange, as compensate --load); give it two or three times to measure the plan in as "
                   "many parts, one load each (columns load_mass..load_cz; KRL: HOME and HALT to change the load, "
                   "$LOAD set): data from which train identifies what loads do")
    p.add_argument("--wait", type=float, default=1.0, metavar="S",
                   help="settling time before each measurement (default 1 s)")
    progs = p.add_argument_group("a plan for the programs that will run (instead of the Latin hypercube)")
    progs.add_argument("--for", dest="programs", nargs="+", metavar="PROGRAM",
                       help="programs (any dialect compensate reads): poses covering the joint arcs, arm configurations "
                       "and tools they use, each configuration x tool at least 20 %% of the plan, half space-filling, "
                       "half chosen for observability (D-optimal over the identification's Jacobian); s,t columns "
                       "(and tool_x..tool_c for several tools)")
    progs.add_argument("--data", metavar="MEASURED_CSV",
                       help="with --for: measurements already made: the design counts them, and the targets they do not "
                       "cover are named (P337 at each)")
    iso = p.add_argument_group("ISO 9283 pose test (instead of the Latin hypercube)")
    iso.add_argument("--iso9283", action="store_true",
                     help="the standard's pose test: P1..P5 in the diagonal plane of the largest cube of the box "
                     "(reachable), cycles P1 P5 P4 P3 P2 at the working attitude; CSV gets pose,cycle columns")
    iso.add_argument("--cube", type=float, nargs=4, metavar=("CX", "CY", "CZ", "SIDE"),
                     help="a given test cube (centre and side, mm) instead of the largest one")
    iso.add_argument("--cycles", type=int, default=30, metavar="N", help="cycles (the standard: 30)")
    p.set_defaults(run=run)


def run(args) -> int:
    from pathlib import Path

    import numpy as np

    from ..calibration.planning import (
        DEFAULT_ATTITUDE,
        DEFAULT_BOX,
        DEFAULT_RANGE,
        krl_measurement_program,
        latin_hypercube,
        plan_configurations,
        plan_csv_chunks,
        reachable,
        round_poses,
    )
    from ..core.diagnostics import P335, P512, PostprocError
    from ..core.outputs import check_outputs, write
    from ..core.progress import stages
    from ..measurements.csv import parse_tool
    from ..robot.arm import Robot
    from ..robot.description import robot_description
    from . import show_progress

    check_outputs([args.output, args.krl or "-", args.ls or "-"], [args.robot or "-"])
    description = robot_description(args.robot)
    tools = [parse_tool(t) for t in args.tool or []]
    if tools:
        description = description.replace(tool=tools[0], tool_name=f"$TOOL {args.tool[0]}")
    ws = description.workspace
    box = args.box if args.box is not None else ws.get("box", DEFAULT_BOX)
    attitude = args.attitude if args.attitude is not None else ws.get("attitude", DEFAULT_ATTITUDE)
    range_deg = args.range if args.range is not None else ws.get("range", DEFAULT_RANGE)
    if args.krl is not None and Path(args.krl).suffix.lower() != ".src":
        raise PostprocError(f"--krl {args.krl}: a KRL program is a .src file", code=P512)
    if args.ls is not None and (Path(args.ls).suffix.lower() != ".ls" or description.configuration != "fanuc"):
        raise PostprocError(f"--ls {args.ls}: an LS program is a .ls file, for a robot whose description states FANUC "
                            "configurations ([robot] configuration = \"fanuc\", e.g. models/r2000ic.toml)", code=P512)
    if args.ls is not None and (args.iso9283 or len(tools) > 1):
        raise PostprocError("--ls writes a Latin-hypercube plan measured with one tool", code=P512)
    from ..calibration.planning import in_parts, parse_load

    loads = [parse_load(t) for t in args.load or []]
    if loads and (args.programs or args.iso9283 or args.ls is not None or len(tools) > 1):
        raise PostprocError("--load plans a Latin-hypercube campaign at test loads (CSV and --krl), with one tool: "
                            "leave out --for, --iso9283, --ls and a second --tool", code=P512)
    if args.programs:
        return _run_for(args, description)
    if args.data:
        raise PostprocError("--data goes with --for (the programs the plan is for)", code=P512)
    args.poses = 2000 if args.poses is None else args.poses
    if args.iso9283:
        from .iso9283 import run_plan

        if len(tools) > 1:
            raise PostprocError("the ISO 9283 pose test is measured with one tool: give --tool once", code=P512)
        return run_plan(args, description, box, attitude)
    with stages(["sample", "reach check (IK)", "write"], "plan", show_progress(args)) as stage:
        stage("sample")
        poses = round_poses(latin_hypercube(args.poses, box, attitude, range_deg, args.seed))
        robot = Robot(description)
        stage("reach check (IK)")
        rows = in_parts(len(poses), tools) if len(tools) > 1 else None
        config = None if args.wrist is None else np.zeros((len(poses), 2), np.int64)
        ok = np.zeros(len(poses), bool)
        for k, tool in enumerate(tools if rows is not None else [robot.tool]):  # each part with its own tool
            part = np.arange(len(poses)) if rows is None else np.flatnonzero((rows == tool).all(axis=1))
            arm = robot if k == 0 else Robot(description.replace(tool=tool))
            if args.wrist is not None:
                config[part], ok[part] = plan_configurations(arm, poses[part], args.wrist)
            else:
                ok[part] = reachable(arm, poses[part])
        if not ok.all():
            bad = np.flatnonzero(~ok)
            raise PostprocError(
                f"{len(bad)} of {len(poses)} poses are out of reach of {robot.name} with tool "
                f"{robot.tool_name if rows is None else rows[bad[0]].tolist()} "
                f"(first: pose {bad[0] + 1} = {poses[bad[0]].tolist()}); shrink --box or --range, or move the box",
                description.path, code=P335)
        stage("write")
        # (one tool: said in the plan, so that measure simulates the tool the program measures with)
        meta = {"tool": ",".join(f"{v:g}" for v in tools[0])} if len(tools) == 1 else None
        load_rows = in_parts(len(poses), loads) if loads else None
        outputs = [(Path(args.output), plan_csv_chunks(poses, config, tools=rows, metadata=meta, loads=load_rows))]
        if args.krl is not None:
            src = Path(args.krl)
            comment = (f"Latin hypercube seed {args.seed}, box {list(map(float, box))}, "
                       f"attitude {list(map(float, attitude))} +- {range_deg:g} deg")
            outputs.append((src, krl_measurement_program(poses, src.stem, robot, wait_s=args.wait, comment=comment,
                                                                  config=config, tools=rows, loads=load_rows)))
        if args.ls is not None:
            from ..calibration.planning import ls_measurement_program

            ls = Path(args.ls)
            outputs.append((ls, ls_measurement_program(poses, ls.stem, robot, wait_s=args.wait, config=config,
                                                       comment=f"postproc plan seed {args.seed}")))
        write(outputs)
    if not args.quiet:
        written = " + ".join(str(p) for p, _ in outputs)
        print(f"postproc: {written}: {len(poses)} poses (LHS seed {args.seed}) in X {box[0]:g}..{box[1]:g} "
              f"Y {box[2]:g}..{box[3]:g} Z {box[4]:g}..{box[5]:g} mm, A {attitude[0]:g} B {attitude[1]:g} "
              f"C {attitude[2]:g} ± {range_deg:g}°, all reachable by {robot.name}", file=sys.stderr)
    return 0


def _run_for(args, description) -> int:
    """``plan --for PROGRAMS``: arguments → ``plan_for`` → the plan CSV (and KRL program), the
    coverage findings printed."""
    from pathlib import Path

    import numpy as np

    from ..calibration.plan_for import (
        coverage,
        listed,
        plan_for,
        program_targets,
        read_data,
    )
    from ..calibration.planning import krl_measurement_program, plan_csv_chunks
    from ..core.diagnostics import P512, PostprocError
    from ..core.outputs import check_outputs, write
    from ..robot.arm import Robot

    from ..programs.cell import load_programs
    from .settings import settings_of

    if args.iso9283 or args.wrist or (args.tool and len(args.tool) > 1):
        raise PostprocError("--for takes the configurations and tools from the programs: leave out --iso9283 and "
                            "--wrist, and give --tool once (the $TOOL of programs that do not set it, as compensate "
                            "takes it)", code=P512)
    check_outputs([args.output, args.krl or "-"], [*args.programs, args.data or "-"])
    n = 300 if args.poses is None else args.poses
    reading = settings_of(args, **({"tool": args.tool[0]} if args.tool else {})).reading
    programs = load_programs(args.programs, reading.config_list, reading.active, reading.registers, families=True)
    targets = program_targets(programs, description)
    modules = sum(not f.lower().endswith(".dat") for program in programs for f in program.files)  # (KRL: not .dat)
    data_q, data_tools = read_data(args.data, description) if args.data else (None, None)
    plan = plan_for(targets, description, n, args.seed, data_q, data_tools)
    several = len(np.unique(plan.tools, axis=0)) > 1
    tools = plan.tools if several else None
    meta = {"tool": ",".join(f"{v:g}" for v in plan.tools[0])} if not several and len(plan.tools) else None
    outputs = [(Path(args.output), plan_csv_chunks(plan.poses, plan.config, tools=tools, metadata=meta))]
    robot = Robot(description if several else description.replace(tool=plan.tools[0]))
    if args.krl is not None:
        src = Path(args.krl)
        comment = f"for {modules} program(s), {len(targets)} targets, seed {args.seed}"
        outputs.append((src, krl_measurement_program(plan.poses, src.stem, robot, wait_s=args.wait, comment=comment,
                                                    config=plan.config, tools=tools)))
    write(outputs)
    coverage_rows = coverage(targets, description, data_q, data_tools) if args.data else []
    findings = [*targets.skipped, *listed(coverage_rows)]
    for d in findings:
        print(d.format(), file=sys.stderr)
    if not args.quiet:
        groups = ", ".join(f"S {int(k[0])} tool {[round(float(v), 3) for v in k[1:4]]}: {int((plan.group == g).sum())} "
                           f"poses for {int(c)} targets" for g, (k, c) in enumerate(zip(plan.keys, plan.targets_per_group)))
        uncovered = len(coverage_rows)
        print(f"postproc: {' + '.join(str(p) for p, _ in outputs)}: {len(plan.poses)} poses for {len(targets)} targets "
              f"of {modules} program(s) ({groups}); log det of the identification's information "
              f"{plan.log_det[0]:.1f} -> {plan.log_det[1]:.1f}"
              + (f"; {uncovered} target(s) the data does not cover (P337)" if args.data else ""), file=sys.stderr)
    return 0

"""``postproc train``: measurement CSV → a compensator ONNX file (the method: GPSO-DNN)."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

METHODS = ("hybrid", "kinematic", "dnn-joints", "gpso", "ga", "pso", "plain")  # see EXAMPLES; no torch import here
OPTIMIZERS = ("lm", "lbfgs", "adam", "momentum", "gd")

EXAMPLES = """\
Data: a CSV with the header x,y,z,a,b,c,x_meas,y_meas,z_meas (mm, deg, robot base frame):
the commanded TCP pose and the measured TCP position, one row per visited pose. The model
learns E = P_target − P_measured. Optional columns: a_meas,b_meas,c_meas (a 6-DOF probe's
TCP orientation: hybrid/kinematic then fit the orientation error too and the model outputs
rotation_error, for compensate --orientation), q1..q6 (the controller's joint angles) or,
without them, s,t (KUKA Status/Turn: the joint angles of that configuration). `--val-fraction` of the rows (drawn with --split-seed)
are held out and only scored on.

Methods: hybrid (the default: the robot's kinematics, compliance, backlash and gear ripple
identified on its nominal description --robot FILE.toml, default models/kr500.toml, plus
residual networks on the joint angles when they help on held-back rows; the visiting order
of the rows gives the approach directions, and the model takes previous_pose), kinematic
(the identification alone), dnn-joints (no identification: an ensemble of MLPs on the
nominal joint angles and approach directions), gpso (the method of Hu, Hua & Tian: GPSO-searched initial weights
of a pose-only MLP, then backprop), ga, pso, plain (random initial weights). Backprop
optimiser of the pose-only MLPs: lm (Levenberg–Marquardt, the default, as MATLAB's trainlm),
lbfgs, adam, momentum, gd (the method's lr 0.01).

Examples:
  postproc train measured.csv -o models/cell3.onnx --robot models/kr500.toml --name cell3
  postproc train measured.csv -o m.onnx --method gpso --seed 1
  postproc train ipa.csv --register --robot models/ur10.toml -o ur10.onnx --val-fraction 0.2
  postproc train measured.csv -o m.onnx --search        # pick the hidden layers first (minutes)
  postproc train new30.csv -o new.onnx --update old.onnx --robot models/ur10.toml  # re-calibrate
"""


def _hidden(text: str) -> tuple[int, ...]:
    try:
        values = tuple(int(v) for v in text.replace(" ", "").split(",") if v)
    except ValueError:
        values = ()
    if not values or any(v < 1 for v in values):
        raise argparse.ArgumentTypeError(f"expected positive layer widths like 20,10,5, got {text!r}")
    return values


def _positive(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return value


def add_parser(sub, common, formatter) -> None:
    p = sub.add_parser(
        "train",
        parents=[common],
        formatter_class=formatter,
        help="learn an error model from measurements and write it as ONNX",
        description="Train the error model (identified kinematics + residual networks by default) on a measurement "
        "CSV and export it as a compensator.",
        epilog=EXAMPLES,
    )
    p.add_argument("data", metavar="DATA.csv", help="measurement CSV")
    p.add_argument("-o", "--output", required=True, metavar="MODEL.onnx", help="model file to write")
    p.add_argument("--method", choices=METHODS, default="hybrid", help="the model (default hybrid; see below)")
    p.add_argument("--hidden", type=_hidden, default=None, metavar="W,W,...",
                   help="hidden layer widths (default 20,10,5; hybrid's residual networks 32,32)")
    p.add_argument("--optimizer", choices=OPTIMIZERS, default=None, help="backprop optimiser (default lm)")
    p.add_argument("--search", action="store_true", help="search the hidden layers first (1-6 layers of 3-16 nodes; minutes)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="--search: fit the candidates as tasks on this Dask scheduler (postproc[fleet]; in a fleet: its own)")
    p.add_argument("--seed", type=int, default=0, metavar="S", help="seed of the training's random draws (default 0)")
    p.add_argument("--split-seed", type=int, default=0, metavar="S", help="seed of the validation draw (default 0)")
    p.add_argument("--val-fraction", type=float, default=0.05, metavar="F", help="rows held out for validation (default 0.05)")
    p.add_argument("--epochs", type=_positive, default=None, metavar="N",
                   help="backprop epochs at most (default 500; hybrid's residual networks 1500)")
    p.add_argument("--name", help="model name for the metadata (default: the output file's stem)")
    p.add_argument("--robot", metavar="NAME|FILE.toml", help="robot name, or its description file (adds reach and tool; "
                   "hybrid/kinematic: the nominal description to identify, default models/kr500.toml)")
    p.add_argument("--tool", metavar="X,Y,Z,A,B,C",
                   help="the TCP on the flange the data were measured with (default: the CSV's '# tool:' line or "
                   "tool_x..tool_c columns, else the robot description's tool)")
    p.add_argument("--pose-only", action="store_true",
                   help="hybrid/kinematic: ignore the visiting order (no backlash; the model takes the pose only)")
    p.add_argument("--update", metavar="OLD.onnx",
                   help="re-calibrate: re-fit OLD's base, joint zero offsets and tool on these rows (from as few as 30), "
                        "with OLD's values as prior; everything else is OLD's (its structure: --hidden, --epochs, "
                        "--pose-only do not apply); prints what moved")
    p.add_argument(
        "--register",
        action="store_true",
        help="measured columns are in a tracker's frame: fit the rigid tracker → base transform on the training rows",
    )
    p.set_defaults(run=run)


def _robot_metadata(robot: str | None) -> dict:
    """robot / reach / tool metadata from a robot description, when there is one to read."""
    from .train_hybrid import arm_metadata

    if not robot:
        return {}
    path = Path(robot)
    try:
        from ..robot import load_description
    except ImportError:  # robot description support (pin) not installed: the name only
        return {"robot": robot}
    if path.suffix == ".toml":
        description = load_description(path)
    else:
        default = load_description()
        if default.name != robot:
            return {"robot": robot}  # an unknown robot: record its name, claim no reach
        description = default
    return arm_metadata(description)


def run(args) -> int:
    import numpy as np

    from ..diagnostics import PostprocError
    from ..outputs import check_outputs
    from ..measurements import read_measurements
    from ..training.data import (check_errors, check_rotation_errors, check_size, envelope_of, measured_tools,
                                 split_indices)
    from . import show_progress
    from .train_hybrid import HYBRID_METHODS, run_hybrid

    check_outputs([args.output], [args.data, args.robot or "-", args.update or "-"])  # before the fit, not after it
    if args.update and args.method not in HYBRID_METHODS:
        raise PostprocError(f"--update re-fits an identified model: --method {args.method} identifies none "
                            f"(use hybrid or kinematic, or leave --method out)", args.update, code="P317")
    data = read_measurements(args.data)
    from ..planning import parse_tool

    tools = measured_tools(data, None if args.tool is None else parse_tool(args.tool))
    train_rows, val_rows = split_indices(len(data), args.val_fraction, args.split_seed)
    # a robot description is read before the long part, so that a typo fails fast
    # (hybrid methods read it themselves: it is the model, and may be an arm postproc.robot cannot solve)
    robot_meta = {} if args.method in HYBRID_METHODS else _robot_metadata(args.robot)
    poses, measured = data.poses, data.measured
    notes = []
    frame = data.meta.get("frame", "base").lower()
    if args.register:
        from ..registration import register_measurements

        mask = np.zeros(len(data), dtype=bool)
        mask[train_rows] = True
        measured, transform, rms = register_measurements(poses[:, :3], measured, mask)
        notes.append(f"registered tracker → base on {len(train_rows)} training rows (rms {rms:.3f} mm)")
        if data.orientation is not None:  # the probe's orientation turns with the tracker frame
            from ..frames import abc_from_rotation, rotation_from_abc

            data.orientation = abc_from_rotation(transform[:3, :3] @ rotation_from_abc(data.orientation))
    elif frame != "base":
        raise PostprocError(
            f"measured columns are in the {frame}'s frame ('# frame: {frame}'): train with --register",
            args.data,
            code="P507",
        )
    if data.holdout is not None and len(val_rows) and not data.holdout[val_rows].all():
        seen = int((~data.holdout[val_rows]).sum())
        notes.append(
            f"warning: {seen} validation row(s) were used by the file's registration (holdout = 0): "
            "the validation figures are optimistic; use the import's --split-seed and a smaller --val-fraction"
        )
    errors = poses[:, :3] - measured
    notes += check_errors(poses[:, :3], measured, data.lines, args.data)
    rotation_errors = data.rotation_errors
    if rotation_errors is not None:
        check_rotation_errors(rotation_errors, data.lines, args.data)
        if args.method not in ("hybrid", "kinematic"):
            notes.append(f"warning: --method {args.method} fits the position only: a_meas,b_meas,c_meas not used "
                         "(the model has no rotation_error output; compensate --orientation refuses it)")

    progress = show_progress(args)
    if args.method in HYBRID_METHODS:
        fitted = rotation_errors if args.method in ("hybrid", "kinematic") else None
        if fitted is not None and tools is not None and len(np.unique(tools, axis=0)) > 1:
            notes.append("warning: the orientation is fitted from data of one tool: with several tools "
                         "(tool_x..tool_c) a_meas,b_meas,c_meas are not used (no rotation_error output)")
            fitted = None
        return run_hybrid(args, data, errors, train_rows, val_rows, notes, progress, tools, fitted)
    if tools is not None:  # a pose → error map learns one TCP's error
        if len(np.unique(tools, axis=0)) > 1:
            raise PostprocError(f"--method {args.method} learns the error of one tool, the data have "
                                f"{len(np.unique(tools, axis=0))}: train --method hybrid (a physical model)",
                                args.data, code="P320")
        robot_meta["tool"] = {"name": f"$TOOL {','.join(f'{v:g}' for v in tools[0])}",
                              "frame": [round(float(v), 6) for v in tools[0]]}
    hidden = args.hidden or (20, 10, 5)
    args.epochs = args.epochs or 500
    if args.search:
        from ..fleet import task_map
        from ..training.search import format_table, search_structure

        try:
            with task_map(args.scheduler) as map_fn:
                result = search_structure(
                    poses[train_rows], errors[train_rows], args.method, args.optimizer, args.epochs, args.seed,
                    progress=progress, map_fn=map_fn,
                )
        except PostprocError as exc:
            exc.path = exc.path or args.data  # too few points for every candidate: say which file
            raise
        if not args.quiet:
            print(format_table(result))
        hidden = result.best

    from ..training import ErrorModel, accuracy_card
    from ..training.network import Structure

    structure = Structure(tuple(hidden))
    check_size(len(train_rows), structure.n_params, str(structure), args.data)
    model = ErrorModel(hidden, args.method, args.optimizer, args.epochs, seed=args.seed, progress=progress)
    model.fit(poses[train_rows], errors[train_rows])

    accuracy = accuracy_card(errors[val_rows], model.predict(poses[val_rows]), model.train_stats_["mean"],
                             len(train_rows))
    # c = P + Ê(c): iterations after which one more moves no training command by > 0.001 mm;
    # at least 2 (one more batched call is cheap insurance off the training poses)
    settled = model.fixed_point_iterations(poses[train_rows])
    iterations = max(2, settled)
    metadata = {
        "name": args.name or Path(args.output).stem,
        "robot": "",
        "envelope": envelope_of(poses),
        "data_sha256": data.sha256,
        "accuracy": accuracy,
        "iterations": iterations,
    }
    metadata.update(robot_meta)
    model.export_onnx(args.output, **metadata)

    if not args.quiet:
        for note in notes:
            print(note, file=sys.stderr)
        print(f"model     {args.output}  ({model.label}, structure {structure}, {structure.n_params} weights, "
              f"{model.fit_seconds_['total']:.1f} s, backprop stopped: {model.stopped_} after {len(model.losses_)} epochs)")
        print(f"data      {args.data}: {len(train_rows)} training rows, {len(val_rows)} validation rows; "
              f"fixed point settles after {settled} iteration(s), model card says {iterations}")
        print_figures(accuracy, model.train_stats_)
        print(f"postproc train: wrote {args.output}", file=sys.stderr)
    return 0


def print_figures(accuracy: dict, train_stats: dict) -> None:
    """The validation table train prints at the end (stdout), from the model card's figures."""
    if accuracy["n_val"]:
        a = accuracy
        print(f"{'|E| mm (validation)':<26} {'mean':>7} {'max':>7} {'std':>7}")
        print(f"{'uncompensated':<26} {a['val_uncompensated_mean_mm']:7.4f} {a['val_uncompensated_max_mm']:7.4f} "
              f"{a['val_uncompensated_std_mm']:7.4f}")
        print(f"{'residual |E − Ê|':<26} {a['val_mean_mm']:7.4f} {a['val_max_mm']:7.4f} {a['val_std_mm']:7.4f}")
    s = train_stats
    print(f"{'residual |E − Ê| (train)':<26} {s['mean']:7.4f} {s['max']:7.4f} {s['std']:7.4f}")

"""``postproc train --method hybrid|kinematic|dnn-joints``: the identified arm (+ residual
networks), or networks on the joint angles alone.

Called by :mod:`postproc.cli.train` after it has read, split and (``--register``) registered
the data; this part needs the robot's nominal description (``--robot FILE.toml``, default the
shipped models/kr500.toml), reads the controller's joint angles if the file has ``q1..q6``
columns (they pick the IK branch) and takes the visiting order from the row order.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

HYBRID_METHODS = ("hybrid", "kinematic", "dnn-joints")
DEFAULT_HIDDEN = {"hybrid": (32, 32), "kinematic": (32, 32), "dnn-joints": (64, 64)}  # the networks'
DEFAULT_EPOCHS = 1500
# dnn-joints: no identification, only the networks on the joint angles (+ approach signs)
SETTINGS = {"hybrid": {"residual": "auto"}, "kinematic": {"residual": "none"},
            "dnn-joints": {"residual": "always", "kinematic": {"groups": (), "ripple": []}}}


def _description(robot: str | None):
    from ..diagnostics import PostprocError
    from ..robot import load_description

    if robot and Path(robot).suffix == ".toml":
        return load_description(robot)
    default = load_description()
    if robot and robot != default.name:
        raise PostprocError(f"--method hybrid identifies the robot's kinematics: give its description file "
                            f"(--robot FILE.toml), not the name {robot!r}; or use --method gpso", code="P508")
    return default


def arm_metadata(description) -> dict:
    """robot / reach / tool for the model card. KUKA-type arms: postproc.robot's reach sphere;
    others: a conservative sphere about A2's origin on the A1 axis (every link after it laid end
    to end)."""
    import math

    from ..robot import Robot

    tool = {"name": description.tool_name, "frame": [round(float(v), 6) for v in description.tool]}
    try:
        reach = Robot(description).reach
    except Exception:  # not a KUKA-type arm: no closed-form IK in postproc.robot
        origins = np.array([j.origin[:3] for j in description.joints])
        centre = origins[0] + [0.0, 0.0, origins[1, 2]]
        flange = np.asarray(description.flange[:3])
        radius = (math.hypot(*origins[1, :2]) + float(np.linalg.norm(origins[2:], axis=1).sum())
                  + float(np.linalg.norm(flange)) + float(np.linalg.norm(description.tool[:3])))
        reach = {"center": [round(float(v), 3) for v in centre], "radius_min": 0.0, "radius_max": round(radius, 3)}
    return {"robot": description.name, "reach": reach, "tool": tool}


def run_hybrid(args, data, errors: np.ndarray, train_rows: np.ndarray, val_rows: np.ndarray, notes: list[str],
               progress: bool, tools: np.ndarray | None = None, rotation_errors: np.ndarray | None = None) -> int:
    """Fit, export and report a hybrid-family model; ``errors`` [N, 3] = E of ``data``'s rows
    (after any registration); ``tools`` [N, 6] the TCP each row was measured with (None: the
    description's); ``rotation_errors`` [N, 3] deg their orientation errors (None: no
    a_meas,b_meas,c_meas: the model then has no ``rotation_error`` output)."""
    from ..diagnostics import PostprocError
    from ..training import accuracy_card
    from ..training.features import previous_joints, previous_poses
    from ..training.hybrid import HybridModel
    from .train import print_figures

    description = _description(args.robot)
    if args.method == "dnn-joints" and tools is not None and len(np.unique(tools, axis=0)) > 1:
        raise PostprocError(f"--method dnn-joints learns the error of one tool, the data have "
                            f"{len(np.unique(tools, axis=0))}: train --method hybrid (a physical model)",
                            args.data, code="P320")
    poses = data.poses
    # rows in visiting order (the first came from HOME): the approach direction of each joint
    previous = None if args.pose_only else previous_poses(poses)
    from ..configuration import measurement_joints

    q_deg, stated, warnings = measurement_joints(description, data)
    notes += warnings
    if not stated.all():  # (the visiting order stays the file's: previous poses computed above)
        train_rows, val_rows = train_rows[stated[train_rows]], val_rows[stated[val_rows]]
    # where the arm really stood before each row (its configuration may differ from the row's)
    q_previous = None if previous is None else previous_joints(q_deg)
    rows = (lambda a, r: None if a is None else a[r])  # noqa: E731
    update = None
    if getattr(args, "update", None):
        from ..training.update import read_old_model, update_model

        if tools is not None and not np.allclose(tools, description.tool):
            raise PostprocError("--update re-fits a model at the tool it was measured with; these rows name "
                                "other tools (# tool: / tool_x..tool_c / --tool): train a new model", args.data,
                                code="P317")
        old = read_old_model(args.update, description)
        try:
            update = update_model(old, description, poses[train_rows], errors[train_rows],
                                  rows(previous_poses(poses), train_rows), rows(q_deg, train_rows))
        except PostprocError as exc:
            exc.path = exc.path or args.data  # too few rows: say which file
            raise
        model = update.model
        if rotation_errors is not None:
            notes.append("warning: --update re-fits the position only: a_meas,b_meas,c_meas not used (the "
                         "updated model has no rotation_error output)")
    else:
        model = HybridModel(
            description,
            hidden=args.hidden or DEFAULT_HIDDEN[args.method],
            epochs=args.epochs or DEFAULT_EPOCHS,
            seed=args.seed,
            progress=progress,
            **SETTINGS[args.method],
        )
        model.fit(poses[train_rows], errors[train_rows], rows(previous, train_rows), rows(q_deg, train_rows),
                  rows(tools, train_rows), rows(rotation_errors, train_rows), rows(q_previous, train_rows))

    if len(model.dropped_):
        lines = data.lines[train_rows][model.dropped_]
        notes.append(f"warning: {len(lines)} training row(s) left out, out of reach of the nominal {description.name} "
                     f"or singular (or their q1..q6 not of that pose): line(s) "
                     f"{', '.join(str(int(n)) for n in lines[:10])}{' ...' if len(lines) > 10 else ''}")
    ident = model.kinematic_.identifiability() if model.kinematic_.layout_.n and update is None else None
    share = model.kinematic_.branch_share_
    if share == share and share < 0.99:  # (NaN: no joint angles to compare with)
        notes.append(f"warning: {100 * (1 - share):.1f} % of the training rows were reached on another IK branch "
                     f"than {list(model.kinematic_.ik_.branch)}: the model assumes that one everywhere")
    accuracy = accuracy_card(errors[val_rows], model.predict(poses[val_rows], rows(previous, val_rows),
                                                             rows(q_deg, val_rows), rows(tools, val_rows),
                                                             rows(q_previous, val_rows)),
                             model.train_stats_["mean"], len(train_rows))
    if model.orientation and len(val_rows):
        from ..stats import table2

        before = np.linalg.norm(rotation_errors[val_rows], axis=1)
        after = np.linalg.norm(rotation_errors[val_rows] - model.predict_rotation(
            poses[val_rows], rows(previous, val_rows), rows(q_deg, val_rows)), axis=1)
        accuracy["val_rotation_deg"] = {"uncompensated": table2(before), "residual": table2(after)}
    found = model.describe()
    found["identifiability"] = ident
    metadata = {
        "name": args.name or Path(args.output).stem,
        "data_sha256": data.sha256,
        "accuracy": accuracy,
        "iterations": max(2, model.fixed_point_iterations(poses[train_rows])),
        "identified": found,
    }
    if update is not None:
        metadata["update"] = update.card()
    metadata.update(arm_metadata(description))
    if tools is not None or model.kinematic_.layout_.n:
        own = model.description_.tool
        same = np.allclose(own, description.tool)
        metadata["tool"] = model.tool_card(description.tool_name if same else f"$TOOL {','.join(f'{v:g}' for v in own)}")
    model.export_onnx(args.output, **metadata)

    if not args.quiet:
        for note in notes:
            print(note, file=sys.stderr)
        order = "backlash from the visiting order" if model.uses_previous else "no visiting order"
        took = f"; {model.fit_seconds_['total']:.1f} s" if hasattr(model, "fit_seconds_") else ""
        print(f"model     {args.output}  ({model.label}; {model.structure}; {order}{took})")
        if update is not None:
            print_update(update)
        if ident:
            apart = "; ".join("+".join(g) for g in ident["unseparated"][:6]) or "none"
            apart += " ..." if len(ident["unseparated"]) > 6 else ""
            print(f"identify  rank {ident['rank']} of {ident['parameters']} parameters, condition "
                  f"{ident['condition']:.3g}; groups the data cannot "
                  f"separate (settled by the prior): {apart}")
        tool = metadata["tool"]
        if "unseparated" in tool:
            print(f"tools     measured {len(tool['measured'])}: valid for {tool['valid']}")
        if found["ripple"]:
            print(f"ripple    joint:order {' '.join(f'A{j}:{n}' for j, n in found['ripple'])}")
        print(f"data      {args.data}: {len(train_rows)} training rows, {len(val_rows)} validation rows")
        print_figures(accuracy, model.train_stats_)
        if "val_rotation_deg" in accuracy:
            r = accuracy["val_rotation_deg"]
            print(f"{'angle deg (validation)':<26} {'mean':>7} {'max':>7} {'std':>7}")
            for label, key in (("uncompensated", "uncompensated"), ("residual", "residual")):
                print(f"{label:<26} {r[key]['mean']:7.4f} {r[key]['max']:7.4f} {r[key]['std']:7.4f}")
        print(f"postproc train: wrote {args.output}", file=sys.stderr)
    return 0


def print_update(update) -> None:
    """What ``--update`` re-fitted and which parameters moved (stdout)."""
    card = update.card()
    moved = update.moved
    print(f"update    from {update.old.path} ({card['from']}): {update.rows} rows; re-fitted {', '.join(card['groups'])} "
          f"({len(update.parameters)} parameters), everything else kept; {len(moved)} moved "
          f"(|change| > {card['moved_at_sigmas']:g} std)")
    for p in moved:
        print(f"moved     {p['name']:<9} old {p['old']:+11.5f}  new {p['new']:+11.5f}  change {p['change']:+10.5f} "
              f"± {p['std']:.5f} {p['unit']}")

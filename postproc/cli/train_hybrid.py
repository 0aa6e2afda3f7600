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
               progress: bool, tools: np.ndarray | None = None) -> int:
    """Fit, export and report a hybrid-family model; ``errors`` [N, 3] = E of ``data``'s rows
    (after any registration); ``tools`` [N, 6] the TCP each row was measured with (None: the
    description's)."""
    from ..training import accuracy_card
    from ..training.features import previous_joints, previous_poses
    from ..training.hybrid import HybridModel
    from .train import print_figures

    description = _description(args.robot)
    if args.method == "dnn-joints" and tools is not None and len(np.unique(tools, axis=0)) > 1:
        from ..diagnostics import PostprocError

        raise PostprocError(f"--method dnn-joints learns the error of one tool, the data have "
                            f"{len(np.unique(tools, axis=0))}: train --method hybrid (a physical model)",
                            args.data, code="P320")
    poses = data.poses
    # rows in visiting order (the first came from HOME): the approach direction of each joint
    previous = None if args.pose_only else previous_poses(poses)
    q_deg = data.joints
    # where the arm really stood before each row (its configuration may differ from the row's)
    q_previous = None if previous is None else previous_joints(q_deg)
    model = HybridModel(
        description,
        hidden=args.hidden or DEFAULT_HIDDEN[args.method],
        epochs=args.epochs or DEFAULT_EPOCHS,
        seed=args.seed,
        progress=progress,
        **SETTINGS[args.method],
    )
    rows = (lambda a, r: None if a is None else a[r])  # noqa: E731
    model.fit(poses[train_rows], errors[train_rows], rows(previous, train_rows), rows(q_deg, train_rows),
              rows(tools, train_rows), rows(q_previous, train_rows))

    if len(model.dropped_):
        lines = data.lines[train_rows][model.dropped_]
        notes.append(f"warning: {len(lines)} training row(s) left out, out of reach of the nominal {description.name} "
                     f"or singular (or their q1..q6 not of that pose): line(s) "
                     f"{', '.join(str(int(n)) for n in lines[:10])}{' ...' if len(lines) > 10 else ''}")
    ident = model.kinematic_.identifiability() if model.kinematic_.layout_.n else None
    share = model.kinematic_.branch_share_
    if share == share and share < 0.99:  # (NaN: no joint angles to compare with)
        notes.append(f"warning: {100 * (1 - share):.1f} % of the training rows were reached on another IK branch "
                     f"than {list(model.kinematic_.ik_.branch)}: the model assumes that one everywhere")
    accuracy = accuracy_card(errors[val_rows], model.predict(poses[val_rows], rows(previous, val_rows),
                                                             rows(q_deg, val_rows), rows(tools, val_rows),
                                                             rows(q_previous, val_rows)),
                             model.train_stats_["mean"], len(train_rows))
    found = model.describe()
    found["identifiability"] = ident
    metadata = {
        "name": args.name or Path(args.output).stem,
        "data_sha256": data.sha256,
        "accuracy": accuracy,
        "iterations": max(2, model.fixed_point_iterations(poses[train_rows])),
        "identified": found,
    }
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
        print(f"model     {args.output}  ({model.label}; {model.structure}; {order}; "
              f"{model.fit_seconds_['total']:.1f} s)")
        if ident:
            apart = "; ".join("+".join(g) for g in ident["unseparated"][:6]) or "none"
            apart += " ..." if len(ident["unseparated"]) > 6 else ""
            print(f"identify  rank {ident['rank']} of {ident['parameters']} parameters; groups the data cannot "
                  f"separate (settled by the prior): {apart}")
        tool = metadata["tool"]
        if "unseparated" in tool:
            print(f"tools     measured {len(tool['measured'])}: valid for {tool['valid']}")
        if found["ripple"]:
            print(f"ripple    joint:order {' '.join(f'A{j}:{n}' for j, n in found['ripple'])}")
        print(f"data      {args.data}: {len(train_rows)} training rows, {len(val_rows)} validation rows")
        print_figures(accuracy, model.train_stats_)
        print(f"postproc train: wrote {args.output}", file=sys.stderr)
    return 0

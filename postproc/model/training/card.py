"""The model card's robot parts: ``robot``, ``reach`` (the sphere compensate checks targets
against, P302) and ``tool`` of a robot description, ``demonstration`` (data the simulator
measured), and the rule for ``iterations``.

numpy only (the robot description and its closed-form IK are read lazily): fit's card and
the benchmarks that export models of their own take these from here.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

__all__ = ["MIN_ITERATIONS", "arm_metadata", "card_iterations", "demonstration_metadata", "robot_metadata",
           "tool_metadata", "tool_name"]

# c = P + Ê(c): the card's iterations are those after which the fixed point settled on the
# training poses, at least 2 (one more batched call is cheap insurance off the training poses)
MIN_ITERATIONS = 2


def card_iterations(settled: int) -> int:
    """The card's ``iterations`` for a fixed point that settled after ``settled`` iterations."""
    return max(MIN_ITERATIONS, settled)


def demonstration_metadata(meta: dict) -> dict:
    """The card's ``demonstration`` of a model trained on a measurement CSV's ``meta`` (its
    ``# key: value`` lines): data ``postproc measure`` simulated (``# simulated: ROBOT``, ``#
    robot_seed: S``) make a demonstration model of a simulated robot; other data none."""
    if "simulated" not in meta:
        return {}
    seed = meta.get("robot_seed", "")
    return {"demonstration": {"robot": meta["simulated"],
                              "robot_seed": int(seed) if seed.lstrip("-").isdigit() else None}}


def tool_name(frame) -> str:
    """The card's name of a TCP that is not the description's: ``$TOOL X,Y,Z,A,B,C``."""
    return f"$TOOL {','.join(f'{v:g}' for v in frame)}"


def tool_metadata(frame) -> dict:
    """The card's ``tool`` of a model that learned one measured TCP ``frame`` [6]."""
    return {"name": tool_name(frame), "frame": [round(float(v), 6) for v in frame]}


def arm_metadata(description) -> dict:
    """robot / reach / tool for the model card. KUKA-type arms: postproc.robot.arm's reach sphere;
    others: a conservative sphere about A2's origin on the A1 axis (every link after it laid end
    to end)."""
    from ...robot.arm import Robot

    tool = {"name": description.tool_name, "frame": [round(float(v), 6) for v in description.tool]}
    try:
        reach = Robot(description).reach
    except Exception:  # not a KUKA-type arm: no closed-form IK in postproc.robot.arm
        origins = np.array([j.origin[:3] for j in description.joints])
        centre = origins[0] + [0.0, 0.0, origins[1, 2]]
        flange = np.asarray(description.flange[:3])
        radius = (math.hypot(*origins[1, :2]) + float(np.linalg.norm(origins[2:], axis=1).sum())
                  + float(np.linalg.norm(flange)) + float(np.linalg.norm(description.tool[:3])))
        reach = {"center": [round(float(v), 3) for v in centre], "radius_min": 0.0, "radius_max": round(radius, 3)}
    out = {"robot": description.name, "reach": reach, "tool": tool}
    if np.any(np.asarray(description.controller_base) != 0):  # (a program's base is not the model's frame)
        out["controller_base"] = [round(float(v), 6) for v in description.controller_base]
    return out


def robot_metadata(robot) -> dict:
    """robot / reach / tool metadata from a robot description (a RobotDescription, a .toml
    file or the name of the shipped default), when there is one to read; an unknown name (or
    no robot description support installed) → the name only, claiming no reach."""
    if not robot:
        return {}
    if not isinstance(robot, (str, Path)):
        return arm_metadata(robot)
    from ...robot.description import (
        is_description_file,
        load_description,
        shipped_description,
    )

    name = str(robot)
    description = load_description(robot) if is_description_file(robot) else shipped_description(name)
    if description is None:
        return {"robot": name}  # an unknown robot: record its name, claim no reach
    return arm_metadata(description)

"""Inputs beyond the pose: the visiting order's approach directions and joint-space features.

A measurement log keeps the order in which the robot visited its poses, and a program's order
is known: so the direction each joint last moved in before reaching a target is available.
Lost motion (backlash) makes the error depend on it, which no function of the pose alone can
learn. ``previous_poses`` gives each row the pose commanded just before it (the contract's
optional ``previous_pose`` input), ``motion_signs`` the sign of each joint's last motion.
"""
from __future__ import annotations

import math

import numpy as np
import torch

from ...robot.kinematics.twin import wrapped_step

# a load-aware model (trained on data at known loads: ``KinematicModel.fit``'s ``loads``) is held
# to masses from 0 to this × the largest it was measured with, and centres of mass up to this ×
# the farthest (the card's ``loads.extrapolate``; ``Compensator.load_reach``): its compliance is
# physical, the torque of a load linear in its mass, so it extrapolates; benchmarks/loads.py
# measures it at 500 kg from data at 0 and 300 kg (1.67×)
LOAD_EXTRAPOLATE = 2.0

__all__ = ["LOAD_EXTRAPOLATE", "measured_loads", "previous_poses", "previous_joints", "motion_signs", "wrap_angles", "inside_ranges", "joint_features"]


def measured_loads(loads: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict]:
    """The distinct loads [K, 4] of the rows' ``loads`` [N, 4] (mass kg, centre of mass mm; to
    1e-6), the rows at each [K], and the card's words for them (``measured``, ``rows``)."""
    distinct, counts = np.unique(np.round(np.asarray(loads, dtype=np.float64).reshape(-1, 4), 6), axis=0,
                                 return_counts=True)
    return distinct, counts, {"measured": [[float(v) for v in row] for row in distinct],
                              "rows": [int(n) for n in counts]}


def previous_poses(poses: np.ndarray, first: np.ndarray | None = None) -> np.ndarray:
    """[N, 6] the pose visited before each row (rows in visiting order); the first row's is
    ``first`` (e.g. HOME's pose) or the row itself (no motion known), as ``compensate`` does."""
    poses = np.asarray(poses, dtype=float).reshape(-1, 6)
    head = poses[:1] if first is None else np.asarray(first, dtype=float).reshape(1, 6)
    return np.vstack([head, poses[:-1]]) if len(poses) else poses.copy()


def previous_joints(q_deg: np.ndarray | None) -> np.ndarray | None:
    """[N, 6] the joint angles (deg) the arm stood at before each row (rows in visiting order,
    ``q_deg`` the data's q1..q6); the first row's is unknown (NaN: it came from HOME). Where
    consecutive rows are in different configurations (a plan with ``--wrist both``) these, not
    the previous pose solved on the row's own branch, give the joints' true approach directions."""
    if q_deg is None:
        return None
    q_deg = np.asarray(q_deg, dtype=float).reshape(-1, 6)
    return np.vstack([np.full((min(len(q_deg), 1), 6), np.nan), q_deg[:-1]])


def wrap_angles(q: torch.Tensor) -> torch.Tensor:
    """Angles (rad) wrapped to [−π, π): the IK does not unwrap turns, nor do the joint ranges."""
    return torch.remainder(q + math.pi, 2 * math.pi) - math.pi


def inside_ranges(q: torch.Tensor, ranges: torch.Tensor) -> torch.Tensor:
    """1.0 / 0.0 [N]: every joint angle of q [N, 6] rad (any turn) on its arc ``ranges`` [6, 2]
    rad (from lo counterclockwise to hi, ``compensator.joint_arcs``, widened)."""
    return (torch.remainder(q - ranges[:, 0], 2 * math.pi) <= ranges[:, 1] - ranges[:, 0]).all(dim=1).to(q.dtype)


def motion_signs(q: torch.Tensor, q_previous: torch.Tensor, fill: bool = False, eps: float = 1e-9) -> torch.Tensor:
    """Sign (+1 / −1, 0 = did not move) of each joint's step q_previous → q, [N, J].

    With ``fill`` (a whole visiting sequence, rows in order) a joint that did not move keeps its
    last sign: what the joint really remembers. A model fed one (pose, previous_pose) pair at
    a time cannot know that, and takes 0 (the middle of the lost motion) instead.
    """
    step = wrapped_step(q, q_previous)
    sign = torch.where(torch.abs(step) > eps, torch.sign(step), torch.zeros_like(step))
    if fill and len(sign):
        idx = torch.arange(len(sign))[:, None].expand_as(sign)
        last = torch.where(sign != 0, idx, torch.zeros_like(idx))
        last = torch.cummax(last, dim=0).values
        sign = torch.gather(sign, 0, last)
    return sign


def joint_features(q: torch.Tensor, signs: torch.Tensor | None = None) -> torch.Tensor:
    """sin, cos of each joint angle (periodic: the IK does not unwrap turns) [+ approach signs]."""
    parts = [torch.sin(q), torch.cos(q)]
    if signs is not None:
        parts.append(signs)
    return torch.cat(parts, dim=1)

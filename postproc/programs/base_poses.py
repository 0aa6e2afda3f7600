"""Every target's pose in the robot base frame."""
from __future__ import annotations

import numpy as np

from ..core import frames
from .model import Program

__all__ = ['robot_base_poses']


def robot_base_poses(program: Program, bases: list[np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Every target's pose in the robot base frame [N, 6] (the model's, with ``bases`` from
    :func:`model_bases`; else the program's frames), and a mask of those whose frame is known.
    Unknown orientation components stay NaN; unresolved rows are NaN."""
    t = program.targets
    out = np.full((len(t), 6), np.nan)
    resolved = t.frame >= 0
    for f, rows in frames.frame_groups(t.frame):
        base = program.frames[f].base if bases is None else bases[f]
        out[rows, :3] = frames.transform_points(base, t.poses[rows, :3])
        known = rows[~np.isnan(t.poses[rows, 3:6]).any(axis=1)]
        if not len(known):
            continue
        if np.allclose(base[:3, :3], np.eye(3), atol=1e-12):
            # keep the triple as written: A,B,C and (A±180, 180−B, C±180) are one rotation,
            # but a model and its envelope see numbers
            out[known, 3:6] = t.poses[known, 3:6]
        else:
            rot = base[:3, :3] @ frames.rotation_from_abc(t.poses[known, 3:6])
            out[known, 3:6] = frames.abc_from_rotation(rot)
    return out, resolved

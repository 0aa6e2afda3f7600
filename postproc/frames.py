"""KUKA frames: X,Y,Z (mm) and A,B,C (deg) with R = Rz(A)·Ry(B)·Rx(C).

All functions are vectorised over leading axes: a frame is ``[..., 6]``, a homogeneous
transform ``[..., 4, 4]``. ``F1:F2`` in KRL is ``compose(F1, F2)`` = T1·T2.
"""
from __future__ import annotations

import numpy as np

__all__ = [
    "rotation_from_abc",
    "abc_from_rotation",
    "frame_to_matrix",
    "matrix_to_frame",
    "compose",
    "inverse",
    "transform_points",
    "rotate_vectors",
    "rotation_vector",
    "rotation_error_deg",
    "frames_used",
]


def frames_used(frame: np.ndarray) -> np.ndarray:
    """The distinct frame indices ≥ 0 in ``frame`` (targets' ``Targets.frame``), ascending:
    ``np.unique`` without its import of numpy.ma (8 ms of a 100-target CLI run)."""
    frame = np.asarray(frame, dtype=np.int64)
    return np.flatnonzero(np.bincount(frame[frame >= 0]))


def rotation_from_abc(abc: np.ndarray) -> np.ndarray:
    """[..., 3] A,B,C in degrees → [..., 3, 3] rotation Rz(A)·Ry(B)·Rx(C)."""
    a, b, c = np.moveaxis(np.radians(np.asarray(abc, dtype=float)), -1, 0)
    with np.errstate(invalid="ignore"):  # an infinite angle gives NaN (callers check), not a warning
        ca, sa, cb, sb, cc, sc = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    r = np.empty(a.shape + (3, 3))
    r[..., 0, 0] = ca * cb
    r[..., 0, 1] = ca * sb * sc - sa * cc
    r[..., 0, 2] = ca * sb * cc + sa * sc
    r[..., 1, 0] = sa * cb
    r[..., 1, 1] = sa * sb * sc + ca * cc
    r[..., 1, 2] = sa * sb * cc - ca * sc
    r[..., 2, 0] = -sb
    r[..., 2, 1] = cb * sc
    r[..., 2, 2] = cb * cc
    return r


def abc_from_rotation(r: np.ndarray) -> np.ndarray:
    """[..., 3, 3] rotation → [..., 3] A,B,C in degrees, B in [-90, 90].

    At gimbal lock (|B| = 90°) only A−C (or A+C) is defined; C is set to 0 there.
    """
    r = np.asarray(r, dtype=float)
    cb = np.hypot(r[..., 0, 0], r[..., 1, 0])
    b = np.arctan2(-r[..., 2, 0], cb)
    locked = cb < 1e-9
    a = np.where(locked, np.arctan2(-r[..., 0, 1], r[..., 1, 1]), np.arctan2(r[..., 1, 0], r[..., 0, 0]))
    c = np.where(locked, 0.0, np.arctan2(r[..., 2, 1], r[..., 2, 2]))
    return np.degrees(np.stack([a, b, c], axis=-1))


def frame_to_matrix(frame: np.ndarray) -> np.ndarray:
    """[..., 6] X,Y,Z,A,B,C → [..., 4, 4] homogeneous transform."""
    frame = np.asarray(frame, dtype=float)
    t = np.zeros(frame.shape[:-1] + (4, 4))
    t[..., :3, :3] = rotation_from_abc(frame[..., 3:6])
    t[..., :3, 3] = frame[..., :3]
    t[..., 3, 3] = 1.0
    return t


def matrix_to_frame(t: np.ndarray) -> np.ndarray:
    """[..., 4, 4] homogeneous transform → [..., 6] X,Y,Z,A,B,C."""
    t = np.asarray(t, dtype=float)
    return np.concatenate([t[..., :3, 3], abc_from_rotation(t[..., :3, :3])], axis=-1)


def compose(*transforms: np.ndarray) -> np.ndarray:
    """T1·T2·…: KRL's ``F1:F2:…`` on 4×4 transforms (broadcasting)."""
    out = transforms[0]
    for t in transforms[1:]:
        out = out @ t
    return out


def inverse(t: np.ndarray) -> np.ndarray:
    """Inverse of rigid transforms (KRL's INV_POS)."""
    t = np.asarray(t, dtype=float)
    out = np.zeros_like(t)
    rt = np.swapaxes(t[..., :3, :3], -1, -2)
    out[..., :3, :3] = rt
    out[..., :3, 3] = -(rt @ t[..., :3, 3, None])[..., 0]
    out[..., 3, 3] = 1.0
    return out


def transform_points(t: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply [..., 4, 4] transforms to [..., 3] points."""
    t = np.asarray(t, dtype=float)
    return (t[..., :3, :3] @ np.asarray(points, dtype=float)[..., None])[..., 0] + t[..., :3, 3]


def rotate_vectors(t: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """Apply only the rotation of [..., 4, 4] transforms to [..., 3] vectors (e.g. corrections)."""
    t = np.asarray(t, dtype=float)
    return (t[..., :3, :3] @ np.asarray(vectors, dtype=float)[..., None])[..., 0]


def rotation_vector(r: np.ndarray) -> np.ndarray:
    """[..., 3, 3] rotations → [..., 3] rotation vectors (rad; the log map, angles < 180°)."""
    r = np.asarray(r, dtype=float)
    v = 0.5 * np.stack([r[..., 2, 1] - r[..., 1, 2], r[..., 0, 2] - r[..., 2, 0], r[..., 1, 0] - r[..., 0, 1]], axis=-1)
    s = np.linalg.norm(v, axis=-1)
    angle = np.arctan2(s, 0.5 * (np.trace(r, axis1=-2, axis2=-1) - 1.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.where(s > 1e-12, angle / np.where(s > 1e-12, s, 1.0), 1.0)
    return v * scale[..., None]


def rotation_error_deg(nominal_abc: np.ndarray, actual_abc: np.ndarray) -> np.ndarray:
    """[..., 3] the orientation error as the model contract has it: the rotation vector (deg, base
    frame) of nominal → actual, r with R_actual = exp(r)·R_nominal, from A,B,C [..., 3] each."""
    relative = rotation_from_abc(actual_abc) @ np.swapaxes(rotation_from_abc(nominal_abc), -1, -2)
    return np.degrees(rotation_vector(relative))

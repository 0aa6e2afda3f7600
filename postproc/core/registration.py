"""Best-fit rigid transform between corresponding point sets (Kabsch / Umeyama).

A laser tracker measures in its own frame. To compute errors E = P_target − P_actual the
measured points are mapped into the robot base frame by the rigid transform that best fits
them (least squares) to the commanded positions. :func:`register_measurements` fits it on
the training rows only, so that held-out rows stay unseen, and applies it to every row.

The residual of that fit is not noise: it is the robot's positioning error minus the part
of it a rigid motion can explain (a constant offset, a small rotation), which is why the
registration must not see the validation rows.

Reference: S. Umeyama, "Least-squares estimation of transformation parameters between two
point patterns", IEEE TPAMI 13(4), 1991 (the rotation step is Kabsch's).
"""
from __future__ import annotations

import numpy as np

from .diagnostics import P510, P511, PostprocError

__all__ = [
    "fit_rigid",
    "transform_matrix",
    "apply_rigid",
    "residuals",
    "register_measurements",
]

# A point set whose second singular value (after centring) is below this fraction of the
# first is collinear (or a single point) to working precision: the rotation about that line
# is then undetermined.
_RANK_TOLERANCE = 1e-9


def _points(points: np.ndarray, name: str) -> np.ndarray:
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3:
        raise PostprocError(f"{name} must be an [N, 3] array of points, got shape {p.shape}", code=P511)
    if not np.all(np.isfinite(p)):
        raise PostprocError(f"{name} contains NaN or infinite coordinates", code=P511)
    return p


def fit_rigid(
    source: np.ndarray, target: np.ndarray, scale: bool = False
) -> tuple[np.ndarray, np.ndarray] | tuple[np.ndarray, np.ndarray, float]:
    """Least-squares R, t (and s with ``scale=True``) such that target ≈ s·R·source + t.

    ``source`` and ``target`` are corresponding [N, 3] points, N ≥ 3, not collinear.
    R is a proper rotation (det +1, never a reflection). Returns ``(R [3,3], t [3])`` or
    ``(R, t, s)``. Raises :class:`PostprocError` (P510) for degenerate input.
    """
    src = _points(source, "source")
    dst = _points(target, "target")
    if src.shape != dst.shape:
        raise PostprocError(
            f"source and target must correspond point by point: {len(src)} vs {len(dst)} points", code=P511
        )
    n = len(src)
    if n < 3:
        raise PostprocError(f"a rigid registration needs at least 3 points, got {n}", code=P510)
    mu_s, mu_d = src.mean(axis=0), dst.mean(axis=0)
    xs, xd = src - mu_s, dst - mu_d
    spread = np.linalg.svd(xs, compute_uv=False)
    if spread[0] == 0.0 or spread[1] <= _RANK_TOLERANCE * spread[0]:
        raise PostprocError(
            f"the {n} source points are collinear or coincident: the rotation about their line is undetermined",
            code=P510,
        )
    cov = xd.T @ xs / n  # Σ_ds of Umeyama's eq. (38)
    u, d, vt = np.linalg.svd(cov)
    if d[1] <= _RANK_TOLERANCE * d[0]:
        raise PostprocError(
            "source and target do not correspond (their cross-covariance has rank < 2): "
            "the rotation is undetermined",
            code=P510,
        )
    # the sign fix turns a best-fit reflection into the best proper rotation
    signs = np.array([1.0, 1.0, np.sign(np.linalg.det(u) * np.linalg.det(vt)) or 1.0])
    rotation = (u * signs) @ vt
    if not scale:
        return rotation, mu_d - rotation @ mu_s
    s = float((d * signs).sum() / (xs**2).sum() * n)
    return rotation, mu_d - s * rotation @ mu_s, s


def transform_matrix(rotation: np.ndarray, translation: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """[4, 4] homogeneous matrix of x ↦ s·R·x + t."""
    t = np.eye(4)
    t[:3, :3] = scale * np.asarray(rotation, dtype=float)
    t[:3, 3] = translation
    return t


def apply_rigid(points: np.ndarray, rotation: np.ndarray, translation: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """s·R·p + t for [N, 3] points."""
    return scale * np.asarray(points, dtype=float) @ np.asarray(rotation).T + np.asarray(translation)


def residuals(
    source: np.ndarray, target: np.ndarray, rotation: np.ndarray, translation: np.ndarray, scale: float = 1.0
) -> np.ndarray:
    """[N] distances |target − (s·R·source + t)|."""
    return np.linalg.norm(np.asarray(target, dtype=float) - apply_rigid(source, rotation, translation, scale), axis=1)


def register_measurements(
    commanded_xyz: np.ndarray, measured_xyz: np.ndarray, train_mask: np.ndarray
) -> tuple[np.ndarray, np.ndarray, float]:
    """Map tracker-frame measurements into the robot base frame.

    The rigid transform tracker → base is fitted (Kabsch, no scale: a tracker's scale is
    calibrated, a fitted one would absorb part of the robot's error) on the rows where
    ``train_mask`` is True, then applied to all rows.

    Returns ``(measured_in_base [N, 3], transform [4, 4] tracker → base, rms_mm)`` where
    rms_mm is the RMS residual |commanded − registered measured| over the training rows.
    """
    commanded = _points(commanded_xyz, "commanded positions")
    measured = _points(measured_xyz, "measured positions")
    mask = np.asarray(train_mask, dtype=bool)
    if mask.shape != (len(commanded),) or len(measured) != len(commanded):
        raise PostprocError(
            f"commanded {commanded.shape}, measured {measured.shape} and train_mask {mask.shape} must have N rows",
            code=P511,
        )
    rotation, translation = fit_rigid(measured[mask], commanded[mask])
    in_base = apply_rigid(measured, rotation, translation)
    rms = float(np.sqrt(np.mean(np.sum((commanded[mask] - in_base[mask]) ** 2, axis=1))))
    return in_base, transform_matrix(rotation, translation), rms

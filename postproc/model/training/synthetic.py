"""A synthetic measurement set: a smooth error field of the pose, for tests and benchmarks.

Stands in for the simulated robot where the simulator is not wanted (unit tests) or not yet
there. E(pose) is a sum of a few sinusoids of the normalised pose (≈1 mm in size, a few
oscillations across the box, depending on position more than on attitude, as joint-offset
and deflection errors do) plus gaussian measurement noise (0.02 mm, a laser tracker's).
The attitude range straddles ±180° in A so that wrap handling is exercised too.
"""
from __future__ import annotations

import numpy as np

__all__ = ["BOX", "ATTITUDE", "RANGE_DEG", "synthetic_poses", "synthetic_errors", "synthetic_measurements", "to_csv"]

BOX = np.array([1700.0, 2300.0, -600.0, 600.0, 500.0, 1300.0])  # x0,x1,y0,y1,z0,z1 mm
ATTITUDE = np.array([180.0, 0.0, 180.0])  # deg: tool pointing down, A wrapping at ±180
RANGE_DEG = 10.0


def synthetic_poses(n: int, seed: int = 0) -> np.ndarray:
    """n Latin-hypercube poses [n, 6] in BOX × ATTITUDE ± RANGE_DEG (angles wrapped)."""
    from scipy.stats import qmc

    u = qmc.LatinHypercube(d=6, seed=seed).random(n)
    lo = np.concatenate([BOX[0::2], ATTITUDE - RANGE_DEG])
    hi = np.concatenate([BOX[1::2], ATTITUDE + RANGE_DEG])
    poses = lo + u * (hi - lo)
    poses[:, 3:] = (poses[:, 3:] + 180.0) % 360.0 - 180.0
    return poses


def synthetic_errors(poses: np.ndarray, field_seed: int = 7) -> np.ndarray:
    """The noise-free error field E [n, 3] mm at poses [n, 6]."""
    rng = np.random.default_rng(field_seed)
    u = np.empty((len(poses), 6))
    u[:, :3] = (poses[:, :3] - (BOX[0::2] + BOX[1::2]) / 2) / ((BOX[1::2] - BOX[0::2]) / 2)
    u[:, 3:] = ((poses[:, 3:] - ATTITUDE + 180.0) % 360.0 - 180.0) / RANGE_DEG
    n_terms = 4
    freq = rng.normal(size=(n_terms, 6)) * np.array([1.5, 1.5, 1.5, 0.5, 0.5, 0.5])  # [T, 6]
    phase = rng.uniform(0, 2 * np.pi, size=(n_terms, 3))
    amp = rng.uniform(0.15, 0.45, size=(n_terms, 3))
    arg = (u @ freq.T)[:, :, None] + phase[None]  # [n, T, 3]
    return (amp[None] * np.sin(arg)).sum(axis=1) + np.array([0.2, -0.1, 0.3])


def synthetic_measurements(n: int, seed: int = 0, noise_mm: float = 0.02) -> tuple[np.ndarray, np.ndarray]:
    """(poses [n, 6], measured positions [n, 3]) with measured = target − E + noise."""
    poses = synthetic_poses(n, seed)
    noise = np.random.default_rng(seed + 1).normal(scale=noise_mm, size=(n, 3))
    return poses, poses[:, :3] - synthetic_errors(poses) + noise


def to_csv(poses: np.ndarray, measured: np.ndarray) -> str:
    """The measurement CSV text for these rows (4 decimals)."""
    from ...measurements.csv import measurement_csv

    return measurement_csv(poses, measured, fmt="%.4f")

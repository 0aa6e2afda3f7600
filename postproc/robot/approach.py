"""Approach signs: the side each joint reaches a pose from (the backlash's lost motion)."""
from __future__ import annotations

import numpy as np

__all__ = ['approach_signs']


def approach_signs(q_deg: np.ndarray, start_q: np.ndarray, start_sign: float = 1.0) -> np.ndarray:
    """Sign (+1/−1) of each joint's last motion when the robot visits ``q_deg`` [N, 6] in order
    from ``start_q``; a joint that has not moved keeps its previous sign (``start_sign`` before
    the first move). Vectorised: np.diff, then a forward fill of the last nonzero sign."""
    q = np.atleast_2d(np.asarray(q_deg, float))
    seq = np.vstack([np.asarray(start_q, float)[None, :], q])
    step = np.diff(seq, axis=0)
    sign = np.where(np.abs(step) > 1e-9, np.sign(step), 0.0)
    sign = np.vstack([np.full((1, q.shape[1]), start_sign), sign])
    last = np.where(sign != 0, np.arange(len(sign))[:, None], 0)
    last = np.maximum.accumulate(last, axis=0)
    return np.take_along_axis(sign, last, axis=0)[1:]


def ordered_approach_signs(q_deg: np.ndarray, prev: np.ndarray, start_q: np.ndarray, axes: np.ndarray | None = None,
                           start_sign: float = 1.0) -> np.ndarray:
    """:func:`approach_signs` in execution order: each row reached from its predecessor row
    ``prev`` [N] (``prev[i] < i``; -1: from ``axes[i]`` where a joint motion left the robot,
    else from ``start_q``); a joint that has not moved keeps its predecessor's sign."""
    q = np.atleast_2d(np.asarray(q_deg, float))
    prev = np.asarray(prev, int)
    n = len(q)
    before = np.tile(np.asarray(start_q, float), (n, 1))
    if axes is not None:
        given = np.isfinite(axes).all(axis=1)
        before[given] = axes[given]
    inner = prev >= 0
    before[inner] = q[prev[inner]]
    step = q - before
    sign = np.where(np.abs(step) > 1e-9, np.sign(step), 0.0)
    out = sign.copy()
    for i in np.flatnonzero((sign == 0).any(axis=1)).tolist():  # (rows come after their predecessors)
        carried = out[prev[i]] if prev[i] >= 0 else np.full(q.shape[1], start_sign)
        out[i] = np.where(sign[i] != 0, sign[i], carried)
    return out

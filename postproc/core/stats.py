"""Positioning-error statistics as the method reports them (its Table 2): max, min, mean and
std (ddof 1, as MATLAB's std) of per-point error norms in mm, and the 95th percentile beside
them (a cell is accepted by its worst targets, not by the mean). numpy only."""
from __future__ import annotations

import math

import numpy as np

__all__ = ["table2"]


def table2(error_norms: np.ndarray) -> dict:
    """The method's Table 2 figures of positioning-error norms (mm): max, min, mean, std, and
    p95 (the 95th percentile, linear interpolation) (NaN for no points)."""
    e = np.asarray(error_norms, float)
    if e.size == 0:
        return {"max": math.nan, "min": math.nan, "mean": math.nan, "std": math.nan, "p95": math.nan}
    std = float(e.std(ddof=1)) if e.size > 1 else 0.0
    return {"max": float(e.max()), "min": float(e.min()), "mean": float(e.mean()), "std": std,
            "p95": float(np.percentile(e, 95))}

"""Positions in another unit than mm: the one check of every input that gives positions as bare
numbers — a pose list ``compensate`` and ``check`` read (``findings.unit_rule``), a measurement
CSV ``train`` reads (``training.data.check_errors``; ``fleet`` trains through ``train``).

A robot of the size postproc ships (it reaches metres) has no workspace that fits in a 5 mm
cube: every |x|, |y|, |z| below 5 is a file in metres (P517, naming the unit, before any target
becomes 48 P309s). Uncompensated errors of ~1/1000 of any robot's (a median |E| below
ERROR_FLOOR_MM, where the tracker's noise alone is ~0.02 mm) are metres too, and so are measured
positions ~1000× nearer (or farther) than the commanded ones (errors ~1000× a robot's); other
errors no robot makes (a median above ``training.data.FRAME_ERROR_MM``) are another frame: P509
there.

numpy only.
"""
from __future__ import annotations

import numpy as np

from .diagnostics import P517, PostprocError

__all__ = ["METRES_BOUND", "METRES_REACH_MM", "ERROR_FLOOR_MM", "unit_problem", "check_unit"]

# every |x|, |y|, |z| below this (the file's numbers) with a robot reaching METRES_REACH_MM or more: metres
METRES_BOUND = 5.0
METRES_REACH_MM = 500.0
# a median uncompensated |E| below this (mm) is no robot's: ~1/1000 of the 0.1–10 mm robots have
ERROR_FLOOR_MM = 0.002


def unit_problem(positions: np.ndarray, reach_mm: float | None = None, errors: np.ndarray | None = None,
                 measured: np.ndarray | None = None) -> str | None:
    """Why ``positions`` [N, ≥3] (the numbers as written, meant to be mm) are in another unit,
    or None: every |x|, |y|, |z| below METRES_BOUND for a robot that reaches ``reach_mm`` (None:
    unknown, a robot of metres' reach assumed); ``errors`` [N, 3] (uncompensated, mm) whose
    median norm is below ERROR_FLOOR_MM; or ``measured`` [N, 3] positions (a measurement CSV's
    x_meas..z_meas) ~1000× nearer the origin than the commanded ones, or ~1000× farther: one of
    the two in metres (errors ~1000× a robot's)."""
    xyz = np.asarray(positions, float)[:, :3]
    xyz = xyz[np.isfinite(xyz).all(axis=1)]
    if not len(xyz):
        return None
    largest = float(np.abs(xyz).max())
    if largest < METRES_BOUND and (reach_mm is None or reach_mm >= METRES_REACH_MM):
        robot = "a robot that reaches metres" if reach_mm is None else f"a robot that reaches {reach_mm:.0f} mm"
        return (f"every |x|, |y|, |z| is below {METRES_BOUND:g} (at most {largest:.4g}) for {robot}: these positions "
                "are in metres, not mm; multiply them by 1000")
    if measured is not None and len(measured):
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = float(np.nanmedian(np.linalg.norm(np.asarray(positions, float)[:, :3], axis=1)
                                       / np.linalg.norm(np.asarray(measured, float)[:, :3], axis=1)))
        for low, which in ((300.0, "x_meas, y_meas, z_meas"), (1 / 3000.0, "x, y, z")):
            if low < ratio < low * 10:
                return (f"the commanded positions lie {ratio:.4g} × as far from the origin as the measured ones: {which} "
                        "are in metres, not mm; multiply them by 1000")
    if errors is not None and len(errors):
        median = float(np.median(np.linalg.norm(np.asarray(errors, float)[:, :3], axis=1)))
        if median < ERROR_FLOOR_MM:
            return (f"uncompensated errors of {median:.3g} mm (median) are ~1/1000 of any robot's: the positions are "
                    "in metres, not mm; multiply them by 1000")
    return None


def check_unit(positions: np.ndarray, path: str = "", line: int = 0, reach_mm: float | None = None,
               errors: np.ndarray | None = None, measured: np.ndarray | None = None) -> None:
    """Raise PostprocError P517 (at ``path:line``) where :func:`unit_problem` finds one."""
    problem = unit_problem(positions, reach_mm, errors, measured)
    if problem is not None:
        raise PostprocError(problem, path, line, 1 if line else 0, P517)

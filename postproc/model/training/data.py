"""What training needs of measurements besides reading them (that is postproc.measurements.csv):
the TCP the rows were measured with, the train / validation split, the size check, implausible
errors, the envelope of the data.

Codes: P320 tool sources that disagree (``measured_tools``), P505 too few points for the
network, P506 a split that leaves a side empty, P509 errors no robot makes (another frame or
unit: ``check_errors``; positions in metres, P517, ``postproc.core.units``), P518 registered rows that
do not fit one frame (several set-ups not named as campaigns: ``check_errors`` with ``registered``), P515 orientation errors no robot makes (``check_rotation_errors``).

numpy only: no torch here, so bad data is reported before torch is even loaded.
"""
from __future__ import annotations

import math

import numpy as np

from ...core.diagnostics import P320, P505, P506, P509, P515, P518, PostprocError
from ...measurements.csv import Measurements

__all__ = [
    "measured_tools",
    "check_errors",
    "frame_split",
    "check_rotation_errors",
    "split_indices",
    "check_size",
    "min_points",
    "envelope_of",
    "attitude_centre",
    "wrap_deg",
]


def measured_tools(data: Measurements, tool: np.ndarray | None = None) -> np.ndarray | None:
    """Each row's TCP on the flange [N, 6]: the ``tool_x..tool_c`` columns, else the ``# tool:``
    line, else ``tool`` (``train --tool``), else None (the robot description's tool). Two
    sources that disagree are refused (P320): the product does not pick one."""
    from ...measurements.csv import parse_tool

    sources = []
    if data.tools is not None:
        sources.append(("the columns tool_x..tool_c", data.tools))
    if "tool" in data.meta:
        try:
            sources.append(("the '# tool:' line", np.tile(parse_tool(data.meta["tool"]), (len(data), 1))))
        except PostprocError as exc:
            raise PostprocError(f"'# tool: {data.meta['tool']}': {exc.message}", data.path, code=P320) from None
    if tool is not None:
        sources.append(("--tool", np.tile(np.asarray(tool, float), (len(data), 1))))
    for (name, rows), (other, rows2) in zip(sources, sources[1:]):
        differ = np.flatnonzero(np.abs(rows - rows2).max(axis=1) > 1e-6)
        if len(differ):
            i = differ[0]
            raise PostprocError(f"{other} says the tool is {rows2[i].tolist()}, {name} {rows[i].tolist()}: which "
                                "TCP were the data measured with?", data.path, int(data.lines[i]), 1, P320)
    return sources[0][1] if sources else None


# --val-fraction when not given: VAL_FRACTION of the rows, none below ALL_ROWS_BELOW rows (a
# validation figure of one to four rows says little, and each row counts in a small fit: a
# 30-row --update held two of them out)
VAL_FRACTION = 0.05
ALL_ROWS_BELOW = 100


def default_val_fraction(n: int, val_fraction: float | None = None) -> float:
    """``val_fraction`` as given, else the default for ``n`` rows (VAL_FRACTION; 0 below ALL_ROWS_BELOW)."""
    if val_fraction is not None:
        return val_fraction
    return 0.0 if n < ALL_ROWS_BELOW else VAL_FRACTION


def split_indices(n: int, val_fraction: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Random (seeded) train / validation row indices; each side sorted (visiting order kept)."""
    if not 0.0 <= val_fraction < 1.0:
        raise PostprocError(f"--val-fraction must be in [0, 1), got {val_fraction}", code=P506)
    n_val = int(round(n * val_fraction))
    if val_fraction > 0 and n_val == 0:
        n_val = 1
    if n - n_val < 1:
        raise PostprocError(f"{n} rows leave no training points at --val-fraction {val_fraction}", code=P506)
    order = np.random.default_rng(seed).permutation(n)
    return np.sort(order[n_val:]), np.sort(order[:n_val])


def min_points(n_weights: int) -> int:
    """Fewest training rows for a network of ``n_weights`` weights and biases.

    Each row gives three numbers (Ex, Ey, Ez), so 3·n_train ≥ n_weights: at least as many
    fitted numbers as free parameters. Below that the fit interpolates noise.
    """
    return math.ceil(n_weights / 3)


def check_size(n_train: int, n_weights: int, structure: str, path: str = "") -> None:
    """Raise P505 when ``n_train`` rows are too few for a network of ``n_weights`` parameters."""
    need = min_points(n_weights)
    if n_train < need:
        raise PostprocError(
            f"{n_train} training points are too few for structure {structure} ({n_weights} weights): "
            f"need at least {need} (3 per point ≥ weights); measure more points or use a smaller --hidden",
            path,
            code=P505,
        )


# uncompensated errors with a median above this (mm) are not a robot's positioning error: the
# measured points are in another frame (not registered) or another unit (metres)
FRAME_ERROR_MM = 50.0


def check_errors(positions: np.ndarray, measured: np.ndarray, lines: np.ndarray, path: str = "",
                 registered: bool = False, campaign: str | None = None, split: str | None = None) -> list[str]:
    """Refuse errors E = positions − measured [N, 3] that no robot makes — median |E| above FRAME_ERROR_MM:
    another frame or unit (P509: register them, or convert); where the rows were ``registered``
    already (one rigid fit of them all), several set-ups in one file (P518: name the campaigns;
    ``campaign``: the campaign these rows are, whose set-up they do not fit; ``split``:
    ``frame_split``'s warning, where it found the place); return warnings
    naming the rows (file lines) whose |E| is far
    above the others' (more than 10 × the median + 5 mm): a mis-measured point or a
    wrong row."""
    from ...core.units import check_unit

    errors = positions - measured
    check_unit(positions, path, int(lines[0]) if len(lines) else 0, errors=errors, measured=measured)  # (P517: metres)
    size = np.linalg.norm(errors, axis=1)
    median = float(np.median(size)) if len(size) else 0.0
    if median > FRAME_ERROR_MM and registered:  # (the rigid fit of them all did not bring them onto the commands)
        i = int(np.argmax(size))
        rms = float(np.sqrt(np.mean(size**2)))
        what = f"campaign {campaign!r}'s rows do" if campaign else "the rows do"
        name = ("split it: each set-up its own campaign name" if campaign else
                "name them with a 'campaign' column or give each campaign's file to train (train a.csv c.csv ...)")
        raise PostprocError(f"{what} not fit one tracker frame (rigid fit residual {rms:.4g} mm rms, {median:.4g} mm "
                            f"median; line {lines[i]}: {size[i]:.4g} mm): the measurements hold several set-ups: {name}"
                            + (f" ({split.removeprefix('warning: ').split(': if they')[0]})" if split else ""),
                            path, int(lines[i]), 1, P518)
    if median > FRAME_ERROR_MM:  # (not metres: postproc.core.units said so above)
        i = int(np.argmax(size))
        raise PostprocError(f"uncompensated errors of {median:.4g} mm (median; line {lines[i]}: {size[i]:.4g} mm): "
                            f"the measured points are in another frame or unit: register them (--register, "
                            f"'# frame: tracker') or convert to mm", path, int(lines[i]), 1, P509)
    far = np.flatnonzero(size > 10.0 * median + 5.0)
    if not len(far):
        return []
    shown = ", ".join(str(int(lines[i])) for i in far[:10]) + (" ..." if len(far) > 10 else "")
    return [f"warning: {len(far)} row(s) with an error far above the others' (median {median:.3f} mm): "
            f"line(s) {shown}"]


# a file whose rows, split once in their order, fit two rigid frames this many times better
# (rms) than one looks like two set-ups: a robot's own error splits far less (the IPA UR10's
# series cut at their best place: A, B, C 1.00, D 1.37; A and C in one file: 223)
SPLIT_GAIN = 2.0


def _rigid_rss(n: np.ndarray, s_c, s_m, s_cc, s_mm, s_cm) -> np.ndarray:
    """The least residual sum of squares of a rigid fit c ≈ R·m + t from the points' sums (count
    ``n`` [K], Σc, Σm [K, 3], Σ|c|², Σ|m|² [K], Σ c·mᵀ [K, 3, 3]): Kabsch's, without the points."""
    n = np.maximum(n, 1)[:, None]
    cov = s_cm - s_c[:, :, None] * s_m[:, None, :] / n[:, :, None]
    spread = s_cc - (s_c**2).sum(1) / n[:, 0] + s_mm - (s_m**2).sum(1) / n[:, 0]
    u, d, vt = np.linalg.svd(cov)
    sign = np.sign(np.linalg.det(u) * np.linalg.det(vt))
    return np.maximum(spread - 2.0 * (d[:, 0] + d[:, 1] + sign * d[:, 2]), 0.0)


def frame_split(commanded: np.ndarray, measured: np.ndarray, lines: np.ndarray, least: int = 12) -> str | None:
    """A warning where the rows (in file order, tracker frame) fit two rigid frames — the rows
    before and after one place in the file, every place tried (each side ``least`` rows or more)
    — ``SPLIT_GAIN`` times better (rms) than one: the file may hold two set-ups that a rigid
    registration of them all mixes. None otherwise."""
    c, m = np.asarray(commanded, float), np.asarray(measured, float)
    n = len(c)
    if n < 2 * least:
        return None
    sums = [np.cumsum(v, axis=0) for v in (c, m, (c**2).sum(1), (m**2).sum(1), c[:, :, None] * m[:, None, :])]
    total = [v[-1] for v in sums]
    k = np.arange(least, n - least + 1)
    before = _rigid_rss(k.astype(float), *(v[k - 1] for v in sums))
    after = _rigid_rss((n - k).astype(float), *(t[None] - v[k - 1] for t, v in zip(total, sums)))
    one = float(np.sqrt(_rigid_rss(np.array([float(n)]), *(t[None] for t in total))[0] / n))
    i = int(np.argmin(before + after))
    two = float(np.sqrt((before[i] + after[i]) / n))
    if two * SPLIT_GAIN > one:
        return None
    cut = int(k[i])
    return (f"warning: the rows fit two tracker frames far better than one (lines up to {int(lines[cut - 1])} and from "
            f"{int(lines[cut])}: rms {two:.3g} mm, one frame {one:.3g} mm): if they are two set-ups, name them (a "
            "'campaign' column, or each set-up's file given to train)")


# measured orientations further than this (deg, median angle) from the commanded ones are not a
# robot's orientation error: another frame (a tracker's, unregistered), the probe's own axes
# (its mounting not taken out) or radians
ROTATION_ERROR_DEG = 5.0


def check_rotation_errors(rotation_errors: np.ndarray, lines: np.ndarray, path: str = "") -> None:
    """Refuse (P515) orientation errors [N, 3] deg (rotation vectors) that no robot makes: a
    median angle above ROTATION_ERROR_DEG."""
    angle = np.linalg.norm(rotation_errors, axis=1)
    median = float(np.median(angle)) if len(angle) else 0.0
    if median > ROTATION_ERROR_DEG:
        i = int(np.argmax(angle))
        raise PostprocError(f"measured orientations a_meas,b_meas,c_meas are {median:.3g}° from the commanded ones "
                            f"(median; line {lines[i]}: {angle[i]:.3g}°): not a robot's orientation error but another "
                            "frame, the probe's own axes or radians: give the TCP's A,B,C in the frame of x_meas..z_meas "
                            "(in degrees), or drop the columns", path, int(lines[i]), 1, P515)


def wrap_deg(angles: np.ndarray) -> np.ndarray:
    """Angles to [−180, 180)."""
    return (np.asarray(angles, dtype=float) + 180.0) % 360.0 - 180.0


def attitude_centre(abc: np.ndarray) -> np.ndarray:
    """Per component, the middle of the smallest arc holding all the angles (wrap-aware).

    KUKA tools pointing down sit at C ≈ ±180; a plain min/max there would span 360°.
    """
    abc = np.asarray(abc, dtype=float).reshape(-1, 3)
    centre = np.empty(3)
    for k in range(3):  # three components, not a loop over data
        a = np.sort(wrap_deg(abc[:, k]))
        gaps = np.diff(np.concatenate([a, a[:1] + 360.0]))
        j = int(np.argmax(gaps))  # the arc outside the data is the widest gap
        start, end = a[(j + 1) % len(a)], a[j]
        span = (end - start) % 360.0
        centre[k] = wrap_deg(start + span / 2.0)
    return centre


def envelope_of(poses: np.ndarray) -> dict:
    """The contract's envelope of training poses: position box, attitude centre and ± range."""
    poses = np.asarray(poses, dtype=float)
    lo, hi = poses[:, :3].min(axis=0), poses[:, :3].max(axis=0)
    centre = attitude_centre(poses[:, 3:6])
    dev = np.abs(wrap_deg(poses[:, 3:6] - centre)).max()
    return {
        "box": [float(v) for pair in zip(lo, hi) for v in pair],
        "attitude": [round(float(v), 6) for v in centre],
        "range": float(math.ceil(dev)),
    }

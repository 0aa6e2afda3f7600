"""Public measurement data sets → postproc's measurement CSV.

The IPA robot-accuracy data (Landgraf et al., IEEE CASE 2021; a UR10 and a laser tracker;
MIT licence) come as ';'-separated files with a decimal comma and one header row:

* ``Goal x/y/z`` (m) and ``Goal roll/pitch/yaw`` (rad, extrinsic x-y-z, i.e.
  R = Rz(yaw)·Ry(pitch)·Rx(roll)): the commanded TCP pose of the T-Mac probe, robot base frame;
* six joint angles (rad) ``shoulder_pan_joint`` … ``wrist_3_joint``;
* ``measurement_x/y/z`` (mm) of the probe's TCP and ``measurement_rx/ry/rz`` (deg, intrinsic
  X-Y-Z) in the *tracker's* frame; ``measurement_temperature`` (°C); optional ``_std`` columns.

postproc's measurement CSV (:mod:`postproc.measurements.csv`; read by ``postproc train``) has the header
``x,y,z,a,b,c,x_meas,y_meas,z_meas`` (mm, KUKA A,B,C deg) followed by optional extra columns;
here ``q1..q6`` (joint angles, deg) and ``temperature``. Metadata lines ``# key: value`` may
precede the header; ``# frame: tracker`` says the measured columns are still in the
tracker's frame (``train --register`` maps them into the base frame), ``# frame: base`` (or
no frame line) says they are in the robot base frame already.

The measured orientation is that of the probe's own axes, which sit on the flange at an
unknown fixed rotation: ``probe_orientation`` takes it out (the chordal mean of
R_goalᵀ·R_measured over the registration's rows, after the tracker → base rotation), so that
``import --register`` can write the TCP's measured A,B,C as ``a_meas,b_meas,c_meas`` in the
base frame. (That mean also takes the robot's mean orientation error in the TCP frame: a tool
rotation, which a calibration re-identifies anyway.)

Codes (as in postproc.measurements.csv): P500 unreadable or empty, P501 not the expected columns,
P502 a value that is not a finite number, P503 wrong number of fields.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.diagnostics import P500, P501, P502, P503, PostprocError
from ..core.frames import MM

__all__ = [
    "IpaSeries",
    "read_ipa",
    "parse_ipa",
    "rpy_to_abc",
    "probe_orientation",
]

IPA_GOAL = ("Goal x", "Goal y", "Goal z", "Goal roll", "Goal pitch", "Goal yaw")
IPA_JOINTS = (
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
)
IPA_MEASURED = ("measurement_x", "measurement_y", "measurement_z")
IPA_MEASURED_ROTATION = ("measurement_rx", "measurement_ry", "measurement_rz")
IPA_TEMPERATURE = "measurement_temperature"


@dataclass
class IpaSeries:
    """One IPA measurement file, converted to postproc's units (mm, deg, KUKA A,B,C)."""

    path: str
    commanded: np.ndarray  # [N, 6] X,Y,Z mm, A,B,C deg: commanded TCP pose, robot base frame
    joints: np.ndarray  # [N, 6] joint angles, deg
    measured: np.ndarray  # [N, 3] measured TCP position, mm, TRACKER frame
    measured_rotation: np.ndarray | None  # [N, 3, 3] measured probe orientation, tracker frame
    temperature: np.ndarray | None  # [N] °C
    lines: np.ndarray  # [N] 1-based line of each row in the source file

    def __len__(self) -> int:
        return len(self.commanded)


def rpy_to_abc(rpy: np.ndarray, branch: str = "nearest") -> np.ndarray:
    """[N, 3] roll, pitch, yaw (rad, extrinsic x-y-z) → [N, 3] KUKA A, B, C (deg).

    Both describe R = Rz(·)·Ry(·)·Rx(·); the conversion goes through the rotation matrix
    (scipy) so that any input triple gives a valid one. A rotation has two Euler triples
    (A, B, C) and (A+180, 180−B, C+180):

    * ``"canonical"``: B in [−90, 90], as a KUKA controller reports it;
    * ``"nearest"``: of the two triples, shifted by whole turns, the one nearest the given
      (yaw, pitch, roll) in degrees, i.e. the planner's own numbers when they are valid. Data
      whose pitch straddles 90° and roll 180° (IPA Series C: 70…110°, 90…220°) then keep
      continuous angles instead of A and C jumping by 180° or 360° between neighbours.
    """
    from scipy.spatial.transform import Rotation

    if branch not in ("nearest", "canonical"):
        raise ValueError(f"branch must be 'nearest' or 'canonical', not {branch!r}")
    rpy = np.atleast_2d(np.asarray(rpy, dtype=float))
    # scipy: lower-case = extrinsic, upper-case = intrinsic; intrinsic Z-Y-X is Rz·Ry·Rx = KUKA
    canonical = Rotation.from_euler("xyz", rpy).as_euler("ZYX", degrees=True)
    if branch == "canonical":
        return canonical
    wanted = np.degrees(rpy[:, ::-1])  # (yaw, pitch, roll) ~ (A, B, C)
    other = canonical * [1.0, -1.0, 1.0] + [180.0, 180.0, 180.0]
    candidates = np.stack([canonical, other])  # [2, N, 3]
    candidates += 360.0 * np.round((wanted - candidates) / 360.0)
    pick = np.abs(candidates - wanted).sum(axis=2).argmin(axis=0)  # [N]
    return candidates[pick, np.arange(len(rpy))]


def _column_offset(line: str, index: int) -> int:
    """1-based character column where field ``index`` of a ';'-separated line starts."""
    return sum(len(f) + 1 for f in line.split(";")[:index]) + 1


def _ipa_table(text: str, path: str) -> tuple[np.ndarray, list[str], bool, np.ndarray]:
    """The IPA file's numbers: [N, len(wanted)] floats of the ``wanted`` columns (the required
    ones, then the optional ones present), whether the measured rotation is there, and each
    row's 1-based line; PostprocError (P500-P503) at the first bad place."""
    raw_lines = text.lstrip("\ufeff").splitlines()
    if not raw_lines or not raw_lines[0].strip():
        raise PostprocError("empty file: expected an IPA header line", path, 1, 1, P500)
    header = [h.strip() for h in raw_lines[0].split(";")]
    if len(header) == 1:
        raise PostprocError(
            "the header has no ';' separators: not an IPA measurement file (';'-separated, decimal comma)",
            path,
            1,
            1,
            P501,
        )
    where = {name: i for i, name in enumerate(header)}
    required = IPA_GOAL + IPA_JOINTS + IPA_MEASURED
    missing = [name for name in required if name not in where]
    if missing:
        raise PostprocError(f"missing IPA column(s): {', '.join(missing)}", path, 1, 1, P501)
    optional = [name for name in IPA_MEASURED_ROTATION + (IPA_TEMPERATURE,) if name in where]
    has_rotation = all(name in where for name in IPA_MEASURED_ROTATION)
    wanted = list(required) + optional
    columns = np.array([where[name] for name in wanted])

    numbered = [(i, line) for i, line in enumerate(raw_lines[1:], start=2) if line.strip()]
    if not numbered:
        raise PostprocError("no data rows after the header", path, 1, 1, P500)
    line_no = np.array([i for i, _ in numbered])
    fields = [line.split(";") for _, line in numbered]
    counts = np.fromiter(map(len, fields), dtype=int, count=len(fields))
    bad = np.flatnonzero(counts != len(header))
    if bad.size:
        k = bad[0]
        raise PostprocError(
            f"expected {len(header)} ';'-separated fields as in the header, found {counts[k]}",
            path,
            int(line_no[k]),
            1,
            P503,
        )
    # fast path: one vectorised conversion; the slow search below only locates a bad cell
    cells = np.char.replace(np.char.strip(np.array(fields, dtype=str)[:, columns]), ",", ".")
    try:
        values = cells.astype(float)
        bad_cell = np.argwhere(~np.isfinite(values))
    except ValueError:
        bad_cell = np.argwhere(~np.vectorize(_is_number, otypes=[bool])(cells))
    if bad_cell.size:
        r, c = bad_cell[0]
        original = fields[r][columns[c]]
        raise PostprocError(
            f"column {wanted[c]!r}: {original!r} is not a finite number (decimal comma expected)",
            path,
            int(line_no[r]),
            _column_offset(numbered[r][1], int(columns[c])),
            P502,
        )
    return values, wanted, has_rotation, line_no


def parse_ipa(text: str, path: str = "<text>", branch: str = "nearest") -> IpaSeries:
    """Parse the text of an IPA measurement file (see the module docstring)."""
    from scipy.spatial.transform import Rotation

    values, wanted, has_rotation, line_no = _ipa_table(text, path)
    col = {name: values[:, i] for i, name in enumerate(wanted)}
    goal = np.stack([col[name] for name in IPA_GOAL], axis=1)
    commanded = np.concatenate([goal[:, :3] / MM, rpy_to_abc(goal[:, 3:], branch)], axis=1)
    joints = np.degrees(np.stack([col[name] for name in IPA_JOINTS], axis=1))
    measured = np.stack([col[name] for name in IPA_MEASURED], axis=1)
    rotation = None
    if has_rotation:
        angles = np.stack([col[name] for name in IPA_MEASURED_ROTATION], axis=1)
        rotation = Rotation.from_euler("XYZ", angles, degrees=True).as_matrix()
    temperature = col.get(IPA_TEMPERATURE)
    return IpaSeries(path, commanded, joints, measured, rotation, temperature, line_no)


def _is_number(cell: str) -> bool:
    try:
        return bool(np.isfinite(float(cell)))
    except ValueError:
        return False


def read_ipa(path: str | os.PathLike, branch: str = "nearest") -> IpaSeries:
    """Read an IPA measurement file (``Series_*/measurements_*.csv``)."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise PostprocError("no such file", str(path), 0, 0, P500) from None
    except UnicodeDecodeError as exc:
        raise PostprocError(f"not UTF-8 text ({exc.reason} at byte {exc.start})", str(path), 0, 0, P500) from None
    except OSError as exc:
        raise PostprocError(f"cannot read: {exc.strerror}", str(path), 0, 0, P500) from None
    return parse_ipa(text, str(path), branch)


def probe_orientation(commanded_abc: np.ndarray, measured_rotation: np.ndarray,
                      mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """The TCP's measured orientation from a probe's, both in the base frame.

    ``commanded_abc`` [N, 3] deg, ``measured_rotation`` [N, 3, 3] (the probe's axes, base
    frame), ``mask`` [N] the rows to estimate the probe's fixed rotation on the flange from
    (the registration's). Returns (A,B,C [N, 3] deg of R_measured·R_probeᵀ, R_probe [3, 3],
    rms deg of the masked rows' orientation error after it)."""
    from ..core.frames import abc_from_rotation, nearest_rotation, rotation_from_abc, rotation_vector

    goal = rotation_from_abc(commanded_abc)
    relative = np.swapaxes(goal, 1, 2) @ measured_rotation  # R_goalᵀ·R_measured: the probe on the TCP + error
    probe = nearest_rotation(relative[np.asarray(mask, bool)].mean(axis=0))  # the nearest rotation to the mean
    tcp = measured_rotation @ probe.T
    angle = np.linalg.norm(rotation_vector(tcp @ np.swapaxes(goal, 1, 2)), axis=1)
    rms = float(np.degrees(np.sqrt(np.mean(angle[np.asarray(mask, bool)] ** 2))))
    return abc_from_rotation(tcp), probe, rms

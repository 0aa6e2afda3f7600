"""Measurement CSV → arrays, checked row by row; the split; the envelope of the data.

The file (docs/ARCHITECTURE.md): header ``x,y,z,a,b,c,x_meas,y_meas,z_meas`` (mm, deg,
robot base frame; commanded TCP pose, measured TCP position), one row per visited pose in
visiting order. E = P_target − P_measured. Column names are matched case-insensitively and
in any order; extra columns (a point id, a timestamp) are ignored, except ``holdout`` (1 = a
row that an earlier registration did not see, see ``postproc import``); blank lines and lines
starting with ``#`` are skipped, and ``# key: value`` lines before the header are kept as
metadata (``# frame: tracker`` = measured columns still in the tracker's frame; ``# tool:
X,Y,Z,A,B,C`` = the TCP on the flange every row was measured with). Columns ``tool_x, tool_y,
tool_z, tool_a, tool_b, tool_c`` give each row's TCP instead (data of several tools, which
lets the identification separate the tool mount's rotation): ``measured_tools``.

Codes: P500 unreadable/empty, P501 missing or misnamed column, P502 a value that is not a
finite number, P503 wrong number of fields, P504 duplicate pose, P505 too few points for the
network, P506 a split that leaves a side empty, P509 errors no robot makes (another frame or
unit: ``check_errors``), P515 orientation errors no robot makes (``check_rotation_errors``).

Optional columns: ``a_meas,b_meas,c_meas`` (deg, KUKA A,B,C: a 6-DOF probe's measured TCP
orientation, same frame as x_meas..z_meas; all three or none, P501), ``q1..q6`` (deg, the
controller's joint angles), ``s,t`` (KUKA Status/Turn integers, used when q1..q6 are absent:
``postproc.configuration`` turns them into joint angles).

numpy only: no torch here, so bad data is reported before torch is even loaded.
"""
from __future__ import annotations

import difflib
import hashlib
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..diagnostics import PostprocError

__all__ = [
    "COLUMNS",
    "Measurements",
    "read_measurements",
    "measured_tools",
    "TOOL_COLUMNS",
    "check_errors",
    "check_rotation_errors",
    "parse_measurements",
    "parse_rows",
    "split_indices",
    "check_size",
    "min_points",
    "envelope_of",
    "attitude_centre",
    "wrap_deg",
]

POSE_COLUMNS = ("x", "y", "z", "a", "b", "c")
MEAS_COLUMNS = ("x_meas", "y_meas", "z_meas")
COLUMNS = POSE_COLUMNS + MEAS_COLUMNS
TOOL_COLUMNS = ("tool_x", "tool_y", "tool_z", "tool_a", "tool_b", "tool_c")
ORIENTATION_COLUMNS = ("a_meas", "b_meas", "c_meas")
STATUS_TURN_COLUMNS = ("s", "t")


@dataclass
class Measurements:
    """One measurement file as arrays; ``lines`` maps each row back to its 1-based file line."""

    poses: np.ndarray  # [N, 6] commanded X,Y,Z,A,B,C
    measured: np.ndarray  # [N, 3] measured X,Y,Z
    lines: np.ndarray  # [N] int
    sha256: str  # of the file's bytes, for the model's data_sha256
    path: str = ""
    meta: dict = field(default_factory=dict)  # '# key: value' lines before the header
    holdout: np.ndarray | None = None  # [N] bool from a 'holdout' column, if any
    joints: np.ndarray | None = None  # [N, 6] deg from 'q1'..'q6' (the controller's angles), if all there
    tools: np.ndarray | None = None  # [N, 6] from 'tool_x'..'tool_c' (each row's TCP on the flange), if there
    orientation: np.ndarray | None = None  # [N, 3] measured A,B,C (deg) from 'a_meas'..'c_meas', if there
    status_turn: np.ndarray | None = None  # [N, 2] int S, T from 's','t' (only without q1..q6)

    @property
    def errors(self) -> np.ndarray:
        """E = P_target − P_measured, [N, 3] mm."""
        return self.poses[:, :3] - self.measured

    @property
    def rotation_errors(self) -> np.ndarray | None:
        """The orientation error [N, 3] deg (rotation vector commanded → measured, the measured
        columns' frame), None without a_meas,b_meas,c_meas."""
        if self.orientation is None:
            return None
        from ..frames import rotation_error_deg

        return rotation_error_deg(self.poses[:, 3:6], self.orientation)

    def __len__(self) -> int:
        return len(self.poses)


def read_measurements(path: str | Path) -> Measurements:
    """Read and check a measurement CSV; raise PostprocError (P5xx) at the first bad place."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise PostprocError(f"cannot read measurement file: {exc.strerror or exc}", str(path), code="P500") from exc
    return parse_measurements(data, str(path))


def parse_measurements(data: bytes, path: str = "<data>", repeats: bool = False) -> Measurements:
    """Parse the bytes of a measurement CSV (see the module docstring). Rows repeating a pose
    are refused (P504) unless ``repeats`` (a repeatability test, ISO 9283, measures each pose n times)."""
    sha = hashlib.sha256(data).hexdigest()
    # any byte decodes as latin-1; numbers and names are ASCII anyway (a UTF-8 BOM is dropped)
    text = data.removeprefix(b"\xef\xbb\xbf").decode("latin-1")
    header: list[str] | None = None
    index: list[int] = []
    meta: dict[str, str] = {}
    lines = text.splitlines()
    first = None
    for first, raw in enumerate(lines):
        line = raw.strip()
        if line and not line.startswith("#"):
            header = [f.strip().lower() for f in raw.split(",")]
            index = _column_index(header, raw, path, first + 1)
            if "holdout" in header:
                index.append(header.index("holdout"))
            break
        key, sep, value = line[1:].partition(":")
        if sep:
            meta[key.strip().lower()] = value.strip()
    if header is None:
        raise PostprocError("empty measurement file (expected header " + ",".join(COLUMNS) + ")", path, code="P500")
    table, line_numbers = parse_rows(lines, first, header, index, path)
    if not len(table):
        raise PostprocError("measurement file has a header but no data rows", path, code="P500")
    joints = _joint_columns(lines, first, header, path)
    tools = None
    if set(TOOL_COLUMNS) & set(header):  # the TCP of each row: all six, finite numbers (P501/P502)
        missing = [n for n in TOOL_COLUMNS if n not in header]
        if missing:
            raise PostprocError(f"missing column(s) {', '.join(missing)}: a row's tool is {','.join(TOOL_COLUMNS)}",
                                path, first + 1, 1, "P501")
        tools = parse_rows(lines, first, header, [header.index(n) for n in TOOL_COLUMNS], path)[0]
    orientation = _orientation_columns(lines, first, header, path)
    status_turn = _status_turn_columns(lines, first, header, path) if joints is None else None
    # the same pose in another arm configuration (joint angles a degree or more apart) or
    # with another tool is another measurement, not a repeat
    key = table[:, :6] if joints is None else np.c_[table[:, :6], np.round(joints)]
    key = key if tools is None else np.c_[key, tools]
    if not repeats:
        _check_duplicates(key, line_numbers, path)
    holdout = table[:, 9] != 0 if table.shape[1] > 9 else None
    return Measurements(table[:, :6].copy(), table[:, 6:9].copy(), line_numbers, sha, path, meta, holdout, joints,
                        tools, orientation, status_turn)


def measured_tools(data: Measurements, tool: np.ndarray | None = None) -> np.ndarray | None:
    """Each row's TCP on the flange [N, 6]: the ``tool_x..tool_c`` columns, else the ``# tool:``
    line, else ``tool`` (``train --tool``), else None (the robot description's tool). Two
    sources that disagree are refused (P320): the product does not pick one."""
    from ..planning import parse_tool

    sources = []
    if data.tools is not None:
        sources.append(("the columns tool_x..tool_c", data.tools))
    if "tool" in data.meta:
        try:
            sources.append(("the '# tool:' line", np.tile(parse_tool(data.meta["tool"]), (len(data), 1))))
        except PostprocError as exc:
            raise PostprocError(f"'# tool: {data.meta['tool']}': {exc.message}", data.path, code="P320") from None
    if tool is not None:
        sources.append(("--tool", np.tile(np.asarray(tool, float), (len(data), 1))))
    for (name, rows), (other, rows2) in zip(sources, sources[1:]):
        differ = np.flatnonzero(np.abs(rows - rows2).max(axis=1) > 1e-6)
        if len(differ):
            i = differ[0]
            raise PostprocError(f"{other} says the tool is {rows2[i].tolist()}, {name} {rows[i].tolist()}: which "
                                "TCP were the data measured with?", data.path, int(data.lines[i]), 1, "P320")
    return sources[0][1] if sources else None


def _orientation_columns(lines: list[str], first: int, header: list[str], path: str) -> np.ndarray | None:
    """The measured orientation [N, 3] (deg) from ``a_meas,b_meas,c_meas``: all three or none
    (P501); each a finite number (P502): it is fitted, not an extra."""
    present = [name in header for name in ORIENTATION_COLUMNS]
    if not any(present):
        return None
    if not all(present):
        raise PostprocError(f"give all of {','.join(ORIENTATION_COLUMNS)} or none", path, first + 1, 1, "P501")
    return parse_rows(lines, first, header, [header.index(n) for n in ORIENTATION_COLUMNS], path)[0]


def _status_turn_columns(lines: list[str], first: int, header: list[str], path: str) -> np.ndarray | None:
    """KUKA Status and Turn [N, 2] (ints) from ``s,t``: both or none (P501); each a whole
    number 0..63 (P502)."""
    present = [name in header for name in STATUS_TURN_COLUMNS]
    if not any(present):
        return None
    if not all(present):
        raise PostprocError("give both s and t (KUKA Status and Turn) or neither", path, first + 1, 1, "P501")
    index = [header.index(n) for n in STATUS_TURN_COLUMNS]
    values, numbers = parse_rows(lines, first, header, index, path)
    bad = np.flatnonzero(((values != np.round(values)) | (values < 0) | (values > 63)).any(axis=1))
    if len(bad):
        k = int(np.argmax((values[bad[0]] != np.round(values[bad[0]])) | (values[bad[0]] < 0) | (values[bad[0]] > 63)))
        raw = lines[int(numbers[bad[0]]) - 1]
        raise PostprocError(f"column '{STATUS_TURN_COLUMNS[k]}': {values[bad[0], k]:g} is not a Status/Turn "
                            "(a whole number 0..63)", path, int(numbers[bad[0]]), _field_starts(raw)[index[k]] + 1, "P502")
    return values.astype(np.int64)


def _joint_columns(lines: list[str], first: int, header: list[str], path: str) -> np.ndarray | None:
    """The controller's joint angles [N, 6] (deg) from ``q1..q6`` (``postproc import`` writes
    them); None without them, or with a value that is not a finite number: they are an extra,
    not worth refusing the data for."""
    wanted = [f"q{i}" for i in range(1, 7)]
    if not set(wanted) <= set(header):
        return None
    try:
        return parse_rows(lines, first, header, [header.index(n) for n in wanted], path)[0]
    except PostprocError:
        return None


def parse_rows(lines: list[str], first: int, header: list[str], index: list[int],
               path: str) -> tuple[np.ndarray, np.ndarray]:
    """The columns ``index`` of the rows after header line ``lines[first]`` as floats [N, len(index)]
    and their 1-based line numbers [N]; blank and ``#`` lines skipped. PostprocError with
    file:line:col on a row of another width (P503) or a value that is not a finite number (P502)."""
    rows, numbers = [], []
    for number in range(first + 2, len(lines) + 1):
        raw = lines[number - 1]
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        fields = raw.split(",")
        if len(fields) != len(header):
            raise PostprocError(f"row has {len(fields)} fields, the header has {len(header)}", path, number, 1, "P503")
        row = []
        for i in index:
            try:
                value = float(fields[i])
            except ValueError:
                value = math.nan
            if not math.isfinite(value):
                shown = fields[i].strip() or "(empty)"
                raise PostprocError(f"column '{header[i]}': '{shown}' is not a finite number",
                                    path, number, _field_starts(raw)[i] + 1, "P502")
            row.append(value)
        rows.append(row)
        numbers.append(number)
    return np.asarray(rows, dtype=np.float64).reshape(-1, len(index)), np.asarray(numbers, dtype=np.int64)


def _field_starts(raw: str) -> list[int]:
    starts, pos = [], 0
    for text in raw.split(","):
        starts.append(pos + len(text) - len(text.lstrip()))
        pos += len(text) + 1
    return starts


def _column_index(header: list[str], raw: str, path: str, line: int) -> list[int]:
    missing = [name for name in COLUMNS if name not in header]
    if not missing:
        duplicated = sorted({h for h in header if h in COLUMNS and header.count(h) > 1})
        if duplicated:
            raise PostprocError(f"column(s) {', '.join(duplicated)} appear more than once", path, line, 1, "P501")
        return [header.index(name) for name in COLUMNS]
    unknown = [h for h in header if h not in COLUMNS]
    hints, col = [], 1
    for name in missing:
        close = difflib.get_close_matches(name, unknown, n=1, cutoff=0.5)
        if close:
            hints.append(f"'{close[0]}' for '{name}'?")
            if col == 1:  # point at the first misnamed column
                col = _field_starts(raw)[header.index(close[0])] + 1
    message = f"missing column(s) {', '.join(missing)}; the header must name {','.join(COLUMNS)}"
    if hints:
        message += " (misnamed: " + ", ".join(hints) + ")"
    raise PostprocError(message, path, line, col, "P501")


def _check_duplicates(poses: np.ndarray, lines: np.ndarray, path: str) -> None:
    # Two rows with the same commanded pose would give the network two answers for one input:
    # repeated measurements belong averaged into one row.
    _, first, inverse = np.unique(poses, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    dup = np.nonzero(first[inverse] != np.arange(len(poses)))[0]
    if len(dup):
        i = dup[0]
        raise PostprocError(
            f"duplicate pose: same x,y,z,a,b,c{'' if poses.shape[1] == 6 else ' and joint angles'} as line "
            f"{lines[first[inverse[i]]]} "
            f"({len(dup)} duplicate row(s) in all; average repeated measurements into one row)",
            path,
            int(lines[i]),
            1,
            "P504",
        )


def split_indices(n: int, val_fraction: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Random (seeded) train / validation row indices; each side sorted (visiting order kept)."""
    if not 0.0 <= val_fraction < 1.0:
        raise PostprocError(f"--val-fraction must be in [0, 1), got {val_fraction}", code="P506")
    n_val = int(round(n * val_fraction))
    if val_fraction > 0 and n_val == 0:
        n_val = 1
    if n - n_val < 1:
        raise PostprocError(f"{n} rows leave no training points at --val-fraction {val_fraction}", code="P506")
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
            code="P505",
        )


# uncompensated errors with a median above this (mm) are not a robot's positioning error: the
# measured points are in another frame (not registered) or another unit (metres)
FRAME_ERROR_MM = 50.0


def check_errors(positions: np.ndarray, measured: np.ndarray, lines: np.ndarray, path: str = "") -> list[str]:
    """Refuse (P509) errors E = positions − measured [N, 3] that no robot makes — median |E| above FRAME_ERROR_MM:
    another frame or unit; return warnings naming the rows (file lines) whose |E| is far
    above the others' (more than 10 × the median + 5 mm): a mis-measured point or a
    wrong row."""
    errors = positions - measured
    size = np.linalg.norm(errors, axis=1)
    median = float(np.median(size)) if len(size) else 0.0
    if median > FRAME_ERROR_MM:
        i = int(np.argmax(size))
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = float(np.median(np.linalg.norm(positions, axis=1) / np.linalg.norm(measured, axis=1)))
        unit = f" (commanded / measured distances from the origin: {ratio:.4g}, metres?)" if 300 < ratio < 3000 else ""
        raise PostprocError(f"uncompensated errors of {median:.4g} mm (median; line {lines[i]}: {size[i]:.4g} mm): "
                            f"the measured points are in another frame or unit{unit}: register them (--register, "
                            f"'# frame: tracker') or convert to mm", path, int(lines[i]), 1, "P509")
    far = np.flatnonzero(size > 10.0 * median + 5.0)
    if not len(far):
        return []
    shown = ", ".join(str(int(lines[i])) for i in far[:10]) + (" ..." if len(far) > 10 else "")
    return [f"warning: {len(far)} row(s) with an error far above the others' (median {median:.3f} mm): "
            f"line(s) {shown}"]


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
                            "(in degrees), or drop the columns", path, int(lines[i]), 1, "P515")


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

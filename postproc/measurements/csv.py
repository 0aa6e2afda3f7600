"""The measurement CSV: one module that reads it, writes it and names its columns.

The file (docs/ARCHITECTURE.md): header ``x,y,z,a,b,c,x_meas,y_meas,z_meas`` (mm, deg,
robot base frame; commanded TCP pose, measured TCP position), one row per visited pose in
visiting order. E = P_target − P_measured. Column names are matched case-insensitively and
in any order; extra columns (a point id, a timestamp) are ignored, except ``holdout`` (1 = a
row that an earlier registration did not see, see ``postproc import``) and ``q1..q6`` (the
controller's joint angles, deg); blank lines and lines starting with ``#`` are skipped, and
``# key: value`` lines before the header are kept as metadata (``# frame: tracker`` =
measured columns still in the tracker's frame; ``# tool: X,Y,Z,A,B,C`` = the TCP on the flange
every row was measured with). Columns ``tool_x, tool_y, tool_z, tool_a, tool_b, tool_c`` give
each row's TCP instead (data of several tools, which lets the identification separate the tool
mount's rotation): ``Measurements.tools``; which TCP training takes is ``training.data.measured_tools``.

Optional columns: ``a_meas,b_meas,c_meas`` (deg, KUKA A,B,C: a 6-DOF probe's measured TCP
orientation, same frame as x_meas..z_meas; all three or none, P501), ``q1..q6`` (deg, the
controller's joint angles), ``s,t`` (KUKA Status/Turn integers, used when q1..q6 are absent:
``postproc.robot.configuration`` turns them into joint angles), ``pose,cycle`` (a plan's labels of
each row, whole numbers ≥ 1: ``postproc plan --iso9283`` names the ISO 9283 poses P1…P5 so, and
``postproc measure`` carries them into its output: ``Measurements.labels``), ``campaign`` (a name
per row: the measurement set-up — tracker placement, day — it was measured in; each campaign
gets its own tracker → base frame in the fit: ``Measurements.campaigns``). Several files given
to one ``train`` are one data set of several campaigns (``combine_measurements``: each file a
campaign, or its own ``campaign`` column's, with its own ``# key: value`` lines).
Columns ``load_mass, load_cx, load_cy, load_cz`` (kg; mm in the flange frame): the load the robot
carried at each row (a campaign measured at two or three test loads): all four or none (P501),
a mass ≥ 0 (P502); ``Measurements.loads``, which ``train`` identifies the compliance under (a
load-aware model). The same pose at two loads is two measurements.

Codes: P500 unreadable/empty, P501 missing or misnamed column, P502 a value that is not a
finite number, P503 wrong number of fields, P504 duplicate pose.

Writers: ``postproc import`` (``write_measurements``: 12 significant digits), ``postproc
measure`` and ``training.synthetic`` (``measurement_csv`` with their own number formats).
numpy only: no torch here, so bad data is reported before torch is even loaded.
"""
from __future__ import annotations

import difflib
import hashlib
import io
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core.atomic import write_atomic
from ..core.diagnostics import P500, P501, P502, P503, P504, P512, PostprocError

__all__ = [
    "POSE_COLUMNS", "MEAS_COLUMNS", "COLUMNS", "TOOL_COLUMNS", "ORIENTATION_COLUMNS", "STATUS_TURN_COLUMNS",
    "LABEL_COLUMNS", "Measurements", "read_measurements", "parse_measurements", "parse_rows", "data_rows", "is_data",
    "label_columns",
    "read_metadata", "metadata_of", "measurement_csv", "write_measurements", "parse_tool", "CAMPAIGN_COLUMN", "combine_measurements",
    "LOAD_COLUMNS",
]

POSE_COLUMNS = ("x", "y", "z", "a", "b", "c")
MEAS_COLUMNS = ("x_meas", "y_meas", "z_meas")
COLUMNS = POSE_COLUMNS + MEAS_COLUMNS
TOOL_COLUMNS = ("tool_x", "tool_y", "tool_z", "tool_a", "tool_b", "tool_c")
ORIENTATION_COLUMNS = ("a_meas", "b_meas", "c_meas")
STATUS_TURN_COLUMNS = ("s", "t")
# a plan's labels of each row, carried by ``postproc measure``: the ISO 9283 pose (1…5 = P1…P5 as
# the plan names them) and the cycle (1…n)
LABEL_COLUMNS = ("pose", "cycle")
# the load carried at each row: mass (kg) and its centre of mass in the flange frame (mm)
LOAD_COLUMNS = ("load_mass", "load_cx", "load_cy", "load_cz")
# the measurement set-up (campaign) of each row: any name (a tracker placement, a day)
CAMPAIGN_COLUMN = "campaign"


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
    labels: dict[str, np.ndarray] = field(default_factory=dict)  # LABEL_COLUMNS present: [N] int each
    campaigns: np.ndarray | None = None  # [N] str: each row's campaign (set-up), None: one campaign
    # each campaign's file and '# key: value' lines: {name: {"path": str, "meta": dict}} (with ``campaigns``)
    campaign_files: dict = field(default_factory=dict)
    loads: np.ndarray | None = None  # [N, 4] from 'load_mass','load_cx'..'load_cz' (kg, mm flange), if there

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
        from ..core.frames import rotation_error_deg

        return rotation_error_deg(self.poses[:, 3:6], self.orientation)

    def __len__(self) -> int:
        return len(self.poses)


def read_measurements(path: str | Path) -> Measurements:
    """Read and check a measurement CSV; raise PostprocError (P5xx) at the first bad place."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise PostprocError(f"cannot read measurement file: {exc.strerror or exc}", str(path), code=P500) from exc
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
        raise PostprocError("empty measurement file (expected header " + ",".join(COLUMNS) + ")", path, code=P500)
    table, line_numbers = parse_rows(lines, first, header, index, path)
    if not len(table):
        raise PostprocError("measurement file has a header but no data rows", path, code=P500)
    joints = _joint_columns(lines, first, header, path)
    tools = _tool_columns(lines, first, header, path)
    orientation = _orientation_columns(lines, first, header, path)
    status_turn = _status_turn_columns(lines, first, header, path) if joints is None else None
    labels = label_columns(lines, first, header, path)
    campaigns = _campaign_column(lines, first, header, path)
    loads = _load_columns(lines, first, header, path)
    # the same pose in another arm configuration (joint angles a degree or more apart) or
    # with another tool is another measurement, not a repeat
    key = table[:, :6] if joints is None else np.c_[table[:, :6], np.round(joints)]
    key = key if tools is None else np.c_[key, tools]
    key = key if loads is None else np.c_[key, loads]  # (the same pose under another load: another measurement)
    if campaigns is not None:  # (the same pose measured in two set-ups is two measurements)
        key = np.c_[key, np.unique(campaigns, return_inverse=True)[1]]
    if not repeats:
        _check_duplicates(key, line_numbers, path)
    holdout = table[:, 9] != 0 if table.shape[1] > 9 else None
    files = {} if campaigns is None else {str(c): {"path": path, "meta": dict(meta)} for c in dict.fromkeys(campaigns)}
    return Measurements(table[:, :6].copy(), table[:, 6:9].copy(), line_numbers, sha, path, meta, holdout, joints,
                        tools, orientation, status_turn, labels, campaigns, files, loads)


def _load_columns(lines: list[str], first: int, header: list[str], path: str) -> np.ndarray | None:
    """The load of each row [N, 4] (kg, mm in the flange frame) from ``load_mass, load_cx,
    load_cy, load_cz``: all four or none (P501), finite numbers (P502), a mass ≥ 0 (P502)."""
    present = [name in header for name in LOAD_COLUMNS]
    if not any(present):
        return None
    if not all(present):
        missing = ", ".join(n for n, p in zip(LOAD_COLUMNS, present) if not p)
        raise PostprocError(f"missing column(s) {missing}: a row's load is {','.join(LOAD_COLUMNS)} (mass kg, its "
                            "centre of mass mm in the flange frame)", path, first + 1, 1, P501)
    index = [header.index(n) for n in LOAD_COLUMNS]
    values, numbers = parse_rows(lines, first, header, index, path)
    bad = np.flatnonzero(values[:, 0] < 0)
    if len(bad):
        raw = lines[int(numbers[bad[0]]) - 1]
        raise PostprocError(f"column 'load_mass': {values[bad[0], 0]:g} kg is not a mass (>= 0)", path,
                            int(numbers[bad[0]]), _field_starts(raw)[index[0]] + 1, P502)
    return values


def _campaign_column(lines: list[str], first: int, header: list[str], path: str) -> np.ndarray | None:
    """Each row's campaign name [N] str from the ``campaign`` column (any text but empty: P502)."""
    if CAMPAIGN_COLUMN not in header:
        return None
    k = header.index(CAMPAIGN_COLUMN)
    names = []
    for number, raw in data_rows(lines, first):
        fields = raw.split(",")
        name = fields[k].strip() if k < len(fields) else ""
        if not name:
            raise PostprocError("column 'campaign': empty: name the set-up each row was measured in", path, number,
                                _field_starts(raw)[k] + 1 if k < len(fields) else 1, P502)
        names.append(name)
    return np.asarray(names, dtype=object)


def combine_measurements(parts: Sequence[Measurements]) -> Measurements:
    """Several measurement files as one data set of several campaigns: each file's rows are its
    campaign (named after the file; a file with a ``campaign`` column keeps its names, after the
    file's), with the file's own ``# key: value`` lines (``campaign_files``). Columns that only some
    files have are left out (joint angles, orientations, S/T, labels, loads); tools: each file's
    ``tool_x..tool_c`` or ``# tool:`` line, all or none (P320 otherwise)."""
    from ..core.diagnostics import P320

    if len(parts) == 1:
        return parts[0]
    stems = [Path(p.path).stem for p in parts]
    names = stems if len(set(stems)) == len(stems) else [p.path for p in parts]
    campaigns, files = [], {}
    for name, part in zip(names, parts):
        if part.campaigns is None:
            campaigns.append(np.full(len(part), name, dtype=object))
            files[name] = {"path": part.path, "meta": dict(part.meta)}
        else:
            own = np.asarray([f"{name}:{c}" for c in part.campaigns], dtype=object)
            campaigns.append(own)
            files.update({f"{name}:{c}": v for c, v in part.campaign_files.items()})
    tools = [p.tools if p.tools is not None else (np.tile(parse_tool(p.meta["tool"]), (len(p), 1))
                                                 if "tool" in p.meta else None) for p in parts]
    if any(t is None for t in tools) and not all(t is None for t in tools):
        given = ", ".join(p.path for p, t in zip(parts, tools) if t is not None)
        raise PostprocError(f"{given} name the TCP their rows were measured with (tool_x..tool_c or '# tool:'), "
                            "the other files do not: give every file's tool or none", parts[0].path, code=P320)

    def joined(values):
        return None if any(v is None for v in values) else np.concatenate(values)

    sha = hashlib.sha256("".join(p.sha256 for p in parts).encode()).hexdigest()
    meta = {k: v for k, v in parts[0].meta.items() if all(p.meta.get(k) == v for p in parts)}
    meta.pop("frame", None)  # (each campaign's own: campaign_files)
    meta.pop("tool", None)
    return Measurements(np.concatenate([p.poses for p in parts]), np.concatenate([p.measured for p in parts]),
                        np.concatenate([p.lines for p in parts]), sha, " + ".join(p.path for p in parts), meta,
                        joined([p.holdout for p in parts]), joined([p.joints for p in parts]), joined(tools),
                        joined([p.orientation for p in parts]), joined([p.status_turn for p in parts]), {},
                        np.concatenate(campaigns), files, joined([p.loads for p in parts]))


def _tool_columns(lines: list[str], first: int, header: list[str], path: str) -> np.ndarray | None:
    """The TCP of each row [N, 6] from ``tool_x..tool_c``: all six (P501), finite numbers (P502)."""
    if not set(TOOL_COLUMNS) & set(header):
        return None
    missing = [n for n in TOOL_COLUMNS if n not in header]
    if missing:
        raise PostprocError(f"missing column(s) {', '.join(missing)}: a row's tool is {','.join(TOOL_COLUMNS)}",
                            path, first + 1, 1, P501)
    return parse_rows(lines, first, header, [header.index(n) for n in TOOL_COLUMNS], path)[0]


def _orientation_columns(lines: list[str], first: int, header: list[str], path: str) -> np.ndarray | None:
    """The measured orientation [N, 3] (deg) from ``a_meas,b_meas,c_meas``: all three or none
    (P501); each a finite number (P502): it is fitted, not an extra."""
    present = [name in header for name in ORIENTATION_COLUMNS]
    if not any(present):
        return None
    if not all(present):
        raise PostprocError(f"give all of {','.join(ORIENTATION_COLUMNS)} or none", path, first + 1, 1, P501)
    return parse_rows(lines, first, header, [header.index(n) for n in ORIENTATION_COLUMNS], path)[0]


def _status_turn_columns(lines: list[str], first: int, header: list[str], path: str) -> np.ndarray | None:
    """KUKA Status and Turn [N, 2] (ints) from ``s,t``: both or none (P501); each a whole
    number 0..63 (P502)."""
    present = [name in header for name in STATUS_TURN_COLUMNS]
    if not any(present):
        return None
    if not all(present):
        raise PostprocError("give both s and t (KUKA Status and Turn) or neither", path, first + 1, 1, P501)
    index = [header.index(n) for n in STATUS_TURN_COLUMNS]
    values, numbers = parse_rows(lines, first, header, index, path)
    bad = np.flatnonzero(((values != np.round(values)) | (values < 0) | (values > 63)).any(axis=1))
    if len(bad):
        k = int(np.argmax((values[bad[0]] != np.round(values[bad[0]])) | (values[bad[0]] < 0) | (values[bad[0]] > 63)))
        raw = lines[int(numbers[bad[0]]) - 1]
        raise PostprocError(f"column '{STATUS_TURN_COLUMNS[k]}': {values[bad[0], k]:g} is not a Status/Turn "
                            "(a whole number 0..63)", path, int(numbers[bad[0]]), _field_starts(raw)[index[k]] + 1, P502)
    return values.astype(np.int64)


def label_columns(lines: list[str], first: int, header: list[str], path: str) -> dict[str, np.ndarray]:
    """The plan's labels of each row (``LABEL_COLUMNS`` the header names: ``pose``, ``cycle``) as
    ints [N]; each a whole number ≥ 1 (P502 at the value)."""
    out = {}
    for name in (n for n in LABEL_COLUMNS if n in header):
        values, numbers = parse_rows(lines, first, header, [header.index(name)], path)
        bad = np.flatnonzero((values[:, 0] != np.round(values[:, 0])) | (values[:, 0] < 1))
        if len(bad):
            raw = lines[int(numbers[bad[0]]) - 1]
            raise PostprocError(f"column '{name}': {values[bad[0], 0]:g} is not a {name} number (a whole number "
                                "1, 2, …)", path, int(numbers[bad[0]]),
                                _field_starts(raw)[header.index(name)] + 1, P502)
        out[name] = values[:, 0].astype(np.int64)
    return out


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


def is_data(raw: str) -> bool:
    """A CSV line that holds the header or a row: not blank, not a ``#`` comment."""
    line = raw.strip()
    return bool(line) and not line.startswith("#")


def data_rows(lines: list[str], first: int) -> list[tuple[int, str]]:
    """(1-based line number, text) of each row after the header line ``lines[first]``: blank
    and ``#`` lines skipped."""
    return [(number, lines[number - 1]) for number in range(first + 2, len(lines) + 1) if is_data(lines[number - 1])]


def parse_rows(lines: list[str], first: int, header: list[str], index: list[int],
               path: str) -> tuple[np.ndarray, np.ndarray]:
    """The columns ``index`` of the rows after header line ``lines[first]`` as floats [N, len(index)]
    and their 1-based line numbers [N]; blank and ``#`` lines skipped. PostprocError with
    file:line:col on a row of another width (P503) or a value that is not a finite number (P502)."""
    rows, numbers = [], []
    for number, raw in data_rows(lines, first):
        fields = raw.split(",")
        if len(fields) != len(header):
            raise PostprocError(f"row has {len(fields)} fields, the header has {len(header)}", path, number, 1, P503)
        row = []
        for i in index:
            try:
                value = float(fields[i])
            except ValueError:
                value = math.nan
            if not math.isfinite(value):
                shown = fields[i].strip() or "(empty)"
                raise PostprocError(f"column '{header[i]}': '{shown}' is not a finite number",
                                    path, number, _field_starts(raw)[i] + 1, P502)
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
            raise PostprocError(f"column(s) {', '.join(duplicated)} appear more than once", path, line, 1, P501)
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
    raise PostprocError(message, path, line, col, P501)


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
            P504,
        )


def read_metadata(path: str | os.PathLike) -> dict[str, str]:
    """The ``# key: value`` lines at the top of a measurement CSV (keys lower-cased).

    ``read_metadata(p).get("frame", "base")`` is the frame of the measured columns.
    """
    with open(path, encoding="utf-8") as f:
        return metadata_of(f)


def metadata_of(lines) -> dict[str, str]:
    """The ``# key: value`` lines (keys lower-cased) at the top of ``lines`` (an iterable of
    text lines: a file's, a plan's), up to the first line that is not a comment."""
    meta: dict[str, str] = {}
    for line in lines:
        if not line.startswith("#"):
            break
        key, sep, value = line[1:].partition(":")
        if sep:
            meta[key.strip().lower()] = value.strip()
    return meta


def measurement_csv(
    commanded: np.ndarray,
    measured: np.ndarray,
    extra: dict[str, np.ndarray] | None = None,
    metadata: dict[str, str] | None = None,
    fmt: str | Sequence[str] = "%.12g",
) -> str:
    """The text of a measurement CSV: ``# key: value`` lines, header, one row per pose.

    ``commanded`` [N, 6] (mm, KUKA deg), ``measured`` [N, 3] (mm), ``extra`` columns [N]
    after the nine standard ones; ``fmt`` one printf format for every column or one per column.
    """
    extra = extra or {}
    names = list(COLUMNS) + list(extra)
    table = np.column_stack([commanded, measured] + [np.asarray(v, dtype=float) for v in extra.values()])
    text = io.StringIO()
    text.write("".join(f"# {key}: {value}\n" for key, value in (metadata or {}).items()))
    np.savetxt(text, table, fmt=fmt, delimiter=",", header=",".join(names), comments="")
    return text.getvalue()


def write_measurements(
    path: str | os.PathLike,
    commanded: np.ndarray,
    measured: np.ndarray,
    extra: dict[str, np.ndarray] | None = None,
    metadata: dict[str, str] | None = None,
) -> None:
    """Write a measurement CSV atomically (:func:`measurement_csv`). Numbers are written with 12
    significant digits, enough to keep every digit of the source data."""
    write_atomic([(Path(path), measurement_csv(commanded, measured, extra, metadata).encode("utf-8"))])


def parse_tool(text: str) -> np.ndarray:
    """``X,Y,Z,A,B,C`` (mm, deg) → [6]; PostprocError P512 otherwise."""
    try:
        tool = np.array([float(v) for v in str(text).split(",")])
    except ValueError:
        tool = np.zeros(0)
    if tool.shape != (6,) or not np.isfinite(tool).all():
        raise PostprocError(f"a tool is X,Y,Z,A,B,C (six numbers, mm and deg), not {text!r}", code=P512)
    return tool

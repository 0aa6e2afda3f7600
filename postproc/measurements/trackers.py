"""Measurements from the tools cells use → postproc's measurement CSV (``postproc import``).

Three formats besides the IPA data set (``datasets.py``), each a text table with comment lines
(``//``, ``#`` or ``;``) that may hold ``key: value`` metadata, one header row and one row per
measurement:

* ``spatialanalyzer``: a SpatialAnalyzer point export, columns point name (``Collection::Group::
  Point`` or the point's name alone, column ``name``/``point``/``target``; or no header: name,
  X, Y, Z per line), X, Y, Z; the robot's commanded poses come from a second file (``--poses``,
  postproc's plan CSV: ``x,y,z,a,b,c`` mm/deg in the robot base, optional ``name`` column),
  matched by name where both name their rows (the export's last ``::`` part against the plan's
  ``name``; the rows then in the plan's order, the visiting order), else by order (then the
  counts must agree);
* ``robodk``: a RoboDK-style calibration table, columns ``J1..J6`` (the robot's joint angles)
  and ``X, Y, Z`` (the measured TCP), an optional leading ``id``/``name``; the commanded pose
  is the nominal forward kinematics of the joints with the description's tool (``--robot``;
  ``--tool`` another TCP), written with ``q1..q6``;
* ``reflectors``: three-reflector flange measurements, columns ``x,y,z,a,b,c`` (commanded) and
  ``r1_x … r3_z`` (the three SMR centres measured), their places on the TCP frame in the
  metadata ``reflectors: x,y,z; x,y,z; x,y,z``; each row's measured TCP pose is the rigid fit
  of those three places onto the measured centres (``registration.fit_rigid``) → ``x_meas..
  z_meas`` and ``a_meas,b_meas,c_meas``; a row whose centres do not fit the stated places
  within ``reflector_tolerance`` (default 0.5 mm: a swapped or moved SMR) is refused at its line
  (place the three at unequal distances from each other: two swapped on an equilateral
  triangle fit as well as the right ones, turned over);

**Units and frame are stated in the file, or it is refused** (P530; no silent metres): a
``units:`` line (``mm`` or ``m`` or ``in``, and ``deg`` or ``rad`` where the file has angles) or
units in the header (``X [mm]``, ``J1 (deg)``); a ``frame:`` line, ``tracker`` (the measured
columns in the tracker's frame: ``train --register`` or ``import --register`` fits tracker →
base) or ``base`` (the robot base already). Metres and inches are converted to mm, radians to
degrees. A file of another shape is refused at its line and column (P501 columns, P502 a value,
P503 a row's width, P531 reflectors, P532 points and poses that do not match).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core.diagnostics import P500, P501, P502, P503, P530, P531, P532, PostprocError
from ..core.frames import MM

__all__ = ["FORMATS", "Imported", "read_spatial_analyzer", "read_robodk", "read_reflectors", "REFLECTOR_TOLERANCE_MM"]

FORMATS = ("spatialanalyzer", "robodk", "reflectors")
LENGTHS = {"mm": 1.0, "m": 1 / MM, "in": 25.4, "inch": 25.4}
ANGLES = {"deg": 1.0, "rad": 180.0 / np.pi}
FRAMES = ("tracker", "base")
REFLECTOR_TOLERANCE_MM = 0.5
_UNIT = re.compile(r"^(.*?)\s*[\[(]\s*([A-Za-z°]+)\s*[\])]\s*$")


@dataclass
class Imported:
    """What an importer read: ``commanded`` [N, 6] (mm, KUKA A,B,C deg, robot base), ``measured``
    [N, 3] mm in ``frame``, ``orientation`` [N, 3] A,B,C deg of the measured TCP (same frame) or
    None, ``extra`` columns, ``metadata`` for the CSV (frame, units, source)."""

    commanded: np.ndarray
    measured: np.ndarray
    frame: str
    orientation: np.ndarray | None = None
    extra: dict = field(default_factory=dict)
    metadata: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.commanded)


@dataclass
class _Table:
    path: str
    meta: dict  # key → (value, line)
    names: list[str]  # header names, lower case, units taken off
    units: list[str | None]  # each column's unit from the header
    rows: list[list[str]]
    lines: list[int]  # each row's line number
    starts: list[list[int]]  # each field's column (1-based)
    header_line: int

    def column(self, name: str) -> int | None:
        return self.names.index(name) if name in self.names else None

    def numbers(self, columns: list[int]) -> np.ndarray:
        """[N, k] floats of ``columns``; P502 at the first field that is not a finite number."""
        out = np.empty((len(self.rows), len(columns)))
        for r, (row, line, starts) in enumerate(zip(self.rows, self.lines, self.starts)):
            for k, c in enumerate(columns):
                try:
                    value = float(row[c])
                except ValueError:
                    value = float("nan")
                if not np.isfinite(value):
                    raise PostprocError(f"{self.names[c]}: {row[c].strip()!r} is not a finite number", self.path, line,
                                        starts[c], P502)
                out[r, k] = value
        return out


def _read(path: str | Path) -> str:
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise PostprocError(f"cannot read: {exc.strerror or exc}", str(path), code=P500) from None
    return data.removeprefix(b"\xef\xbb\xbf").decode("latin-1")


def _split(line: str, sep: str | None) -> tuple[list[str], list[int]]:
    """Fields of ``line`` and their 1-based columns (``sep`` None: whitespace)."""
    if sep is None:
        found = list(re.finditer(r"\S+", line))
        return [m.group(0) for m in found], [m.start() + 1 for m in found]
    fields, starts, at = [], [], 0
    for part in line.split(sep):
        fields.append(part.strip())
        starts.append(at + len(part) - len(part.lstrip()) + 1)
        at += len(part) + 1
    return fields, starts


def _table(path: str | Path, header: bool = True) -> _Table:
    """Comment lines (metadata), the header row (``header``; else none: name, x, y, z) and the rows."""
    path = str(path)
    meta: dict = {}
    rows, lines, starts = [], [], []
    names: list[str] | None = None
    units: list[str | None] = []
    sep = None
    header_line = 0
    for n, raw in enumerate(_read(path).splitlines(), 1):
        line = raw.strip()
        if not line:
            continue
        comment = next((p for p in ("//", "#", ";") if line.startswith(p)), None)
        if comment is not None:
            key, colon, value = line[len(comment):].partition(":")
            if colon and key.strip():
                meta[key.strip().lower()] = (value.strip(), n)
            continue
        if sep is None and names is None:
            sep = next((s for s in (",", ";", "\t") if s in raw), None)
        fields, at = _split(raw, sep)
        if names is None:
            if header:
                names, units = [], []
                for f in fields:
                    m = _UNIT.match(f)
                    names.append((m.group(1) if m else f).strip().lower())
                    units.append(m.group(2).lower().replace("°", "deg") if m else None)
                header_line = n
                continue
            names, units = ["name", "x", "y", "z"], [None] * 4
        if len(fields) != len(names):
            raise PostprocError(f"{len(fields)} fields, the header has {len(names)} ({', '.join(names)})", path, n,
                                1, P503)
        rows.append(fields)
        lines.append(n)
        starts.append(at)
    if names is None or not rows:
        raise PostprocError("no rows", path, code=P500)
    return _Table(path, meta, names, units, rows, lines, starts, header_line)


def _stated(table: _Table, columns: list[int], kind: str) -> float:
    """The factor to mm (``kind`` "length") or deg ("angle") of ``columns``: from the header's
    units, else the ``units:`` line; P530 where neither states it."""
    known = LENGTHS if kind == "length" else ANGLES
    given = {table.units[c] for c in columns if table.units[c] is not None}
    if len(given) > 1:
        raise PostprocError(f"the {kind} columns state different units {sorted(given)}", table.path, table.header_line,
                            1, P530)
    if given:
        unit = given.pop()
        if unit not in known:
            raise PostprocError(f"unit {unit!r} of {table.names[columns[0]]}: expected one of {', '.join(known)}",
                                table.path, table.header_line, 1, P530)
        return known[unit]
    value, line = table.meta.get("units", (None, 0))
    words = [w for w in re.split(r"[\s,;/]+", (value or "").lower()) if w]
    unit = next((w for w in words if w in known), None)
    if unit is None:
        what = "mm, m or in" if kind == "length" else "deg or rad"
        raise PostprocError(f"the file does not state the units of its {kind}s ({what}): add a line "
                            f"'// units: {'mm' if kind == 'length' else 'mm, deg'}' or units in the header "
                            "('X [mm]'); postproc does not guess them", table.path, line or table.header_line or 1,
                            1, P530)
    return known[unit]


def _frame(table: _Table) -> str:
    value, line = table.meta.get("frame", (None, 0))
    if value is None or value.lower() not in FRAMES:
        said = f" ({value!r})" if value is not None else ""
        raise PostprocError(f"the file does not state the frame of its measurements{said}: add a line '// frame: "
                            "tracker' (the tracker's own frame: import or train with --register) or '// frame: base' "
                            "(the robot base)", table.path, line or table.header_line or 1, 1, P530)
    return value.lower()


def _columns(table: _Table, wanted: list[str], what: str) -> list[int]:
    missing = [w for w in wanted if w not in table.names]
    if missing:
        raise PostprocError(f"not a {what}: no column {', '.join(missing)} (has {', '.join(table.names)})",
                            table.path, table.header_line or 1, 1, P501)
    return [table.names.index(w) for w in wanted]


def _source(path, what: str, n: int) -> str:
    return f"{Path(path).name} ({what}, {n} rows)"


# --------------------------------------------------------------------------- SpatialAnalyzer

_NAME_COLUMNS = ("name", "point", "point name", "target", "id")


def read_spatial_analyzer(points: str | Path, poses: str | Path) -> Imported:
    """A SpatialAnalyzer point export (``points``) and the commanded poses (``poses``: a plan CSV)."""
    first = next((ln.strip() for ln in _read(points).splitlines()
                  if ln.strip() and not ln.strip().startswith(("//", "#", ";"))), "")
    fields = re.split(r"[,;\t]|\s+", first)
    header = not all(_is_number(f) for f in fields[1:4]) if len(fields) >= 4 else True
    table = _table(points, header=header)
    name_col = next((table.names.index(c) for c in _NAME_COLUMNS if c in table.names), None)
    if name_col is None and "collection" not in table.names:
        raise PostprocError(f"not a SpatialAnalyzer point export: no point name column ({' / '.join(_NAME_COLUMNS)}; "
                            f"has {', '.join(table.names)})", str(points), table.header_line or 1, 1, P501)
    xyz = _columns(table, ["x", "y", "z"], "SpatialAnalyzer point export")
    scale = _stated(table, xyz, "length")
    frame = _frame(table)
    measured = table.numbers(xyz) * scale
    names = [row[name_col].split("::")[-1].strip() if name_col is not None else "" for row in table.rows]

    plan = _table(poses)
    pose_cols = _columns(plan, ["x", "y", "z", "a", "b", "c"], "plan CSV (the commanded poses)")
    commanded = plan.numbers(pose_cols)
    plan_names = [row[plan.column("name")].strip() for row in plan.rows] if plan.column("name") is not None else None
    if plan_names is not None and all(names):
        where = {}
        for name, line in zip(plan_names, plan.lines):
            if name in where:
                raise PostprocError(f"pose name {name!r} twice (line {where[name]})", str(poses), line, 1, P532)
            where[name] = line
        index = {name: i for i, name in enumerate(plan_names)}
        order = []
        for name, line in zip(names, table.lines):
            if name not in index:
                raise PostprocError(f"point {name!r} names no pose of {poses}", str(points), line, 1, P532)
            order.append(index[name])
        if len(set(order)) != len(order):
            seen = set()
            line = next(ln for i, ln in zip(order, table.lines) if i in seen or seen.add(i))
            raise PostprocError("a pose measured twice: average repeated measurements into one row", str(points),
                                line, 1, P532)
        # rows in the plan's order: the visiting order (the approach directions a model learns)
        visit = np.argsort(order, kind="stable")
        commanded, measured, how = commanded[np.asarray(order)[visit]], measured[visit], "by name"
    else:
        if len(commanded) != len(measured):
            raise PostprocError(f"{len(measured)} points but {len(commanded)} poses in {poses}: without names on both "
                                "sides they are matched by order, so the counts must agree", str(points),
                                table.lines[-1], 1, P532)
        how = "by order"
    meta = {"frame": frame, "units": "mm, deg (converted from the export's)" if scale != 1.0 else "mm, deg",
            "source": _source(points, f"SpatialAnalyzer points, matched to {Path(poses).name} {how}", len(measured))}
    return Imported(commanded, measured, frame, metadata=meta)


def _is_number(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False


# --------------------------------------------------------------------------- RoboDK


def read_robodk(path: str | Path, description=None, tool: np.ndarray | None = None) -> Imported:
    """A RoboDK-style calibration table: J1..J6 and the measured X, Y, Z; the commanded pose is
    the nominal FK of the joints (``description``: a ``robot.RobotDescription``, default the
    shipped KR500's; ``tool`` [6]: the TCP on the flange, default the description's)."""
    from dataclasses import replace

    from ..robot.arm import Robot
    from ..robot.description import load_description

    table = _table(path)
    joints = _columns(table, [f"j{i}" for i in range(1, 7)], "RoboDK calibration table")
    xyz = _columns(table, ["x", "y", "z"], "RoboDK calibration table")
    scale = _stated(table, xyz, "length")
    angle = _stated(table, joints, "angle")
    frame = _frame(table)
    q = table.numbers(joints) * angle
    measured = table.numbers(xyz) * scale
    description = description if description is not None else load_description()
    if tool is not None:
        description = replace(description, tool=np.asarray(tool, float))
    commanded = Robot(description).fk(q)
    meta = {"frame": frame, "units": "mm, deg", "robot": description.name,
            "tool": ",".join(f"{v:g}" for v in description.tool),
            "commanded": f"the nominal forward kinematics of J1..J6 ({description.name}, its tool)",
            "source": _source(path, "RoboDK-style calibration table", len(q))}
    return Imported(commanded, measured, frame, extra={f"q{i + 1}": q[:, i] for i in range(6)}, metadata=meta)


# --------------------------------------------------------------------------- three reflectors


def _reflector_places(table: _Table) -> np.ndarray:
    value, line = table.meta.get("reflectors", (None, 0))
    if value is None:
        raise PostprocError("the file does not state where its three reflectors sit on the TCP frame: add a line "
                            "'// reflectors: x,y,z; x,y,z; x,y,z' (mm)", table.path, table.header_line or 1, 1, P531)
    try:
        places = np.array([[float(v) for v in part.split(",")] for part in value.split(";")], float)
    except ValueError:
        places = np.zeros((0, 0))
    if places.shape != (3, 3) or not np.isfinite(places).all():
        raise PostprocError(f"reflectors: {value!r} is not three points x,y,z; x,y,z; x,y,z", table.path, line, 1, P531)
    return places


def read_reflectors(path: str | Path, tolerance_mm: float | None = None) -> Imported:
    """Three-reflector flange measurements: each row's TCP pose from its three SMR centres."""
    from ..core import frames
    from ..core.frames import nearest_triple
    from ..core.registration import fit_rigid

    table = _table(path)
    pose_cols = _columns(table, ["x", "y", "z", "a", "b", "c"], "three-reflector table")
    smr = _columns(table, [f"r{k}_{c}" for k in (1, 2, 3) for c in "xyz"], "three-reflector table")
    scale = _stated(table, smr, "length")
    frame = _frame(table)
    value, line = table.meta.get("reflector_tolerance", (None, 0))
    if tolerance_mm is None:
        tolerance_mm = REFLECTOR_TOLERANCE_MM if value is None else float(value.split()[0])
    places = _reflector_places(table)
    try:
        fit_rigid(places, places)
    except PostprocError as exc:
        raise PostprocError(f"reflectors: {exc.message}", table.path, table.meta["reflectors"][1], 1, P531) from None
    commanded = table.numbers(pose_cols)
    commanded[:, :3] *= _stated(table, pose_cols[:3], "length")
    commanded[:, 3:] *= _stated(table, pose_cols[3:], "angle")
    centres = (table.numbers(smr) * scale).reshape(-1, 3, 3)
    measured = np.empty((len(commanded), 3))
    rotations = np.empty((len(commanded), 3, 3))
    for r, (points, line) in enumerate(zip(centres, table.lines)):
        rotation, origin = fit_rigid(places, points)
        worst = float(np.linalg.norm(points - (places @ rotation.T + origin), axis=1).max())
        if worst > tolerance_mm:
            raise PostprocError(f"the three reflectors do not fit their places on the TCP frame: {worst:.3f} mm off "
                                f"(> {tolerance_mm:g} mm): a swapped, moved or mis-measured SMR", table.path, line,
                                table.starts[r][smr[0]], P531)
        measured[r], rotations[r] = origin, rotation
    orientation = nearest_triple(frames.abc_from_rotation(rotations), commanded[:, 3:6])
    meta = {"frame": frame, "units": "mm, deg",
            "reflectors": "; ".join(",".join(f"{v:g}" for v in p) for p in places) + " (on the TCP frame, mm)",
            "source": _source(path, "three-reflector flange measurements", len(commanded))}
    return Imported(commanded, measured, frame, orientation=orientation, metadata=meta)

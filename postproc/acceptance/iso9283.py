"""The ISO 9283 pose test: its test cube and points, the plan, and pose accuracy / repeatability.

ISO 9283:1998 (manipulating industrial robots, performance criteria) tests a robot's pose
characteristics in a cube placed in the working space:

* the cube is the largest one of the stated working space (here: an axis-parallel cube in
  the workspace box, shrunk about its centre until its test points are reachable) or a
  given one (centre and side);
* the test plane is a diagonal plane of the cube: here the plane through the cube's lower
  edge at Y0 and its upper edge at Y1, both along X; its corners, in this module's
  numbering, are C1 = (X0,Y0,Z0), C2 = (X1,Y0,Z0), C3 = (X1,Y1,Z1), C4 = (X0,Y1,Z1);
* P1 is the centre of the cube; P2…P5 lie on the plane's diagonals at 10 % of the
  diagonal's length from C1…C4;
* each cycle visits P1 → P5 → P4 → P3 → P2 (every pose approached from the same side), and
  the test runs n = 30 cycles; all poses have the same (working) attitude.

For each pose j = 1…n attained (x_j, y_j, z_j) with command (x_c, y_c, z_c), ISO 9283 §7.2.1
(pose accuracy) takes the barycentre x̄ = (1/n)·Σ x_j (likewise ȳ, z̄) and

    AP_P = √((x̄ − x_c)² + (ȳ − y_c)² + (z̄ − z_c)²),  AP_x = x̄ − x_c, AP_y = ȳ − y_c, AP_z = z̄ − z_c,
    AP_a = ā − a_c, AP_b = b̄ − b_c, AP_c = c̄ − c_c   (orientation, where it was measured);

§7.2.2 (pose repeatability) takes the distance of each attained position from the barycentre
l_j = √((x_j − x̄)² + (y_j − ȳ)² + (z_j − z̄)²), its mean l̄ and S_l = √(Σ (l_j − l̄)² / (n − 1)):

    RP_l = l̄ + 3·S_l,  RP_a = ±3·S_a with S_a = √(Σ (a_j − ā)² / (n − 1))  (likewise b, c).

When the commands of one pose are not bit-identical (a data set whose planner jittered them
by a fraction of a millimetre, as IPA Series D), the same formulas are applied to the
deviations d_j = attained_j − command_j: x̄ − x_c becomes the mean of d_j, and l_j the distance
of d_j from that mean. With identical commands this is exactly the standard's figure.
Orientation deviations a_j − a_c, b_j − b_c, c_j − c_c are taken as rotations about the base
X, Y, Z axes (the rotation vector of R_attained·R_commandᵀ, :func:`orientation_deviation`),
not as differences of KUKA A, B, C, which are undefined at the usual B = 90° attitude.
numpy only.
"""
from __future__ import annotations

import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.diagnostics import P335, P500, P502, P503, P512, P513, PostprocError

__all__ = [
    "ISO_CYCLES",
    "CYCLE_ORDER",
    "ORIENTATION_COLUMNS",
    "IsoCube",
    "largest_cube",
    "pose_test_plan",
    "iso_test",
    "iso_plan_csv_text",
    "cluster_poses",
    "orientation_deviation",
    "PoseFigures",
    "pose_figures",
    "IsoResult",
    "read_iso_result",
    "iso_summary",
    "iso_markdown",
]

ISO_CYCLES = 30
CYCLE_ORDER = (1, 5, 4, 3, 2)  # P1 → P5 → P4 → P3 → P2
CORNER_FRACTION = 0.10  # P2…P5 at 10 % of the plane's diagonal from its corners
ORIENTATION_COLUMNS = ("a_meas", "b_meas", "c_meas")
POSITION_TOLERANCE_MM = 1.0  # rows whose commands lie closer than this are one pose …
ATTITUDE_TOLERANCE_DEG = 0.5  # … if their A, B, C also agree within this


@dataclass(frozen=True)
class IsoCube:
    """An axis-parallel test cube (robot base frame, mm)."""

    centre: tuple[float, float, float]
    side: float

    @property
    def plane_corners(self) -> np.ndarray:
        """[4, 3] corners C1…C4 of the test plane (the diagonal plane from the lower edge at Y0
        to the upper edge at Y1)."""
        c, h = np.asarray(self.centre, float), self.side / 2.0
        signs = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, 1], [-1, 1, 1]], float)
        return c + h * signs

    def points(self) -> np.ndarray:
        """[5, 3] P1 (centre) … P5; P(k+2) at 10 % of the diagonal from corner C(k+1)."""
        corners = self.plane_corners
        opposite = corners[[2, 3, 0, 1]]
        near = corners + CORNER_FRACTION * (opposite - corners)
        return np.vstack([np.asarray(self.centre, float), near])


def largest_cube(box, reachable=None, attitude=(0.0, 90.0, 0.0), shrink: float = 0.95,
                 min_fraction: float = 0.1) -> IsoCube:
    """The largest cube of the working space ``box`` (X0 X1 Y0 Y1 Z0 Z1 mm) whose test points
    the robot reaches: the box's largest axis-parallel cube, centred in it, shrunk about its
    centre by ``shrink`` while ``reachable`` ([N, 6] poses → [N] bool) refuses a point.
    P335 when even ``min_fraction`` of the side does not fit."""
    box = np.asarray(box, float)
    if box.shape != (6,) or np.any(box[1::2] <= box[0::2]):
        raise PostprocError(f"working space must be X0 X1 Y0 Y1 Z0 Z1 with X0 < X1 etc., got {box.tolist()}",
                            code=P512)
    centre = tuple(float(v) for v in (box[0::2] + box[1::2]) / 2.0)
    full = float(np.min(box[1::2] - box[0::2]))
    side = full
    while True:
        cube = IsoCube(centre, side)
        if reachable is None or bool(np.all(reachable(_with_attitude(cube.points(), attitude)))):
            return cube
        side *= shrink
        if side < min_fraction * full:
            raise PostprocError(f"no test cube of at least {min_fraction:.0%} of the working space's {full:g} mm "
                                "has all of P1..P5 within reach: give --cube or another --box", code=P335)


def _with_attitude(points: np.ndarray, attitude) -> np.ndarray:
    return np.hstack([points, np.broadcast_to(np.asarray(attitude, float), (len(points), 3))])


def pose_test_plan(cube: IsoCube, attitude=(0.0, 90.0, 0.0), cycles: int = ISO_CYCLES) -> tuple[np.ndarray, np.ndarray]:
    """The test's visiting order: ``cycles`` × (P1, P5, P4, P3, P2) at ``attitude``.
    Returns poses [5·cycles, 6] and their pose numbers [5·cycles] (1…5)."""
    if cycles < 1:
        raise PostprocError(f"an ISO 9283 test needs at least 1 cycle, got {cycles}", code=P512)
    order = np.tile(np.array(CYCLE_ORDER), cycles)
    poses = _with_attitude(cube.points()[order - 1], attitude)
    return poses, order


def iso_test(box, attitude, reachable=None, cube: IsoCube | None = None,
             cycles: int = ISO_CYCLES) -> tuple[IsoCube, np.ndarray, np.ndarray]:
    """The whole test plan: ``cube`` (or the largest reachable one of ``box``), its poses in
    visiting order and their pose numbers (see :func:`pose_test_plan`). P335 if a given cube's
    points are out of reach."""
    if cube is None:
        cube = largest_cube(box, reachable, attitude)
    elif not cube.side > 0:
        raise PostprocError(f"the test cube's side must be positive, got {cube.side:g}", code=P512)
    elif reachable is not None:
        ok = np.asarray(reachable(_with_attitude(cube.points(), attitude)))
        if not ok.all():
            raise PostprocError(f"P{int(np.flatnonzero(~ok)[0]) + 1} of the given cube is out of reach", code=P335)
    poses, numbers = pose_test_plan(cube, attitude, cycles)
    return cube, poses, numbers


def iso_plan_csv_text(poses: np.ndarray, pose_numbers: np.ndarray) -> str:
    """The plan CSV (x,y,z,a,b,c as planning writes them) with two more columns: ``pose``
    (1…5 = P1…P5) and ``cycle`` (1…n). Readers of plans ignore the extra columns."""
    from ..calibration.planning import DEG_DECIMALS, MM_DECIMALS, POSE_COLUMNS, round_poses

    pose_numbers = np.asarray(pose_numbers, int)
    cycle = np.cumsum(pose_numbers == pose_numbers[0])
    buf = io.StringIO()
    fmt = [f"%.{MM_DECIMALS}f"] * 3 + [f"%.{DEG_DECIMALS}f"] * 3 + ["%d", "%d"]
    np.savetxt(buf, np.column_stack([round_poses(poses), pose_numbers, cycle]), fmt=fmt, delimiter=",",
               header=",".join(POSE_COLUMNS + ("pose", "cycle")), comments="")
    return buf.getvalue()


# --------------------------------------------------------------------------- clustering


def cluster_poses(commanded: np.ndarray, position_mm: float = POSITION_TOLERANCE_MM,
                  attitude_deg: float = ATTITUDE_TOLERANCE_DEG, chunk: int = 2048) -> np.ndarray:
    """Rows [N, 6] → pose labels [N] (0…K−1, numbered by first appearance): rows belong to one
    nominal pose when a chain of rows links them, each link closer than ``position_mm`` and
    with orientations less than ``attitude_deg`` apart (the angle of R₁ᵀR₂, so that two A,B,C
    triples of one rotation — at B = ±90° A and C trade — are one pose). Connected components
    by label propagation over chunked distance blocks."""
    from ..core.frames import rotation_from_abc

    poses = np.asarray(commanded, float)
    n = len(poses)
    flat = rotation_from_abc(poses[:, 3:]).reshape(n, 9)  # trace(R1ᵀ R2) = flat1 · flat2
    cos_limit = 1.0 + 2.0 * math.cos(math.radians(attitude_deg))
    labels = np.arange(n)
    while True:
        new = labels.copy()
        for start in range(0, n, chunk):
            block = slice(start, start + chunk)
            near = (np.linalg.norm(poses[block, None, :3] - poses[None, :, :3], axis=2) < position_mm) & \
                   (flat[block] @ flat.T > cos_limit)
            new[block] = np.where(near, labels[None, :], n).min(axis=1)
        new = new[new]  # pointer jumping: follow the smallest label one more step
        if np.array_equal(new, labels):
            break
        labels = new
    _, first, inverse = np.unique(labels, return_index=True, return_inverse=True)
    rank = np.argsort(np.argsort(first))  # clusters numbered by the row where each first appears
    return rank[inverse.ravel()]


def orientation_deviation(commanded_abc: np.ndarray, attained_abc: np.ndarray) -> np.ndarray:
    """[N, 3] deg: the attained orientation's deviation from the command as rotations about the
    base X, Y, Z axes (rotation vector of R_attained·R_commandᵀ). For the small deviations of a
    pose test these are the a, b, c deviations about the base axes, and they stay defined at
    B = ±90°, where KUKA's A and C (and so ā − a_c) are not."""
    from ..core.frames import rotation_error_deg

    return rotation_error_deg(np.asarray(commanded_abc, float), np.asarray(attained_abc, float))


# --------------------------------------------------------------------------- figures


@dataclass
class PoseFigures:
    """ISO 9283 figures of every pose (arrays over K poses; mm, deg)."""

    n: np.ndarray  # [K] cycles measured
    command: np.ndarray  # [K, 6] mean commanded position, the first row's A, B, C
    ap_xyz: np.ndarray  # [K, 3] APx, APy, APz
    ap: np.ndarray  # [K] AP_P
    l_mean: np.ndarray  # [K] l̄
    s_l: np.ndarray  # [K] S_l (NaN for n < 2)
    rp: np.ndarray  # [K] RP_l = l̄ + 3·S_l (NaN for n < 2)
    ap_abc: np.ndarray | None = None  # [K, 3] APa, APb, APc
    rp_abc: np.ndarray | None = None  # [K, 3] RPa, RPb, RPc (±, the value given is 3·S)
    numbers: np.ndarray | None = None  # [K] each pose's number (P1…P5 of a plan's pose column); None: 1…K

    def __len__(self) -> int:
        return len(self.n)

    def number(self, k: int) -> int:
        """The k-th pose's number: the plan's (its ``pose`` column) or, without one, k + 1 (the
        poses numbered by first appearance)."""
        return k + 1 if self.numbers is None else int(self.numbers[k])

    def name(self, k: int) -> str:
        return f"P{self.number(k)}"


def _group_mean(values: np.ndarray, labels: np.ndarray, k: int, counts: np.ndarray) -> np.ndarray:
    out = np.stack([np.bincount(labels, weights=values[:, i], minlength=k) for i in range(values.shape[1])], axis=1)
    return out / counts[:, None]


def _group_std(values: np.ndarray, labels: np.ndarray, k: int, counts: np.ndarray) -> np.ndarray:
    """Sample std (n − 1) per group and column of ``values`` [N, m] (NaN for n < 2)."""
    mean = _group_mean(values, labels, k, counts)
    squares = _group_mean((values - mean[labels]) ** 2, labels, k, counts) * counts[:, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(counts[:, None] > 1, np.sqrt(squares / (counts[:, None] - 1)), math.nan)


def pose_figures(commanded: np.ndarray, attained: np.ndarray, labels: np.ndarray,
                 attained_abc: np.ndarray | None = None, numbers: np.ndarray | None = None) -> PoseFigures:
    """AP and RP of each pose (ISO 9283:1998 §7.2.1 and §7.2.2, formulas in the module
    docstring) from commands [N, 6], attained positions [N, 3] (robot base frame), pose
    labels [N] (0…K−1), if measured, attained A, B, C [N, 3], and the poses' ``numbers`` [K]
    (their names P<number>; None: 1…K)."""
    commanded, attained = np.asarray(commanded, float), np.asarray(attained, float)
    labels = np.asarray(labels, int)
    k = int(labels.max()) + 1
    counts = np.bincount(labels, minlength=k).astype(float)
    d = attained - commanded[:, :3]  # deviation of each attained position from its command
    ap_xyz = _group_mean(d, labels, k, counts)  # x̄ − x_c …
    l = np.linalg.norm(d - ap_xyz[labels], axis=1)  # l_j: distance from the barycentre
    l_mean = _group_mean(l[:, None], labels, k, counts)[:, 0]
    s_l = _group_std(l[:, None], labels, k, counts)[:, 0]
    command = commanded[:, :3].copy()
    attitude = commanded[np.unique(labels, return_index=True)[1], 3:]  # the first row's A,B,C: a valid rotation
    figures = PoseFigures(
        n=counts.astype(int),
        command=np.hstack([_group_mean(command, labels, k, counts), attitude]),
        ap_xyz=ap_xyz,
        ap=np.linalg.norm(ap_xyz, axis=1),
        l_mean=l_mean,
        s_l=s_l,
        rp=l_mean + 3.0 * s_l,
        numbers=None if numbers is None else np.asarray(numbers, int),
    )
    if attained_abc is not None:
        da = orientation_deviation(commanded[:, 3:], attained_abc)
        figures.ap_abc = _group_mean(da, labels, k, counts)
        figures.rp_abc = 3.0 * _group_std(da, labels, k, counts)
    return figures


# --------------------------------------------------------------------------- measured files


@dataclass
class IsoResult:
    """An ISO 9283 evaluation of one measurement (and, with ``after``, of the compensated run)."""

    source: str
    source_sha256: str
    labels: np.ndarray  # [N] pose of each row (0…K−1; its name: ``before.name``)
    before: PoseFigures
    deviation: np.ndarray  # [N, 3] attained − command, before compensation
    after: PoseFigures | None = None
    deviation_after: np.ndarray | None = None  # [N, 3] attained with compensation − nominal command
    after_source: str = ""
    after_sha256: str = ""
    meta: dict | None = None

    @property
    def poses(self) -> int:
        return len(self.before)


def _orientation_columns(data: bytes, lines: np.ndarray, path: str) -> np.ndarray | None:
    """``a_meas,b_meas,c_meas`` at the rows of file ``lines``, if the header names all three."""
    from .report import _optional_columns

    found = _optional_columns(data, path, ORIENTATION_COLUMNS)
    if found is None:
        return None
    text, index = found
    rows = [text[line - 1].split(",") for line in lines.tolist()]
    try:
        out = np.array([[float(r[i]) for i in index] for r in rows])
    except (ValueError, IndexError):
        out = np.full((len(rows), 3), math.nan)
    bad = np.flatnonzero(~np.isfinite(out).all(axis=1))
    if len(bad):
        raise PostprocError("a_meas/b_meas/c_meas is not a finite number", path, int(lines[bad[0]]), 1, P502)
    return out


def _read(path: Path):
    from ..measurements.csv import parse_measurements

    try:
        data = path.read_bytes()
    except OSError as exc:
        raise PostprocError(f"cannot read measurement file: {exc.strerror or exc}", str(path), code=P500) from None
    m = parse_measurements(data, str(path), repeats=True)
    frame = m.meta.get("frame", "base")
    if frame != "base":
        raise PostprocError(f"measured positions are in the {frame}'s frame, not the robot base frame: pose accuracy "
                            "needs them in the base frame (postproc import ... --register)", str(path), 1, 1, P513)
    return data, m


def _pose_labels(m, path: str, position_mm: float, attitude_deg: float) -> tuple[np.ndarray, np.ndarray | None]:
    """Each row's pose (0…K−1) and the poses' numbers: the plan's ``pose`` column where the file
    has it (``postproc measure`` carries it from ``plan --iso9283``: P1…P5 as the standard and the
    plan name them), each number one commanded pose (P503 where a number labels rows the
    clustering puts apart, or one pose carries two numbers); else the rows clustered to their
    nominal poses, numbered by first appearance (numbers None)."""
    clusters = cluster_poses(m.poses, position_mm, attitude_deg)
    given = m.labels.get("pose")
    if given is None:
        return clusters, None
    numbers, labels = np.unique(given, return_inverse=True)
    labels = labels.reshape(-1)
    for mine, theirs, what in ((labels, clusters, "rows of different commanded poses"),
                               (clusters, labels, "one commanded pose by different numbers")):
        for k in np.unique(mine):  # every row of one value of ``mine`` has one value of ``theirs``
            rows = np.flatnonzero(mine == k)
            apart = rows[theirs[rows] != theirs[rows[0]]]
            if len(apart):
                raise PostprocError(f"column 'pose' names {what} (lines {int(m.lines[rows[0]])} and "
                                    f"{int(m.lines[apart[0]])}): it must be the plan's", path,
                                    int(m.lines[apart[0]]), 1, P503)
    return labels.reshape(-1), numbers


def read_iso_result(path: str | Path, after: str | Path | None = None,
                    position_mm: float = POSITION_TOLERANCE_MM,
                    attitude_deg: float = ATTITUDE_TOLERANCE_DEG) -> IsoResult:
    """Cluster the rows of a measurement CSV to their nominal poses and compute each pose's
    AP/RP; with ``after`` (the compensated program measured in the same row order, as
    ``postproc report --after``) the same figures of the compensated run, against the
    nominal commands of ``path``."""
    import hashlib

    path = Path(path)
    data, m = _read(path)
    labels, numbers = _pose_labels(m, str(path), position_mm, attitude_deg)
    before = pose_figures(m.poses, m.measured, labels, _orientation_columns(data, m.lines, str(path)), numbers)
    result = IsoResult(str(path), hashlib.sha256(data).hexdigest(), labels, before, m.measured - m.poses[:, :3],
                       meta=m.meta)
    if after is not None:
        from .report import _reached_after

        after = Path(after)
        after_data, am = _read(after)
        reached = _reached_after(after, m.poses, am)  # am: read once, above
        abc = _orientation_columns(after_data, am.lines, str(after))
        result.after = pose_figures(m.poses, reached, labels, abc, numbers)
        result.deviation_after = reached - m.poses[:, :3]
        result.after_source, result.after_sha256 = str(after), hashlib.sha256(after_data).hexdigest()
    return result


def _figures_dict(f: PoseFigures) -> list[dict]:
    rows = []
    for k in range(len(f)):
        row = {"pose": f.number(k), "n": int(f.n[k]), "command": f.command[k].round(4).tolist(),
               "APx": float(f.ap_xyz[k, 0]), "APy": float(f.ap_xyz[k, 1]), "APz": float(f.ap_xyz[k, 2]),
               "AP": float(f.ap[k]), "l_mean": float(f.l_mean[k]), "S_l": _num(f.s_l[k]), "RP": _num(f.rp[k])}
        if f.ap_abc is not None:
            row.update({f"AP{c}": float(f.ap_abc[k, i]) for i, c in enumerate("abc")})
            row.update({f"RP{c}": _num(f.rp_abc[k, i]) for i, c in enumerate("abc")})
        rows.append(row)
    return rows


def _num(v: float) -> float | None:
    return None if not np.isfinite(v) else float(v)


def iso_summary(result: IsoResult) -> dict:
    """The ISO figures as JSON-ready numbers: per pose, and the worst pose (max AP, max RP)."""
    def overall(f: PoseFigures) -> dict:
        rp = f.rp[np.isfinite(f.rp)]
        out = {"AP_max": float(f.ap.max()), "AP_mean": float(f.ap.mean()),
               "RP_max": float(rp.max()) if rp.size else None, "cycles_min": int(f.n.min()),
               "cycles_max": int(f.n.max())}
        if f.ap_abc is not None:
            out.update({f"AP{c}_max_abs": float(np.abs(f.ap_abc[:, i]).max()) for i, c in enumerate("abc")})
        return out

    out = {"standard": "ISO 9283:1998 §7.2.1 (AP), §7.2.2 (RP)", "source": result.source,
           "source_sha256": result.source_sha256, "poses": result.poses,
           "before": {"overall": overall(result.before), "poses": _figures_dict(result.before)}}
    if result.after is not None:
        out["after_source"], out["after_sha256"] = result.after_source, result.after_sha256
        out["after"] = {"overall": overall(result.after), "poses": _figures_dict(result.after)}
    return out


def _cell(v) -> str:
    return "–" if v is None or (isinstance(v, float) and not math.isfinite(v)) else f"{v:.3f}"


def iso_markdown(result: IsoResult, max_rows: int = 60) -> list[str]:
    """Markdown lines: the per-pose table (before, and after where measured) and its notes."""
    lines = ["| pose | n | X | Y | Z | APx | APy | APz | AP | RP" + (" | AP after | RP after" if result.after else "")
             + " |", "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:" + ("|---:|---:" if result.after else "") + "|"]
    b, a = result.before, result.after
    shown = min(len(b), max_rows)
    for k in range(shown):
        row = (f"| {b.name(k)} | {b.n[k]} | {b.command[k, 0]:.1f} | {b.command[k, 1]:.1f} | {b.command[k, 2]:.1f} | "
               f"{b.ap_xyz[k, 0]:.3f} | {b.ap_xyz[k, 1]:.3f} | {b.ap_xyz[k, 2]:.3f} | {b.ap[k]:.3f} | {_cell(b.rp[k])}")
        if a is not None:
            row += f" | {a.ap[k]:.3f} | {_cell(a.rp[k])}"
        lines.append(row + " |")
    if shown < len(b):
        lines.append(f"| … {len(b) - shown} more poses in iso9283.json | | | | | | | | | |")
    if b.ap_abc is not None:
        lines += ["", "| pose | APa | APb | APc | RPa (±) | RPb (±) | RPc (±) |", "|---:|---:|---:|---:|---:|---:|---:|"]
        for k in range(shown):
            lines.append(f"| {b.name(k)} | " + " | ".join(f"{v:.4f}" for v in b.ap_abc[k]) + " | "
                         + " | ".join(_cell(v) for v in b.rp_abc[k]) + " |")
    notes = ["", "mm and degrees. AP = distance of the barycentre of the attained positions from the command "
             "(ISO 9283:1998 §7.2.1), RP = l̄ + 3·S_l (§7.2.2), S with n − 1."]
    if b.n.min() < ISO_CYCLES:
        notes.append(f"**{int((b.n < ISO_CYCLES).sum())} of {len(b)} poses have fewer than the standard's "
                     f"{ISO_CYCLES} cycles (n = {b.n.min()}…{b.n.max()}): the figures are the standard's formulas, "
                     "not a test to the standard.**")
    if b.numbers is None:
        notes.append("Poses numbered by first appearance in the file (it has no pose column: a plan's "
                     "`postproc plan --iso9283` names them P1…P5 as the standard does, `postproc measure` keeps it).")
    if b.ap_abc is None:
        notes.append("Orientation was not measured (no a_meas,b_meas,c_meas columns): no APa/b/c, RPa/b/c.")
    return lines + notes

"""Measurement plans: Latin hypercube poses in a box, the plan CSV and a KRL measurement program.

A plan is an [N, 6] array of TCP poses X,Y,Z,A,B,C (mm, deg, robot base frame) in visiting
order. ``latin_hypercube`` draws it (scipy.stats.qmc, seeded) as the method does: positions
uniform in a box, each of A, B, C within ± range of a working attitude. The plan is written
as CSV (header ``x,y,z,a,b,c``) and, for the robot, as a runnable KRL program that moves
LIN to each pose, lets it settle and hands over to the tracker.

A plan may state each pose's arm configuration (``plan_configurations``: the branch the
controller takes from HOME, or half the poses, in pairs, in the flipped-wrist configuration): the CSV
then has ``s,t`` columns and the KRL program moves PTP to each pose with its S and T (a LIN
cannot change the configuration). A plan may be for another tool than the description's
(``$TOOL`` in the program, the reach check with that TCP). A plan may be measured at several
test loads (``in_parts``: consecutive parts, one load each, as a cell calibrates with two or
three test loads): the CSV then has ``load_mass,load_cx,load_cy,load_cz`` columns, which
``postproc measure`` simulates and carries into the measurements, and the KRL program halts at
HOME to change the load and sets ``$LOAD`` for each part.
"""
from __future__ import annotations

import io
import re
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.diagnostics import P335, P500, P501, P503, P512, PostprocError
from ..measurements.csv import LOAD_COLUMNS, TOOL_COLUMNS, data_rows, is_data, label_columns, parse_rows

__all__ = [
    "DEFAULT_BOX", "DEFAULT_ATTITUDE", "DEFAULT_RANGE", "POSE_COLUMNS", "latin_hypercube", "round_poses",
    "plan_csv_text", "write_plan_csv", "read_pose_csv", "Plan", "read_plan",
    "plan_configurations", "WRIST_CHOICES", "krl_measurement_program", "write_krl_measurement_program",
    "ls_measurement_program", "in_parts", "parse_load",
]

# the calibration box of the method (Hu, Hua & Tian) and models/kr500.toml's [workspace]
DEFAULT_BOX = (1700.0, 2300.0, -600.0, 600.0, 500.0, 1300.0)
DEFAULT_ATTITUDE = (0.0, 90.0, 0.0)
DEFAULT_RANGE = 10.0
POSE_COLUMNS = ("x", "y", "z", "a", "b", "c")
# digits written for mm and degrees: the plan CSV and the KRL program hold the same numbers
MM_DECIMALS, DEG_DECIMALS = 3, 4
# a plan is drawn whole (a Latin hypercube is one permutation per dimension: 48 bytes a pose),
# then checked and written CHUNK rows at a time; MAX_POSES keeps it to about 1 GB
MAX_POSES = 10_000_000
CHUNK = 65_536


def latin_hypercube(
    n: int,
    box=DEFAULT_BOX,
    attitude=DEFAULT_ATTITUDE,
    range_deg: float = DEFAULT_RANGE,
    seed: int | None = 0,
) -> np.ndarray:
    """``n`` poses [n, 6]: X,Y,Z Latin-hypercube sampled in ``box`` (x0,x1,y0,y1,z0,z1 mm),
    A,B,C in ``attitude`` ± ``range_deg`` (deg), one 6-D hypercube (scipy.stats.qmc)."""
    from scipy.stats import qmc

    box = np.asarray(box, float)
    attitude = np.asarray(attitude, float)
    if n < 1:
        raise PostprocError(f"a plan needs at least 1 pose, got {n}", code=P512)
    if n > MAX_POSES:
        raise PostprocError(f"a plan holds at most {MAX_POSES:,} poses (about 1 GB of memory), got {n:,}: "
                            "split it into several plans with different --seed", code=P512)
    if box.shape != (6,) or np.any(box[1::2] < box[0::2]):
        raise PostprocError(f"box must be X0 X1 Y0 Y1 Z0 Z1 with X0 <= X1 etc., got {box.tolist()}", code=P512)
    if attitude.shape != (3,) or not range_deg >= 0:
        raise PostprocError("attitude must be A B C and range a non-negative number of degrees", code=P512)
    lo = np.concatenate([box[0::2], attitude - range_deg])
    hi = np.concatenate([box[1::2], attitude + range_deg])
    unit = qmc.LatinHypercube(d=6, seed=seed).random(n)
    return lo + unit * (hi - lo)  # qmc.scale refuses degenerate (lo == hi) dimensions


def round_poses(poses: np.ndarray) -> np.ndarray:
    """Poses rounded as they are written (0.001 mm, 0.0001°), so CSV and KRL agree."""
    poses = np.asarray(poses, float)
    return np.concatenate([np.round(poses[:, :3], MM_DECIMALS), np.round(poses[:, 3:6], DEG_DECIMALS)], axis=1) + 0.0


def plan_csv_text(poses: np.ndarray, config: np.ndarray | None = None, tools: np.ndarray | None = None) -> str:
    """The plan as CSV text: header ``x,y,z,a,b,c`` (``,s,t`` with ``config`` [N, 2];
    ``,tool_x,…,tool_c`` with ``tools`` [N, 6], each row's TCP), one pose per row, in visiting order."""
    return "".join(plan_csv_chunks(poses, config, tools=tools))


def in_parts(n: int, values) -> np.ndarray:
    """Each of ``n`` rows' value [n, m] when a plan is measured in consecutive parts of equal size
    (±1), one per row of ``values`` [k, m] — a tool [k, 6] (its TCP) or a test load [k, 4] (mass
    kg, centre of mass mm in the flange frame) — changed between them."""
    values = np.atleast_2d(np.asarray(values, float))
    return values[np.arange(n) * len(values) // max(n, 1)]


def parse_load(text: str) -> np.ndarray:
    """``MASS[,CX,CY,CZ]`` (kg; mm in the flange frame) → [4]; a mass alone has its centre of mass
    at the flange (0, 0, 0), as ``compensate --load`` reads it; a mass of 0 no centre.
    PostprocError P512 otherwise."""
    from ..programs.model import parse_load as parse_stated

    try:
        values = np.array(parse_stated(str(text)))
    except ValueError:
        raise PostprocError(f"a load is MASS[,CX,CY,CZ] (kg >= 0; its centre of mass, mm in the flange frame), "
                            f"not {text!r}", code=P512) from None
    if values[0] == 0:
        values[1:] = 0.0
    return values


def _plan_header(lines: list[str]) -> tuple[list[str], int, list[str]] | None:
    """A plan/pose CSV's (lines, the header's line index, its column names lower-case), None for
    a file of comments only."""
    first = next((i for i, ln in enumerate(lines) if is_data(ln)), None)
    if first is None:
        return None
    return lines, first, [h.strip().lower() for h in lines[first].split(",")]


@dataclass
class Plan:
    """A plan or pose CSV read once (:func:`read_plan`): the poses [N, 6] and their 1-based file
    lines [N]; the ``s,t`` columns [N, 2] (ints, -1 where empty; None without them); the labels
    of each row (``measurements.LABEL_COLUMNS``: ``pose``, ``cycle`` of an ISO 9283 plan; {}
    without them); each row's TCP ``tool_x..tool_c`` [N, 6] and load ``load_mass..load_cz``
    [N, 4] (None without them; the loads all four or none, P501, a mass >= 0, P502); the
    ``# key: value`` lines above the header (keys lower-cased: ``tool`` of a plan measured with
    one tool other than the description's)."""

    poses: np.ndarray
    lines: np.ndarray
    config: np.ndarray | None
    labels: dict[str, np.ndarray]
    tools: np.ndarray | None
    loads: np.ndarray | None
    metadata: dict[str, str]


def read_plan(path: str | Path) -> Plan:
    """The plan or pose CSV at ``path``, read and decoded once (:class:`Plan`); PostprocError with
    file:line:col (P500–P503) on anything malformed."""
    from ..measurements.csv import _load_columns, metadata_of

    text = _read_text(path)
    poses, numbers = parse_pose_csv(text, str(path))
    lines = text.splitlines()
    found = _plan_header(lines)
    assert found is not None  # (parse_pose_csv found the header)
    _, first, header = found
    tools = None
    if set(TOOL_COLUMNS) <= set(header):
        tools = parse_rows(lines, first, header, [header.index(c) for c in TOOL_COLUMNS], str(path))[0]
    return Plan(poses, numbers, _plan_config(lines, first, header, str(path)), label_columns(*found, str(path)),
                tools, _load_columns(*found, str(path)), metadata_of(lines))


def plan_csv_chunks(poses: np.ndarray, config: np.ndarray | None = None, chunk: int = CHUNK,
                    tools: np.ndarray | None = None, metadata: dict[str, str] | None = None,
                    loads: np.ndarray | None = None):
    """:func:`plan_csv_text` in pieces of ``chunk`` rows (for a writer that streams them), after
    ``# key: value`` lines (``metadata``: what shapes the measurement and is not a column, e.g. the
    ``tool`` of a plan measured with one tool other than the description's); ``loads`` [N, 4]:
    each row's load, columns ``load_mass..load_cz``."""
    if metadata:
        yield "".join(f"# {key}: {value}\n" for key, value in metadata.items())
    fmt = [f"%.{MM_DECIMALS}f"] * 3 + [f"%.{DEG_DECIMALS}f"] * 3
    header = list(POSE_COLUMNS)
    if config is not None:
        config = np.asarray(config, float).reshape(-1, 2)
        fmt, header = fmt + ["%d", "%d"], header + ["s", "t"]
    if tools is not None:
        tools = np.asarray(tools, float).reshape(-1, 6)
        fmt, header = fmt + ["%.10g"] * 6, header + list(TOOL_COLUMNS)
    if loads is not None:
        loads = np.asarray(loads, float).reshape(-1, 4)
        fmt, header = fmt + ["%.10g"] * 4, header + list(LOAD_COLUMNS)
    yield ",".join(header) + "\n"
    for start in range(0, len(poses), chunk):
        buf = io.StringIO()
        table = round_poses(poses[start:start + chunk])
        if config is not None:
            table = np.hstack([table, config[start:start + chunk]])
        if tools is not None:
            table = np.hstack([table, tools[start:start + chunk]])
        if loads is not None:
            table = np.hstack([table, loads[start:start + chunk]])
        np.savetxt(buf, table, fmt=fmt, delimiter=",")
        yield buf.getvalue()


def reachable(robot, poses: np.ndarray, chunk: int = CHUNK) -> np.ndarray:
    """``robot.ik``'s reachable mask, ``chunk`` rows at a time (bounded memory)."""
    return np.concatenate([robot.ik(poses[i:i + chunk])[1] for i in range(0, len(poses), chunk)])


def write_plan_csv(path: str | Path, poses: np.ndarray, config: np.ndarray | None = None) -> None:
    """Write the plan CSV atomically (temp file beside it, then rename)."""
    from ..core.atomic import write_atomic

    write_atomic([(Path(path), plan_csv_text(poses, config))])


# how a plan chooses each pose's configuration: the controller's from HOME, or half the poses
# (in pairs) in the flipped-wrist configuration (both wrist configurations in one data set)
WRIST_CHOICES = ("home", "both")


def plan_configurations(robot, poses: np.ndarray, wrist: str = "home") -> tuple[np.ndarray, np.ndarray]:
    """S/T [N, 2] for each pose of a plan and a mask of the poses reachable so: ``wrist``
    "home" = the branch nearest HOME (the controller's own choice), "both" = half the poses in
    the flipped-wrist configuration of that (S bit 2 toggled; the pose keeps the HOME branch
    where the flipped one is out of reach or limits): rows 2, 3 of every four, so each
    configuration is approached from the other and from itself alike. (Alternating row by
    row would tie A5's approach direction to the configuration, and A5's backlash to its
    zero offset: a mirrored A5 turns the offset's sign as a reversed approach does.)"""
    from ..robot import configuration, conventions

    if wrist not in WRIST_CHOICES:
        raise PostprocError(f"--wrist must be one of {', '.join(WRIST_CHOICES)}, not {wrist!r}", code=P512)
    q, ok = robot.ik(poses)
    status, turn = conventions.status_turn_of(robot, q)
    if wrist == "both":
        odd = (np.arange(len(poses)) // 2 % 2 == 1) & ok
        flipped, found = configuration.stated_joints(robot, poses[odd], status[odd] ^ 4,
                                                     np.full(int(odd.sum()), conventions.UNSTATED))
        rows = np.flatnonzero(odd)[found]
        s_f, t_f = conventions.status_turn_of(robot, flipped[found])
        status[rows], turn[rows] = s_f, t_f
    return np.stack([status, turn], axis=1), ok


def _plan_config(lines: list[str], first: int, header: list[str], path: str) -> np.ndarray | None:
    """The ``s,t`` columns [N, 2] of a plan/pose CSV (ints; -1 where empty), None without them."""
    if "s" not in header or "t" not in header:
        return None
    cols = [header.index("s"), header.index("t")]
    rows = data_rows(lines, first)
    out = np.full((len(rows), 2), -1, dtype=np.int64)
    for k_row, (number, line) in enumerate(rows):
        fields = line.split(",")
        for k, c in enumerate(cols):
            value = fields[c].strip() if c < len(fields) else ""
            if value:
                try:
                    out[k_row, k] = int(float(value))
                except ValueError:
                    raise PostprocError(f"column {'st'[k]} is not an integer: {value!r}", path, number, 1,
                                        P503) from None
    return out


# --------------------------------------------------------------------------- reading


def read_pose_csv(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """Poses [N, 6] and their 1-based file lines [N] from a CSV whose header names at least
    x,y,z,a,b,c (any case, any order, extra columns ignored; blank lines and ``#`` comments
    skipped). PostprocError with file:line:col (P500–P503, as the measurement reader) on
    anything malformed."""
    return parse_pose_csv(_read_text(path), str(path))


def _read_text(path: str | Path) -> str:
    """A pose CSV's text (a UTF-8 byte-order mark dropped; latin-1: any byte reads)."""
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise PostprocError(f"cannot read pose file: {exc.strerror or exc}", str(path), code=P500) from exc
    return data.removeprefix(b"\xef\xbb\xbf").decode("latin-1")


def parse_pose_csv(text: str, path: str = "<poses>") -> tuple[np.ndarray, np.ndarray]:
    """Parse the text of a pose CSV (see :func:`read_pose_csv`)."""
    lines = text.splitlines()
    poses = _parse_pose_lines(lines, path)
    first = next(i for i, raw in enumerate(lines) if is_data(raw))
    return poses, np.array([number for number, _ in data_rows(lines, first)], dtype=np.int64)


def _parse_pose_lines(lines: list[str], path: str) -> np.ndarray:
    first = next((i for i, raw in enumerate(lines) if is_data(raw)), None)
    if first is None:
        raise PostprocError("empty pose file (expected a header with x,y,z,a,b,c)", path, 1, 1, P500)
    header = [h.strip().lower() for h in lines[first].split(",")]
    missing = [c for c in POSE_COLUMNS if c not in header]
    if missing:
        raise PostprocError(f"header lacks column(s) {', '.join(missing)} (need {','.join(POSE_COLUMNS)})",
                            path, first + 1, 1, P501)
    dupes = sorted({c for c in POSE_COLUMNS if header.count(c) > 1})
    if dupes:
        raise PostprocError(f"column(s) {', '.join(dupes)} appear more than once", path, first + 1, 1, P501)
    index = [header.index(c) for c in POSE_COLUMNS]
    body = "\n".join(lines[first + 1:])
    try:  # fast path for well-formed files (10^5 rows); the slow scan below finds the culprit
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # "input contained no data" is reported below
            table = np.loadtxt(io.StringIO(body), delimiter=",", comments="#", ndmin=2, dtype=float)
        if table.shape[1] == len(header) and np.isfinite(table[:, index]).all():
            if len(table) == 0:
                raise PostprocError("pose file has a header but no rows", path, first + 1, 1, P500)
            return table[:, index].copy()
    except ValueError:
        pass
    table, _ = parse_rows(lines, first, header, index, path)
    if not len(table):
        raise PostprocError("pose file has a header but no rows", path, first + 1, 1, P500)
    return table


# --------------------------------------------------------------------------- KRL


def _krl_pos(pose: np.ndarray, status: int | None = None, turn: int | None = None) -> str:
    x, y, z, a, b, c = pose
    text = (f"X {x:.{MM_DECIMALS}f},Y {y:.{MM_DECIMALS}f},Z {z:.{MM_DECIMALS}f},"
            f"A {a:.{DEG_DECIMALS}f},B {b:.{DEG_DECIMALS}f},C {c:.{DEG_DECIMALS}f}")
    if status is not None:
        text += f",S 'B{status:03b}',T 'B{turn:06b}'"
    return "{" + text + "}"


def _krl_frame(frame: np.ndarray) -> str:
    return "{" + ",".join(f"{k} {v:.4f}" for k, v in zip("XYZABC", frame)) + "}"


def krl_measurement_program(
    poses: np.ndarray,
    name: str,
    robot,
    wait_s: float = 1.0,
    approach_mm: float = 100.0,
    trigger_out: int = 1,
    done_in: int = 1,
    comment: str = "",
    config: np.ndarray | None = None,
    tools: np.ndarray | None = None,
    loads: np.ndarray | None = None,
) -> str:
    """A runnable KRL module (one .src, targets inline) that measures ``poses`` in order:
    HOME, PTP above the first pose, then for each pose LIN to it, settle ``wait_s``, raise
    $OUT[trigger_out] and wait for the tracker's $IN[done_in], then retreat and HOME.

    ``robot`` (a :class:`postproc.robot.arm.Robot`) gives HOME, the tool and the S/T of the
    approach PTP. Targets are in the robot base frame ($BASE = $NULLFRAME). With ``config``
    [N, 2] (S, T per pose) each pose is reached PTP with its S and T (E6POS components). With
    ``tools`` [N, 6] (each pose's TCP, in consecutive parts: ``in_parts``) every part after the
    first starts at HOME with a HALT to mount its tool, then sets its $TOOL. With ``loads`` [N, 4]
    (each pose's load, mass kg and centre of mass mm on the flange, in consecutive parts:
    ``in_parts``) every part starts so to mount its test load, and sets $LOAD (the first part
    too)."""
    if not comment.isascii():  # controllers read .src as ANSI: keep the program plain ASCII
        comment = comment.encode("ascii", "replace").decode()
    if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]{0,23}", name):
        raise PostprocError(f"'{name}' is not a KRL module name (letters, digits, _; at most 24; not starting "
                            "with a digit): name the .src file like one", code=P512)
    poses = round_poses(np.atleast_2d(poses))
    starts = [0]
    if tools is not None:
        tools = np.asarray(tools, float).reshape(len(poses), 6)
        starts += (np.flatnonzero((np.diff(tools, axis=0) != 0).any(axis=1)) + 1).tolist()
    if loads is not None:
        loads = np.asarray(loads, float).reshape(len(poses), 4)
        starts = sorted(set(starts) | set((np.flatnonzero((np.diff(loads, axis=0) != 0).any(axis=1)) + 1).tolist()))
    parts = []  # (first, end, the arm with that part's tool, approach above its first and last pose, their S, T)
    for first, end in zip(starts, starts[1:] + [len(poses)]):
        arm = robot if tools is None or np.array_equal(tools[first], robot.tool) else \
            type(robot)(robot.description.replace(tool=tools[first]))
        above = poses[[first, end - 1]].copy()
        above[:, 2] += approach_mm
        q, ok = arm.ik(above)
        if not ok.all():
            raise PostprocError(f"the approach {approach_mm:g} mm above the first/last pose is out of reach", code=P335)
        parts.append((first, end, arm, above, *arm.status_turn(q)))
    home = ",".join(f"A{i + 1} {v:.4f}" for i, v in enumerate(robot.home_q))
    nl = "\n"
    head = [
        "&ACCESS RVP",
        "&REL 1",
        f"&COMMENT postproc measurement program, {len(poses)} poses",
        f"DEF {name}( )",
        f"; postproc measurement program: {len(poses)} poses in visiting order{', ' + comment if comment else ''}",
        f"; robot {robot.name}, tool {robot.tool_name if tools is None else f'in {len(parts)} parts, one each'}; "
        "targets in the robot base frame",
        f"; at each pose: LIN, settle {wait_s:g} s, $OUT[{trigger_out}]=TRUE asks the tracker to measure,",
        f"; $IN[{done_in}]=TRUE says it has; a measurement row is written per pose in this order",
        "BAS(#INITMOV, 0)",
        "$BASE = $NULLFRAME",
        f"$TOOL = {_krl_frame(parts[0][2].tool)}",
        "$VEL.CP = 0.2",
        "$ACC.CP = 1.0",
        "$APO.CDIS = 0.0",
        f"$OUT[{trigger_out}] = FALSE",
        f"PTP {{{home}}}",
    ]
    if config is None:
        moves = [f"LIN {_krl_pos(p)}{nl}MEASURE_HERE( )" for p in poses]
    else:
        config = np.asarray(config, int).reshape(len(poses), 2)
        moves = [f"PTP {_krl_pos(p, int(st[0]), int(st[1]))}{nl}MEASURE_HERE( )" for p, st in zip(poses, config)]
    body = []
    for k, (first, end, arm, above, status, turn) in enumerate(parts):
        load = None if loads is None else loads[first]
        mount = f"the test load {load[0]:g} kg at ({load[1]:g}, {load[2]:g}, {load[3]:g}) mm" if load is not None else ""
        if k and (tools is None or np.array_equal(tools[first], tools[parts[k - 1][0]])):
            body += [f"PTP {{{home}}}", f"; part {k + 1} of {len(parts)}: mount {mount}, then continue", "HALT"]
        elif k:
            body += [f"PTP {{{home}}}", f"; part {k + 1} of {len(parts)}: mount the tool {_krl_frame(arm.tool)}, "
                     f"{'and ' + mount + ', ' if mount else ''}then continue", "HALT", f"$TOOL = {_krl_frame(arm.tool)}"]
        elif mount:
            body += [f"; part 1 of {len(parts)}: {mount} mounted"]
        if load is not None:
            body += [f"$LOAD.M = {load[0]:g}", f"$LOAD.CM = {{X {load[1]:g}, Y {load[2]:g}, Z {load[3]:g}, A 0, B 0, C 0}}"]
        body += [f"PTP {_krl_pos(above[0], int(status[0]), int(turn[0]))}", *moves[first:end],
                 f"LIN {_krl_pos(above[1])}"]
    tail = [
        f"PTP {{{home}}}",
        "END",
        "",
        "DEF MEASURE_HERE( )",
        f"WAIT SEC {wait_s:.2f}",
        f"$OUT[{trigger_out}] = TRUE",
        f"WAIT FOR $IN[{done_in}]",
        f"$OUT[{trigger_out}] = FALSE",
        f"WAIT FOR NOT $IN[{done_in}]",
        "END",
    ]
    return nl.join(head + body + tail) + nl


def write_krl_measurement_program(path: str | Path, poses: np.ndarray, robot, **options) -> None:
    """Write :func:`krl_measurement_program` to ``path`` (.src, module named after the file), atomically."""
    from ..core.atomic import write_atomic

    path = Path(path)
    write_atomic([(path, krl_measurement_program(poses, path.stem, robot, **options))])


# --------------------------------------------------------------------------- FANUC LS


def ls_measurement_program(poses: np.ndarray, name: str, robot, wait_s: float = 1.0, trigger_out: int = 1,
                           done_in: int = 1, config: np.ndarray | None = None, comment: str = "") -> str:
    """A FANUC LS program (one .ls, UF 0 = the robot's world, UT 1 = the plan's tool) that
    measures ``poses`` in order: J to each pose in the configuration it states, ``CONFIG : 'F U T,
    t1, t4, t6'`` (``conventions.fanuc_configs`` of its joint angles: the S/T of ``config`` [N,
    2], else the branch nearest HOME — what ``measure`` simulates), settle ``wait_s``, DO
    ``trigger_out`` on, wait for DI ``done_in``. ``robot`` (a :class:`postproc.robot.arm.Robot` of a
    FANUC-type description) gives the joint angles and the TCP UT 1 must hold (the caller says it:
    the program cannot set a tool frame's values); poses are W, P, R = C, B, A."""
    from ..robot import configuration, conventions

    if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]{0,35}", name):
        raise PostprocError(f"'{name}' is not an LS program name (a letter, then letters, digits, _): name the .ls "
                            "file like one", code=P512)
    poses = round_poses(np.atleast_2d(poses))
    if config is None:
        q, ok = robot.ik(poses)
    else:
        config = np.asarray(config, int).reshape(len(poses), 2)
        q, ok = configuration.stated_joints(robot, poses, config[:, 0], config[:, 1])
    if not ok.all():
        raise PostprocError(f"pose {int(np.flatnonzero(~ok)[0]) + 1} is out of reach in its configuration", code=P335)
    configs = conventions.fanuc_configs(robot, q)
    comment = (comment or f"postproc plan, {len(poses)} poses").encode("ascii", "replace").decode()[:30]
    mn = ["UFRAME_NUM=0 ;", "UTOOL_NUM=1 ;", "! UT 1: the plan's TCP ;"]
    for k in range(1, len(poses) + 1):
        mn += [f"J P[{k}] 20% FINE ;", f"WAIT {wait_s:.2f}(sec) ;", f"DO[{trigger_out}]=ON ;",
               f"WAIT DI[{done_in}]=ON ;", f"DO[{trigger_out}]=OFF ;", f"WAIT DI[{done_in}]=OFF ;"]
    body = [f"{i:4d}:  {line}" if not line.startswith(("J ", "L ")) else f"{i:4d}:{line}" for i, line in
            enumerate(mn, start=1)]
    pos = []
    for k, (p, c) in enumerate(zip(poses, configs), start=1):
        x, y, z, a, b, cc = p
        pos.append(f"P[{k}]{{\n   GP1:\n\tUF : 0, UT : 1,\t\tCONFIG : '{c}',\n"
                   f"\tX = {x:10.3f}  mm,\tY = {y:10.3f}  mm,\tZ = {z:10.3f}  mm,\n"
                   f"\tW = {cc:10.3f} deg,\tP = {b:10.3f} deg,\tR = {a:10.3f} deg\n}};")
    head = [f"/PROG  {name.upper()}", "/ATTR", "OWNER\t\t= MNEDITOR;", f'COMMENT\t\t= "{comment}";',
            f"LINE_COUNT\t= {len(body)};", "PROTECT\t\t= READ_WRITE;", "DEFAULT_GROUP\t= 1,*,*,*,*;", "/MN"]
    return "\n".join(head + body + ["/POS"] + pos + ["/END", ""])

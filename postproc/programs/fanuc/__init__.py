"""Fanuc LS reader: the ASCII form of TP programs (.ls) → the motion IR (``lower.py``) → the
analysis (``programs.analysis`` with LS's ``semantics.py``) → FanucProgram; a backup's cell data
(``backup.py``: the frames of sysframe.va, the registers of posreg.va and numreg.va).

Semantics (tests/test_fanuc.py and tests/test_fanuc_ir.py show each on a small program):

* the /MN instructions run as the controller runs them: motions (``J``, ``L``, ``C`` via and
  end, ``A``) with their options, registers ``R[n]`` and position registers ``PR[n]``
  (``PR[n]=P[m]``, ``PR[n,k]=…``, ``PR[i]=PR[j]+PR[k]``), ``UFRAME_NUM``/``UTOOL_NUM``,
  ``UFRAME[n]=PR[m]``, labels and jumps (``JMP LBL[n]``, ``IF …,JMP LBL[n]``), ``IF … THEN``,
  ``SELECT``, ``FOR``/``ENDFOR``, ``CALL`` (of a program read with it: it runs; of one not read:
  what it changes is not known), ``RUN``, ``END``, ``ABORT``,
  ``PAUSE``, ``WAIT``; each executed motion to a Cartesian position is a row, in execution order
  (a position moved to several times: a row each, its numbers written once where all agree);
* a target's numbers are those of a ``/POS`` record ``P[n]`` (group GP1, ``X = … mm``, W, P, R in
  deg), as such or copied into a register; W, P, R are fixed angles about X, Y, Z:
  R = Rz(R)·Ry(P)·Rx(W), i.e. KUKA A = R, B = P, C = W; X, Y, Z are rewritten (with
  ``--orientation``, W, P, R too);
* its frame is the position's own UF and UT (a register's: the ones selected), from the frame file
  given with ``--frames`` (TOML: ``[uframe.1] xyzwpr = [x, y, z, w, p, r]``, ``[utool.1] …``) or as
  the program sets them; a frame not known leaves the target as written (P201 user frame, P203
  tool); ``CONFIG : '…'`` is kept as written (:attr:`FanucProgram.configs`, aligned with the rows),
  translated to joint angles for a model that takes them by ``configuration.stated_configuration``
  (a description whose controller states FANUC configurations; else P309); a joint
  representation is no target;
* several .ls files are one unit (a backup's programs); a backup's .va files give the frames and
  the registers no TP program read sets, each use said (P234; ``registers="runtime"``: none);
* ``Tool_Offset,PR[n]`` with the register known: the shift in the position's tool frame (its
  X, Y, Z rewritten, its W, P, R computed);
* left as written, located: a position not taught (``********``, P212), without a record (P215),
  moving other groups or extended axes (a track: P225), moved to with ``INC`` (P210), a vision
  offset or a register known only at run time (P211), one whose numbers another instruction reads
  too (P217).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from ...core.diagnostics import P101, P108, P118, P234, Diagnostic, PostprocError
from ...core.frames import frame_to_matrix
from ...core.toml import check_value, key_line, parse_toml
from ..analysis import analyse
from ..ir import Assign, Async, Field, Invoke, Loop, Name, Unit, walk
from ..model import STAMP_PREFIX, Program
from ..text import newline
from .backup import read_backup, serve
from .lower import TOKEN_RE, Lowering, parser
from .semantics import LS

__all__ = ["read", "lower", "parser", "FanucProgram", "read_frames", "insert_stamp", "wpr_to_abc", "TOKEN_RE"]

_LINE_COUNT = re.compile(r"^(LINE_COUNT[ \t]*=[ \t]*)(\d+)", re.M)
_STAMP = re.compile(r"^[ \t]*\d+:[ \t]*!.*" + re.escape(STAMP_PREFIX) + r".*$", re.M)


@dataclass
class FanucProgram(Program):
    """An LS Program, plus each row's CONFIG string as written ('N U T, 0, 0, 0'; '' none)."""

    configs: list[str] = field(default_factory=list)


def wpr_to_abc(wpr: np.ndarray) -> np.ndarray:
    """[..., 3] Fanuc W, P, R (fixed X, Y, Z angles: R = Rz(R)·Ry(P)·Rx(W)) → KUKA A, B, C."""
    wpr = np.asarray(wpr, float)
    return wpr[..., ::-1].copy()


def read_frames(text: str | None, path: str = "--frames") -> tuple[dict[int, np.ndarray], dict[int, tuple]]:
    """The frame file: ``[uframe.N] xyzwpr = [x, y, z, w, p, r]`` (mm, deg) and ``[utool.N]``
    alike → (user frames as 4×4, tools as X,Y,Z,A,B,C). UF 0 is the world (the robot
    base), UT 0 the flange. Raises P118 on a malformed file."""
    uframes: dict[int, np.ndarray] = {0: np.eye(4)}
    utools: dict[int, tuple] = {0: (0.0,) * 6}
    if text is None:
        return uframes, utools
    data = parse_toml(text, path, P118)
    for key in data:
        if key not in ("uframe", "utool", "external"):
            line = key_line(text, key) or key_line(text, None, key)
            raise PostprocError(f"frame file: unknown table [{key}] (expected [uframe.N] or [utool.N])", path, line,
                                1 if line else 0, P118)
    for kind, out in (("uframe", uframes), ("utool", utools)):
        for number, entry in data.get(kind, {}).items():
            line = key_line(text, f"{kind}.{number}")

            def bad(_message, kind=kind, number=number, line=line):
                return PostprocError(f"frame file: [{kind}.{number}] needs xyzwpr = [x, y, z, w, p, r] (six finite "
                                     "numbers, mm and deg) and a number 1…61", path, line, 1 if line else 0, P118)

            if not (number.isdigit() and 1 <= int(number) <= 61 and isinstance(entry, dict)):
                raise bad("")
            value = check_value("vec:6", entry.get("xyzwpr"), "xyzwpr", bad)
            xyzabc = np.concatenate([value[:3], wpr_to_abc(value[3:])])
            out[int(number)] = frame_to_matrix(xyzabc) if kind == "uframe" else tuple(float(v) for v in xyzabc)
    return uframes, utools


def insert_stamp(text: str, stamp: str, newline: str) -> str:
    """The stamp as the last line of /MN: a remark numbered after the last line,
    ``  N:  ! postproc: … ;`` — LS has no comment outside /MN, and a remark added at the end
    leaves every other line's number as it was."""
    mn = re.search(r"^/MN\b[^\n]*\n", text, re.M)
    end = re.search(r"^/(?:POS|END)\b", text[mn.end():], re.M) if mn else None
    if mn is None or end is None:
        return stamp + newline + text
    body_end = mn.end() + end.start()
    numbers = re.findall(r"^[ \t]*(\d+)[ \t]*:", text[mn.end():body_end], re.M)
    number = max(map(int, numbers), default=0) + 1
    head = text[:body_end]
    # /ATTR's LINE_COUNT counts /MN's lines: one more (the controller's loader may check it)
    head = _LINE_COUNT.sub(lambda m: f"{m.group(1)}{int(m.group(2)) + 1}", head[:mn.start()], count=1) + head[mn.start():]
    return head + f"{number:4d}:  {stamp} ;" + newline + text[body_end:]


def frame_file_units(text: str | None, path: str = "--frames") -> tuple:
    """The ``[[external]]`` units of a frame file (a group-2 track, a positioner:
    postproc.robot.external), () where it has none."""
    if not text or "external" not in text:
        return ()
    data = parse_toml(text, path, P118)
    if "external" not in data:
        return ()
    from ...robot.external import parse_external

    return parse_external(data["external"], path, text)


def _written(unit, lowerings) -> tuple[dict, dict]:
    """The registers and frames the programs read set (name → "path:line" of the first place),
    and the kinds one of them sets with an index known at run time (kind → "path:line")."""
    written: dict = {}
    for k, lw in enumerate(lowerings):
        routine = unit.routines[lw.name]
        for s in walk(routine.body):
            name = None
            if isinstance(s, Assign):
                target = s.target.base if isinstance(s.target, Field) else s.target
                name = target.name if isinstance(target, Name) else None
            elif isinstance(s, Loop) and s.var:
                name = s.var
            if name and name.startswith(("R[", "PR[", "UFRAME[", "UTOOL[")):
                written.setdefault(name, f"{lw.path}:{s.loc.line}")
    indirect: dict = {}
    for lw in lowerings:
        for kind, line in lw.indirect.items():
            indirect.setdefault(kind, f"{lw.path}:{line}")
    return written, indirect


def lower(files: list[str], texts: list[str], frames: list[str] | None = None, external: tuple = (),
          va: dict[str, str] | None = None, registers: str = "backup"):
    """The motion IR of an LS program and its dialect (what ``read`` analyses): the programs of
    ``files`` (.ls) as one unit — a ``CALL`` of one of them runs it —, started where none of the
    others calls them. ``external``: the external units' kinematics (the frame file's
    ``[[external]]`` are added); ``va``: a backup's .va files (path → text: sysframe.va,
    posreg.va, numreg.va are read, ``backup.py``); ``registers``: "backup" (a register no TP
    program read sets holds the backup's value) or "runtime" (registers are run-time values)."""
    if not files:
        raise PostprocError("no .ls file given", "<none>", 0, 0, P108)
    if frames and len(frames) > 1:
        raise PostprocError("one frame file (--frames) per LS program", files[0], 0, 0, P118)
    if registers not in ("backup", "runtime"):
        raise ValueError(f"registers is 'backup' or 'runtime', not {registers!r}")
    uframes, utools = read_frames(frames[0] if frames else None)
    external = tuple(external or ()) or frame_file_units(frames[0] if frames else None)
    names = [_program_name(t) for t in texts]
    programs = frozenset(n for n in names if n)
    unit = Unit("fanuc", list(files), list(texts))
    lowerings, first = [], {}
    for k, (path, text) in enumerate(zip(files, texts)):
        lowering = Lowering(path, text, k, programs)
        part = lowering.lower()
        name = lowering.name
        if name in first:
            raise PostprocError(f"program {name} is in two files read ({first[name]} and {path})", path, 1, 1, P101)
        first[name] = path
        unit.routines[name] = part.routines[name]
        unit.diagnostics += part.diagnostics
        lowerings.append(lowering)
    called = {s.name for r in unit.routines.values() for s in walk(r.body) if isinstance(s, Invoke)}
    called |= {s.action.name for r in unit.routines.values() for s in walk(r.body)
               if isinstance(s, Async) and isinstance(s.action, Invoke)}
    unit.entries = [lw.name for lw in lowerings if lw.name not in called] or [lowerings[0].name]
    used = set().union(*(lw.registers for lw in lowerings))
    cell = None
    found = read_backup(va)
    if found is not None:
        cell = serve(found, *_written(unit, lowerings), registers, uframes, utools)
        unit.config_names, unit.config_texts = cell.config_names, cell.config_texts
    return unit, LS(uframes, utools, used, external=external, cell=cell)


def _program_name(text: str) -> str:
    m = re.match(r"\s*/PROG[ \t]+([^\s;]+)", text)
    return m.group(1).upper() if m else ""


def read(files: list[str], texts: list[str], frames: list[str] | None = None, external: tuple = (),
         va: dict[str, str] | None = None, registers: str = "backup") -> FanucProgram:
    """Read an LS program: one .ls file, or several read as one (a backup's TP programs: a
    ``CALL`` of one of them is followed); ``frames`` holds the text of the frame file (TOML);
    ``va`` a backup's .va files (path → text) whose frames and registers the programs use
    (each use of a register's or frame's backup value is said, P234, among the notes);
    ``registers`` "backup" or "runtime" (``lower``). Raises PostprocError (P101 syntax, P118
    position, frame file or .va file, P103) on bad input."""
    unit, dialect = lower(files, texts, frames, external, va, registers)
    built = analyse(unit, dialect)
    stamps = {}
    for k, text in enumerate(texts):
        m = _STAMP.search(text)
        if m:
            stamps[k] = m.group().strip()
    configs = [c or "" for c in built.extras.get("config", [])] or [""] * len(built.targets)
    found = unit.diagnostics + built.diagnostics
    said = [Diagnostic(d.path, d.line, d.col, d.code, d.message, "note") for d in found if d.code == P234]
    program = FanucProgram(files=list(files), texts=list(texts), targets=built.targets, frames=built.frames,
                           diagnostics=[d for d in found if d.code != P234], notes=built.notes + said,
                           dialect="fanuc", stamps=stamps, newlines=[newline(t) for t in texts], comment="!",
                           named_targets=True, configs=configs)
    program.held, program.sites = built.held, built.sites
    if va:  # (read again as it was read: guards.check_round_trip)
        program.read_with = {"data": dict(va), "registers": registers}
    return program

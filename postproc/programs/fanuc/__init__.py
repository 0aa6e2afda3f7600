"""Fanuc LS reader: the ASCII form of a TP program (.ls) → the motion IR (``lower.py``) → the
analysis (``programs.analysis`` with LS's ``semantics.py``) → FanucProgram.

Semantics (tests/test_fanuc.py and tests/test_fanuc_ir.py show each on a small program):

* the /MN instructions run as the controller runs them: motions (``J``, ``L``, ``C`` via and
  end, ``A``) with their options, registers ``R[n]`` and position registers ``PR[n]``
  (``PR[n]=P[m]``, ``PR[n,k]=…``, ``PR[i]=PR[j]+PR[k]``), ``UFRAME_NUM``/``UTOOL_NUM``,
  ``UFRAME[n]=PR[m]``, labels and jumps (``JMP LBL[n]``, ``IF …,JMP LBL[n]``), ``IF … THEN``,
  ``SELECT``, ``FOR``/``ENDFOR``, ``CALL`` (a program not read), ``RUN``, ``END``, ``ABORT``,
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
* left as written, located: a position not taught (``********``, P212), without a record (P215),
  moving other groups or extended axes (a track: P225), moved to with ``INC`` (P210), a vision
  offset or a register known only at run time (P211), one whose numbers another instruction reads
  too (P217).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from ...core.diagnostics import P108, P118, PostprocError
from ...core.frames import frame_to_matrix
from ...core.toml import check_value, key_line, parse_toml
from ..analysis import analyse
from ..model import STAMP_PREFIX, Program
from ..text import newline
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


def lower(files: list[str], texts: list[str], frames: list[str] | None = None, external: tuple = ()):
    """The motion IR of an LS program and its dialect (what ``read`` analyses); ``external``:
    the external units' kinematics (the frame file's ``[[external]]`` are added)."""
    if len(files) != 1:
        raise PostprocError("an LS program is one .ls file", files[0] if files else "<none>", 0, 0, P108)
    if frames and len(frames) > 1:
        raise PostprocError("one frame file (--frames) per LS program", files[0], 0, 0, P118)
    uframes, utools = read_frames(frames[0] if frames else None)
    external = tuple(external or ()) or frame_file_units(frames[0] if frames else None)
    lowering = Lowering(files[0], texts[0])
    unit = lowering.lower()
    return unit, LS(uframes, utools, lowering.registers, external=external)


def read(files: list[str], texts: list[str], frames: list[str] | None = None, external: tuple = ()) -> FanucProgram:
    """Read an LS program (one file); ``frames`` holds the text of the frame file (TOML).
    Raises PostprocError (P101 syntax, P118 position or frame file, P103) on bad input."""
    unit, dialect = lower(files, texts, frames, external)
    built = analyse(unit, dialect)
    text = texts[0]
    stamps = {}
    m = _STAMP.search(text)
    if m:
        stamps[0] = m.group().strip()
    configs = [c or "" for c in built.extras.get("config", [])] or [""] * len(built.targets)
    program = FanucProgram(files=[files[0]], texts=[text], targets=built.targets, frames=built.frames,
                           diagnostics=unit.diagnostics + built.diagnostics, notes=built.notes, dialect="fanuc",
                           stamps=stamps, newlines=[newline(text)], comment="!", named_targets=True, configs=configs)
    program.held, program.sites = built.held, built.sites
    return program

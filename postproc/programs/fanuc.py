"""Fanuc LS reader: the ASCII form of a TP program (.ls) → Program.

Sections ``/PROG``, ``/ATTR``, ``/APPL``, ``/MN``, ``/POS``, ``/END``. The ``/MN`` lines are
read with regular expressions (the motion letter, its position, its modifiers); each
``/POS`` record ``P[n]{ … };`` with ``grammars/ls.lark``, each distinct record *shape*
(numbers → 0, strings emptied) parsed once.

Semantics (tests/test_fanuc.py shows each on a small program):

* a target is a ``P[n]`` of the ``/POS`` section in Cartesian representation (group GP1,
  ``X = … mm, Y, Z, W = … deg, P, R``) that a motion (``J``, ``L``, ``C`` via and end, ``A``)
  moves to; only X, Y, Z are ever rewritten;
* W, P, R are fixed-angle rotations about the frame's X, Y and Z axes: R = Rz(R)·Ry(P)·Rx(W),
  i.e. KUKA A = R, B = P, C = W;
* its frame is the position's own ``UF : u`` (user frame, 0 = world, taken as the robot
  base) and ``UT : t`` (tool frame) from the frame file given with ``--frames`` (TOML:
  ``[uframe.1] xyzwpr = [x, y, z, w, p, r]``, ``[utool.1] …``); a frame the file does not
  give leaves the target as written (P201 user frame, P203 tool);
* ``CONFIG : '…'`` is kept as written (:attr:`FanucProgram.configs`); a model that takes joint
  angles has it translated (``configuration.stated_configuration``, for a description whose
  controller states FANUC configurations; else P309, left as written); joint representations
  (``J1 = … deg``) are not targets;
* ``PR[…]`` position registers, indirect positions (``P[R[1]]``) and motions with ``Offset``/``Tool_Offset``/``INC``/``VOFFSET``
  are computed at run time (P211); a ``P[n]`` other instructions read too (``PR[1]=P[2]``)
  is left as written (P217); a ``P[n]`` no ``/POS`` record gives (P215).
"""
from __future__ import annotations

import re
import tomllib
from dataclasses import dataclass, field

import numpy as np
from lark import Lark, Token
from lark.exceptions import UnexpectedInput

from ..diagnostics import Diagnostic, LineIndex, PostprocError
from ..frames import frame_to_matrix
from .grammar import lalr_parser, unexpected
from . import MOTIONS, STAMP_PREFIX, Frame, Program, Targets
from .poses import _newline

__all__ = ["read", "parser", "FanucProgram", "read_frames", "insert_stamp", "wpr_to_abc", "TOKEN_RE"]

_NUM = r"(?<![\w.])(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?![\w.])"
# the tokens a record's shape keeps the order of: strings and numbers
TOKEN_RE = re.compile(r"'[^'\n]*'|\"[^\"\n]*\"|" + _NUM, re.ASCII)
_SECTION = re.compile(r"^/(PROG|ATTR|APPL|MN|POS|END)\b[^\n]*", re.M)
_MN_LINE = re.compile(r"[ \t]*(\d*)[ \t]*:(.*)")
# a motion line: letter, position (P or PR) and its index: a number, or an indirect one (P[R[1]])
_MOTION_RE = re.compile(r"\s*([JLCA])?\s*(@?)\s*(PR|P)\[\s*(\d+|[A-Za-z]+\[[^\]]*\])\s*(?::[^\]]*)?\]")
_MODIFIER = re.compile(r"\b(Offset|Tool_Offset|INC|VOFFSET|VTOOL_OFFSET)\b", re.I)
_P_REF = re.compile(r"(?<![A-Za-z_\]])P\[\s*(\d+)")
_RECORD = re.compile(r"P\[[^\]\n]*\]\s*\{.*?\}\s*;", re.S)
_MOTION = {m: i for i, m in enumerate(MOTIONS)}
_KIND = {"J": "PTP", "L": "LIN", "C": "CIRC-aux", "A": "CIRC-end"}
_NUM_RE = re.compile(_NUM, re.ASCII)
_STRINGS = re.compile(r"'[^'\n]*'|\"[^\"\n]*\"")
_BLANKS = re.compile(r"\s+")
_LINE_COUNT = re.compile(r"^(LINE_COUNT[ \t]*=[ \t]*)(\d+)", re.M)
_STAMP = re.compile(r"^[ \t]*\d+:[ \t]*!.*" + re.escape(STAMP_PREFIX) + r".*$", re.M)


def _empty(m: re.Match) -> str:
    return m.group()[0] * 2  # a string emptied: '' or ""


@dataclass
class FanucProgram(Program):
    """An LS Program, plus each target's CONFIG string as written ('N U T, 0, 0, 0')."""

    configs: list[str] = field(default_factory=list)


def parser() -> Lark:
    """The LALR parser of ``grammars/ls.lark`` (built once, cached on disk by lark)."""
    return lalr_parser("ls.lark", "record")


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
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        line, col = getattr(exc, "lineno", 0), getattr(exc, "colno", 0)
        raise PostprocError(f"frame file is not TOML: {exc.msg if hasattr(exc, 'msg') else exc}", path, line, col,
                            "P118") from None
    for key in data:
        if key not in ("uframe", "utool"):
            raise PostprocError(f"frame file: unknown table [{key}] (expected [uframe.N] or [utool.N])", path, 0, 0,
                                "P118")
    for kind, out in (("uframe", uframes), ("utool", utools)):
        for number, entry in data.get(kind, {}).items():
            value = entry.get("xyzwpr") if isinstance(entry, dict) else None
            ok = number.isdigit() and 1 <= int(number) <= 61 and isinstance(value, list) and len(value) == 6 and \
                all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
            if not ok or not np.isfinite(np.array(value, float)).all():
                raise PostprocError(f"frame file: [{kind}.{number}] needs xyzwpr = [x, y, z, w, p, r] (six finite "
                                    "numbers, mm and deg) and a number 1…61", path, 0, 0, "P118")
            xyzabc = np.concatenate([np.array(value[:3], float), wpr_to_abc(np.array(value[3:], float))])
            out[int(number)] = frame_to_matrix(xyzabc) if kind == "uframe" else tuple(float(v) for v in xyzabc)
    return uframes, utools


# ---------------------------------------------------------------------------- record shapes


def _analyse(tree, ordinal_at) -> dict | None:
    """GP1 of a record: {'X': (ordinal, signed), …, 'uf': ordinal | 'F', 'ut': …, 'config':
    ordinal, 'units': {axis: unit}}; None when the record has no GP1."""
    for group in tree.find_data("group"):
        if str(group.children[0]) != "GP1":
            continue
        out: dict = {"units": {}}
        for item in group.children[1:]:
            if item.data in ("uf", "ut"):
                v = item.children[0]
                out[item.data] = ordinal_at[v.start_pos] if isinstance(v, Token) and v.type == "NUMBER" else "F"
            elif item.data == "config":
                out["config"] = ordinal_at[item.children[0].start_pos]
            else:
                axis, signed = str(item.children[0]), item.children[1]
                number = signed.children[-1]
                out[axis] = (ordinal_at[number.start_pos], len(signed.children) > 1 and signed.children[0] is not None)
                unit = item.children[2] if len(item.children) > 2 else None
                out["units"][axis] = str(unit) if unit is not None else ""
        return out
    return None


def _problem(gp1: dict | None) -> tuple[str, str] | None:
    """(axis or '', what is wrong) with a Cartesian GP1's components and units, None if right."""
    if gp1 is None or "X" not in gp1:
        return None
    missing = [a for a in "XYZWPR" if a not in gp1]
    if missing:
        return "", f"lacks {', '.join(missing)}"
    for axis in "XYZWPR":
        unit = gp1["units"].get(axis)
        want = "mm" if axis in "XYZ" else "deg"
        if unit != want:
            return axis, f"{axis} in {unit or 'no unit'}, expected {want}"
    return None


# ---------------------------------------------------------------------------- reading


class _Reader:
    def __init__(self, path: str, text: str, frames_text: str | None):
        self.path, self.text = path, text
        self.frames_text = frames_text
        self.diagnostics: list[Diagnostic] = []
        self._lines = LineIndex(text)
        self.shapes: dict[str, dict | None] = {}

    def warn(self, at: int, code: str, message: str) -> None:
        self.diagnostics.append(Diagnostic(self.path, *self.line_col(at), code, message))

    def line_col(self, at: int) -> tuple[int, int]:
        """1-based (line, column) of an offset (``diagnostics.LineIndex``: many warnings stay cheap)."""
        return self._lines.line_col(at)

    def error(self, at: int, message: str, code: str = "P101"):
        return PostprocError(message, self.path, *self.line_col(at), code)

    def sections(self) -> dict[str, tuple[int, int]]:
        text = self.text
        found = list(_SECTION.finditer(text))
        lead = len(text) - len(text.lstrip())
        if not found or found[0].start() != lead or found[0].group(1) != "PROG":
            raise self.error(lead, "an LS program starts with /PROG <name>")
        out: dict[str, tuple[int, int]] = {}
        for k, m in enumerate(found):
            name = m.group(1)
            if name in out:
                raise self.error(m.start(), f"/{name} twice")
            end = found[k + 1].start() if k + 1 < len(found) else len(text)
            out[name] = (m.end(), end)
        if "MN" not in out:
            raise self.error(len(text), "no /MN section")
        if "END" not in out:
            raise self.error(len(text), "no /END at the end of the program")
        if text[out["END"][0]:].strip():
            raise self.error(out["END"][0] + len(text[out["END"][0]:]) - len(text[out["END"][0]:].lstrip()),
                             "text after /END")
        order = [m.group(1) for m in found]
        if "POS" in out and order.index("POS") < order.index("MN"):
            raise self.error(found[order.index("POS")].start(), "/POS before /MN")
        return out

    def main(self, start: int, end: int):
        """The /MN lines → motions [(offset, kind, 'P' | 'PR', n, modifier)], reads {n: offset}."""
        text = self.text
        motions, reads = [], {}
        previous_c = False
        offset = text.find("\n", start) + 1 if text.find("\n", start) >= 0 else end
        while offset < end:
            nl = text.find("\n", offset)
            line_end = end if nl < 0 or nl > end else nl
            line = text[offset:line_end]
            if line.strip():
                m = _MN_LINE.match(line)
                if m is None:
                    raise self.error(offset + len(line) - len(line.lstrip()), "a /MN line is '<number>: <instruction> ;'")
                body, at = m.group(2), offset + m.start(2)
                instr = body.strip()
                if instr.startswith("!") or instr.startswith("--eg") or instr.startswith("//"):
                    pass
                else:
                    mm = _MOTION_RE.match(body)
                    continued = m.group(1) == ""
                    if mm and (mm.group(1) or (continued and previous_c)):
                        letter = mm.group(1)
                        kind = _KIND[letter] if letter else "CIRC-end"
                        modifier = _MODIFIER.search(body, mm.end())
                        index = mm.group(4)
                        motions.append((at + mm.start(3), kind, mm.group(3), int(index) if index.isdigit() else index,
                                        modifier.group(1) if modifier else None))
                        rest = body[mm.end():]
                        rest_at = at + mm.end()
                        previous_c = letter == "C"
                    else:
                        rest, rest_at = body, at
                        if not continued:
                            previous_c = False
                    for r in _P_REF.finditer(rest):
                        reads.setdefault(int(r.group(1)), rest_at + r.start())
            offset = line_end + 1
        return motions, reads

    def positions(self, start: int, end: int) -> dict[int, tuple]:
        """The /POS records: n → (offset of 'P[', record start, GP1 analysis | None, tokens)."""
        text = self.text
        out: dict[int, tuple] = {}
        at = start
        for m in _RECORD.finditer(text, start, end):
            gap = text[at:m.start()]
            if gap.strip():
                raise self.error(at + len(gap) - len(gap.lstrip()), "/POS holds only records P[n]{ … };")
            at = m.end()
            record = m.group()
            key = _BLANKS.sub(" ", _NUM_RE.sub("0", _STRINGS.sub(_empty, record)))
            if key not in self.shapes:
                try:
                    tree = parser().parse(key)
                except UnexpectedInput:
                    self.syntax_error(m.start(), record)
                ordinal_at = {t.start(): k for k, t in enumerate(TOKEN_RE.finditer(key))}
                gp1 = _analyse(tree, ordinal_at)
                self.shapes[key] = (gp1, ordinal_at[key.index("[") + 1], _problem(gp1))
            gp1, n_ord, problem = self.shapes[key]
            tokens = list(TOKEN_RE.finditer(text, m.start(), m.end()))
            n = int(float(tokens[n_ord][0]))
            if n in out:
                raise self.error(m.start(), f"P[{n}] twice in /POS")
            out[n] = (m.start(), gp1, tokens, problem)
        gap = text[at:end]
        if gap.strip():
            raise self.error(at + len(gap) - len(gap.lstrip()), "/POS holds only records P[n]{ … }; (one not closed?)")
        return out

    def syntax_error(self, start, record):
        located = unexpected(parser().parse, record, "end of record")
        if located is not None:
            pos, found = located
            raise self.error(start + pos, f"syntax error: unexpected {found}")
        raise self.error(start, "syntax error")

    def number(self, tokens, ordinal, signed):
        """(value, span start, span end) of a number token, its sign included."""
        t = tokens[ordinal]
        s = t.start()
        token = t.group()
        if signed:
            s -= 1
            while self.text[s] in " \t\r\n":
                s -= 1
            token = self.text[s] + token
        return float(token), s, t.end()

    def read(self) -> FanucProgram:
        sections = self.sections()
        motions, reads = self.main(*sections["MN"])
        records = self.positions(*sections["POS"]) if "POS" in sections else {}
        uframes, utools = read_frames(self.frames_text)
        frames: list[Frame] = []
        frame_keys: dict = {}
        chosen: dict[int, tuple] = {}  # n → (kind of its first motion, offset)
        skipped: set[int] = set()
        for at, kind, register, n, modifier in motions:
            if isinstance(n, str):
                self.warn(at, "P211", f"target {register}[{n}] is indexed at run time: left as written")
                continue
            if register == "PR":
                self.warn(at, "P211", f"target PR[{n}] is a position register, known at run time: left as written")
                continue
            if n in skipped:
                continue
            if modifier is not None:
                self.warn(at, "P211", f"P[{n}] is moved to with {modifier}: the target is computed at run time; "
                          f"P[{n}] left as written")
                skipped.add(n)
                chosen.pop(n, None)
                continue
            if n not in records:
                self.warn(at, "P215", f"P[{n}] has no record in /POS: left as written")
                skipped.add(n)
                continue
            if n in reads:
                self.warn(at, "P217", f"P[{n}] is also read by the instruction at line "
                          f"{self.line_col(reads[n])[0]}: compensating it would change that too; left as written")
                skipped.add(n)
                continue
            chosen.setdefault(n, (kind, at))
        rows = []
        configs = []
        for n, (kind, at) in sorted(chosen.items(), key=lambda kv: records[kv[0]][0]):
            start, gp1, tokens, problem = records[n]
            if gp1 is None:
                self.warn(start, "P211", f"P[{n}] has no group GP1: left as written")
                continue
            if "X" not in gp1:
                continue  # joint representation: not a Cartesian target
            if problem is not None:
                axis, message = problem
                raise self.error(tokens[gp1[axis][0]].start() if axis else start, f"P[{n}] {message}", "P118")
            values, spans = [], []
            for axis in "XYZWPR":
                v, s, e = self.number(tokens, *gp1[axis])
                values.append(v)
                spans.append((s, e))  # (X, Y, Z, W, P, R)
            uf, ut = gp1.get("uf"), gp1.get("ut")
            uf_n = int(float(tokens[uf][0])) if isinstance(uf, int) else None
            ut_n = int(float(tokens[ut][0])) if isinstance(ut, int) else None
            frame = -1
            if uf_n is None or uf_n not in uframes:
                self.warn(start, "P201", f"user frame UF {uf_n if uf_n is not None else 'F'} of P[{n}] is not in the "
                          "frame file (--frames): left as written")
            elif ut_n is None or ut_n not in utools:
                self.warn(start, "P203", f"tool frame UT {ut_n if ut_n is not None else 'F'} of P[{n}] is not in the "
                          "frame file (--frames): left as written")
            else:
                key = (uf_n, ut_n)
                if key not in frame_keys:
                    frames.append(Frame(uframes[uf_n], utools[ut_n], f"UF {uf_n} / UT {ut_n}"))
                    frame_keys[key] = len(frames) - 1
                frame = frame_keys[key]
            configs.append(tokens[gp1["config"]][0][1:-1] if "config" in gp1 else "")
            rows.append((start, values, spans, frame, _MOTION[kind]))
        return self.build(rows, configs, frames)

    def build(self, rows, configs, frames) -> FanucProgram:
        n = len(rows)
        if n:
            at, values, spans, frame, motion = zip(*rows)
        else:
            at, values, spans, frame, motion = (), (), (), (), ()
        values = np.array(values, float).reshape(n, 6)
        line, col = self._lines.lines_cols(np.array(at, np.int64))
        bad = ~np.isfinite(values).all(axis=1)
        if bad.any():
            r = int(np.flatnonzero(bad)[0])
            raise PostprocError("a position's component is not a finite number", self.path, int(line[r]), int(col[r]),
                                "P103")
        poses = np.concatenate([values[:, :3], wpr_to_abc(values[:, 3:])], axis=1)
        spans = np.array(spans, np.int64).reshape(n, 6, 2)
        # A, B, C = R, P, W (``wpr_to_abc``): the orientation's tokens in A, B, C order, so that
        # --orientation writes each corrected angle into its own token
        targets = Targets(poses=poses, spans=spans[:, :3], abc_spans=spans[:, [5, 4, 3]], file=np.zeros(n, np.int32),
                          line=line, col=col, frame=np.array(frame, np.int32),
                          motion=np.array(motion, np.int8))
        stamps = {}
        m = _STAMP.search(self.text)
        if m:
            stamps[0] = m.group().strip()
        return FanucProgram(files=[self.path], texts=[self.text], targets=targets, frames=frames,
                            diagnostics=self.diagnostics, dialect="fanuc", stamps=stamps,
                            newlines=[_newline(self.text)], comment="!", named_targets=True, configs=configs,
                            unmapped_configuration=np.array([bool(c.strip()) for c in configs], bool))


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


def read(files: list[str], texts: list[str], frames: list[str] | None = None) -> FanucProgram:
    """Read an LS program (one file); ``frames`` holds the text of the frame file (TOML).
    Raises PostprocError (P101 syntax, P118 position or frame file, P103) on bad input."""
    if len(files) != 1:
        raise PostprocError("an LS program is one .ls file", files[0] if files else "<none>", 0, 0, "P108")
    if frames and len(frames) > 1:
        raise PostprocError("one frame file (--frames) per LS program", files[0], 0, 0, "P118")
    return _Reader(files[0], texts[0], frames[0] if frames else None).read()

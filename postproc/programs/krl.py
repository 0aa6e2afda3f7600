"""KUKA KRL reader: the texts of a module (.src, its .dat, optionally $config.dat) → Program.

Syntax lives in ``grammars/krl.lark`` (one statement per physical line, as KRL has it).
Speed comes from parsing each distinct line *shape* once: a line with every number token
and every digit run ending a name (``XP12``, ``FP3``) replaced by ``0`` (``SHAPE_RE``).
Whatever the parse of a shape tells (the statement, which of its numbers are a target's
X…C) holds for every line of that shape, so the numbers and names of the line are all that
is left to read. Target lines of frequent shapes are then read
without a Python loop: one regex built from those shapes (``_Accel``) pulls the numbers of
a whole chunk of text at once and numpy turns them into poses and spans. Everything else
(declarations, frames, block structure, motions to names) goes line by line through the
interpreter (``_Reader``), in textual order.

Semantics (tests/test_krl.py shows each on a small program):

* a Target is a Cartesian motion target (inline POS/E6POS/FRAME aggregate or the
  aggregate a position variable was given: its .dat declaration or an assignment);
  axis targets, frames, comments and strings are never targets;
* the frame of a target is INV_POS($ROBROOT):$BASE (and the left operands of ``:``),
  tracked in textual order through each DEF; unresolvable → frame -1 + warning P201;
* a partial inline aggregate takes its missing components from the preceding Cartesian
  motion target (same DEF, same frame), NaN where none is known.
"""
from __future__ import annotations

import gc
import re
from bisect import bisect_left
from dataclasses import dataclass

import numpy as np
from lark import Lark, Token, Tree
from lark.exceptions import UnexpectedCharacters, UnexpectedInput, UnexpectedToken

from ..diagnostics import Diagnostic, PostprocError, line_col
from ..frames import compose, frame_to_matrix, inverse, matrix_to_frame
from ..resources import grammar_path
from . import MOTIONS, STAMP_PREFIX, Frame, Program, Targets

__all__ = ["read", "NUMBER_RE", "SHAPE_RE", "parser"]

# A number token: what the grammar's NUMBER matches (same look-arounds), so that the k-th
# match of a line is the k-th NUMBER the parser sees (or a digit string inside a comment
# or a string, which no rule ever reads as a value).
_NUM = r"(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
NUMBER_RE = re.compile(r"(?<![\w$.])" + _NUM + r"(?![\w.])")
# The shape placeholders: number tokens (group 1) and the digits ending a name (XP12 → XP0;
# in P[3] the 3 is a number): lines that differ only there share one parse. The component
# names A1…A6 / E1…E6 stay as written (one letter + digits): they tell axis from Cartesian.
_NAME_DIGITS = r"(?:(?<=[^\W\d])|(?<=\$))(?<!(?<![\w$])[AaEe])\d+(?![\w$])"
SHAPE_RE = re.compile(r"(?<![\w$.])(" + _NUM + r")(?![\w.])|" + _NAME_DIGITS)
_PLACEHOLDER = "0"

XYZABC = ("X", "Y", "Z", "A", "B", "C")
_COMP = {k: i for i, k in enumerate(XYZABC)}
_AXIS_KEYS = {f"A{i}" for i in range(1, 7)}
_POS_TYPES = {"POS", "E6POS", "FRAME"}
_AXIS_TYPES = {"AXIS", "E6AXIS"}
_MOTION = {m: i for i, m in enumerate(MOTIONS)}
_KIND_OF = {"PTP": "PTP", "LIN": "LIN", "SPTP": "SPTP", "SLIN": "SLIN", "SPL": "SPL"}
_STANDARD_AXIS = re.compile(r"^XHOME\d*$|^\$AXIS_\w+$|^\$H_AXIS\w*$", re.I)
_RUNTIME_POS = re.compile(r"^\$POS_\w+$", re.I)
_BLANK = re.compile(r"\s*")
_FOLD = re.compile(r"^\s*;\s*(END)?FOLD\b", re.I)

# ---------------------------------------------------------------------------- parser

_PARSER = None


def parser():
    """The LALR parser of ``grammars/krl.lark`` (built once, cached on disk by lark)."""
    global _PARSER
    if _PARSER is None:
        _PARSER = Lark(
            grammar_path("krl.lark").read_text(),
            parser="lalr",
            lexer="contextual",
            start="line",
            cache=True,
        )
    return _PARSER


_SHOWN = {
    "COMMA": "','", "RBRACE": "'}'", "LBRACE": "'{'", "LPAR": "'('", "RPAR": "')'",
    "LSQB": "'['", "RSQB": "']'", "COLON": "':'", "EQUAL": "'='", "DOT": "'.'",
    "NUMBER": "a number", "NAME": "a name", "STRING": "a string", "$END": "end of line",
    "ENUM": "a #value", "APPROX": "C_PTP/C_DIS/C_VEL/C_ORI/C_SPL", "MOVE": "a motion",
    "COMP_OP": "a comparison", "ADD_OP": "'+' or '-'", "BITS": "a bit literal",
    "VALUE": "a value ({…}, a name or a number)",
}
_OPERATORS = {"ADD_OP", "MUL_OP", "AND_OP", "OR_OP", "EXOR_OP", "COMP_OP", "COLON", "DOT",
              "LSQB", "LPAR", "COMMENT", "NOT_OP", "BITS", "STRING", "ENUM"}


# ---------------------------------------------------------------------------- values


class _Unknown:
    """A value the reader cannot know statically, with where and why."""

    __slots__ = ("why", "where")

    def __init__(self, why: str, where: tuple[int, int] = (0, 0)):
        self.why = why
        self.where = where  # (line, col) in the file being read


@dataclass
class _Num:
    value: float
    start: int  # offsets of the token (sign included) in the file's text
    end: int


@dataclass
class _Bad:
    """A non-numeric value where a number may be needed (P103 if it is)."""

    text: str
    line: int
    col: int


class _Agg:
    """An aggregate as written: fields (upper-case names) → _Num | str | _Agg | _Bad.

    ``base`` is the value a partial assignment was merged onto (its fields count where this
    one has none); ``file/line/col`` locate the ``{``."""

    __slots__ = ("fields", "type", "file", "line", "col", "base")

    def __init__(self, fields, type_, file, line, col, base=None):
        self.fields = fields
        self.type = type_
        self.file = file
        self.line = line
        self.col = col
        self.base = base

    def get(self, key):
        a = self
        while a is not None:
            if key in a.fields:
                return a.fields[key]
            a = a.base
        return None

    def keys(self) -> set:
        out, a = set(), self
        while a is not None:
            out |= a.fields.keys()
            a = a.base
        return out

    def kind(self) -> str:
        """'cart', 'axis' or 'other' (no component that tells)."""
        t = (self.type or "").upper()
        if t in _AXIS_TYPES:
            return "axis"
        if t in _POS_TYPES:
            return "cart"
        keys = self.keys()
        if keys & _AXIS_KEYS:
            return "axis"
        if keys & set(XYZABC):
            return "cart"
        return "other"

    def pose(self, path: str, text: str):
        """(pose[6] NaN where unwritten, spans[6], written[6]); P103 on a bad component."""
        pose, spans, written = [np.nan] * 6, [-1] * 6, [False] * 6
        for i, k in enumerate(XYZABC):
            v = self.fields.get(k)
            own = v is not None
            if v is None and self.base is not None:
                v = self.base.get(k)
            if v is None:
                continue
            if isinstance(v, _Num):
                if not np.isfinite(v.value):
                    raise PostprocError(f"component {k} of the target is not a finite number", path,
                                        *line_col(text, v.start), "P103")
                pose[i] = v.value
                written[i] = True
                if own and i < 3:
                    spans[2 * i], spans[2 * i + 1] = v.start, v.end
            elif isinstance(v, _Bad):
                raise PostprocError(f"component {k} of a target must be a number, found '{v.text}'", path,
                                    v.line, v.col, "P103")
            else:
                raise PostprocError(f"component {k} of a target must be a number", path, self.line, self.col,
                                    "P103")
        return pose, spans, written

    def frame6(self):
        """The 6 numbers of a fully written frame, or None."""
        out = []
        for k in XYZABC:
            v = self.get(k)
            if not isinstance(v, _Num) or not np.isfinite(v.value):
                return None
            out.append(v.value)
        return out


@dataclass
class _Var:
    name: str
    type: str  # upper-case declared type ('' when not declared here)
    array: bool
    value: object = None  # _Agg | _Unknown | scalar | None (not initialised)
    elems: dict | None = None  # array: index tuple → value


# ---------------------------------------------------------------------------- frames


@dataclass(frozen=True)
class _FrameState:
    base: object  # 4x4 ndarray, or _Unknown
    base_label: str
    tool: object  # 6 floats tuple, or _Unknown / None (never set)
    tool_label: str
    robroot: object  # 4x4 ndarray or _Unknown

    def same(self, other) -> bool:
        def eq(a, b):
            if isinstance(a, np.ndarray) and isinstance(b, np.ndarray):
                return np.allclose(a, b)
            return a is b or a == b

        return eq(self.base, other.base) and eq(self.tool, other.tool) and eq(self.robroot, other.robroot)


_I4 = np.eye(4)
_START = _FrameState(_I4, "$NULLFRAME", None, "", _I4)


# ---------------------------------------------------------------------------- shapes


class _Shape:
    """What the parse of one line shape says. ``kind``: 'blank', 'hot' (a motion whose
    targets are literal Cartesian aggregates: read vectorised) or 'stmt'."""

    __slots__ = ("text", "kind", "tree", "ph", "phidx", "names", "name_paths", "plan", "fold", "error")

    def __init__(self, text):
        self.text = text
        ms = list(SHAPE_RE.finditer(text))
        self.ph = [m.start() for m in ms]  # every placeholder, in order (the line's "slots")
        self.phidx = {p: j for j, p in enumerate(self.ph)}
        self.names = [m.start() for m in ms if m.group(1) is None]  # those inside names
        self.name_paths = None  # where in the tree those names are (on first use)
        self.kind = "stmt"
        self.tree = None
        self.plan = None
        self.fold = 0
        self.error = None


@dataclass
class _Plan:
    """How to read the targets of a hot line from its numbers: per target row, the slot
    (index among the line's numbers) of each of X…C, its sign and the distance from the
    sign to the digits, the ``{`` position in the shape, motion index, chain flag."""

    slots: np.ndarray  # [R, 6] int, -1 = not written
    neg: np.ndarray  # [R, 6] bool
    gap: np.ndarray  # [R, 6] int, chars from sign to number (0 = unsigned)
    brace: list  # [R] shape positions of '{'
    motion: list  # [R]
    chain: list  # [R] bool: does the row become the current position (CIRC aux: no)
    spl: bool  # an SPL segment (must stand inside SPLINE … ENDSPLINE)
    ph: list  # placeholder positions in the shape
    free: list = ()  # slots that carry their own sign (accelerator alternatives)
    names: list = ()  # slots that are the digits ending a name


def _number_slot(expr, shape: _Shape):
    """(slot, negative, gap) when ``expr`` is a literal number (optionally signed)."""
    if expr.data == "number":
        return shape.phidx[expr.children[0].start_pos], False, 0
    if expr.data == "signed" and expr.children[1].data == "number":
        sign = expr.children[0]
        num = expr.children[1].children[0]
        return shape.phidx[num.start_pos], sign == "-", num.start_pos - sign.start_pos
    return None


def _hot_aggregate(agg, shape):
    """Slots of a literal Cartesian aggregate (or None when it is not one)."""
    ch = agg.children
    typ = None
    if ch and isinstance(ch[0], Token):
        typ = ch[0].upper()
        ch = ch[1:]
    keys = {}
    for item in ch:
        if item is None:
            continue
        name = item.children[0].upper()
        keys[name] = item.children[-1]
    if typ is not None and typ not in ("POS", "E6POS"):
        return None
    if typ is None and (keys.keys() & _AXIS_KEYS or not keys.keys() & {"X", "Y", "Z"}):
        return None
    slots, neg, gap = [-1] * 6, [False] * 6, [0] * 6
    for k, v in keys.items():
        if k in _COMP:
            s = _number_slot(v, shape)
            if s is None:
                return None  # the interpreter reports it
            slots[_COMP[k]], neg[_COMP[k]], gap[_COMP[k]] = s
    if all(s < 0 for s in slots[:3]):
        return None
    return slots, neg, gap, agg.meta_brace


def _analyse(shape: _Shape) -> None:
    """Parse ``shape.text`` and decide how lines of this shape are read."""
    text = shape.text
    stripped = text.strip()
    if not stripped:
        shape.kind = "blank"
        return
    if stripped.startswith(";"):
        # a comment line: folds matter (balance), nothing else does
        m = _FOLD.match(text)
        if m:
            shape.fold = -1 if m.group(1) else 1
        shape.kind = "fold" if shape.fold else ("stamp" if STAMP_PREFIX in text else "blank")
        return
    try:
        tree = parser().parse(text)
    except UnexpectedInput as exc:
        shape.kind = "error"
        shape.error = exc
        return
    shape.tree = tree
    stmt = None
    comment = None
    for c in tree.children:
        if isinstance(c, Tree):
            stmt = c
        elif isinstance(c, Token) and c.type == "COMMENT":
            comment = c
    if comment is not None:
        m = _FOLD.match(text[comment.start_pos:])
        if m:
            shape.fold = -1 if m.group(1) else 1
    if stmt is None:
        shape.kind = "fold" if shape.fold else "blank"
        return
    if shape.fold or (comment is not None and STAMP_PREFIX in comment):
        return
    if stmt.data not in ("move", "circ"):
        return
    kw = stmt.children[0].upper()
    if kw.endswith("_REL"):
        return
    tail = stmt.children[-1]
    for item in tail.children:
        if isinstance(item, Tree) and item.data == "with_item":
            root = item.children[0]
            while root.data in ("member", "index"):
                root = root.children[0]
            if root.data == "name" and root.children[0].upper() in ("$BASE", "$TOOL", "$ROBROOT", "$IPO_MODE"):
                return
    if stmt.data == "move":
        ops = [(stmt.children[1], _MOTION[_KIND_OF[kw]], True)]
    else:
        s = "SCIRC" if kw.startswith("S") else "CIRC"
        ops = [(stmt.children[1], _MOTION[s + "-aux"], False), (stmt.children[2], _MOTION[s + "-end"], True)]
    rows = []
    for expr, motion, chain in ops:
        if not (isinstance(expr, Tree) and expr.data == "aggregate"):
            return
        _mark_brace(expr, text)
        hot = _hot_aggregate(expr, shape)
        if hot is None:
            return
        rows.append((hot, motion, chain))
    shape.plan = _Plan(
        slots=np.array([r[0][0] for r in rows], dtype=np.int64),
        neg=np.array([r[0][1] for r in rows], dtype=bool),
        gap=np.array([r[0][2] for r in rows], dtype=np.int64),
        brace=[r[0][3] for r in rows],
        motion=[r[1] for r in rows],
        chain=[r[2] for r in rows],
        spl=kw == "SPL",
        ph=shape.ph,
        names=[shape.phidx[p] for p in shape.names],
    )
    shape.kind = "hot"


def _mark_brace(agg, text: str) -> None:
    """Remember where the aggregate's '{' stands (lark drops anonymous tokens)."""
    first = _first_pos(agg)
    if first is None:  # '{}' : find it from the end
        agg.meta_brace = -1
        return
    agg.meta_brace = text.rfind("{", 0, first)


def _name_paths(tree, names) -> list:
    """Child-index paths to the tokens of ``tree`` that hold a name placeholder."""
    out = []

    def walk(node, path):
        for i, c in enumerate(node.children):
            if isinstance(c, Token):
                if c.type in ("NAME", "ENUM", "BITS") and any(c.start_pos <= p < c.end_pos for p in names):
                    out.append(path + (i,))
            elif c is not None:
                walk(c, path + (i,))

    walk(tree, ())
    return out


def _first_pos(tree):
    for c in tree.children:
        if isinstance(c, Token):
            return c.start_pos
        if c is not None:
            p = _first_pos(c)
            if p is not None:
                return p
    return None


# ---------------------------------------------------------------------------- hot rows


class _HotRows:
    """Columns of the targets read from hot lines (vectorised), appended chunk by chunk."""

    def __init__(self):
        self.parts = []

    def add(self, plan: _Plan, fi: int, line0: np.ndarray, start: np.ndarray, cols: list, key0: int,
            where=None) -> None:
        """``line0``: 0-based line numbers, ``start``: line start offsets, ``cols[j]``: the
        j-th number string of each line (a sequence, one per line)."""
        n = len(line0)
        if n == 0:
            return
        used = sorted({int(s) for s in plan.slots.ravel() if s >= 0})
        brace_slots = [sum(1 for p in plan.ph if p < b) for b in plan.brace]
        need_len = max([int(plan.slots[:, :3].max()) + 1] + brace_slots)
        lens = {j: np.fromiter(map(len, cols[j]), np.int64, n) for j in range(need_len)}
        vals = {j: np.array(cols[j], dtype=np.float64) for j in used}
        ph = np.array(plan.ph, dtype=np.int64)
        for j, v in vals.items():
            if not np.isfinite(v).all():  # 1E999: P103 at the token
                k = int(np.flatnonzero(~np.isfinite(v))[0])
                off = int(start[k]) + int(ph[j]) + sum(len(cols[q][k]) - 1 for q in range(j))
                path, text = where
                raise PostprocError(f"'{cols[j][k]}' is not a finite number", path, *line_col(text, off), "P103")
        # offset of slot j in its line: ph[j] + Σ_{i<j} (len_i − 1)
        shift = [np.zeros(n, np.int64)]
        for j in range(need_len):
            shift.append(shift[-1] + lens[j] - 1)
        for r in range(len(plan.motion)):
            pose = np.full((n, 6), np.nan)
            written = np.zeros((n, 6), bool)
            spans = np.full((n, 6), -1, np.int64)
            for c in range(6):
                j = int(plan.slots[r, c])
                if j < 0:
                    continue
                v = vals[j]
                pose[:, c] = -v if plan.neg[r, c] else v
                written[:, c] = True
                if c < 3:
                    s = start + ph[j] + shift[j]
                    spans[:, 2 * c] = s - plan.gap[r, c]
                    spans[:, 2 * c + 1] = s + lens[j]
            b = plan.brace[r]
            col = b + 1 + shift[brace_slots[r]]
            self.parts.append(dict(
                key=key0 + line0 * 4 + r, pose=pose, written=written, spans=spans,
                file=np.full(n, fi, np.int32), line=(line0 + 1).astype(np.int32), col=col.astype(np.int32),
                motion=np.full(n, plan.motion[r], np.int8), chain=np.full(n, plan.chain[r]),
                spl=np.full(n, plan.spl),
            ))


# ---------------------------------------------------------------------------- accelerator


class _Accel:
    """One regex matching, line by line, the frequent hot shapes with their numbers as
    groups; any other line falls into the last group and goes to the interpreter.

    Alternatives are *sign-free* shapes (``_generalise``): a target component may carry
    a sign or not, so ``{X 1,Y -2}`` and ``{X -1,Y 2}`` share one alternative."""

    MAX = 8

    def __init__(self, alts: list):
        self.alts = alts[: self.MAX]  # (sign-free text, plan)
        parts_all, self.first = [], []
        g = 1
        for text, plan in self.alts:
            parts, last = [], 0
            free, names = set(plan.free), set(plan.names)
            for j, p in enumerate(plan.ph):
                parts.append(re.escape(text[last:p]))
                parts.append(r"(\d+)" if j in names else "([-+]?" + _NUM + ")" if j in free else "(" + _NUM + ")")
                last = p + 1
            parts.append(re.escape(text[last:]))
            parts_all.append("".join(parts))
            self.first.append(g)
            g += len(plan.ph)
        self.fallback = g
        self.regex = re.compile("^(?:" + "|".join(parts_all) + r"|([^\n]*))$", re.M)


def _generalise(shape: _Shape):
    """(sign-free text, plan) of a hot shape: the sign written before a target component
    moves into the number slot (the slot then matches ``[-+]?number``)."""
    plan = shape.plan
    text = shape.text
    free, drop = set(), set()
    for r in range(len(plan.motion)):
        for c in range(6):
            j = int(plan.slots[r, c])
            if j < 0:
                continue
            if plan.gap[r, c] == 1:
                drop.add(plan.ph[j] - 1)
                free.add(j)
            elif plan.gap[r, c] == 0:
                free.add(j)
    out, keep = [], []
    for i, ch in enumerate(text):
        if i not in drop:
            keep.append(i)
            out.append(ch)
    newpos = {old: new for new, old in enumerate(keep)}
    ph = [newpos[p] for p in plan.ph]
    brace = [newpos[b] for b in plan.brace]
    neg = plan.neg.copy()
    gap = plan.gap.copy()
    for r in range(len(plan.motion)):
        for c in range(6):
            if int(plan.slots[r, c]) in free:
                neg[r, c] = False
                gap[r, c] = 0
    g = _Plan(slots=plan.slots, neg=neg, gap=gap, brace=brace, motion=plan.motion, chain=plan.chain,
              spl=plan.spl, ph=ph, names=plan.names)
    g.free = sorted(free)
    return "".join(out), g


# ---------------------------------------------------------------------------- reader


def read(files: list[str], texts: list[str], config: list[str] | None = None) -> Program:
    """Parse a KRL module: ``files[0]`` the .src (or any module), ``files[1]`` its .dat when
    present, ``config`` the texts of $config.dat files (BASE_DATA / TOOL_DATA / globals).

    Raises PostprocError (P101 syntax, P102 undeclared target, P103 bad component, P104
    empty / no DEF) with the file:line:col of the offending token."""
    enabled = gc.isenabled()
    gc.disable()  # millions of small objects, no cycles: the collector only costs time here
    try:
        return _Reader(list(files), list(texts), list(config or [])).run()
    finally:
        if enabled:
            gc.enable()


class _Reader:
    CHUNK = 1 << 17  # characters per vectorised chunk: small enough that its strings stay in cache

    def __init__(self, files, texts, config, accelerate: bool = True):
        if len(files) != len(texts):
            raise ValueError("files and texts differ in length")
        self.files, self.texts, self.config = files, texts, config
        self.accelerate = accelerate
        self.shapes: dict[str, _Shape] = {}
        self.diagnostics: list[Diagnostic] = []
        self.frames: list[Frame] = []
        self.newline: dict[int, str] = {}
        self.frame_ix: dict = {}
        self.unknown_frames: dict = {}  # reason key → [path, line, col, message, count]
        self.hot = _HotRows()
        self.cold = {k: [] for k in ("key", "pose", "written", "spans", "file", "line", "col", "motion",
                                     "frame", "emit", "chain")}
        self.timeline: list = []  # (key, frame index, unknown reason key)
        self.globals: dict[str, _Var] = {}
        self.module: dict[str, _Var] = {}
        self.local: dict[str, _Var] | None = None
        self.targets_of: dict[int, tuple] = {}  # id(_Agg) → (frame, line) of its first use
        self.call_states: dict[str, list] = {}

    # ---------------------------------------------------------------- driver

    def run(self) -> Program:
        for k, text in enumerate(self.config):
            self.scan(-1 - k, text, "$config.dat" if len(self.config) == 1 else f"$config.dat[{k}]", role="config")
        order = list(range(1, len(self.files))) + [0]
        for rank, fi in enumerate(order):
            self.scan(fi, self.texts[fi], self.files[fi], role="module", rank=rank)
        targets = self.assemble()
        stamps, newlines = {}, []
        for fi, text in enumerate(self.texts):
            newlines.append(self.newline.get(fi, "\n"))
            at = text.find(STAMP_PREFIX)
            while at >= 0:
                a = text.rfind("\n", 0, at) + 1
                b = text.find("\n", at)
                b = len(text) if b < 0 else b
                line = text[a:b]
                if ";" in line[: at - a]:
                    stamps[fi] = line.strip()
                    break
                at = text.find(STAMP_PREFIX, b)
        for path, line, col, msg, count in self.unknown_frames.values():
            if count:
                self.diagnostics.append(Diagnostic(path, line, col, "P201",
                                                   f"{msg}: {count} target(s) left as written"))
        return Program(files=self.files, texts=self.texts, targets=targets, frames=self.frames,
                       named_targets=bool(self.targets_of),
                       diagnostics=self.diagnostics, dialect="krl", stamps=stamps, newlines=newlines, comment=";")

    def warn(self, path, line, col, code, msg):
        self.diagnostics.append(Diagnostic(path, line, col, code, msg))

    # ---------------------------------------------------------------- scanning a file

    def shape(self, text: str) -> _Shape:
        sh = self.shapes.get(text)
        if sh is None:
            sh = _Shape(text)
            _analyse(sh)
            self.shapes[text] = sh
        return sh

    def scan(self, fi: int, text: str, path: str, role: str, rank: int = 0) -> None:
        self.fi, self.path, self.text, self.role = fi, path, text, role
        self.key0 = rank << 40
        self.blocks: list = []  # (kind, line, col, detail)
        self.folds: list = []
        self.defs_seen = 0
        self.state = _START
        self.saved_state = None
        self.fdat = None
        self.in_def = False
        self.has_def = False
        self.has_dat = False
        self.kbase = self.key0
        self.def_lines: list = []  # (first, last) 1-based lines of DEF/DEFFCT bodies
        self.spline_lines: list = []
        self.block_open = {}
        if _BLANK.fullmatch(text):
            if role == "module" and fi == 0:
                raise PostprocError("the file is empty", path, 1, 1, "P104")
            return  # an empty .dat or $config.dat declares nothing
        data = text.encode("latin-1", "replace") if not text.isascii() else text.encode("ascii")
        raw = np.frombuffer(data, np.uint8)
        nl = np.flatnonzero(raw == 10)
        if role == "module":  # the dominant line ending, for the rewriter
            crlf = int(np.count_nonzero(raw[nl[nl > 0] - 1] == 13))
            self.newline[fi] = "\r\n" if crlf and 2 * crlf >= len(nl) else "\n"
        self.starts = np.concatenate([[0], nl + 1]).astype(np.int64)
        nlines = len(self.starts) - (1 if text.endswith("\n") else 0)
        hot_lines = {}  # shape → (lines, starts, numbers) read by the interpreter loop
        first_part = len(self.hot.parts)
        if role == "module" and fi == 0 and self.accelerate and nlines > 4096:
            self.scan_accelerated(text, nlines, hot_lines)
        else:
            self.scan_lines(range(nlines), hot_lines)
        for sh, (lines, starts, nums) in hot_lines.items():
            cols = list(zip(*nums)) if sh.ph else []
            self.hot.add(sh.plan, fi, np.array(lines, np.int64), np.array(starts, np.int64), cols, self.key0,
                         (self.path, self.text))
        self.finish_file(nlines)
        self.check_parts(self.hot.parts[first_part:])

    def check_parts(self, parts) -> None:
        """Hot lines stand inside a DEF, SPL segments inside SPLINE … ENDSPLINE (the
        accelerator reads them without the interpreter, so check against the blocks)."""
        for spans, need, msg in ((self.def_lines, None, "a motion must stand inside DEF … END"),
                                 (self.spline_lines, "spl", "SPL must stand inside SPLINE … ENDSPLINE")):
            lo = np.array([a for a, _ in spans] or [0], np.int64)
            hi = np.array([b for _, b in spans] or [-1], np.int64)
            for p in parts:
                lines = p["line"] if need is None else p["line"][p["spl"]]
                if not len(lines):
                    continue
                k = np.searchsorted(lo, lines, "right") - 1
                bad = (k < 0) | (lines > hi[np.maximum(k, 0)])
                if bad.any():
                    ln = int(lines[np.flatnonzero(bad)[0]])
                    a = int(self.starts[ln - 1])
                    row = self.text[a:].split("\n", 1)[0]
                    raise PostprocError(msg, self.path, ln, len(row) - len(row.lstrip()) + 1, "P101")

    def scan_lines(self, line_indices, hot_lines) -> None:
        text, starts = self.text, self.starts
        n = len(starts)
        for i in line_indices:
            a = int(starts[i])
            b = int(starts[i + 1]) - 1 if i + 1 < n else len(text)
            self.line_at(i, a, text[a:b], hot_lines)

    def line_at(self, i: int, a: int, line: str, hot_lines) -> None:
        sh = self.shape(SHAPE_RE.sub(_PLACEHOLDER, line))
        k = sh.kind
        if k == "blank":
            return
        if k == "hot":
            nums = [m.group() for m in SHAPE_RE.finditer(line)] if sh.ph else []
            entry = hot_lines.get(sh)
            if entry is None:
                entry = hot_lines[sh] = ([], [], [])
            entry[0].append(i)
            entry[1].append(a)
            entry[2].append(nums)
            self.hot_line(i, sh)
            return
        self.interpret(i, a, line, sh)

    def hot_line(self, i: int, sh: _Shape) -> None:
        if not self.in_def:
            self.structure_error(i, sh, "a motion must stand inside DEF … END")
        if sh.plan.spl and not any(b[0] == "SPLINE" for b in self.blocks):
            self.structure_error(i, sh, "SPL must stand inside SPLINE … ENDSPLINE")

    def structure_error(self, i, sh, msg):
        line = self.text[int(self.starts[i]):].split("\n", 1)[0]
        col = len(line) - len(line.lstrip()) + 1
        raise PostprocError(msg, self.path, i + 1, col, "P101")

    def scan_accelerated(self, text: str, nlines: int, hot_lines) -> None:
        """Learn the shapes of the first lines with the interpreter, then read chunks with one
        regex over the frequent hot shapes; lines it does not take go to the interpreter."""
        from operator import itemgetter

        starts = self.starts
        learn = 2048
        self.scan_lines(range(learn), hot_lines)
        counts, plans = {}, {}

        def learn_from(entries):
            dirty = False
            for sh, entry in entries.items():
                if sh.plan is None:
                    continue
                g = _generalise(sh)
                if g[0] not in plans:
                    plans[g[0]] = g[1]
                    dirty = True
                counts[g[0]] = counts.get(g[0], 0) + len(entry[0])
            return dirty

        learn_from(hot_lines)
        accel, dirty, i = None, True, learn
        while i < nlines:
            if dirty:
                ranked = sorted(counts, key=counts.get, reverse=True)
                new = _Accel([(t, plans[t]) for t in ranked])
                if accel is None or [a[0] for a in new.alts] != [a[0] for a in accel.alts]:
                    accel = new
                dirty = False
            a = int(starts[i])
            j = int(np.searchsorted(starts, a + self.CHUNK, "left"))
            j = min(max(j, i + 1), nlines)
            b = int(starts[j]) if j < len(starts) else len(text)
            rows = accel.regex.findall(text[a:b])
            n = j - i
            if len(rows) < n or not accel.alts:  # (never: one match per line) line by line
                self.scan_lines(range(i, j), hot_lines)
                i = j
                continue
            del rows[n:]
            cols = list(zip(*rows))
            del rows
            fallback = cols[accel.fallback - 1]
            line0 = np.arange(i, j, dtype=np.int64)
            is_hot = np.zeros(n, bool)
            for (gtext, plan), g in zip(accel.alts, accel.first):
                m = np.fromiter(map(bool, cols[g - 1]), bool, n)
                if not m.any():
                    continue
                is_hot |= m
                sel = np.flatnonzero(m)
                if len(sel) == n:
                    sub = [cols[g - 1 + q] for q in range(len(plan.ph))]
                else:
                    pick = itemgetter(*sel.tolist()) if len(sel) > 1 else (lambda c, k=int(sel[0]): (c[k],))
                    sub = [pick(cols[g - 1 + q]) for q in range(len(plan.ph))]
                self.hot.add(plan, self.fi, line0[sel], starts[line0[sel]], sub, self.key0, (self.path, self.text))
                counts[gtext] += len(sel)
            del cols
            rest = np.flatnonzero(~is_hot)
            if len(rest):
                found = {}
                for k in rest.tolist():
                    li = i + k
                    self.line_at(li, int(starts[li]), fallback[k], found)
                for sh, entry in found.items():
                    e = hot_lines.setdefault(sh, ([], [], []))
                    for q in range(3):
                        e[q].extend(entry[q])
                if sum(len(e[0]) for e in found.values()) > 64:
                    dirty = learn_from(found) or dirty
                else:
                    learn_from(found)
            i = j

    def finish_file(self, nlines: int) -> None:
        if self.blocks:
            kind, line, col, detail = self.blocks[-1]
            closer = {"DEF": "END", "DEFFCT": "ENDFCT", "DEFDAT": "ENDDAT", "IF": "ENDIF", "FOR": "ENDFOR",
                      "WHILE": "ENDWHILE", "LOOP": "ENDLOOP", "REPEAT": "UNTIL", "SWITCH": "ENDSWITCH",
                      "SPLINE": "ENDSPLINE"}[kind]
            raise PostprocError(f"{kind}{' ' + detail if detail else ''} has no matching {closer}",
                                self.path, line, col, "P101")
        for line, col in self.folds:
            self.warn(self.path, line, col, "P105", ";FOLD without ;ENDFOLD")
        if self.role == "module" and self.fi == 0 and not self.has_def:
            what = "a data list (DEFDAT) with no DEF" if self.has_dat else "no DEF"
            raise PostprocError(f"{what}: expected a KRL module with DEF name( ) … END", self.path, 1, 1, "P104")

    # ---------------------------------------------------------------- interpreting a line

    def interpret(self, i, a, line, sh):
        self.ln = i + 1
        self.kbase = self.key0 + i * 4
        self.la = a
        self.lt = line
        self.sh = sh
        self._nums = None  # before a syntax error is reported: its column needs this line's numbers
        if sh.kind == "error":
            self.syntax_error(sh.error)
        if sh.fold:
            col = line.find(";") + 1
            if sh.fold > 0:
                self.folds.append((i + 1, col))
            elif self.folds:
                self.folds.pop()
            else:
                self.warn(self.path, i + 1, col, "P105", ";ENDFOLD without ;FOLD")
        if sh.tree is None:
            return
        tree = self.concrete(sh.tree) if sh.names else sh.tree
        stmt = None
        for c in tree.children:
            if hasattr(c, "data"):
                stmt = c
        if stmt is None:
            return
        if sh.kind == "hot":
            return
        handler = getattr(self, "s_" + stmt.data, None)
        if handler is not None:
            handler(stmt)

    def concrete(self, tree):
        """``tree`` with the names of this line (a shape has XP0 where the line has XP12);
        positions stay those of the shape. Only the nodes above such names are copied."""
        sh = self.sh
        if sh.name_paths is None:
            sh.name_paths = _name_paths(tree, sh.names)
        return self._rebuild(tree, sh.name_paths) if sh.name_paths else tree

    def _rebuild(self, node, paths):
        groups: dict = {}
        for p in paths:
            groups.setdefault(p[0], []).append(p[1:])
        children = list(node.children)
        for i, sub in groups.items():
            c = children[i]
            if isinstance(c, Token):
                text = self.text[self.abs_pos(c.start_pos):self.abs_pos(c.end_pos)]
                children[i] = Token.new_borrow_pos(c.type, text, c)
            else:
                children[i] = self._rebuild(c, sub)
        new = Tree(node.data, children, node._meta)
        if hasattr(node, "meta_brace"):
            new.meta_brace = node.meta_brace
        return new

    # positions and numbers of the current line
    def nums(self):
        """(start, end) in the file of each placeholder of the current line, in order."""
        if self._nums is None:
            la = self.la
            self._nums = [(m.start() + la, m.end() + la) for m in SHAPE_RE.finditer(self.lt)]
            cum, extra = [0], 0
            for a, b in self._nums:  # how much longer than its "0" each placeholder is
                extra += b - a - 1
                cum.append(extra)
            self._cum = cum
        return self._nums

    def abs_pos(self, shape_pos: int) -> int:
        """Offset in the file of a position in the current line's shape."""
        if not self.sh.ph:
            return self.la + shape_pos
        self.nums()
        return self.la + shape_pos + self._cum[bisect_left(self.sh.ph, shape_pos)]

    def col(self, shape_pos: int) -> int:
        return self.abs_pos(shape_pos) - self.la + 1

    def err(self, msg, token_or_pos, code="P101"):
        pos = token_or_pos if isinstance(token_or_pos, int) else token_or_pos.start_pos
        raise PostprocError(msg, self.path, self.ln, self.col(pos), code)

    def number(self, tok) -> _Num:
        s, e = self.nums()[self.sh.phidx[tok.start_pos]]
        return _Num(float(self.text[s:e]), s, e)

    def syntax_error(self, exc):
        shape = self.sh.text
        if isinstance(exc, UnexpectedToken) and exc.token.type != "$END":
            pos = exc.token.start_pos
            found = self.text[self.abs_pos(pos): self.abs_pos(exc.token.end_pos)] \
                if exc.token.type != "NUMBER" else self.text[slice(*self.nums()[self.sh.phidx[pos]])]
            found = f"'{found}'"
        elif isinstance(exc, UnexpectedCharacters):
            pos = exc.pos_in_stream
            rest = self.lt[self.abs_pos(pos) - self.la:]
            bad = re.match(r"[-+]?[\d.][\w.]*(?:[eE][-+]?\w*)?", rest)
            if bad:
                raise PostprocError(f"syntax error: malformed number '{bad.group()}'", self.path, self.ln,
                                    self.col(pos), "P101")
            found = f"'{rest[:1]}'"
        else:
            pos = len(shape.rstrip())
            found = "end of line"
        if isinstance(exc, UnexpectedToken) and exc.token.type == "COMMENT":
            found = "';' (a comment)"
        expected = set(getattr(exc, "expected", None) or getattr(exc, "allowed", None) or [])
        if "COMMENT" in expected:  # a comment may end any statement: say "end of line" once
            expected = (expected - {"COMMENT"}) | {"$END"}
        if {"NUMBER", "NAME", "LBRACE"} <= expected:  # anything that starts an expression
            expected = (expected - {"NUMBER", "NAME", "LBRACE", "STRING", "ENUM", "BITS", "LPAR", "ADD_OP",
                                    "NOT_OP"}) | {"VALUE"}
        shown = sorted(e for e in expected if e not in _OPERATORS) or sorted(expected)
        depth = 0
        for ch in shape[:pos]:
            depth += (ch == "{") - (ch == "}")
        where = " in aggregate" if depth > 0 else ""
        if shown and len(shown) <= 5:
            names = [_SHOWN.get(e, e) for e in shown]
            exp = ", ".join(names[:-1]) + (" or " if len(names) > 1 else "") + names[-1]
            msg = f"expected {exp}{where}, found {found}"
        else:
            msg = f"unexpected {found}{where}"
        raise PostprocError(f"syntax error: {msg}", self.path, self.ln, self.col(pos), "P101")

    # ---------------------------------------------------------------- block structure

    def open_block(self, kind, node, detail=""):
        self.blocks.append((kind, self.ln, self.col(_first_pos(node) or 0), detail))

    def close_block(self, kinds, node, word):
        if not self.blocks or self.blocks[-1][0] not in kinds:
            if self.blocks:
                kind, line, _, _ = self.blocks[-1]
                self.err(f"{word} does not close {kind} (line {line})", _first_pos(node) or 0)
            self.err(f"{word} without {' / '.join(sorted(kinds))}", _first_pos(node) or 0)
        return self.blocks.pop()

    def s_header(self, node):
        pass

    def s_def_head(self, node):
        names = [c for c in node.children if isinstance(c, Token) and c.type == "NAME"]
        name = names[0]
        self.begin_def(name, node)

    def s_fct_head(self, node):
        names = [c for c in node.children if isinstance(c, Token) and c.type == "NAME"]
        self.begin_def(names[0], node, kind="DEFFCT")

    def begin_def(self, name, node, kind="DEF"):
        if self.blocks:
            self.err(f"{kind} inside {self.blocks[-1][0]} (line {self.blocks[-1][1]}): missing "
                     f"{'END' if self.blocks[-1][0] == 'DEF' else 'end of block'}", _first_pos(node))
        self.open_block(kind, node, str(name))
        self.block_open["DEF"] = self.ln
        self.has_def = True
        self.in_def = True
        self.local = {}
        self.fdat = None
        # the first DEF starts at $NULLFRAME; a later one (a local subroutine) inherits the
        # frames its callers had, when they all agree
        if self.defs_seen == 0:
            st = _START
        else:
            calls = self.call_states.get(str(name).upper(), [])
            if not calls:
                st = _START
            elif all(c.same(calls[0]) for c in calls[1:]):
                st = calls[0]
            else:
                why = _Unknown(f"{kind} {name} is called with different $BASE/$TOOL", (self.ln, 1))
                st = _FrameState(why, "", calls[0].tool, calls[0].tool_label, calls[0].robroot)
        self.defs_seen += 1
        self.set_state(st)

    def s_def_end(self, node):
        self.close_block({"DEF"}, node, "END")
        self.end_def()

    def s_fct_end(self, node):
        self.close_block({"DEFFCT"}, node, "ENDFCT")
        self.end_def()

    def end_def(self):
        self.def_lines.append((self.block_open["DEF"], self.ln))
        self.in_def = False
        self.local = None
        self.barrier()

    def s_dat_head(self, node):
        if self.blocks:
            self.err(f"DEFDAT inside {self.blocks[-1][0]}", _first_pos(node))
        self.has_dat = True
        self.open_block("DEFDAT", node)

    def s_dat_end(self, node):
        self.close_block({"DEFDAT"}, node, "ENDDAT")

    def s_if_head(self, node):
        self.open_block("IF", node)

    def s_else_(self, node):
        if not self.blocks or self.blocks[-1][0] != "IF":
            self.err("ELSE without IF", _first_pos(node))

    def s_endif(self, node):
        self.close_block({"IF"}, node, "ENDIF")

    def s_for_head(self, node):
        self.open_block("FOR", node)

    def s_endfor(self, node):
        self.close_block({"FOR"}, node, "ENDFOR")

    def s_while_head(self, node):
        self.open_block("WHILE", node)

    def s_endwhile(self, node):
        self.close_block({"WHILE"}, node, "ENDWHILE")

    def s_loop_head(self, node):
        self.open_block("LOOP", node)

    def s_endloop(self, node):
        self.close_block({"LOOP"}, node, "ENDLOOP")

    def s_repeat_head(self, node):
        self.open_block("REPEAT", node)

    def s_until(self, node):
        self.close_block({"REPEAT"}, node, "UNTIL")

    def s_switch_head(self, node):
        self.open_block("SWITCH", node)

    def s_case(self, node):
        if not self.blocks or self.blocks[-1][0] != "SWITCH":
            self.err("CASE outside SWITCH", _first_pos(node))

    s_default = s_case

    def s_endswitch(self, node):
        self.close_block({"SWITCH"}, node, "ENDSWITCH")

    def s_spline_head(self, node):
        self.open_block("SPLINE", node)
        self.block_open["SPLINE"] = self.ln
        self.saved_state = self.state
        st = self.with_frames(node.children)
        if st is not self.state:
            self.set_state(st)

    def s_spline_end(self, node):
        self.close_block({"SPLINE"}, node, "ENDSPLINE")
        self.spline_lines.append((self.block_open["SPLINE"], self.ln))
        if self.saved_state is not None and self.saved_state is not self.state:
            self.set_state(self.saved_state)
        self.saved_state = None

    # ---------------------------------------------------------------- names and values

    def lookup(self, name: str):
        u = name.upper()
        for scope in (self.local, self.module, self.globals):
            if scope is not None and u in scope:
                return scope[u]
        return None

    def declare(self, name, type_, array, value=None, elems=None):
        u = str(name).upper()
        var = _Var(u, type_, array, value, {} if array else None)
        if self.role == "config":
            self.globals[u] = var
        elif self.local is not None:
            self.local[u] = var
        else:
            self.module[u] = var
        return var

    def value(self, expr):
        """A declaration's / assignment's right-hand side → _Agg, scalar or _Unknown."""
        d = expr.data
        if d == "aggregate":
            return self.aggregate(expr)
        if d in ("number", "signed"):
            v = self.literal_number(expr)
            return v.value if isinstance(v, _Num) else _Unknown("an expression", (self.ln, 1))
        if d == "enum":
            return expr.children[0].upper()
        if d == "name" and expr.children[0].upper() in ("TRUE", "FALSE"):
            return expr.children[0].upper() == "TRUE"
        if d == "string":
            return str(expr.children[0])
        if d == "bits":
            return str(expr.children[0])
        return _Unknown("a run-time value", (self.ln, self.col(_first_pos(expr) or 0)))

    def literal_number(self, expr):
        if expr.data == "number":
            return self.number(expr.children[0])
        if expr.data == "signed" and expr.children[1].data == "number":
            sign = expr.children[0]
            n = self.number(expr.children[1].children[0])
            start = self.abs_pos(sign.start_pos)
            return _Num(-n.value if sign == "-" else n.value, start, n.end)
        return None

    def aggregate(self, node) -> _Agg:
        ch = node.children
        typ = None
        if ch and isinstance(ch[0], Token):
            typ = ch[0].upper()
            ch = ch[1:]
        fields = {}
        for item in ch:
            if item is None:
                continue
            key = item.children[0].upper()
            v = item.children[-1]
            if v.data in ("number", "signed"):
                num = self.literal_number(v)
                if num is not None:
                    fields[key] = num
                    continue
            if v.data == "aggregate":
                fields[key] = self.aggregate(v)
            elif v.data == "enum":
                fields[key] = v.children[0].upper()
            elif v.data in ("string", "bits"):
                fields[key] = str(v.children[0])
            else:
                p = _first_pos(v) or 0
                a, b = self.abs_pos(p), self.abs_pos(_last_end(v))
                fields[key] = _Bad(self.text[a:b], self.ln, self.col(p))
        if not hasattr(node, "meta_brace"):
            _mark_brace(node, self.sh.text)
        brace = node.meta_brace if node.meta_brace >= 0 else (_first_pos(node) or 0)
        return _Agg(fields, typ, self.fi, self.ln, self.col(brace), None)

    def s_decl(self, node):
        typ = None
        for c in node.children:
            if isinstance(c, Tree) and c.data == "type":
                typ = c.children[0].upper()
            elif isinstance(c, Tree) and c.data == "decl_item":
                name = c.children[0]
                dims = next((x for x in c.children[1:] if isinstance(x, Tree) and x.data == "dims"), None)
                init = c.children[-1] if len(c.children) > 1 and c.children[-1] is not dims else None
                val = self.value(init) if init is not None else None
                if isinstance(val, _Agg) and val.type is None and typ:
                    val.type = typ
                self.declare(name, typ, dims is not None, None if dims is not None else val)
            elif isinstance(c, Token):
                pass

    def s_struc_decl(self, node):
        pass

    s_enum_decl = s_signal_decl = s_ext_decl = s_struc_decl

    def index_key(self, node):
        """Literal index of ``a[…]`` → tuple of ints, or None."""
        out = []
        for e in node.children[1:]:
            if e is None:
                return None
            v = self.literal_number(e) if e.data in ("number", "signed") else None
            if v is None or not np.isfinite(v.value) or v.value != int(v.value):  # (int(inf) raises)
                return None
            out.append(int(v.value))
        return tuple(out) if out else None

    def s_assign(self, node):
        lhs, rhs = node.children
        root = lhs
        while root.data in ("member", "index"):
            root = root.children[0]
        if root.data != "name":
            return
        name = root.children[0].upper()
        if lhs.data == "name":
            if name in ("$BASE", "$TOOL", "$ROBROOT"):
                self.assign_frame(name, rhs)
                return
            if name == "FDAT_ACT":
                self.fdat = self.value(rhs) if rhs.data == "aggregate" else self.fdat_of(rhs)
                return
            var = self.lookup(name)
            if var is None:
                if name.startswith("$"):
                    return
                var = self.declare(name, "", False)
            if var.array:
                return
            if rhs.data == "aggregate":
                agg = self.aggregate(rhs)
                if agg.type is None and var.type:
                    agg.type = var.type
                if isinstance(var.value, _Agg):
                    agg.base = var.value
                var.value = agg
            else:
                var.value = self.value(rhs)
                if not isinstance(var.value, _Unknown) and var.type in _POS_TYPES | _AXIS_TYPES:
                    var.value = _Unknown("assigned from an expression", (self.ln, 1))
                elif isinstance(var.value, _Unknown):
                    var.value = _Unknown(f"{name} is assigned a run-time value", (self.ln, 1))
            return
        if lhs.data == "member" and lhs.children[0].data == "name":
            if name in ("$BASE", "$TOOL", "$ROBROOT"):
                comp = lhs.children[1].upper()
                self.assign_frame(name, rhs, component=comp)
                return
            var = self.lookup(name)
            if var is not None and not var.array and isinstance(var.value, _Agg):
                var.value = _Unknown(f"{name} is modified component-wise at line {self.ln}", (self.ln, 1))
            return
        if lhs.data == "index" and lhs.children[0].data == "name":
            var = self.lookup(name)
            if name.startswith("$") and var is None:
                return
            key = self.index_key(lhs)
            if var is None:
                if self.role == "config" or name in ("BASE_DATA", "TOOL_DATA"):
                    var = self.declare(name, "FRAME" if name in ("BASE_DATA", "TOOL_DATA") else "", True)
                else:
                    return
            if not var.array:
                return
            if key is None:
                var.elems = {k: _Unknown(f"{name}[…] is assigned with a run-time index at line {self.ln}")
                             for k in var.elems}
                var.value = _Unknown(f"{name}[…] is assigned with a run-time index at line {self.ln}")
                return
            val = self.value(rhs)
            if isinstance(val, _Agg):
                if val.type is None and var.type:
                    val.type = var.type
                old = var.elems.get(key)
                if isinstance(old, _Agg) and self.role != "config":
                    val.base = old
            var.elems[key] = val
            return
        # $VEL.CP, $OUT[3], P[1].X, … : a component of an array element
        if lhs.data == "member" and lhs.children[0].data == "index":
            var = self.lookup(name)
            if var is not None and var.array:
                key = self.index_key(lhs.children[0])
                if key is not None and key in var.elems:
                    var.elems[key] = _Unknown(f"{name}{list(key)} is modified component-wise at line {self.ln}")

    def fdat_of(self, expr):
        if expr.data == "name":
            var = self.lookup(expr.children[0])
            if var is not None and isinstance(var.value, _Agg):
                return var.value
        return _Unknown("FDAT_ACT is a run-time value", (self.ln, 1))

    # ---------------------------------------------------------------- frames

    def frame_of(self, expr):
        """A frame expression → (4x4, label) or (_Unknown, label)."""
        d = expr.data
        if d == "aggregate":
            six = self.aggregate(expr).frame6()
            if six is None:
                return _Unknown("a partial or non-literal frame aggregate", (self.ln, 1)), ""
            return frame_to_matrix(np.array(six)), "{…} line %d" % self.ln
        if d == "name":
            n = expr.children[0].upper()
            if n == "$NULLFRAME":
                return _I4, "$NULLFRAME"
            if n == "$BASE":
                return self.state.base, self.state.base_label
            if n == "$ROBROOT":
                return self.state.robroot, "$ROBROOT"
            if n == "$TOOL":
                t = self.state.tool
                if isinstance(t, tuple):
                    return frame_to_matrix(np.array(t)), self.state.tool_label
                return _Unknown("$TOOL is not known here", (self.ln, 1)), ""
            var = self.lookup(n)
            if var is not None and not var.array and isinstance(var.value, _Agg):
                six = var.value.frame6()
                if six is not None:
                    return frame_to_matrix(np.array(six)), n
            why = "not a statically known frame" if var is not None else "undeclared"
            return _Unknown(f"{n}: {why}", (self.ln, 1)), ""
        if d == "index" and expr.children[0].data == "name":
            n = expr.children[0].children[0].upper()
            key = self.index_key(expr)
            label = f"{n}[{key[0] if key and len(key) == 1 else '…'}]"
            return self.data_frame(n, key), label
        if d == "compose":
            m, labels = _I4, []
            for op in expr.children:
                t, lab = self.frame_of(op)
                if isinstance(t, _Unknown):
                    return t, ""
                m = compose(m, t)
                labels.append(lab)
            return m, ":".join(labels)
        if d == "fcall":
            fn = expr.children[0].upper()
            args = [a for a in expr.children[1].children if a is not None]
            if fn == "INV_POS" and len(args) == 1:
                t, lab = self.frame_of(args[0])
                return (t if isinstance(t, _Unknown) else inverse(t)), f"INV_POS({lab})"
            if fn == "SBASE" and len(args) == 1:
                n = self.int_of(args[0])
                if n is None:
                    return _Unknown("SBASE(…) of a run-time number", (self.ln, 1)), ""
                return (self.data_frame("BASE_DATA", (n,)) if n else _I4), f"BASE_DATA[{n}]"
            if fn in ("STOOL2", "STOOL") and len(args) == 1:
                f = self.fdat_of(args[0]) if args[0].data == "name" else _Unknown("STOOL2 of a run-time FDAT")
                return self.fdat_tool(f)
        return _Unknown("a run-time value (function call or expression)", (self.ln, 1)), ""

    def int_of(self, expr):
        v = self.literal_number(expr) if expr.data in ("number", "signed") else None
        if v is not None:
            return int(v.value) if np.isfinite(v.value) else None  # (int(inf) raises)
        if expr.data == "member" and expr.children[0].data == "name":
            f = self.fdat_of(expr.children[0])
            if isinstance(f, _Agg):
                x = f.get(expr.children[1].upper())
                if isinstance(x, _Num) and np.isfinite(x.value):
                    return int(x.value)
        return None

    def data_frame(self, name, key):
        if key is None:
            return _Unknown(f"{name}[…] with a run-time index", (self.ln, 1))
        var = self.lookup(name)
        if var is None or not var.array:
            if name in ("BASE_DATA", "TOOL_DATA") and not self.config:
                return _Unknown(f"{name}[{key[0]}] needs $config.dat (not given)", (self.ln, 1))
            return _Unknown(f"{name} is not declared", (self.ln, 1))
        v = var.elems.get(key)
        if isinstance(v, _Agg):
            six = v.frame6()
            if six is not None:
                return frame_to_matrix(np.array(six))
        return _Unknown(f"{name}[{', '.join(map(str, key))}] is not set in the data given", (self.ln, 1))

    def fdat_tool(self, f):
        if not isinstance(f, _Agg):
            return _Unknown("FDAT is a run-time value", (self.ln, 1)), ""
        n = f.get("TOOL_NO")
        ipo = f.get("IPO_FRAME")
        if isinstance(ipo, str) and ipo.upper() == "#TCP":
            return _Unknown("external TCP (IPO_FRAME #TCP) is not supported", (self.ln, 1)), ""
        if not isinstance(n, _Num):
            return _Unknown("FDAT without TOOL_NO", (self.ln, 1)), ""
        if not np.isfinite(n.value) or n.value != int(n.value):  # (int(inf) raises)
            return _Unknown("FDAT with a TOOL_NO that is not a whole number", (self.ln, 1)), ""
        k = int(n.value)
        if k == 0:
            return _I4, "$NULLFRAME"
        return self.data_frame("TOOL_DATA", (k,)), f"TOOL_DATA[{k}]"

    def fdat_base(self, f):
        if not isinstance(f, _Agg):
            return _Unknown("FDAT_ACT is not known here", (self.ln, 1)), ""
        n = f.get("BASE_NO")
        ipo = f.get("IPO_FRAME")
        if isinstance(ipo, str) and ipo.upper() == "#TCP":
            return _Unknown("external TCP (IPO_FRAME #TCP) is not supported", (self.ln, 1)), ""
        if not isinstance(n, _Num):
            return _Unknown("FDAT without BASE_NO", (self.ln, 1)), ""
        if not np.isfinite(n.value) or n.value != int(n.value):  # (int(inf) raises)
            return _Unknown("FDAT with a BASE_NO that is not a whole number", (self.ln, 1)), ""
        k = int(n.value)
        if k == 0:
            return _I4, "$NULLFRAME"
        return self.data_frame("BASE_DATA", (k,)), f"BASE_DATA[{k}]"

    def replace_state(self, st, which, value, label):
        if which == "$BASE":
            return _FrameState(value, label, st.tool, st.tool_label, st.robroot)
        if which == "$TOOL":
            if isinstance(value, np.ndarray):
                value = tuple(float(x) for x in matrix_to_frame(value))
            return _FrameState(st.base, st.base_label, value, label, st.robroot)
        return _FrameState(st.base, st.base_label, st.tool, st.tool_label, value)

    def assign_frame(self, which, rhs, component=None):
        st = self.state
        if component is not None:
            cur = st.base if which == "$BASE" else (st.robroot if which == "$ROBROOT" else (
                frame_to_matrix(np.array(st.tool)) if isinstance(st.tool, tuple) else _Unknown("")))
            v = self.literal_number(rhs) if rhs.data in ("number", "signed") else None
            if isinstance(cur, np.ndarray) and v is not None and component in _COMP:
                six = matrix_to_frame(cur)
                six[_COMP[component]] = v.value
                new, label = frame_to_matrix(six), f"{which}.{component}= line {self.ln}"
            else:
                new, label = _Unknown(f"{which}.{component} set to a run-time value", (self.ln, 1)), ""
        elif rhs.data == "aggregate":
            agg = self.aggregate(rhs)
            six = agg.frame6()
            if six is None:  # partial: the other components keep their values
                cur = st.base if which == "$BASE" else (st.robroot if which == "$ROBROOT" else (
                    frame_to_matrix(np.array(st.tool)) if isinstance(st.tool, tuple) else None))
                ok = all(isinstance(agg.fields.get(k, None), (_Num, type(None))) for k in XYZABC)
                if isinstance(cur, np.ndarray) and ok:
                    six = list(matrix_to_frame(cur))
                    for k, i in _COMP.items():
                        if isinstance(agg.fields.get(k), _Num):
                            six[i] = agg.fields[k].value
            if six is None:
                new, label = _Unknown(f"{which} is set to a run-time value", (self.ln, 1)), ""
            else:
                new, label = frame_to_matrix(np.array(six, float)), f"{which}={{…}} line {self.ln}"
                if which == "$TOOL":
                    new = tuple(float(x) for x in six)
        else:
            new, label = self.frame_of(rhs)
            if isinstance(new, _Unknown):
                new = _Unknown(f"{which} = {new.why}", (self.ln, 1))
        self.set_state(self.replace_state(st, which, new, label))

    def s_call(self, node):
        name = node.children[0].upper()
        args = [a for a in node.children[1].children]
        if name == "BAS" and args and args[0] is not None and args[0].data == "enum":
            self.bas(args[0].children[0].upper(), args[1] if len(args) > 1 else None)
            return
        self.call_states.setdefault(name, []).append(self.state)

    def s_bare_call(self, node):
        self.call_states.setdefault(node.children[0].upper(), []).append(self.state)

    def bas(self, cmd, arg):
        st = self.state
        if cmd in ("#BASE", "#TOOL"):
            n = self.int_of(arg) if arg is not None else None
            which = "$" + cmd[1:]
            if n is None:
                new, label = _Unknown(f"BAS({cmd}, …) with a run-time number", (self.ln, 1)), ""
            elif n == 0:
                new, label = _I4, "$NULLFRAME"
            else:
                data = "BASE_DATA" if cmd == "#BASE" else "TOOL_DATA"
                new, label = self.data_frame(data, (n,)), f"{data}[{n}]"
            self.set_state(self.replace_state(st, which, new, label))
        elif cmd in ("#PTP_PARAMS", "#CP_PARAMS", "#FRAMES"):  # $BASE/$TOOL from FDAT_ACT
            base, bl = self.fdat_base(self.fdat)
            tool, tl = self.fdat_tool(self.fdat)
            st = self.replace_state(st, "$BASE", base, bl)
            st = self.replace_state(st, "$TOOL", tool, tl)
            self.set_state(st)

    def with_frames(self, children):
        """The frame state for a motion/spline with a WITH list ($BASE/$TOOL in it)."""
        st = self.state
        items = []
        for c in children:
            if isinstance(c, Tree) and c.data == "motion_tail":
                items += [x for x in c.children if isinstance(x, Tree) and x.data == "with_item"]
            elif isinstance(c, Tree) and c.data == "with_item":
                items.append(c)
        for it in items:
            lhs, rhs = it.children
            if lhs.data == "name" and lhs.children[0].upper() in ("$BASE", "$TOOL", "$ROBROOT"):
                which = lhs.children[0].upper()
                t, label = self.frame_of(rhs)
                if which == "$TOOL" and isinstance(t, tuple):
                    t = frame_to_matrix(np.array(t))
                st = self.replace_state(st, which, t, label)
            elif lhs.data == "name" and lhs.children[0].upper() == "$IPO_MODE":
                mode = rhs.children[0].upper() if rhs.data == "enum" else None
                if rhs.data == "fcall" and rhs.children[0].upper() == "SIPO_MODE":
                    arg = next((x for x in rhs.children[1].children if x is not None), None)
                    if arg is not None and arg.data == "member" and arg.children[0].data == "name":
                        f = self.fdat_of(arg.children[0])
                        mode = f.get(arg.children[1].upper()) if isinstance(f, _Agg) else None
                if isinstance(mode, str) and mode.upper() == "#TCP":
                    st = _FrameState(_Unknown("external TCP ($IPO_MODE #TCP) is not supported", (self.ln, 1)), "",
                                     st.tool, st.tool_label, st.robroot)
        return st

    def set_state(self, st: _FrameState) -> None:
        """Make ``st`` current from this line on: a timeline entry for the hot rows and a
        barrier for partial aggregates (the current position changes frame)."""
        self.state = st
        if self.role != "module":
            return
        f = self.frame_index(st)
        self.timeline.append((self.kbase + 3, f[0], f[1]))
        self.barrier()

    def frame_index(self, st: _FrameState):
        """(index into Program.frames or -1, reason key for P201)."""
        why = st.base if isinstance(st.base, _Unknown) else (
            st.robroot if isinstance(st.robroot, _Unknown) else None)
        if why is not None:
            key = (self.path, why.why)
            if key not in self.unknown_frames:
                self.unknown_frames[key] = [self.path, why.where[0] or self.ln, why.where[1] or 1,
                                            f"frame not statically known ({why.why})", 0]
            return -1, key
        base = compose(inverse(st.robroot), st.base) if st.robroot is not _I4 else st.base
        tool = st.tool if isinstance(st.tool, tuple) else None
        with np.errstate(over="ignore", invalid="ignore"):  # a 1e308 frame: refused later, not a warning here
            key = (np.round(base, 9).tobytes(), None if tool is None else tuple(round(x, 9) for x in tool))
        ix = self.frame_ix.get(key)
        if ix is None:
            if isinstance(st.tool, _Unknown) and st.tool.why:
                self.warn(self.path, st.tool.where[0] or self.ln, st.tool.where[1] or 1, "P203",
                          f"tool not statically known ({st.tool.why}): Frame.tool left empty")
            label = st.base_label + (f" / {st.tool_label}" if st.tool_label else "")
            ix = self.frame_ix[key] = len(self.frames)
            self.frames.append(Frame(base=base.copy(), tool=None if tool is None else np.array(tool), label=label))
        return ix, None

    # ---------------------------------------------------------------- motions

    def barrier(self):
        """The current position is unknown from here on (partial aggregates get NaN)."""
        if self.role != "module":
            return
        self.add_row(self.kbase + 3, [np.nan] * 6, [True] * 6, [-1] * 6, self.fi, 0, 0, 0, -1, False, True)

    def add_row(self, key, pose, written, spans, fi, line, col, motion, frame, emit, chain):
        c = self.cold
        c["key"].append(key)
        c["pose"].append(pose)
        c["written"].append(written)
        c["spans"].append(spans)
        c["file"].append(fi)
        c["line"].append(line)
        c["col"].append(col)
        c["motion"].append(motion)
        c["frame"].append(frame)
        c["emit"].append(emit)
        c["chain"].append(chain)

    def s_move(self, node):
        kw = node.children[0].upper()
        self.motion(kw, [(node.children[1], _MOTION[_KIND_OF[kw.replace("_REL", "")]], True)], node)

    def s_circ(self, node):
        kw = node.children[0].upper()
        s = "SCIRC" if kw.startswith("S") else "CIRC"
        self.motion(kw, [(node.children[1], _MOTION[s + "-aux"], False),
                         (node.children[2], _MOTION[s + "-end"], True)], node)

    def motion(self, kw, ops, node):
        if not self.in_def:
            self.err("a motion must stand inside DEF … END", _first_pos(node))
        if kw == "SPL" and not any(b[0] == "SPLINE" for b in self.blocks):
            self.err("SPL must stand inside SPLINE … ENDSPLINE", _first_pos(node))
        if kw.endswith("_REL"):
            self.warn(self.path, self.ln, self.col(_first_pos(node)), "P210",
                      f"relative motion {kw} left as written (its absolute target is known only at run time)")
            self.barrier()
            return
        st = self.with_frames(node.children)
        for sub, (expr, motion, chain) in enumerate(ops):
            self.target(expr, motion, chain, st, sub)

    def target(self, expr, motion, chain, st, sub):
        """Resolve one motion operand; add its row(s)."""
        key = self.kbase + sub
        extra = []  # left operands of ':'
        if expr.data == "compose":
            *lefts, expr = expr.children
            extra = lefts
        d = expr.data
        if d == "aggregate":
            agg = self.aggregate(expr)
            kind = agg.kind()
            if kind == "axis":
                self.barrier()
                return
            if kind == "other":
                return
            f, why = self.frame_for(st, extra)
            pose, spans, written = agg.pose(self.path, self.text)
            emit = any(written[:3])
            self.add_row(key, pose, written, spans, self.fi, agg.line, agg.col, motion, f, emit, chain)
            if emit:
                self.count_unknown(f, why)
            return
        if d == "name":
            name = expr.children[0]
            aggs = self.named_value(name, None, expr)
        elif d == "index" and expr.children[0].data == "name":
            name = expr.children[0].children[0]
            aggs = self.named_value(name, self.index_key(expr), expr, indexed=True)
        else:
            self.warn(self.path, self.ln, self.col(_first_pos(expr)), "P211",
                      "target is computed at run time (function call or expression): left as written")
            self.barrier()
            return
        if aggs is None:
            self.barrier()
            return
        f, why = self.frame_for(st, extra)
        for agg in aggs:
            seen = self.targets_of.get(id(agg))
            if seen is not None:
                if seen[0] != f:
                    self.warn(self.path, self.ln, self.col(_first_pos(expr)), "P202",
                              f"{str(name)} is used in another frame than at its first use (line {seen[1]}): "
                              "compensated for the first")
                pose, _, _ = agg.pose(*self.where(agg.file))
                if len(aggs) == 1:
                    self.add_row(key, pose, [True] * 6, [-1] * 6, agg.file, agg.line, agg.col, motion, f, False,
                                 chain)
                continue
            self.targets_of[id(agg)] = (f, self.ln)
            pose, spans, _ = agg.pose(*self.where(agg.file))
            emit = any(s >= 0 for s in spans) and agg.file >= 0
            self.add_row(key, pose, [True] * 6, spans, agg.file, agg.line, agg.col, motion, f, emit,
                         chain and len(aggs) == 1)
            if emit:
                self.count_unknown(f, why)
        if len(aggs) != 1:
            self.barrier()

    def named_value(self, name, key, expr, indexed=False):
        """The aggregates a named target stands for, or None (warned) when not Cartesian/known."""
        u = str(name).upper()
        var = self.lookup(u)
        pos = _first_pos(expr)
        if var is None:
            if _STANDARD_AXIS.match(u):
                return None
            if _RUNTIME_POS.match(u) or u.startswith("$"):
                self.warn(self.path, self.ln, self.col(pos), "P211",
                          f"target {name} is a run-time position: left as written")
                return None
            raise PostprocError(f"undeclared target name '{name}'", self.path, self.ln, self.col(pos), "P102")
        if var.type in _AXIS_TYPES:
            return None
        if var.type and var.type not in _POS_TYPES:
            # user STRUC types or wrong types: nothing we can read as X…C
            values = [var.value] if not var.array else list(var.elems.values())
            if not any(isinstance(v, _Agg) and v.kind() == "cart" for v in values):
                self.warn(self.path, self.ln, self.col(pos), "P211",
                          f"target {name} has type {var.type}, not a position: left as written")
                return None
        if var.array != indexed:
            if var.array:
                self.warn(self.path, self.ln, self.col(pos), "P211", f"target {name} is a whole array")
                return None
            self.warn(self.path, self.ln, self.col(pos), "P211", f"target {name}[…] is not an array")
            return None
        if indexed:
            if key is None:
                items = sorted(var.elems.items())
                vals = [v for _, v in items if isinstance(v, _Agg)]
                unknown = [v for _, v in items if isinstance(v, _Unknown)]
                if isinstance(var.value, _Unknown) or unknown or not vals:
                    why = var.value.why if isinstance(var.value, _Unknown) else (
                        unknown[0].why if unknown else f"no element of {name} is initialised")
                    self.warn(self.path, self.ln, self.col(pos), "P211",
                              f"target {name}[…] not statically known ({why}): left as written")
                    return None
                out = []
                for v in vals:
                    if v.kind() == "cart":
                        out.append(v)
                return out or None
            v = var.elems.get(key)
            label = f"{name}[{', '.join(map(str, key))}]"
        else:
            v = var.value
            label = str(name)
        if isinstance(v, _Agg):
            if v.kind() == "axis":
                return None
            return [v]
        why = v.why if isinstance(v, _Unknown) else "it has no value here"
        self.warn(self.path, self.ln, self.col(pos), "P211", f"target {label} not statically known ({why}): "
                  "left as written")
        return None

    def where(self, fi):
        """(path, text) of file index ``fi`` (negative: a $config.dat text)."""
        if fi >= 0:
            return self.files[fi], self.texts[fi]
        return ("$config.dat" if len(self.config) == 1 else f"$config.dat[{-1 - fi}]"), self.config[-1 - fi]

    def count_unknown(self, f, why):
        if f < 0 and why in self.unknown_frames:
            self.unknown_frames[why][4] += 1

    def frame_for(self, st, lefts):
        if lefts:
            m, labels = (st.base if not isinstance(st.base, _Unknown) else None), [st.base_label]
            for op in lefts:
                t, lab = self.frame_of(op)
                if isinstance(t, _Unknown):
                    st = _FrameState(t, "", st.tool, st.tool_label, st.robroot)
                    m = None
                    break
                if m is not None:
                    m = compose(m, t)
                    labels.append(lab)
            if m is not None:
                st = _FrameState(m, ":".join(labels), st.tool, st.tool_label, st.robroot)
        return self.frame_index(st)

    # ---------------------------------------------------------------- assembling

    def assemble(self) -> Targets:
        """All rows (hot parts + the interpreter's rows) in program order → Targets: frames of
        hot rows from the timeline, partial aggregates filled, only emitted rows kept."""
        c = self.cold
        n = len(c["key"])
        parts = list(self.hot.parts)
        self.timeline.sort(key=lambda t: t[0])  # (already in order: one file after the other, line by line)
        tk = np.array([t[0] for t in self.timeline], np.int64)
        tf = np.array([t[1] for t in self.timeline], np.int32)
        for p in parts:
            p.pop("spl", None)
            m = len(p["key"])
            # the frame in force at their line: the last timeline entry before them
            at = np.searchsorted(tk, p["key"], "right") - 1
            if (at < 0).any():  # (cannot happen after a DEF: it starts the timeline)
                tk, tf = np.concatenate([[-1], tk]), np.concatenate([[self.start_frame()], tf])
                self.timeline.insert(0, (-1, int(tf[0]), None))
                at = at + 1
            f = tf[at]
            p["frame"] = f.astype(np.int32)
            p["emit"] = np.ones(m, bool)
            if (f < 0).any():
                for r, cnt in zip(*np.unique(at[f < 0], return_counts=True)):
                    reason = self.timeline[r][2] if r >= 0 else None
                    if reason in self.unknown_frames:
                        self.unknown_frames[reason][4] += int(cnt)
        if n:
            parts.append(dict(
                key=np.array(c["key"], np.int64), pose=np.array(c["pose"], float).reshape(n, 6),
                written=np.array(c["written"], bool).reshape(n, 6), spans=np.array(c["spans"], np.int64).reshape(n, 6),
                file=np.array(c["file"], np.int32), line=np.array(c["line"], np.int32),
                col=np.array(c["col"], np.int32), motion=np.array(c["motion"], np.int8),
                chain=np.array(c["chain"], bool), frame=np.array(c["frame"], np.int32),
                emit=np.array(c["emit"], bool),
            ))
        if not parts:
            return _empty_targets()

        def column(k, rows=None):
            v = np.concatenate([p[k] for p in parts]) if len(parts) > 1 else parts[0][k]
            return v if rows is None else v[rows]

        order = np.argsort(column("key"), kind="stable")
        pose, written, chain = column("pose", order), column("written", order), column("chain", order)
        emit = column("emit", order)
        # partial aggregates: a component not written comes from the last chain row before
        # (the current position; barrier rows hold NaN)
        m = len(pose)
        ar = np.arange(m)
        for k in range(6):
            w = written[:, k]
            if w.all():
                continue
            src = np.where(chain & w, ar, -1)
            np.maximum.accumulate(src, out=src)
            need = np.flatnonzero(~w)
            prev = src[need]
            ok = prev >= 0
            pose[need[ok], k] = pose[prev[ok], k]
            pose[need[~ok], k] = np.nan
        keep = np.flatnonzero(emit)
        sel = order[keep]
        frame = column("frame", sel)
        # only the frames targets use, in order of first use
        used, first = np.unique(frame[frame >= 0], return_index=True)
        used = used[np.argsort(first)]
        remap = np.full(len(self.frames) + 1, -1, np.int32)
        remap[used] = np.arange(len(used), dtype=np.int32)
        frame = np.where(frame >= 0, remap[frame], -1).astype(np.int32)
        self.frames[:] = [self.frames[k] for k in used]
        return Targets(
            poses=pose[keep],
            spans=column("spans", sel).reshape(len(sel), 3, 2),
            file=column("file", sel),
            line=column("line", sel),
            col=column("col", sel),
            frame=frame,
            motion=column("motion", sel),
        )

    def start_frame(self) -> int:
        return self.frame_index(_START)[0]



def _last_end(tree):
    end = 0
    for c in tree.children:
        if isinstance(c, Token):
            end = max(end, c.end_pos)
        elif c is not None:
            end = max(end, _last_end(c))
    return end


def _empty_targets() -> Targets:
    return Targets(
        poses=np.zeros((0, 6)), spans=np.zeros((0, 3, 2), np.int64), file=np.zeros(0, np.int32),
        line=np.zeros(0, np.int32), col=np.zeros(0, np.int32), frame=np.zeros(0, np.int32),
        motion=np.zeros(0, np.int8),
    )

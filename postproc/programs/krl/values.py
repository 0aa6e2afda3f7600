"""Values as written in KRL: numbers, aggregates, variables, what cannot be known statically."""
from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
from lark import Token

from ...diagnostics import P103, PostprocError, line_col
from ..model import MOTIONS


XYZABC = ("X", "Y", "Z", "A", "B", "C")


_COMP = {k: i for i, k in enumerate(XYZABC)}


_AXIS_KEYS = {f"A{i}" for i in range(1, 7)}


_POS_TYPES = {"POS", "E6POS", "FRAME"}


_AXIS_TYPES = {"AXIS", "E6AXIS"}


_MOTION = {m: i for i, m in enumerate(MOTIONS)}


_KIND_OF = {"PTP": "PTP", "LIN": "LIN", "SPTP": "SPTP", "SLIN": "SLIN", "SPL": "SPL"}


_STANDARD_AXIS = re.compile(r"^XHOME\d*$|^\$AXIS_\w+$|^\$H_AXIS\w*$", re.I)


_RUNTIME_POS = re.compile(r"^\$POS_\w+$", re.I)


class _Unknown:
    """A value the reader cannot know statically, with where and why."""

    __slots__ = ("why", "where")

    def __init__(self, why: str, where: tuple[int, int] = (0, 0)):
        self.why = why
        self.where = where  # (line, col) in the file being read


class _Derived(_Unknown):
    """A position assigned from another position (``P2 = P1``, ``P2.Z = P1.Z + 150``): at run
    time it moves with ``source`` (and with its correction, when ``source`` is compensated)."""

    __slots__ = ("source",)

    def __init__(self, source: str, where: tuple[int, int]):
        super().__init__(f"derived from {source} at line {where[0]}", where)
        self.source = source


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
        """(pose[6] NaN where unwritten, spans[12] (start, end of X, Y, Z, A, B, C's own tokens, -1
        where not its own), written[6]); P103 on a bad component."""
        pose, spans, written = [np.nan] * 6, [-1] * 12, [False] * 6
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
                                        *line_col(text, v.start), P103)
                pose[i] = v.value
                written[i] = True
                if own:
                    spans[2 * i], spans[2 * i + 1] = v.start, v.end
            elif isinstance(v, _Bad):
                raise PostprocError(f"component {k} of a target must be a number, found '{v.text}'", path,
                                    v.line, v.col, P103)
            else:
                raise PostprocError(f"component {k} of a target must be a number", path, self.line, self.col,
                                    P103)
        return pose, spans, written

    def config(self):
        """(S, T) as written (own or merged fields): integers, 'B010' / 'H2' literals; -1 when
        absent or not a whole number in 0…32767."""
        out = []
        for k in ("S", "T"):
            v = self.get(k)
            x = -1
            if isinstance(v, _Num):
                if np.isfinite(v.value) and v.value == int(v.value) and 0 <= v.value <= 32767:
                    x = int(v.value)
            elif isinstance(v, str) and len(v) >= 3 and v[0] == "'" and v[-1] == "'":
                digits, base = v[2:-1], (2 if v[1] in "Bb" else 16)
                try:
                    x = int(digits, base) if digits else -1
                except ValueError:
                    x = -1
                x = x if 0 <= x <= 32767 else -1
            out.append(x)
        return out

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


def _mark_brace(agg, text: str) -> None:
    """Remember where the aggregate's '{' stands (lark drops anonymous tokens)."""
    first = _first_pos(agg)
    if first is None:  # '{}' : find it from the end
        agg.meta_brace = -1
        return
    agg.meta_brace = text.rfind("{", 0, first)


def _first_pos(tree):
    for c in tree.children:
        if isinstance(c, Token):
            return c.start_pos
        if c is not None:
            p = _first_pos(c)
            if p is not None:
                return p
    return None


def _last_end(tree):
    end = 0
    for c in tree.children:
        if isinstance(c, Token):
            end = max(end, c.end_pos)
        elif c is not None:
            end = max(end, _last_end(c))
    return end


class Values:
    """Values as written in KRL: numbers, aggregates, variables, what cannot be known statically. (methods of the Reader)"""

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

"""The analysis's values: known (with provenance: which number token a number comes from and
what was added to it) or unknown (``Top``, with why and where), and the join of two.

* plain Python values: float/int (numbers no token holds, or read through an operation that
  does not keep a token: ``P.X * 2``), bool, str (strings, enums ``#BASE``);
* :class:`Tok`: a number that is a token of the program plus an offset (``XA.Z = XS1.Z + 300``
  keeps XS1's Z token, offset 300): rewriting the token moves the number with it;
* :class:`Taint`: a number computed from tokens in another way (``P.X * 2``, a copy through a
  scalar, the join of two paths' tokens): known, but no one token to rewrite; where it flows
  into something other than a target its tokens are read there;
* :class:`Rec`: an aggregate / record / pose (fields → values; a field not present is not
  set: a partial aggregate);
* :class:`Arr`: an array (index tuple → value; elements not set hold ``default``);
* :class:`Mat`: a frame computed by the analysis (``F1:F2``, ``INV_POS``), a 4×4 transform;
* :class:`Top`: not known statically, with why and where (the cause's ``Loc``).

Values are immutable; equality is structural (the fixed point compares states).
"""
from __future__ import annotations

import math

import numpy as np

from ...core.diagnostics import P220, P221
from ..ir import Loc

__all__ = ["Top", "Tok", "Taint", "Rec", "Arr", "Mat", "Moving", "Six", "Load", "NotSet", "LOAD_NOT_SET", "join", "same",
           "tokens_of", "number", "is_number", "frame_product", "frame_inverse"]


class Top:
    """A value not known statically: ``why`` (a phrase: "$BASE is set from a run-time value"),
    ``loc`` where the cause stands (or None), ``code`` the diagnostic it leaves a target with
    where it is a frame (P201 base, P203 tool, P220/P221 not set, P225 a track) or None;
    ``tokens`` the number tokens it may hold or be computed from (the join of two paths'
    tokens, a token plus a value not known): what reads it reads them."""

    __slots__ = ("why", "loc", "code", "tokens")

    def __init__(self, why: str, loc: Loc | None = None, code: str | None = None, tokens: frozenset = frozenset()):
        self.why = why
        self.loc = loc
        self.code = code
        self.tokens = tokens

    def carrying(self, *values) -> "Top":
        """This unknown, holding the tokens of ``values`` too."""
        toks = set(self.tokens)
        for v in values:
            tokens_of(v, toks)
        return self if len(toks) == len(self.tokens) else Top(self.why, self.loc, self.code, frozenset(toks))

    def __eq__(self, other):
        return isinstance(other, Top) and other.why == self.why and other.loc == self.loc and other.code == self.code \
            and other.tokens == self.tokens

    def __hash__(self):
        return hash((self.why, self.loc))

    def __repr__(self):
        return f"Top({self.why!r})"


class Tok:
    """A number that is token ``token`` (file, start, end) of the program, + ``offset``:
    ``value`` = the token's value + offset."""

    __slots__ = ("value", "token", "offset")

    def __init__(self, value: float, token: tuple, offset: float = 0.0):
        self.value = value
        self.token = token
        self.offset = offset

    def __eq__(self, other):
        return isinstance(other, Tok) and other.token == self.token and other.value == self.value \
            and other.offset == self.offset

    def __hash__(self):
        return hash((self.token, self.value))

    def __repr__(self):
        return f"Tok({self.value}, {self.token}, {self.offset:+g})"


class Taint:
    """A number computed from number tokens (``tokens``) other than by adding a constant to one."""

    __slots__ = ("value", "tokens")

    def __init__(self, value: float, tokens: frozenset):
        self.value = value
        self.tokens = tokens

    def __eq__(self, other):
        return isinstance(other, Taint) and other.value == self.value and other.tokens == self.tokens

    def __hash__(self):
        return hash((self.value, len(self.tokens)))

    def __repr__(self):
        return f"Taint({self.value}, {len(self.tokens)} tokens)"


def taint(value, *sources):
    """``value`` computed from ``sources``: a Taint of their tokens, or the plain value where none
    holds a token."""
    toks = set()
    for v in sources:
        tokens_of(v, toks)
    return Taint(value, frozenset(toks)) if toks else value


class Rec:
    """An aggregate: ``type`` (upper case: E6POS, FRAME, ROBTARGET, a STRUC's name; "" not
    known), ``fields`` name → value in the order set, ``loc`` where its literal stands (the
    aggregate a target's message points at; None for one made by the analysis), ``label``
    (how a frame is named in messages: ``BASE_DATA[3]``)."""

    __slots__ = ("type", "fields", "loc", "label")

    def __init__(self, type_: str, fields: dict, loc: Loc | None = None, label: str = ""):
        self.type = type_
        self.fields = fields
        self.loc = loc
        self.label = label

    def get(self, name: str, default=None):
        return self.fields.get(name, default)

    def with_field(self, name: str, value) -> "Rec":
        fields = dict(self.fields)
        fields[name] = value
        return Rec(self.type, fields, self.loc, "")

    def __eq__(self, other):
        return isinstance(other, Rec) and other.type == self.type and other.loc == self.loc \
            and other.fields == self.fields

    def __hash__(self):
        return hash((self.type, self.loc, len(self.fields)))

    def __repr__(self):
        return f"Rec({self.type}, {self.fields})"


class Arr:
    """An array: ``elems`` index tuple → value, ``default`` the value of an element not in
    ``elems`` (a ``Top`` "not initialised"), ``type`` its element type."""

    __slots__ = ("elems", "default", "type")

    def __init__(self, elems: dict, default, type_: str = ""):
        self.elems = elems
        self.default = default
        self.type = type_

    def get(self, key: tuple):
        return self.elems.get(key, self.default)

    def with_elem(self, key: tuple, value) -> "Arr":
        elems = dict(self.elems)
        elems[key] = value
        return Arr(elems, self.default, self.type)

    def __eq__(self, other):
        return isinstance(other, Arr) and other.type == self.type and other.default == self.default \
            and other.elems == self.elems

    def __hash__(self):
        return hash((self.type, len(self.elems)))

    def __repr__(self):
        return f"Arr({len(self.elems)} elems)"


class Mat:
    """A frame the analysis computed: ``m`` 4×4 (read-only), ``label`` for messages,
    ``tokens`` the number tokens it was computed from (a frame built from a point)."""

    __slots__ = ("m", "label", "tokens", "flags", "_key")

    def __init__(self, m: np.ndarray, label: str = "", tokens: frozenset = frozenset(), flags: frozenset = frozenset()):
        self.m = m
        self.label = label
        self.tokens = tokens
        self.flags = flags  # what a target taken in this frame is said with once (``assumed-robroot``: P224)
        with np.errstate(over="ignore", invalid="ignore"):
            self._key = np.round(m, 9).tobytes()

    def __eq__(self, other):
        return isinstance(other, Mat) and other._key == self._key and other.tokens == self.tokens

    def __hash__(self):
        return hash(self._key)

    def __repr__(self):
        return f"Mat({self.label or 'computed'})"


class Moving:
    """A frame that moves with an external unit's axis (``postproc.robot.external.ExternalUnit``):
    ``left · B(e)^(-1 if inverse) · right`` with B(e) = ``unit.base_at(e)``, known once a target
    states e (``at``); ``label``, ``tokens`` as a Mat's."""

    __slots__ = ("unit", "left", "right", "inverse", "label", "tokens", "flags", "_key")

    def __init__(self, unit, left=None, right=None, inverse: bool = False, label: str = "",
                 tokens: frozenset = frozenset(), flags: frozenset = frozenset()):
        self.unit = unit
        self.flags = flags
        self.left = np.eye(4) if left is None else left
        self.right = np.eye(4) if right is None else right
        self.inverse = inverse
        self.label = label
        self.tokens = tokens
        with np.errstate(over="ignore", invalid="ignore"):
            self._key = (unit, inverse, np.round(self.left, 9).tobytes(), np.round(self.right, 9).tobytes())

    def at(self, e: float) -> np.ndarray:
        b = self.unit.base_at(e)
        if self.inverse:
            b = np.linalg.inv(b)
        return self.left @ b @ self.right

    def __eq__(self, other):
        return isinstance(other, Moving) and other._key == self._key and other.tokens == self.tokens

    def __hash__(self):
        return hash(self._key)

    def __repr__(self):
        return f"Moving({self.unit.name}, {self.label or 'computed'})"


def frame_product(a, b, label: str = ""):
    """``a · b`` of two frames (Mat or Moving): a Mat, a Moving, or Top where both move (two
    external units in one frame: not taken)."""
    from ...core.diagnostics import P225

    toks = a.tokens | b.tokens
    if isinstance(a, Mat) and isinstance(b, Mat):
        return Mat(a.m @ b.m, label, toks, a.flags | b.flags)
    flags = a.flags | b.flags
    if isinstance(a, Mat):
        return Moving(b.unit, a.m @ b.left, b.right, b.inverse, label, toks, flags)
    if isinstance(b, Mat):
        return Moving(a.unit, a.left, a.right @ b.m, a.inverse, label, toks, flags)
    if a.unit == b.unit and a.inverse != b.inverse and np.allclose(a.right @ b.left, np.eye(4), atol=1e-9):
        return Mat(a.left @ b.right, label, toks, flags)  # (B(e)^-1 · B(e): the unit cancels)
    return Top(f"{a.unit.describe()} and {b.unit.describe()} both move this frame: postproc takes one external "
               "unit per frame", None, P225)


def frame_inverse(a, label: str = ""):
    if isinstance(a, Mat):
        return Mat(np.linalg.inv(a.m), label, a.tokens, a.flags)
    return Moving(a.unit, np.linalg.inv(a.right), np.linalg.inv(a.left), not a.inverse, label, a.tokens, a.flags)


class Six(tuple):
    """Six numbers X,Y,Z,A,B,C (a tool), with the ``label`` it is named by in messages
    (``TOOL_DATA[1]``); equal by its numbers."""

    label: str = ""

    def __new__(cls, numbers, label: str = ""):
        self = super().__new__(cls, (float(x) for x in numbers))
        self.label = label
        return self


class Load(tuple):
    """A payload the robot carries: mass (kg) and centre of mass cx, cy, cz (mm, flange frame),
    with the ``label`` it is named by in messages (``LOAD_DATA[2]``, ``GripLoad piece``); equal by
    its numbers."""

    label: str = ""

    def __new__(cls, numbers, label: str = ""):
        self = super().__new__(cls, (float(x) for x in numbers))
        self.label = label
        return self


class NotSet:
    """The payload where the program has not set one (and its user did not state it): the
    controller's is whatever is in force; the model takes its own reference load there."""

    __slots__ = ()

    def __eq__(self, other):
        return isinstance(other, NotSet)

    def __hash__(self):
        return hash("NotSet")

    def __repr__(self):
        return "NotSet"


LOAD_NOT_SET = NotSet()


def is_number(v) -> bool:
    return isinstance(v, (Tok, Taint)) or (isinstance(v, (int, float)) and not isinstance(v, bool))


def number(v):
    """The float of a known number (a Tok's or Taint's value), None otherwise."""
    if isinstance(v, (Tok, Taint)):
        return v.value
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        return float(v)
    return None


def whole_number(v) -> int | None:
    """The int of a known whole, finite number (an index, a handler's or a frame's number), else None."""
    n = number(v)
    if n is None or not math.isfinite(n) or n != int(n):
        return None
    return int(n)


def tokens_of(v, out: set | None = None) -> set:
    """The number tokens a value holds (Tok tokens, a Mat's, inside records and arrays)."""
    out = set() if out is None else out
    if isinstance(v, Tok):
        out.add(v.token)
    elif isinstance(v, Taint):
        out |= v.tokens
    elif isinstance(v, Rec):
        for x in v.fields.values():
            tokens_of(x, out)
    elif isinstance(v, Arr):
        for x in v.elems.values():
            tokens_of(x, out)
    elif isinstance(v, (Mat, Moving, Top)):
        out |= v.tokens
    return out


def same(a, b) -> bool:
    if a is b:
        return True
    try:
        return bool(a == b)
    except (ValueError, TypeError):  # (numpy comparisons)
        return False


def join(a, b, why: str, loc: Loc | None):
    """One value for two paths: the value where both agree; records and arrays field by
    field / element by element; else unknown for ``why`` at ``loc`` (a path on which it is
    already unknown gives its own reason)."""
    if same(a, b):
        return a
    if isinstance(a, Rec) and isinstance(b, Rec) and a.type == b.type and a.fields.keys() == b.fields.keys():
        return Rec(a.type, {k: join(a.fields[k], b.fields[k], why, loc) for k in a.fields},
                   a.loc if a.loc == b.loc else None)
    if isinstance(a, (Tok, Taint, int, float)) and isinstance(b, (Tok, Taint, int, float)) \
            and not isinstance(a, bool) and not isinstance(b, bool) and number(a) == number(b):
        return taint(number(a), a, b)  # (one number, from one token or the other: no one token to rewrite)
    if isinstance(a, Arr) and isinstance(b, Arr):
        keys = a.elems.keys() | b.elems.keys()
        return Arr({k: join(a.get(k), b.get(k), why, loc) for k in keys}, join(a.default, b.default, why, loc),
                   a.type or b.type)
    # (the tokens either path holds stay with the unknown: what reads it may read them)
    for x in (a, b):  # a path on which it is unknown already: its reason (one warning for the cause)...
        if isinstance(x, Top) and x.code not in NOT_SET:
            return x.carrying(a, b)
    if isinstance(a, Top) and isinstance(b, Top):
        return a.carrying(b)
    return Top(why, loc).carrying(a, b)  # (...but not "never set" where another path sets it)


# the codes of a frame the program does not set and its user did not state (P220 base, P221 tool)
NOT_SET = (P220, P221)

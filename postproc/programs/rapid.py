"""ABB RAPID reader: the text of a module (.mod, .prg, .sys) → Program.

Syntax lives in ``grammars/rapid.lark``. The module is cut into *units* (a statement up to
its ``;``, or a line that opens or closes a block), with ``!`` comments and the insides of
strings blanked out (same length: offsets stay those of the file). Each distinct unit
*shape* — numbers → ``0``, the digits ending a name → ``0``, blanks collapsed — is parsed
once; what its tree tells (a declaration, a motion and which of its tokens are a target's
numbers) holds for every unit of that shape, so only the unit's tokens are read again.

Semantics (tests/test_rapid.py shows each on a small program):

* a target is a ``robtarget`` given as numbers: inline in a motion (``MoveL [[x,y,z],
  [q1,q2,q3,q4],[cf1,cf4,cf6,cfx],[eax…]], …``) or a declared variable (or array element)
  that a motion of the module moves to; its frame is that motion's ``\\WObj`` (work object;
  ``wobj0`` when absent): uframe · oframe, the world frame taken as the robot base;
* orientation is the quaternion q1..q4 (w, x, y, z), held as KUKA A,B,C (Rz·Ry·Rx) like
  every pose in postproc, its four numbers as written located (``Program.orientation`` =
  "quaternion", ``Targets.orientation``, ``Targets.abc_spans``): X, Y, Z are rewritten, and
  with ``compensate --orientation`` q1..q4 too;
* the configuration cf1, cf4, cf6, cfx of every target is kept as read
  (:attr:`RapidProgram.confdata`);
* ``Offs(…)``/``RelTool(…)`` and other computed targets, robtargets assigned at run time or
  declared elsewhere, work objects held by the robot or moved by a mechanical unit, and
  unknown work objects are left as written with a warning (P211 / P201);
* a declared robtarget moved to in two frames is compensated for its first use (P202).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np
from lark import Lark, Token, Tree
from lark.exceptions import UnexpectedInput

from ..diagnostics import P101, P102, P103, P104, P201, P202, P211, Diagnostic, PostprocError, line_col
from ..frames import abc_from_rotation, rotation_from_quaternion
from .grammar import BLANKS, NUM, TOKEN_RE, exact_key, first_ordinal, lalr_parser, shape_key, unexpected
from . import MOTIONS, STAMP_PREFIX, Frame, Program, Targets
from .poses import _newline  # a file's newline: \r\n if at least half its line ends are

__all__ = ["read", "parser", "RapidProgram", "TOKEN_RE", "MOTION_OF"]

# an inline robtarget of plain numbers: x, y, z, q1..q4, cf1, cf4, cf6, cfx (a sign may stand
# before each, as in the grammar: blanks between); its extax aggregate follows
_SNUM = r"\s*([-+]?\s*" + NUM + r")\s*"
_RT_RE = re.compile(r"\[\s*\[" + ",".join([_SNUM] * 3) + r"\]\s*,\s*\[" + ",".join([_SNUM] * 4) + r"\]\s*,\s*\["
                    + ",".join([_SNUM] * 4) + r"\]\s*,\s*\[", re.ASCII)
# strings, comments, and a quote that opens no string on its line
_HIDE = re.compile(r'"[^"\n]*"|!.*|"')
_BLOCK_WORDS = {"MODULE", "ENDMODULE", "PROC", "ENDPROC", "FUNC", "ENDFUNC", "TRAP", "ENDTRAP", "LOCAL",
                "IF", "ELSEIF", "ELSE", "ENDIF", "FOR", "ENDFOR", "WHILE", "ENDWHILE", "TEST", "CASE",
                "DEFAULT", "ENDTEST", "ERROR", "UNDO", "BACKWARD", "RECORD", "ENDRECORD"}
_FIRST_WORD = re.compile(r"[ \t]*([A-Za-z_]\w*)", re.ASCII)
_LABEL = re.compile(r"[ \t]*[A-Za-z_]\w*[ \t]*:[ \t]*$", re.ASCII)
_MOTION = {m: i for i, m in enumerate(MOTIONS)}

# motion instructions → the motion kind of each robtarget they move to, from their first
# positional argument on (MoveAbsJ, MoveExtJ: joint targets, not listed)
MOTION_OF: dict[str, tuple[str, ...]] = {}
for _stem, _kinds in (("MoveL", ("LIN",)), ("MoveJ", ("PTP",)), ("MoveC", ("CIRC-aux", "CIRC-end"))):
    for _suffix in ("", "DO", "Sync", "GO", "AO"):
        MOTION_OF[(_stem + _suffix).lower()] = _kinds
for _name, _kinds in (("TriggL", ("LIN",)), ("TriggJ", ("PTP",)), ("TriggC", ("CIRC-aux", "CIRC-end")),
                      ("ArcL", ("LIN",)), ("ArcLStart", ("LIN",)), ("ArcLEnd", ("LIN",)),
                      ("ArcC", ("CIRC-aux", "CIRC-end")), ("ArcCStart", ("CIRC-aux", "CIRC-end")),
                      ("ArcCEnd", ("CIRC-aux", "CIRC-end"))):
    MOTION_OF[_name.lower()] = _kinds
_RUNTIME_FUNCS = {"offs", "reltool"}


@dataclass
class RapidProgram(Program):
    """A RAPID Program, plus each target's configuration data as written."""

    # [N, 4] cf1, cf4, cf6, cfx per target row (NaN where not a number)
    confdata: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))


def parser() -> Lark:
    """The LALR parser of ``grammars/rapid.lark`` (built once, cached on disk by lark)."""
    return lalr_parser("rapid.lark", "unit")


def _scaled(q: np.ndarray) -> np.ndarray | None:
    """A quaternion as written, scaled to length 1 (no overflow for 1e308), None for zero."""
    big = np.abs(q).max()
    if not big > 0:
        return None
    q = q / big
    return q / np.linalg.norm(q)


def _pose_matrix(xyz, q) -> np.ndarray:
    t = np.eye(4)
    t[:3, :3] = rotation_from_quaternion(q)
    t[:3, 3] = xyz
    return t


# ---------------------------------------------------------------------------- shapes
#
# A value as a shape's tree gives it: ("num", token ordinal, sign) | ("name", ordinal)
# | ("agg", [values], ordinal of '[''s first token) | ("ref", name ordinal, index keys |
# None (not literal) | (), ) | ("call", function name (lower), ordinal) | ("expr", ordinal)


class _Shape:
    """What one unit shape is: kind + the parts the reader needs, by token ordinal."""

    __slots__ = ("kind", "data")

    def __init__(self, kind, data=None):
        self.kind = kind
        self.data = data


def _analyse(tree, ordinal_at) -> _Shape:
    def first(node):
        return first_ordinal(node, ordinal_at, ("NAME", "NUMBER"))

    def value(node):
        if isinstance(node, Tree):
            if node.data == "number":
                return ("num", ordinal_at[node.children[0].start_pos], 1)
            if node.data == "signed" and isinstance(node.children[1], Tree) and node.children[1].data == "number":
                sign = -1 if str(node.children[0]) == "-" else 1
                return ("num", ordinal_at[node.children[1].children[0].start_pos], sign, True)
            if node.data == "name":
                return ("ref", ordinal_at[node.children[0].start_pos], ())
            if node.data == "aggregate":
                return ("agg", [value(c) for c in node.children if c is not None], first(node))
            if node.data == "index" and isinstance(node.children[0], Tree) and node.children[0].data == "name":
                keys = []
                for c in node.children[1:]:
                    if isinstance(c, Tree) and c.data == "number":
                        keys.append(ordinal_at[c.children[0].start_pos])
                    else:
                        return ("ref", ordinal_at[node.children[0].children[0].start_pos], None)
                return ("ref", ordinal_at[node.children[0].children[0].start_pos], tuple(keys))
            if node.data == "fcall":
                return ("call", str(node.children[0]).lower(), first(node))
        return ("expr", first(node))

    kind = tree.data
    if kind == "decl":
        kids = [c for c in tree.children if c is not None]
        at = 0
        while isinstance(kids[at], Token):  # LOCAL / TASK
            at += 1
        storage = str(kids[at].children[0]).upper()
        type_tok, name_tok = kids[at + 1], kids[at + 2]
        rest = kids[at + 3:]
        dims = next((c for c in rest if isinstance(c, Tree) and c.data == "dims"), None)
        init = next((c for c in rest if not (isinstance(c, Tree) and c.data == "dims")), None)
        return _Shape("decl", (storage, str(type_tok).lower(), ordinal_at[name_tok.start_pos], dims is not None,
                               value(init) if init is not None else None))
    if kind == "call":
        name = str(tree.children[0]).lower()
        args = [c for c in tree.children[1:] if c is not None]
        positional, options = [], {}
        for arg in args:
            kids = arg.children
            if kids and not (isinstance(kids[0], Tree) and kids[0].data == "option"):
                positional.append(value(kids[0]))
                kids = kids[1:]
            for opt in kids:
                options[str(opt.children[0]).lower()] = (value(opt.children[1]) if len(opt.children) > 1 and
                                                         opt.children[1] is not None else None,
                                                         ordinal_at[opt.children[0].start_pos])
        return _Shape("call", (name, positional, options, first(tree)))
    if kind == "assign":
        target = tree.children[0]
        while isinstance(target, Tree) and target.data in ("member", "index"):
            target = target.children[0]
        if isinstance(target, Tree) and target.data == "name":
            return _Shape("assign", ordinal_at[target.children[0].start_pos])
        return _Shape("other")
    if kind == "compact_if":
        return _analyse(tree.children[2], ordinal_at)
    if kind in ("module_head", "module_end", "routine_head", "routine_end"):
        return _Shape(kind)
    return _Shape("other")


# ---------------------------------------------------------------------------- reading


@dataclass
class _Decl:
    type: str
    storage: str
    name: str
    file: int
    array: bool
    value: object  # the shape's value description
    tokens: list  # the unit's tokens: (start, end, text)
    pos: int  # offset of the declared name
    used: int = -1  # -1: never moved to; -3: moved to in a frame not known; 0: moved to
    uses: dict = field(default_factory=dict)  # element index tuple → (frame, offset) of its first use


@dataclass
class _State:
    path: str
    text: str
    file: int
    diagnostics: list
    decls: dict = field(default_factory=dict)  # name (lower) → _Decl, or None (declared twice)
    assigned: set = field(default_factory=set)
    moves: list = field(default_factory=list)  # (call shape data, tokens, unit start)
    code: str = ""  # the text with comments and strings blanked
    _newlines: np.ndarray | None = None

    def locate(self, offsets):
        """1-based (line, col) arrays of character offsets (one pass over the text, then bisection)."""
        if self._newlines is None:
            self._newlines = np.flatnonzero(np.frombuffer(self.text.encode("latin-1", "replace"), np.uint8) == 10)
        offsets = np.asarray(offsets, np.int64)
        before = np.searchsorted(self._newlines, offsets, "left")
        starts = np.where(before > 0, self._newlines[np.maximum(before - 1, 0)] + 1, 0)
        return before + 1, offsets - starts + 1


class _Reader:
    def __init__(self, files, texts, config):
        self.files, self.texts = files, texts
        self.config = config or []
        self.diagnostics: list[Diagnostic] = []
        self.shapes: dict[str, _Shape] = {}
        self.frames: list[Frame] = []
        self.frame_keys: dict = {}
        self.rows: list = []  # (file, offset, pose3, quat4 as written, conf4, spans of the 7 numbers, frame, motion)
        self.referenced: set[str] = set()  # names motions move to
        self.exact: dict[str, _Shape] = {}
        self.fast_rows: list = []  # (file, _RT_RE match, frame, motion)

    # -------------------------------------------------------------- text → units

    def units(self, path: str, text: str):
        """Yield (start, end) of each unit and fill ``self.code`` (comments and strings blanked)."""
        bad = []

        def hide(m):
            s = m.group()
            if s == '"':
                bad.append(m.start())
                return s
            if s.startswith("!"):
                return " " * len(s)
            return '"' + " " * (len(s) - 2) + '"'

        code = _HIDE.sub(hide, text)
        if bad:
            raise PostprocError("string not closed on its line", path, *line_col(text, bad[0]), P101)
        # the %%% VERSION / LANGUAGE %%% header of .prg/.mod files of older controllers
        head = re.match(r"\s*%%%[^\n]*\n(?:.*\n)*?\s*%%%[^\n]*", code)
        if head:
            code = re.sub(r"[^\n]", " ", head.group()) + code[head.end():]
        self.code = code
        pending = -1
        offset = 0
        n = len(code)
        while offset < n:
            nl = code.find("\n", offset)
            end = n if nl < 0 else nl
            if pending < 0:
                line = code[offset:end]
                if line.strip():
                    word = _FIRST_WORD.match(line)
                    if ";" not in line and ((word and word.group(1).upper() in _BLOCK_WORDS) or _LABEL.match(line)):
                        start = offset + len(line) - len(line.lstrip())
                        yield start, end
                    else:
                        pending = offset
            if pending >= 0:
                semi = code.find(";", max(pending, offset), end)
                while semi >= 0:
                    yield pending, semi + 1
                    pending = semi + 1
                    semi = code.find(";", pending, end)
                if not code[pending:end].strip():
                    pending = -1
            offset = end + 1
        if pending >= 0:
            lead = pending + len(code[pending:]) - len(code[pending:].lstrip())
            raise PostprocError("statement not ended by ';'", path, *line_col(text, lead), P101)

    def shape_of(self, path, text, start, end):
        """(shape, exact key) of the unit at [start, end): the exact key keeps the names as
        written (numbers → 0), the shape key also drops the digits ending names."""
        unit = self.code[start:end]
        exact = exact_key(unit)
        shape = self.exact.get(exact)
        if shape is not None:
            return shape, exact
        key = shape_key(exact)
        shape = self.shapes.get(key)
        if shape is None:
            try:
                tree = parser().parse(key)
            except UnexpectedInput:
                self.syntax_error(path, text, start, unit)
            ordinal_at = {m.start(): k for k, m in enumerate(TOKEN_RE.finditer(key))}
            shape = self.shapes[key] = _analyse(tree, ordinal_at)
        if len(self.exact) < 100_000:
            self.exact[exact] = shape
        return shape, exact

    def syntax_error(self, path, text, start, unit):
        """Parse the unit as written to locate the error; raise P101 there."""
        lead = len(unit) - len(unit.lstrip())
        located = unexpected(parser().parse, unit, "end of statement")
        if located is not None:
            pos, found = located
            raise PostprocError(f"syntax error: unexpected {found}", path, *line_col(text, start + pos), P101)
        raise PostprocError("syntax error", path, *line_col(text, start + lead), P101)

    # -------------------------------------------------------------- one module

    def module(self, fi: int, path: str, text: str, collect_moves: bool) -> _State:
        st = _State(path, text, fi, self.diagnostics)
        depth = []  # open MODULE / routine heads
        seen_module = False
        for start, end in self.units(path, text):
            st.code = self.code
            shape, exact = self.shape_of(path, text, start, end)
            kind = shape.kind
            if kind == "module_head":
                if depth:
                    raise PostprocError("MODULE inside a module", path, *line_col(text, start), P102)
                depth.append("MODULE")
                seen_module = True
                continue
            if kind == "module_end":
                if depth != ["MODULE"]:
                    raise PostprocError("ENDMODULE without its MODULE" if not depth else "ENDMODULE inside a routine",
                                        path, *line_col(text, start), P102)
                depth.pop()
                continue
            if not depth:
                raise PostprocError("statement outside MODULE … ENDMODULE", path, *line_col(text, start), P102)
            if kind == "routine_head":
                if len(depth) > 1:
                    raise PostprocError("routine inside a routine (ENDPROC missing?)", path,
                                        *line_col(text, start), P102)
                depth.append("ROUTINE")
                continue
            if kind == "routine_end":
                if len(depth) < 2:
                    raise PostprocError("end of a routine that was not opened", path, *line_col(text, start), P102)
                depth.pop()
                continue
            if kind == "call":
                if collect_moves and shape.data[0] in MOTION_OF:
                    st.moves.append((shape.data, exact, start, end))
            elif kind in ("decl", "assign"):
                tokens = list(TOKEN_RE.finditer(self.code, start, end))  # match objects: m[0] text, m.start()
                if kind == "decl":
                    storage, type_, name_ord, array, value = shape.data
                    s, name = tokens[name_ord].start(), tokens[name_ord][0]
                    key = name.lower()
                    decl = _Decl(type_, storage, name, fi, array, value, tokens, s)
                    if key in st.decls:
                        st.decls[key] = None  # routine-local and module data of one name: which is meant is not known
                    else:
                        st.decls[key] = decl
                else:
                    st.assigned.add(tokens[shape.data][0].lower())
        if depth:
            raise PostprocError("MODULE without ENDMODULE" if depth == ["MODULE"] else "routine not closed at the end",
                                path, *line_col(text, len(text)), P102)
        if not seen_module:
            raise PostprocError("expected a RAPID module: MODULE name … ENDMODULE", path, 1, 1, P104)
        return st

    # -------------------------------------------------------------- values

    def number(self, st, v, tokens):
        """(value, span start, span end) of a ("num", …) value; None if it is not one."""
        if v[0] != "num":
            return None
        m = tokens[v[1]]
        s, e, txt = m.start(), m.end(), m[0]
        span_start = s
        if len(v) > 3:  # a unary sign belongs to the token that is rewritten
            j = s
            code = st.code
            while j > 0 and code[j - 1] in " \t\r\n":
                j -= 1
            span_start = j - 1
        val = float(txt) * v[2]
        return val, span_start, e

    def robtarget(self, st, v, tokens, what):
        """[[x,y,z],[q1..q4],[cf…],[eax…]] → (xyz, spans of x..q4, quat as written, conf, offset of x)
        or None + P211."""
        if v[0] != "agg" or len(v[1]) != 4 or any(p[0] != "agg" for p in v[1][:3]) or \
                len(v[1][0][1]) != 3 or len(v[1][1][1]) != 4 or len(v[1][2][1]) != 4:
            self.warn(st, self.at(v, tokens), P211, f"{what} is not a robtarget [[x,y,z],[q1,q2,q3,q4],"
                      "[cf1,cf4,cf6,cfx],[eax…]]: left as written")
            return None
        nums = [self.number(st, c, tokens) for c in v[1][0][1] + v[1][1][1]]
        if any(n is None for n in nums):
            self.warn(st, self.at(v, tokens), P211, f"{what} has a position or orientation that is not a "
                      "number here: left as written")
            return None
        for n in nums:
            if not np.isfinite(n[0]):
                raise PostprocError(f"{what}: '{st.text[n[1]:n[2]]}' is not a finite number", st.path,
                                    *line_col(st.text, n[1]), P103)
        q = [n[0] for n in nums[3:]]
        if _scaled(np.array(q)) is None:
            raise PostprocError(f"{what}: quaternion [0,0,0,0] is no orientation", st.path,
                                *line_col(st.text, nums[3][1]), P103)
        conf = [self.number(st, c, tokens) for c in v[1][2][1]]
        conf = [c[0] if c is not None else np.nan for c in conf]
        spans = [p for n in nums for p in n[1:]]
        return [n[0] for n in nums[:3]], spans, q, conf, nums[0][1]

    def at(self, v, tokens):
        k = v[2] if v[0] in ("agg", "call") else v[1]
        return tokens[k].start() if 0 <= k < len(tokens) else (tokens[0].start() if tokens else 0)

    def warn(self, st, offset, code, message):
        line, col = st.locate([offset])
        self.diagnostics.append(Diagnostic(st.path, int(line[0]), int(col[0]), code, message))

    # -------------------------------------------------------------- frames

    def data_named(self, name: str, type_: str, states):
        """The _Decl of ``name`` of type ``type_`` in the module or the --config modules: decl,
        None (not found) or a reason string (not statically known)."""
        key = name.lower()
        found = []
        for st in states:
            d = st.decls.get(key, False)
            if d is None:
                return f"{name} is declared twice"
            if d is not False:
                found.append((st, d))
        if not found:
            return None
        if len(found) > 1:
            return f"{name} is declared in two modules"
        st, d = found[0]
        if d.type != type_:
            return f"{name} is a {d.type}, not a {type_}"
        if key in st.assigned:
            return f"{name} is assigned at run time"
        if d.value is None:
            return f"{name} has no value"
        return st, d

    def pose_of(self, st, v, tokens):
        """[[x,y,z],[q1..q4]] → 4×4, or None."""
        if v is None or v[0] != "agg" or len(v[1]) != 2 or any(p[0] != "agg" for p in v[1]):
            return None
        if len(v[1][0][1]) != 3 or len(v[1][1][1]) != 4:
            return None
        nums = [self.number(st, c, tokens) for c in v[1][0][1] + v[1][1][1]]
        if any(n is None or not np.isfinite(n[0]) for n in nums):
            return None
        q = _scaled(np.array([n[0] for n in nums[3:]]))
        if q is None:
            return None
        return _pose_matrix([n[0] for n in nums[:3]], q)

    def wobj(self, name, states):
        """4×4 of work object ``name`` (None: wobj0) or a reason string."""
        if name is None or name.lower() == "wobj0" and not any(name.lower() in s.decls for s in states):
            return np.eye(4)
        d = self.data_named(name, "wobjdata", states)
        if d is None:
            return f"work object {name} is not declared in this module or --config"
        if isinstance(d, str):
            return d
        st, decl = d
        v = decl.value
        if v[0] != "agg" or len(v[1]) < 5:
            return f"work object {name} is not a wobjdata [robhold,ufprog,ufmec,uframe,oframe]"
        robhold, ufprog = v[1][0], v[1][1]

        def boolean(x):
            return decl.tokens[x[1]][0].upper() if x[0] == "ref" and x[2] == () else "?"

        if boolean(robhold) != "FALSE":
            return f"work object {name} is held by the robot (robhold {boolean(robhold)}): a stationary-tool program"
        if boolean(ufprog) != "TRUE":
            return f"work object {name}'s user frame is moved by a mechanical unit (ufprog {boolean(ufprog)})"
        uframe, oframe = self.pose_of(st, v[1][3], decl.tokens), self.pose_of(st, v[1][4], decl.tokens)
        if uframe is None or oframe is None:
            return f"work object {name}'s frames are not numbers here"
        return uframe @ oframe

    def tool(self, name, states):
        """X,Y,Z,A,B,C of tool ``name`` or None (not known)."""
        if name is None:
            return None
        if name.lower() == "tool0" and not any("tool0" in s.decls for s in states):
            return (0.0,) * 6
        d = self.data_named(name, "tooldata", states)
        if not isinstance(d, tuple):
            return None
        st, decl = d
        v = decl.value
        if v[0] != "agg" or len(v[1]) < 2:
            return None
        robhold = v[1][0]
        if not (robhold[0] == "ref" and robhold[2] == () and decl.tokens[robhold[1]][0].upper() == "TRUE"):
            return None
        t = self.pose_of(st, v[1][1], decl.tokens)
        if t is None:
            return None
        return tuple(float(x) for x in np.concatenate([t[:3, 3], abc_from_rotation(t[:3, :3])]))

    def frame_index(self, wobj_name, tool_name, states):
        key = ((wobj_name or "wobj0").lower(), (tool_name or "").lower())
        if key in self.frame_keys:
            return self.frame_keys[key]
        base = self.wobj(wobj_name, states)
        if isinstance(base, str):
            index = (-1, base)
        else:
            self.frames.append(Frame(base, self.tool(tool_name, states), f"{wobj_name or 'wobj0'} / {tool_name or '?'}"))
            index = (len(self.frames) - 1, None)
        self.frame_keys[key] = index
        return index

    # -------------------------------------------------------------- motions

    def add_row(self, st, rt, frame, motion):
        xyz, spans, q, conf, x_at = rt
        self.rows.append((st.file, x_at, xyz, q, conf, spans, frame, _MOTION[motion]))

    def motions(self, st: _State, states):
        """Every motion of the module, in text order. A motion whose exact key (its text with
        numbers → 0) was seen before with only inline robtargets, all read without a
        finding, takes its numbers from one regex pass over the file (``_RT_RE``)."""
        rt = list(_RT_RE.finditer(st.code))
        rt_starts = np.array([m.start() for m in rt], np.int64)
        fast: dict[str, tuple] = {}
        for data, exact, start, end in st.moves:
            known = fast.get(exact)
            lo = int(np.searchsorted(rt_starts, start))
            hi = int(np.searchsorted(rt_starts, end))
            if known is not None and hi - lo == len(known[1]):
                frame, kinds = known
                for m, kind in zip(rt[lo:hi], kinds):
                    self.fast_rows.append((st.file, m, frame, _MOTION[kind]))
                continue
            rows, notes = len(self.rows), len(self.diagnostics)
            tokens = list(TOKEN_RE.finditer(st.code, start, end))
            made = self.motion(st, states, data, tokens)
            if made is not None and len(self.rows) - rows == len(made[1]) == hi - lo and \
                    len(self.diagnostics) == notes and all(v[0] == "agg" for v in data[1][:len(made[1])]):
                fast[exact] = made

    def motion(self, st, states, data, tokens):
        """Targets of one motion → rows; (frame, motion kinds) of the motion."""
        instr, positional, options, first = data
        kinds = MOTION_OF.get(instr)
        if kinds is None or len(positional) < len(kinds):
            return None
        instr_name = tokens[first][0] if first >= 0 else instr
        wobj = options.get("wobj")
        wobj_name = None
        frame, why = None, None
        if wobj is not None:
            wv = wobj[0]
            if wv is not None and wv[0] == "ref" and wv[2] == ():
                wobj_name = tokens[wv[1]][0]
            else:
                frame, why = -1, "the \\WObj argument is not a work object's name"
        tool_name = None
        for v in positional[len(kinds):]:
            if v[0] == "ref" and v[2] == ():
                nm = tokens[v[1]][0]
                if nm.lower() == "tool0" or isinstance(self.data_named(nm, "tooldata", states), tuple):
                    tool_name = nm
                    break
        if frame is None:
            frame, why = self.frame_index(wobj_name, tool_name, states)
        for v, kind in zip(positional, kinds):
            self.target(st, states, v, tokens, frame, why, kind, instr_name)
        return (frame, kinds) if frame >= 0 else None

    def target(self, st, states, v, tokens, frame, why, kind, instr):
        where = self.at(v, tokens)
        if v[0] == "agg":
            if frame < 0:
                self.unknown(st, where, why)
                return
            rt = self.robtarget(st, v, tokens, f"the target of {instr}")
            if rt is not None:
                self.add_row(st, rt, frame, kind)
            return
        if v[0] == "call":
            name = v[1]
            label = "Offs" if name == "offs" else ("RelTool" if name == "reltool" else tokens[v[2]][0])
            extra = (": not compensated itself (it moves with the numbers of the robtarget it is computed from)"
                     if name in _RUNTIME_FUNCS else ": left as written")
            self.warn(st, where, P211, f"target {label}(…) of {instr} is computed at run time{extra}")
            return
        if v[0] != "ref":
            self.warn(st, where, P211, f"target of {instr} is an expression, not known statically: left as written")
            return
        name = tokens[v[1]][0]
        self.referenced.add(name.lower())
        d = self.data_named(name, "robtarget", states)
        if d is None:
            self.warn(st, where, P211, f"robtarget {name} is not declared in this module: left as written")
            return
        if isinstance(d, str):
            self.warn(st, where, P211, f"target {name} not statically known ({d}): left as written")
            return
        dst, decl = d
        if dst is not st:
            self.warn(st, where, P211, f"robtarget {name} is declared in --config {dst.path}: left as written")
            return
        keys = v[2]
        if decl.array != (keys != ()):
            self.warn(st, where, P211, f"target {name} is {'an array' if decl.array else 'not an array'}: "
                      "left as written")
            return
        if frame < 0:
            self.unknown(st, where, why)
            if decl.uses:
                first = next(iter(decl.uses.values()))
                self.warn(st, where, P202, f"{name} is moved to here in a frame not known statically, at line "
                          f"{int(st.locate([first[1]])[0][0])} in a known one: compensated for the first")
            elif decl.used == -1:
                decl.used = -3  # moved to in an unknown frame first: never compensated
            return
        elements = self.elements(decl, keys, where, st, tokens)
        if elements is None:
            return
        for key, ev in elements:
            uses = decl.uses
            seen = uses.get(key)
            label = name + ("{" + ",".join(map(str, key)) + "}" if key else "")
            if seen is not None:
                if seen[0] != frame:
                    self.warn(st, where, P202, f"{label} is used in another frame than at its first use "
                              f"(line {int(st.locate([seen[1]])[0][0])}): compensated for the first")
                continue
            if decl.used == -3:
                break
            uses[key] = (frame, where)
            rt = self.robtarget(st, ev, decl.tokens, f"robtarget {label}")
            if rt is not None:
                self.add_row(st, rt, frame, kind)
        if decl.used == -1:
            decl.used = 0

    def elements(self, decl, keys, where, st, tokens):
        """[(index tuple, value)] of the declared robtarget(s) that ``keys`` selects."""
        if not decl.array:
            return [((), decl.value)]
        flat = []

        def walk(v, prefix):
            if v[0] == "agg" and v[1] and v[1][0][0] == "agg" and v[1][0][1] and v[1][0][1][0][0] == "agg":
                if v[1][0][1][0][1] and v[1][0][1][0][1][0][0] == "agg":  # one more dimension
                    for i, c in enumerate(v[1], start=1):
                        walk(c, prefix + (i,))
                    return
                for i, c in enumerate(v[1], start=1):
                    flat.append((prefix + (i,), c))
                return
            flat.append((prefix, v))

        walk(decl.value, ())
        if keys is None:  # an index computed at run time: every element may be meant
            return flat
        want = tuple(int(float(tokens[k][0])) for k in keys)
        hit = [(k, v) for k, v in flat if k == want]
        if not hit:
            self.warn(st, where, P211, f"{decl.name}{{{','.join(map(str, want))}}} is outside the array: left as written")
            return None
        return hit

    def unknown(self, st, where, why):
        self.warn(st, where, P201, f"frame not statically known ({why}): target left as written")

    # -------------------------------------------------------------- all

    def read(self) -> RapidProgram:
        states = []
        for i, text in enumerate(self.config):
            states.append(self.module(-1 - i, f"--config[{i}]" if len(self.config) > 1 else "--config", text, False))
        mine = []
        for fi, (path, text) in enumerate(zip(self.files, self.texts)):
            st = self.module(fi, path, text, True)
            mine.append(st)
        self.states = mine
        for st in mine:
            scope = [st] + states
            self.motions(st, scope)
            for decl in st.decls.values():
                if decl is not None and decl.type == "robtarget" and decl.value is not None and \
                        decl.name.lower() not in self.referenced:
                    self.warn(st, decl.pos, P211, f"robtarget {decl.name} is not moved to by a motion of this "
                              "module: left as written")
        return self.build()

    def columns(self):
        """The rows of both paths as arrays: file, offset of X, xyz, quaternion as written, conf, spans of the
        seven numbers x..q4, frame, motion."""
        n = len(self.rows)
        if n:
            file, at, xyz, q, conf, spans, frame, motion = zip(*self.rows)
            cols = [np.array(file, np.int32), np.array(at, np.int64), np.array(xyz, float).reshape(n, 3),
                    np.array(q, float).reshape(n, 4), np.array(conf, float).reshape(n, 4),
                    np.array(spans, np.int64).reshape(n, 7, 2), np.array(frame, np.int32), np.array(motion, np.int8)]
        else:
            cols = [np.zeros(0, np.int32), np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 4)), np.zeros((0, 4)),
                    np.zeros((0, 7, 2), np.int64), np.zeros(0, np.int32), np.zeros(0, np.int8)]
        m = len(self.fast_rows)
        if m:
            file, match, frame, motion = zip(*self.fast_rows)
            text = BLANKS.sub("", ",".join(",".join(x.groups()) for x in match))
            values = np.array(text.split(","), dtype=float).reshape(m, 11)
            spans = np.array([x.regs[1:8] for x in match], np.int64)
            fast = [np.array(file, np.int32), spans[:, 0, 0].copy(), values[:, :3], values[:, 3:7], values[:, 7:],
                    spans, np.array(frame, np.int32), np.array(motion, np.int8)]
            cols = [np.concatenate([a, b]) for a, b in zip(cols, fast)]
        order = np.lexsort((cols[1], cols[0]))  # text order
        return [c[order] for c in cols]

    def build(self) -> RapidProgram:
        file, at, xyz, q, conf, spans, frame, motion = self.columns()
        n = len(file)
        line, col = np.zeros(n, np.int64), np.zeros(n, np.int64)
        for st in self.states:
            here = file == st.file
            if here.any():
                line[here], col[here] = st.locate(at[here])
        bad = ~np.isfinite(np.concatenate([xyz, q], axis=1)).all(axis=1)
        if bad.any():
            r = int(np.flatnonzero(bad)[0])
            raise PostprocError("a robtarget's position or orientation is not a finite number", self.files[file[r]],
                                int(line[r]), int(col[r]), P103)
        with np.errstate(invalid="ignore", over="ignore"):
            big = np.abs(q).max(axis=1)
        if not (big > 0).all():
            r = int(np.flatnonzero(~(big > 0))[0])
            raise PostprocError("a robtarget's quaternion [0,0,0,0] is no orientation", self.files[file[r]],
                                int(line[r]), int(col[r]), P103)
        if n:
            abc = abc_from_rotation(rotation_from_quaternion(q / big[:, None]))
        else:
            abc = np.zeros((0, 3))
        targets = Targets(poses=np.concatenate([xyz, abc], axis=1), spans=spans[:, :3], file=file,
                          line=line.astype(np.int32), col=col.astype(np.int32), frame=frame, motion=motion,
                          abc_spans=spans[:, 3:], orientation=q)
        stamps = {}
        for fi, text in enumerate(self.texts):
            m = re.search(r"^[ \t]*!.*" + re.escape(STAMP_PREFIX) + r".*$", text, re.M)
            if m:
                stamps[fi] = m.group().strip()
        return RapidProgram(
            files=list(self.files), texts=list(self.texts), targets=targets, frames=self.frames,
            diagnostics=self.diagnostics, dialect="rapid", stamps=stamps,
            newlines=[_newline(t) for t in self.texts], comment="!", named_targets=True, confdata=conf,
            orientation="quaternion")


def read(files: list[str], texts: list[str], config: list[str] | None = None) -> RapidProgram:
    """Read RAPID module(s) ``files`` with contents ``texts``; ``config`` holds the texts of
    other modules (e.g. a .sys) whose tooldata / wobjdata the motions may name. Raises
    PostprocError (P1xx, with path:line:col) on bad input."""
    return _Reader(files, texts, config).read()

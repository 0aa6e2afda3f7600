"""RAPID units → the motion IR (``programs.ir``): what each statement of a module IS. What
the constructs *mean* (frames, tools, Offs, PDispOn …) is in ``semantics.py`` and the analysis.

Two passes over the units of the files (``syntax.scan``): the first collects what the second
needs to know before it reads a statement — the declared data (name → type, dimensions,
storage), the routines' parameters (how a call's arguments bind, which are by reference),
the RECORD types and which routines have an ERROR handler; the second lowers every statement.

* Modules: data outside routines run before the entry (``Unit.data``), ``LOCAL`` data in the
  module's scope, the rest global; ``main`` is the entry (else the routines nothing calls).
  Routines: PROC, FUNC, TRAP; parameters IN (a copy) or ``VAR``/``PERS``/``INOUT`` (by
  reference: mode "ref"), optional ones (``\\name``) bound by name.
* Control: IF/ELSEIF/ELSE, FOR … FROM … TO … STEP, WHILE, TEST/CASE/DEFAULT, GOTO and labels,
  RETURN; ``EXIT`` ends the program (``Halt``), ``Stop``/``Break`` pause it (nothing);
  a routine's ERROR handler may run after each statement that may raise an error (an
  instruction, a call, an assignment: :func:`_with_handler`), RETRY runs the statement again,
  TRYNEXT goes on after it, its end (or RAISE) returns to the caller, whose handler takes it.
* Interrupts: ``CONNECT n WITH trap`` declares a handler (``Async``), ``ISignalDI … n``,
  ``ITimer``, ``IWatch`` switch it on, ``ISleep``/``IDelete`` off.
* Motions: ``MOTIONS`` (each instruction's target arguments and its tool's position), the
  frame ``RAPID.FRAME(\\WObj (wobj0), C_PROGDISP)``, the tool ``RAPID.TOOL(tool)``;
  ``MoveAbsJ``/``MoveExtJ`` are axis motions; ``SearchL``'s search point is set at run time.
* Runs of motions to inline robtargets of plain numbers (an offline-programmed module's body)
  are one ``MoveRun`` of columns: a unit of an exact key seen before is read by the ordinals of
  its numbers (``Template``), without a tree.
"""
from __future__ import annotations

import copy
import math
import re
from dataclasses import dataclass, field

import numpy as np
from lark import Token, Tree

from ...core import frames as fr
from ...core.diagnostics import P102, P201, P211, PostprocError
from ...robot.conventions import MOTIONS
from ..grammar import BLANKS, NUM, TOKEN_RE
from ..ir import (
    Agg, Assign, Async, AsyncSwitch, Call, Decl, Eval, Field, Goto, Halt, If, Invoke, Item, Label, Lit, Loc, Loop,
    Move, MoveRun, Name, Note, Num, Op, Param, Return, Routine, Stmt, Switch, Unit, Unknown, walk, Havoc,
)
from .semantics import FUNCTIONS, INSTRUCTIONS, RECORDS, RUNTIME_POSITION, SCALARS, UNUSED_AXIS
from .syntax import STRING_RE, Source, misread

__all__ = ["Lowering", "MOTIONS_OF", "MOTION_OF"]

_MOTION = {m: i for i, m in enumerate(MOTIONS)}
_XYZ, _Q, _CF = ("X", "Y", "Z"), ("Q1", "Q2", "Q3", "Q4"), ("CF1", "CF4", "CF6", "CFX")
_EAX = tuple(f"EAX_{c}" for c in "ABCDEF")


@dataclass(frozen=True)
class MotionSpec:
    """An instruction that moves the robot: its targets (positional argument → motion kind),
    the position of its tool argument (-1: none), an axis motion, the position of an INOUT
    search point (-1: none)."""

    targets: tuple
    tool: int
    joint: bool = False
    search: int = -1


MOTIONS_OF: dict[str, MotionSpec] = {}
for _stem, _kinds in (("MOVEL", ("LIN",)), ("MOVEJ", ("PTP",)), ("MOVEC", ("CIRC-aux", "CIRC-end"))):
    for _suffix in ("", "DO", "SYNC", "GO", "AO"):
        MOTIONS_OF[_stem + _suffix] = MotionSpec(tuple(enumerate(_kinds)), len(_kinds) + 2)
for _name, _kinds, _tool in (("TRIGGL", ("LIN",), 4), ("TRIGGJ", ("PTP",), 4), ("TRIGGC", ("CIRC-aux", "CIRC-end"), 5),
                             ("TRIGGLIOS", ("LIN",), 3), ("TRIGGJIOS", ("PTP",), 3),
                             ("ARCL", ("LIN",), 5), ("ARCLSTART", ("LIN",), 5), ("ARCLEND", ("LIN",), 5),
                             ("ARCC", ("CIRC-aux", "CIRC-end"), 6), ("ARCCSTART", ("CIRC-aux", "CIRC-end"), 6),
                             ("ARCCEND", ("CIRC-aux", "CIRC-end"), 6)):
    MOTIONS_OF[_name] = MotionSpec(tuple(enumerate(_kinds)), _tool)
MOTIONS_OF["SEARCHL"] = MotionSpec(((1, "LIN"),), 3, search=0)
MOTIONS_OF["SEARCHC"] = MotionSpec(((1, "CIRC-aux"), (2, "CIRC-end")), 4, search=0)
MOTIONS_OF["MOVEABSJ"] = MotionSpec(((0, "PTP"),), 3, joint=True)
MOTIONS_OF["MOVEEXTJ"] = MotionSpec(((0, "PTP"),), -1, joint=True)
# (the public table of old: instruction (lower case) → the motion kind of each target it moves to)
MOTION_OF = {k.lower(): tuple(kind for _, kind in v.targets) for k, v in MOTIONS_OF.items()
             if not v.joint and v.search < 0}

# interrupt orders: the interrupt is their last positional argument
_ORDERS = frozenset({"ISIGNALDI", "ISIGNALDO", "ISIGNALAI", "ISIGNALAO", "ISIGNALGI", "ISIGNALGO", "ITIMER", "IPERS",
                     "IERROR", "IRMQMESSAGE", "TRIGGINT"})
_OPS = {"DIV": "div", "MOD": "mod", "AND": "and", "OR": "or", "XOR": "xor", "=": "==", "<>": "<>"}
_MATH = frozenset({"ABS", "SQRT", "EXP", "SIN", "COS", "TAN", "ASIN", "ACOS", "ATAN", "ATAN2", "POW", "TRUNC", "ROUND"})
_POSE_FUNCS = {"POSEMULT": "POSE", "POSEINV": "POSE", "ORIENTZYX": "ORIENT", "POSEVECT": "POS"}
_MAY_RAISE = (Move, Invoke, Assign, Eval)
MAY_RAISE = "an error may be raised here (the routine's ERROR handler runs)"


# private statements, resolved when the routine ends (``_with_handler``)
class _Raise(Stmt):
    __slots__ = ("loc",)

    def __init__(self, loc):
        self.loc = loc


class _Retry(_Raise):
    __slots__ = ()


class _TryNext(_Raise):
    __slots__ = ()


@dataclass
class _Sig:
    """A routine as its callers see it: its key in ``Unit.routines``, parameters
    ``(NAME, type, mode, optional)``, return type, module, and the file/unit where it stands."""

    key: str
    params: list
    rtype: str
    module: str
    handler: bool = False
    locals: dict = field(default_factory=dict)  # NAME → (type, dims)
    written: str = ""  # the name as declared (messages)
    at: tuple = ()  # (path, line) of its head


@dataclass
class Template:
    """What every unit of one exact key is, for the fast path: an inline-robtarget motion.
    ``kinds`` per target; ``numbers`` per target the 17 (ordinal, signed) of x,y,z, q1..q4,
    cf1..cfx, eax_a..f; its frame and tool expressions; ``count`` its names and numbers."""

    kinds: tuple
    numbers: tuple
    frame: object
    tool: object
    count: int = 0


class _Run:
    """The rows of a MoveRun being collected (one frame and tool): each robtarget's ``RT_RE``
    match and motion kind."""

    def __init__(self, frame, tool, fi):
        self.frame, self.tool, self.fi = frame, tool, fi
        self.matches: list = []
        self.motion: list = []


# a robtarget aggregate of plain numbers (a sign may stand before each, blanks between): its
# 17 numbers x, y, z, q1..q4, cf1, cf4, cf6, cfx, eax_a..f, each with its sign
_SNUM = r"\s*([-+]?\s*" + NUM + r")\s*"
RT_RE = re.compile(r"\[\s*\[" + ",".join([_SNUM] * 3) + r"\]\s*,\s*\[" + ",".join([_SNUM] * 4) + r"\]\s*,\s*\["
                   + ",".join([_SNUM] * 4) + r"\]\s*,\s*\[" + ",".join([_SNUM] * 6) + r"\]\s*\]", re.ASCII)


class Lowering:
    """The files of one read lowered to a Unit."""

    def __init__(self, sources: list, config_sources: list, unit: Unit, accelerate: bool = True):
        self.accelerate = accelerate
        self.sources = sources
        self.config_sources = config_sources
        self.unit = unit
        self.globals: dict = {}  # NAME → (type, dims, storage)
        self.module_data: dict = {}  # (MODULE, NAME) → (type, dims, storage) of LOCAL data
        self.sigs: dict = {}  # routine key → _Sig
        self.local_routines: dict = {}  # MODULE → {NAME}
        self.records: dict = {}  # user RECORD type → ((FIELD, type), …)
        self.consts: set = set()
        self.readonly: set = set()
        self.intnums: dict = {}  # interrupt variable → its number in the IR
        self.storage: dict = {}  # id(Decl) → storage (PERS assigned by the program: see ``_persistent``)
        self.element_inits: dict = {}  # id(Assign) of an array's initial element → declared name
        self.config_routines: dict = {}
        self.written: dict = {}  # NAME → as first written (messages)
        self._plains: dict = {}  # (shape, aggregate node) → plain robtarget ordinals
        self.calls: dict = {}  # routine key → the keys of the routines it calls (read)
        self._unused: dict = {}  # an external axis value as written → not in use (9E9)
        self._decl_templates: dict = {}  # id(shape) → (shape, what a module's robtarget declaration is)
        self._exprs: dict = {}  # a frame or tool expression → the one object for it

    # ================================================================ pass 1: declarations
    def declare(self) -> None:
        for src in self.config_sources + self.sources:
            self._declare(src, src.fi < 0)

    def _declare(self, src: Source, config: bool) -> None:
        module = None
        sig = None
        record = None
        for start, end, entry in src.units:
            shape = entry.shape
            kind = shape.kind
            if kind == "module_head":
                module = self._name(src, shape, start, end, shape.tree.children[1]).upper()
                src.module = module
                continue
            if kind in ("proc_head", "func_head", "trap_head"):
                if module is None:
                    continue  # (the second pass says where)
                u = _U(src, shape, start, end)
                tree = shape.tree
                kids = [c for c in tree.children if c is not None]
                local = isinstance(kids[0], Token) and kids[0].type == "LOCAL"
                names = [c for c in kids if isinstance(c, Token) and c.type == "NAME"]
                rtype = ""
                if kind == "func_head":
                    rtype, name = u.text(names[0]).upper(), u.text(names[1])
                else:
                    name = u.text(names[0])
                params = []
                ptree = next((c for c in kids if isinstance(c, Tree) and c.data == "params"), None)
                alt = False
                for p in (ptree.children if ptree is not None else []):
                    if isinstance(p, Token) and p.type == "ALT":
                        alt = True
                        continue
                    if p is None:
                        continue
                    words = [c for c in p.children if isinstance(c, Token)]
                    optional = alt or any(w.type == "OPT" for w in words)
                    alt = False
                    mode = "ref" if any(w.type in ("VAR", "PERS", "INOUT") for w in words) else "in"
                    pn = [w for w in words if w.type == "NAME"]
                    dims = any(isinstance(c, Tree) and c.data == "pdims" for c in p.children)
                    params.append((u.text(pn[1]).upper(), u.text(pn[0]).upper(), mode, optional, dims))
                upper = name.upper()
                key = f"{module}::{upper}" if local else upper
                if local:
                    self.local_routines.setdefault(module, set()).add(upper)
                line, col = u.at()
                first = self.sigs.get(key)
                if first is not None:
                    # (a task holds one routine of a global name, one of a LOCAL name per module: the
                    # controller refuses to load the second)
                    where = "in the task" if not local else f"in module {module}"
                    raise PostprocError(f"routine {name} is declared twice {where}: here and at {first.at[0]}:"
                                        f"{first.at[1]} (RAPID loads a task with one routine of a name)", src.path,
                                        line, col, P102)
                sig = _Sig(key, params, rtype, module, written=name, at=(src.path, line))
                self.sigs[key] = sig
                for pname, ptype, _, _, pdims in params:
                    sig.locals[pname] = (ptype, () if pdims else None)
                continue
            if kind == "routine_end":
                sig = None
                continue
            if kind == "error_head" and sig is not None:
                sig.handler = True
                continue
            if kind == "record_head":
                u = _U(src, shape, start, end)
                names = [c for c in shape.tree.children if isinstance(c, Token) and c.type == "NAME"]
                record = (u.text(names[0]).upper(), [])
                continue
            if kind == "record_end":
                if record is not None:
                    self.records[record[0]] = tuple(record[1])
                record = None
                continue
            if record is not None:
                if kind == "call":  # (``num x;`` inside RECORD … ENDRECORD: a field)
                    u = _U(src, shape, start, end)
                    tree = shape.tree
                    args = [c for c in tree.children[1:] if c is not None]
                    if args and isinstance(args[0].children[0], Tree) and args[0].children[0].data == "name":
                        ftype = u.text(tree.children[0]).upper()
                        fname = u.text(args[0].children[0].children[0]).upper()
                        record[1].append((fname, ftype))
                continue
            if kind == "decl" and module is not None:
                u = _U(src, shape, start, end)
                info = _decl_parts(shape.tree)
                storage, tnode, nnode, dims_node, _, local = info
                typ, name = u.text(tnode).upper(), u.text(nnode).upper()
                dims = self._dims(u, dims_node) if dims_node is not None else None
                if sig is not None:
                    sig.locals[name] = (typ, dims)
                elif local:
                    self.module_data[(module, name)] = (typ, dims, storage)
                else:
                    self.globals[name] = (typ, dims, storage)
                if sig is None:
                    if storage == "CONST":
                        self.consts.add(name)
                    if config:
                        self.readonly.add(name)

    def _dims(self, u, node) -> tuple:
        """Literal array dimensions (None for one that is not a literal number)."""
        out = []
        for c in node.children:
            if isinstance(c, Tree) and c.data == "number":
                out.append(int(float(u.text(c.children[0]))))
            else:
                out.append(None)
        return tuple(out)

    def _name(self, src, shape, start, end, token) -> str:
        return _U(src, shape, start, end).text(token)

    # ================================================================ pass 2: statements
    def lower(self) -> None:
        # --config modules first (their data are there before the program's); their routines
        # are read where the program calls them
        for src in self.config_sources:
            self._lower(src, config=True)
        for src in self.sources:
            self._lower(src)
        self._reach_config()
        self._persistent()

    def _reach_config(self) -> None:
        """Routines of --config modules the program calls (transitively) join the unit."""
        routines = self.unit.routines
        if not self.config_routines:
            return
        todo = list(routines)
        while todo:
            for name in self.calls.get(todo.pop(), ()):
                extra = self.config_routines.get(name)
                if extra is not None and name not in routines:
                    routines[name] = extra
                    todo.append(name)

    def _lower(self, src: Source, config: bool = False) -> None:
        self.src = src
        self.fi = src.fi
        self.config = config
        self.module = None
        self.routine = None
        self.sig = None
        self.bodies: list = []
        self.nodes: list = []
        self.blocks: list = []  # (kind, loc)
        self.run: _Run | None = None
        self.handler = None
        self.data: list | None = None
        self.record = False
        self.discard = False
        for start, end, entry in src.units:
            shape = entry.shape
            kind = shape.kind
            if self.record and kind != "record_end":
                continue
            if kind == "call" and self.accelerate and not config and self.routine is not None \
                    and not self.sig.handler and not self.discard:
                template = entry.template
                if template is None:
                    template = entry.template = self._template(_U(src, shape, start, end)) or False
                if template and self._fast(template, start, end):
                    continue
            if kind == "decl" and self.routine is None and self.data is not None and self._fast_decl(shape, start, end):
                continue
            self.flush()
            u = _U(src, shape, start, end)
            self.u = u
            handler = getattr(self, "s_" + kind, None)
            if handler is None:
                raise PostprocError(f"statement not understood here ({kind})", src.path, *u.at(), P102)
            handler(u, shape.tree)
        self.flush()
        if self.routine is not None or self.module is not None:
            at = src.locate(len(src.text))
            raise PostprocError("MODULE without ENDMODULE" if self.routine is None else "routine not closed at the end",
                                src.path, *at, P102)

    # ------------------------------------------------------------ emission
    def here(self, u=None, node=None) -> Loc:
        u = u or self.u
        return Loc(self.fi, *u.at(node))

    def emit(self, stmt) -> None:
        self.flush()
        if self.discard:
            return
        self.bodies[-1].append(stmt)

    def flush(self) -> None:
        run = self.run
        if run is None:
            return
        self.run = None
        if not self.discard:
            self.bodies[-1].append(_move_run(run, self.src))

    def _fail(self, message, u, node=None):
        raise PostprocError(message, self.src.path, *u.at(node), P102)

    # ------------------------------------------------------------ modules and routines
    def s_module_head(self, u, tree):
        if self.module is not None:
            self._fail("MODULE inside a module", u)
        self.module = u.text(tree.children[1]).upper()
        self.data = []
        self.unit.data.append((self.module, self.data))

    def s_module_end(self, u, tree):
        if self.module is None:
            self._fail("ENDMODULE without its MODULE", u)
        if self.routine is not None:
            self._fail("ENDMODULE inside a routine", u)
        self.module = None
        self.data = None

    def _need_module(self, u):
        if self.module is None:
            self._fail("statement outside MODULE … ENDMODULE", u)

    def _routine(self, u, tree, names_at: int):
        self._need_module(u)
        if self.routine is not None:
            self._fail("routine inside a routine (ENDPROC missing?)", u)
        kids = [c for c in tree.children if c is not None]
        local = isinstance(kids[0], Token) and kids[0].type == "LOCAL"
        names = [c for c in kids if isinstance(c, Token) and c.type == "NAME"]
        name = u.text(names[names_at]).upper()
        key = f"{self.module}::{name}" if local else name
        sig = self.sigs.get(key)
        if sig is None or sig.module != self.module:  # (one of two routines of one name: the first)
            sig = _Sig(key, [], "", self.module)
        self.sig = sig
        params = tuple(Param(p[0], p[2]) for p in sig.params)
        self.routine = Routine(key, params, [], self.here(u), self.module, not local, tree.data == "func_head")
        if self.config:
            self.config_routines.setdefault(key, self.routine)
        elif key not in self.unit.routines:
            self.unit.routines[key] = self.routine
        self.bodies = [self.routine.body]
        self.nodes = [self.routine]
        self.blocks = [("ROUTINE", self.here(u))]
        self.handler = None
        self.discard = False

    def s_proc_head(self, u, tree):
        self._routine(u, tree, 0)

    def s_func_head(self, u, tree):
        self._routine(u, tree, 1)

    def s_trap_head(self, u, tree):
        self._routine(u, tree, 0)

    def s_routine_end(self, u, tree):
        if self.routine is None:
            self._fail("end of a routine that was not opened", u)
        if len(self.blocks) > 1:
            kind, loc = self.blocks[-1]
            self._fail(f"{kind} at line {loc.line} is not closed before the end of the routine", u)
        r = self.routine
        r.body = _with_handler(r.body, self.handler) if self.handler is not None else _no_handler(r.body)
        self.routine = None
        self.sig = None
        self.bodies, self.nodes, self.blocks = [], [], []
        self.discard = False

    def s_record_head(self, u, tree):
        self.record = True

    def s_record_end(self, u, tree):
        self.record = False

    def s_error_head(self, u, tree):
        self._handler_part(u, "ERROR")
        self.handler = []
        self.bodies[-1] = self.handler
        self.discard = False

    def s_undo_head(self, u, tree):
        self._handler_part(u, "UNDO")
        self.discard = True  # (UNDO runs when the routine is left abnormally, BACKWARD when stepping back)

    s_backward_head = s_undo_head

    def _handler_part(self, u, word):
        if self.routine is None or len(self.blocks) != 1:
            self._fail(f"{word} outside a routine's body", u)

    # ------------------------------------------------------------ blocks
    def _open(self, kind, node, body):
        self.emit(node)
        self.blocks.append((kind, node.loc))
        self.nodes.append(node)
        self.bodies.append(body)

    def _close(self, kinds, word, u):
        if self.routine is None:
            self._need_module(u)
            self._fail(f"{word} outside a routine", u)
        if len(self.blocks) < 2 or self.blocks[-1][0] not in kinds:
            if len(self.blocks) >= 2:
                kind, loc = self.blocks[-1]
                self._fail(f"{word} does not close {kind} (line {loc.line})", u)
            self._fail(f"{word} without {' / '.join(sorted(kinds))}", u)
        self.blocks.pop()
        self.nodes.pop()
        self.bodies.pop()

    def _in_routine(self, u):
        self._need_module(u)
        if self.routine is None:
            self._fail("a statement outside a routine", u)

    def s_if_head(self, u, tree):
        self._in_routine(u)
        node = If(self.expr(tree.children[1]), [], [], self.here(u))
        self._open("IF", node, node.then)

    def s_elseif(self, u, tree):
        if not self.blocks or self.blocks[-1][0] != "IF":
            self._fail("ELSEIF without IF", u)
        inner = If(self.expr(tree.children[1]), [], [], self.here(u))
        self.flush()
        self.nodes[-1].orelse.append(inner)
        self.nodes[-1] = inner
        self.bodies[-1] = inner.then

    def s_else_(self, u, tree):
        if not self.blocks or self.blocks[-1][0] != "IF":
            self._fail("ELSE without IF", u)
        self.flush()
        self.bodies[-1] = self.nodes[-1].orelse

    def s_endif(self, u, tree):
        self.flush()
        self._close({"IF"}, "ENDIF", u)

    def s_for_head(self, u, tree):
        self._in_routine(u)
        var = next(c for c in tree.children if isinstance(c, Token) and c.type == "NAME")
        exprs = [c for c in tree.children if isinstance(c, Tree)]
        node = Loop("for", [], self.here(u), var=u.text(var).upper(), start=self.expr(exprs[0]),
                    stop=self.expr(exprs[1]), step=self.expr(exprs[2]) if len(exprs) > 2 else Lit(1))
        self._open("FOR", node, node.body)

    def s_endfor(self, u, tree):
        self.flush()
        self._close({"FOR"}, "ENDFOR", u)

    def s_while_head(self, u, tree):
        self._in_routine(u)
        node = Loop("while", [], self.here(u), cond=self.expr(tree.children[1]))
        self._open("WHILE", node, node.body)

    def s_endwhile(self, u, tree):
        self.flush()
        self._close({"WHILE"}, "ENDWHILE", u)

    def s_test_head(self, u, tree):
        self._in_routine(u)
        node = Switch(self.expr(tree.children[1]), [], None, self.here(u))
        self._open("TEST", node, [])

    def s_case(self, u, tree):
        if not self.blocks or self.blocks[-1][0] != "TEST":
            self._fail("CASE outside TEST", u)
        self.flush()
        body: list = []
        self.nodes[-1].cases.append((tuple(self.expr(c) for c in tree.children if isinstance(c, Tree)), body))
        self.bodies[-1] = body

    def s_default(self, u, tree):
        if not self.blocks or self.blocks[-1][0] != "TEST":
            self._fail("DEFAULT outside TEST", u)
        self.flush()
        self.nodes[-1].default = []
        self.bodies[-1] = self.nodes[-1].default

    def s_endtest(self, u, tree):
        self.flush()
        self._close({"TEST"}, "ENDTEST", u)

    def s_label(self, u, tree):
        self._in_routine(u)
        self.emit(Label(u.text(tree.children[0]).upper(), self.here(u)))

    def s_goto(self, u, tree):
        self._in_routine(u)
        self.emit(Goto(u.text(tree.children[-1]).upper(), self.here(u)))

    def s_placeholder(self, u, tree):
        """RobotStudio's statement placeholder (``<SMT>``): a statement not written yet — what it
        will do is not known (the values and frames after it are not known either)."""
        self._in_routine(u)
        loc = self.here(u)
        self.emit(Havoc(None, f"the editor's placeholder {tree.children[0]} at line {loc.line} stands for a "
                              "statement not written yet", loc))

    def s_compact_if(self, u, tree):
        self._in_routine(u)
        node = If(self.expr(tree.children[1]), [], [], self.here(u))
        self.emit(node)
        self.bodies.append(node.then)
        try:
            getattr(self, "s_" + tree.children[2].data)(u, tree.children[2])
            self.flush()
        finally:
            self.bodies.pop()

    # ------------------------------------------------------------ data
    def s_decl(self, u, tree):
        self._need_module(u)
        storage, tnode, nnode, dims_node, init, local = _decl_parts(tree)
        typ, written = u.text(tnode).upper(), u.text(nnode)
        name = written.upper()
        loc = self.here(u, nnode)
        in_routine = self.routine is not None
        scope = "local" if in_routine else ("module" if local else "global")
        dims = None
        if dims_node is not None:
            dims = tuple(self.expr(c) for c in dims_node.children if isinstance(c, Tree))
        target = self.bodies[-1] if in_routine and not self.discard else (self.data if not in_routine else None)
        if target is None:
            return
        if dims is None:
            value = self.expr(init, typ) if init is not None else None
            decl = Decl(name, typ, None, value, scope, loc, written)
            self.storage[id(decl)] = storage
            target.append(decl)
            return
        decl = Decl(name, typ, dims, None, scope, loc, written)
        self.storage[id(decl)] = storage
        target.append(decl)
        if init is not None:
            for index, node in _elements(init, len(dims)):
                a = Assign(Item(Name(name, written), tuple(Lit(i) for i in index)), self.expr(node, typ),
                           self.here(u, node))
                self.element_inits[id(a)] = name
                target.append(a)

    def s_assign(self, u, tree):
        self._in_routine(u)
        lhs, rhs = tree.children
        typ, dims = self.type_of(lhs)
        loc = self.here(u)
        if dims is not None and dims and isinstance(rhs, Tree) and rhs.data == "aggregate":
            target = self.expr(lhs)
            for index, node in _elements(rhs, len(dims)):
                self.emit(Assign(Item(target, tuple(Lit(i) for i in index)), self.expr(node, typ), loc))
            return
        self.emit(Assign(self.expr(lhs), self.expr(rhs, typ), loc))

    # ------------------------------------------------------------ interrupts
    def s_connect(self, u, tree):
        self._in_routine(u)
        target, trap = tree.children[1], tree.children[3]
        name = u.text(trap).upper()
        key = self.resolve(name) or name
        self.emit(Async(self.intnum(target), Invoke(key, (), self.here(u)), self.here(u), False, "TRAP"))

    def intnum(self, node):
        """The IR number of an interrupt variable (a plain name), None for any other."""
        if isinstance(node, Tree) and node.data == "name":
            name = self.u.text(node.children[0]).upper()
            return Lit(self.intnums.setdefault(name, len(self.intnums) + 1))
        return None

    # ------------------------------------------------------------ calls
    def s_late_call(self, u, tree):
        self._in_routine(u)
        args = [c for c in tree.children[1:] if c is not None]
        positional, options = _split(args)
        value = self.expr(tree.children[0])
        exprs = (value,) + tuple(self.expr(a) for a in positional) + \
            tuple(self.expr(v) for _, v in options if v is not None)
        self.emit(Invoke("%late%", exprs, self.here(u)))

    def s_call(self, u, tree):
        self._in_routine(u)
        written = u.text(tree.children[0])
        name = written.upper()
        args = [c for c in tree.children[1:] if c is not None]
        named: list = []
        positional, options = _split(args, named)
        loc = self.here(u)
        if named:
            positional, options, unplaced = _place(name, positional, named, options, self.resolve(name) is not None)
            if unplaced:
                self._by_name_unknown(u, name, written, positional, options, unplaced, loc)
                return
        if name == "RETURN":
            self.emit(Return(self.expr(positional[0], self.sig.rtype) if positional else None, loc))
        elif name == "RAISE":
            if positional:
                self.emit(Eval(self.expr(positional[0]), loc))
            self.emit(_Raise(loc))
        elif name == "RETRY":
            self.emit(_Retry(loc))
        elif name == "TRYNEXT":
            self.emit(_TryNext(loc))
        elif name in ("EXIT", "EXITCYCLE"):
            self.emit(Halt(loc))
        elif name in ("STOP", "BREAK"):
            pass  # (a pause: the operator's start goes on with the next statement)
        elif name == "CALLBYVAR" and self.resolve(name) is None:  # (CallByVar "proc", n: proc<n>, late bound)
            self.emit(Invoke("%late%", tuple(self.expr(a) for a in positional), loc))
        elif name in MOTIONS_OF:
            self.motion(u, name, written, positional, options)
        elif name in ("PDISPON", "PDISPSET", "PDISPOFF"):
            self.pdisp(u, name, positional, options)
        elif name in _ORDERS:
            if name == "TRIGGINT" and positional:
                self.emit(Invoke("RAPID.TRIGGINT", tuple(self.expr(a) for a in positional[1:-1]), loc))
                self.emit(Assign(self.expr(positional[0]), Unknown("set by TriggInt"), loc))
            else:
                self.emit(Invoke("RAPID." + name, tuple(self.expr(a) for a in positional[:-1]), loc))
            if positional:
                self.emit(AsyncSwitch(self.intnum(positional[-1]), True, loc))
        elif name in ("IWATCH", "ISLEEP", "IDELETE"):
            if positional:
                self.emit(AsyncSwitch(self.intnum(positional[0]), name == "IWATCH", loc))
        elif name == "IENABLE":
            self.emit(AsyncSwitch(None, True, loc))
        elif name == "IDISABLE":
            pass  # (interrupts are queued while disabled: they run at IEnable)
        elif name == "GRIPLOAD" and positional and self.resolve(name) is None:  # (the payload gripped: $LOAD)
            self.emit(Assign(Name("$LOAD"), self.expr(positional[0], "LOADDATA"), loc))
        elif name in ("INCR", "DECR", "ADD", "CLEAR") and positional and self.resolve(name) is None:
            target = self.expr(positional[0])
            if name == "CLEAR":
                value = Lit(0.0)
            elif name == "ADD":
                value = Op("+", (target, self.expr(positional[1]) if len(positional) > 1 else Unknown("Add")))
            else:
                value = Op("+" if name == "INCR" else "-", (target, Lit(1.0)))
            self.emit(Assign(target, value, loc))
        else:
            key = self.resolve(name)
            if key is not None:
                self.emit(Invoke(key, self.bind(key, positional, options), loc))
            elif name in INSTRUCTIONS:
                exprs = tuple(self.expr(a) for a in positional) + \
                    tuple(self.expr(v) for _, v in options if v is not None)
                self.emit(Invoke("RAPID." + name, exprs, loc))
                for k in INSTRUCTIONS[name]:
                    if k < len(positional) and _assignable(positional[k]):
                        self.emit(Assign(self.expr(positional[k]), Unknown(f"set by {written} at run time"), loc))
                for opt, value in options:
                    if value is not None and opt.upper() in ("TIMEFLAG", "RESULT", "ANSWER") and _assignable(value):
                        self.emit(Assign(self.expr(value), Unknown(f"set by {written} at run time"), loc))
            else:
                exprs = tuple(self.expr(a) for a in positional) + \
                    tuple(self.expr(v) for _, v in options if v is not None)
                self.emit(Invoke(written, exprs, loc))

    def resolve(self, name: str) -> str | None:
        """The key of the routine a call names from the running module (its LOCAL routines
        first), None where no file read holds it; the call is recorded (``calls``)."""
        key = None
        if name in self.local_routines.get(self.module, ()):
            key = f"{self.module}::{name}"
        elif name in self.sigs and "::" not in name:
            key = name
        if key is not None:
            self.calls.setdefault(self.routine.name if self.routine is not None else "", set()).add(key)
        return key

    def _by_name_unknown(self, u, name, written, positional, options, unplaced, loc):
        """An instruction given a required argument by a name postproc cannot place (no parameter
        names of it are known): its targets are left as written, what it may set is unknown."""
        why = (f"{written} is given {', '.join(k + ':=' for k in unplaced)} by name, and postproc does not know "
               f"which of {written}'s arguments that is")
        spec = MOTIONS_OF.get(name)
        if spec is not None:
            self.emit(Note(P211, f"{why}: left as written", loc, True))
            for _, kind in spec.targets:
                self.emit(Move(kind, Unknown(why), loc, joint=spec.joint, relative=True))
            return
        exprs = tuple(self.expr(a) for a in positional if a is not None) + \
            tuple(self.expr(v) for _, v in options if v is not None)
        self.emit(Invoke(written, exprs, loc))  # (not a routine of the files read: what it may change, unknown)
        for _, value in options:
            if value is not None and _assignable(value):
                self.emit(Assign(self.expr(value), Unknown(why), loc))

    def bind(self, key: str, positional, options) -> tuple:
        """A call's arguments in the order of the routine's parameters (None: not passed);
        optional parameters by name, a switch passed as TRUE."""
        sig = self.sigs[key]
        params = sig.params
        out = [None] * len(params)
        required = [k for k, p in enumerate(params) if not p[3]]
        for k, node in zip(required, positional):
            out[k] = self.argument(node, params[k][1])
        for opt, value in options:  # (and required arguments given by name: Speed:=v100)
            k = next((k for k, p in enumerate(params) if p[0] == opt.upper()), None)
            if k is None:
                continue
            out[k] = Lit(True) if value is None else self.argument(value, params[k][1])
        return tuple(out)

    def argument(self, node, typ: str):
        """An argument for a parameter of type ``typ``: a number written for a scalar (``lift
        pWork, 300``) is a constant of the routine's computation, no target's token."""
        return self.constant(node) if typ in SCALARS else self.expr(node, typ)

    # ------------------------------------------------------------ motions
    def motion(self, u, name, written, positional, options):
        spec = MOTIONS_OF[name]
        loc = self.here(u)
        frame, tool = self._frame_tool(u, spec, positional, options)
        for k, kind in spec.targets:
            if k >= len(positional):
                self.emit(Note(P211, f"{written} without its target argument: nothing to compensate", loc, False))
                continue
            node = positional[k]
            want = "JOINTTARGET" if spec.joint else "ROBTARGET"
            target = self.expr(node, want)
            self.emit(Move(kind, target, self.here(u, node), frame, tool, joint=spec.joint, chain=kind != "CIRC-aux",
                           load=_load_of(tool)))
        if spec.search >= 0 and spec.search < len(positional) and _assignable(positional[spec.search]):
            self.emit(Assign(self.expr(positional[spec.search]),
                             Unknown(f"the position {written} found, known at run time", P211), loc))

    def _frame_tool(self, u, spec, positional, options):
        wobj = next((v for k, v in options if k.upper() == "WOBJ" and v is not None), None)
        if wobj is None:
            wexpr, wlabel = Name("WOBJ0", "wobj0"), "wobj0"
        else:
            wexpr = self.expr(wobj)
            wlabel = u.text(wobj.children[0]) if isinstance(wobj, Tree) and wobj.data == "name" else ""
        frame = Call("RAPID.FRAME", (wexpr, Name("C_PROGDISP"), Lit(wlabel)))
        if 0 <= spec.tool < len(positional):
            node = positional[spec.tool]
            label = u.text(node.children[0]) if isinstance(node, Tree) and node.data == "name" else ""
            tool = Call("RAPID.TOOL", (self.expr(node), Lit(label)))
        else:
            tool = Call("RAPID.TOOL", (Unknown("the motion names no tool"), Lit("")))
        # (one object for each frame and tool written alike: the runs and the analysis compare them)
        return self._exprs.setdefault(frame, frame), self._exprs.setdefault(tool, tool)

    def pdisp(self, u, name, positional, options):
        loc = self.here(u)
        target = Name("C_PROGDISP")
        if name == "PDISPOFF":
            self.emit(Assign(target, Call("RAPID.NOFRAME", ()), loc))
        elif name == "PDISPSET":
            value = self.expr(positional[0], "POSE") if positional else Unknown("PDispSet without a frame", P201)
            self.emit(Assign(target, value, loc))
        else:
            rot = any(k.upper() == "ROT" for k, _ in options)
            exe = next((v for k, v in options if k.upper() == "EXEP" and v is not None), None)
            exe_expr = self.expr(exe, "ROBTARGET") if exe is not None else \
                Unknown("PDispOn without \\ExeP takes the robot's position when it runs (known at run time)", P201)
            prog = self.expr(positional[0], "ROBTARGET") if positional else Unknown("PDispOn without its point", P201)
            self.emit(Assign(target, Call("RAPID.PDISPON", (Lit(rot), exe_expr, prog), loc), loc))

    # ------------------------------------------------------------ the fast path
    def _template(self, u) -> Template | None:
        """A Template where the unit is a motion to inline robtargets of plain numbers with a
        work object and a tool named by plain names."""
        tree = u.shape.tree
        name = u.text(tree.children[0]).upper()
        spec = MOTIONS_OF.get(name)
        if spec is None or spec.joint or spec.search >= 0:
            return None
        args = [c for c in tree.children[1:] if c is not None]
        positional, options = _split(args)
        numbers = []
        for k, _ in spec.targets:
            if k >= len(positional):
                return None
            nums = _plain_robtarget(positional[k], u.shape.ordinal_at)
            if nums is None:
                return None
            numbers.append(nums)
        if not (0 <= spec.tool < len(positional)) or not _is_name(positional[spec.tool]):
            return None
        if any(v is not None and not _is_name(v) for k, v in options if k.upper() == "WOBJ"):
            return None
        # (the regex finds these robtargets, each number where the tree has it)
        toks = u.toks()
        found = list(RT_RE.finditer(u.src.code, u.start, u.end))
        if len(found) != len(numbers) or any(m.regs[1 + k][1] != toks[o].end() for m, nums in zip(found, numbers)
                                             for k, (o, _) in enumerate(nums)):
            return None
        saved = self.u
        self.u = u
        try:
            frame, tool = self._frame_tool(u, spec, positional, options)
        finally:
            self.u = saved
        return Template(tuple(kind for _, kind in spec.targets), tuple(numbers), frame, tool, len(u.shape.ordinal_at))

    def _fast(self, t: Template, start: int, end: int) -> bool:
        """The unit's rows into the run being collected (its robtargets found by ``RT_RE``, read
        at the run's end); False where it cannot be one (an external axis in use: the general
        path says why)."""
        ms = list(RT_RE.finditer(self.src.code, start, end))
        if len(ms) != len(t.kinds):
            return False
        unused = self._unused
        for m in ms:
            for x in m.groups()[11:]:
                free = unused.get(x)
                if free is None:
                    free = unused[x] = abs(float(BLANKS.sub("", x))) >= UNUSED_AXIS
                if not free:
                    return False
        run = self.run
        if run is not None and not (run.frame is t.frame and run.tool is t.tool) and \
                (run.frame != t.frame or run.tool != t.tool):
            self.flush()
            run = None
        if run is None:
            run = self.run = _Run(t.frame, t.tool, self.fi)
        run.matches += ms
        run.motion += t.kinds
        return True

    def _fast_decl(self, shape, start: int, end: int) -> bool:
        """A module's robtarget declared with plain numbers (a RobotStudio module's data),
        read by the ordinals of its name and numbers; False for any other declaration."""
        t = self._decl_templates.get(id(shape))
        if t is None:
            storage, tnode, nnode, dims, init, local = _decl_parts(shape.tree)
            plain = _plain_robtarget(init, shape.ordinal_at) if dims is None and init is not None else None
            t = self._decl_templates[id(shape)] = (shape, (storage, shape.ordinal_at[tnode.start_pos],
                                                            shape.ordinal_at[nnode.start_pos], local, plain))
        storage, type_at, name_at, local, plain = t[1]
        if not plain:
            return False
        toks = list(TOKEN_RE.finditer(self.src.code, start, end))
        if len(toks) != len(shape.ordinal_at) or toks[type_at].group().upper() != "ROBTARGET":
            return False
        u = self.u = _U(self.src, shape, start, end)
        u._toks = toks
        written = toks[name_at].group()
        decl = Decl(written.upper(), "ROBTARGET", None, self._robtarget(plain), "module" if local else "global",
                    Loc(self.fi, *self.src.locate(toks[name_at].start())), written)
        self.storage[id(decl)] = storage
        self.data.append(decl)
        return True

    # ------------------------------------------------------------ expressions
    def type_of(self, node) -> tuple:
        """(type, dims) of an expression (upper case; "" not known; dims None: not an array)."""
        if not isinstance(node, Tree):
            return "", None
        d = node.data
        if d == "name":
            return self.type_of_name(self.u.text(node.children[0]).upper())
        if d == "member":
            typ, _ = self.type_of(node.children[0])
            fields = RECORDS.get(typ) or self.records.get(typ) or ()
            want = self.u.text(node.children[1]).upper()
            return next(((t, None) for f, t in fields if f == want), ("", None))
        if d == "index":
            typ, _ = self.type_of(node.children[0])
            return typ, None
        if d == "fcall":
            name = self.u.text(node.children[0]).upper()
            if name in ("OFFS", "RELTOOL", "CROBT", "CALCROBT", "MIRPOS", "OROBT"):
                return "ROBTARGET", None
            if name in _POSE_FUNCS:
                return _POSE_FUNCS[name], None
            key = self.resolve(name)
            if key is not None:
                return self.sigs[key].rtype, None
        return "", None

    def type_of_name(self, name: str) -> tuple:
        sig = self.sig
        if sig is not None and name in sig.locals:
            return sig.locals[name]
        found = self.module_data.get((self.module, name)) or self.globals.get(name)
        if found is not None:
            return found[0], found[1]
        return "", None

    def expr(self, node, typ: str = ""):
        if node is None:
            return None
        if isinstance(node, Token):
            return Lit(str(node))
        d = node.data
        u = self.u
        if d == "placeholder":
            return Unknown(f"the editor's placeholder {node.children[0]} stands for a value not written yet")
        if d == "conditional":
            arg, par = (str(c) for c in node.children)
            return Unknown(f"\\{arg}?{par} passes {arg} on only where the caller got its optional {par}: "
                           "whether it did is known at run time")
        if d == "number":
            s, e = u.span(node.children[0])
            return Num(float(u.src.code[s:e]), self.fi, s, e)
        if d == "signed":
            sign, inner = node.children
            if isinstance(inner, Tree) and inner.data == "number":
                s, e = u.span(inner.children[0])
                code = u.src.code
                j = s
                while code[j - 1] in " \t\r\n":
                    j -= 1
                v = float(code[s:e])
                return Num(-v if str(sign) == "-" else v, self.fi, j - 1, e)
            e = self.expr(inner, typ)
            return Op("neg", (e,)) if str(sign) == "-" else e
        if d == "string":
            return Lit(u.string(node.children[0])[1:-1])
        if d == "name":
            written = u.text(node.children[0])
            name = written.upper()
            if name in ("TRUE", "FALSE"):
                return Lit(name == "TRUE")
            self.written.setdefault(name, written)
            return Name(name, written)
        if d == "aggregate":
            return self.aggregate(node, typ)
        if d == "member":
            written = u.text(node.children[1])
            return Field(self.expr(node.children[0]), written.upper(), written)
        if d == "index":
            return Item(self.expr(node.children[0]), tuple(self.expr(c) for c in node.children[1:] if c is not None))
        if d == "fcall":
            return self.fcall(node)
        if d == "binop":
            a, op, b = node.children
            word = str(op).upper()
            return Op(_OPS.get(word, word.lower() if word.isalpha() else str(op)), (self.expr(a), self.expr(b)))
        if d == "not_":
            return Op("not", (self.expr(node.children[-1]),))
        return Unknown("an expression the reader does not evaluate")

    def aggregate(self, node, typ: str, loc: Loc | None = None) -> Agg:
        if typ == "ROBTARGET":
            plain = self._plain(node)
            if plain:
                return self._robtarget(plain)
        items = [c for c in node.children if c is not None]
        fields = RECORDS.get(typ) or self.records.get(typ)
        loc = loc or self.here(self.u, node)
        if fields is not None and len(fields) == len(items):
            lowered = tuple((f, self.expr(c, t)) for (f, t), c in zip(fields, items))
        else:
            lowered = tuple((str(k + 1), self.expr(c)) for k, c in enumerate(items))
        return Agg("pose" if typ == "ROBTARGET" else "record", lowered, loc, typ, "quaternion")

    def _plain(self, node):
        """The 17 (ordinal, signed) of a robtarget aggregate of plain numbers (cached by the
        shape), False for another."""
        shape = self.u.shape
        key = (id(shape), id(node))
        found = self._plains.get(key)
        if found is None:
            found = self._plains[key] = (shape, node, _plain_robtarget(node, shape.ordinal_at) or False)
        return found[2]

    def _robtarget(self, plain) -> Agg:
        """A robtarget aggregate of plain numbers, read by their ordinals (no tree walk)."""
        toks = self.u.toks()
        code = self.src.code
        fi = self.fi
        nums = []
        for ordinal, signed in plain:
            m = toks[ordinal]
            s, e = m.span()
            v = float(m.group())
            if signed:
                j = s
                while code[j - 1] in " \t\r\n":
                    j -= 1
                s = j - 1
                if code[s] == "-":
                    v = -v
            nums.append(Num(v, fi, s, e))
        loc = Loc(fi, *self.src.locate(toks[plain[0][0]].start()))

        def rec(typ, names, values):
            return Agg("record", tuple(zip(names, values)), loc, typ, "quaternion")

        return Agg("pose", (("TRANS", rec("POS", _XYZ, nums[:3])), ("ROT", rec("ORIENT", _Q, nums[3:7])),
                            ("ROBCONF", rec("CONFDATA", _CF, nums[7:11])), ("EXTAX", rec("EXTJOINT", _EAX, nums[11:]))),
                   loc, "ROBTARGET", "quaternion")

    def constant(self, node):
        """A number written as an argument of a function is a constant of that computation (no
        target's token): ``Offs(p10, 0, 0, 100)``."""
        if isinstance(node, Tree) and node.data == "number":
            return Lit(float(self.u.text(node.children[0])))
        if isinstance(node, Tree) and node.data == "signed" and isinstance(node.children[1], Tree) \
                and node.children[1].data == "number":
            v = float(self.u.text(node.children[1].children[0]))
            return Lit(-v if str(node.children[0]) == "-" else v)
        return self.expr(node)

    def fcall(self, node):
        u = self.u
        written = u.text(node.children[0])
        name = written.upper()
        args = [c for c in node.children[1:] if c is not None]
        named: list = []
        positional, options = _split(args, named)
        loc = self.here(u, node)
        key = self.resolve(name)
        if key is not None:
            return Call(key, self.bind(key, positional, options + named), loc)
        if named:
            return Unknown(f"{written}() is given {', '.join(k + ':=' for k, _ in named)} by name, and postproc "
                           f"does not place arguments of {written}() by name")
        if name in RUNTIME_POSITION:
            return Unknown(f"{written}() is where the robot is at run time", P211)
        if name == "OFFS":
            point = self.expr(positional[0], "ROBTARGET") if positional else Unknown("Offs() without its point")
            return Call("RAPID." + written, (point,)
                        + tuple(self.constant(a) for a in positional[1:4]), loc)
        if name == "RELTOOL":
            rot = {k.upper(): self.constant(v) for k, v in options if v is not None}
            point = self.expr(positional[0], "ROBTARGET") if positional else Unknown("RelTool() without its point")
            return Call("RAPID." + written, (point,)
                        + tuple(self.constant(a) for a in positional[1:4])
                        + tuple(rot.get(k, Lit(0.0)) for k in ("RX", "RY", "RZ")), loc)
        if name == "DIM" and len(positional) == 2 and _is_name(positional[0]):
            _, dims = self.type_of(positional[0])
            k = self.constant(positional[1])
            if dims and isinstance(k, Lit) and 1 <= int(k.value) <= len(dims) and dims[int(k.value) - 1] is not None:
                return Lit(dims[int(k.value) - 1])
        if name == "PRESENT":
            return Unknown("whether an optional argument is present is known at run time")
        if name in _POSE_FUNCS:
            types = {"POSEMULT": ("POSE", "POSE"), "POSEINV": ("POSE",), "POSEVECT": ("POSE", "POS")}.get(name, ())
            return Call("RAPID." + written, tuple(self.expr(a, types[k] if k < len(types) else "")
                                               for k, a in enumerate(positional)), loc)
        if name in _MATH:
            extra = tuple(self.expr(v) for k, v in options if v is not None and k.upper() == "DEC")
            return Call("RAPID.MATH", (Lit(name),) + tuple(self.expr(a) for a in positional) + extra, loc)
        if name in FUNCTIONS:
            exprs = tuple(self.expr(a) for a in positional) + tuple(self.expr(v) for _, v in options if v is not None)
            return Call("RAPID." + written, exprs, loc)
        exprs = tuple(self.expr(a) for a in positional) + tuple(self.expr(v) for _, v in options if v is not None)
        return Call(written, exprs, loc)

    # ================================================================ after the statements
    def _persistent(self) -> None:
        """Module data (PERS, and VAR: initialised when the module is loaded or the program
        pointer set to main, not when ``main`` runs again in continuous mode) that the program
        assigns (or passes by reference) keep what the last run left: the parts it assigns
        (``w.oframe.trans``: that component; ``p``: all of it) are not known when a run starts
        (they are from their assignment on), the others are as written."""
        assigned: dict = {}  # NAME → the component paths assigned (() the whole)
        for r in list(self.unit.routines.values()) + list(self.config_routines.values()):
            for s in walk(r.body):
                if isinstance(s, Assign) and id(s) not in self.element_inits:
                    root, path = _path(s.target)
                    if root is not None:
                        assigned.setdefault(root, set()).add(path)
                elif isinstance(s, Invoke) and s.name in self.sigs:
                    for p, a in zip(self.sigs[s.name].params, s.args):
                        if p[2] == "ref" and a is not None:
                            root, path = _path(a)
                            if root is not None:
                                assigned.setdefault(root, set()).add(path)
        for module, stmts in self.unit.data:
            for k, s in enumerate(stmts):
                storage = self.storage.get(id(s))
                if not (isinstance(s, Decl) and storage in ("PERS", "VAR") and s.name in assigned):
                    continue
                paths = assigned[s.name]
                why = (f"{storage} {s.written or s.name} is assigned at run time (a run starts with the value the last "
                       "run left)")
                if s.init is not None:
                    s.init = _unknown_at(s.init, paths, why)
                for a in stmts[k + 1:]:
                    if isinstance(a, Assign) and self.element_inits.get(id(a)) == s.name:
                        a.value = Unknown(why, P211)


    # ================================================================ what code the entry does not run changes
    def changed_outside(self, entries: list) -> dict:
        """The data (scope key ``("G", NAME)`` / ``("M", MODULE, NAME)``, not CONST) that a routine
        the entries do not reach changes — a routine the pendant, an event routine or another task
        can run at any moment — and the routines that routine calls: key → (name as written, what
        changes it, where (Loc), the routine (as written)), the first found. A change: an
        assignment (an instruction that sets an argument is lowered to one), an argument to a
        VAR/PERS/INOUT parameter of a routine read, any argument of a routine not read (RAPID
        passes by reference). TRAPs connected by the code the entries run are reached (CONNECT)."""
        routines = dict(self.config_routines)
        routines.update(self.unit.routines)
        reached, todo = set(), [k for k in entries if k in routines]
        while todo:
            k = todo.pop()
            if k in reached:
                continue
            reached.add(k)
            todo.extend(self.calls.get(k, ()))
        roots = [k for k in routines if k not in reached]
        if not roots:
            return {}
        outside, todo = {}, list(roots)
        while todo:  # (each routine run outside the entry's flow: from the root that reaches it)
            k = todo.pop(0)
            root = outside.setdefault(k, k if k in roots else None)
            for c in self.calls.get(k, ()):
                if c in routines and c not in outside:
                    outside[c] = root
                    todo.append(c)
        out: dict = {}
        for key, root in outside.items():
            r = routines[key]
            sig = self.sigs.get(key)
            for name, what, loc in self._changes(r, sig):
                scope = self._scope_of(name, r.module, sig)
                if scope is None or scope in out:
                    continue
                info = self.globals.get(name) if scope[0] == "G" else self.module_data.get((r.module, name))
                if info is None or info[2] == "CONST" or info[0] in _NOT_RUNTIME:
                    continue
                rsig = self.sigs.get(root) if root is not None else sig
                out[scope] = (self.written.get(name, name), what, loc, r, (rsig.written if rsig else "") or root)
        return out

    def _scope_of(self, name: str, module: str, sig) -> tuple | None:
        if sig is not None and name in sig.locals:
            return None
        if (module, name) in self.module_data:
            return ("M", module, name)
        if name in self.globals:
            return ("G", name)
        return None

    def _changes(self, r, sig):
        """(NAME, what changes it, Loc) of each change a routine's statements make to a variable."""
        for s in walk(r.body):
            if isinstance(s, Assign):
                root, _ = _path(s.target)
                if root is not None:
                    why = getattr(s.value, "why", "") if isinstance(s.value, Unknown) else ""
                    what = why[7:].split(" ")[0] if why.startswith("set by ") else "an assignment"
                    yield root, what, s.loc
            for e in _exprs_of(s):
                for c in _calls_in(e):
                    yield from self._passed(c, s.loc)
            if isinstance(s, Invoke):
                yield from self._passed(s, s.loc)

    def _passed(self, call, loc):
        """The variables a call may change: its by-reference arguments (a routine read), every
        argument (a routine or function not read)."""
        name = call.name
        if name.startswith("RAPID."):
            return
        sig = self.sigs.get(name)
        written = (sig.written if sig is not None else "") or ("a routine named at run time" if name == "%late%"
                                                               else name)
        for k, a in enumerate(call.args):
            if a is None or (sig is not None and (k >= len(sig.params) or sig.params[k][2] != "ref")):
                continue
            root, _ = _path(a)
            if root is not None:
                yield root, written, loc


# the types of data whose change by other code matters to no target (speeds, zones, loads,
# strings, interrupt numbers, I/O and clocks)
_NOT_RUNTIME = frozenset({"STRING", "SPEEDDATA", "ZONEDATA", "LOADDATA", "INTNUM", "IODEV", "CLOCK", "ERRNUM",
                          "SIGNALDI", "SIGNALDO", "SIGNALAI", "SIGNALAO", "SIGNALGI", "SIGNALGO", "TRIGGDATA",
                          "STOPPOINTDATA", "BYTE"})


def _exprs_of(s) -> tuple:
    """The expressions a statement holds at its own level (not those of nested statements)."""
    kind = type(s)
    if kind is Assign:
        return (s.target, s.value)
    if kind is Move:
        return (s.target, s.frame, s.tool, s.config, s.ext)
    if kind is Eval:
        return (s.expr,)
    if kind is If:
        return (s.cond,)
    if kind is Loop:
        return (s.start, s.stop, s.step, s.cond)
    if kind is Switch:
        return (s.subject,) + tuple(v for values, _ in s.cases for v in values)
    if kind is Return:
        return (s.value,)
    if kind is Decl:
        return (s.init,) + tuple(s.dims or ())
    if kind is Invoke:
        return tuple(s.args)
    if kind is Goto:
        return (s.cond,)
    return ()


def _calls_in(e):
    """Every Call inside an expression."""
    if e is None:
        return
    kind = type(e)
    if kind is Call:
        yield e
        for a in e.args:
            yield from _calls_in(a)
    elif kind in (Field, Item):
        yield from _calls_in(e.base)
        if kind is Item:
            for x in e.index:
                yield from _calls_in(x)
    elif kind is Op:
        for a in e.args:
            yield from _calls_in(a)
    elif kind is Agg:
        for _, v in e.items:
            yield from _calls_in(v)


# ------------------------------------------------------------------------------- helpers


class _U:
    """The unit being lowered: its tokens read from the file by their ordinals in the shape."""

    __slots__ = ("src", "shape", "start", "end", "_toks", "_strings")

    def __init__(self, src: Source, shape, start: int, end: int):
        self.src, self.shape, self.start, self.end = src, shape, start, end
        self._toks = None
        self._strings = None

    def toks(self):
        if self._toks is None:
            self._toks = list(TOKEN_RE.finditer(self.src.code, self.start, self.end))
            if len(self._toks) != len(self.shape.ordinal_at):
                misread(self.src, self.start, self.end, self.shape, self._toks)
        return self._toks

    def tok(self, token):
        return self.toks()[self.shape.ordinal_at[token.start_pos]]

    def text(self, token) -> str:
        return self.tok(token).group()

    def span(self, token) -> tuple:
        m = self.tok(token)
        return m.start(), m.end()

    def string(self, token) -> str:
        if self._strings is None:
            self._strings = [(m.start(), m.end()) for m in STRING_RE.finditer(self.src.code, self.start, self.end)]
        s, e = self._strings[self.shape.string_at[token.start_pos]]
        return self.src.text[s:e]

    def at(self, node=None) -> tuple:
        """(line, col) of ``node``'s first token (the unit's start without one)."""
        offset = self.start
        if node is not None:
            first = _first_token(node, self.shape.ordinal_at)
            if first is not None:
                offset = self.toks()[self.shape.ordinal_at[first.start_pos]].start()
        elif self.toks():
            offset = self.toks()[0].start()
        return self.src.locate(offset)


def _first_token(node, ordinal_at):
    if isinstance(node, Token):
        return node if node.start_pos in ordinal_at else None
    for c in node.children:
        if c is None:
            continue
        t = _first_token(c, ordinal_at)
        if t is not None:
            return t
    return None


def _decl_parts(tree):
    """(storage, type token, name token, dims node, init node, LOCAL) of a decl tree."""
    kids = [c for c in tree.children if c is not None]
    at = 0
    local = False
    while isinstance(kids[at], Token):  # LOCAL / TASK
        local = local or kids[at].type == "LOCAL"
        at += 1
    storage = str(kids[at].children[0]).upper()
    type_tok, name_tok = kids[at + 1], kids[at + 2]
    rest = kids[at + 3:]
    dims = next((c for c in rest if isinstance(c, Tree) and c.data == "dims"), None)
    init = next((c for c in rest if not (isinstance(c, Tree) and c.data == "dims")), None)
    return storage, type_tok, name_tok, dims, init, local


# the required parameters of the motion instructions, in order (ABB's RAPID instructions
# reference): a required argument given by name goes to its place
_MOVE = ("TOPOINT", "SPEED", "ZONE", "TOOL")
_CIRC = ("CIRPOINT", "TOPOINT", "SPEED", "ZONE", "TOOL")
PARAMETERS: dict[str, tuple] = {"MOVEABSJ": ("TOJOINTPOS", "SPEED", "ZONE", "TOOL"),
                                "TRIGGL": ("TOPOINT", "SPEED", "TRIGG_1", "ZONE", "TOOL"),
                                "TRIGGJ": ("TOPOINT", "SPEED", "TRIGG_1", "ZONE", "TOOL"),
                                "TRIGGC": ("CIRPOINT", "TOPOINT", "SPEED", "TRIGG_1", "ZONE", "TOOL")}
for _stem, _params in (("MOVEL", _MOVE), ("MOVEJ", _MOVE), ("MOVEC", _CIRC)):
    PARAMETERS[_stem] = _params
    PARAMETERS[_stem + "DO"] = PARAMETERS[_stem + "GO"] = PARAMETERS[_stem + "AO"] = _params + ("SIGNAL", "VALUE")
    PARAMETERS[_stem + "SYNC"] = _params + ("PROCNAME",)


def _place(name: str, positional: list, named: list, options: list, routine: bool) -> tuple:
    """(positional, options, names not placed) with the required arguments given by name put in
    place: an instruction's by :data:`PARAMETERS`, a routine's of the files read by its
    parameters' names (``bind`` reads them with the options)."""
    if routine:
        return positional, options + named, []
    order = PARAMETERS.get(name)
    if order is None:
        return positional, options, [k for k, _ in named]
    out = list(positional)
    for key, value in named:
        if key.upper() not in order:
            return positional, options, [key]
        k = order.index(key.upper())
        out.extend([None] * (k + 1 - len(out)))
        if out[k] is not None:
            return positional, options, [key]
        out[k] = value
    return out, options, []


def _split(args, named: list | None = None) -> tuple:
    """A call's ``arg`` trees → (positional expression trees, [(option name, value tree | None)]);
    a required argument given by name (``Tool:=tool0``) goes to ``named`` [(NAME, value tree)]
    where given, else with the options (bound by name like them: ``Lowering.bind``)."""
    positional, options = [], []
    for arg in args:
        kids = arg.children
        if arg.data == "named":
            (named if named is not None else options).append((str(kids[0]), kids[1]))  # (as written)
            kids = kids[2:]
        elif kids and not (isinstance(kids[0], Tree) and kids[0].data == "option"):
            positional.append(kids[0])
            kids = kids[1:]
        for opt in kids:
            if opt is None:
                continue
            if opt.data == "conditional":  # (\Arg?Par: a value the lowering reads as a run-time one)
                options.append((str(opt.children[0]), opt))
                continue
            options.append((str(opt.children[0]), opt.children[1] if len(opt.children) > 1 else None))
    return positional, options


def _is_name(node) -> bool:
    return isinstance(node, Tree) and node.data == "name"


def _assignable(node) -> bool:
    return isinstance(node, Tree) and node.data in ("name", "member", "index")


def _elements(node, ndims: int, prefix=()):
    """(index, element tree) of an array's aggregate of ``ndims`` dimensions."""
    if ndims == 0 or not (isinstance(node, Tree) and node.data == "aggregate"):
        yield prefix, node
        return
    for k, c in enumerate([c for c in node.children if c is not None], start=1):
        yield from _elements(c, ndims - 1, prefix + (k,))


def _plain_robtarget(node, ordinal_at):
    """The 17 (ordinal, signed) of a robtarget aggregate [[x,y,z],[q1..q4],[cf…],[eax…]] of
    plain numbers, None for anything else."""
    if not (isinstance(node, Tree) and node.data == "aggregate"):
        return None
    parts = [c for c in node.children if c is not None]
    if len(parts) != 4:
        return None
    out = []
    for part, n in zip(parts, (3, 4, 4, 6)):
        if not (isinstance(part, Tree) and part.data == "aggregate"):
            return None
        items = [c for c in part.children if c is not None]
        if len(items) != n:
            return None
        for c in items:
            if c.data == "number":
                out.append((ordinal_at[c.children[0].start_pos], False))
            elif c.data == "signed" and isinstance(c.children[1], Tree) and c.children[1].data == "number":
                out.append((ordinal_at[c.children[1].children[0].start_pos], True))
            else:
                return None
    return tuple(out)


def _move_run(run: _Run, src: Source) -> MoveRun:
    n = len(run.matches)
    text = BLANKS.sub("", ",".join(",".join(m.groups()) for m in run.matches))
    values = np.array(text.split(","), float).reshape(n, 17)
    spans = np.array([m.regs[1:8] for m in run.matches], np.int64).reshape(n, 7, 2)
    line, col = src.lines_cols(spans[:, 0, 0])
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):  # (as analysis.targets reads one target)
        abc = fr.abc_from_rotation(fr.orientation_rotation(values[:, 3:7], "quaternion"))
    pose = np.concatenate([values[:, :3], abc], axis=1)
    all_spans = np.full((n, 12), -1, np.int64)
    all_spans[:, :6] = spans[:, :3].reshape(n, 6)
    motion = np.array([_MOTION[k] for k in run.motion], np.int8)
    rows = dict(pose=pose, written=np.ones((n, 6), bool), spans=all_spans, file=np.full(n, run.fi, np.int32),
                line=line.astype(np.int32), col=col.astype(np.int32), motion=motion,
                chain=motion != _MOTION["CIRC-aux"], config=np.full((n, 2), -1, np.int16),
                orient=values[:, 3:7].copy(), ospans=spans[:, 3:7].copy(), confdata=values[:, 7:11].copy())
    return MoveRun(rows, run.frame, run.tool, _load_of(run.tool))


def _load_of(tool):
    """The payload at a motion with ``tool`` (a ``RAPID.TOOL`` call): its tload + the GripLoad."""
    return Call("RAPID.LOAD", (tool.args[0],)) if isinstance(tool, Call) and tool.name == "RAPID.TOOL" else None


def _path(e) -> tuple:
    """(root name, the component path assigned: field names down to the first element index)
    of an assignable expression; (None, ()) for another."""
    path: list = []
    while isinstance(e, (Field, Item)):
        if isinstance(e, Item):
            path.clear()  # (an element: the path from the array on is not followed)
        else:
            path.append(e.name)
        e = e.base
    return (e.name, tuple(reversed(path))) if isinstance(e, Name) else (None, ())


def _unknown_at(init, paths: set, why: str):
    """``init`` (an aggregate as written) with the components at ``paths`` unknown."""
    if () in paths or not isinstance(init, Agg):
        return Unknown(why, P211)
    items = []
    for name, value in init.items:
        sub = {p[1:] for p in paths if p[0] == name}
        items.append((name, _unknown_at(value, sub, why) if sub else value))
    return Agg(init.kind, tuple(items), init.loc, init.type, init.form)


def _no_handler(body: list) -> list:
    """A routine without an ERROR handler: RAISE returns to the caller (whose handler takes the
    error; in ``main`` the program ends); RETRY/TRYNEXT stand only in a handler."""
    return _resolve(body, lambda s: [Return(None, s.loc)])


def _resolve(body: list, replace) -> list:
    out = []
    for s in body:
        if isinstance(s, _Raise):
            out.extend(replace(s))
            continue
        if isinstance(s, If):
            s.then, s.orelse = _resolve(s.then, replace), _resolve(s.orelse, replace)
        elif isinstance(s, Switch):
            s.cases = [(v, _resolve(b, replace)) for v, b in s.cases]
            if s.default is not None:
                s.default = _resolve(s.default, replace)
        elif isinstance(s, Loop):
            s.body = _resolve(s.body, replace)
        out.append(s)
    return out


def _with_handler(body: list, handler: list) -> list:
    """A routine with an ERROR handler: after each statement that may raise an error the
    handler may run (a copy of it there: ``If`` of a condition known only at run time); its
    RETRY jumps back before the statement, TRYNEXT after it, its end and RAISE return to the
    caller (RETURN too); an explicit RAISE in the body runs it for sure."""
    count = [0]

    def copy_of(k: int) -> list:
        h = copy.deepcopy(handler)
        retry, after = f"@RETRY{k}", f"@NEXT{k}"

        def rename(stmts):
            for s in walk(stmts):
                if isinstance(s, (Label, Goto)):
                    s.name = f"{s.name}@{k}"
        rename(h)
        h = _resolve(h, lambda s: [Goto(retry, s.loc)] if type(s) is _Retry else
                     [Goto(after, s.loc)] if type(s) is _TryNext else [Return(None, s.loc)])
        return h + [Return(None, handler[-1].loc if handler else Loc(0, 0, 0))]

    def visit(stmts: list) -> list:
        out = []
        for s in stmts:
            if type(s) is _Raise:
                k = count[0] = count[0] + 1
                out += [Label(f"@RETRY{k}", s.loc)] + copy_of(k) + [Label(f"@NEXT{k}", s.loc)]
                continue
            if isinstance(s, (_Retry, _TryNext)):
                out.append(Return(None, s.loc))
                continue
            if isinstance(s, If):
                s.then, s.orelse = visit(s.then), visit(s.orelse)
            elif isinstance(s, Switch):
                s.cases = [(v, visit(b)) for v, b in s.cases]
                if s.default is not None:
                    s.default = visit(s.default)
            elif isinstance(s, Loop):
                s.body = visit(s.body)
            if isinstance(s, _MAY_RAISE):
                k = count[0] = count[0] + 1
                out += [Label(f"@RETRY{k}", s.loc), s,
                        If(Unknown(MAY_RAISE), copy_of(k), [], s.loc), Label(f"@NEXT{k}", s.loc)]
            else:
                out.append(s)
        return out

    return visit(body)


_ = math

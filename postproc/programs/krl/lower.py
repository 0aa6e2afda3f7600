"""KRL statements → the motion IR (``programs.ir``): one handler per statement of the grammar
(``s_<rule>``), expressions by :meth:`Lowering.expr`. What a statement *means* is in
``semantics.py`` and the analysis; here is only how KRL writes it.

The block structure (DEF … END, IF … ENDIF, SWITCH, loops, SPLINE, DEFDAT) is checked as the
lines come (a structure error is P101 at its line) and nests the statements; the lines read
vectorised (``fast_path``: motions to literal targets) are put where they stand afterwards:
each statement lowered first leaves a *gap* (the hot lines between it and the statement before
it), which ``fill_gaps`` turns into a ``MoveRun``.
"""
from __future__ import annotations

import numpy as np
from lark import Token, Tree

from ...core.diagnostics import P101, P103, P210, P211
from .. import ir
from ..ir import (
    Agg, Assign, Async, AsyncSwitch, Call, Decl, Eval, Exit, Field, Goto, If, Invoke, Item, Label, Lit, Loc, Loop,
    Move, MoveRun, Name, Note, Num, Op, Param, Return, Routine, Switch, Unknown,
)
from .semantics import BUILTIN_FUNCTIONS

def _rel_frame(node) -> str:
    """The frame a _REL motion's move is in: ``#TOOL`` the tool's, else (``#BASE``, the default) the base's."""
    for c in node.children:
        if isinstance(c, Tree) and c.data == "motion_tail":
            if any(isinstance(x, Token) and str(x).upper() == "#TOOL" for x in c.children):
                return "tool"
    return "base"


def _rel_why(target) -> str:
    """Why a _REL target (lowered) is not a move of X/Y/Z from the start ("" where it is)."""
    if not isinstance(target, Agg):
        return "a move that is not a literal aggregate"
    for name, value in target.items:
        if name in ("X", "Y", "Z"):
            continue
        if name in ("A", "B", "C") and isinstance(value, Num) and value.value == 0.0:
            continue
        return "it turns the tool (A/B/C)" if name in ("A", "B", "C") else f"it moves {name}"
    return ""


_KIND_OF = {"PTP": "PTP", "LIN": "LIN", "SPTP": "SPTP", "SLIN": "SLIN", "SPL": "SPL"}
_OPS = {"MOD": "mod", "AND": "and", "B_AND": "and", "OR": "or", "B_OR": "or", "EXOR": "xor", "B_EXOR": "xor",
        "NOT": "not", "B_NOT": "not"}
_AXIS_KEYS = {f"A{i}" for i in range(1, 7)}
_CLOSER = {"DEF": "END", "DEFFCT": "ENDFCT", "DEFDAT": "ENDDAT", "IF": "ENDIF", "FOR": "ENDFOR", "WHILE": "ENDWHILE",
           "LOOP": "ENDLOOP", "REPEAT": "UNTIL", "SWITCH": "ENDSWITCH", "SPLINE": "ENDSPLINE"}


class _Gap(ir.Stmt):
    """Where the hot lines with keys below ``key`` (and above the gap before) stand."""

    __slots__ = ("key", "base", "tool", "load")

    def __init__(self, key: int, base, tool, load=None):
        self.key = key
        self.base = base
        self.tool = tool
        self.load = load


def first_pos(tree):
    for c in tree.children:
        if isinstance(c, Token):
            return c.start_pos
        if c is not None:
            p = first_pos(c)
            if p is not None:
                return p
    return None


def mark_brace(agg, text: str) -> None:
    """Remember where the aggregate's '{' stands (lark drops anonymous tokens)."""
    first = first_pos(agg)
    if first is None:  # '{}' : find it from the end
        agg.meta_brace = -1
        return
    agg.meta_brace = text.rfind("{", 0, first)


class Lowering:
    """The lowering handlers (methods of the Reader, which provides the line's positions:
    ``number``, ``col``, ``abs_pos``, ``err``, and the unit being built)."""

    # ------------------------------------------------------------ blocks and emission
    def begin_file(self) -> None:
        self.blocks: list = []  # (kind, line, col, detail): the structure check
        self.end_like: list = []  # (word, line) of calls named END… inside a block: a misspelt closer?
        self.bodies: list = []  # the statement lists being filled (innermost last)
        self.nodes: list = []  # the IR node of each open block (If, Switch, Loop, Routine…)
        self.spline: list = []  # (base, tool) expressions of open SPLINE … WITH blocks
        self.spline_load: list = []  # their WITH $LOAD expressions (None: the $LOAD in force)
        self.with_load = None  # the last frame_exprs' $LOAD (a WITH $LOAD = …; None: $LOAD in force)
        self.gaps: list = []
        self.routine = None
        self.in_def = False
        self.data = None  # the data statements of the open DEFDAT

    def here(self, pos: int | None = None) -> Loc:
        return Loc(self.fi, self.ln, self.col(pos) if pos is not None else 1)

    def emit(self, stmt) -> None:
        if self.bodies:
            self.bodies[-1].append(stmt)
        elif self.role in ("config", "module") and isinstance(stmt, (Decl, Assign)):
            self.module_data.append(stmt)  # (a declaration outside DEFDAT … ENDDAT)

    def gap(self) -> None:
        """The hot lines up to this statement stand here (in the innermost open block)."""
        if self.bodies and self.in_def:
            base, tool = self.frame_exprs(())
            g = _Gap(self.kbase, base, tool, self.with_load)
            self.bodies[-1].append(g)
            self.gaps.append(g)

    def open_block(self, kind, node, detail=""):
        self.blocks.append((kind, self.ln, self.col(first_pos(node) or 0), detail))

    def close_block(self, kinds, node, word):
        if not self.blocks or self.blocks[-1][0] not in kinds:
            if self.blocks:
                kind, line, _, _ = self.blocks[-1]
                typo = next((f" ({w} at line {at}: {_CLOSER.get(kind, 'END' + kind)}, misspelt?)" for w, at in reversed(self.end_like)
                             if at > line), "")
                self.err(f"{word} does not close {kind} (line {line}){typo}", first_pos(node) or 0)
            self.err(f"{word} without {' / '.join(sorted(kinds))}", first_pos(node) or 0)
        return self.blocks.pop()

    # ------------------------------------------------------------ modules, routines, data
    def s_header(self, node):
        pass

    def s_def_head(self, node):
        self.begin_def(node)

    def s_fct_head(self, node):
        self.begin_def(node, kind="DEFFCT")

    def begin_def(self, node, kind="DEF"):
        name = next(c for c in node.children if isinstance(c, Token) and c.type == "NAME")
        if self.blocks:
            self.err(f"{kind} inside {self.blocks[-1][0]} (line {self.blocks[-1][1]}): missing "
                     f"{'END' if self.blocks[-1][0] == 'DEF' else 'end of block'}", first_pos(node))
        self.open_block(kind, node, str(name))
        self.block_open["DEF"] = self.ln
        glob = any(isinstance(c, Token) and c.type == "GLOBAL" for c in node.children)
        params = []
        for p in next((c for c in node.children if isinstance(c, Tree) and c.data == "params"), Tree("params", [])) \
                .children:
            if p is None:
                continue
            words = [c for c in p.children if isinstance(c, Token)]
            mode = "unknown"
            if any(w.type == "OUT" for w in words):
                mode = "out"
            elif any(w.type == "IN" for w in words):
                mode = "in"
            params.append(Param(str(words[0]).upper(), mode))
        upper = str(name).upper()
        visible = self.defs_seen == 0 or glob
        key = upper if visible else f"{self.module_name}::{upper}"
        if not visible:
            self.local_defs.setdefault(self.module_name, set()).add(upper)
        self.routine = Routine(key, tuple(params), [], Loc(self.fi, self.ln, self.col(first_pos(node) or 0)),
                               self.module_name, visible, kind == "DEFFCT")
        self.unit.routines[key] = self.routine
        self.routine_order.append(key)
        self.defs_seen += 1
        self.in_def = True
        self.bodies = [self.routine.body]
        self.nodes = [self.routine]

    def s_def_end(self, node):
        self.close_block({"DEF"}, node, "END")
        self.end_def()

    def s_fct_end(self, node):
        self.close_block({"DEFFCT"}, node, "ENDFCT")
        self.end_def()

    def end_def(self):
        self.def_lines.append((self.block_open["DEF"], self.ln))
        self.in_def = False
        self.routine = None
        self.bodies, self.nodes = [], []

    def s_dat_head(self, node):
        if self.blocks:
            self.err(f"DEFDAT inside {self.blocks[-1][0]}", first_pos(node))
        self.has_dat = True
        self.open_block("DEFDAT", node)
        self.bodies = [self.module_data]
        self.nodes = [None]

    def s_dat_end(self, node):
        self.close_block({"DEFDAT"}, node, "ENDDAT")
        self.bodies, self.nodes = [], []

    def scope(self, glob: bool) -> str:
        if self.role == "config" or (glob and not self.in_def):
            return "global"
        return "local" if self.in_def else "module"

    def s_decl(self, node):
        typ = ""
        glob = any(isinstance(c, Token) and c.type == "GLOBAL" for c in node.children)
        scope = self.scope(glob)
        for c in node.children:
            if isinstance(c, Tree) and c.data == "type":
                typ = c.children[0].upper()
            elif isinstance(c, Tree) and c.data == "decl_item":
                written = str(c.children[0])
                name = written.upper()
                dims = next((x for x in c.children[1:] if isinstance(x, Tree) and x.data == "dims"), None)
                init = c.children[-1] if len(c.children) > 1 and c.children[-1] is not dims else None
                value = None
                if init is not None:
                    if self.blocks and self.blocks[-1][0] == "DEFDAT" and self.role != "config":
                        self.constant_only(init, written)
                    value = self.expr(init)
                    if isinstance(value, Agg) and not value.type and typ:
                        value = Agg(value.kind, value.items, value.loc, typ, value.form)
                if scope == "global" and self.role == "config":
                    self.config_globals.add(name)
                self.emit(Decl(name, typ, () if dims is not None else None, value, scope, self.here(), written))

    def constant_only(self, init, declared: str) -> None:
        """A data list's initial values are constants (numbers, strings, bits, #enum values, TRUE,
        FALSE, aggregates of them): the controller does not load a .dat whose declaration names a
        variable or calls a function (``Y NaN`` included: KRL has no NaN constant). Refused here,
        at the name (P103), not read as a value the program sets at run time."""
        for sub in init.iter_subtrees_topdown():
            if sub.data == "name" and str(sub.children[0]).upper() not in ("TRUE", "FALSE"):
                what = f"'{sub.children[0]}', which is no constant"
            elif sub.data == "fcall":
                what = f"a call of {sub.children[0]}"
            else:
                continue
            self.err(f"{declared}'s initial value in this data list holds {what}: a data list's values are "
                     "constants (numbers, strings, #enum values, TRUE/FALSE), and the controller does not load "
                     "it as written", first_pos(sub), P103)

    def s_struc_decl(self, node):
        """``STRUC name type field, field, type field``: the member types (upper case)."""
        fields_ = [c for c in node.children if isinstance(c, Tree) and c.data == "struc_field"]
        name = next(c for c in node.children if isinstance(c, Token) and c.type == "NAME")
        members, typ = {}, ""
        for f in fields_:
            names = [c for c in f.children if isinstance(c, Token) and c.type == "NAME"]
            if len(names) == 2:
                typ = names[0].upper()
            members[names[-1].upper()] = typ
        self.strucs[str(name).upper()] = members

    def s_enum_decl(self, node):
        pass

    s_signal_decl = s_ext_decl = s_time_block = s_anin = s_anout = s_brake = s_resume = s_enum_decl

    def s_continue_(self, node):
        pass  # (KRL's CONTINUE lifts the advance-run stop of the next line; not a loop's continue)

    def s_import_decl(self, node):
        typ = node.children[1].children[0].upper()
        dims = any(isinstance(c, Tree) and c.data == "dims" for c in node.children)
        name = str(node.children[2]).upper()
        self.emit(Decl(name, typ, () if dims else None, Unknown(f"{name} is imported (IMPORT … IS)"),
                       self.scope(False), self.here()))

    # ------------------------------------------------------------ control flow
    def s_if_head(self, node):
        self.open_block("IF", node)
        stmt = If(self.expr(node.children[1]), [], [], self.here(first_pos(node)))
        self.emit(stmt)
        self.bodies.append(stmt.then)
        self.nodes.append(stmt)

    def s_else_(self, node):
        if not self.blocks or self.blocks[-1][0] != "IF":
            self.err("ELSE without IF", first_pos(node))
        self.bodies[-1] = self.nodes[-1].orelse

    def s_endif(self, node):
        self.close_block({"IF"}, node, "ENDIF")
        self._pop()

    def _pop(self):
        if len(self.bodies) > 1:
            self.bodies.pop()
            self.nodes.pop()

    def s_switch_head(self, node):
        self.open_block("SWITCH", node)
        stmt = Switch(self.expr(node.children[1]), [], None, self.here(first_pos(node)))
        self.emit(stmt)
        self.bodies.append([])  # (before the first CASE: nothing runs)
        self.nodes.append(stmt)

    def s_case(self, node):
        if not self.blocks or self.blocks[-1][0] != "SWITCH":
            self.err("CASE outside SWITCH", first_pos(node))
        body: list = []
        self.nodes[-1].cases.append((tuple(self.expr(e) for e in node.children[1:] if isinstance(e, Tree)), body))
        self.bodies[-1] = body

    def s_default(self, node):
        if not self.blocks or self.blocks[-1][0] != "SWITCH":
            self.err("CASE outside SWITCH", first_pos(node))
        self.nodes[-1].default = []
        self.bodies[-1] = self.nodes[-1].default

    def s_endswitch(self, node):
        self.close_block({"SWITCH"}, node, "ENDSWITCH")
        self._pop()

    def _loop(self, kind, node, **kw):
        stmt = Loop(kind.lower(), [], self.here(first_pos(node)), **kw)
        self.emit(stmt)
        self.bodies.append(stmt.body)
        self.nodes.append(stmt)

    def s_for_head(self, node):
        self.open_block("FOR", node)
        var = next(c for c in node.children if isinstance(c, Token) and c.type == "NAME")
        exprs = [c for c in node.children if isinstance(c, Tree)]
        self._loop("FOR", node, var=str(var).upper(), start=self.expr(exprs[0]), stop=self.expr(exprs[1]),
                   step=self.expr(exprs[2]) if len(exprs) > 2 else Lit(1))

    def s_endfor(self, node):
        self.close_block({"FOR"}, node, "ENDFOR")
        self._pop()

    def s_while_head(self, node):
        self.open_block("WHILE", node)
        self._loop("WHILE", node, cond=self.expr(node.children[1]))

    def s_endwhile(self, node):
        self.close_block({"WHILE"}, node, "ENDWHILE")
        self._pop()

    def s_loop_head(self, node):
        self.open_block("LOOP", node)
        self._loop("LOOP", node)

    def s_endloop(self, node):
        self.close_block({"LOOP"}, node, "ENDLOOP")
        self._pop()

    def s_repeat_head(self, node):
        self.open_block("REPEAT", node)
        self._loop("REPEAT", node)

    def s_until(self, node):
        self.close_block({"REPEAT"}, node, "UNTIL")
        self.nodes[-1].cond = self.expr(node.children[1])
        self._pop()

    def s_exit_(self, node):
        self.emit(Exit(self.here(first_pos(node))))

    def s_halt(self, node):
        pass  # (KRL's HALT pauses: the operator's Start resumes at the next statement, which runs)

    def s_return_(self, node):
        value = next((c for c in node.children if isinstance(c, Tree)), None)
        self.emit(Return(self.expr(value) if value is not None else None, self.here(first_pos(node))))

    def s_goto(self, node):
        self.emit(Goto(str(node.children[-1]).upper(), self.here(first_pos(node))))

    def s_label(self, node):
        self.emit(Label(str(node.children[0]).upper(), self.here(first_pos(node))))

    def s_wait_for(self, node):
        for c in node.children:
            if isinstance(c, Tree):
                self.emit(Eval(self.expr(c), self.here(first_pos(node))))

    s_wait_sec = s_wait_for

    def s_spline_head(self, node):
        self.open_block("SPLINE", node)
        self.block_open["SPLINE"] = self.ln
        self.spline.append(self.frame_exprs(node.children))
        self.spline_load.append(self.with_load)

    def s_spline_end(self, node):
        self.close_block({"SPLINE"}, node, "ENDSPLINE")
        self.spline_lines.append((self.block_open["SPLINE"], self.ln))
        if self.spline:
            self.spline.pop()
        if self.spline_load:
            self.spline_load.pop()

    # ------------------------------------------------------------ handlers
    def s_interrupt_decl(self, node):
        action = self.action(node.children[-1])
        number = next((c for c in node.children if isinstance(c, Tree)), None)
        self.emit(Async(self.expr(number) if number is not None else None, action, action.loc, False,
                        "INTERRUPT handler"))

    def s_interrupt_ctl(self, node):
        words = {str(c).upper() for c in node.children if isinstance(c, Token)}
        number = next((c for c in node.children if isinstance(c, Tree)), None)
        if "ON" in words or "OFF" in words:
            self.emit(AsyncSwitch(self.expr(number) if number is not None else None, "ON" in words,
                                  self.here(first_pos(node))))

    def s_trigger(self, node):
        action = next(c for c in node.children if isinstance(c, Tree) and c.data in ("assign", "call", "bare_call",
                                                                                     "brake"))
        act = self.action(action)
        self.emit(Async(None, act, act.loc, True, "TRIGGER handler"))

    def action(self, node):
        """A handler's action (an assignment, a call, BRAKE) as a statement."""
        if node.data == "assign":
            return Assign(self.expr(node.children[0]), self.expr(node.children[1]), self.here(first_pos(node)))
        if node.data in ("call", "bare_call"):
            return self.call_stmt(node)
        return Eval(Lit(None), self.here(first_pos(node)))

    # ------------------------------------------------------------ statements
    def s_assign(self, node):
        lhs, rhs = node.children
        target = self.expr(lhs)
        if not isinstance(target, (Name, Field, Item)):  # (#BASE = …: an ENUM value, a number, a call)
            self.err("the left side of '=' is not a variable", first_pos(node) or 0)
        self.emit(Assign(target, self.expr(rhs), self.here(first_pos(node))))

    def s_call(self, node):
        self.emit(self.call_stmt(node))

    def s_bare_call(self, node):
        name = str(node.children[0])
        if name.upper().startswith("END") and self.blocks:  # (ENDFRO: a call, to the grammar)
            self.end_like.append((name, self.ln))
        self.s_call(node)

    def call_stmt(self, node) -> Invoke:
        name = str(node.children[0])  # (as written: messages name it so; the dialect resolves it case-blind)
        loc = self.here(first_pos(node))
        args = [a for a in node.children[1].children] if node.data == "call" else []
        if name.upper() == "BAS" and args and args[0] is not None and args[0].data == "enum":
            return Invoke("KRL.BAS", (Lit(str(args[0].children[0]).upper()),) +
                          tuple(self.expr(a) if a is not None else None for a in args[1:]), loc)
        return Invoke(name, tuple(self.expr(a) if a is not None else None for a in args), loc)

    def s_move(self, node):
        kw = node.children[0].upper()
        self.motion(kw, [(node.children[1], _KIND_OF[kw.replace("_REL", "")], True)], node)

    def s_circ(self, node):
        kw = node.children[0].upper()
        s = "SCIRC" if kw.startswith("S") else "CIRC"
        self.motion(kw, [(node.children[1], s + "-aux", False), (node.children[2], s + "-end", True)], node)

    def motion(self, kw, ops, node):
        if not self.in_def:
            self.err("a motion must stand inside DEF … END", first_pos(node))
        if kw == "SPL" and not any(b[0] == "SPLINE" for b in self.blocks):
            self.err("SPL must stand inside SPLINE … ENDSPLINE", first_pos(node))
        base, tool = self.frame_exprs(node.children)
        if kw.endswith("_REL"):
            loc = self.here(first_pos(node))
            lowered = [self.expr(expr) if expr.data == "aggregate" else None for expr, _, _ in ops]
            why = next((w for w in map(_rel_why, lowered) if w), "")
            if not why:  # (its start decides, the analysis: P210 where it is not known)
                frame = Call("KRL.FRAME", (Name("$ROBROOT"), base))
                for target, (_, kind, chain) in zip(lowered, ops):
                    self.emit(Move(kind, target, target.loc, frame, tool, relative=True, chain=chain,
                                   rel=_rel_frame(node), load=self.with_load))
                return
            self.emit(Note(P210, f"relative motion {kw} left as written: its absolute target is known only at run "
                           f"time ({why})", loc, True))
            for expr, kind, chain in ops:
                self.emit(Move(kind, Unknown("a relative motion"), loc, relative=True, chain=chain))
            return
        for expr, kind, chain in ops:
            self.target(expr, kind, chain, base, tool)

    def target(self, expr, kind, chain, base, tool):
        lefts = []
        if expr.data == "compose":
            *lefts, expr = expr.children
        loc = self.here(first_pos(expr))
        frame = Call("KRL.FRAME", (Name("$ROBROOT"), base) + tuple(self.expr(x) for x in lefts))
        if expr.data == "aggregate":
            target = self.expr(expr)
            keys = {k for k, _ in target.items}
            joint = target.type in ("AXIS", "E6AXIS") or bool(keys & _AXIS_KEYS)
            if not joint and not keys & {"X", "Y", "Z", "A", "B", "C"} and target.type not in ("POS", "E6POS", "FRAME"):
                return  # (nothing that tells: {S 2})
            self.emit(Move(kind, target, target.loc, frame, tool, joint=joint, chain=chain, load=self.with_load))
            return
        if expr.data in ("name", "index", "member"):
            self.emit(Move(kind, self.expr(expr), loc, frame, tool, chain=chain, load=self.with_load))
            return
        value = self.expr(expr)  # (a function runs: what it does holds)
        self.emit(Eval(value, loc))
        self.emit(Note(P211, "target is computed at run time (function call or expression): left as written", loc,
                       True))
        self.emit(Move(kind, Unknown("computed at run time"), loc, relative=True, chain=chain))

    def frame_exprs(self, children):
        """(base, tool) expressions in force for a motion: $BASE/$TOOL, an open SPLINE's WITH,
        the motion's own WITH ($IPO_MODE #TCP: an external TCP, not supported)."""
        base, tool = self.spline[-1] if self.spline else (Name("$BASE"), Name("$TOOL"))
        self.with_load = self.spline_load[-1] if self.spline_load else None
        items = []
        for c in children:
            if isinstance(c, Tree) and c.data == "motion_tail":
                items += [x for x in c.children if isinstance(x, Tree) and x.data == "with_item"]
            elif isinstance(c, Tree) and c.data == "with_item":
                items.append(c)
        for it in items:
            lhs, rhs = it.children
            if lhs.data != "name":
                continue
            which = lhs.children[0].upper()
            if which == "$BASE":
                base = self.expr(rhs)
            elif which == "$TOOL":
                tool = self.expr(rhs)
            elif which == "$LOAD":  # (the payload of this motion: Move.load)
                self.with_load = self.expr(rhs)
            elif which == "$IPO_MODE":
                mode = rhs.children[0].upper() if rhs.data == "enum" else None
                if rhs.data == "fcall" and rhs.children[0].upper() == "SIPO_MODE":
                    base = Call("KRL.IPO_BASE", (self.expr(next(x for x in rhs.children[1].children if x is not None)),
                                                 base))
                elif mode == "#TCP":
                    base = Unknown("external TCP ($IPO_MODE #TCP) is not supported", P201_CODE)
        return base, tool

    # ------------------------------------------------------------ expressions
    def expr(self, node):
        d = node.data
        if d == "number":
            n = self.number(node.children[0])
            return Num(n.value, self.fi, n.start, n.end)
        if d == "signed":
            sign, inner = node.children
            if inner.data == "number":
                n = self.number(inner.children[0])
                return Num(-n.value if sign == "-" else n.value, self.fi, self.abs_pos(sign.start_pos), n.end)
            e = self.expr(inner)
            return Op("neg", (e,)) if sign == "-" else e
        if d == "name":
            n = node.children[0].upper()
            if n in ("TRUE", "FALSE"):
                return Lit(n == "TRUE")
            return Name(n, str(node.children[0]))
        if d == "aggregate":
            return self.aggregate(node)
        if d == "member":
            return Field(self.expr(node.children[0]), str(node.children[1]).upper(), str(node.children[1]))
        if d == "index":
            return Item(self.expr(node.children[0]),
                        tuple(self.expr(e) if e is not None else Unknown("an index left out") for e in node.children[1:]))
        if d == "fcall":
            name = str(node.children[0]).upper()
            args = tuple(self.expr(a) for a in node.children[1].children if a is not None)
            loc = self.here(first_pos(node))
            if name == "INV_POS" and len(args) == 1:
                return Op("inv", args)
            if name == "SBASE":
                return Call("KRL.SBASE", args, loc)
            if name == "EK":
                return Call("KRL.EK", args, loc)
            if name in ("STOOL2", "STOOL"):
                return Call("KRL.STOOL2", args, loc)
            if name == "SLOAD":  # (KSS: the LOAD_DATA of a tool number, as BAS(#TOOL, n) sets $LOAD)
                return Call("KRL.SLOAD", args, loc)
            if name in BUILTIN_FUNCTIONS:
                return Call("KRL.BUILTIN", (Lit(name),) + args, loc)
            return Call(str(node.children[0]), args, loc)
        if d == "compose":
            return Op("compose", tuple(self.expr(c) for c in node.children))
        if d == "binop":
            a, op, b = node.children
            return Op(_OPS.get(str(op).upper(), str(op)), (self.expr(a), self.expr(b)))
        if d == "compare":
            a, op, b = node.children
            return Op(str(op), (self.expr(a), self.expr(b)))
        if d == "not_":
            return Op("not", (self.expr(node.children[1]),))
        if d in ("string", "bits"):
            return Lit(str(node.children[0]))
        if d == "enum":
            return Lit(str(node.children[0]).upper())
        return Unknown("an expression the reader does not evaluate")

    def aggregate(self, node) -> Agg:
        ch = node.children
        typ = ""
        if ch and isinstance(ch[0], Token):
            typ = ch[0].upper()
            ch = ch[1:]
        items = []
        for item in ch:
            if item is None:
                continue
            key = item.children[0].upper()
            items.append((key, self.expr(item.children[-1])))
        if not hasattr(node, "meta_brace"):
            mark_brace(node, self.sh.text)
        brace = node.meta_brace if node.meta_brace >= 0 else (first_pos(node) or 0)
        kind = "pose" if {k for k, _ in items} & {"X", "Y", "Z", "A", "B", "C"} else "record"
        return Agg(kind, tuple(items), Loc(self.fi, self.ln, self.col(brace)), typ)

    # ------------------------------------------------------------ hot lines → MoveRuns
    def fill_gaps(self, parts) -> None:
        """The hot rows of this file (``parts``: fast_path's columns) into the gaps left."""
        gaps = self.gaps
        self.gaps = []
        if not gaps:
            return
        runs: dict = {}
        if parts:
            keys = np.concatenate([p["key"] for p in parts])
            order = np.argsort(keys, kind="stable")
            keys = keys[order]
            cols = {k: np.concatenate([p[k] for p in parts])[order] for k in MoveRun.COLUMNS}
            bounds = np.searchsorted(keys, np.array([g.key for g in gaps], np.int64), "left")
            lo = 0
            for g, hi in zip(gaps, bounds.tolist()):
                if hi > lo:
                    runs[id(g)] = MoveRun({k: v[lo:hi] for k, v in cols.items()},
                                          Call("KRL.FRAME", (Name("$ROBROOT"), g.base)), g.tool, g.load)
                lo = max(lo, hi)
        for key in self.file_routines:
            r = self.unit.routines[key]
            r.body = _resolved(r.body, runs)
        self.file_routines = []


def _resolved(body: list, runs: dict) -> list:
    out = []
    for s in body:
        if isinstance(s, _Gap):
            run = runs.get(id(s))
            if run is not None:
                if out and isinstance(out[-1], MoveRun) and out[-1].frame == run.frame and out[-1].tool == run.tool \
                        and out[-1].load == run.load:
                    prev = out.pop()
                    run = MoveRun({k: np.concatenate([prev.rows[k], run.rows[k]]) for k in MoveRun.COLUMNS},
                                  run.frame, run.tool, run.load)
                out.append(run)
            continue
        if isinstance(s, If):
            s.then, s.orelse = _resolved(s.then, runs), _resolved(s.orelse, runs)
        elif isinstance(s, Switch):
            s.cases = [(v, _resolved(b, runs)) for v, b in s.cases]
            if s.default is not None:
                s.default = _resolved(s.default, runs)
        elif isinstance(s, Loop):
            s.body = _resolved(s.body, runs)
        out.append(s)
    return out


from ...core.diagnostics import P201 as P201_CODE  # noqa: E402

_ = P101

"""The dataflow analysis: an abstract interpretation of the motion IR to a fixed point.

Each variable holds a value (``values``): known, with its provenance, or unknown (``Top``)
with why and where. The analysis runs the program's entries as the controller would, with
these rules, each written once here:

* at a merge of paths (after an IF/SWITCH, a loop's head, a label some GOTO jumps to)
  differing values join to unknown (``values.join``);
* a loop runs to a fixed point (its head's state the join of the entry and every pass's end);
  a FOR whose bounds are known is unrolled (each pass with its index known) while the
  analysis's budget lasts; code after an endless loop without EXIT, after GOTO, RETURN, HALT
  that no path reaches is dead (no motion there runs);
* a routine read is analysed at each call with the caller's state (call strings up to
  ``MAX_DEPTH``), its IN arguments copied in, its OUT / by-reference arguments copied back;
  a routine not read (or a recursion) makes its OUT arguments, the globals it may touch and
  the frames unknown (``Dialect.unread``);
* an asynchronous handler switched on (an INTERRUPT, a TRIGGER, a thread) may run before any
  statement: what it may write is unknown while it is on and after it is switched off;
* each executed motion is recorded (:class:`Use`) with its target's value, the frame and tool
  in force, and the motions that may have run just before it (its predecessors in execution
  order: a set, joined at merges like any value), in the pass after the fixed point;
* every number token that flows anywhere but into a motion's target (a frame, a condition,
  arithmetic, a routine not read) is recorded as read there (``Recorder.escapes``): compensating
  it would change that computation too.

The result (:class:`Recorder`) is turned into the targets by :mod:`.targets`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..ir import (
    Agg, Assign, Async, AsyncSwitch, Call, Continue, Decl, Eval, Exit, Field, Goto, Halt, Havoc, If, Invoke, Item,
    Label, Lit, Loc, Loop, Move, MoveRun, Name, Note, Num, Op, Return, Routine, Switch, Unit, Unknown,
)
from .values import (
    Arr, Mat, NotSet, Rec, Taint, Tok, Top, frame_product, join, number, same, taint, tokens_of, whole_number,
)

__all__ = ["Analysis", "Recorder", "Use", "RunUse", "State", "START"]

MAX_DEPTH = 8  # nested calls followed
MAX_PASSES = 40  # passes of a loop / of a routine's jumps before what still changes is made unknown
MAX_PREDS = 4  # predecessors of a motion kept apart; more: not known
UNROLL_BUDGET = 2_000_000  # statements run by unrolled FOR passes in one analysis
START = ("start",)  # the predecessor of a program's first motion (where the robot stands before it)


class State:
    """The analysis's state at a point: ``vars`` (scope key → value: ``("G", name)`` globals,
    ``("M", module, name)`` module data, ``("L", activation, name)`` locals), ``last`` (the
    keys of the motions that may have run just before; None: not known), ``cur`` (where the
    robot stands, for a partial aggregate's missing components: (fields, frame value) of the
    last target, None: not known), ``on`` (handlers switched on), ``stand`` (the keys of every
    motion whose command the robot may stand at here: kept where ``last`` is not — past code not
    read, which may not move, and many paths —, so that what a partial target reads at run time
    is known to be read)."""

    __slots__ = ("vars", "last", "cur", "on", "stand")

    def __init__(self, vars_: dict, last=frozenset([START]), cur=None, on=frozenset(), stand=frozenset()):
        self.vars = vars_
        self.last = last
        self.cur = cur
        self.on = on
        self.stand = stand

    def copy(self) -> "State":
        return State(dict(self.vars), self.last, self.cur, self.on, self.stand)

    def __eq__(self, other):
        return isinstance(other, State) and self.last == other.last and self.on == other.on \
            and self.stand == other.stand and _same_cur(self.cur, other.cur) and self.vars == other.vars


def _same_cur(a, b) -> bool:
    if a is None or b is None:
        return a is b
    return a[0] == b[0] and same(a[1], b[1]) and same(a[2], b[2])


def _with_tool(cur, tool):
    """Where the robot stands (position, frame, tool) as a target with ``tool`` reads it: None
    when the tool changed since (the controller's position is the new tool's point, the flange
    where the old tool left it: not the numbers commanded)."""
    return cur if cur is not None and same(cur[2], tool) else None


def join_states(a: State | None, b: State | None, why: str, loc: Loc | None) -> State | None:
    """One state for two paths (None: a path that does not reach here)."""
    if a is None:
        return b
    if b is None or a is b:
        return a
    out = {}
    missing = Top(why, loc)
    for k in a.vars.keys() | b.vars.keys():
        x, y = a.vars.get(k, missing), b.vars.get(k, missing)
        out[k] = x if x is y else join(x, y, why, loc)
    if a.last is None or b.last is None:
        last = None
    else:
        last = a.last | b.last
        if len(last) > MAX_PREDS:
            last = None
    cur = a.cur if _same_cur(a.cur, b.cur) else None
    return State(out, last, cur, a.on | b.on, a.stand | b.stand)


@dataclass
class Use:
    """One executed motion: ``key`` (statement, call path), the statement, the value of its
    target (after a partial aggregate's missing components were taken from where the robot
    stands: ``filled``), the frame (``Mat`` robot base ← target coordinates, or ``Top``) and the
    tool (six numbers, None: the model's, or ``Top``) in force, its predecessors' keys (None:
    not known), and the target as written (``what``: ``XP1``, ``P[3]``) for messages."""

    key: tuple
    stmt: Move
    target: object
    filled: tuple
    frame: object
    tool: object
    preds: frozenset | None
    what: str
    config: object = None
    ext: object = None
    stand: frozenset = frozenset()  # (State.stand before it)
    load: object = None  # the payload in force (values.Load; None: not set; Top: not known)
    # a relative motion's (``Move.relative``): the key of the motion it is relative to (its
    # target then in ``frame``: that motion's pose × the move), or why its start is not known (str)
    rel: object = None


@dataclass
class RunUse:
    """One execution of a MoveRun: its frame and tool, the first row's predecessors and where
    the robot stands before it (``cur``, for the run's partial aggregates)."""

    key: tuple
    run: MoveRun
    frame: object
    tool: object
    preds: frozenset | None
    cur: object
    stand: frozenset = frozenset()  # (State.stand before it)
    load: object = None  # the payload in force (as Use.load)


@dataclass
class Recorder:
    """What the recording pass saw: the motions in the order they ran (``uses``: Use and
    RunUse), the tokens read by something other than a motion's target (``escapes``: token →
    (Loc, why) of the first such read), and the located findings (``notes``: (code, message,
    Loc, left) once each)."""

    uses: list = field(default_factory=list)
    escapes: dict = field(default_factory=dict)
    notes: dict = field(default_factory=dict)

    def escape(self, tokens, loc: Loc | None, why: str) -> None:
        for t in tokens:
            if t not in self.escapes:
                self.escapes[t] = (loc, why)

    def note(self, code: str, message: str, loc: Loc, left: bool = True) -> None:
        self.notes.setdefault((code, loc, message), left)


class _Jump(Exception):
    pass


@dataclass
class _LoopFrame:
    breaks: list = field(default_factory=list)
    continues: list = field(default_factory=list)


class _Activation:
    """One run of a routine: its locals' scope, the path of its motions' keys (call sites and
    unrolled passes), its returns, jumps and loops."""

    def __init__(self, routine: Routine | None, scope: tuple, module: str):
        self.routine = routine
        self.scope = scope  # locals are ("L", scope, name)
        self.path = scope  # motions' keys: the scope + unrolled passes
        self.module = module
        self.returns: list = []  # (state, value)
        self.labels_in: dict = {}  # label → state of the jumps to it (the pass before)
        self.jumps: dict = {}  # label → state of the jumps to it (this pass)
        self.loops: list = []


def _has_goto(body) -> bool:
    from ..ir import walk

    return any(isinstance(s, Goto) for s in walk(body))


class Analysis:
    """The analysis of one Unit with the builtins of its dialect (``dialect``: a
    :class:`.builtins.Dialect`)."""

    def __init__(self, unit: Unit, dialect):
        self.unit = unit
        self.dialect = dialect
        self.rec: Recorder | None = None
        self.stack: tuple = ()
        self.loc: Loc | None = None
        self.act: _Activation | None = None
        self.budget = UNROLL_BUDGET
        self.types: dict = {}  # scope key → (type, is array)
        self.written_names: dict = {}  # scope key → the name as declared (messages)
        self.gotos: dict = {}  # routine name → has a Goto
        self.handlers: dict = {}  # handler id → (Async statement, write set, why)
        self.reached: set = set()  # routines analysed
        self.rel_aux: dict = {}  # a CIRC_REL's auxiliary point's key → the key of the motion both are relative to

    # ------------------------------------------------------------------ the whole program
    def run(self) -> Recorder:
        rec = Recorder()
        self.rec = rec
        start = self.declare_data()
        entries = list(self.unit.entries)
        done = set()
        while True:
            for name in entries:
                if name in done:
                    continue
                done.add(name)
                entry = start.copy()
                entry.last = frozenset([START])
                self.start(name, entry)
            rest = [n for n in self.unit.routines if n not in self.reached and n not in done]
            if not rest:
                break
            entries = rest  # routines no entry reaches: the controller may start them too
        return rec

    # ------------------------------------------------------------------ activations
    # How a program starts and a routine is activated, for the analysis and the interpreter
    # alike (``programs.interpreter`` inherits these and ``call``): the scopes ``("data",)``,
    # ``("prologue", entry)``, ``(entry,)`` and a call's ``path + (id(site),)``, the module
    # a routine's names resolve in, the call stack. What differs is how statements run: each
    # engine's ``straight`` (the data, the prologue) and ``body`` (a routine's statements).
    def declare_data(self) -> State:
        """The state the entries start from: the dialect's initial variables, then the unit's
        data run module by module (activation ``("data",)``, in that module)."""
        st = State(dict(self.dialect.initial(self.unit)))
        top = _Activation(None, ("data",), "")
        self.act = top
        for module, stmts in self.unit.data:
            top.module = module
            st = self.straight(stmts, st, ("data", module))
        for key in self.dialect.runtime:
            if key in st.vars:
                st.vars[key] = self.run_time(key, st.vars[key])
        return st

    def run_time(self, key: tuple, value):
        """What variable ``key`` holds when code the entry does not run may change it at any moment
        (``Dialect.runtime``): not known, for that reason (P233); it may still hold ``value``
        (its tokens stay with it). The interpreter keeps ``value`` (a run where that code did not run)."""
        return self.dialect.runtime[key].carrying(value)

    def start(self, name: str, st: State):
        """The controller starts entry ``name`` from ``st``: the unit's prologue (activation
        ``("prologue", name)``, in the entry's module), the dialect's rule for an entry
        (``Dialect.enter``), then the routine in scope ``(name,)``: (state after it, value)."""
        routine = self.unit.routines[name]
        self.act = _Activation(None, ("prologue", name), routine.module)
        st = self.straight(self.unit.prologue, st, None)
        self.dialect.enter(self, st, routine)
        return self.routine(routine, st, (name,))

    def straight(self, stmts, st: State, where: tuple | None) -> State:
        """Statements outside any routine (``where`` ("data", module): that module's data;
        None: the prologue): the state after them (where no path gets past them: the state
        before them)."""
        return self.block(stmts, st) or st

    def routine(self, routine: Routine, st: State, scope: tuple):
        """Run ``routine`` from ``st`` (its parameters already bound in ``st`` under ``scope``,
        ``call``) in an activation of its own: (state after it, return value)."""
        self.reached.add(routine.name)
        saved = self.act
        act = _Activation(routine, scope, routine.module)
        self.act = act
        self.stack = self.stack + (routine.name,)
        try:
            return self.body(routine, st, act)
        finally:
            self.stack = self.stack[:-1]
            self.act = saved

    def body(self, routine: Routine, st: State, act: _Activation):
        """A routine's statements from ``st`` in activation ``act``: (state after it, return
        value), its returns joined (the analysis: every path; the interpreter: the one run)."""
        has_goto = self.gotos.get(routine.name)
        if has_goto is None:
            has_goto = self.gotos[routine.name] = _has_goto(routine.body)
        if not has_goto:
            out = self.block(routine.body, st)
        else:
            out = self._with_jumps(routine.body, st, act)
        value = None
        for s, v in act.returns:
            out = join_states(out, s, f"{routine.name} returns from several places", routine.loc)
            value = v if value is None else join(value, v, f"{routine.name} returns different values", routine.loc)
        return out, value

    def _with_jumps(self, body, st: State, act: _Activation):
        """A body with GOTOs: passes until the state at every label is the join of all the
        jumps to it (a jump back is a loop); the last pass records."""
        rec, self.rec = self.rec, None
        try:
            for _ in range(MAX_PASSES):
                act.jumps, act.returns, act.loops = {}, [], []
                self.block(body, st.copy())
                changed = False
                for name, s in act.jumps.items():
                    old = act.labels_in.get(name)
                    new = join_states(old, s, f"a GOTO {name} jumps here with others", s and None)
                    if old is None or not (new == old):
                        act.labels_in[name] = new
                        changed = True
                if not changed:
                    break
            else:
                for name, s in act.labels_in.items():
                    act.labels_in[name] = self._widen(s, f"the jumps to {name} do not settle")
        finally:
            self.rec = rec
        act.jumps, act.returns, act.loops = {}, [], []
        return self.block(body, st)

    # ------------------------------------------------------------------ statements
    def block(self, stmts, st: State | None) -> State | None:
        for s in stmts:
            if st is None and not isinstance(s, Label):
                continue  # dead code: no path reaches it
            st = self.stmt(s, st)
        return st

    def stmt(self, s, st: State | None) -> State | None:
        self.loc = getattr(s, "loc", self.loc)
        kind = type(s)
        if kind is MoveRun:
            return self.move_run(s, st)
        if kind is Move:
            return self.move(s, st)
        if kind is Assign:
            value = self.eval(s.value, st)
            self.write(s.target, value, st, literal=isinstance(s.value, Agg))
            return st
        if kind is Invoke:
            return self.invoke(s, st)
        if kind is Eval:
            self.consume(self.eval(s.expr, st), "a condition")
            return st
        if kind is Decl:
            return self.decl(s, st)
        if kind is If:
            return self.if_(s, st)
        if kind is Loop:
            return self.loop(s, st)
        if kind is Switch:
            return self.switch(s, st)
        if kind is Label:
            act = self.act
            # (the jumps' states are copied: the statements after the label change the state they go on with)
            jumped, before = act.jumps.get(s.name), act.labels_in.get(s.name)
            st = join_states(st, jumped.copy() if jumped is not None else None,
                             f"a GOTO {s.name} jumps to line {s.loc.line} with others", s.loc)
            st = join_states(st, before.copy() if before is not None else None,
                             f"a GOTO {s.name} jumps to line {s.loc.line} with others", s.loc)
            if st is not None and (s.name in act.jumps or s.name in act.labels_in):
                st = st.copy()  # (never the jumps' own states: what runs after the label changes it)
            return st
        if kind is Goto:
            if s.cond is not None:
                c = self.condition(s.cond, st)
                if c is False:
                    return st
            act = self.act
            act.jumps[s.name] = join_states(act.jumps.get(s.name), st.copy(),
                                            f"a GOTO {s.name} jumps to it with others", s.loc)
            return None if s.cond is None or c is True else st
        if kind is Return:
            value = self.eval(s.value, st) if s.value is not None else None
            self.act.returns.append((st, value))
            return None
        if kind is Halt:
            return None
        if kind is Exit:
            if self.act.loops:
                self.act.loops[-1].breaks.append(st)
            else:
                self.act.returns.append((st, None))
            return None
        if kind is Continue:
            if self.act.loops:
                self.act.loops[-1].continues.append(st)
            return None
        if kind is Havoc:
            return self.havoc(st, s.names, s.why, s.loc)
        if kind is Note:
            if self.rec is not None:
                self.rec.note(s.code, s.message, s.loc, s.left)
            return st
        if kind is Async:
            return self.async_decl(s, st)
        if kind is AsyncSwitch:
            return self.async_switch(s, st)
        raise TypeError(f"not an IR statement: {s!r}")

    def decl(self, s: Decl, st: State) -> State:
        act = self.act
        if s.scope == "global":
            key = ("G", s.name)
        elif s.scope == "module" or act.routine is None:
            key = ("M", act.module, s.name)
        else:
            key = ("L", act.scope, s.name)
        self.types[key] = (s.type, s.dims is not None)
        if key[0] != "L":
            self.written_names[key] = s.written or s.name
        if s.init is not None:
            value = self.eval(s.init, st)
            if isinstance(value, Tok) and self.dialect.scalar(s.type):
                value = taint(value.value, value)
            if isinstance(value, Rec) and not value.type:
                value = Rec(s.type, value.fields, value.loc)
        elif key in st.vars and act.routine is not None and key[0] == "L":
            return st  # (a parameter declared again in its routine keeps the argument: KRL)
        else:
            value = self.dialect.uninitialised(s)
        st.vars[key] = value
        return st

    def if_(self, s: If, st: State) -> State | None:
        c = self.condition(s.cond, st)
        if c is True:
            return self.block(s.then, st)
        if c is False:
            return self.block(s.orelse, st)
        a = self.block(s.then, st.copy())
        b = self.block(s.orelse, st)
        return join_states(a, b, f"the branches of the IF at line {s.loc.line} leave it different", s.loc)

    def switch(self, s: Switch, st: State) -> State | None:
        subject = self.eval(s.subject, st)
        self.consume(subject, "a SWITCH subject")
        out, whole = None, s.default is not None
        why = f"the branches of the SWITCH at line {s.loc.line} leave it different"
        for values, body in s.cases:
            out = join_states(out, self.block(body, st.copy()), why, s.loc)
        if s.default is not None:
            out = join_states(out, self.block(s.default, st.copy()), why, s.loc)
        if not whole:
            out = join_states(out, st, why, s.loc)
        return out

    def condition(self, expr, st: State):
        """A condition's value: True / False where known, else None (both ways)."""
        v = self.eval(expr, st)
        self.consume(v, "a condition")
        return v if isinstance(v, bool) else None

    # ------------------------------------------------------------------ loops
    def loop(self, s: Loop, st: State) -> State | None:
        if s.kind == "for":
            start, stop, step = (self.eval(e, st) if e is not None else 1 for e in (s.start, s.stop, s.step))
            for v in (start, stop, step):
                self.consume(v, "a FOR bound")
            lo, hi, by = number(start), number(stop), number(step)
            finite = None not in (lo, hi, by) and all(math.isfinite(x) for x in (lo, hi, by))
            if finite and by != 0 and lo == int(lo) and hi == int(hi) and by == int(by):
                count = max(0, (int(hi) - int(lo)) // int(by) + 1)
                cost = count * max(1, _size(s.body))
                if cost <= self.budget:
                    self.budget -= cost
                    return self._unrolled(s, st, int(lo), int(hi), int(by))
            head = self._fixpoint(s, st, Top(f"the FOR at line {s.loc.line} has bounds known only at run time",
                                             s.loc))
        else:
            head = self._fixpoint(s, st, None)
        return head

    def _unrolled(self, s: Loop, st: State, lo: int, hi: int, by: int) -> State | None:
        act = self.act
        frame = _LoopFrame()
        act.loops.append(frame)
        path = act.path
        out = None
        try:
            i = lo
            while (by > 0 and i <= hi) or (by < 0 and i >= hi):
                if st is None:
                    break
                self.write(Name(s.var), i, st)
                act.path = path + ((id(s), i),)
                st = self.block(s.body, st)
                for c in frame.continues:
                    st = join_states(st, c, f"the FOR at line {s.loc.line} continues from several places", s.loc)
                frame.continues = []
                i += by
            out = st
            for b in frame.breaks:
                out = join_states(out, b, f"the FOR at line {s.loc.line} may end after any pass", s.loc)
        finally:
            act.path = path
            act.loops.pop()
        return out

    def _fixpoint(self, s: Loop, st: State, var_value) -> State | None:
        """A loop whose passes are not unrolled: its head's state to a fixed point, then the
        recording pass; the state after it."""
        why = f"the body of the {s.kind.upper()} at line {s.loc.line} changes it between passes"
        act = self.act
        if var_value is not None:
            self.write(Name(s.var), var_value, st)
        head = st.copy()
        rec, self.rec = self.rec, None
        try:
            # a WHILE whose condition holds where the loop is entered runs at least once: it ends
            # after a pass, never from the entry
            entered = s.kind == "while" and self._always(s.cond, st)
            for _ in range(MAX_PASSES):
                end = self._pass(s, head.copy(), act)
                new = join_states(head, end[0], why, s.loc)
                if var_value is not None and new is not None:
                    self.write(Name(s.var), var_value, new)
                if new == head:
                    break
                head = new
            else:
                head = self._widen(head, why)
        finally:
            self.rec = rec
        body_end, breaks = self._pass(s, head.copy(), act)
        exits = list(breaks)
        if s.kind in ("for", "while"):
            if s.kind == "while" and self._always(s.cond, head):
                pass  # (it never ends at its head)
            elif entered:
                exits.append(body_end)  # (the condition fails after a pass)
            else:
                exits.append(head)  # the condition fails at the head (before any pass, or after one)
        elif s.kind == "repeat":
            exits.append(body_end)
        out = None
        for e in exits:
            out = join_states(out, e, f"the {s.kind.upper()} at line {s.loc.line} may end after any pass", s.loc)
        return out

    def _pass(self, s: Loop, st: State, act: _Activation):
        """One pass of the body: (state at its end, continues joined in; the breaks' states)."""
        frame = _LoopFrame()
        act.loops.append(frame)
        try:
            if s.kind == "while":
                c = self.condition(s.cond, st)
                if c is False:
                    return None, []
            end = self.block(s.body, st)
            for c in frame.continues:
                end = join_states(end, c, f"the {s.kind.upper()} at line {s.loc.line} continues from several "
                                  "places", s.loc)
            if s.kind == "repeat" and end is not None:
                c = self.condition(s.cond, end)
                if c is True:
                    return None, frame.breaks + [end]
            return end, frame.breaks
        finally:
            act.loops.pop()

    def _always(self, cond, st) -> bool:
        v = self.eval(cond, st) if cond is not None else True
        return v is True

    def _widen(self, st: State | None, why: str) -> State | None:
        """What still changes after MAX_PASSES made unknown (never reached with the analysis's
        flat values; a guard)."""
        if st is None:
            return None
        out = st.copy()
        for k, v in st.vars.items():
            if isinstance(v, (Arr, Rec)):
                out.vars[k] = Top(why, self.loc).carrying(v)
        out.last, out.cur = None, None
        return out

    # ------------------------------------------------------------------ motions
    def move(self, s: Move, st: State) -> State:
        act = self.act
        key = (id(s), act.path)
        if s.relative and isinstance(s.target, Agg):
            return self.move_relative(s, st, key)
        if s.joint or s.relative:
            # (an axis target: its value, where the robot stands after it — the arm configuration
            # a Cartesian target after it keeps, targets.build; a relative one: known at run time)
            target = Top("a relative motion: its target is known only at run time", s.loc)
            if not s.relative:
                target = self.eval(s.target, st)
            if self.rec is not None:
                self.rec.uses.append(Use(key, s, target, (), None, None, st.last, "", stand=st.stand))
            # (a relative motion's end: where the robot stood plus the move)
            st.stand = st.stand | {key} if s.relative else frozenset([key])
            st.last, st.cur = frozenset([key]), None
            return st
        target = self.eval(s.target, st)
        filled = ()
        frame = self.frame_value(s.frame, st)
        tool = self.tool_value(s.tool, st)
        if isinstance(s.target, Agg) and isinstance(target, Rec):
            target, filled = self.dialect.fill(target, _with_tool(st.cur, tool), frame)
        config = self.eval(s.config, st) if s.config is not None else None
        ext = self.eval(s.ext, st) if s.ext is not None else None
        held = _unknown_tokens(target)
        if held and self.rec is not None:  # (a target not known here that is a point's copy on some path)
            self.rec.escape(held, self.loc, f"a target that is {_written(s.target) or 'a value'} on some path only")
        if self.rec is not None:
            self.rec.uses.append(Use(key, s, target, filled, frame, tool, st.last, _written(s.target), config, ext,
                                     st.stand, self.load_value(s.load, st)))
        st.last = frozenset([key])
        if s.chain:
            st.stand = frozenset([key])
        if s.chain:
            st.cur = (self.dialect.position(target), frame, tool) if isinstance(target, Rec) else None
        return st

    def move_relative(self, s: Move, st: State, key) -> State:
        """A relative motion whose move is X/Y/Z numbers (``Move.rel``): its absolute target is the
        start — the pose of the one motion that runs just before it on every path, in the same
        frame with the same tool — moved by them along the base's (``rel`` "base") or the tool's
        axes ("tool"): recorded with the frame ``start × move`` (so its numbers are the move's);
        where the robot stands after it is known. Otherwise why not (its target left, P210)."""
        frame = self.frame_value(s.frame, st)
        tool = self.tool_value(s.tool, st)
        move = self.eval(s.target, st)
        start, why = self._start_of(st, frame, tool)
        if why is None and not isinstance(move, Rec):
            why = "its move is not known here"
        filled, fields = [], {}
        if why is None:
            here = dict(st.cur[0])
            names = [k for k, _ in st.cur[0]]
            start_pose = [here[k] for k in names]
            local = frame_matrix(start_pose[:3], None if s.rel == "base" else start_pose[3:], self.dialect.form)
            for k in ("X", "Y", "Z"):
                v = move.fields.get(k)
                if v is None:
                    v = 0.0
                    filled.append(k)
                elif number(v) is None:
                    why = f"its {k} is not known here"
                fields[k] = v
            if s.rel == "base":  # (the start's orientation: the move does not turn the tool)
                fields.update({k: here[k] for k in names[3:]})
            else:
                fields.update(zip(names[3:], identity_orientation(self.dialect.form)))
        if why is not None:
            if self.rec is not None:
                self.rec.uses.append(Use(key, s, Top(why, s.loc), (), frame, tool, st.last, "", stand=st.stand,
                                         rel=why))
            st.stand = st.stand | {key}
            st.last, st.cur = frozenset([key]), None
            return st
        target = Rec(getattr(move, "type", ""), fields, move.loc)
        moved = frame_product(frame, Mat(local), frame.label)
        if self.rec is not None:
            self.rec.uses.append(Use(key, s, target, tuple(filled), moved, tool, st.last, "", stand=st.stand,
                                     rel=start, load=self.load_value(s.load, st)))
        st.last = frozenset([key])
        if s.chain:
            end = local @ _np.r_[[number(fields[k]) for k in ("X", "Y", "Z")], 1.0]
            st.cur = (tuple((k, float(end["XYZ".index(k)]) if k in ("X", "Y", "Z") else v) for k, v in st.cur[0]),
                      frame, tool)
            st.stand = frozenset([key])
        else:  # (a CIRC_REL's auxiliary point: its end is relative to the same start)
            self.rel_aux[key] = start
        return st

    def _start_of(self, st: State, frame, tool) -> tuple:
        """(the key of the motion a relative motion starts from, None), or (None, why it is not known)."""
        last = st.last
        if not last or len(last) != 1:
            return None, ("it is reached from several motions" if last else
                          "where the robot stands before it is not known")
        (start,) = last
        start = self.rel_aux.get(start, start)
        if start == START:
            return None, "it is the program's first motion"
        cur = st.cur
        if cur is None:
            return None, "where the robot stands before it is not known: after an axis motion, a target not known " \
                "or a relative motion whose start is not known"
        if not isinstance(frame, Mat):
            return None, "its frame is not known"
        if not same(cur[1], frame):
            return None, "the frame changed since the motion before it"
        if not same(cur[2], tool):
            return None, "the tool changed since the motion before it"
        if any(v is None or not math.isfinite(v) for _, v in cur[0]):
            return None, "where the robot stands before it is not fully known"
        return start, None

    def move_run(self, s: MoveRun, st: State) -> State:
        key = (id(s), self.act.path)
        if len(s):  # (where the analysis is: the run's first motion)
            rows = s.rows
            self.loc = Loc(int(rows["file"][0]), int(rows["line"][0]), int(rows["col"][0]))
        frame = self.frame_value(s.frame, st)
        tool = self.tool_value(s.tool, st)
        if self.rec is not None:
            self.rec.uses.append(RunUse(key, s, frame, tool, st.last, st.cur, st.stand, self.load_value(s.load, st)))
        st.last = frozenset([key])
        if len(s):
            st.stand = frozenset([key])
        st.cur = (*self.dialect.run_position(s, _with_tool(st.cur, tool), frame), tool)
        return st

    def frame_value(self, expr, st: State):
        if expr is None:
            return Mat(_EYE, "")
        return self.dialect.frame(self, self.eval(expr, st))

    def load_value(self, expr, st: State):
        """The payload at a motion (``Dialect.load``): its own ``load`` expression, else the
        dialect's ``load_var`` in force (None where the dialect has none)."""
        if expr is None:
            name = self.dialect.load_var
            if name is None:
                return None
            key, value = self.lookup(name, st)
            if key is None:
                return None
        else:
            value = self.eval(expr, st)
        return self.dialect.load(self, value)

    def tool_value(self, expr, st: State):
        if expr is None:
            return None
        return self.dialect.tool(self, self.eval(expr, st))

    # ------------------------------------------------------------------ calls
    def invoke(self, s: Invoke, st: State) -> State | None:
        name = s.name
        proc = self.dialect.procedure(name)
        if proc is not None:
            return proc(self, st, s.args, s.loc)
        routine = self.unit.routines.get(self.dialect.routine_key(self, name))
        if routine is None:
            return self.dialect.unread(self, st, s, None)
        return self.call(routine, s.args, st, s)[0]

    def call(self, routine: Routine, args, st: State, site) -> tuple:
        """(state after the call, its value) of ``routine(args)`` at ``site`` (an Invoke or a
        Call expression) — the one binding of arguments to parameters, the interpreter's too.
        ``args`` stand in their parameters' places (a lowering puts keyword and optional
        arguments there, None where one is left out: its ``default`` evaluated at the call, else
        unknown); each is evaluated in the caller (copy-in); a parameter not passed "in" whose
        argument is a variable, a field or an element is copied back to it after the call; the
        callee's locals (scope ``path + (id(site),)``) are dropped."""
        loc = site.loc
        if len(self.stack) >= MAX_DEPTH or routine.name in self.stack:
            why = f"{routine.name}() called at line {loc.line if loc else 0} recurses" if routine.name in self.stack \
                else f"{routine.name}() called at line {loc.line if loc else 0} is nested too deep"
            st = self.dialect.unread(self, st, site, why)
            return st, Top(why, loc)
        scope = self.act.path + (id(site),)
        bound, back = {}, []
        for k, p in enumerate(routine.params):
            arg = args[k] if k < len(args) else None
            if arg is None and p.default is not None:
                value = self.eval(p.default, st)
            elif arg is None:
                value = Top(f"parameter {p.name} of {routine.name}() is not passed", loc)
            else:
                value = self.eval(arg, st)
                if p.mode != "in" and isinstance(arg, (Name, Field, Item)):
                    back.append((p.name, arg))
            bound[("L", scope, p.name)] = value
        st.vars.update(bound)
        before = {k: v for k, v in st.vars.items() if k[0] == "G"}
        out, value = self.routine(routine, st, scope)
        if out is None:
            return None, value
        self._relocate(before, out, getattr(site, "name", routine.name), loc)
        for name, arg in back:
            v = out.vars.get(("L", scope, name))
            if v is not None:
                self.write(arg, v, out)
        for k in [k for k in out.vars if k[0] == "L" and k[1] == scope]:
            del out.vars[k]
        return out, value

    def _relocate(self, before: dict, out: State, name: str, loc: Loc | None) -> None:
        """Globals a callee left unknown say so at the call (``… in MoveSettings() called at
        line 4``): where the caller's reader looks."""
        if loc is None:
            return
        for k, v in out.vars.items():
            if k[0] == "G" and isinstance(v, Top) and not (before.get(k) == v) and v.loc != loc:
                out.vars[k] = Top(f"{v.why} in {name}() called at line {loc.line}", loc, v.code)

    def havoc(self, st: State, names, why: str, loc: Loc | None) -> State:
        """Code not seen runs here: ``names`` (None: every global and frame the dialect says such
        code may touch) get what ``unseen`` says, and where the robot stands is not known (the
        interpreter's too: it gives the world's values)."""
        top = Top(why, loc)
        keys = self.dialect.touched(self, st, names)
        for k in keys:
            st.vars[k] = self.unseen(st.vars.get(k), top)
        st.last, st.cur = None, None
        return st

    def unseen(self, v, top: Top):
        """What a variable holding ``v`` holds after code not read ran: unknown for ``top``'s
        reason (it may still hold what it held: its tokens stay with the unknown)."""
        return top.carrying(v) if not isinstance(v, Arr) else Arr({}, top.carrying(v), v.type)

    # ------------------------------------------------------------------ handlers
    def async_decl(self, s: Async, st: State) -> State:
        """A handler declared: what it writes is unknown while it is on (``_pin``). A handler
        whose code is not read is taken as a call at its declaration (``Dialect.unread_handler``:
        the frames unknown from here until the program sets them again), unless the dialect
        knows it sets none."""
        action = s.action
        if isinstance(action, Invoke) and self.dialect.procedure(action.name) is None and \
                self.unit.routines.get(self.dialect.routine_key(self, action.name)) is None:
            return self.dialect.unread_handler(self, st, s)
        writes = self.dialect.writes(self, action, st)
        why = f"may be set by the {s.what} declared at line {s.loc.line}"
        if isinstance(action, Invoke):
            why += f" ({action.name}())"
        self.handlers[id(s)] = (s, writes, why)
        if self.rec is not None:
            self.dialect.handler_reached(self, s)
        if s.on:
            st.on = st.on | {id(s)}
            st = self._pin(st)
        return st

    def async_switch(self, s: AsyncSwitch, st: State) -> State:
        """Handlers switched on or off: ``number`` None all of them; a number known only at run
        time switches every one on (any may be), and none off (which is not known)."""
        n = None
        if s.number is not None:
            n = whole_number(self.eval(s.number, st))
            if n is None and not s.on:
                return st
        chosen = [h for h, (decl, _, _) in self.handlers.items()
                  if n is None or decl.number is None or whole_number(self.eval(decl.number, st)) in (n, None)]
        if s.on:
            st.on = st.on | set(chosen)
            return self._pin(st)
        off = [h for h in chosen if h in st.on]
        st.on = st.on - set(off)
        for h in off:  # it may have run: what it sets stays unknown until set again
            decl, writes, why = self.handlers[h]
            for k in writes:
                st.vars[k] = Top(f"{_key_name(k)} {why}", decl.loc, self.dialect.handler_code(k))
        return st

    def _pin(self, st: State) -> State:
        for h in st.on:
            decl, writes, why = self.handlers[h]
            for k in writes:
                st.vars[k] = Top(f"{_key_name(k)} {why}", decl.loc, self.dialect.handler_code(k))
        return st

    # ------------------------------------------------------------------ values
    def lookup(self, name: str, st: State):
        """(scope key, value) of a variable read here; key None: not declared anywhere."""
        act = self.act
        for key in (("L", act.scope, name), ("M", act.module, name), ("G", name)):
            if key in st.vars:
                v = st.vars[key]
                if st.on:
                    for h in st.on:
                        decl, writes, why = self.handlers[h]
                        if key in writes:  # (a frame: at the handler; another variable: where it is read)
                            at = decl.loc if name in self.dialect.frame_names or name == self.dialect.load_var \
                                else self.loc
                            return key, Top(f"{name} {why}", at, self.dialect.handler_code(key))
                return key, v
        return None, None

    def eval(self, e, st: State):
        kind = type(e)
        if kind is Num:
            return Tok(e.value, (e.file, e.start, e.end))
        if kind is Lit:
            return e.value
        if kind is Name:
            key, v = self.lookup(e.name, st)
            if key is None:
                return self.dialect.undeclared(self, e.name)
            return v
        if kind is Agg:
            return Rec(e.type.upper() if e.type else "", {k: self.eval(v, st) for k, v in e.items}, e.loc)
        if kind is Field:
            base = self.eval(e.base, st)
            return self.dialect.field(self, base, e.name)
        if kind is Item:
            base = self.eval(e.base, st)
            key = self.index(e.index, st)
            if isinstance(base, Arr):
                if isinstance(key, Top):  # (any element: it reads every element's tokens)
                    return Top(f"{_written(e.base)}[…] with a run-time index ({key.why})", self.loc).carrying(base)
                return base.get(key)
            if isinstance(base, Top):
                return base
            return Top(f"{_written(e)} is not an array", self.loc)
        if kind is Op:
            # (a number written in an operation is a constant: ``XP1.Z + 150`` keeps XP1's token)
            return self.dialect.operate(self, e.op, [a.value if type(a) is Num else self.eval(a, st) for a in e.args])
        if kind is Call:
            fn = self.dialect.function(e.name)
            if fn is not None:
                return fn(self, st, [self.eval(a, st) for a in e.args], e)
            routine = self.unit.routines.get(self.dialect.routine_key(self, e.name))
            if routine is not None:
                out, value = self.call(routine, e.args, st, e)
                if out is not None and out is not st:
                    st.vars, st.last, st.cur, st.on, st.stand = out.vars, out.last, out.cur, out.on, out.stand
                return value if value is not None else Top(f"the value of {e.name}()", e.loc)
            self.dialect.unread(self, st, e, None)
            return Top(f"{e.name}() is not in the files read", e.loc)
        if kind is Unknown:
            return Top(e.why, self.loc, e.code)
        if e is None:
            return None
        raise TypeError(f"not an IR expression: {e!r}")

    def index(self, index, st: State):
        """An index tuple of whole numbers, or Top."""
        out = []
        for x in index:
            v = self.eval(x, st)
            self.consume(v, "an index")
            n = whole_number(v)
            if n is None:
                return Top(v.why if isinstance(v, Top) else "an index that is not a whole number", self.loc)
            out.append(n)
        return tuple(out)

    def consume(self, value, why: str) -> None:
        """``value`` is read by something other than a motion's target: its tokens escape."""
        if self.rec is not None and not isinstance(value, (bool, str, type(None))) \
                and not (isinstance(value, (int, float)) and not isinstance(value, (Tok, Taint))):
            toks = tokens_of(value)
            if toks:
                self.rec.escape(toks, self.loc, why)

    def write(self, target, value, st: State, literal: bool = False) -> None:
        """``target = value`` (``literal``: an aggregate as written: a record it is assigned to
        keeps the components it does not name)."""
        kind = type(target)
        if kind is Name:
            key, old = self.lookup(target.name, st)
            if key is None:
                key = self.dialect.implicit(self, target.name)
            if literal and isinstance(old, Rec) and isinstance(value, Rec):
                fields = dict(old.fields)
                fields.update(value.fields)
                value = Rec(value.type or old.type, fields, value.loc)
            elif isinstance(value, Rec) and not value.type and key in self.types:
                value = Rec(self.types[key][0], value.fields, value.loc)
            elif isinstance(value, Tok) and self.dialect.scalar(self.types.get(key, ("", False))[0]):
                value = taint(value.value, value)  # (a scalar variable's number: not a target's own token)
            if key in self.dialect.runtime:
                value = self.run_time(key, value)
            st.vars[key] = value
            return
        if kind is Field:
            base = self.eval(target.base, st)
            if isinstance(base, Mat):  # (a frame the analysis computed: its components)
                base = self.dialect.record_of(base)
            if isinstance(base, Rec):
                if literal and isinstance(value, Rec) and isinstance(base.get(target.name), Rec):
                    merged = dict(base.get(target.name).fields)
                    merged.update(value.fields)
                    value = Rec(value.type or base.get(target.name).type, merged, value.loc)
                new = base.with_field(target.name, value)
            elif isinstance(base, Top):
                new = base
            elif isinstance(base, NotSet):  # (a payload the program has not set: one component of it known)
                new = Top(f"{_written(target.base)}.{target.name} is set where {_written(target.base)} is not: the "
                          "rest of it is the controller's", self.loc)
            else:
                new = Top(f"{_written(target.base)} is not a record", self.loc)
            self.write(target.base, new, st)
            return
        if kind is Item:
            base = self.eval(target.base, st)
            key = self.index(target.index, st)
            if isinstance(base, Arr):
                if isinstance(key, Top):
                    why = f"{_written(target.base)}[…] is assigned with a run-time index at line {self.loc.line}"
                    new = Arr({}, Top(why, self.loc).carrying(base, value), base.type)
                else:
                    old = base.get(key)
                    if literal and isinstance(old, Rec) and isinstance(value, Rec):
                        fields = dict(old.fields)
                        fields.update(value.fields)
                        value = Rec(value.type or old.type, fields, value.loc)
                    new = base.with_elem(key, value)
            elif isinstance(base, Top) and isinstance(key, tuple) and self.dialect.implicit_arrays:
                new = Arr({key: value}, base, "")
            else:
                new = base if isinstance(base, Top) else Top(f"{_written(target.base)} is not an array", self.loc)
            self.write(target.base, new, st)
            return
        raise TypeError(f"not an assignable expression: {target!r}")


def _unknown_tokens(v, out: set | None = None) -> set:
    """The tokens the unknown parts of a value hold (``Top.tokens``: a join's)."""
    out = set() if out is None else out
    if isinstance(v, Top):
        out |= v.tokens
    elif isinstance(v, Rec):
        for x in v.fields.values():
            _unknown_tokens(x, out)
    return out


def _key_name(key: tuple) -> str:
    return key[-1]


def _written(e) -> str:
    """An expression as the program names it, for messages (``XP1``, ``P[3]``, ``gs[…].fCNC``)."""
    if isinstance(e, Name):
        return e.written or e.name
    if isinstance(e, Field):
        return f"{_written(e.base)}.{e.written or e.name}"
    if isinstance(e, Item):
        parts = [str(whole_number(x.value)) if isinstance(x, (Num, Lit)) and whole_number(getattr(x, "value", None))
                 is not None else "…" for x in e.index]
        return f"{_written(e.base)}[{', '.join(parts)}]"
    if isinstance(e, Call):
        return f"{e.name.split('.')[-1]}(…)"
    if isinstance(e, Op) and e.op == "compose":
        return ":".join(_written(a) for a in e.args)
    return ""


def _size(body) -> int:
    from ..ir import walk

    return sum(len(s) if isinstance(s, MoveRun) else 1 for s in walk(body))


import numpy as _np  # noqa: E402

_EYE = _np.eye(4)
_EYE.setflags(write=False)


def frame_matrix(xyz, orientation, form: str):
    """The 4×4 of a position ``xyz`` with the orientation's numbers in ``form`` (None: unturned)."""
    from ...core import frames as fr

    m = _np.eye(4)
    m[:3, 3] = xyz
    if orientation is not None:
        m[:3, :3] = fr.orientation_rotation(_np.asarray(orientation, float), form)
    return m


def identity_orientation(form: str) -> tuple:
    """The numbers of no turn in ``form`` (A,B,C or a rotation vector: 0,0,0; a quaternion 1,0,0,0)."""
    return (1.0, 0.0, 0.0, 0.0) if form == "quaternion" else (0.0, 0.0, 0.0)

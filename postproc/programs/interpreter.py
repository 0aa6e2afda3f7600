"""A concrete interpreter of the motion IR: runs a lowered program as the controller would and
records the poses it commands — the oracle against which the analysis is checked.

What the program leaves to the world (a condition on an input, the value of ``$IN[3]``, what a
routine that is not read does to the frames and to its arguments, how often a WHILE runs) is
answered by an :class:`Oracle`: the same answer to the same question (asked at the same place
for the same time), so a program and its compensated twin, which differ in numbers only, run
the same path. The property tests (``tests/test_interpreter.py``, ``benchmarks/interpreter.py``)
run both and check that every executed target is either commanded at P + Ê for its own executed
nominal pose P (reached from the motion that really ran before it) or was left as written — and
that the product did not exit 0 where one was left.

The interpreter is the analysis (``execute.Analysis``) with concrete control flow. It shares
its evaluation (values, the dialect's builtins), how a program starts and a routine is
activated (``declare_data``, ``start``, ``routine``), the binding of a call's arguments
(``call``: copy-in, copy-back of OUT / by-reference parameters, defaults, the callee's scope)
and which variables code not read touches (``havoc``). It replaces how statements run
(``straight``, ``body``: each routine's statements compiled to a flat list with jumps,
``_compile``, run one path), the values code not read leaves (``unseen``: the world's) and what
a motion records, with the oracle's answers where a value is not known.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

from ..core import frames as fr
from ..robot.conventions import MOTIONS
from .analysis.execute import Analysis, Recorder, State
from .analysis.values import Arr, Mat, Rec, Six, Top, number
from .ir import Agg, Continue, Exit, Goto, Halt, If, Invoke, Label, Loc, Loop, Move, MoveRun, Name, Return, Switch

__all__ = ["Interpreter", "Oracle", "Motion", "run"]

MAX_STEPS = 200_000  # statements one run may execute (an endless LOOP the oracle does not leave)


@dataclass
class Motion:
    """One executed motion: where its statement stands (``site``), its kind, the commanded TCP
    pose in the robot base (``base`` 4×4; None: not a Cartesian target the run knows: an axis
    target, a relative motion), the tool, and where its target's numbers stand (``loc``: the
    aggregate; ``token``: (file, start) of its X number, None where it has none)."""

    site: Loc
    kind: str
    base: np.ndarray | None
    tool: tuple | None
    loc: Loc | None = None
    token: tuple | None = None
    axes: list | None = None  # (a joint motion: its six axis values where known, deg)
    motion: str = ""  # the motion kind (robot.conventions.MOTIONS: a run's row its own)
    config: tuple = (-1, -1)  # the configuration its target writes: KRL's (S, T), -1 not written
    # the payload the robot carries at it (mass kg, cx, cy, cz mm): as the program sets it, the world's
    # where the analysis does not know it (the oracle's), None where the program sets none
    load: tuple | None = None


class Oracle:
    """The world's answers, each drawn once per question (its place, what is asked, and the how
    many-th time there) from a seeded generator: ``loops`` bounds how often an unknown loop
    condition holds in a row."""

    def __init__(self, seed: int = 0, loops: int = 3):
        self.rng = np.random.default_rng(seed)
        self.seed = seed
        self.loops = loops
        self.answers: dict = {}
        self.asked: dict = {}

    def _key(self, site, what):
        base = (site, what)
        n = self.asked.get(base, 0)
        self.asked[base] = n + 1
        return base + (n,)

    def _draw(self, key, make):
        if key not in self.answers:
            # (a stable hash: Python's hash of a string changes from one process to the next)
            digest = hashlib.blake2b(repr((self.seed,) + key).encode(), digest_size=8).digest()
            rng = np.random.default_rng(int.from_bytes(digest, "little"))
            self.answers[key] = make(rng)
        return self.answers[key]

    def reset(self) -> None:
        """Start a run: the same questions get the same answers (``answers`` are kept)."""
        self.asked = {}

    def boolean(self, site) -> bool:
        return self._draw(self._key(site, "bool"), lambda r: bool(r.random() < 0.5))

    def whole(self, site) -> int:
        return self._draw(self._key(site, "int"), lambda r: int(r.integers(0, 3)))

    def number(self, site) -> float:
        return self._draw(self._key(site, "num"), lambda r: float(r.uniform(-50, 50)))

    def frame(self, site) -> Mat:
        def make(r):
            six = np.r_[r.uniform(-200, 200, 3), r.uniform(-30, 30, 3)]
            return Mat(fr.frame_to_matrix(six), "the world's frame")
        return self._draw(self._key(site, "frame"), make)

    def load(self, site) -> tuple:
        """A payload the world has where the program's is not known (mass kg, centre of mass mm)."""
        return self._draw(self._key(site, "load"), lambda r: (float(r.choice([0.0, 120.0, 300.0, 450.0])), 0.0,
                                                              float(r.uniform(-40, 40)), float(r.uniform(0, 300))))

    def model_tool(self) -> np.ndarray:
        """The model's own tool on the flange in this world (drawn once)."""
        def make(r):
            return fr.frame_to_matrix(np.r_[r.uniform(-200, 200, 3), r.uniform(-30, 30, 3)])
        return self._draw(("the model's tool",), make)


class _Halt(Exception):
    pass


class Interpreter(Analysis):
    """Runs a Unit (``dialect``: its :class:`~.analysis.dialect.Dialect`) with an ``oracle``:
    ``run()`` → the motions in the order they ran (``Motion``)."""

    def __init__(self, unit, dialect, oracle: Oracle | None = None, entry: str | None = None):
        super().__init__(unit, dialect)
        self.oracle = oracle or Oracle()
        self.entry = entry
        self.motions: list[Motion] = []
        self.steps = 0
        self.code: dict = {}
        self.budget = 0  # (no unrolling: FORs run as loops)
        self._here: tuple = ("start", 0)

    # ------------------------------------------------------------------ the program
    def run(self) -> list[Motion]:
        self.oracle.reset()
        self.rec = Recorder()  # (escapes and notes are not wanted; the analysis's code records into it)
        st = self.declare_data()
        name = self.entry or (self.unit.entries[0] if self.unit.entries else None)
        if name is None:
            return []
        try:
            self.start(name, st)
        except _Halt:
            pass
        return self.motions

    def straight(self, stmts, st: State, where: tuple | None) -> State:
        """The data (``where``: ("data", module): each statement a place the oracle is asked
        at) and the prologue (None: asked where the data left off), one statement after another."""
        for k, s in enumerate(stmts):
            if where is not None:
                self._here = where + (k,)
            st = self.simple(s, st)
        return st

    # ------------------------------------------------------------------ routines: flat code
    def body(self, routine, st: State, act):
        """A routine's flat code (``_compile``) run one path: (state at its end or RETURN, the
        value returned)."""
        code, labels = self.code.get(routine.name) or self.code.setdefault(routine.name, _compile(routine.body))
        value = None
        pc = 0
        while pc < len(code):
            self._here = (routine.name, pc)
            self.steps += 1
            if self.steps > MAX_STEPS:
                raise _Halt
            op = code[pc]
            kind = op[0]
            if kind == "S":
                self.loc = getattr(op[1], "loc", self.loc)
                st = self.simple(op[1], st)
                pc += 1
            elif kind == "JMP":
                pc = op[1] if isinstance(op[1], int) else labels[op[1]]
            elif kind == "BR":  # (cond, jump when it is ``op[3]``)
                _, cond, target, when, site = op
                pc = target if self.truth(cond, st, site) == when else pc + 1
            elif kind == "LOOP":  # an unknown loop condition: the oracle, a bounded number of times
                _, cond, target, when, site = op
                pc = target if self.truth(cond, st, site, loop=True) == when else pc + 1
            elif kind == "SET":
                self.loc = op[3]
                self.write(Name(op[1]), number(self.eval(op[2], st)), st)
                pc += 1
            elif kind == "STEP":
                _, var, step, site = op
                self.loc = site
                _, v = self.lookup(var, st)
                self.write(Name(var), number(v) + number(self.eval(step, st)), st)
                pc += 1
            elif kind == "FOR?":
                _, var, stop, step, target, site = op
                _, v = self.lookup(var, st)
                hi, by = number(self.eval(stop, st)), number(self.eval(step, st))
                if hi is None or by is None:
                    go = self.oracle.boolean(self.here) if self.oracle.whole(self.here) else False
                else:
                    go = number(v) <= hi if by > 0 else number(v) >= hi
                pc = pc + 1 if go else target
            elif kind == "SW":
                _, subject, cases, default, site = op
                v = self.eval(subject, st)
                pc = default
                if isinstance(v, Top):
                    choice = self.oracle.whole(self.here) % (len(cases) + 1)
                    pc = cases[choice][1] if choice < len(cases) else default
                else:
                    for values, target in cases:
                        if any(_equal(self.eval(x, st), v) for x in values):
                            pc = target
                            break
            elif kind == "RET":
                value = self.eval(op[1], st) if op[1] is not None else None
                break
            elif kind == "HALT":
                raise _Halt
            else:  # pragma: no cover
                raise TypeError(kind)
        return st, value

    def truth(self, cond, st, site, loop: bool = False) -> bool:
        v = self.eval(cond, st) if cond is not None else True
        if isinstance(v, bool):
            return v
        site = self.here
        if loop:  # (how often a condition only the world knows holds in a row: bounded)
            key = (site, "runs")
            n = self.oracle.asked.get(key, 0)
            self.oracle.asked[key] = n + 1
            return n < self.oracle.loops and self.oracle.boolean(site)
        return self.oracle.boolean(site)

    @property
    def here(self) -> tuple:
        """The place a question is asked, the same in a program and its compensated twin (which
        differ in numbers, and in the stamp's line): the routine and the position in its code."""
        return self._here

    # ------------------------------------------------------------------ statements
    def simple(self, s, st: State) -> State:
        kind = type(s)
        if kind is Move:
            return self.move(s, st)
        if kind is MoveRun:
            return self.move_run(s, st)
        if kind is Invoke:
            return self.invoke(s, st) or st
        out = self.stmt(s, st)
        return out if out is not None else st

    def run_time(self, key, value):
        """Data that code the entry does not run may change (``Analysis.run_time``): this run is one
        where that code did not run — the value the program gives it."""
        return value

    def unseen(self, v, top):
        """Code not read ran (``Analysis.havoc``): the oracle gives what it touches new values
        (frames: a frame of the world's; numbers, flags, poses: the world's)."""
        return self._world(v, self.here)

    def _world(self, v, site):
        if isinstance(v, bool):
            return self.oracle.boolean(site)
        if number(v) is not None:
            return float(number(v)) + self.oracle.number(site)
        if isinstance(v, (Mat, Rec)) or v is None or isinstance(v, Top):
            if isinstance(v, Rec) and v.fields.keys() & {"X", "Y", "Z"}:
                m = self.dialect.frame(self, v)
                if isinstance(m, Mat):
                    moved = m.m @ self.oracle.frame(site).m
                    six = fr.matrix_to_frame(moved)
                    return Rec(v.type, {**v.fields, **dict(zip("XYZABC", map(float, six)))}, None)
            return self.oracle.frame(site)
        if isinstance(v, Arr):
            return Arr({k: self._world(x, site) for k, x in v.elems.items()}, v.default, v.type)
        return v

    # ------------------------------------------------------------------ motions
    def move(self, s: Move, st: State) -> State:
        if s.relative and isinstance(s.target, Agg):
            return self.move_relative(s, st)
        if s.joint or s.relative:
            axes = None
            if s.joint and not s.relative:
                target = self.eval(s.target, st)
                axes = self.dialect.axis_values(target) if isinstance(target, Rec) else None
            self.motions.append(Motion(s.loc, s.kind, None, None, axes=axes))
            st.cur = None
            return st
        if self.dialect.halts(self, st, s):  # (the controller's alarm: the program stops here)
            raise _Halt
        target = self.eval(s.target, st)
        frame = self.frame_value(s.frame, st)
        if isinstance(frame, Top):  # (a frame the analysis does not know: the world's, as the controller has one)
            frame = self.oracle.frame(self.here)
        tool = self.tool_value(s.tool, st)
        if isinstance(s.target, Agg) and isinstance(target, Rec):
            target = self.fill_from(target, st, frame, tool)
        m = self._pose(target, frame)
        view = self.dialect.view(target) if isinstance(target, Rec) else None
        if view is not None and view.kind == "axis":
            m = None
        token = None
        if view is not None and view.xyz and hasattr(view.xyz[0], "token"):
            token = view.xyz[0].token[:2]
        self.motions.append(Motion(s.loc, s.kind, m, tool if not isinstance(tool, Top) else None,
                                   view.loc if view is not None else None, token, motion=s.kind,
                                   config=tuple(view.config) if view is not None and view.config else (-1, -1),
                                   load=self.load_in_force(s.load, st)))
        if s.chain:
            st.cur = (m, frame, tool) if m is not None else None
        return st

    def move_relative(self, s: Move, st: State) -> State:
        """A relative motion (``Move.rel``): from the pose last commanded — as the new tool reads
        it where the tool changed (the flange stays) — by the move's X/Y/Z along the motion's
        frame's axes ("base") or the tool's ("tool"); None where the run does not know it."""
        move = self.eval(s.target, st)
        frame = self.frame_value(s.frame, st)
        if isinstance(frame, Top):
            frame = self.oracle.frame(self.here)
        tool = self.tool_value(s.tool, st)
        m = None
        if isinstance(move, Rec) and st.cur is not None and st.cur[0] is not None and isinstance(frame, Mat):
            here = self._standing(st, tool)
            d = [number(move.fields.get(k, 0.0)) for k in ("X", "Y", "Z")]
            if here is not None and all(v is not None for v in d):
                step = np.eye(4)
                step[:3, 3] = d
                if s.rel == "base":
                    m = here.copy()
                    m[:3, 3] += frame.m[:3, :3] @ np.asarray(d, float)
                else:
                    m = here @ step
        view = self.dialect.view(move) if isinstance(move, Rec) else None
        token = None
        if view is not None and view.xyz and hasattr(view.xyz[0], "token"):
            token = view.xyz[0].token[:2]
        self.motions.append(Motion(s.loc, s.kind, m, tool if not isinstance(tool, Top) else None,
                                   view.loc if view is not None else None, token, motion=s.kind,
                                   load=self.load_in_force(s.load, st)))
        if s.chain:
            st.cur = (m, frame, tool) if m is not None else None
        return st

    def fill_from(self, target: Rec, st: State, frame, tool):
        """A partial target takes its missing components from where the robot stands: the pose
        last commanded, in the motion's frame, for the motion's tool (as the controller does:
        the flange stays where the tool before left it)."""
        names = ("X", "Y", "Z", "A", "B", "C")
        missing = [k for k in names if k not in target.fields]
        if not missing or st.cur is None or not isinstance(frame, Mat):
            return target
        here = self._standing(st, tool)
        if here is None:
            return target
        here = np.linalg.inv(frame.m) @ here
        six = fr.matrix_to_frame(here)
        fields = dict(target.fields)
        for k in missing:
            fields[k] = float(six[names.index(k)])
        return Rec(target.type, fields, target.loc, target.label)

    def _standing(self, st: State, tool):
        """The TCP pose [4, 4] (robot base) where the robot stands after the last command, for
        ``tool``: the flange stays where the tool before left it (None where a tool is not known)."""
        here = st.cur[0]
        if here is None or _equal_tools(st.cur[2], tool):
            return here
        before, now = self._tool_matrix(st.cur[2]), self._tool_matrix(tool)
        return None if before is None or now is None else here @ np.linalg.inv(before) @ now

    def _pose(self, target, frame):
        if not isinstance(target, Rec) or not isinstance(frame, Mat):
            return None
        m = self.dialect.frame(self, target)
        if not isinstance(m, Mat) or not np.isfinite(m.m).all():
            return None
        return frame.m @ m.m

    def move_run(self, s: MoveRun, st: State) -> State:
        frame = self.frame_value(s.frame, st)
        if isinstance(frame, Top):
            frame = self.oracle.frame(self.here)
        tool = self.tool_value(s.tool, st)
        load = self.load_in_force(s.load, st)
        r = s.rows
        names = ("X", "Y", "Z", "A", "B", "C")
        for i in range(len(r["line"])):
            # (a row's pose column is X, Y, Z, A, B, C in every dialect: the orientation as A, B, C)
            six = np.where(r["written"][i], r["pose"][i], np.nan).astype(float)
            site = Loc(int(r["file"][i]), int(r["line"][i]), int(r["col"][i]))
            if np.isnan(six).any():
                fields = {k: float(six[j]) for j, k in enumerate(names) if r["written"][i, j]}
                six = self._filled(fields, st, frame, tool)
            m = None
            if isinstance(frame, Mat) and six is not None and np.isfinite(six).all():
                m = frame.m @ fr.frame_to_matrix(six)
            token = (int(r["file"][i]), int(r["spans"][i, 0])) if r["spans"][i, 0] >= 0 else None
            self.motions.append(Motion(site, "row", m, tool if not isinstance(tool, Top) else None, site, token,
                                       motion=MOTIONS[int(r["motion"][i])],
                                       config=tuple(int(v) for v in r["config"][i]), load=load))
            if r["chain"][i]:
                st.cur = (m, frame, tool) if m is not None else None
        return st

    def _filled(self, fields: dict, st: State, frame, tool):
        """A MoveRun's partial row (X…C as A, B, C) completed from where the robot stands: six
        numbers, None where that is not known."""
        names = ("X", "Y", "Z", "A", "B", "C")
        out = self.fill_from(Rec("", dict(fields), None), st, frame, tool).fields
        if any(k not in out for k in names):
            return None
        return np.array([float(out[k]) for k in names])

    def load_in_force(self, expr, st):
        """The payload at a motion (``Analysis.load_value``) in this run: the world's (the oracle's)
        where the program's is not known, None where it sets none."""
        v = self.load_value(expr, st)
        if isinstance(v, Top):
            return self.oracle.load(self.here)
        return None if v is None else tuple(float(x) for x in v)

    def tool_value(self, expr, st):
        v = super().tool_value(expr, st)
        if isinstance(v, Six):
            return tuple(v)
        return v

    def _tool_matrix(self, tool):
        """A tool on the flange in this world: six numbers as written; the model's own (None): a
        tool the oracle draws once; unknown (Top): None."""
        if isinstance(tool, tuple):
            return fr.frame_to_matrix(np.asarray(tool, float))
        if tool is None:
            return self.oracle.model_tool()
        return None


def _equal_tools(a, b) -> bool:
    if isinstance(a, tuple) and isinstance(b, tuple):
        return np.allclose(a, b, rtol=0, atol=1e-12)
    return a is b


def _equal(a, b) -> bool:
    na, nb = number(a), number(b)
    if na is not None and nb is not None:
        return na == nb
    return a == b


def _compile(body: list):
    """A routine's structured statements → (flat code, label → position): ``("S", stmt)``,
    ``("JMP", to)``, ``("BR", cond, to, when, site)`` (jump when cond is ``when``), ``("LOOP",
    …)`` (the same for a loop's condition), ``("SET", var, expr, site)``, ``("STEP", var, step,
    site)``, ``("FOR?", var, stop, step, to, site)``, ``("SW", subject, [(values, to)], default,
    site)``, ``("RET", expr)``, ``("HALT",)``."""
    code: list = []
    labels: dict = {}
    loops: list = []  # (continue-fixups, break-fixups)

    def emit(*op):
        code.append(list(op))
        return len(code) - 1

    def block(stmts):
        for s in stmts:
            kind = type(s)
            if kind is If:
                br = emit("BR", s.cond, None, False, s.loc)
                block(s.then)
                jmp = emit("JMP", None)
                code[br][2] = len(code)
                block(s.orelse)
                code[jmp][1] = len(code)
            elif kind is Switch:
                sw = emit("SW", s.subject, [], None, s.loc)
                ends = []
                for values, b in s.cases:
                    code[sw][2].append((values, len(code)))
                    block(b)
                    ends.append(emit("JMP", None))
                code[sw][3] = len(code)
                if s.default is not None:
                    block(s.default)
                for j in ends:
                    code[j][1] = len(code)
            elif kind is Loop:
                cont, brk = [], []
                loops.append((cont, brk))
                if s.kind == "for":
                    emit("SET", s.var, s.start, s.loc)
                    head = len(code)
                    test = emit("FOR?", s.var, s.stop, s.step, None, s.loc)
                    block(s.body)
                    step_at = len(code)
                    emit("STEP", s.var, s.step, s.loc)
                    emit("JMP", head)
                    code[test][4] = len(code)
                elif s.kind == "while":
                    head = len(code)
                    test = emit("LOOP", s.cond, None, False, s.loc)
                    block(s.body)
                    step_at = head
                    emit("JMP", head)
                    code[test][2] = len(code)
                elif s.kind == "repeat":
                    head = len(code)
                    block(s.body)
                    step_at = len(code)
                    emit("LOOP", s.cond, None, False, s.loc)  # (UNTIL cond: again while it fails)
                    code[-1][2] = head
                    code[-1][3] = False
                else:  # endless
                    head = len(code)
                    block(s.body)
                    step_at = head
                    emit("JMP", head)
                end = len(code)
                loops.pop()
                for j in cont:
                    code[j][1] = step_at
                for j in brk:
                    code[j][1] = end
            elif kind is Label:
                labels[s.name] = len(code)
            elif kind is Goto:
                if s.cond is None:
                    emit("JMP", s.name)
                else:
                    emit("BR", s.cond, s.name, True, s.loc)
            elif kind is Return:
                emit("RET", s.value)
            elif kind is Halt:
                emit("HALT")
            elif kind is Exit:
                if loops:
                    loops[-1][1].append(emit("JMP", None))
                else:
                    emit("RET", None)
            elif kind is Continue:
                if loops:
                    loops[-1][0].append(emit("JMP", None))
            else:
                emit("S", s)

    block(body)
    out = [tuple(op) for op in code]
    # (a jump to a label: its position; BR's target too)
    resolved = []
    for op in out:
        if op[0] == "BR" and isinstance(op[2], str):
            op = (op[0], op[1], labels.get(op[2], len(out)), op[3], op[4])
        resolved.append(op)
    return resolved, labels


def run(unit, dialect, oracle: Oracle | None = None, entry: str | None = None) -> list[Motion]:
    """The motions a run of ``unit`` commands (see :class:`Interpreter`)."""
    return Interpreter(unit, dialect, oracle, entry).run()

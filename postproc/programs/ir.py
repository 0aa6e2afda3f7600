"""The motion IR: the one small language every dialect reader lowers its program to.

A reader (KRL, RAPID, URScript, Fanuc LS, pose lists) parses its texts and *lowers* them to a
:class:`Unit`: routines whose bodies are statements (assignments, motions, calls, branches,
loops, labels and jumps, returns, halts), with expressions over variables, number tokens and
aggregates. Every number that may be rewritten is a :class:`Num` that keeps its span in its
file's text, so the rewrite stays byte-lossless. After lowering nothing downstream knows the
dialect: :mod:`postproc.programs.analysis` runs one dataflow analysis over the IR (values known
or unknown, frames, tools, configuration, the motions' predecessors in execution order) and
:mod:`postproc.programs.interpreter` executes it concretely (the oracle of the property tests).

What a dialect means by a construct is said once, in its lowering: KRL's ``BAS(#BASE, n)``
becomes a call of the builtin ``KRL.BAS_BASE``, RAPID's ``\\WObj:=w`` the motion's ``frame``
expression, URScript's ``set_tcp(p)`` an assignment to ``$TOOL``. The builtins a dialect
needs (``INV_POS``, ``Offs``, ``pose_trans`` …) are functions of :mod:`.analysis.builtins`,
one place for the analysis and the interpreter.

Structure: statements are nested (``If``/``Switch``/``Loop`` hold blocks), with ``Label`` and
``Goto`` for the jumps every dialect has (Fanuc LS is made of them); a ``Goto`` may only jump
within its routine. Straight-line runs of motions to literal targets (a CAM program's 10^6
``LIN {X …}`` lines) are one :class:`MoveRun` of columns, so straight-line programs stay
linear: the analysis handles a run with a few numpy operations.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..robot.conventions import MOTIONS

MOTION_INDEX = {m: i for i, m in enumerate(MOTIONS)}

__all__ = [
    "Expr", "Lit", "Num", "Name", "Field", "Item", "Agg", "Op", "Call", "Unknown",
    "Stmt", "Decl", "Eval", "Assign", "Move", "MoveRun", "Invoke", "If", "Switch", "Loop", "Label", "Goto",
    "Return", "Halt", "Exit", "Continue", "Havoc", "Note", "Async", "AsyncSwitch", "Param", "Routine", "Unit",
    "Loc", "walk", "MOTION_INDEX", "empty_rows",
]


@dataclass(frozen=True, slots=True)
class Loc:
    """Where a statement or an aggregate stands: file index (into ``Unit.files``; negative: a
    configuration text, ``Unit.config_names``), 1-based line and column."""

    file: int
    line: int
    col: int


# ----------------------------------------------------------------------------- expressions


class Expr:
    """An expression (immutable)."""

    __slots__ = ()


@dataclass(frozen=True, slots=True)
class Lit(Expr):
    """A value that is no rewritable number: a bool, a string, an enum (``#BASE``, upper case),
    an int or float that no token holds (a loop's step of 1)."""

    value: object


@dataclass(frozen=True, slots=True)
class Num(Expr):
    """A number token of the program (the sign, where one stands before it, included): its
    value in the IR's units (mm, degrees; a dialect in metres lowers × 1000) and its span
    ``[start, end)`` in file ``file``'s text."""

    value: float
    file: int
    start: int
    end: int


@dataclass(frozen=True, slots=True)
class Name(Expr):
    """A variable, by its canonical name (upper case for the case-insensitive dialects);
    ``written`` as the program writes it, for messages ("" the same)."""

    name: str
    written: str = field(default="", compare=False)


@dataclass(frozen=True, slots=True)
class Field(Expr):
    """``base.name`` (a component of a pose, a member of a record); ``written`` as written."""

    base: Expr
    name: str
    written: str = field(default="", compare=False)


@dataclass(frozen=True, slots=True)
class Item(Expr):
    """``base[index…]`` (an array element)."""

    base: Expr
    index: tuple


@dataclass(frozen=True, slots=True)
class Agg(Expr):
    """An aggregate as written: a pose (``kind`` "pose": fields X, Y, Z, the orientation's
    numbers in ``form``'s names, S, T, E1… and the like) or a record (``kind`` its type name).
    ``items``: (field name, expression) in the order written; ``type``: the type the program
    names (``E6POS``, ``robtarget``) or ""; ``loc``: where it stands (its ``{`` / ``[``);
    ``form``: the orientation's numbers (``frames.ORIENTATION_NAMES``: "abc", "quaternion",
    "rotvec")."""

    kind: str
    items: tuple
    loc: Loc
    type: str = ""
    form: str = "abc"

    def get(self, name: str):
        for k, v in self.items:
            if k == name:
                return v
        return None


@dataclass(frozen=True, slots=True)
class Op(Expr):
    """An operator: ``+ - * / neg not and or == <> < <= > >=`` (numbers, bools), ``:``
    (``compose``: frames), ``inv`` (a frame's inverse)."""

    op: str
    args: tuple


@dataclass(frozen=True, slots=True)
class Call(Expr):
    """A function call in an expression: a builtin of the dialect (``KRL.INV_POS``,
    ``RAPID.Offs``: qualified names, :mod:`.analysis.builtins`) or a routine of the unit."""

    name: str
    args: tuple
    loc: Loc | None = None


@dataclass(frozen=True, slots=True)
class Unknown(Expr):
    """A value only the running controller knows (``$POS_ACT``, ``$IN[3]``,
    ``get_actual_tcp_pose()``), with why; ``code`` the diagnostic it leaves a target with
    (None: the analysis's default for what it is)."""

    why: str
    code: str | None = None


# ------------------------------------------------------------------------------ statements


class Stmt:
    __slots__ = ()


@dataclass(slots=True)
class Decl(Stmt):
    """A variable declared (scope "local", "module" or "global") with its type (upper case for
    KRL; "" not said), array dimensions (None: a scalar) and initial value (None: none)."""

    name: str
    type: str
    dims: tuple | None
    init: Expr | None
    scope: str
    loc: Loc
    written: str = ""  # the name as written (messages)


@dataclass(slots=True)
class Eval(Stmt):
    """An expression evaluated for what it does (a function it calls, a condition waited for:
    ``WAIT FOR Ok()``): its value is read, nothing is assigned."""

    expr: Expr
    loc: Loc


@dataclass(slots=True)
class Assign(Stmt):
    """``target = value``; ``target`` a Name, Field or Item chain."""

    target: Expr
    value: Expr
    loc: Loc


@dataclass(slots=True)
class Move(Stmt):
    """A motion. ``kind``: one of ``programs.MOTIONS`` (LIN, PTP, CIRC-aux, …); ``target``: its
    Cartesian target; ``frame``: the frame its coordinates are in, as an expression of the robot
    base (KRL: ``INV_POS($ROBROOT):$BASE``; RAPID: the work object's user and object frame);
    ``tool``: the TCP on the flange; ``joint``: an axis target (its ``target`` the joint values,
    not Cartesian); ``relative``: the target is relative to where the robot stands (``_REL``,
    ``INC``): ``target`` the move — X/Y/Z only — in the frame ``rel`` names (``"base"``: the
    motion's frame's axes; ``"tool"``: the tool's axes where the robot stands), or an ``Unknown``
    (its absolute target known only at run time); ``chain``: the motion's target becomes where the robot stands
    (a CIRC's auxiliary point does not); ``config``: the configuration the target states where
    it is not a field of the target (a Fanuc CONFIG string, RAPID's confdata record); ``ext``:
    the external axes' values (a track's position) where the dialect states them apart; ``load``:
    the payload the robot carries at it (KRL's ``$LOAD``, RAPID's tool load + ``GripLoad``), as an
    expression (None: the dialect's ``Dialect.load_var``, the load it holds in force)."""

    kind: str
    target: Expr
    loc: Loc
    frame: Expr | None = None
    tool: Expr | None = None
    joint: bool = False
    relative: bool = False
    chain: bool = True
    config: Expr | None = None
    ext: Expr | None = None
    rel: str = "base"
    load: Expr | None = None


@dataclass(slots=True)
class MoveRun(Stmt):
    """Consecutive motions to literal Cartesian targets with nothing between them (a CAM
    program's body), as columns of ``rows`` (``MoveRun.COLUMNS``: pose [n, 6] NaN where not
    written, written [n, 6], spans [n, 12] (X…C token spans, -1 absent), file, line, col,
    motion [n] (index into MOTIONS), chain [n] bool, config [n, 2] S/T (-1 not stated); where
    the orientation's form is not A,B,C, ``orient`` [n, k] its numbers as written and ``ospans``
    [n, k, 2] their spans; a dialect may add its own columns, ``Dialect.run_extras``); in
    the frame and with the tool the program has in force at the run (its ``frame``/``tool``
    expressions, as a Move's; ``load`` too)."""

    rows: dict
    frame: Expr | None = None
    tool: Expr | None = None
    load: Expr | None = None

    COLUMNS = ("pose", "written", "spans", "file", "line", "col", "motion", "chain", "config")

    def __len__(self) -> int:
        return len(self.rows["line"])


@dataclass(frozen=True, slots=True)
class Param:
    """A routine's parameter: its name, how it is passed ("in": a copy; "out"/"ref": by
    reference, the routine may change the caller's variable) and the value it takes where a
    call leaves it out (``default``: an expression evaluated at the call; None: none)."""

    name: str
    mode: str = "in"
    default: Expr | None = None


@dataclass(slots=True)
class Invoke(Stmt):
    """A call of a routine as a statement: ``name`` (upper case for KRL) and its arguments;
    a builtin (qualified name) or a routine of the unit; one the unit does not hold is code
    not read (what it may change is unknown after it)."""

    name: str
    args: tuple
    loc: Loc


@dataclass(slots=True)
class If(Stmt):
    cond: Expr
    then: list
    orelse: list
    loc: Loc


@dataclass(slots=True)
class Switch(Stmt):
    """``cases``: (values, body); ``default``: None where there is none (no case matching: no
    body runs)."""

    subject: Expr
    cases: list
    default: list | None
    loc: Loc


@dataclass(slots=True)
class Loop(Stmt):
    """``kind`` "for" (``var`` from ``start`` to ``stop`` by ``step``), "while" (``cond`` before
    each pass), "repeat" (``cond`` after each pass: it ends when true), "loop" (endless)."""

    kind: str
    body: list
    loc: Loc
    var: str | None = None
    start: Expr | None = None
    stop: Expr | None = None
    step: Expr | None = None
    cond: Expr | None = None


@dataclass(slots=True)
class Label(Stmt):
    name: str
    loc: Loc


@dataclass(slots=True)
class Goto(Stmt):
    """A jump to a label of the same routine (``cond`` None: always)."""

    name: str
    loc: Loc
    cond: Expr | None = None


@dataclass(slots=True)
class Return(Stmt):
    value: Expr | None
    loc: Loc


@dataclass(slots=True)
class Halt(Stmt):
    """The program stops here (HALT, Fanuc END/ABORT, URScript halt): nothing after it runs."""

    loc: Loc


@dataclass(slots=True)
class Exit(Stmt):
    """Leaves the innermost loop (KRL EXIT, URScript break)."""

    loc: Loc


@dataclass(slots=True)
class Continue(Stmt):
    loc: Loc


@dataclass(slots=True)
class Havoc(Stmt):
    """Code the reader does not see runs here and may change ``names`` (None: every global,
    the frames and the tool), e.g. a handler of the controller's; ``why`` says what."""

    names: tuple | None
    why: str
    loc: Loc


@dataclass(slots=True)
class Note(Stmt):
    """A finding the lowering makes at a statement (a code of ``diagnostics.CODES`` and its
    text), reported by the analysis where the statement is reached (dead code says nothing)."""

    code: str
    message: str
    loc: Loc
    left: bool = True  # a motion target left as written (counted in the summary)


@dataclass(slots=True)
class Async(Stmt):
    """An asynchronous handler declared (KRL ``INTERRUPT DECL n … DO action``, ``TRIGGER …
    DO``, RAPID ``CONNECT … WITH trap``, URScript ``run`` of a thread): ``action`` (a
    statement) may run at any moment while the handler is switched on (``on`` True from here:
    a TRIGGER, a thread; False: until an ``AsyncSwitch`` with its ``number``)."""

    number: Expr | None
    action: Stmt
    loc: Loc
    on: bool = False
    what: str = "handler"  # how messages name it ("INTERRUPT handler", "TRIGGER handler")


@dataclass(slots=True)
class AsyncSwitch(Stmt):
    """Handlers switched on / off (``number`` None: all)."""

    number: Expr | None
    on: bool
    loc: Loc


@dataclass(slots=True)
class Routine:
    """A routine (DEF, PROC, def, an LS program): ``module`` the scope of its module-level
    variables; ``visible``: callable from other modules; ``function``: returns a value."""

    name: str
    params: tuple
    body: list
    loc: Loc
    module: str = ""
    visible: bool = True
    function: bool = False


@dataclass
class Unit:
    """A lowered program (one file or a whole cell): its routines by name (upper case for
    the case-insensitive dialects), the entries (routines the controller starts), the
    declarations of module and global data (``data``: statements run before the entries,
    module by module), and what the rewrite needs of the dialect."""

    dialect: str
    files: list
    texts: list
    routines: dict = field(default_factory=dict)
    entries: list = field(default_factory=list)
    data: list = field(default_factory=list)
    config_names: list = field(default_factory=list)  # names of configuration texts (file -1, -2, …)
    config_texts: list = field(default_factory=list)
    # statements each entry starts with (the frames in force when the controller starts a program:
    # KRL's $BASE/$TOOL/$ROBROOT as stated or not set)
    prologue: list = field(default_factory=list)
    form: str = "abc"  # the orientation form of its poses (frames.ORIENTATION_NAMES)
    unit: float = 1.0  # mm per unit of its X/Y/Z numbers as written
    diagnostics: list = field(default_factory=list)  # what the lowering found (syntax warnings, folds)


def walk(body: list):
    """Every statement of ``body``, nested blocks included, in the order written."""
    for s in body:
        yield s
        if isinstance(s, If):
            yield from walk(s.then)
            yield from walk(s.orelse)
        elif isinstance(s, Switch):
            for _, b in s.cases:
                yield from walk(b)
            if s.default is not None:
                yield from walk(s.default)
        elif isinstance(s, Loop):
            yield from walk(s.body)


def empty_rows() -> dict:
    """The columns of a MoveRun of no rows."""
    return dict(pose=np.zeros((0, 6)), written=np.zeros((0, 6), bool), spans=np.full((0, 12), -1, np.int64),
                file=np.zeros(0, np.int32), line=np.zeros(0, np.int32), col=np.zeros(0, np.int32),
                motion=np.zeros(0, np.int8), chain=np.zeros(0, bool), config=np.full((0, 2), -1, np.int16))

"""What a dialect means, as the analysis asks for it: the base class :class:`Dialect`.

The analysis (``execute.py``) is the same for every dialect; a dialect's reader hands it a
``Dialect`` whose methods say, once, what its constructs do: the initial values of its system
variables, its builtin procedures and functions (``procedures`` / ``functions``: qualified name
→ function), what a routine not read may change (``unread`` / ``touched``), how a value is a
frame, a tool or a motion's pose (``frame``, ``tool``, ``view``), where a partial target takes
its missing components from (``fill``). The defaults here are those most dialects share.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...core import frames as fr
from ...core.diagnostics import P215, P232, P235, listed
from ..ir import Assign, Decl, Field, Invoke, Item, Loc, Name, walk
from .values import (
    LOAD_NOT_SET, Arr, Load, Mat, Moving, NotSet, Rec, Six, Taint, Tok, Top, frame_inverse, frame_product, number, taint,
    tokens_of,
)

__all__ = ["Dialect", "PoseView", "ABC", "AXIS_TYPES"]

ABC = ("A", "B", "C")
ORIENTATION_FIELDS = {"abc": ("A", "B", "C"), "quaternion": ("Q1", "Q2", "Q3", "Q4"), "rotvec": ("RX", "RY", "RZ")}
AXIS_TYPES = frozenset({"AXIS", "E6AXIS", "JOINTTARGET", "JOINTS"})
_AXIS_FIELDS = frozenset({f"A{i}" for i in range(1, 7)})
_XYZ = ("X", "Y", "Z")


@dataclass
class PoseView:
    """A value as a motion's target: ``kind`` "cart", "axis" or "other" (nothing that tells);
    ``xyz`` the X, Y, Z components and ``orient`` the orientation's numbers in ``form``
    (each a value: Tok, a float, Top, or None where the value leaves it out); ``config`` (S, T)
    as integers (-1 not stated); ``loc`` the aggregate it was written as."""

    kind: str
    xyz: list
    orient: list
    form: str
    config: tuple
    loc: Loc | None
    type: str = ""
    # the target's own robot base moves (an external axis it states: a track), a Top with why and
    # code (P225): the target is left as written as with an unknown frame; None: it stands still.
    # A frame that moves with a known external unit (``values.Moving``) over the axes the target
    # states takes the place of this Top (``targets.build``)
    moving: object = None
    # the external axis values the target states, by the unit's axis name (``E1``…``E6``,
    # ``GP2.J1``…; postproc.robot.external): a number, a Tok/Taint, a Top; only the axes in use
    external: dict | None = None


class Dialect:
    """The base: KUKA-like poses (X, Y, Z and the orientation of ``form`` as fields of a
    record), frames as such poses, tools as six numbers."""

    name = ""
    form = "abc"
    frame_names: tuple = ()  # the system variables that hold the frames (what a handler not read may set)
    implicit_arrays = False  # an element assigned to an undeclared name makes it an array (LS registers)
    # what a target name declared in none of the files read may be (P215's message)
    undeclared_hint = "a global of a data list or $config.dat not given?"
    # a call to a routine not read says so (P232: the run is not complete); the declared types of
    # the globals such a routine may move to or change, named in that message (``visible``)
    incomplete = True
    visible_types: frozenset = frozenset()
    # what such a routine may change, in P232's words
    visible_what = "the global targets, tools and frames"
    # the variable that holds the payload in force (a motion without its own ``Move.load`` carries
    # it): set to ``values.LOAD_NOT_SET`` where each entry starts, assigned by the dialect's load
    # statements (KRL ``$LOAD``, URScript ``set_payload``, Fanuc ``PAYLOAD[n]``); None: no such
    load_var: str | None = "$LOAD"
    # the names of a payload record's mass and centre of mass (KRL LOAD: M, CM; RAPID loaddata: MASS, COG)
    load_fields = (("M", "MASS"), ("CM", "COG"))

    def axis_values(self, value) -> list | None:
        """The six arm axis values (deg, the controller's convention) of a joint motion's target
        where every one is a known number (KRL's ``E6AXIS``/``AXIS``: A1…A6), else None."""
        fields = getattr(value, "fields", None)
        if not fields:
            return None
        out = [number(fields.get(f"A{k}")) for k in range(1, 7)]
        return None if any(v is None for v in out) else [float(v) for v in out]

    def __init__(self):
        self.procedures: dict = {}
        self.functions: dict = {}
        self.async_routines: set = set()
        # scope key → Top: data that code the entry does not run changes (a routine run from the
        # pendant, an event routine, another task): a run-time value wherever it is read (P233)
        self.runtime: dict = {}
        self._incomplete: dict = {}  # a call site's Loc → its P232 message (one per site)

    # ---------------------------------------------------------------- state
    def initial(self, unit) -> dict:
        """The state's variables before the program's data are declared."""
        return {}

    def enter(self, an, st, routine) -> None:
        """An entry routine starts: the payload not set (``load_var``); handlers' routines start
        with the frames unknown."""
        if self.load_var is not None:
            st.vars[("G", self.load_var)] = LOAD_NOT_SET
        if routine.name in self.async_routines:
            an.havoc(st, None, f"{routine.name} runs as a handler: what is in force then is not known", routine.loc)

    def uninitialised(self, decl):
        top = Top(f"{decl.written or decl.name} is not initialised", decl.loc)
        if decl.dims is not None:
            return Arr({}, top, decl.type)
        return top

    def undeclared(self, an, name: str):
        return Top(f"{name} is not declared in the files read", an.loc, P215)

    def implicit(self, an, name: str) -> tuple:
        """The scope key of a name assigned without a declaration."""
        act = an.act
        if act.routine is None:
            return ("M", act.module, name)
        return ("L", act.scope, name)

    def touched(self, an, st, names) -> list:
        """The state keys code not read may change: ``names`` (resolved where they are
        declared), or (None) every global."""
        if names is not None:
            out = []
            for n in names:
                key, _ = an.lookup(n, st)
                out.append(key if key is not None else ("G", n))
            return out
        return [k for k in st.vars if k[0] == "G"]

    def unread(self, an, st, site, why: str | None):
        """A routine not read (``site`` an Invoke or a Call; ``why``: another reason, a
        recursion): the variables passed to it escape and may change, so may every global;
        where the robot stands is not known after it."""
        name = site.name.split(".")[-1]
        loc = site.loc
        if why is None:
            self.not_read(an, st, site, f"{name}()")
        why = why or f"{name}() called at line {loc.line if loc else 0} is not in the files read"
        names = []
        for a in site.args:
            if a is None:
                continue
            v = an.eval(a, st)
            an.consume(v, f"passed to {name}(), which is not read")
            root = a
            while isinstance(root, (Field, Item)):
                root = root.base
            if isinstance(root, Name):
                names.append(root.name)
        an.havoc(st, tuple(names), why, loc)
        return an.havoc(st, None, why, loc)

    def not_read(self, an, st, site, what: str) -> None:
        """P232 at a call to a routine not read (``what``: how the message names it): the run is not
        complete — it may move the robot to the globals it can see and change them (named: the
        ``visible`` ones). One message per call site however often it runs (the first said)."""
        loc = site.loc
        if not self.incomplete or loc is None or an.rec is None:
            return
        message = self._incomplete.get(loc)
        if message is None:
            names = self.visible(an, st, site)
            seen = f": {listed(names)}" if names else ""
            message = self._incomplete[loc] = (
                f"{what} is in none of the files read and is not an instruction postproc knows: it may move the "
                f"robot, and change {self.visible_what} it can see{seen}; what it does is not known, the run is not "
                "complete")
        an.rec.note(P232, message, loc, False)

    def visible(self, an, st, site) -> list:
        """The globals a routine not read can see that matter (declared with a type of
        ``visible_types``), as written, in the order declared."""
        if not self.visible_types:
            return []
        return [an.written_names.get(k, k[-1]) for k, (t, _) in an.types.items()
                if k[0] == "G" and t.upper() in self.visible_types]

    def procedure(self, name: str):
        """The builtin procedure called ``name`` (None: not a builtin)."""
        return self.procedures.get(name)

    def function(self, name: str):
        return self.functions.get(name)

    def routine_key(self, an, name: str) -> str:
        """The key in ``Unit.routines`` of a routine called by ``name`` from the running routine."""
        return name

    # ---------------------------------------------------------------- values
    def field(self, an, base, name: str):
        if isinstance(base, Rec):
            v = base.fields.get(name)
            if v is None:
                return Top(f"{base.label or 'the value'}.{name} is not set", an.loc)
            return v
        if isinstance(base, Top):
            return base
        if isinstance(base, Mat):
            six = fr.matrix_to_frame(base.m)
            names = _XYZ + ABC
            if name in names:
                return float(six[names.index(name)])
        return Top(f"a .{name} of a value that has none", an.loc)

    def operate(self, an, op: str, args: list):
        """``op`` over values: + and − of a token and a constant keep the token (an offset);
        every other number is a Taint of the tokens it is computed from; a comparison and a
        logical operator read their operands (their tokens escape: the flow depends on them)."""
        if any(isinstance(a, Top) for a in args):
            return next(a for a in args if isinstance(a, Top)).carrying(*args)
        if op in ("+", "-") and len(args) == 2:
            a, b = args
            if isinstance(a, Tok) and _constant(b):
                an.consume(b, "an offset added to a target's number")
                d = number(b)
                return Tok(a.value + d if op == "+" else a.value - d, a.token, a.offset + (d if op == "+" else -d))
            if op == "+" and isinstance(b, Tok) and _constant(a):
                an.consume(a, "an offset added to a target's number")
                return Tok(number(a) + b.value, b.token, b.offset + number(a))
            if isinstance(a, str) and isinstance(b, str) and op == "+":
                return a + b
        if op == "compose":
            return self.compose(an, args)
        if op == "inv":
            m = self.frame(an, args[0])
            return m if isinstance(m, Top) else frame_inverse(m, f"INV_POS({m.label})")
        logical = op in ("==", "<>", "!=", "<", "<=", ">", ">=", "and", "or", "xor", "not")
        if logical:
            for a in args:
                an.consume(a, f"a comparison or logic ({op})")
        vals = [number(a) if not isinstance(a, (bool, str)) else a for a in args]
        try:
            value = _apply(op, vals)
        except (TypeError, ValueError, ZeroDivisionError, ArithmeticError):
            return Top(f"an operation ({op}) the analysis does not evaluate", an.loc)
        if logical or isinstance(value, (bool, str)):
            return value
        return taint(value, *args)

    def compose(self, an, args: list):
        """``F1:F2:…``: frames composed; a pose on the right is that pose in the left frame."""
        *lefts, right = args
        m = np.eye(4)
        labels, toks = [], set()
        moving = None
        for a in lefts:
            f = self.frame(an, a)
            if isinstance(f, Top):
                return f
            if isinstance(f, Moving) or moving is not None:  # (a frame on an external unit)
                moving = frame_product(moving if moving is not None else Mat(m, "", frozenset(toks)), f)
                if isinstance(moving, Top):
                    return moving
                continue
            m = m @ f.m
            labels.append(f.label)
            toks |= f.tokens
        view = self.view(right) if isinstance(right, Rec) else None
        if moving is not None:
            if view is not None and view.kind == "cart" and right.type not in ("FRAME",):
                from ...core.diagnostics import P225

                return Top(f"a pose composed with a frame on the {moving.unit.describe()}: its numbers depend on the "
                           "unit's axis", an.loc, P225)
            f = self.frame(an, right)
            if isinstance(f, Top):
                return f
            out = frame_product(moving, f)
            if not isinstance(out, Top):
                out.label = ":".join(labels + [f.label])
            return out
        if view is not None and view.kind == "cart" and right.type not in ("FRAME",):
            f = self.frame(an, right)
            if isinstance(f, Top):
                return f
            six = fr.matrix_to_frame(m @ f.m)
            fields = dict(right.fields)
            for k, x in zip(_XYZ + ABC, six):
                fields[k] = float(x)
            return Rec(right.type, fields, None)
        f = self.frame(an, right)
        if isinstance(f, Top):
            return f
        if isinstance(f, Moving):
            out = frame_product(Mat(m, "", frozenset(toks)), f)
            if not isinstance(out, Top):
                out.label = ":".join(labels + [f.label])
            return out
        return Mat(m @ f.m, ":".join(labels + [f.label]), frozenset(toks | f.tokens))

    def frame(self, an, value):
        """A value as a frame (robot base ← its coordinates): Mat, or Top with why; its tokens
        are read (they escape)."""
        if isinstance(value, (Mat, Moving, Top)):
            if value.tokens:
                an.consume(value, "a frame")
            return value
        if isinstance(value, Rec):
            view = self.view(value)
            nums = [number(v) for v in view.xyz] + [number(v) for v in view.orient]
            unknown = next((v for v in view.xyz + view.orient if isinstance(v, Top)), None)
            if unknown is not None:
                an.consume(value, "a frame")
                return Top(unknown.why, unknown.loc)
            if view.kind == "cart" and None not in nums:  # (not finite: a frame P103 refuses, findings.frame_rule)
                an.consume(value, "a frame")
                m = np.eye(4)
                with np.errstate(invalid="ignore", over="ignore"):
                    m[:3, :3] = fr.orientation_rotation(np.array(nums[3:], float), view.form)
                m[:3, 3] = nums[:3]
                return Mat(m, value.label, frozenset(tokens_of(value)))
            return Top(f"{value.label or 'a frame'} is not a fully known frame", an.loc)
        return Top("not a frame", an.loc)

    def tool(self, an, value):
        """A value as the TCP on the flange: six numbers X,Y,Z,A,B,C, None (the model's own:
        ``"model"``), or Top."""
        if value == "model":
            return None
        f = self.frame(an, value)
        if isinstance(f, Top):
            return f
        if isinstance(f, Moving):
            from ...core.diagnostics import P203

            return Top(f"the tool is on the {f.unit.describe()}: a stationary tool", an.loc, P203)
        return Six(fr.matrix_to_frame(f.m), f.label)

    def load(self, an, value):
        """A value as the payload at a motion: ``values.Load`` (mass kg, centre of mass mm in the
        flange frame), None (not set: the model's reference load, or the one stated with
        ``--load``), or Top (not known statically: P235 where the model takes the load). A record
        with a mass (``load_fields``: KRL's M, RAPID's MASS) and a centre of mass (CM / COG: X, Y,
        Z); a negative mass is KUKA's "the machine data's default load": not known. Its numbers
        are read (they escape)."""
        if value is None or isinstance(value, NotSet):
            return None
        if isinstance(value, Load):
            return value
        if isinstance(value, Top):
            return value if value.code == P235 else Top(value.why, value.loc, P235, value.tokens)
        if isinstance(value, Rec):
            an.consume(value, "a payload")
            (m_names, cm_names) = self.load_fields
            mass = next((value.fields[k] for k in m_names if k in value.fields), None)
            cm = next((value.fields[k] for k in cm_names if k in value.fields), None)
            label = value.label or "the payload"
            if isinstance(mass, Top):
                return Top(mass.why, mass.loc or an.loc, P235)
            m = number(mass)
            if m is None:
                return Top(f"{label} has no known mass", value.loc or an.loc, P235)
            if m < 0:
                return Top(f"{label} has mass {m:g}: the machine data's default load, not in the files read", an.loc,
                           P235)
            xyz = [0.0, 0.0, 0.0]
            if cm is None and m != 0:
                return Top(f"the centre of mass of {label} is not set (only its mass)", value.loc or an.loc, P235)
            if cm is not None:
                if isinstance(cm, Top):
                    return Top(f"its centre of mass: {cm.why}", cm.loc or an.loc, P235)
                for k, name in enumerate("XYZ"):
                    v = cm.fields.get(name) if isinstance(cm, Rec) else None
                    if isinstance(v, Top):
                        return Top(f"its centre of mass: {v.why}", v.loc or an.loc, P235)
                    x = number(v) if v is not None else 0.0
                    if x is None:
                        return Top(f"the centre of mass of {label} is not a number", an.loc, P235)
                    xyz[k] = x
            if not all(np.isfinite([m] + xyz)):
                return Top(f"{label} is not finite", an.loc, P235)
            return Load([m] + xyz, label)
        return Top("the payload is not a load record", an.loc, P235)

    SCALARS = frozenset({"INT", "REAL", "BOOL", "CHAR", "NUM", "DNUM", "BYTE", "FLOAT"})

    def scalar(self, type_: str) -> bool:
        """A declared type whose numbers are constants of the program, never a target's
        component (a token read through it is not that target's)."""
        return type_.upper() in self.SCALARS

    def record_of(self, m: Mat) -> Rec:
        """A computed frame as a record of its components (to set one of them)."""
        six = fr.matrix_to_frame(m.m)
        return Rec("FRAME", {k: float(x) for k, x in zip(_XYZ + ABC, six)}, None, m.label)

    # ---------------------------------------------------------------- poses
    def view(self, value) -> PoseView:
        """A record as a motion's target (see PoseView)."""
        fields = value.fields
        names = ORIENTATION_FIELDS[self.form]
        kind = "other"
        if value.type in AXIS_TYPES or (fields.keys() & _AXIS_FIELDS and not fields.keys() & set(_XYZ)):
            kind = "axis"
        elif fields.keys() & set(_XYZ) or value.type in ("POS", "E6POS", "FRAME", "ROBTARGET", "POSE"):
            kind = "cart"
        config = tuple(_status(fields.get(k)) for k in ("S", "T"))
        return PoseView(kind, [fields.get(k) for k in _XYZ], [fields.get(k) for k in names], self.form, config,
                        value.loc, value.type)

    def row_extras(self, use, view) -> dict:
        """A dialect's own columns for the row of ``use`` (an ``execute.Use`` whose target is
        ``view``): name → value (``Built.extras``; e.g. RAPID's confdata, Fanuc's CONFIG)."""
        return {}

    def run_extras(self, run) -> dict:
        """The same for a MoveRun's rows: name → a sequence of len(run) values."""
        return {}

    def position(self, target):
        """Where the robot stands after a motion to ``target`` (for the partial targets after it)."""
        names = _XYZ + ORIENTATION_FIELDS[self.form]
        return tuple((k, number(target.fields.get(k))) for k in names)

    def halts(self, an, st, move) -> str | None:
        """Why the controller stops the program at ``move`` (an alarm) with the values a concrete
        run has (the interpreter asks; the analysis does not): None, it moves. The default: never."""
        return None

    def fill(self, target: Rec, cur, frame):
        """A target aggregate that leaves components out takes them from where the robot stands
        (``cur``, in the same frame): (the target, the names filled). The default: none."""
        return target, ()

    def run_position(self, run, cur, frame):
        """Where the robot stands after a MoveRun: its last row that becomes the position."""
        rows = run.rows
        chain = np.flatnonzero(rows["chain"])
        if not len(chain):
            return cur
        pose, written = rows["pose"], rows["written"]
        names = _XYZ + ORIENTATION_FIELDS[self.form]
        out = []
        last = int(chain[-1])
        for k, name in enumerate(names[:6]):
            w = np.flatnonzero(written[chain, k])
            if len(w):
                out.append((name, float(pose[chain[w[-1]], k])))
            else:
                prev = dict(cur[0]).get(name) if cur is not None and _same_frame(cur[1], frame) else None
                out.append((name, prev))
        del last
        return (tuple(out), frame)

    # ---------------------------------------------------------------- handlers
    def writes(self, an, action, st) -> set:
        """The state keys a handler's action may write (its assignments; a routine it calls:
        that routine's assignments to what is not its own; a routine not read: every global)."""
        out: set = set()
        self._writes(an, action, out, set(), st)
        return out

    def _writes(self, an, action, out: set, seen: set, st) -> None:
        if isinstance(action, Assign):
            root = action.target
            while isinstance(root, (Field, Item)):
                root = root.base
            if isinstance(root, Name):
                out.add(self._key_of(an, root.name, st))
        elif isinstance(action, Invoke):
            routine = an.unit.routines.get(self.routine_key(an, action.name))
            if routine is None:
                if self.procedure(action.name) is None:  # code not read: the frames and the payload (not points)
                    out.update(("G", n) for n in self.frame_names)
                    if self.load_var is not None:
                        out.add(("G", self.load_var))
                return
            if routine.name in seen:
                return
            seen.add(routine.name)
            own = {p.name for p in routine.params}
            local = {s.name for s in walk(routine.body) if isinstance(s, Decl) and s.scope == "local"}
            for s in walk(routine.body):
                if isinstance(s, Assign):
                    root = s.target
                    while isinstance(root, (Field, Item)):
                        root = root.base
                    if isinstance(root, Name) and root.name not in own and root.name not in local:
                        out.add(self._key_of(an, root.name, st))
                elif isinstance(s, Invoke):
                    self._writes(an, s, out, seen, st)

    def _key_of(self, an, name: str, st) -> tuple:
        key, _ = an.lookup(name, st)
        return key if key is not None else ("G", name)

    def unread_handler(self, an, st, s):
        """A handler whose code is not read (``s.action`` calls it): the frames unknown from its
        declaration until the program sets them again."""
        why = f"{s.action.name}() (the {s.what} declared at line {s.loc.line}) is not in the files read"
        top = Top(why, s.loc)
        for name in self.frame_names + ((self.load_var,) if self.load_var is not None else ()):
            st.vars[("G", name)] = top
        return st

    def handler_reached(self, an, s) -> None:
        action = s.action
        if isinstance(action, Invoke) and action.name in an.unit.routines:
            self.async_routines.add(action.name)

    def handler_code(self, key) -> str | None:
        return None


def _same_frame(a, b) -> bool:
    if isinstance(a, Mat) and isinstance(b, Mat):
        return a == b
    return a is b


def _plain(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _constant(v) -> bool:
    """A number that is no target's own token: a plain number or a Taint (a scalar's copy)."""
    return _plain(v) or isinstance(v, Taint)


def _status(v) -> int:
    """S or T as written → an int 0…32767, -1 where not stated or not a whole number."""
    if isinstance(v, str) and len(v) >= 3 and v[0] == "'" and v[-1] == "'":
        digits, base = v[2:-1], (2 if v[1] in "Bb" else 16)
        try:
            x = int(digits, base) if digits else -1
        except ValueError:
            return -1
        return x if 0 <= x <= 32767 else -1
    x = number(v)
    if x is None or not np.isfinite(x) or x != int(x) or not 0 <= x <= 32767:
        return -1
    return int(x)


def _apply(op: str, v: list):
    if op == "+":
        return v[0] + v[1]
    if op == "-":
        return v[0] - v[1]
    if op == "*":
        return v[0] * v[1]
    if op == "/":
        return v[0] / v[1]
    if op == "div":
        return float(int(v[0]) // int(v[1]))
    if op == "mod":
        return float(int(v[0]) % int(v[1]))
    if op == "neg":
        return -v[0]
    if op == "not":
        return (not v[0]) if isinstance(v[0], bool) else float(~int(v[0]))
    if op in ("and", "or", "xor"):
        a, b = v
        if isinstance(a, bool) and isinstance(b, bool):
            return {"and": a and b, "or": a or b, "xor": a != b}[op]
        a, b = int(a), int(b)
        return float({"and": a & b, "or": a | b, "xor": a ^ b}[op])
    if op in ("==", "<>", "!=", "<", "<=", ">", ">="):
        a, b = v
        if op == "==":
            return a == b
        if op in ("<>", "!="):
            return a != b
        if isinstance(a, bool) or isinstance(b, bool) or a is None or b is None:
            raise TypeError
        return {"<": a < b, "<=": a <= b, ">": a > b, ">=": a >= b}[op]
    raise ValueError(op)

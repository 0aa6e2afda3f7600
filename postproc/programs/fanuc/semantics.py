"""What Fanuc LS means, written once for the analysis (``analysis.dialect.Dialect``).

* A position ``P[n]`` is the program's own (its ``/POS`` record: X, Y, Z, W, P, R with W, P, R
  fixed angles about X, Y, Z, i.e. KUKA A = R, B = P, C = W; its UF, UT and CONFIG). A motion to
  it is in the position's own user frame UF and tool frame UT: the controller stops where they
  are not the selected ones (INTP-250, user frame mismatch, with its default frame check) —
  where the program selects others (``UFRAME_NUM``, ``UTOOL_NUM`` known and different) the target
  is left (P201/P203: stopped, or moved in the selected frame with the check off). The frames' values from the frame file given
  with ``--frames`` (``UFRAME[n]``/``UTOOL[n]``; UF 0 = the world, taken as the robot base; UT 0
  = the flange) or as the program sets them (``UFRAME[1]=PR[2]``).
* A position register ``PR[n]`` holds a position without frame numbers: a motion to it is in
  the user and tool frame selected then (``UFRAME_NUM``, ``UTOOL_NUM``: not known where the
  program does not select them); registers ``R[n]``/``PR[n]`` hold what was set before the
  program runs until it sets them. ``PR[n]=P[m]`` copies the position's numbers (the rows of
  both share its tokens); ``PR[i]=PR[j]+PR[k]`` adds component by component; ``PR[n,k]`` is
  one component (1…6: X, Y, Z, W, P, R).
* ``Offset,PR[n]`` (or the ``OFFSET CONDITION`` register) shifts the target by the register's
  X, Y, Z in the position's user frame: a target + constant offset where the register is known
  and turns nothing; ``Tool_Offset`` shifts it in the tool frame at the position (pose · offset:
  its X, Y, Z + the register's X, Y, Z turned by the position's orientation, a constant offset;
  the orientation computed); a register that moves extended axes, and anything else about an
  offset, is known only at run time.
* A program called (``CALL``) that is among the files read runs there; one not read: the
  registers and the selected frame numbers are not known after it (the frame file's
  ``UFRAME[n]``/``UTOOL[n]`` are the cell's configuration, which only the program's own
  statements change); one started with ``RUN`` runs beside it and may change the registers at
  any time.
* A backup's cell data (``cell``: ``backup.Served``) gives the frames and registers that are not
  in the state (``undeclared``): sysframe.va's frames, posreg.va's / numreg.va's registers that
  no TP program read sets; each use is said once per register and program file (P234).
* A position that moves other groups (``GP2``…) or extended axes (``E1``…) is reached with axes
  postproc has no kinematics of (a track, a positioner): left as written (P225) — unless a track
  that carries the robot is given (``--external`` or the frame file's ``[[external]]``, axis
  ``E1`` or ``GP2.J1``) and it is the only axis the position moves: the user frames stand in the
  world, the robot's base rides the track at the position's value (``_on_track``).
"""
from __future__ import annotations

import re

import numpy as np

from ...core import frames as fr
from ...core.diagnostics import P201, P203, P211, P215, P223, P225, P234
from ..analysis.dialect import Dialect, PoseView
from ..analysis.values import Mat, Moving, Rec, Six, Taint, Tok, Top, frame_inverse, frame_product, number, tokens_of, whole_number

_EXTERNAL = re.compile(r"^(?:E[1-9]|GP[2-9]\.J[1-9])$")

__all__ = ["LS", "COMPONENTS"]

# PR[n,k]: the component k of a position register (W, P, R are KUKA's C, B, A)
COMPONENTS = {1: "X", 2: "Y", 3: "Z", 4: "C", 5: "B", 6: "A"}
_POSE = ("X", "Y", "Z", "A", "B", "C")


class LS(Dialect):
    """The LS dialect: ``uframes`` / ``utools`` the frame file's (number → 4×4 / X,Y,Z,A,B,C),
    ``registers`` every R[…]/PR[…] name the program uses (what a program started with RUN may
    change at any time)."""

    name = "LS"
    form = "abc"
    frame_names = ("UFRAME_NUM", "UTOOL_NUM")
    undeclared_hint = ""

    def __init__(self, uframes: dict, utools: dict, registers=(), external: tuple = (), cell=None):
        super().__init__()
        # a backup's cell data (``backup.Served``): the values of frames and registers not set in
        # the program's state, each use said once per file (P234)
        self.cell = cell
        self.noted: set = set()
        self.external = tuple(external or ())
        # a track that carries the robot (group 1's extended axis E1 or a group-2 axis GP2.J1): the
        # user frames stand in the world, the robot's base rides on the track
        self.track = next((u for u in self.external if u.carries == "robot"), None)
        self.uframes = uframes
        self.utools = utools
        self.registers = set(registers)
        self.functions = {"LS.PAYLOAD": payload_of, "LS.UFRAME": uframe_of, "LS.UTOOL": utool_of, "LS.AS_PR": as_register,
                          "LS.Offset": offset, "LS.Tool_Offset": tool_offset, "LS.P": indirect, "LS.PR": indirect,
                          "LS.R": indirect, "LS.READ": read}

    # ---------------------------------------------------------------- state
    def initial(self, unit) -> dict:
        out = {}
        for n, m in self.uframes.items():
            out[("G", f"UFRAME[{n}]")] = Mat(m, f"UF {n}")
        for n, t in self.utools.items():
            out[("G", f"UTOOL[{n}]")] = Six(t, f"UT {n}")
        out[("G", "UFRAME_NUM")] = Top("the user frame selected when the program starts is not known: UFRAME_NUM is "
                                       "not set before this target", None, P201)
        out[("G", "UTOOL_NUM")] = Top("the tool frame selected when the program starts is not known: UTOOL_NUM is not "
                                      "set before this target", None, P203)
        return out

    def undeclared(self, an, name: str):
        cell = self.cell
        if cell is not None:
            if name in cell.values:
                note = cell.notes.get(name)
                if note is not None and an.rec is not None and an.loc is not None and \
                        (an.loc.file, name) not in self.noted:  # (once per register and program file)
                    self.noted.add((an.loc.file, name))
                    an.rec.note(P234, note, an.loc, False)
                return cell.values[name]
            if name in cell.why:
                why, code = cell.why[name]
                return Top(why, an.loc, code)
        also = " nor in sysframe.va" if cell is not None and cell.frames else ""
        if name.startswith("UFRAME["):
            return Top(f"user frame UF {name[7:-1]} is not in the frame file (--frames){also}", an.loc, P201)
        if name.startswith("UTOOL["):
            return Top(f"tool frame UT {name[6:-1]} is not in the frame file (--frames){also}", an.loc, P203)
        if name.startswith("P["):
            return Top(f"{name} has no record in /POS", an.loc, P215)
        if name.startswith(("R[", "PR[")):
            return Top(f"{name} holds what was set before the program runs", an.loc, P211)
        return Top(f"{name} is known only at run time", an.loc, P211)

    def implicit(self, an, name: str) -> tuple:
        return ("G", name)  # (registers and the selected frames are the controller's)

    def touched(self, an, st, names) -> list:
        """A program not read: the registers and the selected frame numbers (not the frame
        file's UFRAME[n]/UTOOL[n], nor this program's own positions)."""
        if names is not None:
            return []
        keys = [k for k in st.vars if k[0] == "G" and k[1].startswith(("R[", "PR["))]
        return keys + [("G", n) for n in self.frame_names] + [("G", n) for n in self.registers] + \
            [("G", self.load_var)]  # (the payload: a program not read may select another, PAYLOAD[n])

    def unread_handler(self, an, st, s):
        """``RUN prog``: the program runs beside this one and may set every register and the
        selected frames at any time while it runs (to the end of this one)."""
        why = f"may be set by {s.action.name} (started with RUN at line {s.loc.line}, not read)"
        writes = {("G", n) for n in self.registers} | {("G", n) for n in self.frame_names} | {("G", self.load_var)}
        an.handlers[id(s)] = (s, writes, why)
        st.on = st.on | {id(s)}
        return an._pin(st)

    def handler_code(self, key):
        return None if key[-1] in self.frame_names else P223

    # ---------------------------------------------------------------- values
    def operate(self, an, op: str, args: list):
        """``PR[i]+PR[j]``, ``PR[i]-PR[j]``: component by component."""
        if op in ("+", "-") and len(args) == 2 and all(isinstance(a, Rec) for a in args):
            a, b = args
            fields = dict(a.fields)
            for k in _POSE:
                x, y = a.fields.get(k), b.fields.get(k)
                if x is None or y is None:
                    return Top(f"a position register's {k} is not set", an.loc)
                fields[k] = super().operate(an, op, [x, y])
            return Rec(a.type, fields, None)
        if op in ("+", "-") and any(isinstance(a, Rec) for a in args):
            return Top(f"{op} of a position and a number", an.loc)
        return super().operate(an, op, args)

    def view(self, value) -> PoseView:
        v = super().view(value)
        if value.type == "JOINTS":
            v.kind = "axis"
        if v.kind == "cart":  # (group 1's extended axes E1…, the other groups' GP2.J1…: postproc.robot.external)
            v.external = {k: x for k, x in value.fields.items() if _EXTERNAL.match(k)}
        return v

    def tool(self, an, value):
        if isinstance(value, Six):
            return value
        return super().tool(an, value)

    def halts(self, an, st, move) -> str | None:
        """A position taught in UF n (UT n) run while another user (tool) frame number is selected:
        the controller's frame check ($MCR.$UFRCHK, on by default) stops the program (INTP-250/252).
        The analysis takes a position whose selected frame is not known in its own UF on this
        ground."""
        target = an.eval(move.target, st) if move.frame is not None else None
        if not isinstance(target, Rec):
            return None
        for field, name in (("UF", "UFRAME_NUM"), ("UT", "UTOOL_NUM")):
            own = whole_number(target.fields.get(field))
            _, selected = an.lookup(name, st)
            active = whole_number(selected) if not isinstance(selected, Top) else None
            if own is not None and active is not None and own != active:
                return f"{target.label or 'the position'} is taught in {field} {own} and {name}={active} is selected"
        return None

    def row_extras(self, use, view) -> dict:
        config = use.target.fields.get("CONFIG") if isinstance(use.target, Rec) else None
        return {"config": config if isinstance(config, str) else ""}


# ------------------------------------------------------------------------------- builtins


def uframe_of(an, st, args, call):
    """``LS.UFRAME(target, UFRAME_NUM)``: the user frame of a motion's target: a position's own
    UF, a register's the selected one; a position moving other groups: not known (P225)."""
    target, selected = args
    key, moving = an.lookup("$MOVING", st)
    if key is not None and isinstance(moving, Top):  # (line tracking: every target moves with the conveyor)
        return moving
    track = an.dialect.track
    if isinstance(target, Rec):
        ext = target.fields.get("EXT")
        moved = {k for k in target.fields if _EXTERNAL.match(k)}
        if isinstance(ext, str) and (track is None or moved != {track.axis}):
            return Top(ext if track is None else f"{ext} (the track given is {track.axis})", an.loc, P225)
        uf = target.fields.get("UF")
        if uf is not None:
            n = whole_number(uf)
            if n is None:
                return Top(f"user frame UF {uf} of {target.label or 'the position'} is not in the frame file "
                           "(--frames)", an.loc, P201)
            active = whole_number(selected)
            if active is not None and active != n:
                return Top(f"the position is taught in UF {n} and UFRAME_NUM={active} is selected: the controller "
                           f"stops (user frame mismatch) or, with its frame check off, moves in UF {active}", an.loc, P201)
            return _on_track(an, _frame(an, st, f"UFRAME[{n}]"))
    if isinstance(selected, Top):
        return selected
    n = whole_number(selected)
    if n is None:
        return Top("UFRAME_NUM is not a frame number", an.loc, P201)
    return _on_track(an, _frame(an, st, f"UFRAME[{n}]"))


def _on_track(an, frame):
    """A user frame (fixed in the world) seen from the robot's base on the track: the track at the
    target's axis value, inverted, times the frame (postproc.robot.external)."""
    track = an.dialect.track
    if track is None or isinstance(frame, Top):
        return frame
    return frame_product(frame_inverse(Moving(track, label="track")), frame, frame.label)


def _frame(an, st, name):
    key, value = an.lookup(name, st)
    if key is None:
        value = an.dialect.undeclared(an, name)
    f = an.dialect.frame(an, value)
    if isinstance(f, Top):
        return Top(f.why, f.loc, P201)
    return f if f.label else Mat(f.m, "UF " + name[7:-1], f.tokens)


def utool_of(an, st, args, call):
    """``LS.UTOOL(target, UTOOL_NUM)``: the tool frame of a motion's target (as LS.UFRAME)."""
    target, selected = args
    n = None
    if isinstance(target, Rec) and target.fields.get("UT") is not None:
        ut = target.fields.get("UT")
        n = whole_number(ut)
        if n is None:
            return Top(f"tool frame UT {ut} of {target.label or 'the position'} is not in the frame file (--frames)",
                       an.loc, P203)
        active = whole_number(selected)
        if active is not None and active != n:
            return Top(f"the position is taught with UT {n} and UTOOL_NUM={active} is selected: the controller stops "
                       f"(tool frame mismatch) or, with its frame check off, moves with UT {active}", an.loc, P203)
    else:
        if isinstance(selected, Top):
            return selected
        n = whole_number(selected)
        if n is None:
            return Top("UTOOL_NUM is not a tool number", an.loc, P203)
    name = f"UTOOL[{n}]"
    key, value = an.lookup(name, st)
    if key is None:
        value = an.dialect.undeclared(an, name)
    if isinstance(value, Six):
        return value
    t = an.dialect.tool(an, value)
    if isinstance(t, Top):
        return Top(t.why, t.loc, P203)
    return t if t is None or t.label else Six(t, f"UT {n}")


def as_register(an, st, args, call):
    """``PR[n] = value``: a position's numbers without its frame numbers (a register's target is
    in the frames selected where it runs); a frame (``UFRAME[n]``) as its components."""
    (v,) = args
    if isinstance(v, Mat):
        return an.dialect.record_of(v)
    if isinstance(v, Rec):
        fields = {k: x for k, x in v.fields.items() if k not in ("UF", "UT")}
        return Rec(v.type, fields, v.loc, v.label)
    return v


def _known_shift(an, reg, what: str):
    """A register's X, Y, Z as three plain numbers where it turns nothing, or a Top."""
    if isinstance(reg, Top):
        return Top(f"{what} ({reg.why})", reg.loc or an.loc, P211)
    if not isinstance(reg, Rec):
        return Top(f"{what} is not a position register", an.loc, P211)
    values = [reg.fields.get(k) for k in _POSE]
    if any(isinstance(x, Top) for x in values):
        return Top(f"{what}: {next(x for x in values if isinstance(x, Top)).why}", an.loc, P211)
    nums = [number(x) for x in values]
    if None in nums:
        return Top(f"{what} is not fully known", an.loc, P211)
    moved = [k for k, x in reg.fields.items() if _EXTERNAL.match(k) and number(x) != 0.0]
    if moved:  # (how the controller adds an offset to a track's axis is not read here)
        unset = [k for k in moved if number(reg.fields[k]) is None]
        return Top(f"{what}'s {', '.join(unset)} not known" if unset else
                   f"{what} moves the extended axes {', '.join(moved)} too", an.loc, P211)
    return nums


def offset(an, st, args, call):
    """``Offset,PR[n]``: the target shifted by the register's X, Y, Z in its user frame (a
    rotation in the register: known only at run time here)."""
    target, reg = args
    if isinstance(target, Top):
        return target
    an.consume(reg, "an Offset")
    nums = _known_shift(an, reg, "the Offset register")
    if isinstance(nums, Top):
        an.consume(target, "an Offset motion's position")
        return nums
    if any(abs(x) > 1e-12 for x in nums[3:]):
        an.consume(target, "an Offset motion's position")
        return Top("the Offset register turns the position (W, P, R not 0): computed at run time", an.loc, P211)
    if not isinstance(target, Rec):
        return Top("an Offset of a value that is not a position", an.loc, P211)
    fields = dict(target.fields)
    for k, d in zip(("X", "Y", "Z"), nums[:3]):
        if k in fields:
            fields[k] = an.dialect.operate(an, "+", [fields[k], float(d)])
    return Rec(target.type, fields, target.loc, target.label)


def tool_offset(an, st, args, call):
    """``Tool_Offset,PR[n]``: the target moved by the register in its tool frame, as the controller
    moves it (the offset is in the tool coordinate system at the position: pose · offset). Its
    X, Y, Z are the position's plus R·t (R the position's orientation, t the register's X, Y, Z): a
    constant added to the position's own numbers, which are rewritten; its orientation R·R_offset
    is computed (not rewritten: --orientation refuses it, P312, since a new W, P, R would turn the
    shift). A register that is all zero moves nothing; one not known: known only at run time."""
    target, reg = args
    an.consume(reg, "a Tool_Offset")
    if isinstance(target, Top):
        return target
    nums = _known_shift(an, reg, "the Tool_Offset register")
    if isinstance(nums, Top):
        an.consume(target, "a Tool_Offset motion's position")
        return nums
    if all(abs(x) < 1e-12 for x in nums):
        return target
    if not isinstance(target, Rec) or None in [number(target.fields.get(k)) for k in _POSE]:
        an.consume(target, "a Tool_Offset motion's position")
        return Top("a Tool_Offset of a position not fully known", an.loc, P211)
    p = fr.frame_to_matrix(np.array([number(target.fields[k]) for k in _POSE], float))
    m = p @ fr.frame_to_matrix(np.array(nums, float))
    fields = dict(target.fields)
    for k, d in zip(("X", "Y", "Z"), np.round(m[:3, 3] - p[:3, 3], 9)):
        fields[k] = an.dialect.operate(an, "+", [fields[k], float(d)])
    toks = frozenset().union(*(tokens_of(target.fields[k]) for k in ("A", "B", "C")))
    for k, x in zip(("A", "B", "C"), fr.matrix_to_frame(m)[3:]):
        fields[k] = Taint(float(x), toks) if toks else float(x)
    return Rec(target.type, fields, target.loc, target.label)


def indirect(an, st, args, call):
    """``P[R[k]]``, ``PR[R[k]]``, ``R[R[k]]``: the element the index register holds."""
    (index,) = args
    kind = call.name.split(".")[-1]
    an.consume(index, "an index")
    n = whole_number(index)
    if n is None:
        why = index.why if isinstance(index, Top) else "an index that is not a whole number"
        return Top(f"{kind}[…] with a run-time index ({why})", an.loc, P211)
    name = f"{kind}[{n}]"
    key, value = an.lookup(name, st)
    if key is None:
        value = an.dialect.undeclared(an, name)
        if isinstance(value, Top) and value.code == P215:
            return Top(value.why, value.loc, P211)
    return value


def read(an, st, args, call):
    """``LS.READ(value, why)``: a value read by something other than a target (an INC motion's
    increment, a vision offset's position)."""
    value, why = args
    an.consume(value, why)
    return value


# (kept importable)
_ = Tok


class Schedule(Top):
    """The payload of the controller's schedule ``PAYLOAD[schedule]``: its numbers are the controller's
    (not in an LS program): not known unless its user states them (settings ``payloads``,
    ``--payload N=MASS,CX,CY,CZ``: ``compensation.findings.load_rule``)."""

    __slots__ = ("schedule",)

    def __init__(self, schedule: int, loc):
        from ...core.diagnostics import P235

        super().__init__(f"PAYLOAD[{schedule}]: the payload schedule's numbers are the controller's, not in the files "
                         f"read (state them with --payload {schedule}=MASS,CX,CY,CZ or the settings' payloads)", loc,
                         P235)
        self.schedule = schedule


def payload_of(an, st, args, call):
    """``PAYLOAD[n]``: the controller's payload schedule n in force from here (``Schedule``)."""
    from ...core.diagnostics import P235

    n = whole_number(args[0]) if args else None
    an.consume(args[0] if args else None, "PAYLOAD[…]")
    if n is None:
        why = args[0].why if args and isinstance(args[0], Top) else "a number known only at run time"
        return Top(f"PAYLOAD[…] with {why}", call.loc or an.loc, P235)
    return Schedule(n, call.loc or an.loc)


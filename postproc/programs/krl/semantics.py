"""What KRL means, written once for the analysis (``analysis.dialect.Dialect``).

* The frame of a target is ``INV_POS($ROBROOT):$BASE`` (and the left operands of ``:``):
  :func:`frame_of` (``KRL.FRAME``); its tool ``$TOOL``. At a program's start they are what its
  user states (``ActiveFrames``: ``--base``/``--tool``/``--robroot``, a backup's machine data)
  or not set (P220/P221 at the targets that need them); $ROBROOT not known is the robot base =
  world, said once (P224). On a track whose kinematics are given (``--external``, the machine
  data's $ERSYS kinematic: ``KRL.track``) $ROBROOT moves with it (``values.Moving``), known at
  each target from the E1… it states; a track whose kinematics are not given: P225.
* ``BAS(#BASE, n)`` is KSS's bas.src: ``$BASE = BASE_DATA[n]`` (n = 0: $NULLFRAME), on top of
  it ``BASE_CORR`` where ``BASE_CORR_ON`` is TRUE; where ``MACHINE_FRAME_DAT[n].MACH_DEF_INDEX``
  names an external kinematic (a turntable, a positioner) the base moves with its axis: known at
  each target where a unit with that ``machine_def`` is given (``KRL.positioner``), else P225. ``BAS(#TOOL, n)`` likewise with TOOL_DATA and
  MACHINE_TOOL_DAT. ``BAS(#PTP_PARAMS|#CP_PARAMS|#FRAMES, …)`` take both from ``FDAT_ACT``
  (TOOL_NO, BASE_NO; ``IPO_FRAME #TCP``: an external TCP, not supported). Variables the
  program and the files read do not declare (``BASE_CORR_ON``) are KSS's defaults (FALSE, 0).
* A partial aggregate as a motion's target (``LIN {Z 1250}``) takes its missing components
  from the current position (the previous target, as commanded: the rewrite writes them in).
* A routine not read may change the frames, its arguments and the globals of the data lists
  (``DECL GLOBAL``); ``$config.dat``'s BASE_DATA / TOOL_DATA are taken as the cell's
  configuration, which only the program's own statements change.
* System functions that set no frame (``HARMLESS``, ``BUILTIN_FUNCTIONS``): KSS's motion
  parameter functions (``SVEL_JOINT``, ``SAPO``…), string and math functions, and
  ``USE_CM_PRO_VALUES`` (KSS collmonlib.src: the collision-monitoring tolerance an inline form
  assigns to ``$COLLMON_TOL_PRO``).
"""
from __future__ import annotations

import math
import re

import numpy as np

from ...core.diagnostics import P201, P203, P211, P215, P220, P221, P222, P223, P225, P235, PostprocError
from ...core.frames import frame_to_matrix
from ..analysis.dialect import Dialect, PoseView
from ..analysis.values import Arr, Mat, Moving, Rec, Six, Tok, Top, frame_inverse, frame_product, number, whole_number
from ..ir import Loc

__all__ = ["KRL", "HARMLESS", "BUILTIN_FUNCTIONS"]

# KUKA system subroutines that set no frame and move nothing (BAS is a builtin of its own)
HARMLESS = frozenset({"SET_CD_PARAMS", "PULSE", "CWRITE", "CREAD", "SWRITE", "SREAD", "CAST_TO", "CAST_FROM",
                      "USE_CM_PRO_VALUES", "ON_ERROR_PROCEED", "ERR_CLEAR", "ERR_RAISE", "MSGNOTIFY", "MSGQUIT",
                      "MSGDIALOG", "MSGSTATE", "MSGLOOP"})
# KRL's built-in functions and KUKA's system functions: they set no frame
BUILTIN_FUNCTIONS = frozenset({
    "ABS", "SQRT", "SIN", "COS", "TAN", "ACOS", "ASIN", "ATAN2", "INV_POS", "FORWARD", "INVERSE", "VARSTATE",
    "STRLEN", "STRDECLLEN", "STRCLEAR", "STRCOPY", "STRCOMP", "STRFIND", "STRADD", "SBASE", "STOOL", "STOOL2",
    "SIPO_MODE", "SLOAD", "SACC_JOINT", "SVEL_JOINT", "SACC_CP", "SVEL_CP", "SORI_TYP", "SCIRC_TYP", "SAPO",
    "SAPO_PTP", "SJERK", "SPATH", "SGEAR_JERK", "SSTEP", "SCIRC_MODE", "STECH", "STECHPAR", "SVEL_TECH",
    "SACC_TECH", "SIPO", "EB_TEST", "EO_TEST", "IS_KEY_PRESSED", "GET_SIG_INF", "GETCYCDEF", "SET_KRLMSG",
    "SET_KRLDLG", "EXISTS_KRLMSG", "EXISTS_KRLDLG", "CLEAR_KRLMSG", "MBX_REC", "DELETE_BACKWARD_BUFFER",
    "GET_SYSTEM_DATA", "CAST_TO", "CAST_FROM", "CREAD", "CWRITE", "SREAD", "SWRITE", "USE_CM_PRO_VALUES",
})  # (EK: the frame of an external kinematic, ``semantics.ek``)
# KSS's interrupt handlers (bas.src's INI fold): they set no frame
SYSTEM_HANDLERS = frozenset({"IR_STOPM"})
# axis positions KUKA's $config.dat declares (a motion to them is an axis motion)
STANDARD_AXIS = re.compile(r"^XHOME\d*$|^\$AXIS_\w+$|^\$H_AXIS\w*$", re.I)
RUNTIME_POS = re.compile(r"^\$POS_\w+$", re.I)
_XYZABC = ("X", "Y", "Z", "A", "B", "C")
_EXTERNAL = tuple(f"E{k}" for k in range(1, 7))
_FRAMES = ("$BASE", "$TOOL", "$ROBROOT")
_EYE = np.eye(4)

BASE_NOT_SET = ("$BASE is not set before this target (the controller uses whatever base is active): set it in the "
                "program or state it with --base N|X,Y,Z,A,B,C")
TOOL_NOT_SET = ("$TOOL is not set before this target (the controller uses whatever tool is active): set it in the "
                "program or state it with --tool N|X,Y,Z,A,B,C|model")
ASSUMED = "assumed-robroot"


class KRL(Dialect):
    """The KRL dialect. ``active``: the frames its user states (``ActiveFrames``), ``config``:
    whether a ``$config.dat`` was given, ``modules``: module → its local DEFs, ``strucs``: STRUC
    type → member → member type."""

    name = "KRL"
    form = "abc"
    frame_names = _FRAMES
    implicit_arrays = True
    visible_types = frozenset({"E6POS", "POS", "FRAME", "E6AXIS", "AXIS"})
    visible_what = "$BASE, $TOOL and the global points and frames"

    def __init__(self, active=None, config: bool = False, modules: dict | None = None, strucs: dict | None = None):
        super().__init__()
        self.active = active
        self.config = config
        self.modules = modules or {}
        self.strucs = strucs or {}
        self.config_globals: set = {"$NULLFRAME"}  # names $config.dat declares (the lowering fills it)
        self.procedures = {"KRL.BAS": bas, "KRL.START": start, "KRL.NOP": lambda an, st, args, loc: st}
        for name in HARMLESS:
            self.procedures[name] = _harmless
        self.functions = {"KRL.EK": ek, "KRL.FRAME": frame_of, "KRL.SBASE": sbase, "KRL.STOOL2": stool2, "KRL.SLOAD": sload, "KRL.BUILTIN": builtin,
                          "KRL.IPO_BASE": ipo_base}

    # ---------------------------------------------------------------- external units
    def track(self):
        """The unit that carries the robot (postproc.robot.external): the one stated (--external),
        else the machine data's $ERSYS kinematic; None: the robot stands still (or its track's
        kinematics are not given: $ROBROOT not known, P225)."""
        active = self.active
        stated = next((u for u in getattr(active, "external", ()) if u.carries == "robot"), None)
        if stated is not None:
            return stated
        robroot = getattr(active, "robroot", None)
        return getattr(robroot, "unit", None)

    def positioner(self, index: int):
        """The unit stated for KUKA's ``MACHINE_DEF[index]`` (a turntable that carries a base), or None."""
        return next((u for u in getattr(self.active, "external", ()) if u.carries == "workpiece"
                     and u.machine_def == index), None)

    # ---------------------------------------------------------------- names
    def procedure(self, name: str):
        return self.procedures.get(name.upper())

    def routine_key(self, an, name: str) -> str:
        name = name.upper()
        local = self.modules.get(an.act.module)
        if local is not None and name in local:
            return f"{an.act.module}::{name}"
        return name

    def undeclared(self, an, name: str):
        if name == "$NULLFRAME":
            return Mat(_EYE, "$NULLFRAME")
        if STANDARD_AXIS.match(name):
            return Rec("E6AXIS", {}, None, name)
        if name in ("BASE_DATA", "TOOL_DATA", "LOAD_DATA"):
            why = f"{name}[…] needs $config.dat (not given)" if not self.config else f"{name} is not declared"
            return Arr({}, Top(why, an.loc), "LOAD" if name == "LOAD_DATA" else "FRAME")
        if name in ("BASE_CORR_ON",):
            return False
        if name in ("MACHINE_FRAME_DAT", "MACHINE_TOOL_DAT"):
            return Arr({}, Rec("", {"MACH_DEF_INDEX": 0}))
        if RUNTIME_POS.match(name):
            return Top(f"{name} is a run-time position", an.loc, P211)
        if name.startswith("$"):
            return Top(f"{name} is a run-time value", an.loc, P211)
        return Top(f"{name} is not declared in the files read", an.loc, P215)

    def implicit(self, an, name: str) -> tuple:
        act = an.act
        if act.routine is None:
            return ("G", name) if act.module == "$CONFIG" or name in ("BASE_DATA", "TOOL_DATA", "LOAD_DATA") else \
                ("M", act.module, name)
        return ("L", act.scope, name)

    def uninitialised(self, decl):
        top = Top(f"{decl.written or decl.name} is not initialised", decl.loc)
        if decl.dims is not None:
            why = f"{decl.written or decl.name}[…] is not set in the data given"
            return Arr({}, Top(why, decl.loc), decl.type)
        return top

    def touched(self, an, st, names) -> list:
        """Code not read: ``names`` (its variable arguments), or $BASE, $TOOL, FDAT_ACT and every
        global of a data list (``DECL GLOBAL``); not $config.dat's (``config_globals``) nor
        $ROBROOT (machine data)."""
        if names is not None:
            return super().touched(an, st, names)
        return [k for k in st.vars if k[0] == "G" and k[1] not in self.config_globals and k[1] != "$ROBROOT"] + \
            [("G", f) for f in ("$BASE", "$TOOL", "$LOAD", "FDAT_ACT")]

    # ---------------------------------------------------------------- values
    def field(self, an, base, name: str):
        value = super().field(an, base, name)
        if isinstance(value, Rec) and not value.type and isinstance(base, Rec):
            member = self.strucs.get(base.type, {}).get(name)
            if member:
                value = Rec(member, value.fields, value.loc, value.label)
        return value

    def fill(self, target: Rec, cur, frame):
        missing = [k for k in _XYZABC if k not in target.fields]
        if not missing or not target.fields.keys() & set(_XYZABC):
            return target, ()
        if target.type in ("E6AXIS", "AXIS") or target.fields.keys() & {f"A{i}" for i in range(1, 7)}:
            return target, ()
        if cur is None or not _same_frame(cur[1], frame):
            return target, ()
        here = dict(cur[0])
        fields = dict(target.fields)
        filled = []
        for k in missing:
            v = here.get(k)
            if v is not None and math.isfinite(v):
                fields[k] = v
                filled.append(k)
        return Rec(target.type, fields, target.loc, target.label), tuple(filled)

    def view(self, value) -> PoseView:
        v = super().view(value)
        if v.kind == "cart" and value.type in ("E6AXIS", "AXIS"):
            v.kind = "axis"
        if v.kind == "cart":  # (E1…E6 of an E6POS: where a track or a turntable stands)
            v.external = {k: value.fields[k] for k in _EXTERNAL if k in value.fields}
        if v.kind == "other" and self.strucs.get(value.type):
            v.kind = "other"
        return v

    def unread_handler(self, an, st, s):
        """KSS's own handlers (IR_STOPM: the stop-message handler of every inline form's INI
        fold) set no frame; another handler not read: $BASE/$TOOL unknown from its declaration
        until set again (not $ROBROOT: machine data)."""
        if s.action.name.upper() in SYSTEM_HANDLERS:
            return st
        why = f"{s.action.name}() (the {s.what} declared at line {s.loc.line}) is not in the files read"
        for name in ("$BASE", "$TOOL", "$LOAD"):
            st.vars[("G", name)] = Top(why, s.loc)
        return st

    def handler_code(self, key):
        return None if key[-1] in _FRAMES else P223


def _same_frame(a, b) -> bool:
    if isinstance(a, Mat) and isinstance(b, Mat):
        return a == b
    return a is b


def _harmless(an, st, args, loc):
    for a in args:
        if a is not None:
            an.consume(an.eval(a, st), "a system routine's argument")
    return st


# ------------------------------------------------------------------------------- builtins


def frame_of(an, st, args, call):
    """``KRL.FRAME(robroot, base, lefts…)``: INV_POS($ROBROOT):$BASE:lefts, the frame of a target."""
    robroot, base, *lefts = args
    d = an.dialect
    r = d.frame(an, robroot)
    if isinstance(r, Top):
        return _frame_top(r)
    b = d.frame(an, base)
    if isinstance(b, Top):
        return _frame_top(b)
    if isinstance(r, Moving) or isinstance(b, Moving):  # (a track, a base on a turntable: postproc.robot.external)
        out = frame_product(frame_inverse(r), b, b.label)
        for x in lefts:
            f = d.frame(an, x)
            if isinstance(f, Top) or isinstance(out, Top):
                return _frame_top(f if isinstance(f, Top) else out)
            out = frame_product(out, f, f"{out.label}:{f.label}" if out.label else f.label)
        return _frame_top(out) if isinstance(out, Top) else out
    m = b.m if r.m is _EYE or np.array_equal(r.m, _EYE) else np.linalg.inv(r.m) @ b.m
    label = b.label
    toks = r.tokens | b.tokens
    for x in lefts:
        f = d.frame(an, x)
        if isinstance(f, Top):
            return _frame_top(f)
        if isinstance(f, Moving):
            out = frame_product(Mat(m, label, toks, r.flags), f, f"{label}:{f.label}" if label else f.label)
            return _frame_top(out) if isinstance(out, Top) else out
        m = m @ f.m
        label = f"{label}:{f.label}" if label else f.label
        toks |= f.tokens
    return Mat(m, label, toks, r.flags)


def _frame_top(top: Top) -> Top:
    """An unknown frame says why with a frame's code (P201; P220/P221 not set, P225 a track)."""
    if top.code in (P201, P203, P220, P221, P225):
        return top
    return Top(top.why, top.loc, P201)


def _data_frame(an, st, name: str, n, label_prefix: str):
    """``BASE_DATA[n]`` / ``TOOL_DATA[n]`` as a frame value (Rec), or Top."""
    if n is None:
        return Top(f"{label_prefix} with a run-time number", an.loc)
    if n == 0:
        return Mat(_EYE, "$NULLFRAME")
    key, data = an.lookup(name, st)
    if key is None:
        data = an.dialect.undeclared(an, name)
    if isinstance(data, Top):
        return data
    if not isinstance(data, Arr):
        return Top(f"{name} is not an array", an.loc)
    v = data.get((n,))
    if isinstance(v, Rec):
        return Rec(v.type or "FRAME", v.fields, v.loc, f"{name}[{n}]")
    if isinstance(v, Top):
        if not an.dialect.config:
            return Top(f"{name}[{n}] needs $config.dat (not given)", an.loc)
        return Top(f"{name}[{n}] is not set in the data given", an.loc)
    return Top(f"{name}[{n}] is not a frame", an.loc)


def _base(an, st, n, via: str):
    """bas.src's #BASE: BASE_DATA[n], BASE_CORR on top where BASE_CORR_ON, not known on an
    external kinematic (MACHINE_FRAME_DAT[n].MACH_DEF_INDEX > 0)."""
    if n is None:
        return Top(f"{via} with a run-time number", an.loc, P201)
    if n == 0:
        return Mat(_EYE, "$NULLFRAME")
    frame = _data_frame(an, st, "BASE_DATA", n, via)
    if isinstance(frame, Top):
        return frame
    key, mach = an.lookup("MACHINE_FRAME_DAT", st)
    mach = mach if key is not None else an.dialect.undeclared(an, "MACHINE_FRAME_DAT")
    entry = mach.get((n,)) if isinstance(mach, Arr) else mach
    index = whole_number(entry.get("MACH_DEF_INDEX")) if isinstance(entry, Rec) else None
    if isinstance(entry, Top) or index is None:
        if not (isinstance(entry, Top) and "not set" in entry.why):  # (an element the data leave out: fixed)
            return Top(f"MACHINE_FRAME_DAT[{n}] (is BASE_DATA[{n}] on an external kinematic?) is not known", an.loc,
                       P201)
    elif index > 0:
        unit = an.dialect.positioner(index)
        if unit is None:
            return Top(f"BASE_DATA[{n}] is on the external kinematic MACHINE_DEF[{index}] "
                       "(MACHINE_FRAME_DAT[{}].MACH_DEF_INDEX {}): it moves with that unit's axes, whose kinematics "
                       "are not given (--external with machine_def = {})".format(n, index, index), an.loc, P225)
        f = an.dialect.frame(an, frame)
        if isinstance(f, Top):
            return f
        if _base_corr_on(an, st) is not False:
            return Top(f"BASE_CORR on a base on the external kinematic MACHINE_DEF[{index}] is not supported", an.loc,
                       P225)
        return Moving(unit, None, f.m, False, f"MACHINE_DEF[{index}]:BASE_DATA[{n}]", f.tokens)
    key, on = an.lookup("BASE_CORR_ON", st)
    on = on if key is not None else False
    if on is True:
        key, corr = an.lookup("BASE_CORR", st)
        corr = corr if key is not None else Top("BASE_CORR is not declared in the files read", an.loc)
        f = an.dialect.frame(an, frame)
        c = an.dialect.frame(an, corr) if not isinstance(corr, Top) else corr
        if isinstance(f, Top) or isinstance(c, Top):
            return Top(f"BASE_CORR_ON is TRUE and BASE_CORR is not known ({(c if isinstance(c, Top) else f).why})",
                       an.loc, P201)
        return Mat(f.m @ c.m, f"BASE_DATA[{n}]:BASE_CORR", f.tokens | c.tokens)
    if on is not False:
        return Top("BASE_CORR_ON (a BASE_CORR on top of the base) is known only at run time", an.loc, P201)
    return frame


def _base_corr_on(an, st):
    key, on = an.lookup("BASE_CORR_ON", st)
    return on if key is not None else False


def _tool(an, st, n, via: str):
    if n is None:
        return Top(f"{via} with a run-time number", an.loc, P203)
    if n == 0:
        return Mat(_EYE, "$NULLFRAME")
    frame = _data_frame(an, st, "TOOL_DATA", n, via)
    if isinstance(frame, Top):
        return Top(frame.why, frame.loc, P203)
    key, mach = an.lookup("MACHINE_TOOL_DAT", st)
    entry = mach.get((n,)) if key is not None and isinstance(mach, Arr) else None
    index = whole_number(entry.get("MACH_DEF_INDEX")) if isinstance(entry, Rec) else 0
    if index:
        return Top(f"TOOL_DATA[{n}] is on the external kinematic MACHINE_DEF[{index}] (a stationary tool)", an.loc, P203)
    return frame


def _load(an, st, n, via: str):
    """bas.src's #TOOL for $LOAD: ``LOAD_DATA[n]`` (n = 0: the machine data's default load
    $DEF_L_M, not in the files read: not known)."""
    if n is None:
        return Top(f"{via} with a run-time number", an.loc, P235)
    if n == 0:
        return Top(f"{via} 0 sets $LOAD to the machine data's default load ($DEF_L_M), not in the files read", an.loc,
                   P235)
    key, data = an.lookup("LOAD_DATA", st)
    if key is None:
        data = an.dialect.undeclared(an, "LOAD_DATA")
    v = data.get((n,)) if isinstance(data, Arr) else data
    if isinstance(v, Rec):
        return Rec(v.type or "LOAD", v.fields, v.loc, f"LOAD_DATA[{n}]")
    if isinstance(v, Top):
        why = f"LOAD_DATA[{n}] needs $config.dat (not given)" if not an.dialect.config else \
            f"LOAD_DATA[{n}] is not set in the data given"
        return Top(f"{why} ({via} sets $LOAD from it)", an.loc, P235)
    return Top(f"LOAD_DATA[{n}] is not a load", an.loc, P235)


def _fdat(an, fdat, which: str):
    """FDAT's TOOL_NO / BASE_NO → (number or None, why)."""
    if not isinstance(fdat, Rec):
        return None, (fdat.why if isinstance(fdat, Top) else "FDAT_ACT is not known here")
    ipo = fdat.get("IPO_FRAME")
    if isinstance(ipo, str) and ipo.upper() == "#TCP":
        return None, "external TCP (IPO_FRAME #TCP) is not supported"
    n = fdat.get(f"{which}_NO")
    if n is None:
        return None, f"FDAT without {which}_NO"
    k = whole_number(n)
    if k is None:
        return None, f"FDAT with a {which}_NO that is not a whole number"
    return k, ""


def bas(an, st, args, loc):
    """``BAS(#command, value)``: what KSS's bas.src does to $BASE / $TOOL."""
    cmd = args[0].value.upper() if args and hasattr(args[0], "value") and isinstance(args[0].value, str) else ""
    arg = an.eval(args[1], st) if len(args) > 1 and args[1] is not None else None
    if arg is not None:
        an.consume(arg, "BAS()")
    if cmd == "#BASE":
        st.vars[("G", "$BASE")] = _base(an, st, whole_number(arg), "BAS(#BASE, …)")
    elif cmd == "#TOOL":  # (bas.src: $TOOL = TOOL_DATA[n], $LOAD = LOAD_DATA[n])
        st.vars[("G", "$TOOL")] = _tool(an, st, whole_number(arg), "BAS(#TOOL, …)")
        st.vars[("G", "$LOAD")] = _load(an, st, whole_number(arg), "BAS(#TOOL, …)")
    elif cmd in ("#PTP_PARAMS", "#CP_PARAMS", "#FRAMES"):
        key, fdat = an.lookup("FDAT_ACT", st)
        fdat = fdat if key is not None else Top("FDAT_ACT is not known here", an.loc)
        for name, which, fn in (("$BASE", "BASE", _base), ("$TOOL", "TOOL", _tool), ("$LOAD", "TOOL", _load)):
            n, why = _fdat(an, fdat, which)
            st.vars[("G", name)] = fn(an, st, n, f"FDAT_ACT.{which}_NO") if n is not None else \
                Top(why, an.loc, {"$BASE": P201, "$TOOL": P203, "$LOAD": P235}[name])
    return st


def ek(an, st, args, call):
    """``EK(root, mech_type, frame)``: a frame on an external kinematic (a turntable, a track):
    it moves with that unit's axes, known only at run time."""
    for v in args:
        an.consume(v, "EK()")
    return Top("EK(…): a frame on an external kinematic moves with its axes, a run-time value", an.loc, P225)


def sbase(an, st, args, call):
    """``SBASE(n)``: the base bas.src would set for BASE_DATA[n]."""
    return _base(an, st, whole_number(args[0]) if args else None, "SBASE(…)")


def stool2(an, st, args, call):
    """``STOOL2(fdat)``: the tool of an FDAT."""
    n, why = _fdat(an, args[0] if args else None, "TOOL")
    return _tool(an, st, n, "STOOL2(…)") if n is not None else Top(why, an.loc, P203)


def sload(an, st, args, call):
    """``SLOAD(n)``: the load bas.src would set for tool n (``LOAD_DATA[n]``)."""
    if args:
        an.consume(args[0], "SLOAD()")
    return _load(an, st, whole_number(args[0]) if args else None, "SLOAD(…)")


def builtin(an, st, args, call):
    """A KRL system function that sets no frame: its value, where the analysis computes it
    (ABS, SQRT, trigonometry of known numbers), else not known."""
    name = args[0]
    values = args[1:]
    for v in values:
        an.consume(v, f"{name}()")
    nums = [number(v) for v in values]
    if None not in nums:
        try:
            if name == "ABS" and len(nums) == 1:
                return abs(nums[0])
            if name == "SQRT" and len(nums) == 1:
                return math.sqrt(nums[0])
            if name in ("SIN", "COS", "TAN") and len(nums) == 1:
                return {"SIN": math.sin, "COS": math.cos, "TAN": math.tan}[name](math.radians(nums[0]))
        except ValueError:
            pass
    return Top(f"the value of {name}()", an.loc)


def ipo_base(an, st, args, call):
    """``WITH $IPO_MODE = SIPO_MODE(ipo)``: the base in force, unless ``ipo`` is #TCP (an
    external TCP: the robot holds the part, not supported)."""
    ipo, base = args
    if isinstance(ipo, str) and ipo.upper() == "#TCP":
        return Top("external TCP ($IPO_MODE #TCP) is not supported", an.loc, P201)
    if isinstance(ipo, Top):
        return Top(f"$IPO_MODE is not known ({ipo.why})", an.loc, P201)
    return base


def start(an, st, args, loc):
    """A program's start: the frames its user states (``ActiveFrames``), else not set."""
    d = an.dialect
    active = d.active
    base = Top(BASE_NOT_SET, None, P220)
    tool = Top(TOOL_NOT_SET, None, P221)
    if active is not None and active.base is not None:
        base = _stated(an, st, active.base, "base")
    if active is not None and active.tool == "model":
        tool = "model"
    elif active is not None and active.tool is not None:
        tool = _stated(an, st, active.tool, "tool")
    robroot = None if active is None else active.robroot
    track = d.track()
    if track is not None:  # (the robot on a track: $ROBROOT moves with its axis, known at each target)
        rr = Moving(track, label="$ROBROOT")
    elif robroot is None:
        rr = Mat(_EYE, "", flags=frozenset([ASSUMED]))
    elif robroot.frame is None:
        rr = Top(f"$ROBROOT not statically known: {robroot.why} (state it with --robroot X,Y,Z,A,B,C if the track "
                 "stands still)", None, P225)
    else:
        rr = Mat(frame_to_matrix(np.array(robroot.frame, float)), "$ROBROOT")
    st.vars[("G", "$BASE")] = base
    st.vars[("G", "$TOOL")] = tool
    st.vars[("G", "$ROBROOT")] = rr
    st.vars.setdefault(("G", "FDAT_ACT"), Top("FDAT_ACT is not known here", None))
    return st


def _stated(an, st, value, which: str):
    """A stated --base / --tool: six numbers or BASE_DATA[n] / TOOL_DATA[n] (P222 where the data
    given do not hold it)."""
    if isinstance(value, tuple):
        return Mat(frame_to_matrix(np.array(value, float)), f"--{which} {','.join(f'{v:g}' for v in value)}")
    if value == 0:
        return Mat(_EYE, "$NULLFRAME")
    name = f"{which.upper()}_DATA"
    f = _data_frame(an, st, name, value, f"--{which}")
    if isinstance(f, Top):
        raise PostprocError(f"--{which} {value}: {f.why}; give $config.dat with --config, or the frame as X,Y,Z,A,B,C",
                            f"--{which}", 0, 0, P222)
    return f


# (Loc kept importable for the lowering's use)
_ = Loc
_ = Tok
_ = Six

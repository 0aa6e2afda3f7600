"""What ABB RAPID means, written once for the analysis (``analysis.dialect.Dialect``).

References: ABB, *Technical reference manual – RAPID Instructions, Functions and Data types*
(RobotWare 6, 3HAC050917) and *RAPID overview* (3HAC050947); the RAPID Reference Manual of
S4/IRC5 (pages ``8-PDispOn``, ``8-PDispSet``, ``Offs``, ``RelTool``).

* Data are RAPID's records (:data:`RECORDS`): a ``robtarget`` is ``[trans, rot, robconf,
  extax]`` with ``trans`` a ``pos`` ``[x, y, z]``, ``rot`` an ``orient`` ``[q1, q2, q3, q4]``
  (w, x, y, z), ``robconf`` a ``confdata`` ``[cf1, cf4, cf6, cfx]``, ``extax`` an ``extjoint``
  ``[eax_a … eax_f]``; fields are upper case in the IR (``p.trans.x`` is ``P.TRANS.X``).
* A motion's frame (:func:`frame_of`, ``RAPID.FRAME``) is the work object's user frame times
  its object frame times the program displacement in force (``C_PROGDISP``: "all programmed
  positions are related to the ProgDisp coordinate system", which is displaced in the object
  coordinate system), the world frame taken as the robot base. A work object held by the
  robot (``robhold`` TRUE: a stationary tool) is not known statically (P201); one whose user
  frame a mechanical unit moves (``ufprog`` FALSE: coordinated with ``ufmec``) moves with that
  unit's axis: known at each robtarget's ``eax_…`` where a unit with that ``mech_unit`` is given
  (``--external``: postproc.robot.external), else P225. A robot on a track (a unit that carries the
  robot) sees every frame through the track at the robtarget's axis value.
* A motion's tool (``RAPID.TOOL``) is its ``tooldata``'s ``tframe``; a stationary tool
  (``robhold`` FALSE) is not known (P203).
* A robtarget that states an external axis (``eax_a … eax_f`` other than 9E9: a track, a
  positioner coordinated with the robot) is left as written (P225) unless the units given cover
  every axis it uses: without that unit's kinematics its pose in the robot's base is not known.
* ``Offs(p, dx, dy, dz)`` is ``p`` displaced in the object frame: p's tokens + the offset;
  ``RelTool(p, dx, dy, dz \\Rx \\Ry \\Rz)`` displaced in the tool frame (``R(p.rot)·d``: p's
  tokens + that offset) and turned about x, then the new y, then the new z.
* ``PDispOn [\\Rot] [\\ExeP:=e,] p, tool`` sets the displacement that takes ``p`` to ``e``
  (translation; with ``\\Rot`` the rotation too), ``PDispSet f`` sets ``f``, ``PDispOff``
  none; the points read are read as a frame (their tokens escape: P217 holds a target built
  on them). Without ``\\ExeP`` the robot's position at run time is taken: not known.
* ``EOffsOn``/``EOffsSet``/``EOffsOff`` offset the external axes only: a target that uses
  none (every ``eax`` 9E9) is where it was; one that uses one is left already (P225).
* Code not read (a routine of a module not given) may change every global that is not a
  constant nor data of a ``--config`` module (read-only), and the displacement; a call to it is
  said (P232, ``Dialect.not_read``), naming the global robtargets, tooldata and wobjdata.
* Data that a routine ``main`` does not run changes (``runtime``: the pendant, an event routine,
  an unconnected TRAP, another task may run it at any moment) is a run-time value wherever it is
  read: the targets in such a frame or with such a tool are left at each motion (P233).
* The world is the robot base unless the system parameters say otherwise (``base``, from
  MOC.cfg: ``syspar.py``): a base frame B makes every frame B⁻¹ · uframe · oframe · displacement;
  a base a unit moves (``base_frame_coordinated``) leaves every target (P225) unless
  ``--external`` gives that unit.
"""
from __future__ import annotations

import math

import numpy as np

from ...core import frames as fr
from ...core.diagnostics import P201, P203, P211, P215, P223, P225, P233
from ..analysis.dialect import Dialect, PoseView
from ..analysis.values import (
    Arr, Mat, Moving, Rec, Six, Taint, Tok, Top, frame_inverse, frame_product, number, taint, tokens_of,
)

__all__ = ["RAPID", "RECORDS", "INSTRUCTIONS", "FUNCTIONS", "UNUSED_AXIS", "wobj0", "tool0"]

# RAPID's records: type → (field, field type) in the order an aggregate writes them
RECORDS: dict[str, tuple] = {
    "POS": (("X", "NUM"), ("Y", "NUM"), ("Z", "NUM")),
    "ORIENT": (("Q1", "NUM"), ("Q2", "NUM"), ("Q3", "NUM"), ("Q4", "NUM")),
    "POSE": (("TRANS", "POS"), ("ROT", "ORIENT")),
    "CONFDATA": (("CF1", "NUM"), ("CF4", "NUM"), ("CF6", "NUM"), ("CFX", "NUM")),
    "EXTJOINT": tuple((f"EAX_{c}", "NUM") for c in "ABCDEF"),
    "ROBTARGET": (("TRANS", "POS"), ("ROT", "ORIENT"), ("ROBCONF", "CONFDATA"), ("EXTAX", "EXTJOINT")),
    "ROBJOINT": tuple((f"RAX_{k}", "NUM") for k in range(1, 7)),
    "JOINTTARGET": (("ROBAX", "ROBJOINT"), ("EXTAX", "EXTJOINT")),
    "LOADDATA": (("MASS", "NUM"), ("COG", "POS"), ("AOM", "ORIENT"), ("IX", "NUM"), ("IY", "NUM"), ("IZ", "NUM")),
    "TOOLDATA": (("ROBHOLD", "BOOL"), ("TFRAME", "POSE"), ("TLOAD", "LOADDATA")),
    "WOBJDATA": (("ROBHOLD", "BOOL"), ("UFPROG", "BOOL"), ("UFMEC", "STRING"), ("UFRAME", "POSE"),
                 ("OFRAME", "POSE")),
    "PROGDISP": (("PDISP", "POSE"), ("EOFFS", "EXTJOINT")),
    "SPEEDDATA": (("V_TCP", "NUM"), ("V_ORI", "NUM"), ("V_LEAX", "NUM"), ("V_REAX", "NUM")),
    "ZONEDATA": (("FINEP", "BOOL"), ("PZONE_TCP", "NUM"), ("PZONE_ORI", "NUM"), ("PZONE_EAX", "NUM"),
                 ("ZONE_ORI", "NUM"), ("ZONE_LEAX", "NUM"), ("ZONE_REAX", "NUM")),
}
SCALARS = frozenset({"NUM", "DNUM", "BOOL", "STRING", "BYTE", "INTNUM", "SIGNALDI", "SIGNALDO", "SIGNALAI",
                     "SIGNALAO", "SIGNALGI", "SIGNALGO", "ERRNUM", "CLOCK", "IODEV"})
_XYZ = ("X", "Y", "Z")
_Q = ("Q1", "Q2", "Q3", "Q4")
_CF = ("CF1", "CF4", "CF6", "CFX")
_EAX = tuple(f"EAX_{c}" for c in "ABCDEF")
UNUSED_AXIS = 8.99e9  # an external axis value of 9E9 (or more): the axis is not used
_EYE = np.eye(4)
_EYE.setflags(write=False)

# RAPID's instructions that move nothing and set no frame (their arguments are read): name →
# the positions of the arguments they write (INOUT: made unknown after the call). Motions,
# PDisp*, interrupts and the control words are lowered on their own (``lower.py``).
INSTRUCTIONS: dict[str, tuple] = {name.upper(): () for name in (
    "AccSet", "ActUnit", "AliasIO", "BookErrNo", "Break", "CancelLoad", "CheckProgRef", "CirPathMode",
    "ClearIOBuff", "ClearPath", "ClearRawBytes", "ClkReset", "ClkStart", "ClkStop", "Close", "CloseDir",
    "Comment", "ConfJ", "ConfL", "CopyFile", "CopyRawBytes", "CorrClear", "CorrCon", "CorrDiscon", "CorrWrite",
    "DeactUnit", "DitherAct", "DitherDeact", "DropWObj", "EOffsOff", "EOffsOn", "EOffsSet", "ErrLog", "ErrRaise",
    "ErrWrite", "GripLoad", "HollowWristReset", "IndReset", "InvertDO", "IOBusStart", "IODisable",
    "IOEnable", "Load", "LoadId", "MakeDir", "MechUnitLoad", "MotionSup", "MToolRotCalib", "MToolTCPCalib",
    "Open", "OpenDir", "PackDNHeader", "PackRawBytes", "PathAccLim", "PathRecStart", "PathRecStop",
    "PathResol", "ProcerrRecovery", "PulseDO", "RemoveDir", "RemoveFile", "RenameFile", "Reset",
    "ResetPPMoved", "ResetRetryCount", "RestoPath", "Rewind", "Save", "SCWrite", "Set", "SetAllDataVal",
    "SetAO", "SetDataSearch", "SetDO", "SetGO", "SetSysData", "SingArea", "SkipWarn", "SocketBind",
    "SocketClose", "SocketConnect", "SocketListen", "SocketSend", "SoftAct", "SoftDeact", "SpeedRefresh",
    "SpyStart", "SpyStop", "StartLoad", "StartMove", "StartMoveRetry", "StepBwdPath", "StopMove",
    "StopMoveReset", "StorePath", "SyncMoveOff", "SyncMoveOn", "SyncMoveResume", "SyncMoveSuspend",
    "SyncMoveUndo", "SystemStopAction", "TestSignDefine", "TestSignReset", "TextTabInstall", "TPErase",
    "TPShow", "TPWrite", "TriggCheckIO", "TriggSpeed", "TriggStopProc", "TuneReset", "TuneServo", "UIShow",
    "UnLoad", "VelSet", "WaitAI", "WaitAO", "WaitDI", "WaitDO", "WaitGI", "WaitGO", "WaitLoad", "WaitRob",
    "WaitSyncTask", "WaitTime", "WaitUntil", "WaitWObj", "WarmStart", "WorldAccLim", "Write", "WriteAnyBin",
    "WriteBin", "WriteBlock", "WriteCfgData", "WriteRawBytes", "WriteStrBin", "WZBoxDef", "WZCylDef",
    "WZDisable", "WZDOSet", "WZEnable", "WZFree", "WZHomeJointDef", "WZLimJointDef", "WZLimSup", "WZSphDef",
    "UIMsgBox", "IRMQMessage", "RMQFindSlot", "RMQSendMessage", "RMQSendWait", "RMQEmptyQueue",
    "PathRecMoveBwd", "PathRecMoveFwd", "IndAMove", "IndCMove", "IndDMove", "IndRMove", "TryInt", "Stop",
    "ExitCycle", "SetLeadThrough", "SpeedLimAxis", "SpeedLimCheckPoint", "TriggRampAO", "ISignalDI", "ISignalDO",
    "ISignalAI", "ISignalAO", "ISignalGI", "ISignalGO", "ITimer", "IPers", "IError")}
INSTRUCTIONS.update({name.upper(): which for name, which in (
    ("BitClear", (0,)), ("BitSet", (0,)), ("GetDataVal", (1,)), ("GetSysData", (0,)), ("ReadCfgData", (2,)),
    ("TPReadFK", (0,)), ("TPReadNum", (0,)), ("TPReadDnum", (0,)), ("TriggIO", (0,)), ("TriggEquip", (0,)),
    ("TriggInt", (0,)), ("ReadAnyBin", (1,)), ("ReadBlock", (2,)), ("ReadRawBytes", (1,)), ("ReadErrData", (3,)),
    ("SocketAccept", (1,)), ("SocketCreate", (0,)), ("SocketReceive", (1,)), ("UnpackRawBytes", (3,)),
    ("GetTrapData", (0,)), ("RMQGetMessage", (0,)), ("RMQGetMsgData", (1,)), ("RMQReadWait", (0,)),
    ("ClkRead", ()), ("IVarValue", (1,)),
)})

# RAPID's functions (their arguments are read; their value is not known statically unless
# the analysis computes it: ``MATH``, Offs, RelTool, PoseMult, PoseInv, OrientZYX, PoseVect)
FUNCTIONS = frozenset(name.upper() for name in (
    "Abs", "AbsDnum", "ACos", "ACosDnum", "AInput", "AOutput", "ArgName", "ASin", "ATan", "ATan2", "BitAnd",
    "BitCheck", "BitLSh", "BitNeg", "BitOr", "BitRSh", "BitXOr", "ByteToStr", "CalcJointT", "CalcRobT",
    "CalcRotAxisFrame", "CalcRotAxFrameZ", "CDate", "CJointT", "ClkRead", "CorrRead", "Cos", "CPos", "CRobT",
    "CSpeedOverride", "CTime", "CTool", "CWObj", "DecToHex", "DefAccFrame", "DefDFrame", "DefFrame", "Dim",
    "DInput", "Distance", "DnumToNum", "DnumToStr", "DotProd", "DOutput", "EulerZYX", "EventType",
    "ExecHandler", "ExecLevel", "Exp", "FileSize", "FileTimeDnum", "FSSize", "GetMecUnitName",
    "GetNextMechUnit", "GetNextSym", "GetServiceInfo", "GetSignalOrigin", "GetSysInfo", "GetTaskName",
    "GetTime", "GInput", "GInputDnum", "GOutput", "GOutputDnum", "HexToDec", "IndInpos", "IndSpeed",
    "IOUnitState", "IsFile", "IsMechUnitActive", "IsPers", "IsStopMoveAct", "IsSyncMoveOn", "IsSysId", "IsVar",
    "MaxRobSpeed", "MirPos", "ModExist", "ModTime", "NonMotionMode", "NOrient", "NumToDnum", "NumToStr", "Offs",
    "OpMode", "OrientZYX", "ORobT", "PathLevel", "PathRecValidBwd", "PathRecValidFwd", "PFRestart", "PoseInv",
    "PoseMult", "PoseVect", "Pow", "PowDnum", "PPMovedInManMode", "Present", "ProgMemFree", "RawBytesLen",
    "ReadBin", "ReadDir", "ReadMotor", "ReadNum", "ReadStr", "ReadStrBin", "ReadVar", "RelTool",
    "RemainingRetries", "RobName", "RobOS", "Round", "RoundDnum", "RunMode", "Sin", "SocketGetStatus",
    "SocketPeek", "Sqrt", "SqrtDnum", "StrDigCalc", "StrDigCmp", "StrFind", "StrLen", "StrMap", "StrMatch",
    "StrMemb", "StrOrder", "StrPart", "StrToByte", "StrToVal", "Tan", "TaskRunMec", "TaskRunRob", "TasksInSync",
    "TestAndSet", "TestDI", "TestSignRead", "TextGet", "TextTabFreeToUse", "TextTabGet", "Trunc", "TruncDnum",
    "Type", "UIAlphaEntry", "UIClientExist", "UIDnumEntry", "UIDnumTune", "UIListView", "UIMessageBox",
    "UINumEntry", "UINumTune", "ValidIO", "ValToStr", "VectMagn", "IsStopStateEvent", "IsLeadThrough"))
# functions whose value is where the robot is at run time (a target made of one is left as written)
RUNTIME_POSITION = frozenset({"CROBT", "CPOS", "CJOINTT", "CTOOL", "CWOBJ", "CALCROBT", "CALCJOINTT", "OROBT",
                              "MIRPOS"})


def _pose_rec(m: np.ndarray, tokens: frozenset = frozenset(), type_: str = "POSE", label: str = "") -> Rec:
    """A 4×4 as a RAPID pose record (numbers computed from ``tokens``: Taint where any)."""
    q = fr.quaternion_from_rotation(m[:3, :3])

    def num(v):
        return Taint(float(v), tokens) if tokens else float(v)

    trans = Rec("POS", {k: num(v) for k, v in zip(_XYZ, m[:3, 3])})
    rot = Rec("ORIENT", {k: num(v) for k, v in zip(_Q, q)})
    return Rec(type_, {"TRANS": trans, "ROT": rot}, None, label)


def _record(type_: str, values: dict, label: str = "") -> Rec:
    return Rec(type_, values, None, label)


def _pose0() -> Rec:
    return _record("POSE", {"TRANS": _record("POS", dict(zip(_XYZ, (0.0, 0.0, 0.0)))),
                            "ROT": _record("ORIENT", dict(zip(_Q, (1.0, 0.0, 0.0, 0.0))))})


def wobj0() -> Rec:
    """The predefined work object ``wobj0`` (the world frame)."""
    return _record("WOBJDATA", {"ROBHOLD": False, "UFPROG": True, "UFMEC": "", "UFRAME": _pose0(),
                                "OFRAME": _pose0()}, "wobj0")


def tool0() -> Rec:
    """The predefined tool ``tool0`` (the flange)."""
    return _record("TOOLDATA", {"ROBHOLD": True, "TFRAME": _pose0(), "TLOAD": _record("LOADDATA", {})}, "tool0")


class RAPID(Dialect):
    """The RAPID dialect. ``readonly``: the names of the data of ``--config`` modules (code
    not read does not change them), ``consts``: the names of CONST data."""

    name = "RAPID"
    form = "quaternion"
    frame_names = ("C_PROGDISP",)
    undeclared_hint = "declared in a module not given? give it too, or with --config"
    visible_types = frozenset({"ROBTARGET", "TOOLDATA", "WOBJDATA"})
    visible_what = "the global targets, tools and work objects"

    def __init__(self, readonly: set | None = None, consts: set | None = None, written: dict | None = None,
                 external: tuple = (), runtime: dict | None = None, base=None):
        super().__init__()
        self.runtime = dict(runtime or {})  # (data a routine main does not run changes: P233)
        # the robot's base in the world (``syspar.Robot``, MOC.cfg): None the world itself; a Mat
        # robot base ← world; a Top that leaves every target (a base a unit moves, not given)
        self.base = base
        self.units: dict = {}  # the mechanical units the system parameters declare: NAME → (path, line)
        # the external units' kinematics (postproc.robot.external): a track that carries the robot's
        # base (its robtargets' eax_… says where), positioners a work object is coordinated with
        self.track = next((u for u in external if u.carries == "robot"), None)
        self.mech_units = {u.mech_unit.upper(): u for u in external if u.carries == "workpiece" and u.mech_unit}
        self.readonly = set(readonly or ())
        self.consts = set(consts or ())
        self.written = written or {}  # canonical name → as the program writes it (messages)
        self.functions = {"RAPID.FRAME": frame_of, "RAPID.TOOL": tool_of, "RAPID.OFFS": offs,
                          "RAPID.RELTOOL": reltool, "RAPID.PDISPON": pdispon, "RAPID.NOFRAME": noframe,
                          "RAPID.POSEMULT": posemult, "RAPID.POSEINV": poseinv, "RAPID.ORIENTZYX": orientzyx,
                          "RAPID.POSEVECT": posevect, "RAPID.MATH": math_of, "RAPID.LOAD": load_of}
        self._frames: dict = {}
        self._tools: dict = {}

    # ---------------------------------------------------------------- names
    def procedure(self, name: str):
        if name.upper() == "RAPID.GRIPLOAD":
            return gripload
        if name.startswith("RAPID.") and name[6:] in INSTRUCTIONS:
            return _instruction
        return None

    def function(self, name: str):
        if not name.startswith("RAPID."):
            return None
        name = name.upper()
        fn = self.functions.get(name)
        if fn is None and name[6:] in FUNCTIONS:
            return _builtin
        return fn

    def initial(self, unit) -> dict:
        return {("G", "C_PROGDISP"): Mat(_EYE, "")}

    def undeclared(self, an, name: str):
        if name == "WOBJ0":
            return wobj0()
        if name == "TOOL0":
            return tool0()
        if name == "LOAD0":
            return _record("LOADDATA", {}, "load0")
        return Top(f"{self.written.get(name, name)} is not declared in the files read", an.loc, P215)

    def uninitialised(self, decl):
        why = f"{decl.written or decl.name} is not set before it is used"
        if decl.dims is not None:
            return Arr({}, Top(f"{decl.written or decl.name}{{…}} is not set (or outside the array)", decl.loc),
                       decl.type)
        return Top(why, decl.loc)

    def touched(self, an, st, names) -> list:
        """Code not read: ``names`` (its variable arguments; not constants), or every global but
        the constants and the ``--config`` modules' data, and the program displacement."""
        if names is not None:
            return [k for k in super().touched(an, st, [n for n in names if n not in self.consts])
                    if k[-1] not in self.consts]
        keep = self.readonly | self.consts
        return [k for k in st.vars if k[0] == "G" and k[1] not in keep] + [("G", "C_PROGDISP")]

    def unread(self, an, st, site, why: str | None):
        """A routine not read; a late-bound call (``%name%``, ``CallByVar``) names one known only
        at run time."""
        if why is None and site.name == "%late%":
            line = site.loc.line if site.loc else 0
            self.not_read(an, st, site, "a routine named at run time (late binding: %…%, CallByVar)")
            why = f"a routine named at run time (late binding, line {line}) is not known here"
        return super().unread(an, st, site, why)

    def scalar(self, type_: str) -> bool:
        return type_.upper() in SCALARS

    def unread_handler(self, an, st, s):
        why = f"{s.action.name}() (the {s.what} connected at line {s.loc.line}) is not in the files read"
        return an.havoc(st, None, why, s.loc)

    def handler_code(self, key):
        return None if key[-1] in self.frame_names else P223

    # ---------------------------------------------------------------- values
    def field(self, an, base, name: str):
        if isinstance(base, Mat):
            pose = _pose_rec(base.m, base.tokens)
            if name in pose.fields:
                return pose.fields[name]
        return super().field(an, base, name)

    def record_of(self, m: Mat) -> Rec:
        return _pose_rec(m.m, m.tokens, label=m.label)

    def view(self, value) -> PoseView:
        """A robtarget (or a pose) as a motion's target: ``trans`` and ``rot`` (quaternion); a
        robtarget with an external axis in use moves with it (``moving``: P225)."""
        t = value.type
        fields = value.fields
        if t in ("ROBTARGET", "POSE"):
            trans, rot = fields.get("TRANS"), fields.get("ROT")
            view = PoseView("cart", _parts(trans, _XYZ), _parts(rot, _Q), "quaternion", (-1, -1), value.loc, t)
            if t == "ROBTARGET":
                view.moving = _moving(value)
                view.external = _external(value)
            return view
        if t in ("JOINTTARGET", "ROBJOINT"):
            return PoseView("axis", [None] * 3, [None] * 4, "quaternion", (-1, -1), value.loc, t)
        return PoseView("other", [None] * 3, [None] * 4, "quaternion", (-1, -1), value.loc, t)

    def tool(self, an, value):
        if isinstance(value, (Six, Top)) or value is None:
            return value
        return tool_value(an, value, "")

    def row_extras(self, use, view) -> dict:
        return {"confdata": confdata(use.target)}

    def run_extras(self, run) -> dict:
        return {"confdata": run.rows["confdata"]}

    def position(self, target):
        return ()

    def run_position(self, run, cur, frame):
        return ((), frame)


def _parts(rec, names):
    if isinstance(rec, Rec):
        return [rec.fields.get(k) for k in names]
    if isinstance(rec, Top):
        return [rec] * len(names)
    return [None] * len(names)


def _moving(target: Rec):
    """Top (P225) where the robtarget states an external axis in use (or not known), else None."""
    extax = target.fields.get("EXTAX")
    if extax is None:
        return None
    where = target.label or "the robtarget"
    if isinstance(extax, Top):
        return Top(f"the external axes of {where} are not known ({extax.why}): a track or a unit "
                   "coordinated with the robot may move its base", extax.loc or target.loc, P225)
    if not isinstance(extax, Rec):
        return None
    used = []
    for k in _EAX:
        v = extax.fields.get(k)
        if v is None:
            continue
        x = number(v)
        if x is None:
            return Top(f"{k.lower()} of {where} is not known here: a track or a unit coordinated with the robot "
                       "may move its base", target.loc, P225)
        if abs(x) < UNUSED_AXIS:
            used.append(f"{k.lower()} {x:g}")
    if used:
        return Top(f"a robtarget states the external axis position {', '.join(used)} (a track or a positioner "
                   "coordinated with the robot): without that unit's kinematics its pose in the robot's base is not "
                   "known", target.loc, P225)
    return None


def _external(target: Rec) -> dict:
    """The external axes a robtarget uses (eax_a … eax_f not 9E9) as E1 … E6 (postproc.robot.external)."""
    extax = target.fields.get("EXTAX")
    if not isinstance(extax, Rec):
        return {}
    out = {}
    for k, name in enumerate(_EAX):
        v = extax.fields.get(name)
        x = number(v)
        if v is not None and (x is None or abs(x) < UNUSED_AXIS):
            out[f"E{k + 1}"] = v
    return out


def confdata(target) -> list:
    """cf1, cf4, cf6, cfx of a robtarget value (NaN where not a number)."""
    cf = target.fields.get("ROBCONF") if isinstance(target, Rec) else None
    if not isinstance(cf, Rec):
        return [math.nan] * 4
    out = []
    for k in _CF:
        x = number(cf.fields.get(k))
        out.append(math.nan if x is None else x)
    return out


# ------------------------------------------------------------------------------- builtins


def _instruction(an, st, args, loc):
    """A RAPID instruction that sets no frame: its arguments are read."""
    for a in args:
        if a is not None:
            an.consume(an.eval(a, st), "an instruction's argument")
    return st


def _builtin(an, st, args, call):
    """A RAPID function the analysis does not compute: its arguments are read, its value is
    known only at run time."""
    name = call.name[6:]
    for v in args:
        an.consume(v, f"{name}()")
    return Top(f"the value of {name.lower()}() is computed at run time", call.loc or an.loc, P211)


def _frame_top(top: Top, code=P201) -> Top:
    if top.code in (P201, P203, P225, P233):
        return top
    return Top(top.why, top.loc, code)


def _kept(top: Top, code: str) -> str:
    """The code a frame or tool left by ``top`` says: P233 where a routine main does not run changes
    what it is made of, else ``code``."""
    return P233 if top.code == P233 else code


def frame_of(an, st, args, call):
    """``RAPID.FRAME(wobj, progdisp, label)``: the motion's frame, robot base ← target
    coordinates: uframe · oframe · program displacement (cached by the values' identity)."""
    wobj, pdisp, label = args
    d = an.dialect
    key = (id(wobj), id(pdisp), label)
    hit = d._frames.get(key)
    if hit is not None and hit[0] is wobj and hit[1] is pdisp:
        result = hit[2]
        if isinstance(result, Mat) and result.tokens:
            an.consume(result, "a work object's frame")
        return result
    result = _wobj_frame(an, wobj, label) if not isinstance(d.base, Top) else d.base
    if isinstance(result, (Mat, Moving)) and isinstance(d.base, Mat):  # (robot base ← world, MOC.cfg)
        result = frame_product(d.base, result, result.label)
    if isinstance(result, (Mat, Moving)) and d.track is not None:  # (the robot's base rides on the track)
        result = frame_product(frame_inverse(Moving(d.track, label="track")), result, result.label)
    if isinstance(result, Moving):
        p = d.frame(an, pdisp)
        if isinstance(p, Top):
            result = Top(f"the program displacement is not known ({p.why})", p.loc, _kept(p, P201))
        elif not (p.m is _EYE or np.array_equal(p.m, _EYE)):
            result = frame_product(result, p, f"{result.label}:PDisp")
    elif isinstance(result, Mat):
        p = d.frame(an, pdisp)
        if isinstance(p, Top):
            result = Top(f"the program displacement is not known ({p.why})", p.loc, _kept(p, P201))
        elif not (p.m is _EYE or np.array_equal(p.m, _EYE)):
            result = Mat(result.m @ p.m, f"{result.label}:PDisp", result.tokens | p.tokens)
    d._frames[key] = (wobj, pdisp, result)
    return result


def _wobj_frame(an, w, label: str):
    name = label or "the work object"
    if isinstance(w, Top):
        return _frame_top(Top(f"work object {name}: {w.why}" if label and label not in w.why else w.why, w.loc,
                              w.code))
    if not isinstance(w, Rec) or w.type not in ("WOBJDATA", ""):
        return Top(f"\\WObj {name} is not a wobjdata", an.loc, P201)
    robhold, ufprog, ufmec = w.get("ROBHOLD"), w.get("UFPROG"), w.get("UFMEC")
    if robhold is not False:
        if robhold is True:
            return Top(f"work object {name} is held by the robot (robhold TRUE): a stationary-tool program", an.loc,
                       P201)
        return Top(f"work object {name}: its robhold is not known here", an.loc, P201)
    d = an.dialect
    moved = None
    if ufprog is not True:
        if ufprog is False:
            unit = ufmec if isinstance(ufmec, str) and ufmec.strip('"') else "a mechanical unit"
            moved = d.mech_units.get(unit.strip('"').upper())
            if moved is None:
                declared = d.units.get(unit.strip('"').upper())
                at = f", declared at {declared[0]}:{declared[1]}" if declared else ""
                return Top(f"work object {name}'s user frame is moved by the mechanical unit {unit}{at} (ufprog FALSE: "
                           "coordinated): it moves with that unit's axes, whose kinematics are not given (--external "
                           f"with mech_unit = {unit})", an.loc, P225)
        else:
            return Top(f"work object {name}: its ufprog is not known here", an.loc, P201)
    uf = d.frame(an, w.get("UFRAME"))
    of = d.frame(an, w.get("OFRAME"))
    for f, which in ((uf, "uframe"), (of, "oframe")):
        if isinstance(f, Top):
            return Top(f"work object {name}'s {which} is not known ({f.why})", f.loc or an.loc, _kept(f, P201))
    if moved is not None:  # (the user frame on the unit: world ← uframe = the unit at its axis value · uframe)
        return Moving(moved, None, uf.m @ of.m, False, label, uf.tokens | of.tokens)
    return Mat(uf.m @ of.m, label, uf.tokens | of.tokens)


def tool_of(an, st, args, call):
    """``RAPID.TOOL(tool, label)``: six numbers X,Y,Z,A,B,C of the tooldata's tframe."""
    value, label = args
    return tool_value(an, value, label)


def tool_value(an, value, label: str):
    d = an.dialect
    key = (id(value), label)
    hit = d._tools.get(key)
    if hit is not None and hit[0] is value:
        return hit[1]
    name = label or "the tool"
    if isinstance(value, Top):
        result = Top(f"tool {name}: {value.why}" if label and label not in value.why else value.why, value.loc,
                     _kept(value, P203))
    elif not isinstance(value, Rec) or value.type not in ("TOOLDATA", ""):
        result = Top(f"tool {name} is not a tooldata", an.loc, P203)
    elif value.get("ROBHOLD") is not True:
        result = Top(f"tool {name} is not held by the robot (robhold {value.get('ROBHOLD')!s}): a stationary tool",
                     an.loc, P203)
    else:
        f = d.frame(an, value.get("TFRAME"))
        result = Top(f"tool {name}'s tframe is not known ({f.why})", f.loc or an.loc, _kept(f, P203)) \
            if isinstance(f, Top) \
            else Six(fr.matrix_to_frame(f.m), label)
    d._tools[key] = (value, result)
    return result


def noframe(an, st, args, call):
    """``PDispOff``: no displacement."""
    return Mat(_EYE, "")


def _as_frame(an, value, what: str):
    f = an.dialect.frame(an, value)
    if isinstance(f, Top):
        return Top(f"{what} is not known ({f.why})", f.loc or an.loc, P201)
    return f


def pdispon(an, st, args, call):
    """``PDispOn [\\Rot] [\\ExeP:=e,] p, …``: the displacement that takes the programmed point
    ``p`` to ``e`` (its translation; with ``\\Rot`` the rotation too), in the object frame."""
    rot, exe, prog = args
    if isinstance(exe, Top):
        return Top(exe.why, exe.loc or an.loc, P201)
    e = _as_frame(an, exe, "the PDispOn \\ExeP point")
    p = _as_frame(an, prog, "the PDispOn point")
    for f in (e, p):
        if isinstance(f, Top):
            return f
    if rot is True:
        m = e.m @ fr.inverse(p.m)
    else:
        m = np.eye(4)
        m[:3, 3] = e.m[:3, 3] - p.m[:3, 3]
    return Mat(m, "PDispOn", e.tokens | p.tokens)


def _num(an, v, why: str):
    """A number argument as a float (its tokens read: they are no target's own here)."""
    an.consume(v, why)
    return number(v)


def offs(an, st, args, call):
    """``Offs(p, dx, dy, dz)``: p displaced in the object frame: p's X/Y/Z tokens + the offsets."""
    p, *d = args
    if isinstance(p, Top):
        return p
    ds = [_num(an, x, "an offset of Offs()") for x in d]
    if None in ds or len(ds) != 3:
        return Top("an offset of Offs() is not known here", an.loc, P211)
    return _displaced(an, p, ds, "Offs")


def _displaced(an, p, ds, fn: str):
    if not isinstance(p, Rec) or p.type not in ("ROBTARGET", ""):
        return Top(f"{fn}() of a value that is not a robtarget", an.loc, P211)
    trans = p.fields.get("TRANS")
    if not isinstance(trans, Rec):
        return Top(f"the position of {fn}()'s robtarget is not known", an.loc, P211)
    fields = dict(trans.fields)
    for k, dv in zip(_XYZ, ds):
        fields[k] = an.dialect.operate(an, "+", [fields.get(k), float(dv)]) if fields.get(k) is not None \
            else Top(f"the {k} of {fn}()'s robtarget is not set", an.loc)
    return p.with_field("TRANS", Rec(trans.type, fields, trans.loc, trans.label))


def reltool(an, st, args, call):
    """``RelTool(p, dx, dy, dz, rx, ry, rz)``: p displaced by d in its tool frame (R(p.rot)·d
    added to p's X/Y/Z tokens) and turned about x, the new y, the new z (degrees)."""
    p, *rest = args
    if isinstance(p, Top):
        return p
    vals = [_num(an, x, "an argument of RelTool()") for x in rest]
    if None in vals or len(vals) != 6:
        return Top("an argument of RelTool() is not known here", an.loc, P211)
    if not isinstance(p, Rec):
        return Top("RelTool() of a value that is not a robtarget", an.loc, P211)
    rot = p.fields.get("ROT")
    q = [number(rot.fields.get(k)) if isinstance(rot, Rec) else None for k in _Q]
    if None in q or not np.any(np.array(q)):
        return Top("the orientation of RelTool()'s robtarget is not known here", an.loc, P211)
    an.consume(rot, "the tool frame of RelTool()")
    r = fr.rotation_from_quaternion(np.array(q, float))
    out = _displaced(an, p, r @ np.array(vals[:3], float), "RelTool")
    rx, ry, rz = vals[3:]
    if isinstance(out, Rec) and (rx or ry or rz):
        # about x, then the new y, then the new z: Rx·Ry·Rz (rotation_from_abc(A, B, C) = Rz(A)·Ry(B)·Rx(C))
        turn = fr.rotation_from_abc(np.array([0.0, 0.0, rx])) @ fr.rotation_from_abc(np.array([0.0, ry, 0.0])) \
            @ fr.rotation_from_abc(np.array([rz, 0.0, 0.0]))
        new = fr.quaternion_from_rotation(r @ turn)
        if float(np.dot(new, q)) < 0:
            new = -new
        toks = frozenset(tokens_of(rot))
        out = out.with_field("ROT", Rec("ORIENT", {k: Taint(float(v), toks) if toks else float(v)
                                                   for k, v in zip(_Q, new)}))
    return out


def posemult(an, st, args, call):
    """``PoseMult(p1, p2)``: the pose p1·p2."""
    fs = [_as_frame(an, a, "a pose of PoseMult()") for a in args]
    for f in fs:
        if isinstance(f, Top):
            return f
    m = fs[0].m @ fs[1].m
    return _pose_rec(m, fs[0].tokens | fs[1].tokens)


def poseinv(an, st, args, call):
    """``PoseInv(p)``: the inverse pose."""
    f = _as_frame(an, args[0], "the pose of PoseInv()")
    if isinstance(f, Top):
        return f
    return _pose_rec(fr.inverse(f.m), f.tokens)


def posevect(an, st, args, call):
    """``PoseVect(pose, pos)``: the position transformed by the pose."""
    f = _as_frame(an, args[0], "the pose of PoseVect()")
    if isinstance(f, Top):
        return f
    p = args[1]
    xyz = [_num(an, p.fields.get(k), "PoseVect()") if isinstance(p, Rec) else None for k in _XYZ]
    if None in xyz:
        return Top("the position of PoseVect() is not known here", an.loc, P211)
    v = f.m[:3, :3] @ np.array(xyz) + f.m[:3, 3]
    toks = f.tokens | frozenset(tokens_of(p))
    return Rec("POS", {k: Taint(float(x), toks) if toks else float(x) for k, x in zip(_XYZ, v)})


def orientzyx(an, st, args, call):
    """``OrientZYX(z, y, x)``: the orientation of Euler angles about Z, the new Y, the new X."""
    vals = [_num(an, a, "OrientZYX()") for a in args]
    if None in vals or len(vals) != 3:
        return Top("an angle of OrientZYX() is not known here", an.loc, P211)
    q = fr.quaternion_from_rotation(fr.rotation_from_abc(np.array(vals, float)))
    toks = set()
    for a in args:
        tokens_of(a, toks)
    return Rec("ORIENT", {k: Taint(float(x), frozenset(toks)) if toks else float(x) for k, x in zip(_Q, q)})


_MATH = {"ABS": abs, "SQRT": math.sqrt, "EXP": math.exp, "SIN": lambda x: math.sin(math.radians(x)),
         "COS": lambda x: math.cos(math.radians(x)), "TAN": lambda x: math.tan(math.radians(x)),
         "ASIN": lambda x: math.degrees(math.asin(x)), "ACOS": lambda x: math.degrees(math.acos(x)),
         "ATAN": lambda x: math.degrees(math.atan(x)), "ATAN2": lambda y, x: math.degrees(math.atan2(y, x)),
         "POW": lambda a, b: a ** b, "TRUNC": lambda x, dec=0: math.trunc(x * 10 ** dec) / 10 ** dec,
         "ROUND": lambda x, dec=0: round(x, int(dec))}


def math_of(an, st, args, call):
    """``RAPID.MATH(name, args…)``: a math function of known numbers (its value computed from
    their tokens), else not known."""
    name, *values = args
    for v in values:
        an.consume(v, f"{name.lower()}()")
    nums = [number(v) for v in values]
    if None not in nums:
        try:
            return taint(float(_MATH[name](*nums)), *values)
        except (ValueError, TypeError, OverflowError, ZeroDivisionError, KeyError):
            pass
    return Top(f"the value of {name.lower()}() is computed at run time", an.loc, P211)


_ = Tok


# ------------------------------------------------------------------------------- payloads


def gripload(an, st, args, loc):
    """``GripLoad load``: the payload the robot grips from here (``GripLoad load0``: none), on top of
    its tool's tload; the controller resets it to load0 when a program starts."""
    value = an.eval(args[0], st) if args and args[0] is not None else None
    st.vars[("G", "$LOAD")] = value
    return st


def _loaddata(an, value, what: str):
    """A loaddata as (mass, cog x, y, z): ``values.Load``, or Top (P235)."""
    from ...core.diagnostics import P235
    from ..analysis.values import Load

    if isinstance(value, Rec) and (value.label == "load0" or not value.fields):
        return Load((0.0, 0.0, 0.0, 0.0), "load0")
    if isinstance(value, Top):
        return Top(f"{what}: {value.why}", value.loc or an.loc, P235)
    if not isinstance(value, Rec):
        return Top(f"{what} is not a loaddata", an.loc, P235)
    return Dialect.load(an.dialect, an, Rec(value.type, value.fields, value.loc, value.label or what))


def load_of(an, st, args, call):
    """``RAPID.LOAD(tool)``: the payload at a motion with ``tool`` — its tload (cog in the flange
    frame) plus the ``GripLoad`` in force (cog in the tool frame: moved to the flange by the tool's
    tframe), their masses added and their centres of mass weighted."""
    from ...core.diagnostics import P235
    from ..analysis.values import Load, NotSet

    tool = args[0]
    if isinstance(tool, Top):
        return Top(f"the tool is not known ({tool.why})", tool.loc or an.loc, P235)
    if not isinstance(tool, Rec) or tool.type not in ("TOOLDATA", ""):
        return Top("the tool is not a tooldata", an.loc, P235)
    if tool.get("ROBHOLD") is not True:
        return Top("a stationary tool: the robot holds the work object, whose load is not read", an.loc, P235)
    own = _loaddata(an, tool.get("TLOAD"), f"the tload of {tool.label or 'the tool'}")
    if isinstance(own, Top):
        return own
    _, grip = an.lookup("$LOAD", st)
    if grip is None or isinstance(grip, NotSet):
        return own
    held = _loaddata(an, grip, "the GripLoad")
    if isinstance(held, Top) or held[0] == 0:
        return held if isinstance(held, Top) else own
    f = an.dialect.frame(an, tool.get("TFRAME"))
    if isinstance(f, Top):
        return Top(f"the tool's tframe is not known ({f.why})", f.loc or an.loc, P235)
    cog = f.m[:3, :3] @ np.asarray(held[1:], float) + f.m[:3, 3]
    mass = own[0] + held[0]
    centre = (own[0] * np.asarray(own[1:], float) + held[0] * cog) / mass
    return Load([mass, *centre.tolist()], f"{own.label} + {held.label}")


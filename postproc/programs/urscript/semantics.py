"""What URScript means, written once for the analysis (``analysis.dialect.Dialect``).

URScript's own rules (the URScript manual, "Scoping rules", "Threads", module motion):

* Poses ``p[x, y, z, rx, ry, rz]`` are metres and a rotation vector in radians; the lowering
  writes x, y, z as mm (``Num`` value × 1000, ``Unit.unit`` = 1000) and keeps rx, ry, rz as
  written (``form`` "rotvec").
* The frame of every target is the robot base, except where the motion's target is
  ``pose_trans(F, P)`` (P in the frame F: the lowering makes F the motion's frame, P its
  target) and where the controller moves the path at run time: conveyor tracking
  (``track_conveyor_linear/circular`` … ``stop_conveyor_tracking``), a path offset
  (``path_offset_enable`` … ``_disable``), force mode (``force_mode`` … ``end_force_mode``):
  those targets are left as written (P201).
* The tool is ``$TCP``: what ``set_tcp(p)`` sets; before any ``set_tcp`` the installation's
  TCP, which the script does not say (P221 unless the user states it: ``--tool``).
* Variables of the program (the top level of a script, or the body of the ``def`` that is the
  program) are global; a function's variables are local unless declared ``global``, and a
  free variable a function assigns is the global of that name where one exists (``implicit``).
  Parameters are passed by value (lists and poses too).
* A thread (``thread t(): … end``) started with ``run t()`` runs beside the program: what it
  assigns (and the TCP, where it calls ``set_tcp``) is not known while it may run (from the
  ``run`` on; after ``kill``/``join`` of its handle: as it may have left it).
* A function the script neither defines nor is a builtin of URScript is code not read: it may
  change every global and the TCP (``Dialect.unread``). URScript's builtins set none of the
  program's variables: those that only read or report (``get_…``, ``read_…``, I/O,
  ``textmsg`` …) have a value known only at run time (``UR.VALUE``; the math of known numbers is
  computed); those that move the robot without a target (``speedl``, ``stopj``, ``freedrive_mode``
  …) leave where the robot stands unknown.
"""
from __future__ import annotations

import math

import numpy as np

from ...core import frames as fr
from ...core.diagnostics import P201, P203, P211, P215, P221, P222, P223, PostprocError
from ..analysis.dialect import Dialect, PoseView
from ..analysis.values import Mat, Rec, Six, Taint, Tok, Top, number, taint, tokens_of

__all__ = ["UR", "MATH", "JOINT_VALUES", "is_builtin", "TCP_NOT_SET"]

TCP_NOT_SET = ("the TCP is not set by the script before this target (the robot uses the installation's TCP, which the "
               "script does not say): set it with set_tcp(p[…]) or state it with --tool X,Y,Z,A,B,C (mm, deg) or "
               "--tool model")
_EYE = np.eye(4)
_EYE.setflags(write=False)
_XYZ = ("X", "Y", "Z")
_RV = ("RX", "RY", "RZ")
FREE = Mat(_EYE, "robot base")  # the robot base, nothing moving the path

# the math URScript computes from numbers: evaluated where the numbers are known
MATH = {
    "d2r": math.radians, "r2d": math.degrees, "sin": math.sin, "cos": math.cos, "tan": math.tan, "asin": math.asin,
    "acos": math.acos, "atan": math.atan, "atan2": math.atan2, "sqrt": math.sqrt, "pow": math.pow,
    "floor": math.floor, "ceil": math.ceil, "log": math.log, "norm": abs,
}
# builtins whose value is a list of joint positions (a move to it is a joint move)
JOINT_VALUES = frozenset({"get_actual_joint_positions", "get_target_joint_positions", "get_joint_positions",
                          "get_actual_joint_positions_history"})
# URScript builtins that set none of the program's variables, no TCP and no frame (their value,
# if any, is known only at run time); besides the prefixes below
_BUILTINS = frozenset({
    "textmsg", "popup", "sleep", "sync", "powerdown", "is_steady", "is_within_safety_limits", "force",
    "str_at", "str_cat", "str_empty", "str_find", "str_len", "str_sub", "to_num", "to_str", "interpolate_pose",
    "pose_dist", "pose_sub", "point_dist", "binary_list_to_integer", "integer_to_binary_list", "length", "size",
    "normalize", "random", "rotvec2rpy", "rpy2rotvec", "transpose", "inv", "wrench_trans", "struct",
    "tool_contact", "tool_contact_direction", "zero_ftsensor", "high_holding_torque_disable", "enable_external_ft_sensor",
    "conveyor_pulse_decode", "position_deviation_warning", "reset_revolution_counter", "pause_on_error_code",
    "rpc_factory", "modbus_add_signal", "modbus_delete_signal", "modbus_send_custom_command",
    "modbus_set_output_register", "modbus_set_output_signal", "modbus_set_runstate_dependent_choice",
    "modbus_set_signal_update_frequency", "enter_critical", "exit_critical", "request_boolean_from_primary_client",
    "request_integer_from_primary_client", "request_float_from_primary_client", "request_string_from_primary_client",
    "screw_driving", "end_screw_driving", "timer", "local_time", "encoder_enable_pulse_decode",
    "encoder_enable_set_tick_count", "encoder_set_tick_count", "encoder_get_tick_count", "encoder_unwind_delta_tick_count",
    "tool_wrench_limit_set", "safety_remove_tool", "add_frame", "delete_frame", "has_frame", "replace_frame",
    "rename_frame", "convert_pose", "start_ft_sensor", "stop_ft_sensor",
})
_PREFIXES = ("get_", "read_", "write_", "set_", "socket_", "modbus_", "rpc_", "str_", "to_", "is_", "rtde_",
             "tool_", "clear_", "enable_", "disable_", "zero_")


def is_builtin(name: str) -> bool:
    """A URScript builtin that sets none of the program's variables (set_tcp apart: the
    lowering makes it an assignment of ``$TCP``)."""
    return name in _BUILTINS or name in MATH or name.startswith(_PREFIXES)


class UR(Dialect):
    """The URScript dialect. ``active``: the TCP its user states for targets before the first
    ``set_tcp`` (``ActiveFrames.tool``: six numbers or "model"); ``programs``: the routines that
    are the program (their variables are global); ``threads``: the thread routines."""

    name = "URScript"
    form = "rotvec"
    frame_names = ("$TCP", "$CONVEYOR", "$PATH_OFFSET", "$FORCE")
    undeclared_hint = ""
    visible_what = "the TCP and every global"

    def __init__(self, active=None, programs=(), threads=()):
        super().__init__()
        self.active = active
        self.programs = set(programs)
        self.threads = set(threads)
        self._last_tool = None
        self.functions = {"UR.FRAME": frame_of, "UR.pose_trans": pose_trans,
                          "UR.pose_add": pose_add, "UR.pose_inv": pose_inv, "UR.IK": inverse_kin,
                          "UR.PAYLOAD": payload}

    def function(self, name: str):
        if name.startswith("UR.VALUE."):  # (a builtin that reads or reports, by its name)
            return value_of
        return self.functions.get(name)

    # ---------------------------------------------------------------- state
    def initial(self, unit) -> dict:
        tool = None if self.active is None else self.active.tool
        if tool is None:
            tcp = Top(TCP_NOT_SET, None, P221)
        elif tool == "model":
            tcp = "model"
        elif isinstance(tool, tuple):
            tcp = Mat(fr.frame_to_matrix(np.array(tool, float)), "--tool")
        else:  # TOOL_DATA[n] is KUKA's: a script has no such table
            raise PostprocError(f"--tool {tool}: a URScript TCP is stated as X,Y,Z,A,B,C (mm, deg) or 'model'",
                                unit.files[0], 0, 0, P222)
        return {("G", "$TCP"): tcp, ("G", "$CONVEYOR"): FREE, ("G", "$PATH_OFFSET"): FREE, ("G", "$FORCE"): FREE}

    def implicit(self, an, name: str) -> tuple:
        """A variable assigned without ``global``/``local`` where no global of its name exists:
        a global in the program's own body, else the function's local."""
        act = an.act
        if act.routine is None or act.routine.name in self.programs:
            return ("G", name)
        return ("L", act.scope, name)

    def undeclared(self, an, name: str):
        return Top(f"{name} is not assigned before it is read", an.loc, P215)

    def touched(self, an, st, names) -> list:
        """Code not read: ``names`` (its arguments: passed by value, they do not change), or every
        global, the TCP and what moves the path."""
        if names is not None:
            return []
        return [k for k in st.vars if k[0] == "G"] + [("G", n) for n in self.frame_names]

    def handler_code(self, key):
        return None if key[-1] in self.frame_names else P223

    # ---------------------------------------------------------------- values
    def view(self, value) -> PoseView:
        v = super().view(value)
        if value.type == "LIST":
            v.kind = "axis"  # joint positions (movel / movej of a list: a joint target)
        return v

    def axis_values(self, value) -> list | None:
        """A list of six known joint positions (radians, the UR controller's): in degrees."""
        if getattr(value, "type", None) != "LIST" or len(value.fields) != 6:
            return None
        out = [number(value.fields.get(str(k))) for k in range(6)]
        return None if any(v is None for v in out) else [math.degrees(float(v)) for v in out]

    def tool(self, an, value):
        if value == "model":
            return None
        last = self._last_tool
        if last is not None and last[0] is value:  # (one TCP for many targets: its numbers read once)
            an.consume(value, "a frame")
            return last[1]
        six = self._tool(an, value)
        self._last_tool = (value, six)
        return six

    def _tool(self, an, value):
        f = self.frame(an, value)
        if isinstance(f, Top):
            return Top(f.why, f.loc, f.code if f.code in (P203, P221) else P203)
        return Six(fr.matrix_to_frame(f.m), "set_tcp" if f.label != "--tool" else "--tool")

    def row_extras(self, use, view) -> dict:
        return {"qnear": use.config == "qnear"}


# ------------------------------------------------------------------------------- builtins


def frame_of(an, st, args, call):
    """``UR.FRAME(conveyor, path offset, force mode, lefts…)``: the frame of a motion's target,
    the robot base moved by what moves the path, and the ``pose_trans`` frames it is written in."""
    if all(v is FREE for v in args):
        return FREE
    d = an.dialect
    m = np.eye(4)
    labels, toks = [], set()
    for v in args:
        f = d.frame(an, v)
        if isinstance(f, Top):
            return Top(f.why, f.loc, P201)
        m = m @ f.m
        if f.label and f.label != "robot base":
            labels.append(f.label)
        toks |= f.tokens
    return Mat(m, ":".join(labels) or "robot base", frozenset(toks))


def value_of(an, st, args, call):
    """``UR.VALUE.name(args…)``: a builtin that reads or reports: its arguments are read; its
    value is computed for URScript's math of known numbers, a joint list for the functions that
    give joint positions, else known only at run time."""
    name, values = call.name[len("UR.VALUE."):], args
    for v in values:
        an.consume(v, f"passed to {name}()")
    if name in MATH:
        nums = [number(v) for v in values]
        if nums and None not in nums:
            try:
                return taint(float(MATH[name](*nums)), *values)
            except (ValueError, TypeError, OverflowError, ZeroDivisionError):
                pass
    if name in JOINT_VALUES:
        return Rec("LIST", {}, None, f"{name}()")
    return Top(f"{name}() gives a value known only at run time", an.loc, P211)


def _pose(an, v, what: str):
    """A pose value as (4×4, its tokens) or a Top."""
    if isinstance(v, Top):
        return v
    if not isinstance(v, Rec) or v.type == "LIST":
        return Top(f"{what}: not a pose", an.loc)
    nums = [number(v.fields.get(k)) for k in _XYZ + _RV]
    unknown = next((x for x in (v.fields.get(k) for k in _XYZ + _RV) if isinstance(x, Top)), None)
    if unknown is not None:
        return unknown
    if None in nums:
        return Top(f"{what}: a pose with a component that is not a number", an.loc)
    m = np.eye(4)
    with np.errstate(invalid="ignore", over="ignore"):
        m[:3, :3] = fr.rotation_from_rotvec(np.array(nums[3:], float))
    m[:3, 3] = nums[:3]
    return m


def _record(m: np.ndarray, sources) -> Rec:
    """A computed pose (its numbers a Taint of the tokens it comes from: known, not rewritable)."""
    rv = fr.rotvec_from_rotation(m[:3, :3])
    toks: set = set()
    for s in sources:
        tokens_of(s, toks)
    values = list(m[:3, 3]) + list(rv)
    fields = {k: (Taint(float(x), frozenset(toks)) if toks else float(x)) for k, x in zip(_XYZ + _RV, values)}
    return Rec("POSE", fields, None)


def _binary(name, combine):
    def fn(an, st, args, call):
        if len(args) != 2:
            return Top(f"{name}() with {len(args)} arguments", an.loc)
        a, b = (_pose(an, v, f"{name}()") for v in args)
        for x in (a, b):
            if isinstance(x, Top):
                return x
        return _record(combine(a, b), args)
    return fn


def _add(a, b):
    """pose_add: positions added, rotations multiplied (R1·R2; the URScript manual)."""
    m = np.eye(4)
    m[:3, :3] = a[:3, :3] @ b[:3, :3]
    m[:3, 3] = a[:3, 3] + b[:3, 3]
    return m


pose_trans = _binary("pose_trans", lambda a, b: a @ b)
pose_add = _binary("pose_add", _add)


def pose_inv(an, st, args, call):
    if len(args) != 1:
        return Top(f"pose_inv() with {len(args)} arguments", an.loc)
    a = _pose(an, args[0], "pose_inv()")
    if isinstance(a, Top):
        return a
    return _record(fr.inverse(a), args)


def inverse_kin(an, st, args, call):
    """``get_inverse_kin(x, …)`` anywhere but as a motion's target: joint positions computed at
    run time (the pose's numbers are read there)."""
    for v in args:
        an.consume(v, "get_inverse_kin()")
    return Top("joint positions get_inverse_kin() computes at run time", an.loc, P211)


# (kept importable)
_ = Tok


def payload(an, st, args, call):
    """``set_payload(m, cog)`` / ``set_target_payload(m, cog, …)``: the payload in force, mass (kg)
    and centre of gravity (metres in the tool flange frame, here in mm); without ``cog`` the one in
    force stays (``set_payload_mass``): not known unless the mass is 0."""
    from ...core.diagnostics import P235
    from ..analysis.values import Load, Rec

    mass, cog = (list(args) + [None, None])[:2]
    for v in (mass, cog):
        an.consume(v, "a payload")
    what = f"the payload set at line {call.loc.line}" if call.loc is not None else "the payload set"
    m = number(mass)
    if m is None:
        why = mass.why if isinstance(mass, Top) else "its mass is not a number"
        return Top(f"{what}: {why}", an.loc, P235)
    if cog is None:
        if m == 0:
            return Load((0.0, 0.0, 0.0, 0.0), what)
        return Top(f"{what} sets the mass only: the centre of gravity in force is not known", an.loc, P235)
    if not isinstance(cog, Rec):
        why = cog.why if isinstance(cog, Top) else "its centre of gravity is not a list of three numbers"
        return Top(f"{what}: {why}", an.loc, P235)
    xyz = [number(cog.fields.get(str(k))) for k in range(3)]
    if None in xyz or m < 0:
        return Top(f"{what}: its centre of gravity is not known", an.loc, P235)
    return Load([m] + [1000.0 * x for x in xyz], what)


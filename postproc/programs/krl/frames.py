"""$BASE / $TOOL / $ROBROOT tracking: frame expressions, BAS(…), FDAT, WITH lists, frame indices."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from lark import Tree

from ...diagnostics import P201, P203, P220, P221, P222, P225, PostprocError
from ...frames import compose, frame_to_matrix, inverse, matrix_to_frame
from ..model import Frame
from .values import XYZABC, _Agg, _COMP, _Num, _Unknown


@dataclass(frozen=True)
class _FrameState:
    base: object  # 4x4 ndarray, or _Unknown
    base_label: str
    tool: object  # 6 floats tuple, or _Unknown / None (never set)
    tool_label: str
    robroot: object  # 4x4 ndarray or _Unknown

    def same(self, other) -> bool:
        def eq(a, b):
            if isinstance(a, np.ndarray) and isinstance(b, np.ndarray):
                return np.allclose(a, b)
            if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
                return False
            return a is b or a == b

        return eq(self.base, other.base) and eq(self.tool, other.tool) and eq(self.robroot, other.robroot)


_I4 = np.eye(4)


class _NotSet(_Unknown):
    """$BASE / $TOOL that the program does not set before a target and its user did not
    state (``--base`` / ``--tool``): the controller uses whatever is active, so the target's
    frame is not known (P220 base, P221 tool; ``why`` is the whole message)."""

    __slots__ = ("code",)

    def __init__(self, why: str, code: str):
        super().__init__(why)
        self.code = code


_BASE_NOT_SET = _NotSet("$BASE is not set before this target (the controller uses whatever base is active): "
                        "set it in the program or state it with --base N|X,Y,Z,A,B,C", P220)
_TOOL_NOT_SET = _NotSet("$TOOL is not set before this target (the controller uses whatever tool is active): "
                        "set it in the program or state it with --tool N|X,Y,Z,A,B,C|model", P221)
_NEITHER_SET = _NotSet("neither $BASE nor $TOOL is set before this target (the controller uses whatever is "
                       "active): set them in the program or state them with --base and --tool", P220)
# $ROBROOT where nothing gives it (no --robroot, no machine data) and the program does not set
# it: robot base = world, as the controller's default machine data has it. Its own object, so
# that the targets taken with it are known (``Frames.frame_index``) and the assumption said
# once (P224, ``Reader.run``), not per target: every real program would be left otherwise.
_ASSUMED_ROBROOT = np.eye(4)
# a program's start when nothing is stated: neither frame known (``Frames.start_state``)
_START = _FrameState(_BASE_NOT_SET, "", _TOOL_NOT_SET, "", _ASSUMED_ROBROOT)


class Frames:
    """$BASE / $TOOL / $ROBROOT tracking: frame expressions, BAS(…), FDAT, WITH lists, frame indices. (methods of the Reader)"""

    def start_state(self) -> _FrameState:
        """The frames at the start of a program: those its user stated (``ActiveFrames``),
        else not set (P220/P221 at the targets that need them); $ROBROOT stated or from the
        machine data (``ActiveFrames.robroot``), not known on a track (P225), else the assumed
        robot base = world. ``BAS(#INITMOV, 0)`` (the INI fold) initialises motion parameters,
        not $BASE/$TOOL, so it does not change this."""
        st = getattr(self, "_start", None)
        if st is not None:
            return st
        active = self.active
        base, base_label, tool, tool_label = _BASE_NOT_SET, "", _TOOL_NOT_SET, ""
        if active is not None and active.base is not None:
            base, base_label = self.stated_frame(active.base, "base")
        if active is not None and active.tool == "model":
            tool, tool_label = None, ""  # (Frame.tool None: the model's)
        elif active is not None and active.tool is not None:
            tool, tool_label = self.stated_frame(active.tool, "tool")
            tool = tuple(float(x) for x in matrix_to_frame(tool))
        self._start = st = _FrameState(base, base_label, tool, tool_label, self.start_robroot())
        return st

    def start_robroot(self):
        """$ROBROOT before the program sets it: stated or the machine data's (4×4), not known
        (P225: a robot on a track), or the assumed robot base = world."""
        robroot = None if self.active is None else self.active.robroot
        if robroot is None:
            return _ASSUMED_ROBROOT
        if robroot.frame is None:
            return _NotSet(f"$ROBROOT not statically known: {robroot.why} (state it with --robroot X,Y,Z,A,B,C "
                           "if the track stands still)", P225)
        return frame_to_matrix(np.array(robroot.frame, float))

    def stated_frame(self, value, which):
        """A stated --base / --tool (``ActiveFrames``) → (4×4, label); P222 when it names a
        BASE_DATA / TOOL_DATA element not in the data given."""
        if isinstance(value, tuple):
            return frame_to_matrix(np.array(value, float)), f"--{which} {','.join(f'{v:g}' for v in value)}"
        if value == 0:
            return _I4, "$NULLFRAME"
        data = f"{which.upper()}_DATA"
        m = self.data_frame(data, (value,))
        if isinstance(m, _Unknown):
            raise PostprocError(f"--{which} {value}: {m.why}; give $config.dat with --config, or the frame as "
                                "X,Y,Z,A,B,C", f"--{which}", 0, 0, P222)
        return m, f"{data}[{value}]"

    def frame_of(self, expr):
        """A frame expression → (4x4, label) or (_Unknown, label)."""
        d = expr.data
        if d == "aggregate":
            six = self.aggregate(expr).frame6()
            if six is None:
                return _Unknown("a partial or non-literal frame aggregate", (self.ln, 1)), ""
            return frame_to_matrix(np.array(six)), "{…} line %d" % self.ln
        if d == "name":
            n = expr.children[0].upper()
            if n == "$NULLFRAME":
                return _I4, "$NULLFRAME"
            if n == "$BASE":
                return self.state.base, self.state.base_label
            if n == "$ROBROOT":
                return self.state.robroot, "$ROBROOT"
            if n == "$TOOL":
                t = self.state.tool
                if isinstance(t, tuple):
                    return frame_to_matrix(np.array(t)), self.state.tool_label
                return _Unknown("$TOOL is not known here", (self.ln, 1)), ""
            for _, points in self.active_interrupts.values():  # a handler switched on may assign it
                if n in points:
                    return _Unknown(points[n], (self.ln, 1)), ""
            var = self.lookup(n)
            if var is not None and not var.array and isinstance(var.value, _Agg):
                six = var.value.frame6()
                if six is not None:
                    return frame_to_matrix(np.array(six)), n
            why = "not a statically known frame" if var is not None else "undeclared"
            return _Unknown(f"{n}: {why}", (self.ln, 1)), ""
        if d == "index" and expr.children[0].data == "name":
            n = expr.children[0].children[0].upper()
            key = self.index_key(expr)
            label = f"{n}[{key[0] if key and len(key) == 1 else '…'}]"
            return self.data_frame(n, key), label
        if d == "compose":
            m, labels = _I4, []
            for op in expr.children:
                t, lab = self.frame_of(op)
                if isinstance(t, _Unknown):
                    return t, ""
                m = compose(m, t)
                labels.append(lab)
            return m, ":".join(labels)
        if d == "fcall":
            fn = expr.children[0].upper()
            args = [a for a in expr.children[1].children if a is not None]
            if fn == "INV_POS" and len(args) == 1:
                t, lab = self.frame_of(args[0])
                return (t if isinstance(t, _Unknown) else inverse(t)), f"INV_POS({lab})"
            if fn == "SBASE" and len(args) == 1:
                n = self.int_of(args[0])
                if n is None:
                    return _Unknown("SBASE(…) of a run-time number", (self.ln, 1)), ""
                return (self.data_frame("BASE_DATA", (n,)) if n else _I4), f"BASE_DATA[{n}]"
            if fn in ("STOOL2", "STOOL") and len(args) == 1:
                f = self.fdat_of(args[0]) if args[0].data == "name" else _Unknown("STOOL2 of a run-time FDAT")
                return self.fdat_tool(f)
        return _Unknown("a run-time value (function call or expression)", (self.ln, 1)), ""

    def int_of(self, expr):
        v = self.literal_number(expr) if expr.data in ("number", "signed") else None
        if v is not None:
            return int(v.value) if np.isfinite(v.value) else None  # (int(inf) raises)
        if expr.data == "name":  # a variable (or a parameter bound at a call) holding a whole number
            var = self.lookup(expr.children[0])
            v = None if var is None or var.array else var.value
            if isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v) and v == int(v):
                return int(v)
            return None
        if expr.data == "member" and expr.children[0].data == "name":
            f = self.fdat_of(expr.children[0])
            if isinstance(f, _Agg):
                x = f.get(expr.children[1].upper())
                if isinstance(x, _Num) and np.isfinite(x.value):
                    return int(x.value)
        return None

    def data_frame(self, name, key):
        if key is None:
            return _Unknown(f"{name}[…] with a run-time index", (self.ln, 1))
        var = self.lookup(name)
        if var is None or not var.array:
            if name in ("BASE_DATA", "TOOL_DATA") and not self.config:
                return _Unknown(f"{name}[{key[0]}] needs $config.dat (not given)", (self.ln, 1))
            return _Unknown(f"{name} is not declared", (self.ln, 1))
        v = var.elems.get(key)
        if isinstance(v, _Agg):
            six = v.frame6()
            if six is not None:
                return frame_to_matrix(np.array(six))
        return _Unknown(f"{name}[{', '.join(map(str, key))}] is not set in the data given", (self.ln, 1))

    def fdat_tool(self, f):
        return self.fdat_frame(f, "TOOL", "FDAT is a run-time value")

    def fdat_base(self, f):
        return self.fdat_frame(f, "BASE", "FDAT_ACT is not known here")

    def fdat_frame(self, f, which, unknown):
        """The frame FDAT's TOOL_NO / BASE_NO selects (``which`` is "TOOL" or "BASE") and its label."""
        if not isinstance(f, _Agg):
            return _Unknown(unknown, (self.ln, 1)), ""
        n = f.get(f"{which}_NO")
        ipo = f.get("IPO_FRAME")
        if isinstance(ipo, str) and ipo.upper() == "#TCP":
            return _Unknown("external TCP (IPO_FRAME #TCP) is not supported", (self.ln, 1)), ""
        if not isinstance(n, _Num):
            return _Unknown(f"FDAT without {which}_NO", (self.ln, 1)), ""
        if not np.isfinite(n.value) or n.value != int(n.value):  # (int(inf) raises)
            return _Unknown(f"FDAT with a {which}_NO that is not a whole number", (self.ln, 1)), ""
        k = int(n.value)
        if k == 0:
            return _I4, "$NULLFRAME"
        return self.data_frame(f"{which}_DATA", (k,)), f"{which}_DATA[{k}]"

    def replace_state(self, st, which, value, label):
        if which == "$BASE":
            return _FrameState(value, label, st.tool, st.tool_label, st.robroot)
        if which == "$TOOL":
            if isinstance(value, np.ndarray):
                value = tuple(float(x) for x in matrix_to_frame(value))
            return _FrameState(st.base, st.base_label, value, label, st.robroot)
        return _FrameState(st.base, st.base_label, st.tool, st.tool_label, value)

    def assign_frame(self, which, rhs, component=None):
        st = self.state
        if component is not None:
            cur = st.base if which == "$BASE" else (st.robroot if which == "$ROBROOT" else (
                frame_to_matrix(np.array(st.tool)) if isinstance(st.tool, tuple) else _Unknown("")))
            v = self.literal_number(rhs) if rhs.data in ("number", "signed") else None
            if isinstance(cur, np.ndarray) and v is not None and component in _COMP:
                six = matrix_to_frame(cur)
                six[_COMP[component]] = v.value
                new, label = frame_to_matrix(six), f"{which}.{component}= line {self.ln}"
            else:
                new, label = _Unknown(f"{which}.{component} set to a run-time value", (self.ln, 1)), ""
        elif rhs.data == "aggregate":
            agg = self.aggregate(rhs)
            six = agg.frame6()
            if six is None:  # partial: the other components keep their values
                cur = st.base if which == "$BASE" else (st.robroot if which == "$ROBROOT" else (
                    frame_to_matrix(np.array(st.tool)) if isinstance(st.tool, tuple) else None))
                ok = all(isinstance(agg.fields.get(k, None), (_Num, type(None))) for k in XYZABC)
                if isinstance(cur, np.ndarray) and ok:
                    six = list(matrix_to_frame(cur))
                    for k, i in _COMP.items():
                        if isinstance(agg.fields.get(k), _Num):
                            six[i] = agg.fields[k].value
            if six is None:
                new, label = _Unknown(f"{which} is set to a run-time value", (self.ln, 1)), ""
            else:
                new, label = frame_to_matrix(np.array(six, float)), f"{which}={{…}} line {self.ln}"
                if which == "$TOOL":
                    new = tuple(float(x) for x in six)
        else:
            new, label = self.frame_of(rhs)
            if isinstance(new, _Unknown):
                new = _Unknown(f"{which} = {new.why}", (self.ln, 1))
        self.set_state(self.replace_state(st, which, new, label))

    def bas(self, cmd, arg):
        st = self.state
        if cmd in ("#BASE", "#TOOL"):
            n = self.int_of(arg) if arg is not None else None
            which = "$" + cmd[1:]
            if n is None:
                new, label = _Unknown(f"BAS({cmd}, …) with a run-time number", (self.ln, 1)), ""
            elif n == 0:
                new, label = _I4, "$NULLFRAME"
            else:
                data = "BASE_DATA" if cmd == "#BASE" else "TOOL_DATA"
                new, label = self.data_frame(data, (n,)), f"{data}[{n}]"
            self.set_state(self.replace_state(st, which, new, label))
        elif cmd in ("#PTP_PARAMS", "#CP_PARAMS", "#FRAMES"):  # $BASE/$TOOL from FDAT_ACT
            base, bl = self.fdat_base(self.fdat)
            tool, tl = self.fdat_tool(self.fdat)
            st = self.replace_state(st, "$BASE", base, bl)
            st = self.replace_state(st, "$TOOL", tool, tl)
            self.set_state(st)

    def with_frames(self, children):
        """The frame state for a motion/spline with a WITH list ($BASE/$TOOL in it)."""
        st = self.state
        items = []
        for c in children:
            if isinstance(c, Tree) and c.data == "motion_tail":
                items += [x for x in c.children if isinstance(x, Tree) and x.data == "with_item"]
            elif isinstance(c, Tree) and c.data == "with_item":
                items.append(c)
        for it in items:
            lhs, rhs = it.children
            if lhs.data == "name" and lhs.children[0].upper() in ("$BASE", "$TOOL", "$ROBROOT"):
                which = lhs.children[0].upper()
                t, label = self.frame_of(rhs)
                if which == "$TOOL" and isinstance(t, tuple):
                    t = frame_to_matrix(np.array(t))
                st = self.replace_state(st, which, t, label)
            elif lhs.data == "name" and lhs.children[0].upper() == "$IPO_MODE":
                mode = rhs.children[0].upper() if rhs.data == "enum" else None
                if rhs.data == "fcall" and rhs.children[0].upper() == "SIPO_MODE":
                    arg = next((x for x in rhs.children[1].children if x is not None), None)
                    if arg is not None and arg.data == "member" and arg.children[0].data == "name":
                        f = self.fdat_of(arg.children[0])
                        mode = f.get(arg.children[1].upper()) if isinstance(f, _Agg) else None
                if isinstance(mode, str) and mode.upper() == "#TCP":
                    st = _FrameState(_Unknown("external TCP ($IPO_MODE #TCP) is not supported", (self.ln, 1)), "",
                                     st.tool, st.tool_label, st.robroot)
        return st

    def set_state(self, st: _FrameState) -> None:
        """Make ``st`` current from this line on: a timeline entry for the hot rows and a
        barrier for partial aggregates (the current position changes frame)."""
        self.state = st
        if self.role != "module":
            return
        f = self.frame_index(st)
        self.timeline.append((self.kbase + 3, f[0], f[1]))
        self.barrier()

    def frame_index(self, st: _FrameState):
        """(index into Program.frames or -1, reason key for P201/P203).

        A target is left as written (-1) when its base (P201) or its tool (P203: $TOOL set
        but not resolvable, e.g. TOOL_DATA[6] not in the data given) is not known, or when
        the program does not set them and its user did not state them (P220 base or both,
        P221 tool); a tool None is the model's tool, stated with ``--tool model``."""
        for frames, _ in self.active_interrupts.values():  # a handler switched on may set them at any time
            for which, unknown in frames.items():
                st = self.replace_state(st, which, unknown, "")
        why, code = (st.base, P201) if isinstance(st.base, _Unknown) else (
            (st.robroot, P201) if isinstance(st.robroot, _Unknown) else (
                (st.tool, P203) if isinstance(st.tool, _Unknown) and st.tool.why else (None, "")))
        if why is st.base and why is _BASE_NOT_SET and st.tool is _TOOL_NOT_SET:
            why = _NEITHER_SET
        if why is not None:
            code = getattr(why, "code", code)
            key = (self.path, code, why.why)
            if key not in self.unknown_frames:
                what = "frame" if code == P201 else "tool"
                msg = why.why if isinstance(why, _NotSet) else f"{what} not statically known ({why.why})"
                # (a frame not set is located at its first target: ``count_unknown``)
                self.unknown_frames[key] = [self.path, why.where[0] or self.ln, why.where[1] or 1, msg, 0, code,
                                            None if isinstance(why, _NotSet) else ()]
            return -1, key
        assumed = st.robroot is _ASSUMED_ROBROOT
        base = st.base if assumed or st.robroot is _I4 else compose(inverse(st.robroot), st.base)
        tool = st.tool if isinstance(st.tool, tuple) else None
        with np.errstate(over="ignore", invalid="ignore"):  # a 1e308 frame: refused later, not a warning here
            key = (np.round(base, 9).tobytes(), None if tool is None else tuple(round(x, 9) for x in tool), assumed)
        ix = self.frame_ix.get(key)
        if ix is None:
            label = st.base_label + (f" / {st.tool_label}" if st.tool_label else "")
            ix = self.frame_ix[key] = len(self.frames)
            self.frames.append(Frame(base=base.copy(), tool=None if tool is None else np.array(tool), label=label))
            if assumed:
                self.assumed_robroot.add(ix)
        return ix, None

    def count_unknown(self, f, why, n=1, at=None):
        """``n`` more targets left for reason ``why``; ``at`` (key, line, col, path) of the first
        of them, where a frame not set (P220/P221) is reported (default: the current line)."""
        if f < 0 and why in self.unknown_frames:
            entry = self.unknown_frames[why]
            entry[4] += n
            if entry[6] != ():
                at = at or (self.kbase, self.ln, 1, self.path)
                if entry[6] is None or at[0] < entry[6][0]:
                    entry[6] = at

    def frame_for(self, st, lefts):
        if lefts:
            m, labels = (st.base if not isinstance(st.base, _Unknown) else None), [st.base_label]
            for op in lefts:
                t, lab = self.frame_of(op)
                if isinstance(t, _Unknown):
                    st = _FrameState(t, "", st.tool, st.tool_label, st.robroot)
                    m = None
                    break
                if m is not None:
                    m = compose(m, t)
                    labels.append(lab)
            if m is not None:
                st = _FrameState(m, ":".join(labels), st.tool, st.tool_label, st.robroot)
        return self.frame_index(st)

"""One handler per statement that matters to targets: assignments, calls, motions."""
from __future__ import annotations

import re

import numpy as np
from lark import Token, Tree

from ...diagnostics import P202, P210, P211, P214, P215, P223
from .values import _AXIS_TYPES, _Agg, _KIND_OF, _MOTION, _POS_TYPES, _RUNTIME_POS, _STANDARD_AXIS, _Derived, _Unknown, _first_pos


# a handler DEF's own declarations and its assignments (handler_points)
_DECL_NAMES = re.compile(r"^[ \t]*(?:DECL[ \t]+)?(?:INT|REAL|BOOL|CHAR|FRAME|POS|E6POS|AXIS|E6AXIS)[ \t]+(.*)", re.I)
_ASSIGNED = re.compile(r"^[ \t]*([A-Za-z_$][\w$]*)[ \t]*(?:\[[^\]]*\][ \t]*)?(?:\.[ \t]*[\w$]+[ \t]*)?=(?!=)")


class Statements:
    """One handler per statement that matters to targets: assignments, calls, motions. (methods of the Reader)"""

    def s_assign(self, node):
        lhs, rhs = node.children
        root = lhs
        while root.data in ("member", "index"):
            root = root.children[0]
        if root.data != "name":
            return
        name = root.children[0].upper()
        if lhs.data == "name":
            if name in ("$BASE", "$TOOL", "$ROBROOT"):
                self.assign_frame(name, rhs)
                return
            if name == "FDAT_ACT":
                self.fdat = self.value(rhs) if rhs.data == "aggregate" else self.fdat_of(rhs)
                return
            var = self.lookup(name)
            if var is None:
                if name.startswith("$"):
                    return
                var = self.declare(name, "", False)
            if var.array:
                return
            if rhs.data == "aggregate":
                agg = self.aggregate(rhs)
                if agg.type is None and var.type:
                    agg.type = var.type
                if isinstance(var.value, _Agg):
                    agg.base = var.value
                var.value = agg
            elif (source := self.position_source(rhs, name)) is not None:
                var.value = _Derived(source, (self.ln, 1))
            else:
                var.value = self.value(rhs)
                if not isinstance(var.value, _Unknown) and var.type in _POS_TYPES | _AXIS_TYPES:
                    var.value = _Unknown("assigned from an expression", (self.ln, 1))
                elif isinstance(var.value, _Unknown):
                    var.value = _Unknown(f"{name} is assigned a run-time value", (self.ln, 1))
            return
        if lhs.data == "member" and lhs.children[0].data == "name":
            if name in ("$BASE", "$TOOL", "$ROBROOT"):
                comp = lhs.children[1].upper()
                self.assign_frame(name, rhs, component=comp)
                return
            var = self.lookup(name)
            if var is not None and not var.array and isinstance(var.value, _Agg):
                source = self.position_source(rhs, name)
                var.value = _Derived(source, (self.ln, 1)) if source is not None else \
                    _Unknown(f"{name} is modified component-wise at line {self.ln}", (self.ln, 1))
            return
        if lhs.data == "index" and lhs.children[0].data == "name":
            var = self.lookup(name)
            if name.startswith("$") and var is None:
                return
            key = self.index_key(lhs)
            if var is None:
                if self.role == "config" or name in ("BASE_DATA", "TOOL_DATA"):
                    var = self.declare(name, "FRAME" if name in ("BASE_DATA", "TOOL_DATA") else "", True)
                else:
                    return
            if not var.array:
                return
            if key is None:
                var.elems = {k: _Unknown(f"{name}[…] is assigned with a run-time index at line {self.ln}")
                             for k in var.elems}
                var.value = _Unknown(f"{name}[…] is assigned with a run-time index at line {self.ln}")
                return
            val = self.value(rhs)
            if isinstance(val, _Agg):
                if val.type is None and var.type:
                    val.type = var.type
                old = var.elems.get(key)
                if isinstance(old, _Agg) and self.role != "config":
                    val.base = old
            var.elems[key] = val
            return
        # $VEL.CP, $OUT[3], P[1].X, … : a component of an array element
        if lhs.data == "member" and lhs.children[0].data == "index":
            var = self.lookup(name)
            if var is not None and var.array:
                key = self.index_key(lhs.children[0])
                if key is not None and key in var.elems:
                    var.elems[key] = _Unknown(f"{name}{list(key)} is modified component-wise at line {self.ln}")

    def s_call(self, node):
        name = node.children[0].upper()
        args = [a for a in node.children[1].children]
        if name == "BAS" and args and args[0] is not None and args[0].data == "enum":
            self.bas(args[0].children[0].upper(), args[1] if len(args) > 1 else None)
            return
        self.call_states.setdefault(name, []).append(self.state)
        self.after_call(node.children[0], args, node)

    def s_bare_call(self, node):
        self.call_states.setdefault(node.children[0].upper(), []).append(self.state)
        self.after_call(node.children[0], [], node)

    def barrier(self):
        """The current position is unknown from here on (partial aggregates get NaN)."""
        if self.role != "module":
            return
        self.add_row(self.kbase + 3, [np.nan] * 6, [True] * 6, [-1] * 12, self.fi, 0, 0, 0, -1, False, True)

    def add_row(self, key, pose, written, spans, fi, line, col, motion, frame, emit, chain, config=(-1, -1)):
        c = self.cold
        c["config"].append(config)
        c["key"].append(key)
        c["pose"].append(pose)
        c["written"].append(written)
        c["spans"].append(spans)
        c["file"].append(fi)
        c["line"].append(line)
        c["col"].append(col)
        c["motion"].append(motion)
        c["frame"].append(frame)
        c["emit"].append(emit)
        c["chain"].append(chain)

    def s_move(self, node):
        kw = node.children[0].upper()
        self.motion(kw, [(node.children[1], _MOTION[_KIND_OF[kw.replace("_REL", "")]], True)], node)

    def s_circ(self, node):
        kw = node.children[0].upper()
        s = "SCIRC" if kw.startswith("S") else "CIRC"
        self.motion(kw, [(node.children[1], _MOTION[s + "-aux"], False),
                         (node.children[2], _MOTION[s + "-end"], True)], node)

    def motion(self, kw, ops, node):
        if not self.in_def:
            self.err("a motion must stand inside DEF … END", _first_pos(node))
        if kw == "SPL" and not any(b[0] == "SPLINE" for b in self.blocks):
            self.err("SPL must stand inside SPLINE … ENDSPLINE", _first_pos(node))
        if kw.endswith("_REL"):
            self.warn(self.path, self.ln, self.col(_first_pos(node)), P210,
                      f"relative motion {kw} left as written (its absolute target is known only at run time)")
            self.barrier()
            return
        st = self.with_frames(node.children)
        for sub, (expr, motion, chain) in enumerate(ops):
            self.target(expr, motion, chain, st, sub)

    def target(self, expr, motion, chain, st, sub):
        """Resolve one motion operand; add its row(s)."""
        key = self.kbase + sub
        extra = []  # left operands of ':'
        if expr.data == "compose":
            *lefts, expr = expr.children
            extra = lefts
        d = expr.data
        if d == "aggregate":
            agg = self.aggregate(expr)
            kind = agg.kind()
            if kind == "axis":
                self.barrier()
                return
            if kind == "other":
                return
            f, why = self.frame_for(st, extra)
            pose, spans, written = agg.pose(self.path, self.text)
            emit = any(written[:3])
            self.add_row(key, pose, written, spans, self.fi, agg.line, agg.col, motion, f, emit, chain, agg.config())
            if emit:
                self.count_unknown(f, why, at=(key, agg.line, agg.col, self.path))
            return
        if d == "name":
            name = expr.children[0]
            aggs = self.named_value(name, None, expr)
        elif d == "index" and expr.children[0].data == "name":
            name = expr.children[0].children[0]
            aggs = self.named_value(name, self.index_key(expr), expr, indexed=True)
        elif d == "member" and _root_name(expr) is not None and expr.children[0].data in ("name", "index"):
            name = _root_name(expr)
            aggs = self.member_value(expr)
        else:
            self.warn(self.path, self.ln, self.col(_first_pos(expr)), P211,
                      "target is computed at run time (function call or expression): left as written")
            self.barrier()
            return
        if aggs is None:
            self.barrier()
            return
        f, why = self.frame_for(st, extra)
        for agg in aggs:
            seen = self.targets_of.get(id(agg))
            if seen is not None:
                if seen[0] != f:
                    self.warn(self.path, self.ln, self.col(_first_pos(expr)), P202,
                              f"{str(name)} is used in another frame than at its first use (line {seen[1]}): "
                              "compensated for the first")
                pose, _, _ = agg.pose(*self.where(agg.file))
                if len(aggs) == 1:
                    self.add_row(key, pose, [True] * 6, [-1] * 12, agg.file, agg.line, agg.col, motion, f, False,
                                 chain, agg.config())
                continue
            self.targets_of[id(agg)] = (f, self.ln)
            pose, spans, _ = agg.pose(*self.where(agg.file))
            emit = any(s >= 0 for s in spans[:6]) and agg.file >= 0  # (X, Y, Z tokens)
            self.add_row(key, pose, [True] * 6, spans, agg.file, agg.line, agg.col, motion, f, emit,
                         chain and len(aggs) == 1, agg.config())
            if emit:
                self.count_unknown(f, why, at=(key, self.ln, self.col(_first_pos(expr)), self.path))
        if len(aggs) != 1:
            self.barrier()

    def member_value(self, expr):
        """The aggregates a STRUC member target (``gs[i].fCNC``, ``gPoint.fCNC``) stands for:
        one element for a literal index, every element in range for the variable of an
        enclosing FOR with constant bounds; None (warned) otherwise."""
        base, field = expr.children[0], str(expr.children[1]).upper()
        pos = _first_pos(expr)
        name = str(_root_name(expr))
        if self.active_interrupts and self.async_point(name, pos):
            return None
        var = self.lookup(name)
        written = f"{name}{'[…]' if base.data == 'index' else ''}.{expr.children[1]}"
        if var is None:
            self.warn(self.path, self.ln, self.col(pos), P215,
                      f"target {written}: {name} is not declared in the files read (a global of a data list "
                      "or $config.dat not given?): left as written")
            return None
        if var.type in _POS_TYPES | _AXIS_TYPES or (var.array != (base.data == "index")):
            self.warn(self.path, self.ln, self.col(pos), P211, f"target {written} is not a STRUC member: "
                      "left as written")
            return None
        ftype = self.strucs.get(var.type, {}).get(field, "")
        if ftype in _AXIS_TYPES:
            return None
        if base.data == "name":
            values = [var.value]
        else:
            keys = self.loop_keys(base)
            if isinstance(keys, str):
                self.warn(self.path, self.ln, self.col(pos), P211, f"target {written}: {keys}: left as written")
                return None
            values = [var.elems.get(k) for k in keys]
            if any(v is None for v in values):
                missing = next(k for k, v in zip(keys, values) if v is None)
                self.warn(self.path, self.ln, self.col(pos), P211, f"target {written}: {name}"
                          f"[{', '.join(map(str, missing))}] is not initialised in the files read: left as written")
                return None
        out = []
        for v in values:
            m = v.get(field) if isinstance(v, _Agg) else None
            if not isinstance(m, _Agg):
                why = v.why if isinstance(v, _Unknown) else f"its {field} is not a literal aggregate"
                self.warn(self.path, self.ln, self.col(pos), P211,
                          f"target {written} not statically known ({why}): left as written")
                return None
            if m.type is None and ftype:
                m.type = ftype
            if m.kind() == "axis":
                return None
            out.append(m)
        return out

    def loop_keys(self, index):
        """Index tuples of ``a[i]`` for a literal index or the variable of an enclosing FOR
        with constant bounds; a reason (str) otherwise."""
        key = self.index_key(index)
        if key is not None:
            return [key]
        args = [e for e in index.children[1:]]
        if len(args) != 1 or args[0] is None or args[0].data != "name":
            return "the index is not a literal or a FOR variable"
        v = str(args[0].children[0]).upper()
        loop = next((lp for lp in reversed(self.loops) if lp[0] == v), None)
        if loop is None:
            return f"the index {args[0].children[0]} is not the variable of an enclosing FOR"
        _, lo, hi, step = loop
        if lo is None or hi is None or step is None or step == 0:
            return f"the FOR over {args[0].children[0]} has bounds known only at run time"
        return [(k,) for k in range(lo, hi + (1 if step > 0 else -1), step)]

    def named_value(self, name, key, expr, indexed=False):
        """The aggregates a named target stands for, or None (warned) when not Cartesian/known."""
        u = str(name).upper()
        var = self.lookup(u)
        pos = _first_pos(expr)
        if self.active_interrupts and self.async_point(name, pos):
            return None
        if var is None:
            if _STANDARD_AXIS.match(u):
                return None
            if _RUNTIME_POS.match(u) or u.startswith("$"):
                self.warn(self.path, self.ln, self.col(pos), P211,
                          f"target {name} is a run-time position: left as written")
                return None
            self.warn(self.path, self.ln, self.col(pos), P215,
                      f"target {name} is not declared in the files read (a global of a data list or "
                      "$config.dat not given?): left as written")
            return None
        if var.type in _AXIS_TYPES:
            return None
        if var.type and var.type not in _POS_TYPES:
            # user STRUC types or wrong types: nothing we can read as X…C
            values = [var.value] if not var.array else list(var.elems.values())
            if not any(isinstance(v, _Agg) and v.kind() == "cart" for v in values):
                self.warn(self.path, self.ln, self.col(pos), P211,
                          f"target {name} has type {var.type}, not a position: left as written")
                return None
        if var.array != indexed:
            if var.array:
                self.warn(self.path, self.ln, self.col(pos), P211, f"target {name} is a whole array")
                return None
            self.warn(self.path, self.ln, self.col(pos), P211, f"target {name}[…] is not an array")
            return None
        if indexed:
            if key is None:
                items = sorted(var.elems.items())
                vals = [v for _, v in items if isinstance(v, _Agg)]
                unknown = [v for _, v in items if isinstance(v, _Unknown)]
                if isinstance(var.value, _Unknown) or unknown or not vals:
                    why = var.value.why if isinstance(var.value, _Unknown) else (
                        unknown[0].why if unknown else f"no element of {name} is initialised")
                    self.warn(self.path, self.ln, self.col(pos), P211,
                              f"target {name}[…] not statically known ({why}): left as written")
                    return None
                out = []
                for v in vals:
                    if v.kind() == "cart":
                        out.append(v)
                return out or None
            v = var.elems.get(key)
            label = f"{name}[{', '.join(map(str, key))}]"
        else:
            v = var.value
            label = str(name)
        if isinstance(v, _Agg):
            if v.kind() == "axis":
                return None
            return [v]
        if isinstance(v, _Derived):
            self.warn(self.path, self.ln, self.col(pos), P214,
                      f"target {label} is {v.why}: at run time it moves with {v.source} (and carries "
                      f"{v.source}'s correction when {v.source} is compensated), not with its own; left as written")
            return None
        why = v.why if isinstance(v, _Unknown) else "it has no value here"
        self.warn(self.path, self.ln, self.col(pos), P211, f"target {label} not statically known ({why}): "
                  "left as written")
        return None


def _root_name(expr):
    """The name token at the root of a member / index chain, or None."""
    while expr.data in ("member", "index"):
        expr = expr.children[0]
    return expr.children[0] if expr.data == "name" else None


class AsyncStatements:
    """INTERRUPT DECL … DO, TRIGGER … DO and IMPORT: statements whose effect is not at their
    line. (methods of the Reader)"""

    _FRAMES = ("$BASE", "$TOOL", "$ROBROOT")

    def s_interrupt_decl(self, node):
        """A handler whose code is read and that sets frames or points is recorded: while it is
        switched on (INTERRUPT ON … OFF) it may run before any target, so those frames are
        unknown at every target and those points are no targets (P223); after OFF they are
        unknown until set again. A handler calling code not read: its frames unknown from the
        declaration until the program sets them again (it is not known to set any)."""
        action = node.children[-1]
        number = next((c for c in node.children if isinstance(c, Tree)), None)
        n = self.int_of(number) if number is not None else None
        if action.data in ("call", "bare_call") and str(action.children[0]).upper() not in self.defs(self.fi):
            self.async_frames(action, "INTERRUPT")  # (code not read)
            return
        before = self.state
        frames = self.async_frames(action, "INTERRUPT", apply=False)
        points = self.handler_points(action)
        self.state = before
        if frames or points:
            self.interrupts[n] = (frames, points)

    def s_interrupt_ctl(self, node):
        """INTERRUPT ON / OFF [n] (no number: all); ENABLE / DISABLE change nothing here (a
        disabled interrupt runs when enabled again)."""
        words = {str(c).upper() for c in node.children if isinstance(c, Token)}
        number = next((c for c in node.children if isinstance(c, Tree)), None)
        n = self.int_of(number) if number is not None else None
        if "ON" in words:
            keys = list(self.interrupts) if number is None or n is None else [k for k in (n, None)
                                                                               if k in self.interrupts]
            for k in keys:
                self.active_interrupts[k] = self.interrupts[k]
            if keys:
                self.set_state(self.state)  # (the targets from here on see the handlers switched on)
        elif "OFF" in words:
            # (OFF of a run-time number: which one is not known, all stay on)
            keys = list(self.active_interrupts) if number is None else ([n] if n in self.active_interrupts else [])
            st = self.state
            for k in keys:
                frames, points = self.active_interrupts.pop(k)
                # it may have run: what it sets stays unknown until the program sets it again
                for which, unknown in frames.items():
                    st = self.replace_state(st, which, unknown, "")
                for name, why in points.items():
                    var = self.lookup(name)
                    if var is not None and not var.array:
                        var.value = _Unknown(why, (self.ln, 1))
            if keys:
                self.set_state(st)

    def handler_points(self, action) -> dict:
        """The position variables a handler assigns (itself, or the DEF it calls: its
        assignments to names that are not its own), name → why."""
        why = f"may be assigned by the INTERRUPT handler declared at line {self.ln}"
        if action.data == "assign":
            root = action.children[0]
            while root.data in ("member", "index"):
                root = root.children[0]
            name = str(root.children[0]).upper() if root.data == "name" else ""
            return {name: f"{name} {why}"} if name and not name.startswith("$") else {}
        callee = self.defs(self.fi).get(str(action.children[0]).upper())
        if callee is None:
            return {}
        text = self.texts[callee.fi]
        lines = text.split("\n")[callee.first:callee.last]
        own = {p for p in callee.params}
        out = {}
        for line in lines:
            m = _DECL_NAMES.match(line)
            if m:
                own |= {w.upper() for w in re.findall(r"[\w$]+", m.group(1))}
                continue
            m = _ASSIGNED.match(line)
            if m and m.group(1).upper() not in own and not m.group(1).startswith("$"):
                name = m.group(1).upper()
                out[name] = f"{name} {why} ({callee.name}())"
        return out

    def async_point(self, name, pos) -> bool:
        """A target named ``name`` that a handler switched on may assign: P223, left as written."""
        u = str(name).upper()
        for _, points in self.active_interrupts.values():
            if u in points:
                self.warn(self.path, self.ln, self.col(pos), P223,
                          f"target {name} is not known here ({points[u]}, switched on): left as written")
                return True
        return False

    def s_trigger(self, node):
        action = next(c for c in node.children if isinstance(c, Tree) and c.data in ("assign", "call", "bare_call",
                                                                                     "brake"))
        self.async_frames(action, "TRIGGER")

    def async_frames(self, action, what, apply=True):
        """A handler that may set $BASE/$TOOL/$ROBROOT runs at a time the reader cannot know:
        each frame it may set is unknown from its declaration on (P201/P203 at the targets).
        Returns frame → its unknown value; ``apply=False``: the state is left as it was."""
        st, where = self.state, (self.ln, self.col(_first_pos(action)))
        if action.data == "assign":
            root = action.children[0]
            while root.data in ("member", "index"):
                root = root.children[0]
            name = str(root.children[0]).upper() if root.data == "name" else ""
            changed = [name] if name in self._FRAMES else []
            label = name
        elif action.data == "brake":
            return {}
        else:
            self.after_call(action.children[0], [a for a in action.children[1].children]
                            if action.data == "call" else [], action)
            new, self.state = self.state, st
            changed = [w for w, a, b in zip(self._FRAMES, (st.base, st.tool, st.robroot),
                                            (new.base, new.tool, new.robroot)) if a is not b]
            label = f"{action.children[0]}()"
        new, out = st, {}
        for which in changed:
            why = f"{which} may be set by the {what} handler {label} declared at line {self.ln}"
            out[which] = _Unknown(why, where)
            new = self.replace_state(new, which, out[which], "")
        if not apply:
            self.state = st
        elif new is not st:
            self.set_state(new)
        return out

    def s_import_decl(self, node):
        typ = node.children[1].children[0].upper()
        dims = any(isinstance(c, Tree) and c.data == "dims" for c in node.children)
        self.declare(node.children[2], typ, dims, _Unknown(f"{node.children[2]} is imported (IMPORT … IS)"))

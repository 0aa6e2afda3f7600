"""Following calls: what a called subroutine does to $BASE / $TOOL (they are global system
variables, so a frame set in a callee holds after the call, as on the controller).

A call site runs the callee's frame statements (assignments, ``BAS(…)``, FDAT_ACT, nested
calls; declarations) in a sandbox from the caller's frame state, with the parameters bound
that are constants at the call site (``MoveSettings(2, 4, 100, 500)`` → ``nTool`` = 4).
The callee may be a DEF of the same module or the main / GLOBAL DEF of another module read
in the same call. A callee that is not available, a recursion or a depth beyond
``MAX_DEPTH`` make the frame after the call unknown (P201 base / P203 tool, at the call's
line); a frame the callee sets from a run-time value is unknown the same way.
"""
from __future__ import annotations

import re
from bisect import bisect_right
from dataclasses import dataclass

from .frames import _FrameState
from .syntax import _PLACEHOLDER, SHAPE_RE
from .values import _first_pos, _Unknown, _Var

# KUKA system subroutines known not to touch $BASE / $TOOL (BAS is handled by its #command)
# KRL system statements written as calls (PULSE, CWRITE…): they cannot set a frame
HARMLESS = frozenset({"SET_CD_PARAMS", "PULSE", "CWRITE", "CREAD", "SWRITE", "SREAD", "CAST_TO", "CAST_FROM"})
# KRL's built-in functions (and KUKA system functions) called in expressions: they set no
# frame; any other function is followed like a called DEF (not read: frames unknown after it)
BUILTIN_FUNCTIONS = frozenset({
    "ABS", "SQRT", "SIN", "COS", "TAN", "ACOS", "ASIN", "ATAN2", "INV_POS", "FORWARD", "INVERSE", "VARSTATE",
    "STRLEN", "STRDECLLEN", "STRCLEAR", "STRCOPY", "STRCOMP", "STRFIND", "STRADD", "SBASE", "STOOL", "STOOL2",
    "SIPO_MODE", "SLOAD", "SACC_JOINT", "SVEL_JOINT", "SACC_CP", "SVEL_CP", "SORI_TYP", "SCIRC_TYP", "SAPO",
    "SAPO_PTP", "SJERK", "SPATH", "SGEAR_JERK", "SSTEP", "SCIRC_MODE", "STECH", "STECHPAR", "SVEL_TECH",
    "SACC_TECH", "SIPO", "EB_TEST", "EO_TEST", "IS_KEY_PRESSED", "GET_SIG_INF", "GETCYCDEF", "SET_KRLMSG",
    "SET_KRLDLG", "EXISTS_KRLMSG", "EXISTS_KRLDLG", "CLEAR_KRLMSG", "MBX_REC", "DELETE_BACKWARD_BUFFER",
    "GET_SYSTEM_DATA", "CAST_TO", "CAST_FROM", "CREAD", "CWRITE", "SREAD", "SWRITE",
})
MAX_DEPTH = 8
# the statements a callee runs in the sandbox (everything else cannot change a frame), and the
# block statements whose control flow decides which of them hold after it (flow.py)
EFFECT_STATEMENTS = frozenset({"assign", "call", "bare_call", "decl"})
FLOW_STATEMENTS = frozenset({"if_head", "else_", "endif", "switch_head", "case", "default", "endswitch",
                             "for_head", "endfor", "while_head", "endwhile", "loop_head", "endloop",
                             "repeat_head", "until", "exit_", "goto", "label"})

# a line that runs nothing in a sandbox: a motion to a literal aggregate (no function call in
# it), a comment, a blank line; the others (_LIVE, one empty match at each line start)
_INERT = r"[ \t]*(?:(?:S?(?:LIN|PTP|CIRC)|SPL)[ \t]*\{[^()\n;]*(?:;[^\n]*)?|;[^\n]*)?\r?$"
_LOOP_CLOSE = frozenset({"endfor", "endwhile", "endloop", "until"})
_INERT_MOTION = re.compile(r"^[ \t]*(?:S?(?:LIN|PTP|CIRC)|SPL)[ \t]*\{", re.I | re.M)
_LIVE = re.compile(r"^(?!" + _INERT + r")", re.I | re.M)
_FRAME_VARIABLES = frozenset({"$BASE", "$TOOL", "$ROBROOT", "FDAT_ACT", "BASE_DATA", "TOOL_DATA"})
_DEF = re.compile(r"^[ \t]*(GLOBAL[ \t]+)?DEF(?:FCT[ \t]+[\w$\[\] ]+?)?[ \t]+([\w$]+)[ \t]*\(([^)\n]*)\)",
                  re.I | re.M)
_END = re.compile(r"^[ \t]*END(?:FCT)?(?![\w$])", re.I | re.M)


@dataclass
class _Def:
    name: str
    fi: int  # file index of the module
    first: int  # 0-based line index of the first body line
    last: int  # 0-based line index of END (exclusive end of the body)
    params: list  # upper-case parameter names, in order
    visible: bool  # callable from other modules (the module's first DEF, or GLOBAL)


def _index(fi: int, text: str) -> list:
    starts = [0] + [m.end() for m in re.finditer("\n", text)]
    ends = [m.start() for m in _END.finditer(text)]
    out = []
    for k, m in enumerate(_DEF.finditer(text)):
        at = bisect_right(ends, m.end())
        if at >= len(ends):
            continue  # no END: the reader reports it
        first = bisect_right(starts, m.start())  # 1-based line of the header = 0-based next line
        last = bisect_right(starts, ends[at]) - 1
        params = [p.split(":")[0].split("[")[0].strip().upper() for p in m.group(3).split(",") if p.strip()]
        out.append(_Def(m.group(2).upper(), fi, first, last, params, k == 0 or bool(m.group(1))))
    return out


class Calls:
    """Following calls (methods of the Reader)."""

    def defs(self, fi: int) -> dict:
        """name → _Def callable from module file ``fi`` (built on first use)."""
        if getattr(self, "_defs", None) is None:
            self._defs = [_index(k, t) for k, t in enumerate(self.texts)]
            self._def_memo = {}
            self._call_depth = getattr(self, "_call_depth", 0)
        out = {}
        for k, ds in enumerate(self._defs):
            if k != fi:
                for d in ds:
                    if d.visible:
                        out.setdefault(d.name, d)
        for d in self._defs[fi] if fi >= 0 else ():
            out[d.name] = d  # the module's own DEFs first
        return out

    def after_call(self, name: str, args: list, node) -> None:
        """The frame state after ``name(args)`` at the current line (``name`` as written)."""
        written, name = str(name), str(name).upper()
        if name in HARMLESS:
            return
        st = self.state
        callee = self.defs(self.fi).get(name)
        where = (self.ln, self.col(_first(node)))
        if callee is None:
            why = f"{written}() called at line {self.ln} is not in the files read"
            self.set_state(_FrameState(_Unknown(why, where), "", _Unknown(why, where), "", st.robroot))
            return
        if self._call_depth >= MAX_DEPTH or name in getattr(self, "_call_stack", ()):
            why = f"{written}() called at line {self.ln} recurses"
            self.set_state(_FrameState(_Unknown(why, where), "", _Unknown(why, where), "", st.robroot))
            return
        bound = {}
        for p, a in zip(callee.params, args):
            v = self.constant(a) if a is not None else None
            if v is not None:
                bound[p] = v
        key = (name, tuple(sorted(bound.items())), id(st), id(self.fdat))
        hit = self._def_memo.get(key)
        if hit is not None and hit[0] is st and hit[1] is self.fdat:
            new, fdat, moved = hit[2], hit[3], hit[4]
        else:
            fdat0 = self.fdat
            new, fdat, moved = self.run_callee(callee, bound, st)
            self._def_memo[key] = (st, fdat0, new, fdat, moved)
        self.fdat = fdat
        if moved:  # the robot moved in the callee: the current position is not the caller's last target
            self.moves += 1
            if self.role == "effect":
                self._moved = True
            else:
                self.barrier()

        def located(value, entry):
            if value is entry or not isinstance(value, _Unknown):
                return value
            return _Unknown(f"{value.why} in {written}() called at line {self.ln}", where)

        new = _FrameState(located(new.base, st.base), new.base_label, located(new.tool, st.tool), new.tool_label,
                          located(new.robroot, st.robroot))
        if new.base is not st.base or new.tool is not st.tool or new.robroot is not st.robroot:
            self.set_state(new)

    def expression_calls(self, stmt) -> None:
        """Functions called inside the statement's expressions (``n = GetBase()``, ``IF Ok() THEN``),
        in the order written: what they do to $BASE/$TOOL holds after them, as for a call."""
        for node in stmt.iter_subtrees_topdown():
            if node.data != "fcall" or str(node.children[0]).upper() in BUILTIN_FUNCTIONS:
                continue
            self.after_call(node.children[0], [a for a in node.children[1].children], node)

    def constant(self, expr):
        """A call argument that is a constant at the call site (number), or None."""
        v = self.literal_number(expr) if expr.data in ("number", "signed") else None
        if v is not None:
            return v.value
        if expr.data == "name":
            var = self.lookup(expr.children[0])
            if var is not None and not var.array and isinstance(var.value, (int, float)) \
                    and not isinstance(var.value, bool):
                return float(var.value)
        return None

    def frame_write(self, stmt) -> bool:
        """Does this assignment (in a callee) write a frame, FDAT_ACT or a callee's local?"""
        root = stmt.children[0]
        while root.data in ("member", "index"):
            root = root.children[0]
        if root.data != "name":
            return False
        name = root.children[0].upper()
        return name in _FRAME_VARIABLES or name in self.local

    def run_callee(self, callee: _Def, bound: dict, entry: _FrameState):
        """(frame state, FDAT_ACT, moves) after running the callee's frame statements from
        ``entry``; ``moves``: the callee (or one it calls) has a motion statement."""
        local = {p: _Var(p, "", False, v) for p, v in bound.items()}
        for p in callee.params:
            local.setdefault(p, _Var(p, "", False, _Unknown(f"parameter {p} is a run-time value")))
        stack = getattr(self, "_call_stack", ())
        try:
            self._call_stack = stack + (callee.name,)
            self._call_depth += 1
            return self.sandbox(callee.fi, callee.first, callee.last, local, entry)
        finally:
            self._call_stack = stack
            self._call_depth -= 1

    def run_body(self, first: int, last: int | None, entry: _FrameState):
        """(frame state, moves, end) after one run of a loop body (0-based lines ``first`` to
        ``last`` exclusive of the current file; ``last`` None: up to the statement that closes
        the loop, whose line is ``end``, None when there is none) from ``entry``: nothing it writes stays (its
        variables are copies; FDAT_ACT is restored); an element of BASE_DATA / TOOL_DATA it
        assigns is unknown from the loop on (the next iteration sees the new value)."""
        local = {k: _Var(v.name, v.type, v.array, v.value, dict(v.elems) if v.elems is not None else None)
                 for k, v in (self.local or {}).items()}
        data = {n: v for n in ("BASE_DATA", "TOOL_DATA") if (v := self.lookup(n)) is not None and v.elems is not None}
        before = {n: dict(v.elems) for n, v in data.items()}
        fdat = self.fdat
        depth = getattr(self, "_call_depth", 0)
        try:
            self._call_depth = depth + 1
            state, _, moved = self.sandbox(self.fi, first, last, local, entry)
            end = self._closed_at
        finally:
            self._call_depth = depth
            self.fdat = fdat
            for n, v in data.items():
                changed = [k for k, x in v.elems.items() if before[n].get(k) is not x]
                v.elems = before[n]
                for k in changed:
                    v.elems[k] = _Unknown(f"{n}[{', '.join(map(str, k))}] is assigned in the loop at line {self.ln}")
        return state, moved, end

    def sandbox(self, fi: int, first: int, last: int | None, local: dict, entry: _FrameState):
        """Run the frame statements (and the control flow around them) of lines ``first`` to
        ``last`` of file ``fi`` from ``entry`` with ``local`` as the local variables: (frame
        state, FDAT_ACT, moves); the reader's own state is as before afterwards. ``last``
        None: up to a loop's end that no block of these lines opened (its line in
        ``self._closed_at``, None if none)."""
        keep = ("fi", "path", "text", "role", "starts", "ln", "kbase", "la", "lt", "sh", "_nums", "_cum",
                "local", "state", "blocks", "folds", "in_def", "diagnostics", "block_open", "_moved", "flow",
                "loops", "moves", "gotos", "_closed_at")
        saved = {k: getattr(self, k, None) for k in keep}
        saved["_closed_at"] = None
        try:
            text = self.texts[fi]
            self.fi, self.path, self.text, self.role = fi, self.files[fi], text, "effect"
            self.local = local
            self.state, self.blocks, self.folds, self.in_def = entry, [], [], True
            self.flow, self.loops, self.moves, self.gotos = [], [], 0, {}
            self._moved = False
            self.diagnostics, self.block_open = [], {}
            same = fi == saved["fi"] and saved["role"] == "module"  # (the file being read: its line starts)
            starts = saved["starts"] if same else [0] + [m.end() for m in re.finditer("\n", text)]
            self.starts = starts
            n = len(starts)
            self._closed_at = None
            lo = int(starts[first]) if first < n else len(text)
            hi = int(starts[last]) if last is not None and last < n else len(text)
            # literal motions, comments and blank lines do nothing here but move: skipped in C
            moved = False
            for live in _LIVE.finditer(text, lo, hi):
                i = bisect_right(starts, live.start()) - 1
                a = int(starts[i])
                b = int(starts[i + 1]) - 1 if i + 1 < n else len(text)
                line = text[a:b]
                sh = self.shape(SHAPE_RE.sub(_PLACEHOLDER, line))
                if sh.kind == "hot":
                    moved = True
                if sh.kind not in ("stmt",) or sh.tree is None:
                    continue
                stmt = next((c for c in sh.tree.children if hasattr(c, "data")), None)
                if stmt is not None and stmt.data in ("move", "circ"):
                    moved = True
                if last is None and stmt is not None and stmt.data in _LOOP_CLOSE and not self.blocks:
                    saved["_closed_at"] = i  # (the loop's own end: kept after the restore below)
                    break
                if stmt is None or (stmt.data not in EFFECT_STATEMENTS and stmt.data not in FLOW_STATEMENTS):
                    if stmt is not None and sh.fcalls and stmt.data not in ("interrupt_decl", "trigger"):
                        # (WAIT FOR Ok(), a motion to F(): the function runs)
                        self.ln, self.la, self.lt, self.sh, self._nums = i + 1, a, line, sh, None
                        self.expression_calls(self.concrete(sh.tree) if sh.names else sh.tree)
                    continue
                if stmt.data == "assign" and not self.frame_write(stmt):
                    continue  # other variables: the callee's own pass reads them
                self.interpret(i, a, line, sh)
            if saved["_closed_at"] is not None:  # (a loop's body: up to its end)
                hi = int(starts[saved["_closed_at"]])
            moved = moved or _INERT_MOTION.search(text, lo, hi) is not None
            return self.state, self.fdat, moved or self._moved
        finally:
            for k, v in saved.items():
                setattr(self, k, v)


def _first(node):
    return _first_pos(node) or 0

"""URScript statements → the motion IR (``programs.ir``). What a statement *means* is said in
``semantics.py`` and the analysis; here is only how URScript writes it.

The script is cut into logical lines (a line, joined with the next while a bracket is open;
``#`` comments and the insides of strings blanked, same length: offsets stay those of the
file). Each distinct line *shape* (numbers → 0, digits ending a name → 0, blanks collapsed) is
parsed once with ``grammars/urscript.lark``; a line's own names and numbers are its tokens, in
the order the shape's tree holds them (``ordinal``).

Two passes: the first reads every line's shape and the functions the script defines (their
parameters: calls with keyword arguments are bound by name); the second lowers the lines into
the blocks they stand in.
"""
from __future__ import annotations

import re

from lark import Token, Tree
from lark.exceptions import UnexpectedInput

from ...core.diagnostics import P101, P102, P103, P117, LineIndex, PostprocError
from ...core.frames import MM
from ..grammar import TOKEN_RE, exact_key, lalr_parser, shape_key, unexpected
from ..ir import (
    Agg, Assign, Async, AsyncSwitch, Call, Continue, Decl, Eval, Exit, Field, Halt, Havoc, If, Invoke, Item, Lit,
    Loc, Loop, Move, Name, Num, Op, Param, Return, Routine, Unit, Unknown,
)
from .semantics import JOINT_VALUES, MATH, is_builtin

__all__ = ["Lowering", "parser", "UNIT_MM", "MOTION_OF", "SCRIPT"]

UNIT_MM = 1 / MM  # URScript poses are in metres: mm per unit
SCRIPT = "<script>"  # the routine of a script's top-level statements
# strings, comments, and a quote that opens no string on its line
_HIDE = re.compile(r'"[^"\n]*"|\'[^\'\n]*\'|#.*|["\']')
# motion functions → (motion kind, keyword name) of each target they move to, from their first argument on
MOTION_OF = {"movel": (("LIN", "pose"),), "movej": (("PTP", "q"),), "movep": (("LIN", "pose"),),
             "movec": (("CIRC-aux", "pose_via"), ("CIRC-end", "pose_to")), "servoc": (("LIN", "pose"),),
             "servoj": (("PTP", "q"),)}
# builtins that move the robot without a target: where it stands after them is not known
_MOVE_AWAY = frozenset({"speedj", "speedl", "stopj", "stopl", "freedrive_mode", "end_freedrive_mode", "teach_mode",
                        "end_teach_mode", "servo_stop", "set_pos"})
# builtins that move the path of the targets after them (until switched off): global → (on, off)
_PATH_MOVERS = {"track_conveyor_linear": ("$CONVEYOR", True), "track_conveyor_circular": ("$CONVEYOR", True),
                "stop_conveyor_tracking": ("$CONVEYOR", False), "path_offset_enable": ("$PATH_OFFSET", True),
                "path_offset_disable": ("$PATH_OFFSET", False), "force_mode": ("$FORCE", True),
                "end_force_mode": ("$FORCE", False)}
_PATH_WHY = {"$CONVEYOR": "conveyor tracking is on ({}() at line {}): the targets move with the conveyor",
             "$PATH_OFFSET": "a path offset is on ({}() at line {}): the controller shifts the path at run time",
             "$FORCE": "force mode is on ({}() at line {}): the robot yields to forces, not where it is commanded"}
_OPS = {"and": "and", "or": "or", "xor": "xor", "%": "mod", "!=": "!="}
_FRAMES = (Name("$CONVEYOR"), Name("$PATH_OFFSET"), Name("$FORCE"))
_XYZ = ("X", "Y", "Z")
_RV = ("RX", "RY", "RZ")


def parser():
    """The LALR parser of ``grammars/urscript.lark`` (built once, cached on disk by lark)."""
    return lalr_parser("urscript.lark", "unit")


class _Line:
    """One logical line: where it stands, its shape's tree and its tokens (names and numbers)."""

    __slots__ = ("start", "end", "tree", "ordinal_at", "tokens")

    def __init__(self, start, end, tree, ordinal_at, tokens):
        self.start, self.end, self.tree, self.ordinal_at, self.tokens = start, end, tree, ordinal_at, tokens


class _Block:
    """An open block: ``kind`` "def" / "thread" / "if" / "while", its IR node and where its head
    stands; ``current``: the If whose branch is being filled (elif)."""

    __slots__ = ("kind", "node", "at", "current", "outer")

    def __init__(self, kind, node, at, outer):
        self.kind, self.node, self.at, self.current, self.outer = kind, node, at, node, outer


class Lowering:
    """A URScript file → ``Unit`` (``lower()``), with what the dialect needs to know of it:
    ``programs`` (routines whose variables are global), ``threads``."""

    def __init__(self, path: str, text: str):
        self.path, self.text = path, text
        self.index = LineIndex(text)
        self.shapes: dict = {}
        self.exact: dict = {}
        self.code = ""
        self.defs: dict[str, list] = {}  # name → [(key, enclosing def key, parameters)]
        self.params: dict[str, tuple] = {}  # routine key → parameter names
        self.threads: set = set()
        self.programs: set = set()
        self.runs = 0
        self.called: set = set()  # the routines some statement calls (or runs)
        self.unit = Unit("urscript", [path], [text], form="rotvec", unit=UNIT_MM)

    # ------------------------------------------------------------------ lines and shapes
    def units(self):
        """Yield (start, end) of each logical line; fill ``self.code``."""
        text = self.text
        bad = []

        def hide(m):
            s = m.group()
            if s in ('"', "'"):
                bad.append(m.start())
                return s
            if s.startswith("#"):
                return " " * len(s)
            return s[0] + " " * (len(s) - 2) + s[0]

        code = self.code = _HIDE.sub(hide, text)
        if bad:
            raise self.error(bad[0], "string not closed on its line")
        start, depth, offset, n = -1, 0, 0, len(code)
        while offset < n:
            nl = code.find("\n", offset)
            end = n if nl < 0 else nl
            line = code[offset:end]
            if start < 0 and line.strip():
                start = offset + len(line) - len(line.lstrip())
            if start >= 0:
                depth += line.count("(") + line.count("[") - line.count(")") - line.count("]")
                if depth <= 0:
                    if depth < 0:
                        raise self.error(start, "closing bracket without its opening one")
                    yield start, end
                    start, depth = -1, 0
            offset = end + 1
        if start >= 0:
            raise self.error(start, "bracket not closed at the end of the script")

    def error(self, at: int, message: str, code: str = P101) -> PostprocError:
        return PostprocError(message, self.path, *self.index.line_col(at), code)

    def loc(self, at: int) -> Loc:
        return Loc(0, *self.index.line_col(at))

    def shape_of(self, start, end):
        unit = self.code[start:end]
        exact = exact_key(unit)
        got = self.exact.get(exact)
        if got is not None:
            return got
        key = shape_key(exact)
        got = self.shapes.get(key)
        if got is None:
            try:
                tree = parser().parse(key)
            except UnexpectedInput:
                self.syntax_error(start, unit)
            ordinal_at = {m.start(): k for k, m in enumerate(TOKEN_RE.finditer(key))}
            got = self.shapes[key] = (tree, ordinal_at)
        if len(self.exact) < 100_000:
            self.exact[exact] = got
        return got

    def syntax_error(self, start, unit):
        """Parse the line as written to locate the error; raise P101 there."""
        located = unexpected(parser().parse, unit)
        if located is not None:
            pos, found = located
            raise self.error(start + pos, f"syntax error: unexpected {found}")
        raise self.error(start, "syntax error")

    # ------------------------------------------------------------------ the two passes
    def lower(self) -> Unit:
        lines = []
        stack: list = []  # (kind, key) of the open defs and threads, for the first pass
        for start, end in self.units():
            tree, ordinal_at = self.shape_of(start, end)
            line = _Line(start, end, tree, ordinal_at, list(TOKEN_RE.finditer(self.code, start, end)))
            kind = tree.data
            lines.append(line)
            if kind in ("def_head", "thread_head"):
                name = self.tok(line, tree.children[1]).group()
                outer = next((k for kk, k in reversed(stack) if kk in ("def", "thread")), None)
                key = name if name not in self.defs else f"{name}@{self.index.line_col(start)[0]}"
                params = tuple(self.tok(line, p.children[0]).group() for p in tree.children[2:]
                               if isinstance(p, Tree) and p.data == "param")
                self.defs.setdefault(name, []).append((key, outer))
                self.params[key] = params
                stack.append(("def" if kind == "def_head" else "thread", key))
            elif kind == "block_head":
                stack.append(("block", None))
            elif kind == "block_end" and stack:
                stack.pop()
        self.pass_two(lines)
        return self.unit

    def pass_two(self, lines) -> None:
        unit = self.unit
        top: list = []
        self.body = top
        self.blocks: list[_Block] = []
        self.chain: list = []  # keys of the enclosing defs/threads, innermost last
        self.hot: dict | None = None  # the rows of the run of hot lines being read (``MoveRun``)
        plans = self.plans = {}
        for line in lines:
            self.line = line
            tree = line.tree
            plan = plans.get(id(tree), False)
            if plan is False:
                plan = plans[id(tree)] = _plan(tree, line.ordinal_at)
            if plan is not None and line.tokens[0].group() == plan[0] and plan[0] not in self.defs:
                self.hot_row(line, plan)
                continue
            if self.hot is not None:
                self.flush()
            handler = getattr(self, "s_" + tree.data, None)
            if handler is None:
                continue
            handler(tree)
        if self.hot is not None:
            self.flush()
        if self.blocks:
            b = self.blocks[-1]
            what = {"def": "def", "thread": "thread"}.get(b.kind, "block")
            raise self.error(b.at, f"{what} not closed by 'end'", P101)
        if top:
            script = Routine(SCRIPT, (), top, Loc(0, 1, 1), function=False)
            unit.routines[SCRIPT] = script
            unit.entries = [SCRIPT]
            self.programs.add(SCRIPT)
        else:
            called = self.called
            tops = [k for k, outer in ((k, o) for entries in self.defs.values() for k, o in entries)
                    if outer is None and k not in self.threads]
            entries = [k for k in tops if k not in called] or tops
            unit.entries = entries
            self.programs |= set(entries)

    # ------------------------------------------------------------------ hot lines
    def hot_row(self, line, plan) -> None:
        """A motion to a literal pose (``movel(p[…], a=…, v=…)``): a row of the run being read."""
        hot = self.hot
        if hot is None:
            hot = self.hot = {"at": [], "pose": [], "spans": [], "motions": []}
        tokens, code = line.tokens, self.code
        values, spans = [], []
        for k, (ordinal, signed) in enumerate(plan[3]):
            m = tokens[ordinal]
            value = float(m.group())
            start = m.start()
            if signed:
                start -= 1
                while code[start] in " \t\r\n":
                    start -= 1
                if code[start] == "-":
                    value = -value
            values.append(value * UNIT_MM if k < 3 else value)
            spans += (start, m.end())
        hot["at"].append(tokens[plan[2]].start())
        hot["pose"].append(values)
        hot["spans"].append(spans)
        hot["motions"].append(plan[1])

    def flush(self) -> None:
        """The run of hot lines read so far as one ``MoveRun`` where they stand."""
        import numpy as np

        from ..ir import MOTION_INDEX, MoveRun

        hot, self.hot = self.hot, None
        n = len(hot["at"])
        pose = np.array(hot["pose"], float).reshape(n, 6)
        at = np.array(hot["at"], np.int64)
        bad = ~np.isfinite(pose).all(axis=1)
        if bad.any():
            raise self.error(int(at[np.flatnonzero(bad)[0]]), "a pose's position or rotation is not a finite number",
                             P103)
        line, col = self.index.lines_cols(at)
        rows = dict(pose=pose, written=np.ones((n, 6), bool), spans=np.array(hot["spans"], np.int64).reshape(n, 12),
                    file=np.zeros(n, np.int32), line=line, col=col,
                    motion=np.array([MOTION_INDEX[m] for m in hot["motions"]], np.int8), chain=np.ones(n, bool),
                    config=np.full((n, 2), -1, np.int16))
        self.body.append(MoveRun(rows, Call("UR.FRAME", _FRAMES), Name("$TCP")))

    # ------------------------------------------------------------------ helpers
    def tok(self, line, token: Token):
        """The line's match of a NAME / NUMBER token of its shape."""
        return line.tokens[line.ordinal_at[token.start_pos]]

    def at(self, node) -> int:
        """The file offset where a shape's node starts (its first name or number)."""
        line = self.line
        first = _first_token(node)
        if first is None:
            return line.start
        ordinal = line.ordinal_at.get(first.start_pos)
        if ordinal is None:  # (a string, an operator: the nearest token before it)
            before = [p for p in line.ordinal_at if p <= first.start_pos]
            return line.tokens[line.ordinal_at[max(before)]].start() if before else line.start
        return line.tokens[ordinal].start()

    def emit(self, stmt) -> None:
        self.body.append(stmt)

    def resolve(self, name: str) -> str | None:
        """The routine key a call of ``name`` reaches from here (the innermost visible def)."""
        found = self.defs.get(name)
        if not found:
            return None
        if len(found) == 1:
            return found[0][0]
        for outer in reversed(self.chain):
            for key, o in found:
                if o == outer:
                    return key
        for key, o in found:
            if o is None:
                return key
        return found[-1][0]

    # ------------------------------------------------------------------ blocks
    def s_def_head(self, node):
        self.open_routine(node, "def")

    def s_thread_head(self, node):
        self.open_routine(node, "thread")

    def open_routine(self, node, kind):
        line = self.line
        name = self.tok(line, node.children[1]).group()
        key = self.resolve_new(name)
        params = []
        for p in node.children[2:]:
            if isinstance(p, Tree) and p.data == "param":
                default = self.expr(p.children[1]) if len(p.children) > 1 and p.children[1] is not None else None
                params.append(Param(self.tok(line, p.children[0]).group(), "in", default))
        routine = Routine(key, tuple(params), [], self.loc(line.start), function=kind == "def")
        self.unit.routines[key] = routine
        if kind == "thread":
            self.threads.add(key)
        self.blocks.append(_Block(kind, routine, line.start, self.body))
        self.chain.append(key)
        self.body = routine.body

    def resolve_new(self, name: str) -> str:
        """The key the first pass gave the def of ``name`` that opens here."""
        line_no = self.index.line_col(self.line.start)[0]
        for key, _ in self.defs.get(name, []):
            if key == name or key == f"{name}@{line_no}":
                if key not in self.unit.routines:
                    return key
        return name

    def s_block_head(self, node):
        word = str(node.children[0])
        cond = self.expr(node.children[1])
        at = self.line.start
        if word == "if":
            stmt = If(cond, [], [], self.loc(at))
            self.emit(stmt)
            self.blocks.append(_Block("if", stmt, at, self.body))
            self.body = stmt.then
        else:
            stmt = Loop("while", [], self.loc(at), cond=cond)
            self.emit(stmt)
            self.blocks.append(_Block("while", stmt, at, self.body))
            self.body = stmt.body

    def s_block_again(self, node):
        if not self.blocks or self.blocks[-1].kind != "if":
            raise self.error(self.line.start, "elif/else without its if")
        b = self.blocks[-1]
        if b.current is None:
            raise self.error(self.line.start, "elif/else after else")
        if str(node.children[0]) == "elif":
            nested = If(self.expr(node.children[1]), [], [], self.loc(self.line.start))
            b.current.orelse.append(nested)
            b.current = nested
            self.body = nested.then
        else:
            self.body = b.current.orelse
            b.current = None

    def s_block_end(self, node):
        if not self.blocks:
            raise self.error(self.line.start, "end without a def, thread, if or while to close")
        b = self.blocks.pop()
        self.body = b.outer
        if b.kind in ("def", "thread"):
            self.chain.pop()

    # ------------------------------------------------------------------ statements
    def s_assign(self, node):
        kids = [c for c in node.children if c is not None]
        scope = str(kids[0]) if isinstance(kids[0], Token) else ""
        target_node, value_node = kids[-2], kids[-1]
        at = self.line.start
        loc = self.loc(at)
        target = self.target(target_node)
        if isinstance(value_node, Tree) and value_node.data == "run_thread":
            value = self.run_thread(value_node)
        else:
            value = self.expr(value_node)
        if scope and isinstance(target, Name):
            self.emit(Decl(target.name, "", None, value, "global" if scope == "global" else "local", loc,
                           target.name))
            return
        self.emit(Assign(target, value, loc))

    def target(self, node):
        line = self.line
        kids = node.children
        out = Name(self.tok(line, kids[0]).group())
        for c in kids[1:]:
            if isinstance(c, Token):
                name = self.tok(line, c).group()
                out = Field(out, name, name)
            else:
                out = Item(out, (self.expr(c),))
        return out

    def run_thread(self, node) -> Lit:
        """``run t()``: the thread switched on here; its handle (a number the analysis follows to
        ``kill``/``join``)."""
        name = self.tok(self.line, node.children[1]).group()
        key = self.resolve(name) or name
        self.called.add(key)
        self.runs += 1
        loc = self.loc(self.at(node))
        self.emit(Async(Lit(self.runs), Invoke(key, (), loc), loc, True, "thread"))
        return Lit(self.runs)

    def s_run_(self, node):
        self.run_thread(node.children[0])

    def s_kill(self, node):
        name = self.tok(self.line, node.children[1]).group()
        self.emit(AsyncSwitch(Name(name), False, self.loc(self.line.start)))

    s_join = s_kill

    def s_return_(self, node):
        value = node.children[1] if len(node.children) > 1 else None
        self.emit(Return(self.expr(value) if value is not None else None, self.loc(self.line.start)))

    def s_break_(self, node):
        self.emit(Exit(self.loc(self.line.start)))

    def s_continue_(self, node):
        self.emit(Continue(self.loc(self.line.start)))

    def s_halt(self, node):
        self.emit(Halt(self.loc(self.line.start)))

    def s_method_stmt(self, node):
        args, keywords = self.arguments(node.children[2:])
        name = self.tok(self.line, node.children[1]).group()
        self.emit(Eval(Call("UR.VALUE." + name, tuple(args) + tuple(keywords.values()),
                            self.loc(self.line.start)), self.loc(self.line.start)))

    def s_call_stmt(self, node):
        line = self.line
        name = self.tok(line, node.children[0]).group()
        loc = self.loc(line.start)
        key = self.resolve(name)
        if key is not None:  # (a function of the script, even where it has a builtin's name)
            self.called.add(key)
            self.emit(Invoke(key, self.bind(key, node.children[1:]), loc))
            return
        if name in MOTION_OF:
            self.motion(name, node.children[1:])
            return
        args, keywords = self.arguments(node.children[1:])
        if name == "set_tcp":
            if args:
                self.emit(Assign(Name("$TCP"), args[0], loc))
            return
        if name in ("set_payload", "set_target_payload"):  # (the payload in force: mass kg, cog m → mm)
            cog = args[1] if len(args) > 1 else keywords.get("cog")
            mass = args[0] if args else keywords.get("m")
            self.emit(Assign(Name("$LOAD"), Call("UR.PAYLOAD", (mass, cog), loc), loc))
            return
        if name == "set_payload_mass":
            self.emit(Assign(Name("$LOAD"), Call("UR.PAYLOAD", (args[0] if args else None, None), loc), loc))
            return
        if name in _PATH_MOVERS:
            which, on = _PATH_MOVERS[name]
            self.emit(Eval(Call("UR.VALUE." + name, tuple(args) + tuple(keywords.values()), loc), loc))
            value = Unknown(_PATH_WHY[which].format(name, loc.line), None) if on else Call("UR.FRAME", ())
            self.emit(Assign(Name(which), value, loc))
            return
        if name in _MOVE_AWAY:
            self.emit(Eval(Call("UR.VALUE." + name, tuple(args) + tuple(keywords.values()), loc), loc))
            self.emit(Havoc((), f"{name}() at line {loc.line} moves the robot", loc))
            return
        if is_builtin(name) or name in JOINT_VALUES or name == "get_inverse_kin":
            self.emit(Eval(Call("UR.VALUE." + name, tuple(args) + tuple(keywords.values()), loc), loc))
            return
        self.emit(Invoke(name, tuple(args) + tuple(keywords.values()), loc))  # (code not read)

    def arguments(self, nodes) -> tuple[list, dict]:
        """Positional argument expressions and keyword ones (name → expression)."""
        args, keywords = [], {}
        for a in nodes:
            if a is None:
                continue
            if a.data == "keyword":
                keywords[self.tok(self.line, a.children[0]).group()] = self.expr(a.children[1])
            else:
                args.append(self.expr(a.children[0]))
        return args, keywords

    def bind(self, key: str, nodes) -> tuple:
        """A call's arguments in the order of the routine's parameters (None: left out)."""
        args, keywords = self.arguments(nodes)
        params = self.params.get(key, ())
        out = list(args) + [None] * max(0, len(params) - len(args))
        for name, value in keywords.items():
            if name in params:
                out[params.index(name)] = value
            else:
                raise self.error(self.line.start, f"{key}() has no parameter {name}")
        return tuple(out)

    def motion(self, name: str, nodes) -> None:
        line = self.line
        positional, keywords = [], {}
        for a in nodes:
            if a is None:
                continue
            if a.data == "keyword":
                keywords[self.tok(line, a.children[0]).group()] = a.children[1]
            else:
                positional.append(a.children[0])
        for k, (kind, keyword) in enumerate(MOTION_OF[name]):
            node = positional[k] if k < len(positional) else keywords.get(keyword)
            if node is None:
                continue
            self.move(kind, node)
        for k, a in enumerate(positional[len(MOTION_OF[name]):]):  # (speeds, blend: read)
            self.emit(Eval(self.expr(a), self.loc(line.start)))

    def move(self, kind: str, node) -> None:
        """One target of a motion: ``get_inverse_kin(x, …)`` moves to the pose x (its ``tcp``
        the tool, its ``qnear`` the configuration), ``pose_trans(F, P)`` to P in the frame F."""
        at = self.at(node)
        loc = self.loc(at)
        tool = Name("$TCP")
        config = None
        lefts = []
        while isinstance(node, Tree) and node.data == "fcall":
            fname = self.tok(self.line, node.children[0]).group()
            if self.resolve(fname) is not None:
                break
            args = [a for a in node.children[1:] if a is not None]
            positional = [a.children[0] for a in args if a.data == "arg"]
            keywords = {self.tok(self.line, a.children[0]).group(): a.children[1] for a in args if a.data == "keyword"}
            if fname == "get_inverse_kin" and positional:
                tcp = positional[4] if len(positional) > 4 else keywords.get("tcp")
                if tcp is not None:
                    tool = self.expr(tcp)
                if len(positional) > 1 or "qnear" in keywords:
                    config = Lit("qnear")
                    for x in positional[1:2] + [v for k, v in keywords.items() if k == "qnear"]:
                        self.emit(Eval(self.expr(x), loc))
                node = positional[0]
            elif fname == "pose_trans" and len(positional) == 2 and not keywords:
                lefts.append(self.expr(positional[0]))
                node = positional[1]
            else:
                break
        if isinstance(node, Tree) and node.data == "list":
            self.emit(Move(kind, self.expr(node), loc, joint=True, chain=kind != "CIRC-aux"))
            return
        target = self.expr(node)
        self.emit(Move(kind, target, loc, Call("UR.FRAME", _FRAMES + tuple(lefts), loc), tool,
                       chain=kind != "CIRC-aux", config=config))

    # ------------------------------------------------------------------ expressions
    def expr(self, node):
        line = self.line
        d = node.data
        if d == "number":
            return Lit(float(self.tok(line, node.children[0]).group()))
        if d == "string":
            return Lit("")
        if d == "name":
            name = self.tok(line, node.children[0]).group()
            if name in ("True", "False"):
                return Lit(name == "True")
            return Name(name)
        if d == "pose":
            return self.pose(node)
        if d == "list":
            items = tuple((str(k), self.expr(c)) for k, c in enumerate(x for x in node.children if x is not None))
            return Agg("record", items, self.loc(self.at(node)), "LIST", "rotvec")
        if d == "signed":
            sign, inner = node.children
            e = self.expr(inner)
            if str(sign) == "-":
                return Lit(-e.value) if isinstance(e, Lit) and isinstance(e.value, float) else Op("neg", (e,))
            return e
        if d == "not_":
            return Op("not", (self.expr(node.children[1]),))
        if d == "binop":
            a, op, b = node.children
            op = str(op)
            return Op(_OPS.get(op, op), (self.expr(a), self.expr(b)))
        if d == "index":
            return Item(self.expr(node.children[0]), (self.expr(node.children[1]),))
        if d == "member":
            name = self.tok(line, node.children[1]).group()
            return Field(self.expr(node.children[0]), name, name)
        if d == "fcall":
            return self.call(node)
        if d == "method":
            args, keywords = self.arguments(node.children[2:])
            name = self.tok(line, node.children[1]).group()
            return Call("UR.VALUE." + name, (self.expr(node.children[0]),) + tuple(args) + tuple(keywords.values()),
                        self.loc(self.at(node)))
        return Unknown("an expression the reader does not evaluate")

    def call(self, node):
        line = self.line
        name = self.tok(line, node.children[0]).group()
        loc = self.loc(self.at(node))
        key = self.resolve(name)
        if key is not None:
            self.called.add(key)
            return Call(key, self.bind(key, node.children[1:]), loc)
        args, keywords = self.arguments(node.children[1:])
        rest = tuple(args) + tuple(keywords.values())
        if name == "get_inverse_kin":
            return Call("UR.IK", rest, loc)
        if name in ("pose_trans", "pose_add", "pose_inv"):
            return Call("UR." + name, tuple(args), loc)
        if is_builtin(name) or name in JOINT_VALUES or name in MATH:
            return Call("UR.VALUE." + name, rest, loc)
        return Call(name, rest, loc)  # (code not read)

    def pose(self, node) -> Agg:
        """``p[x, y, z, rx, ry, rz]``: x, y, z as mm (× 1000), the rotation vector as written; a
        number's token (its sign included) kept for the rewrite."""
        line = self.line
        at = self.tok(line, node.children[0]).start()  # (the 'p' of 'p[')
        parts = [c for c in node.children[1:] if c is not None]
        if len(parts) != 6:
            raise self.error(at, f"a pose p[…] has {len(parts)} components, not x, y, z, rx, ry, rz", P117)
        items = []
        for k, c in enumerate(parts):
            scale = UNIT_MM if k < 3 else 1.0
            num = self.number(c)
            if num is not None:
                value, start, end = num
                scaled = value * scale
                if not (abs(value) < float("inf") and abs(scaled) < float("inf")):
                    raise self.error(at, "a pose's position or rotation is not a finite number", P103)
                items.append(((_XYZ + _RV)[k], Num(scaled, 0, start, end)))
            else:
                e = self.expr(c)
                items.append(((_XYZ + _RV)[k], Op("*", (e, Lit(scale))) if k < 3 else e))
        return Agg("pose", tuple(items), self.loc(at), "POSE", "rotvec")

    def number(self, node):
        """(value, span start, span end) of a plain number, its sign included; None otherwise."""
        line = self.line
        if node.data == "number":
            m = self.tok(line, node.children[0])
            return float(m.group()), m.start(), m.end()
        if node.data == "signed" and isinstance(node.children[1], Tree) and node.children[1].data == "number":
            m = self.tok(line, node.children[1].children[0])
            s = m.start() - 1
            while self.code[s] in " \t\r\n":
                s -= 1
            sign = self.code[s]
            value = float(m.group())
            return (-value if sign == "-" else value), s, m.end()
        return None


# motions whose one target a literal pose makes a hot line
_HOT = {"movel": "LIN", "movej": "PTP", "movep": "LIN", "servoc": "LIN"}


def _plain(node) -> tuple | None:
    """(the number token, signed) of a plain number node, None otherwise."""
    if isinstance(node, Tree) and node.data == "number":
        return node.children[0], False
    if isinstance(node, Tree) and node.data == "signed" and isinstance(node.children[1], Tree) and \
            node.children[1].data == "number":
        return node.children[1].children[0], True
    return None


def _plan(tree, ordinal_at) -> tuple | None:
    """A hot line's shape: a motion to a pose of six plain numbers, its other arguments plain
    numbers (``movel(p[…], a=1.2, v=0.25, r=0)``) → (function name, motion kind, ordinal of the
    'p', [(ordinal, signed)] × 6); None for any other shape."""
    if tree.data != "call_stmt":
        return None
    name = tree.children[0]
    args = [a for a in tree.children[1:] if a is not None]
    if str(name) not in _HOT or not args or args[0].data != "arg":
        return None
    pose = args[0].children[0]
    if not (isinstance(pose, Tree) and pose.data == "pose"):
        return None
    parts = [c for c in pose.children[1:] if c is not None]
    plain = [_plain(c) for c in parts]
    if len(parts) != 6 or None in plain:
        return None
    for a in args[1:]:
        if _plain(a.children[-1]) is None:
            return None
    return (str(name), _HOT[str(name)], ordinal_at[pose.children[0].start_pos],
            [(ordinal_at[t.start_pos], signed) for t, signed in plain])


def _first_token(node):
    if isinstance(node, Token):
        return node
    for c in node.children:
        if c is None:
            continue
        t = _first_token(c)
        if t is not None:
            return t
    return None


_ = P102

"""Universal Robots URScript reader: the text of a script (.script) → Program.

Syntax lives in ``grammars/urscript.lark``. The script is cut into logical lines (a line,
joined with the next while a bracket is open), with ``#`` comments and the insides of
strings blanked out (same length: offsets stay those of the file). Each distinct line
*shape* — numbers → ``0``, the digits ending a name → ``0``, blanks collapsed — is parsed
once; what its tree tells holds for every line of that shape, so only the line's tokens
are read again.

Semantics (tests/test_urscript.py shows each on a small script):

* a target is a pose ``p[x, y, z, rx, ry, rz]`` of plain numbers (metres, rotation vector in
  radians) moved to by ``movel``/``movej``/``movep`` (the pose) or ``movec`` (via and end
  pose): inline, or a pose variable (``global wp1 = p[…]``, ``local``, plain ``wp1 = p[…]``)
  assigned once in the script and read by motions only. Poses are held in mm and KUKA
  A,B,C degrees (``Program.unit`` = 1000: the numbers are written back in metres, in the
  token's style, with µm resolution); X, Y, Z are rewritten, and with ``compensate
  --orientation`` rx, ry, rz too (``Program.orientation`` = "rotvec": located, as written, in
  ``Targets.abc_spans`` / ``Targets.orientation``);
* the robot base is the frame of every pose; ``set_tcp(p[…])`` is the tool. Its value is
  known for a target on the straight line of the program (top level, or directly in the
  outermost ``def``) from the ``set_tcp`` before it; inside a block, a thread or another
  ``def`` only when every ``set_tcp`` of the script sets one and the same pose, before that
  block. Otherwise the target is left as written (P203); before the first ``set_tcp`` (or with
  none) the robot uses the installation's TCP, which the script does not say: left as written
  (one P221) unless the user states it (``--tool X,Y,Z,A,B,C`` or ``--tool model``);
* ``pose_trans(…)``, ``pose_add(…)``, ``get_…()`` and other targets computed at run time,
  pose variables assigned more than once or from an expression, poses of expressions
  (``d2r(90)``), a parameter of the enclosing ``def`` are left as written (P211); a pose variable that other statements read too
  (``pose_trans(wp1, …)``, ``set_tcp(wp1)``, ``x = wp1``) is left as written (P217); a pose
  variable assigned nowhere in the script (P215);
* joint-space moves (``movej([q1, …, q6])``, or a variable holding a list) are not targets.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
from lark import Lark, Token, Tree
from lark.exceptions import UnexpectedInput

from ..diagnostics import Diagnostic, LineIndex, PostprocError, line_col
from ..frames import abc_from_rotation, rotation_from_rotvec
from .grammar import TOKEN_RE, exact_key, first_ordinal, lalr_parser, shape_key, unexpected
from . import MOTIONS, STAMP_PREFIX, Frame, Program, Targets
from .poses import _newline

__all__ = ["read", "parser", "UNIT_MM", "TOKEN_RE", "MOTION_OF"]

UNIT_MM = 1000.0  # URScript poses are in metres
# strings, comments, and a quote that opens no string on its line
_HIDE = re.compile(r'"[^"\n]*"|\'[^\'\n]*\'|#.*|["\']')
_MOTION = {m: i for i, m in enumerate(MOTIONS)}
# motion functions → the motion kind of each pose they move to, from their first argument on
MOTION_OF = {"movel": ("LIN",), "movej": ("PTP",), "movep": ("LIN",), "movec": ("CIRC-aux", "CIRC-end")}

# functions that give joint angles: a move to their result is a joint-space move, not a target
_JOINT_FUNCS = {"get_inverse_kin", "get_actual_joint_positions", "get_target_joint_positions",
                "get_joint_positions"}

def parser() -> Lark:
    """The LALR parser of ``grammars/urscript.lark`` (built once, cached on disk by lark)."""
    return lalr_parser("urscript.lark", "unit")


# ---------------------------------------------------------------------------- shapes
#
# A value as a shape's tree gives it: ("pose", [("num", ordinal, signed) | ("expr", ordinal)],
# ordinal of 'p') | ("ref", name ordinal) | ("call", function name, ordinal) | ("list", ordinal)
# | ("expr", ordinal)


class _Shape:
    __slots__ = ("kind", "data", "names")

    def __init__(self, kind, data=None, names=()):
        self.kind = kind
        self.data = data
        self.names = names  # ordinals of the names the line reads (besides motion targets, set_tcp's pose)


def _analyse(tree, ordinal_at) -> _Shape:
    def first(node):
        return first_ordinal(node, ordinal_at)

    def value(node):
        if isinstance(node, Tree):
            if node.data == "pose":
                elements = []
                for c in node.children[1:]:
                    if c is None:
                        continue
                    if isinstance(c, Tree) and c.data == "number":
                        elements.append(("num", ordinal_at[c.children[0].start_pos], False))
                    elif isinstance(c, Tree) and c.data == "signed" and isinstance(c.children[1], Tree) and \
                            c.children[1].data == "number":
                        elements.append(("num", ordinal_at[c.children[1].children[0].start_pos], True))
                    else:
                        elements.append(("expr", first(c)))
                return ("pose", elements, ordinal_at[node.children[0].start_pos])
            if node.data == "name":
                return ("ref", ordinal_at[node.children[0].start_pos])
            if node.data == "fcall":
                return ("call", str(node.children[0]), first(node))
            if node.data == "list":
                return ("list", first(node))
        return ("expr", first(node))

    def names(node, skip=()):
        out = []
        for sub in node.iter_subtrees() if isinstance(node, Tree) else ():
            if sub.data == "name" and id(sub) not in skip:
                out.append(ordinal_at[sub.children[0].start_pos])
        return out

    kind = tree.data
    if kind in ("def_head", "thread_head"):
        params = [ordinal_at[t.start_pos] for t in tree.children[2:] if isinstance(t, Token) and t.type == "NAME"]
        return _Shape(kind, tuple(params), ())
    if kind in ("block_head", "block_again"):
        return _Shape(kind, None, tuple(names(tree)))
    if kind == "block_end":
        return _Shape(kind)
    if kind == "assign":
        kids = [c for c in tree.children if c is not None]
        target, expr = kids[-2], kids[-1]
        scope = str(kids[0]) if isinstance(kids[0], Token) else ""
        name_ord = ordinal_at[target.children[0].start_pos]
        indexed = len(target.children) > 1
        used = names(target) + names(expr)
        return _Shape("assign", (scope, name_ord, indexed, value(expr) if not indexed else ("expr", first(expr))),
                      tuple(used))
    if kind == "call_stmt":
        fname = str(tree.children[0])
        args = [c for c in tree.children[1:] if c is not None]
        positional = [value(a.children[0]) for a in args if a.data == "arg"]
        kinds = MOTION_OF.get(fname)
        skip = set()
        if kinds is not None or fname == "set_tcp":
            count = len(kinds) if kinds is not None else 1
            for a in [a for a in args if a.data == "arg"][:count]:
                node = a.children[0]
                if isinstance(node, Tree) and node.data == "name":
                    skip.add(id(node))
        used = []
        for a in args:
            used += names(a, skip)
        return _Shape("call", (fname, positional, first(tree)), tuple(used))
    return _Shape("other", None, tuple(names(tree)))


# ---------------------------------------------------------------------------- reading


@dataclass
class _Assign:
    scope: str
    value: tuple
    tokens: list
    at: int  # offset of the assigned name
    line_start: int


class _Reader:
    def __init__(self, path: str, text: str, active=None):
        self.path, self.text = path, text
        self.active = active  # ActiveFrames: the TCP stated for targets before the first set_tcp
        self.diagnostics: list[Diagnostic] = []
        self._lines = LineIndex(text)
        self.shapes: dict[str, _Shape] = {}
        self.exact: dict[str, _Shape] = {}
        self.code = ""

    def warn(self, at: int, code: str, message: str) -> None:
        self.diagnostics.append(Diagnostic(self.path, *self.line_col(at), code, message))

    def line_col(self, at: int) -> tuple[int, int]:
        """1-based (line, column) of an offset (``diagnostics.LineIndex``: many warnings stay cheap)."""
        return self._lines.line_col(at)

    def units(self):
        """Yield (start, end) of each logical line; fill ``self.code``."""
        text, path = self.text, self.path
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
            raise PostprocError("string not closed on its line", path, *line_col(text, bad[0]), "P101")
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
                        raise PostprocError("closing bracket without its opening one", path,
                                            *line_col(text, start), "P101")
                    yield start, end
                    start, depth = -1, 0
            offset = end + 1
        if start >= 0:
            raise PostprocError("bracket not closed at the end of the script", path, *line_col(text, start), "P101")

    def shape_of(self, start, end):
        unit = self.code[start:end]
        exact = exact_key(unit)
        shape = self.exact.get(exact)
        if shape is not None:
            return shape
        key = shape_key(exact)
        shape = self.shapes.get(key)
        if shape is None:
            try:
                tree = parser().parse(key)
            except UnexpectedInput:
                self.syntax_error(start, unit)
            ordinal_at = {m.start(): k for k, m in enumerate(TOKEN_RE.finditer(key))}
            shape = self.shapes[key] = _analyse(tree, ordinal_at)
        if len(self.exact) < 100_000:
            self.exact[exact] = shape
        return shape

    def syntax_error(self, start, unit):
        """Parse the line as written to locate the error; raise P101 there."""
        located = unexpected(parser().parse, unit)
        if located is not None:
            pos, found = located
            raise PostprocError(f"syntax error: unexpected {found}", self.path, *self.line_col(start + pos), "P101")
        raise PostprocError("syntax error", self.path, *self.line_col(start), "P101")

    # -------------------------------------------------------------- the pass over the script

    def read(self) -> Program:
        stack: list[tuple[str, int]] = []  # open blocks: (kind, offset of their head)
        assigns: dict[str, list[_Assign]] = {}
        read_by: dict[str, int] = {}  # pose variable name → offset of a statement that reads it (not a motion)
        motions = []  # (offset, kind, value, tokens, straight, block start, tcp events so far)
        tcp = []  # set_tcp events: (offset, straight, tool X,Y,Z,A,B,C or None = not known)
        params: list[set[str]] = []  # the parameter names of the open defs
        code = None
        for start, end in self.units():
            code = self.code
            shape = self.shape_of(start, end)
            kind = shape.kind
            tokens = None
            if shape.names or kind in ("assign", "call", "def_head"):
                tokens = list(TOKEN_RE.finditer(code, start, end))  # match objects: m[0] text, m.start()
                for k in shape.names:
                    read_by.setdefault(tokens[k][0], tokens[k].start())
            if kind in ("def_head", "thread_head", "block_head"):
                stack.append((kind, start))
                if kind == "def_head":  # its parameters: what a motion to one of them moves to is known at run time
                    params.append({tokens[k][0] for k in shape.data})
                continue
            if kind == "block_again":
                if not stack or stack[-1][0] != "block_head":
                    raise PostprocError("elif/else without its if", self.path, *self.line_col(start), "P101")
                continue
            if kind == "block_end":
                if not stack:
                    raise PostprocError("end without a def, thread, if or while to close", self.path,
                                        *self.line_col(start), "P101")
                if stack.pop()[0] == "def_head":
                    params.pop()
                continue
            straight = not stack or (len(stack) == 1 and stack[0][0] == "def_head")
            block = (stack[1][1] if stack and stack[0][0] == "def_head" and len(stack) > 1 else
                     stack[0][1] if stack else start)
            if kind == "assign":
                scope, name_ord, indexed, value = shape.data
                name, at = tokens[name_ord][0], tokens[name_ord].start()
                assigns.setdefault(name, []).append(_Assign(scope, value, tokens, at, start))
            elif kind == "call":
                fname, positional, _ = shape.data
                kinds = MOTION_OF.get(fname)
                if kinds is not None:
                    for value, motion in zip(positional, kinds):
                        if value[0] == "ref" and any(tokens[value[1]][0] in p for p in params):
                            value = ("param", value[1])
                        motions.append((start, motion, value, tokens, straight, block, len(tcp)))
                elif fname == "set_tcp":
                    tool = self.tool(positional[0], tokens, assigns) if positional else None
                    tcp.append((start, straight, tool))
        if stack:
            kind, at = stack[-1]
            raise PostprocError(f"{'def' if kind == 'def_head' else 'thread' if kind == 'thread_head' else 'block'} "
                                "not closed by 'end'", self.path, *self.line_col(at), "P101")
        return self.build(motions, assigns, read_by, tcp)

    def pose_numbers(self, value, tokens):
        """(six floats, spans of the six numbers incl. their signs) of a pose of plain numbers, else None."""
        numbers, spans = [], []
        for k, element in enumerate(value[1]):
            if element[0] != "num":
                return None
            token, at = tokens[element[1]][0], tokens[element[1]].start()
            s = at
            if element[2]:  # a signed number: the span takes its sign (and the blanks after it)
                s = at - 1
                while self.code[s] in " \t\r\n":
                    s -= 1
                token = self.code[s] + token
            numbers.append(float(token))
            spans.append((s, tokens[element[1]].end()))
        return numbers, spans

    def tool(self, value, tokens, assigns):
        """set_tcp's pose as X,Y,Z,A,B,C (mm, deg), or None where it is not a pose of numbers."""
        if value[0] == "ref":
            seen = assigns.get(tokens[value[1]][0], [])
            if len(seen) != 1:
                return None
            value, tokens = seen[0].value, seen[0].tokens
        if value[0] != "pose" or len(value[1]) != 6:
            return None
        got = self.pose_numbers(value, tokens)
        if got is None or not np.isfinite(got[0]).all():
            return None
        v = np.array(got[0])
        abc = abc_from_rotation(rotation_from_rotvec(v[3:]))
        return tuple(float(x) for x in np.concatenate([v[:3] * UNIT_MM, abc]))

    def tool_at(self, offset, straight, block, events):
        """(tool, why not known) of a motion at ``offset`` after the first ``events`` set_tcp;
        (``_NOT_SET``, None) before any set_tcp: the installation's TCP, which the script does not
        say (the user may state it: ``ActiveFrames.tool``, X,Y,Z,A,B,C or "model")."""
        tcp, crooked, uniform = self.tcp, self.crooked, self.uniform
        if not tcp:
            return self.stated_tool()
        if straight and not crooked:
            if events == 0:
                return self.stated_tool()
            last = tcp[events - 1]
            if last[2] is None:
                return False, f"the TCP set at line {self.line_col(last[0])[0]} is not a pose of numbers"
            return last[2], None
        if uniform and tcp[0][0] < (block if not straight else offset):
            return tcp[0][2], None
        why = next((f"the TCP set at line {self.line_col(e[0])[0]} is not a pose of numbers"
                    for e in tcp if e[2] is None), None)
        return False, why or (f"set_tcp is called in a block, a thread or a function (line "
                              f"{self.line_col((crooked or tcp)[0][0])[0]}) or with another pose before "
                              "this target")

    def stated_tool(self):
        """The TCP in force before the script's first set_tcp: the one its user stated
        (``--tool X,Y,Z,A,B,C`` or ``model``), else not known (``_NOT_SET``: P221)."""
        tool = None if self.active is None else self.active.tool
        if tool is None:
            return _NOT_SET, None
        if tool == "model":
            return None, None
        if not isinstance(tool, tuple):  # TOOL_DATA[n] is KUKA's: a script has no such table
            raise PostprocError(f"--tool {tool}: a URScript TCP is stated as X,Y,Z,A,B,C (mm, deg) or 'model'",
                                self.path, 0, 0, "P222")
        return tuple(float(v) for v in tool), None

    def build(self, motions, assigns, read_by, tcp) -> Program:
        self.tcp = tcp
        self.crooked = [e for e in tcp if not e[1]]  # set_tcp off the straight line
        # every set_tcp sets one pose of numbers, the first on the straight line
        self.uniform = bool(tcp) and all(e[2] is not None and e[2] == tcp[0][2] for e in tcp) and tcp[0][1]
        frames: list[Frame] = []
        frame_keys: dict = {}
        rows = []  # (offset of p, numbers, spans, frame, motion)
        done: dict[str, tuple] = {}  # pose variable → (frame, offset) of its first use
        skipped: set[str] = set()  # pose variables left as written (warned once)
        not_set: list[int] = []  # targets before any set_tcp, no TCP stated: left as written (one P221)
        for offset, kind, value, tokens, straight, block, events in motions:
            where = tokens[value[-1]].start() if value[-1] >= 0 else offset
            if value[0] == "list":
                continue  # joint space
            if value[0] == "call" and value[1] in _JOINT_FUNCS:
                continue  # joint space
            if value[0] == "call":
                self.warn(where, "P211", f"target {value[1]}(…) is computed at run time: left as written")
                continue
            if value[0] == "param":
                self.warn(where, "P211", f"target {tokens[value[1]][0]} is a parameter of the function: its value is "
                          "known at run time only; left as written")
                continue
            if value[0] == "expr":
                self.warn(where, "P211", "target is an expression, not known statically: left as written")
                continue
            label = "pose"
            if value[0] == "ref":
                name = tokens[value[1]][0]
                if name in skipped:
                    continue
                seen = assigns.get(name)
                if not seen:
                    self.warn(where, "P215", f"pose variable {name} is not assigned in this script: left as written")
                    continue
                if len(seen) > 1:
                    self.warn(where, "P211", f"{name} is assigned {len(seen)} times (lines "
                              f"{', '.join(str(self.line_col(a.at)[0]) for a in seen[:3])}): its value here is "
                              "known at run time only; left as written")
                    continue
                a = seen[0]
                if a.value[0] == "list":
                    continue  # joint space
                if a.value[0] != "pose":
                    self.warn(where, "P211", f"{name} is computed at run time (line {self.line_col(a.at)[0]}): "
                              "left as written")
                    continue
                if name in read_by:
                    self.warn(a.at, "P217", f"pose variable {name} is also read by the statement at line "
                              f"{self.line_col(read_by[name])[0]}: compensating it would change that too; "
                              "left as written")
                    skipped.add(name)
                    continue
                value, tokens, label = a.value, a.tokens, f"pose variable {name}"
            if len(value[1]) != 6:
                raise PostprocError(f"a {label} p[…] has {len(value[1])} components, not x, y, z, rx, ry, rz",
                                    self.path, *self.line_col(tokens[value[2]].start()), "P117")
            got = self.pose_numbers(value, tokens)
            if got is None:
                self.warn(tokens[value[2]].start(), "P211", f"a {label} with a component computed at run time: left as "
                          "written")
                continue
            tool, why = self.tool_at(offset, straight, block, events)
            if tool is _NOT_SET:
                not_set.append(where)
                frame = -1
            elif tool is False:
                frame = -1
            else:
                key = tool
                if key not in frame_keys:
                    frames.append(Frame(np.eye(4), tool, "base / " + ("set_tcp" if tool is not None else "the installation's TCP")))
                    frame_keys[key] = len(frames) - 1
                frame = frame_keys[key]
            if label != "pose":
                name = label.split()[-1]
                first = done.get(name)
                if first is not None:
                    if first[0] != frame:
                        self.warn(where, "P202", f"{name} is moved to here with another tool than at line "
                                  f"{self.line_col(first[1])[0]}: compensated for the first")
                    continue
                done[name] = (frame, offset)
            if frame < 0 and tool is not _NOT_SET:
                self.warn(where, "P203", f"tool not statically known ({why}): target left as written")
            rows.append((tokens[value[2]].start(), got[0], got[1], frame, _MOTION[kind]))
        if not_set:
            more = f" (and {len(not_set) - 1} more targets before a set_tcp)" if len(not_set) > 1 else ""
            self.warn(not_set[0], "P221", "the TCP is not set by the script before this target (the robot uses the "
                      "installation's TCP, which the script does not say): left as written" + more + "; set it with "
                      "set_tcp(p[…]) or state it with --tool X,Y,Z,A,B,C (mm, deg) or --tool model")
        rows.sort(key=lambda r: r[0])
        n = len(rows)
        if n:
            at, numbers, spans, frame, motion = zip(*rows)
            numbers = np.array(numbers, float).reshape(n, 6)
        else:
            at, numbers, spans, frame, motion = (), np.zeros((0, 6)), (), (), ()
        line, col = self._lines.lines_cols(np.array(at, np.int64))
        bad = ~np.isfinite(numbers).all(axis=1)
        with np.errstate(over="ignore", invalid="ignore"):
            bad |= ~np.isfinite(numbers[:, :3] * UNIT_MM).all(axis=1)
        if bad.any():
            r = int(np.flatnonzero(bad)[0])
            raise PostprocError("a pose's position or rotation is not a finite number", self.path, int(line[r]),
                                int(col[r]), "P103")
        abc = abc_from_rotation(rotation_from_rotvec(numbers[:, 3:])) if n else np.zeros((0, 3))
        spans = np.array(spans, np.int64).reshape(n, 6, 2)
        targets = Targets(poses=np.concatenate([numbers[:, :3] * UNIT_MM, abc], axis=1),
                          spans=spans[:, :3], file=np.zeros(n, np.int32),
                          line=line, col=col, frame=np.array(frame, np.int32),
                          motion=np.array(motion, np.int8), abc_spans=spans[:, 3:], orientation=numbers[:, 3:].copy())
        stamps = {}
        m = re.search(r"^[ \t]*#.*" + re.escape(STAMP_PREFIX) + r".*$", self.text, re.M)
        if m:
            stamps[0] = m.group().strip()
        return Program(files=[self.path], texts=[self.text], targets=targets, frames=frames,
                       diagnostics=self.diagnostics, dialect="urscript", stamps=stamps,
                       newlines=[_newline(self.text)], comment="#", named_targets=bool(done), unit=UNIT_MM,
                       orientation="rotvec")


_NOT_SET = object()  # the TCP before the first set_tcp, not stated by the user


def read(files: list[str], texts: list[str], active=None) -> Program:
    """Read a URScript program (one file). ``active`` (``ActiveFrames``): the TCP its user states
    for targets before the script's first set_tcp (only ``tool``: the base is the robot's;
    without it those targets are left as written, P221). Raises PostprocError (P101, P117,
    P103, P222 with path:line:col) on bad input."""
    if len(files) != 1:
        raise PostprocError("a URScript program is one .script file", files[0] if files else "<none>", 0, 0, "P108")
    if active is not None and active.base is not None:
        raise PostprocError("--base: a URScript pose is in the robot's base frame (no base to state)", files[0], 0, 0,
                            "P222")
    return _Reader(files[0], texts[0], active).read()

"""Fanuc LS → the motion IR (``programs.ir``). What an instruction *means* is said in
``semantics.py`` and the analysis; here is only how LS writes it.

Sections ``/PROG``, ``/ATTR``, ``/APPL``, ``/MN``, ``/POS``, ``/END``. Each ``/POS`` record
``P[n]{ … };`` is read with ``grammars/ls.lark`` (each distinct record shape — numbers → 0,
strings emptied — parsed once); its numbers are the program's rewritable tokens (``Num``). The
``/MN`` lines (``  12:  instruction ;``, an instruction continued on lines without a number until
its ``;``; a controller export's sub-lines of a motion, ``  1:  TC_ONLINE (…) ;`` … ``------ ;``)
are cut into tokens and read by a small recursive-descent parser, one instruction at a time:
motions with their options, assignments of registers and frames, labels and jumps, IF / SELECT /
FOR, CALL / RUN, END / ABORT / PAUSE / WAIT. An instruction it does not know is taken as code
not read (what it changes is not known), except the process instructions that change no
position, register or frame (``HARMLESS``).
"""
from __future__ import annotations

import re

from lark import Token
from lark.exceptions import UnexpectedInput

from ...core.diagnostics import P101, P103, P118, P201, P203, P210, P211, P215, P225, LineIndex, PostprocError
from ..grammar import lalr_parser, unexpected
from ..ir import (
    Agg, Assign, Async, Call, Decl, Eval, Field, Goto, Halt, Havoc, If, Invoke, Label, Lit, Loc, Loop, Move, Name,
    Note, Num, Op, Return, Routine, Switch, Unit, Unknown,
)
from .semantics import COMPONENTS

__all__ = ["Lowering", "parser", "TOKEN_RE", "HARMLESS"]

_NUM = r"(?<![\w.])(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?![\w.])"
# the tokens a record's shape keeps the order of: strings and numbers
TOKEN_RE = re.compile(r"'[^'\n]*'|\"[^\"\n]*\"|" + _NUM, re.ASCII)
_SECTION = re.compile(r"^/(PROG|ATTR|APPL|MN|POS|END)\b[^\n]*", re.M)
_MN_LINE = re.compile(r"[ \t]*(\d*)[ \t]*:(.*)")
_END_OF_SUBLINES = re.compile(r"[ \t]*-+[ \t]*;?[ \t]*\r?$")
_RECORD = re.compile(r"P\[[^\]\n]*\]\s*\{.*?\}\s*;", re.S)
_NUM_RE = re.compile(_NUM, re.ASCII)
_STRINGS = re.compile(r"'[^'\n]*'|\"[^\"\n]*\"")
_BLANKS = re.compile(r"\s+")
# a comment inside brackets: P[1:"home"], LBL[10:retry], R[2:count] (not a group: PR[GP1:1])
_BRACKET_COMMENT = re.compile(r"(?<=\[)(\s*\d+\s*)(:[^\]\n]*)(?=\])")
_TOKEN = re.compile(r"""(?P<s>'[^']*'|"[^"]*")|(?P<n>\d+\.?\d*(?:[eE][-+]?\d+)?|\.\d+)"""
                    r"""|(?P<w>\$?[A-Za-z_][\w$]*(?:\.[A-Za-z_$][\w$]*)*)|(?P<o><>|<=|>=|[-+*/=<>()\[\],:%@!;])"""
                    r"""|(?P<x>\S)""")
_KIND = {"J": "PTP", "L": "LIN", "C": "CIRC-aux", "A": "CIRC-end"}
# instructions (by their first word) that change no position, register or frame the analysis follows
HARMLESS = frozenset({
    "ARC", "WEAVE", "SPOT", "WELD", "SEAL", "DISPENSE", "PRESSURE", "PAYLOAD", "OVERRIDE", "UALM", "MESSAGE", "TIMER",
    "COL", "LOCK", "UNLOCK", "SKIP", "TC_ONLINE", "RSR", "DIAG_REC", "JOINT_MAX_SPEED", "LINEAR_MAX_SPEED",
    "MONITOR", "HAND", "GRIPPER", "TRACK_SENSOR", "TORCH", "WIRE", "GAS", "PROCESS", "SERVO", "SENSOR", "BACKUP",
    "COUNTER", "REMARK", "SPEED", "ACC", "DB", "TB", "TA", "PTH", "CONT", "CNT", "STICK", "MAX_SPEED", "UOP",
    "PRESET", "PULSE", "TOOL", "SV_SWITCH", "BG_LOGIC", "EE", "LASER", "PAINT", "GUN",
})
# registers and I/O an instruction may assign without the analysis following: their first word
_IO = frozenset({"DO", "DI", "RO", "RI", "GO", "GI", "AO", "AI", "SO", "SI", "UO", "UI", "WO", "WI", "WSTKO", "F", "M",
                 "SR", "AR", "TIMER", "VR", "OVERRIDE", "TIMER_OVERFLOW", "ER", "CR"})
_TERMINATION = re.compile(r"^(FINE|CNT\d*|CD\d*|CR\d*)$", re.I)
# a motion without options to a P[n] (most lines of a long program): read without the parser
_SIMPLE_MOTION = re.compile(r"([JL])\s*P\[\s*(\d+)\s*(?::[^\]\n]*)?\]\s+\d+(?:\.\d*)?\s*(?:%|mm/sec|cm/min|inch/min|"
                            r"deg/sec|sec|msec)\s+(?:FINE|CNT\s*\d+)")
_NO_OPTIONS = {"offset": None, "tool_offset": None, "inc": False, "vision": None, "coord": False, "rtcp": False,
               "skip": None, "after": ()}


def parser():
    """The LALR parser of ``grammars/ls.lark`` (built once, cached on disk by lark)."""
    return lalr_parser("ls.lark", "record")


class _Tokens:
    """An instruction's tokens: (kind, text, offset in the instruction) and a cursor."""

    __slots__ = ("items", "k")

    def __init__(self, text: str):
        self.items = [(m.lastgroup, m.group(), m.start()) for m in _TOKEN.finditer(text)]
        self.k = 0

    def peek(self, ahead: int = 0):
        k = self.k + ahead
        return self.items[k] if k < len(self.items) else (None, "", -1)

    def word(self, ahead: int = 0) -> str:
        kind, text, _ = self.peek(ahead)
        return text.upper() if kind == "w" else ""

    def take(self):
        t = self.peek()
        self.k += 1
        return t

    def accept(self, text: str) -> bool:
        kind, got, _ = self.peek()
        if got.upper() == text.upper() and kind is not None:
            self.k += 1
            return True
        return False

    def expect(self, text: str):
        if not self.accept(text):
            raise _Unknown(f"'{text}' expected")

    def done(self) -> bool:
        return self.k >= len(self.items)


class _Unknown(Exception):
    """An instruction (or part) the parser does not know."""


class Lowering:
    """An LS program → ``Unit`` (``lower()``); ``registers``: the R[…]/PR[…] names it uses."""

    def __init__(self, path: str, text: str, file: int = 0, programs=frozenset()):
        self.path, self.text = path, text
        self.index = LineIndex(text)
        self.file = file  # its index among the files read (Loc.file, Num.file)
        self.programs = frozenset(programs)  # the programs read with it (a CALL to one is followed)
        # "R", "PR", "UFRAME", "UTOOL" → the line where the program sets one with an index known at run time
        self.indirect: dict = {}
        self.shapes: dict = {}
        self.registers: set = set()
        self.assigned: set = set()  # the registers and frames the program sets (other programs may read them)
        self.labels: list = []
        self.unit = Unit("fanuc", [path], [text])

    def error(self, at: int, message: str, code: str = P101) -> PostprocError:
        return PostprocError(message, self.path, *self.index.line_col(at), code)

    def loc(self, at: int) -> Loc:
        return Loc(self.file, *self.index.line_col(at))

    # ------------------------------------------------------------------ sections
    def sections(self) -> dict[str, tuple[int, int]]:
        text = self.text
        found = list(_SECTION.finditer(text))
        lead = len(text) - len(text.lstrip())
        if not found or found[0].start() != lead or found[0].group(1) != "PROG":
            raise self.error(lead, "an LS program starts with /PROG <name>")
        out: dict[str, tuple[int, int]] = {}
        for k, m in enumerate(found):
            name = m.group(1)
            if name in out:
                raise self.error(m.start(), f"/{name} twice")
            end = found[k + 1].start() if k + 1 < len(found) else len(text)
            out[name] = (m.end(), end)
        if "MN" not in out:
            raise self.error(len(text), "no /MN section")
        if "END" not in out:
            raise self.error(len(text), "no /END at the end of the program")
        rest = text[out["END"][0]:]
        if rest.strip():
            raise self.error(out["END"][0] + len(rest) - len(rest.lstrip()), "text after /END")
        order = [m.group(1) for m in found]
        if "POS" in out and order.index("POS") < order.index("MN"):
            raise self.error(found[order.index("POS")].start(), "/POS before /MN")
        self.name = text[found[0].end() - len(found[0].group()) + 5:found[0].end()].split()
        self.name = self.name[0].upper() if self.name else "MAIN"
        return out

    # ------------------------------------------------------------------ /POS
    def positions(self, start: int, end: int) -> dict:
        """The /POS records: n → (offset of 'P[', GP1 analysis | None, tokens, problem, others)."""
        text = self.text
        out: dict[int, tuple] = {}
        at = start
        for m in _RECORD.finditer(text, start, end):
            gap = text[at:m.start()]
            if gap.strip():
                raise self.error(at + len(gap) - len(gap.lstrip()), "/POS holds only records P[n]{ … };")
            at = m.end()
            record = m.group()
            key = _BLANKS.sub(" ", _NUM_RE.sub("0", _STRINGS.sub(_empty, record)))
            if key not in self.shapes:
                try:
                    tree = parser().parse(key)
                except UnexpectedInput:
                    self.syntax_error(m.start(), record)
                ordinal_at = {t.start(): k for k, t in enumerate(TOKEN_RE.finditer(key))}
                gp1, others = _analyse(tree, ordinal_at)
                self.shapes[key] = (gp1, ordinal_at[key.index("[") + 1], _problem(gp1), others)
            gp1, n_ord, problem, others = self.shapes[key]
            tokens = list(TOKEN_RE.finditer(text, m.start(), m.end()))
            n = int(float(tokens[n_ord][0]))
            if n in out:
                raise self.error(m.start(), f"P[{n}] twice in /POS")
            out[n] = (m.start(), gp1, tokens, problem, others)
        gap = text[at:end]
        if gap.strip():
            raise self.error(at + len(gap) - len(gap.lstrip()), "/POS holds only records P[n]{ … }; (one not closed?)")
        return out

    def syntax_error(self, start, record):
        located = unexpected(parser().parse, record, "end of record")
        if located is not None:
            pos, found = located
            raise self.error(start + pos, f"syntax error: unexpected {found}")
        raise self.error(start, "syntax error")

    def number(self, tokens, ordinal, signed):
        """(value, span start, span end) of a number token, its sign included."""
        t = tokens[ordinal]
        s = t.start()
        token = t.group()
        if signed:
            s -= 1
            while self.text[s] in " \t\r\n":
                s -= 1
            token = self.text[s] + token
        return float(token), s, t.end()

    def declaration(self, n: int, record) -> Decl:
        """``P[n]`` as the value its record gives: a Cartesian position (X, Y, Z tokens, W, P, R
        as C, B, A; UF, UT, CONFIG), a joint one, or one without group 1."""
        start, gp1, tokens, problem, others = record
        loc = self.loc(start)
        name = f"P[{n}]"
        if gp1 is None:
            return Decl(name, "POS", None, Agg("record", (), loc, "NOGP1"), "local", loc, name)
        rform = [a for a in gp1 if len(a) == 2 and a[0] == "R" and a[1] in "XYZWPR"]
        if rform:
            ordinal = gp1[rform[0]][0]
            raise self.error(tokens[ordinal].start() if isinstance(ordinal, int) else start, (
                f"{name} is written in the RX, RY, RZ, RW, RP, RR form, which postproc does not read: no FANUC "
                "document it could check says in which frame and angles these numbers are, so they cannot be "
                "compensated safely; save the positions in the Cartesian X, Y, Z, W, P, R form (or J1…J6) and "
                "give the program again"), P118)
        if "X" not in gp1:
            return Decl(name, "JOINTS", None, Agg("record", (), loc, "JOINTS"), "local", loc, name)
        if problem is not None:
            axis, message = problem
            at = tokens[gp1[axis][0]].start() if axis and isinstance(gp1[axis][0], int) else start
            raise self.error(at, f"P[{n}] {message}", P118)
        items = []
        for axis, field in zip("XYZWPR", ("X", "Y", "Z", "C", "B", "A")):
            ordinal, signed = gp1[axis]
            if ordinal == "*":
                items.append((field, Unknown(f"P[{n}] is not taught (its numbers are ********)", P211)))
                continue
            value, s, e = self.number(tokens, ordinal, signed)
            if not abs(value) < float("inf"):
                raise self.error(start, "a position's component is not a finite number", P103)
            items.append((field, Num(value, self.file, s, e)))
        for which in ("uf", "ut"):
            v = gp1.get(which)
            items.append((which.upper(), Lit(float(tokens[v][0])) if isinstance(v, int) else Lit(v or "F")))
        if "config" in gp1:
            items.append(("CONFIG", Lit(tokens[gp1["config"]][0][1:-1])))
        # the extended axes' and the other groups' values (a track's position: postproc.robot.external)
        for axis in list(gp1.get("ext", ())) + list(gp1.get("axes", {})):
            ordinal, signed = gp1[axis] if axis in gp1 else gp1["axes"][axis]
            if ordinal == "*":
                items.append((axis, Unknown(f"P[{n}]'s {axis} is not taught (********)", P211)))
            else:
                value, s, e = self.number(tokens, ordinal, signed)
                items.append((axis, Num(value, self.file, s, e)))
        if others or gp1.get("ext"):
            what = ", ".join(([f"extended axes {', '.join(gp1['ext'])}"] if gp1.get("ext") else []) +
                             ([f"group{'s' if len(others) > 1 else ''} {', '.join(others)}"] if others else []))
            items.append(("EXT", Lit(f"P[{n}] moves {what} too (a track, a positioner…): without their kinematics "
                                     "its place in the robot base is not known")))
        return Decl(name, "POS", None, Agg("pose", tuple(items), loc, "POS"), "local", loc, name)

    # ------------------------------------------------------------------ the program
    def lower(self, records_only: bool = False) -> Unit:
        sections = self.sections()
        records = self.positions(*sections["POS"]) if "POS" in sections else {}
        self.records = records
        body: list = [self.declaration(n, r) for n, r in sorted(records.items())]
        appl = self.text[slice(*sections["APPL"])] if "APPL" in sections else ""
        if re.search(r"^\s*LINE_TRACK\b", appl, re.M):  # (the program's targets move with a conveyor)
            at = sections["APPL"][0]
            body.append(Assign(Name("$MOVING"), Unknown("line tracking (/APPL LINE_TRACK): the targets move with the "
                                                        "conveyor", P201), self.loc(at)))
        self.body = body
        self.blocks: list = []  # open IF … ENDIF / FOR … ENDFOR: (kind, node, outer body, offset)
        self.select = None  # the SELECT being read (a Switch)
        for text, at in self.instructions(*sections["MN"]):
            self.instruction(text, at)
        if self.blocks:
            kind, _, _, at = self.blocks[-1]
            raise self.error(at, f"{kind} without its END{kind}")
        end = self.loc(sections["MN"][1])
        body.append(_Publish(end, "the program's end"))
        body[:] = _finished(body, self.labels, sorted(self.assigned))
        routine = Routine(self.name, (), body, Loc(self.file, 1, 1), function=False)
        self.unit.routines[self.name] = routine
        self.unit.entries = [self.name]
        return self.unit

    def instructions(self, start: int, end: int):
        """Yield (instruction text, its offset) of each /MN instruction: a numbered line (and the
        lines without a number that continue it to its ';'), comments in brackets blanked."""
        text = self.text
        offset = text.find("\n", start) + 1 if text.find("\n", start) >= 0 else end
        pending, pending_at = None, 0
        while offset < end:
            nl = text.find("\n", offset)
            line_end = end if nl < 0 or nl > end else nl
            line = text[offset:line_end]
            if line.strip() and not _END_OF_SUBLINES.match(line):
                m = _MN_LINE.match(line)
                if m is None:
                    raise self.error(offset + len(line) - len(line.lstrip()), "a /MN line is '<number>: <instruction> ;'")
                body, at = m.group(2), offset + m.start(2)
                if pending is not None and m.group(1) == "":
                    pending += " " + body
                else:
                    if pending is not None:
                        yield pending, pending_at
                    pending, pending_at = body, at
                if pending.rstrip().endswith(";"):
                    yield pending, pending_at
                    pending = None
            offset = line_end + 1
        if pending is not None:
            yield pending, pending_at

    def emit(self, stmt) -> None:
        self.body.append(stmt)

    # ------------------------------------------------------------------ one instruction
    def instruction(self, text: str, at: int) -> None:
        stripped = text.strip()
        if stripped.endswith(";"):
            stripped = stripped[:-1].rstrip()
        if not stripped or stripped.startswith(("!", "//", "--eg")):
            return
        simple = _SIMPLE_MOTION.fullmatch(stripped)
        if simple is not None and self.select is None:  # (the common line: J/L P[n] speed FINE|CNTn, no option)
            self.at = at
            loc = self.loc(at + len(text) - len(text.lstrip()))
            self.here = loc
            self.move(_KIND[simple.group(1)], Name(f"P[{int(simple.group(2))}]"), _NO_OPTIONS, loc)
            return
        self.at = at
        loc = self.loc(at + len(text) - len(text.lstrip()))
        self.here = loc
        t = _Tokens(_BRACKET_COMMENT.sub(lambda m: m.group(1) + " " * len(m.group(2)), stripped))
        if self.select is not None and not (t.peek()[1] in ("=",) or (t.word() == "ELSE" and t.peek(1)[1] == ",")):
            self.select = None
        try:
            self.statement(t, loc)
        except _Unknown:
            self.unknown(stripped, loc)

    def statement(self, t: _Tokens, loc: Loc) -> None:
        w = t.word()
        kind, first, _ = t.peek()
        if kind == "o" and first == "=" and self.select is not None:  # SELECT's next case: =2,JMP LBL[2]
            t.take()
            value = self.expr(t)
            t.expect(",")
            case: list = []
            self.action(t, case, loc)
            self.select.cases.append(((value,), case))
            return
        if w == "ELSE" and self.select is not None and t.peek(1)[1] == ",":
            t.take()
            t.take()
            self.select.default = []
            self.action(t, self.select.default, loc)
            self.select = None
            return
        if w in _KIND and (t.peek(1)[1] in ("@",) or t.word(1) in ("P", "PR") or
                           (t.peek(1)[0] == "w" and t.peek(2)[1] == "[")):
            self.motion(t, loc)
            return
        if w == "LBL":
            t.take()
            n = self.label_number(t)
            self.labels.append(n)
            self.emit(Label(n, loc))
            return
        if w == "JMP":
            t.take()
            self.jump(t, self.body, loc)
            return
        if w == "IF":
            self.if_(t, loc)
            return
        if w == "ELSE" and t.peek(1)[0] is None:  # (of IF … THEN)
            self.else_(loc)
            return
        if w == "ENDIF":
            self.close("IF", loc)
            return
        if w == "SELECT":
            t.take()
            subject = self.ref(t)
            t.expect("=")
            value = self.expr(t)
            t.expect(",")
            case: list = []
            stmt = Switch(subject, [], None, loc)
            self.emit(stmt)
            self.action(t, case, loc)
            stmt.cases.append(((value,), case))
            self.select = stmt
            return
        if w == "FOR":
            t.take()
            var = self.ref(t)
            if not isinstance(var, Name):
                raise _Unknown("FOR over an indirect register")
            t.expect("=")
            start = self.expr(t)
            step = Lit(1.0)
            if t.accept("TO"):
                pass
            elif t.accept("DOWNTO"):
                step = Lit(-1.0)
            else:
                raise _Unknown("FOR without TO")
            stop = self.expr(t)
            stmt = Loop("for", [], loc, var=var.name, start=start, stop=stop, step=step)
            self.emit(stmt)
            self.blocks.append(("FOR", stmt, self.body, self.at))
            self.body = stmt.body
            return
        if w == "ENDFOR":
            self.close("FOR", loc)
            return
        if w in ("END",) and t.peek(1)[0] is None:
            self.emit(_Publish(loc, "the program's END"))
            self.emit(Return(None, loc))
            return
        if w == "ABORT":
            self.emit(_Publish(loc, "ABORT"))
            self.emit(Halt(loc))
            return
        if w in ("PAUSE", "REMARK", "NOP"):
            return
        if w in ("CALL", "RUN"):
            self.action(t, self.body, loc)
            return
        if w == "WAIT":
            self.wait(t, loc)
            return
        if w in ("OFFSET", "TOOL_OFFSET") and t.word(1) == "CONDITION":
            t.take()
            t.take()
            reg = self.ref(t)
            which = "$OFFSET_PR" if w == "OFFSET" else "$TOOL_OFFSET_PR"
            if t.accept(","):  # (in another user / tool frame than the position's)
                self.emit(Assign(Name(which), Unknown(f"{w} CONDITION at line {loc.line} names its own frame"), loc))
                return
            number = re.fullmatch(r"PR\[(\d+)\]", reg.name) if isinstance(reg, Name) else None
            self.emit(Assign(Name(which), Lit(float(number.group(1))) if number else Unknown("an indirect register"),
                             loc))
            return
        if w == "PAYLOAD" and t.peek(1)[1] == "[":  # (the payload schedule in force from here: $LOAD)
            t.take()
            t.expect("[")
            number = self.expr(t)
            t.expect("]")
            self.emit(Assign(Name("$LOAD"), Call("LS.PAYLOAD", (number,), loc), loc))
            return
        if w in HARMLESS:
            return
        if w in ("UFRAME_NUM", "UTOOL_NUM") or (kind == "w" and t.peek(1)[1] in ("[", "=")):
            self.assignment(t, self.body, loc)
            return
        raise _Unknown(first)

    def unknown(self, text: str, loc: Loc) -> None:
        """An instruction the reader does not know: code not read (what it changes is not known,
        where the robot stands after it neither); a label it names may be jumped to, a program it
        calls is called."""
        words = text.upper()
        self.emit(_Publish(loc, f"the instruction at line {loc.line}"))
        for m in re.finditer(r"\bCALL\s+([A-Za-z_]\w*)", text):
            self.emit(Invoke(m.group(1).upper(), (), loc))
        self.emit(Havoc(None, f"the instruction at line {loc.line} ({text.strip()[:40]}) is not read", loc))
        for m in re.finditer(r"\bLBL\s*\[\s*(\d+)", words):
            self.emit(Goto(m.group(1), loc, Unknown("the instruction's jump is known at run time")))

    # ------------------------------------------------------------------ blocks
    def if_(self, t: _Tokens, loc: Loc) -> None:
        t.take()
        cond = self.expr(t)
        if t.accept("THEN"):
            stmt = If(cond, [], [], loc)
            self.emit(stmt)
            self.blocks.append(("IF", stmt, self.body, self.at))
            self.body = stmt.then
            return
        t.expect(",")
        if t.word() == "JMP":
            t.take()
            branch: list = []
            self.jump(t, branch, loc)
            if len(branch) == 1 and isinstance(branch[0], Goto) and branch[0].cond is None:
                self.emit(Goto(branch[0].name, loc, cond))
                return
            self.emit(If(cond, branch, [], loc))
            return
        branch = []
        self.action(t, branch, loc)
        self.emit(If(cond, branch, [], loc))

    def else_(self, loc: Loc) -> None:
        if not self.blocks or self.blocks[-1][0] != "IF":
            raise self.error(self.at, "ELSE without IF … THEN")
        kind, node, outer, at = self.blocks[-1]
        self.body = node.orelse

    def close(self, kind: str, loc: Loc) -> None:
        if not self.blocks or self.blocks[-1][0] != kind:
            raise self.error(self.at, f"END{kind} without {kind}")
        _, _, outer, _ = self.blocks.pop()
        self.body = outer

    def action(self, t: _Tokens, body: list, loc: Loc) -> None:
        """What an IF or a SELECT case does: JMP LBL[n], CALL prog(args), RUN prog, an assignment."""
        w = t.word()
        if w == "JMP":
            t.take()
            self.jump(t, body, loc)
        elif w == "CALL":
            t.take()
            name = t.take()[1].upper()
            args = []
            if t.accept("("):
                while not t.accept(")"):
                    if t.done():
                        raise _Unknown("CALL's arguments not closed")
                    args.append(self.expr(t))
                    t.accept(",")
            if name not in self.programs:  # (one read with it: the analysis follows what it reads)
                body.append(_Publish(loc, f"CALL {name}"))
            body.append(Invoke(name, tuple(args), loc))
        elif w == "RUN":
            t.take()
            name = t.take()[1].upper()
            body.append(_Publish(loc, f"RUN {name}"))
            body.append(Async(None, Invoke(name, (), loc), loc, True, "program started with RUN"))
        else:
            self.assignment(t, body, loc)

    def label_number(self, t: _Tokens) -> str:
        t.expect("[")
        kind, text, _ = t.take()
        if kind != "n":
            raise _Unknown("a label's number")
        t.expect("]")
        return str(int(float(text)))

    def jump(self, t: _Tokens, body: list, loc: Loc) -> None:
        if t.word() != "LBL":
            raise _Unknown("JMP without LBL")
        t.take()
        if t.peek(1)[0] == "n":
            body.append(Goto(self.label_number(t), loc))
            return
        t.expect("[")
        index = self.expr(t)
        t.expect("]")
        # (a computed jump: to any label of the program; none matching stops it with an alarm)
        body.append(_ComputedJump(index, loc))

    def wait(self, t: _Tokens, loc: Loc) -> None:
        t.take()
        words = [x[1].upper() for x in t.items[t.k:]]
        if "TIMEOUT" in words:
            k = words.index("TIMEOUT")
            rest = t.items[t.k + k + 1:]
            numbers = [x[1] for x in rest if x[0] == "n"]
            if any(x[1].upper() == "LBL" for x in rest) and numbers:
                self.emit(Goto(str(int(float(numbers[0]))), loc, Unknown("a WAIT's timeout")))

    # ------------------------------------------------------------------ assignments
    def assignment(self, t: _Tokens, body: list, loc: Loc) -> None:
        kind, first, _ = t.peek()
        w = first.upper()
        if w in ("UFRAME_NUM", "UTOOL_NUM"):
            t.take()
            t.expect("=")
            body.append(Assign(Name(w), self.expr(t), loc))
            return
        if kind != "w":
            raise _Unknown(first)
        if w.startswith("$"):
            t.take()
            while not t.done() and t.peek()[1] != "=":
                t.take()
            t.expect("=")
            value = self.expr(t)
            body.append(Eval(value, loc))
            if "FRAME" in w or "TOOL" in w or "GROUP" in w:  # ($MNUFRAMENUM[1], $MNUFRAME[1,2] …)
                body.append(Havoc(None, f"{first} is set at line {loc.line}", loc))
                for kind in ("UFRAME", "UTOOL"):  # (any user frame / tool: a backup's sysframe.va is not what runs)
                    if kind[1:] in w and "NUM" not in w:
                        self.indirect.setdefault(kind, loc.line)
            return
        if w in _IO and t.peek(1)[1] == "[":
            t.take()
            self.skip_brackets(t)
            t.expect("=")
            body.append(Eval(self.expr(t), loc))
            return
        if w not in ("R", "PR", "UFRAME", "UTOOL"):
            raise _Unknown(first)
        target = self.ref(t)
        t.expect("=")
        value = self.expr(t)
        root = target.base if isinstance(target, Field) else target
        if isinstance(root, Name):
            self.assigned.add(root.name)
        if isinstance(target, Havoc):
            self.indirect.setdefault(w, loc.line)
            body.append(Eval(value, loc))
            body.append(Havoc(tuple(sorted(n for n in self.registers if n.startswith(w + "["))),
                              f"{w}[…] is set with an index known at run time at line {loc.line}", loc))
            return
        if w == "PR" and isinstance(target, Name):  # (a whole register: a position without frame numbers)
            if isinstance(value, Op) and value.op == "-" and value.args[0] == value.args[1]:
                # PR[n]=PR[m]-PR[m]: zero, whatever PR[m] held (the way a register is cleared)
                value = Agg("pose", tuple((k, Lit(0.0)) for k in ("X", "Y", "Z", "A", "B", "C")), loc, "POS")
            value = Call("LS.AS_PR", (value,))
        body.append(Assign(target, value, loc))

    def skip_brackets(self, t: _Tokens) -> None:
        t.expect("[")
        depth = 1
        while depth and not t.done():
            x = t.take()[1]
            depth += (x == "[") - (x == "]")

    # ------------------------------------------------------------------ references and expressions
    def ref(self, t: _Tokens, target: bool = True):
        """``R[n]``, ``PR[n]``, ``PR[n,k]``, ``PR[GPk:n]``, ``P[n]``, ``UFRAME[n]``, ``UTOOL[n]`` and
        their indirect forms (``R[R[1]]``): a Name / Field, a builtin call (read) or, as an
        assignment's target, a Havoc marker (indirect)."""
        kind, first, _ = t.take()
        w = first.upper()
        t.expect("[")
        group = ""
        if t.word().startswith("GP") and t.peek(1)[1] == ":":
            group = t.take()[1].upper()
            t.take()
        kind_i, text_i, _ = t.peek()
        if kind_i == "n" and t.peek(1)[1] in ("]", ","):
            t.take()
            n = int(float(text_i))
            name = f"{w}[{n}]" if not group or group == "GP1" else f"{w}[{group}:{n}]"
            component = None
            if t.accept(","):
                kind_c, text_c, _ = t.take()
                if kind_c != "n" or int(float(text_c)) not in COMPONENTS:
                    raise _Unknown("a register's component")
                component = COMPONENTS[int(float(text_c))]
            t.expect("]")
            if w in ("R", "PR"):
                self.registers.add(name)
            out = Name(name)
            return out if component is None else _field(out, component)
        index = self.expr(t)
        t.expect("]")
        if w not in ("P", "PR", "R"):
            raise _Unknown(f"{w}[…] with a run-time index")
        if target:
            return Havoc(None, "", self.here)
        return Call(f"LS.{w}", (index,), self.here)

    def expr(self, t: _Tokens):
        return self.or_(t)

    def or_(self, t):
        a = self.and_(t)
        while t.word() == "OR":
            t.take()
            a = Op("or", (a, self.and_(t)))
        return a

    def and_(self, t):
        a = self.not_(t)
        while t.word() == "AND":
            t.take()
            a = Op("and", (a, self.not_(t)))
        return a

    def not_(self, t):
        if t.peek()[1] == "!" or t.word() == "NOT":
            t.take()
            return Op("not", (self.not_(t),))
        return self.compare(t)

    def compare(self, t):
        a = self.sum(t)
        op = t.peek()[1]
        if op in ("=", "<>", "<", "<=", ">", ">="):
            t.take()
            b = self.sum(t)
            return Op("==" if op == "=" else op, (a, b))
        return a

    def sum(self, t):
        a = self.term(t)
        while t.peek()[1] in ("+", "-") and t.peek()[0] == "o":
            op = t.take()[1]
            a = Op(op, (a, self.term(t)))
        return a

    def term(self, t):
        a = self.unary(t)
        while t.peek()[1] in ("*", "/") or t.word() in ("MOD", "DIV"):
            op = t.take()[1].lower()
            a = Op({"div": "div", "mod": "mod"}.get(op, op), (a, self.unary(t)))
        return a

    def unary(self, t):
        if t.peek()[1] == "-":
            t.take()
            inner = self.unary(t)
            return Lit(-inner.value) if isinstance(inner, Lit) and isinstance(inner.value, float) else \
                Op("neg", (inner,))
        return self.atom(t)

    def atom(self, t):
        kind, text, _ = t.peek()
        if kind == "n":
            t.take()
            return Lit(float(text))
        if kind == "s":
            t.take()
            return Lit(text[1:-1])
        if text == "(":
            t.take()
            e = self.expr(t)
            t.expect(")")
            return e
        if kind != "w":
            raise _Unknown(text or "end of instruction")
        w = text.upper()
        if w in ("ON", "OFF", "TRUE", "FALSE"):
            t.take()
            if t.peek()[1] in ("+", "-") and t.peek(1)[0] in (None,) or t.peek()[1] in ("+", "-") and \
                    t.peek(1)[1] in (")", ","):
                t.take()  # (an edge: ON+ / OFF-)
            return Lit(w in ("ON", "TRUE"))
        if w in ("P", "PR", "R", "UFRAME", "UTOOL") and t.peek(1)[1] == "[":
            return self.ref(t, target=False)
        if w in ("LPOS", "JPOS"):
            t.take()
            return Unknown(f"{w}: where the robot stands at run time", P211)
        t.take()
        if t.peek()[1] == "[":
            self.skip_brackets(t)
            return Unknown(f"{w}[…] is known only at run time", P211)
        if t.peek()[1] == "(":
            self.skip_parens(t)
            return Unknown(f"{w}(…) is known only at run time", P211)
        return Unknown(f"{text} is known only at run time", P211)

    def skip_parens(self, t):
        t.expect("(")
        depth = 1
        while depth and not t.done():
            x = t.take()[1]
            depth += (x == "(") - (x == ")")

    # ------------------------------------------------------------------ motions
    def motion(self, t: _Tokens, loc: Loc) -> None:
        letter = t.take()[1].upper()
        t.accept("@")
        kinds = ["CIRC-aux", "CIRC-end"] if letter == "C" else [_KIND[letter]]
        targets = []
        for kind in kinds:
            t.accept("@")
            targets.append((kind, self.position(t)))
        options = self.options(t, loc)
        for kind, target in targets:
            self.move(kind, target, options, loc)
        for stmt in options["after"]:
            self.emit(stmt)

    def position(self, t: _Tokens):
        """A motion's position: ``P[n]`` / ``PR[n]`` (a Name), an indirect one (a call), another
        (a palletizing point …: None)."""
        w = t.word()
        if w in ("P", "PR"):
            return self.ref(t, target=False)
        if t.peek()[0] == "w":
            t.take()
            if t.peek()[1] == "[":
                self.skip_brackets(t)
            return None
        raise _Unknown("a motion's position")

    def options(self, t: _Tokens, loc: Loc) -> dict:
        """A motion's speed, termination and options: what changes its target or what runs
        with it (``after``: statements run after the motion)."""
        out = {"offset": None, "tool_offset": None, "inc": False, "vision": None, "coord": False, "rtcp": False,
               "skip": None, "after": []}
        items = t.items
        k = t.k
        while k < len(items):
            kind, text, _ = items[k]
            w = text.upper() if kind == "w" else ""
            nxt = items[k + 1][1] if k + 1 < len(items) else ""
            if w in ("OFFSET", "TOOL_OFFSET"):
                which = "offset" if w == "OFFSET" else "tool_offset"
                if nxt == "," and k + 2 < len(items) and items[k + 2][1].upper() == "PR":
                    sub = _Tokens("")
                    sub.items, sub.k = items, k + 2
                    out[which] = self.ref(sub, target=False)
                    k = sub.k
                    continue
                out[which] = "condition"
            elif w == "INC":
                out["inc"] = True
            elif w in ("VOFFSET", "VTOOL_OFFSET"):
                out["vision"] = w
            elif w == "COORD":
                out["coord"] = True
            elif w == "RTCP":
                out["rtcp"] = True
            elif w == "SKIP" and nxt == ",":
                sub = _Tokens("")
                sub.items, sub.k = items, k + 2
                if sub.word() == "LBL":
                    sub.take()
                    label = self.label_number(sub)
                    store = None
                    if sub.accept(","):
                        store = self.ref(sub)
                        if isinstance(store, Havoc):  # (PR[R[n]]=LPOS: a register an index known at run time names)
                            self.indirect.setdefault("PR", loc.line)
                        sub.expect("=")
                        sub.take()
                    out["skip"] = (label, store)
                    k = sub.k
                    continue
            elif w == "CALL":
                name = items[k + 1][1].upper() if k + 1 < len(items) else ""
                out["after"].append(Invoke(name, (), loc))
            k += 1
        t.k = len(items)
        return out

    def move(self, kind: str, target, options: dict, loc: Loc) -> None:
        chain = kind != "CIRC-aux"
        if target is None:
            self.emit(Note(P211, "the motion's position is not a P[…] or PR[…] (a palletizing or other point "
                           "computed at run time): left as written", loc, True))
            self.emit(Move(kind, Unknown("computed at run time"), loc, relative=True, chain=chain))
            return
        if isinstance(target, Name) and target.name.startswith("P[") and \
                int(target.name[2:-1]) not in self.records:
            self.emit(Note(P215, f"{target.name} has no record in /POS: left as written", loc, True))
            self.emit(Move(kind, Unknown("no record"), loc, relative=True, chain=chain))
            return
        if isinstance(target, Name) and target.name.startswith("P["):
            record = self.records[int(target.name[2:-1])]
            if record[1] is None:
                self.emit(Note(P211, f"{target.name} has no group GP1: left as written", loc, True))
                self.emit(Move(kind, Unknown("no group 1"), loc, relative=True, chain=chain))
                return
            if "X" not in record[1]:
                self.emit(Move(kind, target, loc, joint=True, chain=chain))
                return
        written = _written(target)
        if options["inc"]:
            self.emit(Eval(Call("LS.READ", (target, Lit("an INC motion's increment"))), loc))
            self.emit(Note(P210, f"{written} is moved to with INC (relative to where the robot stands): left as written",
                           loc, True))
            self.emit(Move(kind, Unknown("INC"), loc, relative=True, chain=chain))
            return
        value = target
        if options["vision"]:
            self.emit(Eval(Call("LS.READ", (target, Lit(f"a {options['vision']} motion's position"))), loc))
            value = Unknown(f"{written} is moved to with {options['vision']}: a vision offset known at run time",
                            P211)
        elif options["offset"] is not None:
            reg = options["offset"]
            if reg == "condition":
                reg = Call("LS.PR", (Name("$OFFSET_PR"),), loc)
            value = Call("LS.Offset", (value, reg), loc)
        if options["tool_offset"] is not None:
            reg = options["tool_offset"]
            if reg == "condition":
                reg = Call("LS.PR", (Name("$TOOL_OFFSET_PR"),), loc)
            value = Call("LS.Tool_Offset", (value, reg), loc)
        frame = Call("LS.UFRAME", (target, Name("UFRAME_NUM")), loc)
        tool = Call("LS.UTOOL", (target, Name("UTOOL_NUM")), loc)
        if options["coord"]:
            frame = Unknown(f"{written} is moved to in coordinated motion (COORD): its frame moves with the leader "
                            "group", P225)
        if options["rtcp"]:
            tool = Unknown("a remote TCP (RTCP): the tool stands still, the part moves", P203)
        self.emit(Move(kind, value, loc, frame, tool, chain=chain))
        if options["skip"] is not None and kind != "CIRC-aux":
            label, store = options["skip"]
            stopped = [Havoc((), f"the skip condition stops the motion at line {loc.line} where it is met", loc)]
            if store is not None and not isinstance(store, Havoc):
                stopped.append(Assign(store, Unknown("the position where the skip condition was met", P211), loc))
            # met: the motion stops there and the next line runs; not met: it ends at its target, to LBL[n]
            self.emit(If(Unknown("the skip condition"), stopped, [Goto(label, loc)], loc))


class _ComputedJump(Havoc):
    """(a marker: replaced by a Switch over the program's labels once all are known)"""

    def __init__(self, index, loc):
        super().__init__((), "", loc)
        self.index = index


class _Publish(Havoc):
    """(a marker: where other programs may read the registers and frames this one sets — a CALL,
    RUN, the program's end; replaced by a read of each once all are known)"""

    def __init__(self, loc, where: str):
        super().__init__((), where, loc)


def _finished(body: list, labels: list, assigned: list) -> list:
    """The markers replaced: each computed ``JMP LBL[R[n]]`` by a SWITCH over the program's
    labels (none matching: the controller stops with an alarm); each ``_Publish`` by a read of
    every register and frame the program sets (what they hold there is read by other programs:
    a position copied into one is not rewritten without a word)."""
    out = []
    for s in body:
        if isinstance(s, _ComputedJump):
            cases = [((Lit(float(n)),), [Goto(n, s.loc)]) for n in dict.fromkeys(labels)]
            out.append(Switch(s.index, cases, [Halt(s.loc)], s.loc))
            continue
        if isinstance(s, _Publish):
            out += [Eval(Call("LS.READ", (Name(n), Lit(f"{n} holds them at {s.why}, where other programs may read it"))),
                         s.loc) for n in assigned]
            continue
        if isinstance(s, If):
            s.then, s.orelse = _finished(s.then, labels, assigned), _finished(s.orelse, labels, assigned)
        elif isinstance(s, Switch):
            s.cases = [(v, _finished(b, labels, assigned)) for v, b in s.cases]
            if s.default is not None:
                s.default = _finished(s.default, labels, assigned)
        elif isinstance(s, Loop):
            s.body = _finished(s.body, labels, assigned)
        out.append(s)
    return out


def _field(base, component):
    return Field(base, component, component)


def _written(e) -> str:
    if isinstance(e, Name):
        return e.name
    if isinstance(e, Call):
        return e.name.split(".")[-1] + "[…]"
    return "the position"


def _empty(m: re.Match) -> str:
    return m.group()[0] * 2  # a string emptied: '' or ""


def _analyse(tree, ordinal_at) -> tuple:
    """(GP1 of a record: {'X': (ordinal | '*', signed), …, 'uf': ordinal | 'F' | '*', 'ut': …,
    'config': ordinal, 'units': {axis: unit}, 'ext': [E1…]} | None, the other groups' names)."""
    out = None
    others = []
    axes: dict = {}  # the other groups' axes: "GP2.J1" → (ordinal | '*', signed) (a track's value)
    for group in tree.find_data("group"):
        name = str(group.children[0])
        if name != "GP1":
            others.append(name)
            for item in group.children[1:]:
                if item.data == "component":
                    number = item.children[1].children[-1]
                    axes[f"{name}.{item.children[0]}"] = ("*", False) if number.type == "STARS" else \
                        (ordinal_at[number.start_pos], len(item.children[1].children) > 1
                         and item.children[1].children[0] is not None)
            continue
        out = {"units": {}, "ext": []}
        for item in group.children[1:]:
            if item.data in ("uf", "ut"):
                v = item.children[0]
                if isinstance(v, Token) and v.type == "NUMBER":
                    out[item.data] = ordinal_at[v.start_pos]
                else:
                    out[item.data] = "*" if isinstance(v, Token) and v.type == "STARS" else "F"
            elif item.data == "config":
                out["config"] = ordinal_at[item.children[0].start_pos]
            else:
                axis, signed = str(item.children[0]), item.children[1]
                number = signed.children[-1]
                if number.type == "STARS":
                    out[axis] = ("*", False)
                else:
                    out[axis] = (ordinal_at[number.start_pos],
                                 len(signed.children) > 1 and signed.children[0] is not None)
                unit = item.children[2] if len(item.children) > 2 else None
                out["units"][axis] = str(unit) if unit is not None else ""
                if axis.startswith("E"):
                    out["ext"].append(axis)
    if out is not None:
        out["axes"] = axes
    return out, tuple(others)


def _problem(gp1: dict | None) -> tuple[str, str] | None:
    """(axis or '', what is wrong) with a Cartesian GP1's components and units, None if right."""
    if gp1 is None or "X" not in gp1:
        return None
    missing = [a for a in "XYZWPR" if a not in gp1]
    if missing:
        return "", f"lacks {', '.join(missing)}"
    for axis in "XYZWPR":
        unit = gp1["units"].get(axis)
        want = "mm" if axis in "XYZ" else "deg"
        if unit != want:
            return axis, f"{axis} in {unit or 'no unit'}, expected {want}"
    return None


_ = (P101, P211, Halt)

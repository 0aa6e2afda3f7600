"""The reading loop: files, lines, shapes; the Reader combines the handlers of the other modules."""
from __future__ import annotations

import gc
from pathlib import PurePath
from bisect import bisect_left

import numpy as np
from lark import Token, Tree

from ...diagnostics import P101, P104, P105, P224, Diagnostic, PostprocError
from ..model import ActiveFrames, Frame, Program, STAMP_PREFIX
from .assemble import Assembly
from .blocks import Blocks
from .calls import Calls
from .fast_path import FastPath, _HotRows, _Shape, _analyse, _name_paths
from .flow import Flow
from .frames import Frames, _START
from .scopes import Scopes
from .statements import AsyncStatements, Statements
from .syntax import SHAPE_RE, SyntaxErrors, _BLANK, _PLACEHOLDER
from .values import Values, _Num, _Var


def read(files: list[str], texts: list[str], config: list[str] | None = None, accelerate: bool = True,
         active: ActiveFrames | None = None) -> Program:
    """Parse a KRL module or a set of modules: ``files[0]`` the main .src, then any .dat /
    .src / .sub / ``$config.dat`` of the same cell (a .src and a .dat of one stem are one
    module; ``DECL GLOBAL`` and ``$config.dat`` declarations are seen by every module; calls
    are followed into the DEFs read). ``config`` the texts of $config.dat files not among
    ``files`` (BASE_DATA / TOOL_DATA / globals; read-only).
    ``active``: the $BASE / $TOOL its user states for targets before the program sets them
    (none stated: such targets are left as written, P220/P221).
    ``accelerate=False`` reads every line through the interpreter (no vectorised fast path:
    same result, slower; for tests).

    Raises PostprocError (P101 syntax, P102 undeclared target, P103 bad component, P104
    empty / no DEF) with the file:line:col of the offending token."""
    enabled = gc.isenabled()
    gc.disable()  # millions of small objects, no cycles: the collector only costs time here
    try:
        return Reader(list(files), list(texts), list(config or []), accelerate=accelerate, active=active).run()
    finally:
        if enabled:
            gc.enable()


def _stem(path: str) -> str:
    return PurePath(str(path).replace("\\", "/")).stem.upper()


def _kind(path: str) -> str:
    """'config' ($config.dat), 'dat' (a data list) or 'src' (.src, .sub, anything else)."""
    name = PurePath(str(path).replace("\\", "/")).name.lower()
    if name == "$config.dat":
        return "config"
    return "dat" if name.endswith(".dat") else "src"


class Reader(FastPath, Blocks, Flow, Statements, AsyncStatements, Frames, Scopes, Values, SyntaxErrors, Assembly,
             Calls):
    """The KRL reader: one module per concept, each contributing its methods."""

    def __init__(self, files, texts, config, accelerate: bool = True, active: ActiveFrames | None = None):
        if len(files) != len(texts):
            raise ValueError("files and texts differ in length")
        self.files, self.texts, self.config = files, texts, config
        self.accelerate = accelerate
        self.active = active
        self.ln = 0  # (the line being read; 0 before any)
        self.shapes: dict[str, _Shape] = {}
        self.diagnostics: list[Diagnostic] = []
        self.frames: list[Frame] = []
        self.newline: dict[int, str] = {}
        self.frame_ix: dict = {}
        self.assumed_robroot: set[int] = set()  # frame indices taken with robot base = world assumed (P224)
        self.unknown_frames: dict = {}  # reason key → [path, line, col, message, count, code]
        self.hot = _HotRows()
        self.cold = {k: [] for k in ("key", "pose", "written", "spans", "file", "line", "col", "motion",
                                     "frame", "emit", "chain", "config")}
        self.timeline: list = []  # (key, frame index, unknown reason key)
        self.globals: dict[str, _Var] = {}
        self.module: dict[str, _Var] = {}  # the scope of the module being read
        self.modules: dict[str, dict] = {}  # module name (file stem) → its scope (.src + .dat)
        self.local: dict[str, _Var] | None = None
        self.targets_of: dict[int, tuple] = {}  # id(_Agg) → (frame, line) of its first use
        self.call_states: dict[str, list] = {}
        self.strucs: dict[str, dict] = {}  # STRUC type → member → member type (upper case)

    def run(self) -> Program:
        for k, text in enumerate(self.config):
            self.scan(-1 - k, text, "$config.dat" if len(self.config) == 1 else f"$config.dat[{k}]", role="config")
        kinds = [_kind(f) for f in self.files]
        # $config.dat first, then the data lists, then the code (in the order given): every
        # global is declared before a module uses it
        order = [fi for k in ("config", "dat", "src") for fi in range(len(self.files)) if kinds[fi] == k]
        self.code_in_set = "src" in kinds[1:]
        for rank, fi in enumerate(order):
            role = "config" if kinds[fi] == "config" else "module"
            self.scan(fi, self.texts[fi], self.files[fi], role=role, rank=rank)
        targets = self.assemble()
        stamps, newlines = {}, []
        for fi, text in enumerate(self.texts):
            newlines.append(self.newline.get(fi, "\n"))
            at = text.find(STAMP_PREFIX)
            while at >= 0:
                a = text.rfind("\n", 0, at) + 1
                b = text.find("\n", at)
                b = len(text) if b < 0 else b
                line = text[a:b]
                if ";" in line[: at - a]:
                    stamps[fi] = line.strip()
                    break
                at = text.find(STAMP_PREFIX, b)
        for path, line, col, msg, count, code, first in self.unknown_frames.values():
            if first:
                _, line, col, path = first
            if count:
                self.diagnostics.append(Diagnostic(path, line, col, code,
                                                   f"{msg}: {count} target(s) left as written"))
        return Program(files=self.files, texts=self.texts, targets=targets, frames=self.frames,
                       named_targets=bool(self.targets_of), notes=self.robroot_notes(targets),
                       diagnostics=self.diagnostics, dialect="krl", stamps=stamps, newlines=newlines, comment=";")

    def robroot_notes(self, targets) -> list[Diagnostic]:
        """P224 once, at the first target taken with robot base = world assumed ($ROBROOT not
        stated, not in machine data given, not set by the program): a note, not a target left."""
        if not self.assumed_robroot:
            return []
        taken = np.flatnonzero(np.isin(targets.frame, list(self.assumed_robroot)))
        if not len(taken):
            return []
        first = int(taken[0])
        return [Diagnostic(self.files[targets.file[first]], int(targets.line[first]), int(targets.col[first]), P224,
                           "robot base = world assumed: $ROBROOT is not known (no --robroot, no machine data) "
                           "and the program does not set it, so $NULLFRAME is taken; give --robroot X,Y,Z,A,B,C "
                           "or the backup's Mada/$machine.dat (its System/$config.dat, or the backup directory)",
                           "note")]

    def warn(self, path, line, col, code, msg):
        self.diagnostics.append(Diagnostic(path, line, col, code, msg))

    def shape(self, text: str) -> _Shape:
        sh = self.shapes.get(text)
        if sh is None:
            sh = _Shape(text)
            _analyse(sh)
            self.shapes[text] = sh
        return sh

    def scan(self, fi: int, text: str, path: str, role: str, rank: int = 0) -> None:
        self.module = self.modules.setdefault(_stem(path), {}) if role == "module" else {}
        self.loops: list = []  # enclosing FORs: (variable, first, last, step), None where not constant
        self.fi, self.path, self.text, self.role = fi, path, text, role
        self.key0 = rank << 40
        self.blocks: list = []  # (kind, line, col, detail)
        self.flow: list = []  # open IF / SWITCH / loops (flow.py)
        self.interrupts: dict = {}  # number → (frames, points) a handler read may set (AsyncStatements)
        self.active_interrupts: dict = {}  # those switched on (INTERRUPT ON … OFF)
        self.moves = 0  # calls that moved so far (flow.py: did a branch move?)
        self.gotos: dict = {}  # label → frame states of the GOTOs to it read so far (flow.py)
        self.folds: list = []
        self.defs_seen = 0
        self.state = self.start_state() if role == "module" else _START
        self.saved_state = None
        self.fdat = None
        self.in_def = False
        self.has_dat = False
        self.kbase = self.key0
        self.def_lines: list = []  # (first, last) 1-based lines of DEF/DEFFCT bodies
        self.spline_lines: list = []
        self.block_open = {}
        if _BLANK.fullmatch(text):
            if role == "module" and fi == 0:
                raise PostprocError("the file is empty", path, 1, 1, P104)
            return  # an empty .dat or $config.dat declares nothing
        data = text.encode("latin-1", "replace") if not text.isascii() else text.encode("ascii")
        raw = np.frombuffer(data, np.uint8)
        nl = np.flatnonzero(raw == 10)
        if fi >= 0:  # the dominant line ending, for the rewriter
            crlf = int(np.count_nonzero(raw[nl[nl > 0] - 1] == 13))
            self.newline[fi] = "\r\n" if crlf and 2 * crlf >= len(nl) else "\n"
        self.starts = np.concatenate([[0], nl + 1]).astype(np.int64)
        nlines = len(self.starts) - (1 if text.endswith("\n") else 0)
        hot_lines = {}  # shape → (lines, starts, numbers) read by the interpreter loop
        first_part = len(self.hot.parts)
        if role == "module" and self.accelerate and nlines > 4096 and _kind(path) == "src":  # (data lists: no motions)
            self.scan_accelerated(text, nlines, hot_lines)
        else:
            self.scan_lines(range(nlines), hot_lines)
        for sh, (lines, starts, nums) in hot_lines.items():
            cols = list(zip(*nums)) if sh.ph else []
            self.hot.add(sh.plan, fi, np.array(lines, np.int64), np.array(starts, np.int64), cols, self.key0,
                         (self.path, self.text))
        self.finish_file(nlines)
        self.check_parts(self.hot.parts[first_part:])

    def scan_lines(self, line_indices, hot_lines) -> None:
        text, starts = self.text, self.starts
        n = len(starts)
        for i in line_indices:
            a = int(starts[i])
            b = int(starts[i + 1]) - 1 if i + 1 < n else len(text)
            self.line_at(i, a, text[a:b], hot_lines)

    def line_at(self, i: int, a: int, line: str, hot_lines) -> None:
        sh = self.shape(SHAPE_RE.sub(_PLACEHOLDER, line))
        k = sh.kind
        if k == "blank":
            return
        if k == "hot":
            nums = [m.group() for m in SHAPE_RE.finditer(line)] if sh.ph else []
            entry = hot_lines.get(sh)
            if entry is None:
                entry = hot_lines[sh] = ([], [], [])
            entry[0].append(i)
            entry[1].append(a)
            entry[2].append(nums)
            self.hot_line(i, sh)
            return
        self.interpret(i, a, line, sh)

    def interpret(self, i, a, line, sh):
        self.ln = i + 1
        self.kbase = self.key0 + i * 4
        self.la = a
        self.lt = line
        self.sh = sh
        self._nums = None  # before a syntax error is reported: its column needs this line's numbers
        if sh.kind == "error":
            self.syntax_error(sh.error)
        if sh.fold:
            col = line.find(";") + 1
            if sh.fold > 0:
                self.folds.append((i + 1, col))
            elif self.folds:
                self.folds.pop()
            else:
                self.warn(self.path, i + 1, col, P105, ";ENDFOLD without ;FOLD")
        if sh.tree is None:
            return
        tree = self.concrete(sh.tree) if sh.names else sh.tree
        stmt = None
        for c in tree.children:
            if hasattr(c, "data"):
                stmt = c
        if stmt is None:
            return
        if sh.fcalls and stmt.data not in ("interrupt_decl", "trigger"):  # (handlers: AsyncStatements)
            # functions run before the statement takes effect; one may set a frame
            self.expression_calls(stmt)
        handler = getattr(self, "s_" + stmt.data, None)
        if handler is not None:
            handler(stmt)

    def concrete(self, tree):
        """``tree`` with the names of this line (a shape has XP0 where the line has XP12);
        positions stay those of the shape. Only the nodes above such names are copied."""
        sh = self.sh
        if sh.name_paths is None:
            sh.name_paths = _name_paths(tree, sh.names)
        return self._rebuild(tree, sh.name_paths) if sh.name_paths else tree

    def _rebuild(self, node, paths):
        groups: dict = {}
        for p in paths:
            groups.setdefault(p[0], []).append(p[1:])
        children = list(node.children)
        for i, sub in groups.items():
            c = children[i]
            if isinstance(c, Token):
                text = self.text[self.abs_pos(c.start_pos):self.abs_pos(c.end_pos)]
                children[i] = Token.new_borrow_pos(c.type, text, c)
            else:
                children[i] = self._rebuild(c, sub)
        new = Tree(node.data, children, node._meta)
        if hasattr(node, "meta_brace"):
            new.meta_brace = node.meta_brace
        return new

    # positions and numbers of the current line
    def nums(self):
        """(start, end) in the file of each placeholder of the current line, in order."""
        if self._nums is None:
            la = self.la
            self._nums = [(m.start() + la, m.end() + la) for m in SHAPE_RE.finditer(self.lt)]
            cum, extra = [0], 0
            for a, b in self._nums:  # how much longer than its "0" each placeholder is
                extra += b - a - 1
                cum.append(extra)
            self._cum = cum
        return self._nums

    def abs_pos(self, shape_pos: int) -> int:
        """Offset in the file of a position in the current line's shape."""
        if not self.sh.ph:
            return self.la + shape_pos
        self.nums()
        return self.la + shape_pos + self._cum[bisect_left(self.sh.ph, shape_pos)]

    def col(self, shape_pos: int) -> int:
        return self.abs_pos(shape_pos) - self.la + 1

    def err(self, msg, token_or_pos, code=P101):
        pos = token_or_pos if isinstance(token_or_pos, int) else token_or_pos.start_pos
        raise PostprocError(msg, self.path, self.ln, self.col(pos), code)

    def number(self, tok) -> _Num:
        s, e = self.nums()[self.sh.phidx[tok.start_pos]]
        return _Num(float(self.text[s:e]), s, e)

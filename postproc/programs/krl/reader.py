"""The reading loop: files, lines, shapes → the motion IR (``lower.py``) → the analysis
(``programs.analysis``, with KRL's ``semantics.py``) → Program."""
from __future__ import annotations

import gc
from bisect import bisect_left
from pathlib import PurePath

from lark import Token, Tree

from ...core.diagnostics import P101, P104, P105, Diagnostic, PostprocError
from ..analysis import analyse
from ..ir import Invoke, Loc, Unit, walk
from ..model import STAMP_PREFIX, ActiveFrames, Program
from .blocks import Blocks
from .fast_path import FastPath, _analyse, _HotRows, _name_paths, _Shape
from .lower import Lowering
from .semantics import KRL
from .syntax import _BLANK, _PLACEHOLDER, SHAPE_RE, SyntaxErrors

BOM = "\xef\xbb\xbf"  # a UTF-8 byte order mark, as the latin-1 text holds it


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

    Raises PostprocError (P101 syntax, P103 bad component, P104 empty / no DEF) with the
    file:line:col of the offending token."""
    enabled = gc.isenabled()
    gc.disable()  # millions of small objects, no cycles: the collector only costs time here
    try:
        return Reader(list(files), list(texts), list(config or []), accelerate=accelerate, active=active).run()
    finally:
        if enabled:
            gc.enable()


def lower(files: list[str], texts: list[str], config: list[str] | None = None, accelerate: bool = True,
          active: ActiveFrames | None = None) -> tuple[Unit, KRL]:
    """The motion IR of a KRL module or cell and its dialect (what ``read`` analyses)."""
    reader = Reader(list(files), list(texts), list(config or []), accelerate=accelerate, active=active)
    return reader.lower(), reader.dialect()


def _stem(path: str) -> str:
    return PurePath(str(path).replace("\\", "/")).stem.upper()


def _kind(path: str) -> str:
    """'config' ($config.dat), 'dat' (a data list) or 'src' (.src, .sub, anything else)."""
    name = PurePath(str(path).replace("\\", "/")).name.lower()
    if name == "$config.dat":
        return "config"
    return "dat" if name.endswith(".dat") else "src"


class Reader(FastPath, Lowering, Blocks, SyntaxErrors):
    """The KRL reader: the lines of its files lowered to one Unit."""

    def __init__(self, files, texts, config, accelerate: bool = True, active: ActiveFrames | None = None):
        if len(files) != len(texts):
            raise ValueError("files and texts differ in length")
        self.files, self.texts, self.config = files, texts, config
        self.accelerate = accelerate
        self.active = active
        self.ln = 0  # (the line being read; 0 before any)
        self.shapes: dict[str, _Shape] = {}
        self.diagnostics: list[Diagnostic] = []
        self.newline: dict[int, str] = {}
        self.hot = _HotRows()
        config_names = ["$config.dat" if len(config) == 1 else f"$config.dat[{k}]" for k in range(len(config))]
        self.unit = Unit("krl", files, texts, config_names=config_names, config_texts=config)
        self.datas: dict[str, list] = {}  # module → its data statements
        self.local_defs: dict[str, set] = {}
        self.strucs: dict[str, dict] = {}
        self.config_globals: set = set()
        self.routine_order: list = []
        self.file_routines: list = []

    def dialect(self) -> KRL:
        d = KRL(self.active, config=bool(self.config) or "config" in map(_kind, self.files),
                modules=self.local_defs, strucs=self.strucs)
        d.config_globals |= self.config_globals
        return d

    def lower(self) -> Unit:
        for k, text in enumerate(self.config):
            self.scan(-1 - k, text, self.unit.config_names[k], role="config")
        kinds = [_kind(f) for f in self.files]
        # $config.dat first, then the data lists, then the code (in the order given): every
        # global is declared before a module uses it
        order = [fi for k in ("config", "dat", "src") for fi in range(len(self.files)) if kinds[fi] == k]
        self.code_in_set = "src" in kinds[1:]
        for rank, fi in enumerate(order):
            role = "config" if kinds[fi] == "config" else "module"
            self.scan(fi, self.texts[fi], self.files[fi], role=role, rank=rank)
        unit = self.unit
        unit.data = list(self.datas.items())
        unit.prologue = [Invoke("KRL.START", (), Loc(0, 1, 1))]
        called = set()
        for key in self.routine_order:
            r = unit.routines[key]
            for s in walk(r.body):
                if isinstance(s, Invoke):
                    called.add(self._resolve(s.name, r.module))
            for name in _calls_in(r.body):
                called.add(self._resolve(name, r.module))
        unit.entries = [k for k in self.routine_order if k not in called]
        return unit

    def _resolve(self, name: str, module: str) -> str:
        name = name.upper()
        return f"{module}::{name}" if name in self.local_defs.get(module, ()) else name

    def run(self) -> Program:
        unit = self.lower()
        built = analyse(unit, self.dialect())
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
        program = Program(files=self.files, texts=self.texts, targets=built.targets, frames=built.frames,
                          named_targets=built.named, notes=built.notes,
                          diagnostics=self.diagnostics + built.diagnostics, dialect="krl", stamps=stamps,
                          newlines=newlines, comment=";")
        program.held, program.sites = built.held, built.sites
        return program

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
        self.module_name = "$CONFIG" if role == "config" else _stem(path)
        self.module_data = self.datas.setdefault(self.module_name, [])
        self.fi, self.path, self.text, self.role = fi, path, text, role
        self.key0 = rank << 40
        self.begin_file()
        self.folds: list = []
        self.defs_seen = 0
        self.has_dat = False
        self.kbase = self.key0
        self.def_lines: list = []  # (first, last) 1-based lines of DEF/DEFFCT bodies
        self.spline_lines: list = []
        self.block_open = {}
        self.file_routines = []
        if _BLANK.fullmatch(text):
            if role == "module" and fi == 0:
                raise PostprocError("the file is empty", path, 1, 1, P104)
            return  # an empty .dat or $config.dat declares nothing
        import numpy as np

        data = text.encode("latin-1", "replace") if not text.isascii() else text.encode("ascii")
        raw = np.frombuffer(data, np.uint8)
        nl = np.flatnonzero(raw == 10)
        if fi >= 0:  # the dominant line ending, for the rewriter
            crlf = int(np.count_nonzero(raw[nl[nl > 0] - 1] == 13))
            self.newline[fi] = "\r\n" if crlf and 2 * crlf >= len(nl) else "\n"
        self.starts = np.concatenate([[0], nl + 1]).astype(np.int64)
        if text.startswith(BOM):  # (RSI driver programs start with one: the first line starts after it)
            self.starts[0] = len(BOM)
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
        self.kbase = self.key0 + (nlines + 1) * 4
        self.finish_file(nlines)
        parts = self.hot.parts[first_part:]
        self.check_parts(parts)
        self.fill_gaps(parts)
        del self.hot.parts[first_part:]  # (they are the routines' MoveRuns now)

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
        self.gap()
        handler = getattr(self, "s_" + stmt.data, None)
        if handler is not None:
            before = self.routine
            handler(stmt)
            if self.routine is not None and self.routine is not before:
                self.file_routines.append(self.routine.name)

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

    def number(self, tok):
        from .syntax import Number

        s, e = self.nums()[self.sh.phidx[tok.start_pos]]
        return Number(float(self.text[s:e]), s, e)


def _calls_in(body):
    """Names of routines called in expressions (``Call``) of a body."""
    from ..ir import Call

    out = []

    def visit(e):
        if isinstance(e, Call):
            out.append(e.name)
        for f in getattr(e, "__slots__", ()):
            v = getattr(e, f, None)
            if isinstance(v, tuple):
                for x in v:
                    if isinstance(x, tuple):
                        for y in x:
                            visit(y)
                    else:
                        visit(x)
            elif hasattr(v, "__slots__") and not isinstance(v, (str, Loc)):
                visit(v)

    for s in walk(body):
        for f in getattr(s, "__slots__", ()):
            v = getattr(s, f, None)
            if isinstance(v, tuple):
                for x in v:
                    visit(x)
            elif hasattr(v, "__slots__") and not isinstance(v, (str, Loc)):
                visit(v)
    return out

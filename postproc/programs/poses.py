"""Generic pose programs: a CSV with a header naming at least x,y,z (and a,b,c), or
whitespace-separated ``x y z [a b c]`` lines with no header.

Every row is a Cartesian target in the robot base frame. Optional columns ``s,t`` (Status
and Turn, integers; empty = not stated) give the arm configuration and ``q1..q6`` the joint
angles (deg) the controller uses, passed to the model as they are. Other columns, comment lines
(``#``, ``;``, ``//``) and blank lines are kept as they are. The syntax of a record is
``grammars/poses.lark``; each distinct line shape (numbers abstracted) is parsed once and
reused. Lines of the frequent shapes made of numbers and separators only are then read a chunk
at a time (one regex over the chunk, numbers converted by numpy: ``_Rows.chunk``); every other
line, and a whole chunk holding a value that needs a message, goes through the line-by-line
path (``_Rows.line``), so both give the same targets and the same errors.
"""
from __future__ import annotations

import functools
import math
import re
from operator import itemgetter
from pathlib import Path

import numpy as np
from lark import Lark, UnexpectedInput

from ..core.diagnostics import P101, P103, P104, P105, PostprocError
from ..core.resources import grammar_path
from ..robot.conventions import MOTIONS
from .model import STAMP_PREFIX, Frame, Program, Targets
from .text import newline

COLUMNS = ("x", "y", "z", "a", "b", "c")
CONFIG = ("s", "t")
JOINTS = ("q1", "q2", "q3", "q4", "q5", "q6")
LOADS = ("load_mass", "load_cx", "load_cy", "load_cz")  # the payload at the row (kg; mm, flange frame), as a measurement CSV's
_OPTIONAL = CONFIG + JOINTS + LOADS
_ALL = COLUMNS + _OPTIONAL
_COMMENT = re.compile(r"[ \t]*(#|;|//)")
# ``# frame: controller`` (the robot controller's base) or ``# frame: model`` (the model's frame)
# in the comments before the first row: where a pose list's rows are, for a model whose frame
# is not the controller's base (a UR description in ROS's base_link)
_FRAME = re.compile(r"[ \t]*(?:#|;|//)[ \t]*frame[ \t]*:[ \t]*(\S*)[ \t]*$", re.IGNORECASE)
FRAMES = {"controller": True, "model": False}
_ROW_MOTION = MOTIONS.index("row")
_FAST_MIN_CHARS = 1 << 16  # smaller texts: line by line only
_FAST_LEARN = 256  # lines read line by line first, to learn the shapes
_FAST_CHUNK = 1 << 17  # characters per vectorised chunk
_FAST_MAX = 8  # shapes in the regex


@functools.lru_cache(maxsize=1)
def _parser() -> Lark:
    return Lark(grammar_path("poses.lark").read_text(), start="record", parser="lalr", maybe_placeholders=True)


@functools.lru_cache(maxsize=1)
def _number_re() -> re.Pattern:
    # the grammar's own NUMBER terminal, so there is one definition of what a number is
    return re.compile(_parser().get_terminal("NUMBER").pattern.to_regexp())


def _fields(line: str, path: str, lineno: int, offset: int) -> list:
    """Parse one record → list of (kind, token) per field; kind in number/word/string/None.
    Tokens keep ``start_pos`` (offset in ``line``)."""
    try:
        tree = _parser().parse(line)
    except UnexpectedInput as exc:
        col = offset + exc.column if exc.column and exc.column > 0 else offset + 1
        raise PostprocError(f"cannot read this record: unexpected {line[exc.pos_in_stream:exc.pos_in_stream + 10]!r}",
                            path, lineno, col, P101) from None
    return [(None, None) if f is None else (f.data, f.children[0]) for f in tree.children]


# the first line of a program of another dialect, saved with a pose list's suffix (.txt, .csv)
_OTHER_DIALECTS = ((re.compile(r"def\s+\w+\s*\([^)]*\)\s*:"), "a URScript program", ".script"),  # (before KRL's DEF)
                   (re.compile(r"(?:MODULE|%%%)\b", re.I), "an ABB RAPID module", ".mod, .prg, .sys"),
                   (re.compile(r"(?:&ACCESS|&REL|(?:GLOBAL\s+)?DEF(?:DAT|FCT)?)\b", re.I), "a KUKA KRL program", ".src, .dat"),
                   (re.compile(r"/PROG\b", re.I), "a FANUC LS program", ".ls"))


def _not_another_dialect(body: str, path: str, lineno: int, lead: int) -> None:
    """P104 naming the dialect where a pose list's first line is a program's first line."""
    for pattern, what, suffixes in _OTHER_DIALECTS:
        if pattern.match(body):
            raise PostprocError(f"not a pose list: this line reads like {what}'s first line; give the file its "
                                f"dialect's suffix ({suffixes}): a {Path(path).suffix or 'file without a suffix'} "
                                "is read as a pose list", path, lineno, lead + 1, P104)


def _header(body: str, path: str, lineno: int, lead: int) -> tuple[dict[str, int], int]:
    """The header line: column name → field index, and the number of fields."""
    try:
        fields = _fields(body, path, lineno, lead)
    except PostprocError:
        _not_another_dialect(body, path, lineno, lead)
        raise
    names = [str(tok).lower() if kind == "word" else "" for kind, tok in fields]
    missing = [c for c in COLUMNS[:3] if c not in names]
    if missing:
        _not_another_dialect(body, path, lineno, lead)
        raise PostprocError(f"header has no column {', '.join(missing)} (needs x,y,z[,a,b,c])",
                            path, lineno, lead + 1, P104)
    columns = {c: names.index(c) for c in _ALL if c in names}
    attitude = [c for c in COLUMNS[3:] if c in columns]
    if attitude and len(attitude) < 3:  # one warning here, not one per row and A,B dropped
        absent = [c for c in COLUMNS[3:] if c not in columns]
        raise PostprocError(f"header has {','.join(attitude)} but no {','.join(absent)}: an attitude needs all "
                            "of a,b,c (add the missing column; or drop a,b,c for the model's nominal attitude)",
                            path, lineno, lead + 1, P104)
    return columns, len(fields)


def _shape(body: str, columns: dict[str, int] | None, width: int, path: str, lineno: int,
           lead: int) -> tuple[tuple, dict[str, int], int]:
    """A line shape seen for the first time, parsed: the ordinal among the line's number runs of
    each of x..c, s, t, q1..q6 (-1: absent), and the columns and width (set by the first row of
    a file without header: x y z [a b c] by position)."""
    number = _number_re()
    fields = _fields(body, path, lineno, lead)
    if columns is None:  # headerless: x y z [a b c] by position
        if len(fields) not in (3, 6) and len(fields) < 6:
            raise PostprocError(f"expected 3 or 6 numbers (x y z [a b c]), found {len(fields)} fields",
                                path, lineno, lead + 1, P104)
        columns = {c: i for i, c in enumerate(COLUMNS[: 6 if len(fields) >= 6 else 3])}
        width = len(fields)
    if len(fields) != width:
        raise PostprocError(f"expected {width} fields as in the header, found {len(fields)}",
                            path, lineno, lead + 1, P104)
    # which regex match (of all number-looking runs in the line, words included) each
    # numeric field is; lines of the same shape have the same runs in the same places
    run_at = {m.start(): k for k, m in enumerate(number.finditer(body))}
    ordinal_of = {i: run_at[tok.start_pos] for i, (kind, tok) in enumerate(fields) if kind == "number"}
    for name, index in columns.items():
        if index not in ordinal_of and not (name in _OPTIONAL and fields[index][1] is None):
            kind, tok = fields[index]
            where = body.find(str(tok)) if tok is not None else 0
            raise PostprocError(f"column {name} is not a number: '{tok}'" if tok is not None
                                else f"column {name} is empty", path, lineno, lead + max(where, 0) + 1, P103)
    return tuple(ordinal_of.get(columns[c], -1) if c in columns else -1 for c in _ALL), columns, width


def _extras(matches: list, ordinals: tuple, path: str, lineno: int) -> list[float]:
    """A row's s, t, q1..q6 (NaN where not stated)."""
    extra = [math.nan] * len(_OPTIONAL)
    for k, ordinal in enumerate(ordinals[6:]):
        if ordinal >= 0:
            m = matches[ordinal]
            value = float(m.group())
            if not math.isfinite(value) or (k < 2 and not (value == int(value) and 0 <= value < 64)):
                raise PostprocError(f"{_OPTIONAL[k]} must be {'an integer 0…63' if k < 2 else 'finite'}: "
                                    f"{m.group()}", path, lineno, m.start() + 1, P103)
            extra[k] = value
    return extra


def _pose(matches: list, ordinals: tuple, start: int, path: str, lineno: int) -> tuple[list, list, list]:
    """A row's X..C (NaN where absent), the spans of its X, Y, Z numbers and of its A, B, C
    numbers (offsets in the text; -1 where absent)."""
    pose = [math.nan] * 6
    spans = [-1] * 6
    abc = [-1] * 6
    for k, ordinal in enumerate(ordinals[:6]):
        if ordinal < 0:
            continue
        m = matches[ordinal]
        value = float(m.group())
        if not math.isfinite(value):
            raise PostprocError(f"{COLUMNS[k]} is not finite: {m.group()}", path, lineno, m.start() + 1, P103)
        pose[k] = value
        if k < 3:
            spans[2 * k], spans[2 * k + 1] = start + m.start(), start + m.end()
        else:
            abc[2 * k - 6], abc[2 * k - 5] = start + m.start(), start + m.end()
    return pose, spans, abc


class _Rows:
    """The rows of one pose file, read line by line (``line``: the exact path, the one
    definition of a record) or a chunk of lines at once (``chunk``: lines whose shape the exact
    path accepted, numbers and separators only, read vectorised)."""

    def __init__(self, path: str, text: str):
        self.path, self.text = path, text
        self.number = _number_re()
        self.stamps: dict[int, str] = {}
        self.columns: dict[str, int] | None = None  # column name → field index
        self.width = 0
        self.shapes: dict[str, tuple] = {}  # line shape → ordinal of each x..c among the line's numbers
        self.counts: dict[str, int] = {}  # lines read per shape
        self.extras = False  # the header names s, t or q1..q6
        self.frame: bool | None = None  # a ``# frame:`` line before the rows (``FRAMES``), None: none
        # exact rows (lists), then vectorised parts (arrays), merged by line number at the end
        self.pose: list = []
        self.spans: list = []
        self.abc: list = []
        self.extra: list = []
        self.lineno: list = []
        self.col: list = []
        self.parts: list = []

    def line(self, lineno: int, raw: str, start: int) -> None:
        """One line (its newline included or not) starting at offset ``start``."""
        path, number = self.path, self.number
        line = raw.rstrip("\r\n")
        body = line.strip()
        if not body:
            return
        if _COMMENT.match(line):
            if STAMP_PREFIX in line:
                self.stamps[0] = body
            elif not self.pose and not self.parts:  # (before the first row: where it states their frame)
                self._frame(line, lineno)
            return
        lead = len(line) - len(line.lstrip())
        columns = self.columns
        if columns is None and any(ch.isalpha() for ch in number.sub("", body)):
            self.columns, self.width = _header(body, path, lineno, lead)
            self.extras = any(c in self.columns for c in _OPTIONAL)
            return
        shape = number.sub("0", body)
        ordinals = self.shapes.get(shape)
        if ordinals is None:
            ordinals, self.columns, self.width = _shape(body, columns, self.width, path, lineno, lead)
            self.shapes[shape] = ordinals
        self.counts[shape] = self.counts.get(shape, 0) + 1
        matches = list(number.finditer(line))
        if self.extras:
            self.extra.append(_extras(matches, ordinals, path, lineno))
        pose, spans, abc = _pose(matches, ordinals, start, path, lineno)
        self.pose.append(pose)
        self.spans.append(spans)
        self.abc.append(abc)
        self.lineno.append(lineno)
        self.col.append(lead + 1)

    def _frame(self, line: str, lineno: int) -> None:
        """A ``# frame: controller|model`` comment: the rows' frame; another value is a syntax
        error at its line."""
        found = _FRAME.match(line)
        if found:
            value = found.group(1).lower()
            if value not in FRAMES:
                raise PostprocError(f"# frame: {found.group(1)!r}: say controller (the robot controller's base) or "
                                    f"model (the model's frame)", self.path, lineno, found.start(1) + 1, P101)
            self.frame = FRAMES[value]

    def lines(self, first: int, last: int, starts: np.ndarray) -> None:
        """Lines ``first`` … ``last - 1`` (0-based) by the exact path."""
        text = self.text
        for i in range(first, last):
            a = int(starts[i])
            b = int(starts[i + 1]) if i + 1 < len(starts) else len(text)
            self.line(i + 1, text[a:b], a)

    def fast_shapes(self) -> list[tuple[str, tuple]]:
        """The shapes read so far that a regex reads exactly: numbers and separators only, a
        separator between any two numbers, not a comment; the most frequent first."""
        out = []
        for shape in sorted(self.counts, key=self.counts.get, reverse=True):
            pieces = shape.split("0")
            if (shape[0] in ";/#" or any(set(p) - set(" \t,;") for p in pieces)
                    or any(not p for p in pieces[1:-1])):
                continue
            out.append((shape, self.shapes[shape]))
        return out[:_FAST_MAX]

    def chunk(self, first: int, last: int, starts: np.ndarray, fast: "_FastShapes") -> None:
        """Lines ``first`` … ``last - 1`` with one regex; lines of other shapes, and the whole
        chunk when a value needs a message, by the exact path."""
        text = self.text
        a = int(starts[first])
        b = int(starts[last]) if last < len(starts) else len(text)
        rows = fast.regex.findall(text[a:b])
        n = last - first
        if len(rows) < n:  # (never: one match per line)
            self.lines(first, last, starts)
            return
        del rows[n:]
        cols = list(zip(*rows))
        del rows
        line0 = np.arange(first, last, dtype=np.int64)
        parts, hot = [], np.zeros(n, bool)
        for (shape, ordinals), g, ph in zip(fast.shapes, fast.first, fast.ph):
            m = np.fromiter(map(bool, cols[g]), bool, n)
            if not m.any():
                continue
            hot |= m
            sel = np.flatnonzero(m)
            part = self._vectorised(ordinals, ph, [cols[g + q] for q in range(len(ph))], sel, line0[sel], starts)
            if part is None:  # a value the exact path has a message for
                self.lines(first, last, starts)
                return
            parts.append(part)
            self.counts[shape] += len(sel)
        self.parts.extend(parts)
        for k in np.flatnonzero(~hot).tolist():
            i = first + k
            self.line(i + 1, cols[-1][k], int(starts[i]))

    def _vectorised(self, ordinals: tuple, ph: list, groups: list, sel: np.ndarray, line0: np.ndarray,
                    starts: np.ndarray) -> dict | None:
        n = len(sel)
        if len(sel) < len(groups[0]):
            pick = itemgetter(*sel.tolist()) if n > 1 else (lambda c, k=int(sel[0]): (c[k],))
            groups = [pick(c) for c in groups]
        need = sorted({o for o in ordinals if o >= 0})
        try:  # (the same strings float() takes: a run of number characters that is not one number fails)
            values = {j: np.array(groups[j], dtype=np.float64) for j in need}
        except ValueError:
            return None
        if not all(np.isfinite(v).all() for v in values.values()):
            return None
        start = starts[line0]
        # offset of number j in its line: ph[j] + Σ_{i<j} (len_i − 1)
        last = max(o for o in ordinals[:6] if o >= 0)
        shift = np.zeros(n, np.int64)
        offsets, lens = {}, {}
        for j in range(last + 1):
            offsets[j] = start + ph[j] + shift
            lens[j] = np.fromiter(map(len, groups[j]), np.int64, n)
            shift = shift + lens[j] - 1
        pose = np.full((n, 6), np.nan)
        spans = np.full((n, 6), -1, np.int64)
        abc = np.full((n, 6), -1, np.int64)
        for k, o in enumerate(ordinals[:6]):
            if o < 0:
                continue
            pose[:, k] = values[o]
            end = offsets[o] + lens[o]
            target = spans if k < 3 else abc
            target[:, 2 * (k % 3)] = offsets[o]
            target[:, 2 * (k % 3) + 1] = end
        extra = None
        if self.extras:
            extra = np.full((n, len(_OPTIONAL)), np.nan)
            for k, o in enumerate(ordinals[6:]):
                if o < 0:
                    continue
                v = values[o]
                if k < 2 and not ((v == np.floor(v)) & (v >= 0) & (v < 64)).all():
                    return None
                extra[:, k] = v
        return dict(pose=pose, spans=spans, abc=abc, extra=extra, lineno=line0 + 1, col=np.ones(n, np.int64))

    def targets(self) -> Targets:
        n = len(self.pose)
        pose = np.array(self.pose, dtype=np.float64).reshape(n, 6)
        spans = np.array(self.spans, dtype=np.int64).reshape(n, 6)
        abc = np.array(self.abc, dtype=np.int64).reshape(n, 6)
        lineno = np.array(self.lineno, dtype=np.int64)
        col = np.array(self.col, dtype=np.int64)
        extra = np.array(self.extra, float).reshape(n, len(_OPTIONAL)) if self.extras else None
        if self.parts:  # merge by line number (each line holds one row at most)
            parts = self.parts
            lines = np.concatenate([lineno] + [p["lineno"] for p in parts])
            order = None if (np.diff(lines) > 0).all() else np.argsort(lines, kind="stable")

            def merged(first, key):
                column = np.concatenate([first] + [p[key] for p in parts])
                return column if order is None else column[order]

            pose, spans, abc, lineno, col = (merged(first, key) for first, key in (
                (pose, "pose"), (spans, "spans"), (abc, "abc"), (lineno, "lineno"), (col, "col")))
            if extra is not None:
                extra = merged(extra, "extra")
            n = len(pose)
        targets = Targets(poses=pose, spans=spans.reshape(n, 3, 2), file=np.zeros(n, np.int32),
                          line=lineno.astype(np.int32), col=col.astype(np.int32), frame=np.zeros(n, np.int32),
                          motion=np.full(n, _ROW_MOTION, np.int8))
        targets.abc_spans = abc.reshape(n, 3, 2)
        if extra is not None:
            if any(c in self.columns for c in CONFIG):
                targets.config = np.where(np.isnan(extra[:, :2]), -1, extra[:, :2]).astype(np.int16)
            if any(c in self.columns for c in JOINTS):
                targets.joints = extra[:, 2:8]
            if "load_mass" in self.columns:  # (a row without a mass: the payload not set there; cx..cz default 0)
                load = extra[:, 8:12].copy()
                load[:, 1:] = np.where(np.isnan(load[:, 1:]) & ~np.isnan(load[:, :1]), 0.0, load[:, 1:])
                if (load[:, 0] < 0).any():
                    row = int(np.flatnonzero(load[:, 0] < 0)[0])
                    raise PostprocError("load_mass must be ≥ 0 kg", self.path, int(lineno[row]), 1, P103)
                targets.load = load
                targets.load_cause = np.full(n, -1, np.int32)
        return targets


class _FastShapes:
    """One regex over the frequent fast shapes (numbers as groups, in order); any other line
    falls into the last group."""

    def __init__(self, shapes: list[tuple[str, tuple]]):
        self.shapes = shapes
        self.first, self.ph, parts, g = [], [], [], 0
        # the numbers read: any run of number characters (one that is not a number, e.g.
        # '1-2', fails the conversion, and its chunk goes line by line); the others: a number
        strict = "(" + re.sub(r"\((?!\?)", "(?:", _number_re().pattern) + ")"  # one group per number
        for shape, ordinals in shapes:
            self.first.append(g)
            self.ph.append([i for i, ch in enumerate(shape) if ch == "0"])
            pieces = shape.split("0")
            used = set(ordinals)
            parts.append(re.escape(pieces[0]) + "".join(("([-+.0-9eE]+)" if j in used else strict) + re.escape(p)
                                                         for j, p in enumerate(pieces[1:])) + "\\r?")
            g += len(pieces) - 1
        self.regex = re.compile("^(?:" + "|".join(parts) + r"|([^\n]*))$", re.M)
        assert self.regex.groups == g + 1


def _line_starts(text: str) -> np.ndarray | None:
    """Offset of each line (lines end at "\n" only); None for a text that is not latin-1."""
    try:
        data = text.encode("latin-1")
    except UnicodeEncodeError:
        return None
    return np.concatenate([[0], np.flatnonzero(np.frombuffer(data, np.uint8) == 10) + 1]).astype(np.int64)


def read(files: list[str], texts: list[str], fast: bool = True, _lowered: bool = False) -> Program:
    """Read a pose program (one file). Raises PostprocError with file:line:col on bad input.

    ``fast``: lines of a shape seen before are read a chunk at a time (the same targets and
    the same errors as the line-by-line path, which reads everything else)."""
    path, text = files[0], texts[0]
    rows = _Rows(path, text)
    # lines end at "\n" only, as diagnostics.line_col counts them: str.splitlines would also
    # split at \x0b, \x0c, \x1c-\x1e and \x85 (NEL), which latin-1 text can hold
    starts = _line_starts(text) if fast and len(text) > _FAST_MIN_CHARS else None
    if starts is None:
        offset = 0
        for lineno, raw in enumerate(text.split("\n"), start=1):
            raw = raw + "\n" if offset + len(raw) < len(text) else raw
            rows.line(lineno, raw, offset)
            offset += len(raw)
    else:
        nlines = len(starts)
        i = min(_FAST_LEARN, nlines)
        rows.lines(0, i, starts)
        fast_shapes, regex = None, None
        while i < nlines:
            shapes = rows.fast_shapes() if rows.columns is not None else []
            if [s for s, _ in shapes] != fast_shapes:
                fast_shapes, regex = [s for s, _ in shapes], _FastShapes(shapes) if shapes else None
            j = int(np.searchsorted(starts, starts[i] + _FAST_CHUNK, "left"))
            j = min(max(j, i + 1), nlines)
            if regex is None:
                rows.lines(i, j, starts)
            else:
                rows.chunk(i, j, starts, regex)
            i = j
    if rows.columns is None:
        raise PostprocError("no poses in this file (empty, or comments only)", path, 1, 1, P105)
    targets = rows.targets() if _lowered else _analysed(files, texts, rows.targets())
    stamps = rows.stamps
    stated = rows.frame
    return Program(
        files=list(files[:1]),
        texts=list(texts[:1]),
        targets=targets,
        frames=[Frame(np.eye(4), None, {True: "controller base", False: "model frame"}.get(stated, "robot base"))],
        dialect="poses",
        in_controller_base=stated,
        stamps=stamps,
        newlines=[newline(text)],
        comment="#",
    )


def _analysed(files: list[str], texts: list[str], read: Targets) -> Targets:
    """The rows read, lowered to the motion IR and through the analysis as every dialect's
    targets are: a pose list is visited row after row (``Targets.prev``)."""
    from .analysis import analyse

    unit, dialect = _unit(files, texts, read)
    built = analyse(unit, dialect)
    targets = built.targets
    targets.joints = read.joints
    targets.load, targets.load_cause = read.load, read.load_cause
    return targets


def lower(files: list[str], texts: list[str]):
    """(the motion IR of a pose list, its Dialect): ``programs.lower``."""
    return _unit(files, texts, read(files, texts, _lowered=True).targets)


def _unit(files: list[str], texts: list[str], read: Targets):
    """One routine: a MoveRun of the rows, in the robot base, with the model's tool."""
    from .ir import Loc, MoveRun, Routine, Unit

    n = len(read)
    spans = np.concatenate([read.spans.reshape(n, 6), read.abc_spans.reshape(n, 6)], axis=1)
    run = MoveRun(dict(pose=read.poses, written=~np.isnan(read.poses), spans=spans, file=read.file, line=read.line,
                       col=read.col, motion=read.motion, chain=np.ones(n, bool), config=read.config))
    unit = Unit("poses", list(files[:1]), list(texts[:1]))
    unit.routines["ROWS"] = Routine("ROWS", (), [run], Loc(0, 1, 1))
    unit.entries = ["ROWS"]
    return unit, _PoseList()


def _pose_list_dialect():
    from .analysis import Dialect

    class PoseList(Dialect):
        """A pose list: rows in the robot base (the frame its ``# frame:`` line states), the
        model's tool, nothing written between them."""

        name = "POSES"

    return PoseList()


def _PoseList():
    return _pose_list_dialect()

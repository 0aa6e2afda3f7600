"""Generic pose programs: a CSV with a header naming at least x,y,z (and a,b,c), or
whitespace-separated ``x y z [a b c]`` lines with no header.

Every row is a Cartesian target in the robot base frame. Optional columns ``s,t`` (Status
and Turn, integers; empty = not stated) give the arm configuration and ``q1..q6`` the joint
angles (deg) the controller uses, passed to the model as they are. Other columns, comment lines
(``#``, ``;``, ``//``) and blank lines are kept as they are. The syntax of a record is
``grammars/poses.lark``; each distinct line shape (numbers abstracted) is parsed once and
reused, so a million rows cost one regex pass, not a million parses.
"""
from __future__ import annotations

import functools
import math
import re

import numpy as np
from lark import Lark, UnexpectedInput

from ..diagnostics import P101, P103, P104, P105, PostprocError
from ..resources import grammar_path
from . import MOTIONS, STAMP_PREFIX, Frame, Program, TargetsBuilder

COLUMNS = ("x", "y", "z", "a", "b", "c")
CONFIG = ("s", "t")
JOINTS = ("q1", "q2", "q3", "q4", "q5", "q6")
_OPTIONAL = CONFIG + JOINTS
_ALL = COLUMNS + _OPTIONAL
_COMMENT = re.compile(r"[ \t]*(#|;|//)")
_ROW_MOTION = MOTIONS.index("row")


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


def _newline(text: str) -> str:
    crlf = text.count("\r\n")
    return "\r\n" if crlf and crlf >= text.count("\n") - crlf else "\n"


def _header(body: str, path: str, lineno: int, lead: int) -> tuple[dict[str, int], int]:
    """The header line: column name → field index, and the number of fields."""
    fields = _fields(body, path, lineno, lead)
    names = [str(tok).lower() if kind == "word" else "" for kind, tok in fields]
    missing = [c for c in COLUMNS[:3] if c not in names]
    if missing:
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


def _add_extras(targets, extras: list, columns: dict[str, int]) -> None:
    """The rows' s, t (-1: not stated) and q1..q6 onto ``targets``, for the columns the header names."""
    table = np.array(extras, float).reshape(len(targets), len(_OPTIONAL))
    if any(c in columns for c in CONFIG):
        targets.config = np.where(np.isnan(table[:, :2]), -1, table[:, :2]).astype(np.int16)
    if any(c in columns for c in JOINTS):
        targets.joints = table[:, 2:]


def read(files: list[str], texts: list[str]) -> Program:
    """Read a pose program (one file). Raises PostprocError with file:line:col on bad input."""
    path, text = files[0], texts[0]
    number = _number_re()
    builder = TargetsBuilder()
    stamps: dict[int, str] = {}
    columns: dict[str, int] | None = None  # column name → field index
    width = 0
    shapes: dict[str, tuple] = {}  # line shape → ordinal of each x..c among the line's numbers
    offset = 0
    abc_spans: list = []  # where each row's A, B, C numbers stand
    extras: list | None = None  # s, t, q1..q6 of each row when the header names any of them
    # lines end at "\n" only, as diagnostics.line_col counts them: str.splitlines would also
    # split at \x0b, \x0c, \x1c-\x1e and \x85 (NEL), which latin-1 text can hold
    for lineno, raw in enumerate(text.split("\n"), start=1):
        raw = raw + "\n" if offset + len(raw) < len(text) else raw
        start = offset
        offset += len(raw)
        line = raw.rstrip("\r\n")
        body = line.strip()
        if not body:
            continue
        if _COMMENT.match(line):
            if STAMP_PREFIX in line:
                stamps[0] = body
            continue
        lead = len(line) - len(line.lstrip())
        if columns is None and any(ch.isalpha() for ch in number.sub("", body)):
            columns, width = _header(body, path, lineno, lead)
            if any(c in columns for c in _OPTIONAL):
                extras = []
            continue
        shape = number.sub("0", body)
        ordinals = shapes.get(shape)
        if ordinals is None:
            ordinals, columns, width = _shape(body, columns, width, path, lineno, lead)
            shapes[shape] = ordinals
        matches = list(number.finditer(line))
        if extras is not None:
            extras.append(_extras(matches, ordinals, path, lineno))
        pose, spans, abc = _pose(matches, ordinals, start, path, lineno)
        abc_spans.append(abc)
        builder.add(pose, spans, 0, lineno, lead + 1, 0, _ROW_MOTION)
    if columns is None:
        raise PostprocError("no poses in this file (empty, or comments only)", path, 1, 1, P105)
    targets = builder.build()
    targets.abc_spans = np.array(abc_spans, dtype=np.int64).reshape(len(targets), 3, 2)
    if extras is not None:
        _add_extras(targets, extras, columns)
    return Program(
        files=list(files[:1]),
        texts=list(texts[:1]),
        targets=targets,
        frames=[Frame(np.eye(4), None, "robot base")],
        dialect="poses",
        stamps=stamps,
        newlines=[_newline(text)],
        comment="#",
    )

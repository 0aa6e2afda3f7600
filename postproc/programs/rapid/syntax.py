"""RAPID text → units → shapes (the syntax of ``grammars/rapid.lark``).

A module is cut into *units*: a statement up to its ``;``, or a line that opens or closes a
block (``MODULE``, ``PROC``, ``IF … THEN``, ``ENDIF``, a label …), with ``!`` comments and the
insides of strings blanked out (same length: offsets stay those of the file). Each distinct
unit *shape* — numbers → ``0``, the digits ending a name → ``0``, blanks collapsed — is parsed
once; the tree of a shape holds for every unit of that shape, whose names, numbers and
strings are read from the unit's own text by their ordinals (``Shape.ordinal_at``).
"""
from __future__ import annotations

import re
from bisect import bisect_right

import numpy as np
from lark import Token, Tree
from lark.exceptions import UnexpectedInput

from ...core.diagnostics import P101, LineIndex, PostprocError, line_col
from ..grammar import TOKEN_RE, exact_key, lalr_parser, shape_key, unexpected

__all__ = ["parser", "Shape", "Exact", "Source", "scan", "misread", "TOKEN_RE", "STRING_RE"]

# strings, comments, and a quote that opens no string on its line
_HIDE = re.compile(r'"[^"\n]*"|!.*|"')
STRING_RE = re.compile(r'"[^"\n]*"')
_BLOCK_WORDS = {"MODULE", "ENDMODULE", "PROC", "ENDPROC", "FUNC", "ENDFUNC", "TRAP", "ENDTRAP", "LOCAL",
                "IF", "ELSEIF", "ELSE", "ENDIF", "FOR", "ENDFOR", "WHILE", "ENDWHILE", "TEST", "CASE",
                "DEFAULT", "ENDTEST", "ERROR", "UNDO", "BACKWARD", "RECORD", "ENDRECORD"}
_FIRST_WORD = re.compile(r"[ \t]*([A-Za-z_]\w*)", re.ASCII)
# a compound statement's head followed on its line by a statement (IF x THEN MoveL …;): the head
# ends after its THEN, DO, ELSE or a CASE's ':'
_THEN = re.compile(r"\bTHEN\b", re.I | re.A)
_DO = re.compile(r"\bDO\b", re.I | re.A)
_CASE = re.compile(r":(?!=)")
_HEAD_END = {"IF": _THEN, "ELSEIF": _THEN, "WHILE": _DO, "FOR": _DO, "ELSE": re.compile(r"\bELSE\b", re.I | re.A),
             "CASE": _CASE, "DEFAULT": _CASE}
_CONDITIONS = {"IF", "ELSEIF", "WHILE", "FOR"}
_LABEL_HEAD = re.compile(r"[ \t]*[A-Za-z_]\w*[ \t]*:(?!=)")  # (a label with a statement after it on its line)
_PLACEHOLDER = re.compile(r"[ \t]*<[A-Z]{2,5}>[ \t\r]*$")  # (RobotStudio's <SMT> on a line of its own)
_LABEL = re.compile(r"[ \t]*[A-Za-z_]\w*[ \t]*:[ \t\r]*$", re.ASCII)  # (\r: a CRLF file's line)
# a UTF-8 byte order mark at the start of a file (as latin-1 reads its bytes, or decoded)
BOMS = ("\xef\xbb\xbf", "\ufeff")


def parser():
    """The LALR parser of ``grammars/rapid.lark`` (built once, cached on disk by lark)."""
    return lalr_parser("rapid.lark", "unit")


class Shape:
    """One unit shape: its tree, the ordinal of each name/number token by its position in the
    shape (``ordinal_at``), the ordinal of each string (``string_at``)."""

    __slots__ = ("tree", "kind", "ordinal_at", "string_at", "text", "bad")

    def __init__(self, text: str, tree):
        self.text = text
        self.tree = tree
        self.kind = tree.data if isinstance(tree, Tree) else ""
        words = {m.start(): m.end() for m in TOKEN_RE.finditer(text)}
        self.ordinal_at = {start: k for k, start in enumerate(words)}
        self.string_at = {m.start(): k for k, m in enumerate(STRING_RE.finditer(text))}
        # a name or number of the tree that is not one token of the text (a keyword run into a
        # name: ``PERSata``): the shape position of the first, None for none
        self.bad = None
        if isinstance(tree, Tree):
            for t in tree.scan_values(lambda v: isinstance(v, Token)):
                if t and (t[0].isalnum() or t[0] in "_.") and words.get(t.start_pos) != t.start_pos + len(t):
                    self.bad = t.start_pos
                    break


class Exact:
    """The units of one exact key (their text with numbers → 0: the same names): their shape,
    and what the lowering made of them once (``template``: the fast path of inline motions;
    None not looked at yet, False none)."""

    __slots__ = ("shape", "template")

    def __init__(self, shape: Shape):
        self.shape = shape
        self.template = None


class Source:
    """One file read: ``fi`` its index (negative: a --config module), its path and text, the
    text with comments and strings blanked (``code``), and its units ``(start, end, Exact)``."""

    def __init__(self, fi: int, path: str, text: str):
        self.fi, self.path, self.text = fi, path, text
        self.code = ""
        self.units: list = []
        self.lines = LineIndex(text)
        self._starts = None
        # (a byte order mark is no column of the first line)
        self.bom = next((len(b) for b in BOMS if text.startswith(b)), 0)

    def locate(self, offset: int) -> tuple[int, int]:
        """1-based (line, col) of an offset (a bisection of the line starts, found once)."""
        starts = self._starts
        if starts is None:
            starts = self._starts = self.lines._line_starts().tolist()
            starts[0] = self.bom
        k = bisect_right(starts, offset) - 1
        return k + 1, offset - starts[k] + 1

    def lines_cols(self, offsets):
        """``locate`` of many offsets: (lines, cols) int32 arrays."""
        line, col = self.lines.lines_cols(offsets)
        if self.bom:
            col = col - np.where(line == 1, self.bom, 0).astype(col.dtype)
        return line, col


def _blank(code: str, path: str, text: str) -> str:
    """``code`` with comments and the insides of strings blanked, the %%% header of older
    controllers' .prg/.mod and a byte order mark too (P101 for a string not closed on its line)."""
    bad = []

    def hide(m):
        s = m.group()
        if s == '"':
            bad.append(m.start())
            return s
        if s.startswith("!"):
            return " " * len(s)
        return '"' + " " * (len(s) - 2) + '"'

    for bom in BOMS:
        if code.startswith(bom):
            code = " " * len(bom) + code[len(bom):]
    code = _HIDE.sub(hide, code)
    if bad:
        raise PostprocError("string not closed on its line", path, *line_col(text, bad[0]), P101)
    head = re.match(r"\s*%%%[^\n]*\n(?:.*\n)*?\s*%%%[^\n]*", code)
    if head:
        code = re.sub(r"[^\n]", " ", head.group()) + code[head.end():]
    return code


def _units(code: str, path: str, text: str):
    """(start, end) of each unit of ``code``."""
    pending = -1
    offset = 0
    n = len(code)
    while offset < n:
        nl = code.find("\n", offset)
        end = n if nl < 0 else nl
        if pending < 0:
            line = code[offset:end]
            if line.strip():
                word = _FIRST_WORD.match(line)
                first = word.group(1).upper() if word else ""
                start = offset + len(line) - len(line.lstrip())
                if first in _CONDITIONS:
                    # IF/ELSEIF/WHILE/FOR: a head up to its THEN or DO, over lines where the condition
                    # goes on; none before the next ';': a compact IF (IF cond statement;), over lines or not
                    head_end = _HEAD_END[first].search(code, offset)
                    semi = code.find(";", offset)
                    if head_end is not None and (semi < 0 or head_end.start() < semi):
                        yield start, head_end.end()
                        nl = code.find("\n", head_end.end())
                        end = n if nl < 0 else nl
                        if code[head_end.end():end].strip():
                            pending = head_end.end()  # (the statements after it on its line)
                    else:
                        pending = offset
                elif (head_end := _HEAD_END[first].search(line) if first in _HEAD_END else
                      _LABEL_HEAD.match(line) if first not in _BLOCK_WORDS else None) \
                        and line[head_end.end():].strip():
                    yield start, offset + head_end.end()
                    pending = offset + head_end.end()  # (ELSE, CASE …:, DEFAULT: and a statement after it)
                elif ";" not in line and (first in _BLOCK_WORDS or _LABEL.match(line) or _PLACEHOLDER.match(line)):
                    depth = line.count("(") - line.count(")")
                    while depth > 0 and end < n:  # a routine head whose parameters go on over lines
                        nl = code.find("\n", end + 1)
                        more = code[end + 1:n if nl < 0 else nl]
                        depth += more.count("(") - more.count(")")
                        end = n if nl < 0 else nl
                    yield start, start + len(code[start:end].rstrip())
                else:
                    pending = offset
        if pending >= 0:
            semi = code.find(";", max(pending, offset), end)
            while semi >= 0:
                yield pending, semi + 1
                pending = semi + 1
                semi = code.find(";", pending, end)
            rest = code[pending:end]
            if not rest.strip():
                pending = -1
            elif semi < 0 and pending > offset:  # (statements on this line, then ENDIF/ENDFOR/ELSE … after them)
                word = _FIRST_WORD.match(rest)
                if word and word.group(1).upper() in _BLOCK_WORDS:
                    lead = pending + len(rest) - len(rest.lstrip())
                    yield lead, lead + len(rest.strip())
                    pending = -1
        offset = end + 1
    if pending >= 0:
        lead = pending + len(code[pending:]) - len(code[pending:].lstrip())
        raise PostprocError("statement not ended by ';'", path, *line_col(text, lead), P101)


def scan(fi: int, path: str, text: str, shapes: dict, exact: dict) -> Source:
    """Cut ``text`` into units and shape each (``shapes``: shape key → Shape, ``exact``: exact
    key → Exact, caches shared by the files of one read). P101 at a syntax error."""
    src = Source(fi, path, text)
    code = src.code = _blank(text, path, text)
    units = src.units
    for start, end in _units(code, path, text):
        piece = code[start:end]
        key = exact_key(piece)
        entry = exact.get(key)
        if entry is None:
            skey = shape_key(key)
            shape = shapes.get(skey)
            if shape is None:
                try:
                    tree = parser().parse(skey)
                except UnexpectedInput:
                    _syntax_error(src, start, piece)
                shape = shapes[skey] = Shape(skey, tree)
            if shape.bad is not None:
                _syntax_error(src, start, piece, "syntax error: a keyword run into a name")
            entry = Exact(shape)
            if len(exact) < 100_000:
                exact[key] = entry
        units.append((start, end, entry))
    return src


def _syntax_error(src: Source, start: int, unit: str, why: str = "syntax error"):
    """Parse the unit as written to locate the error; raise P101 there."""
    lead = len(unit) - len(unit.lstrip())
    located = unexpected(parser().parse, unit, "end of statement")
    if located is not None:
        pos, found = located
        raise PostprocError(f"syntax error: unexpected {found}", src.path, *src.locate(start + pos), P101)
    raise PostprocError(why, src.path, *src.locate(start + lead), P101)


def misread(src: Source, start: int, end: int, shape: Shape, toks: list):
    """P101 where the unit's names and numbers are not those of its shape (a malformed number:
    ``9E+099E+09``), at the first that differs."""
    words = list(TOKEN_RE.finditer(shape.text))
    for m, w in zip(toks, words):
        if (m.group()[0].isdigit() or m.group()[0] == ".") != (w.group()[0].isdigit() or w.group()[0] == "."):
            raise PostprocError(f"syntax error: a malformed number or name '{m.group()}'", src.path,
                                *src.locate(m.start()), P101)
    at = toks[min(len(toks), len(words)) - 1].start() if toks else start
    raise PostprocError("syntax error: a malformed number", src.path, *src.locate(at), P101)


_ = Token

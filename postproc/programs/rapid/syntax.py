"""RAPID text → units → shapes (the syntax of ``grammars/rapid.lark``).

A module is cut into *units* by position, as the free-form language it is (line breaks are
whitespace): a statement up to its ``;``, or a block's head where its grammar ends it
(``MODULE m (…)``, ``PROC p(…)`` over lines or not, ``IF … THEN``, ``WHILE … DO``, ``CASE …:``,
``ELSE``, ``ENDIF``, a label, RobotStudio's ``<SMT>`` …: ``_head_end``), with ``!`` comments and
the insides of strings blanked out (same length: offsets stay those of the file). Each distinct
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
# the words that end a head where it is written: THEN, DO, a CASE's ':'
_THEN = re.compile(r"\bTHEN\b", re.I | re.A)
_DO = re.compile(r"\bDO\b", re.I | re.A)
_CASE = re.compile(r":(?!=)")
_CASE_WORD = re.compile(r"\b(?:CASE|DEFAULT)\b", re.I | re.A)
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


# ---- the free-form unit cutter (issue 36): a unit is a statement up to its ';' or a block's head
_WORD = re.compile(r"[A-Za-z_]\w*", re.ASCII)
_SPACE = re.compile(r"\s*")
_ALONE = {"ELSE", "ENDIF", "ENDFOR", "ENDWHILE", "ENDTEST", "ENDPROC", "ENDFUNC", "ENDTRAP", "ENDMODULE",
          "ENDRECORD", "UNDO", "BACKWARD"}
_NAMED = {"TRAP", "RECORD"}  # (the head: the word and the name after it)
_UNTIL = {"IF": _THEN, "ELSEIF": _THEN, "WHILE": _DO, "FOR": _DO}
_LABEL_AT = re.compile(r"([A-Za-z_]\w*)[ \t]*:(?!=)", re.ASCII)
_PLACEHOLDER_AT = re.compile(r"<[A-Z]{2,5}>")


def _after_parens(code: str, at: int) -> int | None:
    """The end of the parenthesised list opening at ``at`` (over lines), None where it does not close."""
    depth = 0
    for k in range(at, len(code)):
        ch = code[k]
        if ch == "(":
            depth += 1
        elif ch == ")":
            depth -= 1
            if depth == 0:
                return k + 1
        elif ch == ";":
            return None
    return None


def _head_end(code: str, at: int) -> int | None:
    """Where the block head starting at ``at`` ends (MODULE m, PROC p(…), IF … THEN, ELSE, CASE …:,
    a label, RobotStudio's <SMT> …), None where a statement starts there."""
    if code.startswith("<", at):
        m = _PLACEHOLDER_AT.match(code, at)
        return m.end() if m else None
    word = _WORD.match(code, at)
    if word is None:
        return None
    w, end = word.group().upper(), word.end()
    if w == "LOCAL":
        nxt = _WORD.match(code, _SPACE.match(code, end).end())
        if nxt is None or nxt.group().upper() not in ("PROC", "FUNC", "TRAP", "RECORD"):
            return None  # (LOCAL CONST …: a declaration)
        return _head_end(code, nxt.start())
    if w in _ALONE:
        return end
    if w in _UNTIL:
        semi = code.find(";", end)
        m = _UNTIL[w].search(code, end, len(code) if semi < 0 else semi)
        return m.end() if m else None  # (no THEN before the ';': a compact IF, a statement)
    if w in ("CASE", "DEFAULT"):
        m = _CASE.search(code, end)
        return m.end() if m else None
    if w == "TEST":  # (TEST and its expression: to its first CASE/DEFAULT or the end of its line)
        nl = code.find("\n", end)
        stop = len(code) if nl < 0 else nl
        case = _CASE_WORD.search(code, end, stop)
        return len(code[:case.start() if case else stop].rstrip())
    if w in ("PROC", "FUNC"):
        paren = code.find("(", end)
        return None if paren < 0 else _after_parens(code, paren)
    if w in _NAMED or w == "MODULE":
        name = _WORD.match(code, _SPACE.match(code, end).end())
        if name is None:
            return end
        after = _SPACE.match(code, name.end()).end()
        if w == "MODULE" and code.startswith("(", after):
            return _after_parens(code, after) or name.end()
        return name.end()
    if w == "ERROR":
        after = _SPACE.match(code, end).end()
        return (_after_parens(code, after) or end) if code.startswith("(", after) else end
    m = _LABEL_AT.match(code, at)
    if m and m.group(1).upper() not in _BLOCK_WORDS:
        return m.end()
    return None


def _units(code: str, path: str, src: "Source"):
    """(start, end) of each unit of ``code`` (comments and strings blanked): the text is free-form,
    line breaks are whitespace — a head ends where its grammar says (THEN, DO, ':', ')', its name),
    a statement at its ';'."""
    n = len(code)
    at = _SPACE.match(code, 0).end()
    while at < n:
        end = _head_end(code, at)
        if end is None:
            semi = code.find(";", at)
            if semi < 0:
                raise PostprocError("statement not ended by ';'", path, *src.locate(at), P101)
            end = semi + 1
        yield at, end
        at = _SPACE.match(code, end).end()


def scan(fi: int, path: str, text: str, shapes: dict, exact: dict) -> Source:
    """Cut ``text`` into units and shape each (``shapes``: shape key → Shape, ``exact``: exact
    key → Exact, caches shared by the files of one read). P101 at a syntax error."""
    src = Source(fi, path, text)
    code = src.code = _blank(text, path, text)
    units = src.units
    for start, end in _units(code, path, src):
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

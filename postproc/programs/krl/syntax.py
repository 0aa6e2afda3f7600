"""The KRL grammar's parser, its number token and the wording of syntax errors."""
from __future__ import annotations

import re

from lark import Lark
from lark.exceptions import UnexpectedCharacters, UnexpectedToken

from ...core.diagnostics import P101, PostprocError
from ...core.resources import grammar_path

# A number token: what the grammar's NUMBER matches (same look-arounds), so that the k-th
# match of a line is the k-th NUMBER the parser sees (or a digit string inside a comment
# or a string, which no rule ever reads as a value).
_NUM = r"(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


NUMBER_RE = re.compile(r"(?<![\w$.])" + _NUM + r"(?![\w.])")


# The shape placeholders: number tokens (group 1) and the digits ending a name (XP12 → XP0;
# in P[3] the 3 is a number): lines that differ only there share one parse. The component
# names A1…A6 / E1…E6 stay as written (one letter + digits): they tell axis from Cartesian.
_NAME_DIGITS = r"(?:(?<=[^\W\d])|(?<=\$))(?<!(?<![\w$])[AaEe])\d+(?![\w$])"


SHAPE_RE = re.compile(r"(?<![\w$.])(" + _NUM + r")(?![\w.])|" + _NAME_DIGITS)


_PLACEHOLDER = "0"


# A shape where a number's mantissa and exponent sign stand before a placeholder: the line
# held an exponent that is not a whole number (``1.5E+3.0``): no number token matches it
# whole, but its tail does (``3.0``), so the line reads as another number unless refused.
_MALFORMED = re.compile(r"(?<![\w$.])(?:\d+\.?\d*|\.\d+)[eE][-+]" + _PLACEHOLDER + r"(?![\w$])")
# what a malformed number looks like in the line, for the message
_BAD_NUMBER = re.compile(r"[-+]?[\d.](?:[\w.]|(?<=[eE])[-+])*")


class MalformedNumber(Exception):
    """A shape with a malformed number at ``pos`` (its start in the shape)."""

    def __init__(self, pos: int):
        super().__init__(pos)
        self.pos = pos


_BLANK = re.compile(r"\s*")


_FOLD = re.compile(r"^\s*;\s*(END)?FOLD\b", re.I)


_PARSER = None


def parser():
    """The LALR parser of ``grammars/krl.lark`` (built once, cached on disk by lark)."""
    global _PARSER
    if _PARSER is None:
        _PARSER = Lark(
            grammar_path("krl.lark").read_text(),
            parser="lalr",
            lexer="contextual",
            start="line",
            cache=True,
        )
    return _PARSER


_SHOWN = {
    "COMMA": "','", "RBRACE": "'}'", "LBRACE": "'{'", "LPAR": "'('", "RPAR": "')'",
    "LSQB": "'['", "RSQB": "']'", "COLON": "':'", "EQUAL": "'='", "DOT": "'.'",
    "NUMBER": "a number", "NAME": "a name", "STRING": "a string", "$END": "end of line",
    "ENUM": "a #value", "APPROX": "C_PTP/C_DIS/C_VEL/C_ORI/C_SPL", "MOVE": "a motion",
    "COMP_OP": "a comparison", "ADD_OP": "'+' or '-'", "BITS": "a bit literal",
    "VALUE": "a value ({…}, a name or a number)", "IMPORT_PATH": "a path /R1/MODULE..NAME",
}


_OPERATORS = {"ADD_OP", "MUL_OP", "AND_OP", "OR_OP", "EXOR_OP", "COMP_OP", "COLON", "DOT",
              "LSQB", "LPAR", "COMMENT", "NOT_OP", "BITS", "STRING", "ENUM"}


class SyntaxErrors:
    """The KRL grammar's parser, its number token and the wording of syntax errors. (methods of the Reader)"""

    def syntax_error(self, exc):
        shape = self.sh.text
        if isinstance(exc, MalformedNumber):
            bad = _BAD_NUMBER.match(self.lt, self.abs_pos(exc.pos) - self.la)
            raise PostprocError(f"syntax error: malformed number '{bad.group()}'", self.path, self.ln,
                                self.col(exc.pos), P101)
        if isinstance(exc, UnexpectedToken) and exc.token.type != "$END":
            pos = exc.token.start_pos
            found = self.text[self.abs_pos(pos): self.abs_pos(exc.token.end_pos)] \
                if exc.token.type != "NUMBER" else self.text[slice(*self.nums()[self.sh.phidx[pos]])]
            found = f"'{found}'"
        elif isinstance(exc, UnexpectedCharacters):
            pos = exc.pos_in_stream
            rest = self.lt[self.abs_pos(pos) - self.la:]
            bad = _BAD_NUMBER.match(rest)
            if bad:
                raise PostprocError(f"syntax error: malformed number '{bad.group()}'", self.path, self.ln,
                                    self.col(pos), P101)
            found = f"'{rest[:1]}'"
        else:
            pos = len(shape.rstrip())
            found = "end of line"
        if isinstance(exc, UnexpectedToken) and exc.token.type == "COMMENT":
            found = "';' (a comment)"
        expected = set(getattr(exc, "expected", None) or getattr(exc, "allowed", None) or [])
        if "COMMENT" in expected:  # a comment may end any statement: say "end of line" once
            expected = (expected - {"COMMENT"}) | {"$END"}
        if {"NUMBER", "NAME", "LBRACE"} <= expected:  # anything that starts an expression
            expected = (expected - {"NUMBER", "NAME", "LBRACE", "STRING", "ENUM", "BITS", "LPAR", "ADD_OP",
                                    "NOT_OP"}) | {"VALUE"}
        shown = sorted(e for e in expected if e not in _OPERATORS) or sorted(expected)
        depth = 0
        for ch in shape[:pos]:
            depth += (ch == "{") - (ch == "}")
        where = " in aggregate" if depth > 0 else ""
        if shown and len(shown) <= 5:
            names = [_SHOWN.get(e, e) for e in shown]
            exp = ", ".join(names[:-1]) + (" or " if len(names) > 1 else "") + names[-1]
            msg = f"expected {exp}{where}, found {found}"
        else:
            msg = f"unexpected {found}{where}"
        raise PostprocError(f"syntax error: {msg}", self.path, self.ln, self.col(pos), P101)


class Number:
    """A number token of the line: its value and its span in the file (sign included)."""

    __slots__ = ("value", "start", "end")

    def __init__(self, value: float, start: int, end: int):
        self.value = value
        self.start = start
        self.end = end

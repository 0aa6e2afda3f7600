"""The dialects' lark parsers: one LALR parser per grammar file of ``grammars/`` and start rule,
built once per process (lark also caches it on disk: ``cache=True``)."""
from __future__ import annotations

import re
from functools import lru_cache

from lark import Lark

from ..core.resources import grammar_path

# a number as the line-based dialects (RAPID, URScript) write it, unsigned (a sign is an operator)
NUM = r"(?<![\w.])(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?![\w.])"
# the tokens a unit's shape keeps the order of: names (keywords too) and numbers
TOKEN_RE = re.compile(r"[A-Za-z_]\w*|" + NUM, re.ASCII)
NUM_RE = re.compile(NUM, re.ASCII)
_NAME_DIGITS = re.compile(r"(?<=[A-Za-z_])\d+(?!\w)", re.ASCII)
BLANKS = re.compile(r"\s+")


def exact_key(unit: str) -> str:
    """A statement's key with its numbers as 0 and its blanks as one space: units that differ
    only in their numbers share one parse."""
    return BLANKS.sub(" ", NUM_RE.sub("0", unit)).strip()


def shape_key(exact: str) -> str:
    """``exact_key`` with the digits that end names as 0 too (``p12`` → ``p0``): units that
    differ only in their numbers and numbered names share one shape."""
    return _NAME_DIGITS.sub("0", exact)


@lru_cache(maxsize=None)
def lalr_parser(grammar: str, start: str) -> Lark:
    """The LALR parser (contextual lexer) of ``grammars/<grammar>`` starting at ``start``."""
    return Lark(grammar_path(grammar).read_text(), parser="lalr", lexer="contextual", start=start, cache=True)


def unexpected(parse, text: str, end: str = "end of line") -> tuple[int, str] | None:
    """Parse ``text`` as written to locate a syntax error: (offset in ``text``, what was found
    there, e.g. ``"'}'"`` or ``end``) from lark's error, or None where it parses."""
    from lark.exceptions import (
        UnexpectedCharacters,
        UnexpectedEOF,
        UnexpectedInput,
        UnexpectedToken,
    )

    try:
        parse(text)
    except UnexpectedInput as exc:
        pos = getattr(exc, "pos_in_stream", None)
        if isinstance(exc, UnexpectedEOF) or pos is None or pos < 0:
            pos = len(text.rstrip())
        if isinstance(exc, UnexpectedToken):
            found = f"'{exc.token}'" if exc.token.type != "$END" else end
        elif isinstance(exc, UnexpectedCharacters):
            found = repr(text[pos])
        else:
            found = end
        return pos, found
    return None


def first_ordinal(node, ordinal_at: dict[int, int], types: tuple[str, ...] | None = None) -> int:
    """The smallest ordinal (``ordinal_at``: a token's start → its number in the line) of the
    tokens below ``node`` (of ``types`` only, if given), -1 if none: where a value starts."""
    from lark import Token

    if isinstance(node, Token):
        return ordinal_at.get(node.start_pos, -1) if types is None or node.type in types else -1
    found = [k for k in (first_ordinal(c, ordinal_at, types) for c in node.children if c is not None) if k >= 0]
    return min(found, default=-1)

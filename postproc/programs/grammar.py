"""The dialects' lark parsers: one LALR parser per grammar file of ``grammars/`` and start rule,
built once per process (lark also caches it on disk: ``cache=True``)."""
from __future__ import annotations

from functools import lru_cache

from lark import Lark

from ..resources import grammar_path


@lru_cache(maxsize=None)
def lalr_parser(grammar: str, start: str) -> Lark:
    """The LALR parser (contextual lexer) of ``grammars/<grammar>`` starting at ``start``."""
    return Lark(grammar_path(grammar).read_text(), parser="lalr", lexer="contextual", start=start, cache=True)

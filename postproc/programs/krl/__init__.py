"""KUKA KRL reader: the texts of a module (.src, its .dat, optionally $config.dat) → Program.

Syntax lives in ``grammars/krl.lark`` (one statement per physical line, as KRL has it).
Speed comes from parsing each distinct line *shape* once: a line with every number token
and every digit run ending a name (``XP12``, ``FP3``) replaced by ``0`` (``SHAPE_RE``).
Whatever the parse of a shape tells (the statement, which of its numbers are a target's
X…C) holds for every line of that shape, so the numbers and names of the line are all that
is left to read. Target lines of frequent shapes are then read
without a Python loop: one regex built from those shapes (``_Accel``) pulls the numbers of
a whole chunk of text at once and numpy turns them into poses and spans. Everything else
(declarations, frames, block structure, motions to names) goes line by line through the
interpreter (``reader.Reader``), in textual order.

Semantics (tests/test_krl.py shows each on a small program):

* a Target is a Cartesian motion target (inline POS/E6POS/FRAME aggregate or the
  aggregate a position variable was given: its .dat declaration or an assignment);
  axis targets, frames, comments and strings are never targets;
* the frame of a target is INV_POS($ROBROOT):$BASE (and the left operands of ``:``),
  tracked through each DEF, branches and loops merged (``flow``); unresolvable → frame -1
  + warning P201 (P203 the tool); not set before the target and not stated by the user
  (``ActiveFrames``: ``--base`` / ``--tool``) → -1 + P220 / P221;
* a partial inline aggregate takes its missing components from the preceding Cartesian
  motion target (same DEF, same frame), NaN where none is known (also after control flow
  that moves).

Modules (one concept each; the ``Reader`` class in ``reader`` combines their methods):
``syntax`` (parser, number token, syntax-error wording), ``values`` (numbers, aggregates,
variables), ``scopes`` (declarations, lookup), ``frames`` ($BASE/$TOOL/$ROBROOT), ``blocks``
(block structure, folds), ``flow`` (branches and loops), ``calls`` (callees, functions,
the sandbox), ``statements`` (assignments, calls, motions), ``fast_path`` (shape
cache, accelerated regex), ``assemble`` (rows → Targets), ``reader`` (the loop).
"""
from __future__ import annotations

from .reader import read
from .syntax import NUMBER_RE, SHAPE_RE, parser

__all__ = ["read", "NUMBER_RE", "SHAPE_RE", "parser"]

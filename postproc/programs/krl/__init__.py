"""KUKA KRL reader: the texts of a module (.src, its .dat, optionally $config.dat) → Program.

Syntax lives in ``grammars/krl.lark`` (one statement per physical line, as KRL has it).
Speed comes from parsing each distinct line *shape* once: a line with every number token
and every digit run ending a name (``XP12``, ``FP3``) replaced by ``0`` (``SHAPE_RE``).
Whatever the parse of a shape tells holds for every line of that shape. Runs of motion lines
to literal aggregates of frequent shapes are read without a Python loop (``fast_path``: one
regex per chunk, numpy) and become one ``ir.MoveRun``; every other statement is lowered to the
motion IR (``lower``) and the one analysis (``programs.analysis``) runs the unit as the
controller would — calls with IN/OUT parameters, branches joined, loops to a fixed point or
unrolled, GOTOs, interrupts and triggers — with KRL's meaning of frames, tools, positions and
system routines (``semantics``: the ``KRL`` Dialect).

Semantics (tests/test_krl*.py and tests/test_execution.py show each on a small program):

* a target is a Cartesian motion target (an inline POS/E6POS/FRAME aggregate or a position
  variable's value where the motion runs), one row per executed motion, in execution order
  (``Targets.prev``); axis targets, frames, comments and strings are never targets (an axis
  target to known values is where the next target's arm configuration starts:
  ``Targets.start``);
* the frame of a target is INV_POS($ROBROOT):$BASE (and the left operands of ``:``) where the
  motion runs; not known → frame -1 + warning P201 (P203 the tool); not set before the target
  and not stated by the user (``ActiveFrames``: ``--base`` / ``--tool``) → -1 + P220 / P221;
* a partial inline aggregate takes its missing components from where the robot stands (the
  command before it), NaN where that is not known here.

Modules: ``syntax`` (parser, number token, syntax-error wording), ``blocks`` (block
structure, folds), ``fast_path`` (shape cache, accelerated regex → MoveRun), ``lower``
(statements → IR), ``semantics`` (the KRL Dialect), ``machine`` (a backup's machine data:
$ROBROOT, a track, $ABS_ACCUR), ``reader`` (``read`` / ``lower``: files → IR → analysis →
Program).
"""
from __future__ import annotations

from .reader import read
from .syntax import NUMBER_RE, SHAPE_RE, parser

__all__ = ["read", "NUMBER_RE", "SHAPE_RE", "parser"]

"""Robot programs: text → motion IR → one analysis → :class:`Program` → text.

Each dialect turns the texts of a program into the motion IR; the one dataflow analysis runs it
as the controller would (frames, tool, configuration, execution order) and gives a
:class:`Program`: the untouched texts of its files and, for every executed Cartesian target,
where its numbers stand in those texts and in which frame it was programmed. Targets are kept
as columns (numpy arrays), not one object per target: CAM programs have 10^6 of them. Nothing
here knows about models.

Modules, in their import order (tests/test_structure.py):

* ``model`` (Program, Targets, Frame, ActiveFrames), ``text`` (decoding, newlines), ``grammar``
  (the lark parsers), ``ir`` (the motion IR), ``rewrite`` (numbers → text, the stamp,
  partial aggregates filled);
* ``analysis/`` — the one sound dataflow analysis over the IR (values joined at merges);
* the dialects, each independent of the others: ``krl/``, ``rapid/``, ``urscript/``,
  ``fanuc/``, ``poses``;
* ``io`` (the dialect of a file, reading one program from disk or text, the input guards),
  ``cell`` (a KRL cell or backup read as one unit), ``base_poses`` (targets in the robot base),
  ``locate`` (where a row stands, located findings) — with this face, the only modules that
  name a dialect;
* ``interpreter`` — the IR run on concrete values: the oracle the analysis is checked against.
"""
from __future__ import annotations

from ..robot.conventions import MOTIONS
from .io import companion_dat, dialect_of, load_program, lower, read_program
from .model import STAMP_PREFIX, ActiveFrames, Frame, Program, RobotRoot, Targets, TargetsBuilder

__all__ = ["ActiveFrames", "RobotRoot", "Frame", "Targets", "TargetsBuilder", "Program", "STAMP_PREFIX", "MOTIONS",
           "read_program", "load_program", "dialect_of", "companion_dat", "lower"]



"""Robot programs as text + the Cartesian targets found in them.

Each dialect module (``krl``, ``poses``) turns the texts of a program into a
:class:`Program`: the untouched texts of its files and, for every Cartesian target, where
its X/Y/Z numbers stand in those texts and in which frame it was programmed. Targets are
kept as columns (numpy arrays), not one object per target: CAM programs have 10^6 of them.
Nothing here knows about models: the compensator and the rewriter work on this.
"""
from __future__ import annotations

from ..robot.conventions import MOTIONS
from .io import companion_dat, dialect_of, load_program, lower, read_program
from .model import STAMP_PREFIX, ActiveFrames, Frame, Program, RobotRoot, Targets, TargetsBuilder

__all__ = ["ActiveFrames", "RobotRoot", "Frame", "Targets", "TargetsBuilder", "Program", "STAMP_PREFIX", "MOTIONS",
           "read_program", "load_program", "dialect_of", "companion_dat", "lower"]



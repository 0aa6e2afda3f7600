"""Robot programs as text + the Cartesian targets found in them.

Each dialect module (``krl``, ``poses``) turns the text of a program into a
:class:`Program`: the untouched texts of its files and, for every Cartesian target,
where its X/Y/Z numbers stand in those texts and in which frame it was programmed.
Nothing here knows about models: the compensator and the rewriter work on this.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..diagnostics import Diagnostic

__all__ = ["Target", "Program", "NumberSpan", "read_program", "dialect_of", "STAMP_PREFIX"]

# The one line postproc adds to a file it compensated (after a comment marker).
STAMP_PREFIX = "postproc: compensated with model"


@dataclass(frozen=True)
class NumberSpan:
    """A number token in one file's text: ``text[start:end]`` is e.g. ``1950.1``."""

    file: str  # key into Program.texts
    start: int
    end: int


@dataclass
class Target:
    """One Cartesian target of a program.

    ``pose`` is X,Y,Z,A,B,C (mm, deg) in the frame the program wrote it in, with any
    components the program left out filled in as the controller would. ``spans`` holds the
    X, Y, Z number tokens (None for a component the aggregate leaves out). ``base`` maps
    that frame to the robot base frame (4×4); None means it could not be resolved
    statically and the target is left as it is.
    """

    file: str
    line: int
    col: int
    pose: np.ndarray
    spans: tuple[NumberSpan | None, NumberSpan | None, NumberSpan | None]
    base: np.ndarray | None = None
    tool: np.ndarray | None = None  # $TOOL frame (6,) when known, for the model's tool check
    motion: str = ""  # e.g. "LIN", "CIRC aux", "SPL", "row"
    name: str = ""  # variable name when the target is a declared variable


@dataclass
class Program:
    """A parsed program: its files' texts (keys are paths or ``<stdin>``) and targets in order."""

    texts: dict[str, str]
    targets: list[Target] = field(default_factory=list)
    diagnostics: list[Diagnostic] = field(default_factory=list)
    dialect: str = ""
    # one text per file as written: the stamp found in it, if any
    stamps: dict[str, str] = field(default_factory=dict)
    newline: dict[str, str] = field(default_factory=dict)  # dominant line ending per file


KRL_SUFFIXES = {".src", ".dat", ".sub"}


def dialect_of(path: str | Path) -> str:
    """'krl' for .src/.dat/.sub, 'poses' for .csv/.txt/.pose(s); ValueError otherwise."""
    suffix = Path(str(path)).suffix.lower()
    if suffix in KRL_SUFFIXES:
        return "krl"
    if suffix in {".csv", ".txt", ".pose", ".poses", ".xyz"}:
        return "poses"
    raise ValueError(f"unknown program type {suffix!r} (expected .src/.dat or .csv/.txt)")


def read_program(texts: dict[str, str], dialect: str, config: dict[str, str] | None = None) -> Program:
    """Parse a program. ``texts`` maps file keys to contents (for KRL: the .src and,
    when there is one, its .dat). ``config`` optionally holds ``$config.dat`` text(s) that
    give BASE_DATA / TOOL_DATA. Raises PostprocError on bad input."""
    if dialect == "krl":
        from . import krl

        return krl.read(texts, config=config)
    if dialect == "poses":
        from . import poses

        return poses.read(texts)
    raise ValueError(f"unknown dialect {dialect!r}")

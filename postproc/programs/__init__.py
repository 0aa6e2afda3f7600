"""Robot programs as text + the Cartesian targets found in them.

Each dialect module (``krl``, ``poses``) turns the texts of a program into a
:class:`Program`: the untouched texts of its files and, for every Cartesian target, where
its X/Y/Z numbers stand in those texts and in which frame it was programmed. Targets are
kept as columns (numpy arrays), not one object per target: CAM programs have 10^6 of them.
Nothing here knows about models: the compensator and the rewriter work on this.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..diagnostics import Diagnostic

__all__ = ["Frame", "Targets", "TargetsBuilder", "Program", "read_program", "dialect_of", "STAMP_PREFIX", "MOTIONS"]

# The one line postproc adds to a file it compensated (after the dialect's comment marker).
STAMP_PREFIX = "postproc: compensated with model"

# Motion kinds, stored per target as an index into this tuple.
MOTIONS = ("LIN", "PTP", "CIRC-aux", "CIRC-end", "SLIN", "SPTP", "SCIRC-aux", "SCIRC-end", "SPL", "row")


@dataclass(frozen=True)
class Frame:
    """The frame a target was programmed in.

    ``base`` maps that frame to the robot base frame (4×4: INV_POS($ROBROOT):$BASE);
    ``tool`` is the active $TOOL as X,Y,Z,A,B,C (None when unknown); ``label`` says where
    they came from, e.g. ``BASE_DATA[3] / TOOL_DATA[1]``.
    """

    base: np.ndarray
    tool: np.ndarray | None = None
    label: str = ""


@dataclass
class Targets:
    """Columns, one row per Cartesian target, in program order.

    poses      [N, 6] float64  X,Y,Z,A,B,C in the target's own frame; NaN = a component
                               the program leaves out and that could not be filled
    spans      [N, 3, 2] int64 (start, end) of the X, Y, Z number tokens in
                               ``Program.texts[file]``; -1 where the component is absent
    file       [N] int32       index into Program.files of the text the numbers stand in
    line, col  [N] int32       1-based location of the target's aggregate (for messages)
    frame      [N] int32       index into Program.frames; -1 = not statically resolvable
    motion     [N] int8        index into MOTIONS
    """

    poses: np.ndarray
    spans: np.ndarray
    file: np.ndarray
    line: np.ndarray
    col: np.ndarray
    frame: np.ndarray
    motion: np.ndarray

    def __len__(self) -> int:
        return len(self.poses)


class TargetsBuilder:
    """Collects targets row by row (plain lists: cheap to append) and builds the columns."""

    def __init__(self) -> None:
        self.poses: list = []  # each a sequence of 6 floats
        self.spans: list = []  # each a sequence of 6 ints (x0, x1, y0, y1, z0, z1)
        self.file: list[int] = []
        self.line: list[int] = []
        self.col: list[int] = []
        self.frame: list[int] = []
        self.motion: list[int] = []

    def add(self, pose, spans, file: int, line: int, col: int, frame: int, motion: int) -> None:
        self.poses.append(pose)
        self.spans.append(spans)
        self.file.append(file)
        self.line.append(line)
        self.col.append(col)
        self.frame.append(frame)
        self.motion.append(motion)

    def __len__(self) -> int:
        return len(self.poses)

    def build(self) -> Targets:
        n = len(self.poses)
        return Targets(
            poses=np.array(self.poses, dtype=np.float64).reshape(n, 6),
            spans=np.array(self.spans, dtype=np.int64).reshape(n, 3, 2),
            file=np.array(self.file, dtype=np.int32),
            line=np.array(self.line, dtype=np.int32),
            col=np.array(self.col, dtype=np.int32),
            frame=np.array(self.frame, dtype=np.int32),
            motion=np.array(self.motion, dtype=np.int8),
        )


@dataclass
class Program:
    """A parsed program: its files (paths or ``<stdin>``), their texts, targets in order."""

    files: list[str]
    texts: list[str]
    targets: Targets
    frames: list[Frame] = field(default_factory=list)
    diagnostics: list[Diagnostic] = field(default_factory=list)
    dialect: str = ""
    stamps: dict[int, str] = field(default_factory=dict)  # file index → stamp line found in it
    newlines: list[str] = field(default_factory=list)  # dominant line ending per file
    comment: str = ";"  # the dialect's comment marker, for the stamp line
    config: list[str] | None = None  # the $config.dat texts it was read with (to read it again)
    from_text: bool = False  # made by read_program: its texts, read again, give it again
    # some targets are variables (declared or assigned aggregates), whose numbers other
    # statements may read too (e.g. as a frame); False: every target is an inline aggregate
    named_targets: bool = True


KRL_SUFFIXES = {".src", ".dat", ".sub"}
POSE_SUFFIXES = {".csv", ".txt", ".pose", ".poses", ".xyz"}
RAPID_SUFFIXES = {".mod", ".prg", ".sys", ".modx"}


def dialect_of(path: str | Path) -> str:
    """'krl' for .src/.dat/.sub, 'poses' for .csv/.txt/.pose(s)/.xyz, 'rapid' for
    .mod/.modx/.prg/.sys; ValueError otherwise."""
    suffix = Path(str(path)).suffix.lower()
    if suffix in KRL_SUFFIXES:
        return "krl"
    if suffix in POSE_SUFFIXES:
        return "poses"
    if suffix in RAPID_SUFFIXES:
        return "rapid"
    raise ValueError(f"unknown program type {suffix!r} (expected .src/.dat, .csv/.txt or .mod/.prg/.sys)")


def read_program(files: list[str], texts: list[str], dialect: str, config: list[str] | None = None) -> Program:
    """Parse a program made of ``files`` (for KRL: the .src first, then its .dat if any)
    with contents ``texts``. ``config`` optionally holds ``$config.dat`` text(s) that give
    BASE_DATA / TOOL_DATA (for RAPID: other modules' tooldata / wobjdata). Raises PostprocError (with file:line:col) on bad input."""
    if dialect == "krl":
        from . import krl

        program = krl.read(files, texts, config=config)
        program.config = list(config) if config else None
        program.from_text = True
        return program
    if dialect == "poses":
        from . import poses

        program = poses.read(files, texts)
        program.from_text = True
        return program
    if dialect == "rapid":
        from . import rapid

        program = rapid.read(files, texts, config=config)
        program.config = list(config) if config else None
        program.from_text = True
        return program
    raise ValueError(f"unknown dialect {dialect!r}")

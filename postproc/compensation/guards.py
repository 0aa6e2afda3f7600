"""The last checks before a compensated program is written, independent of the reader and
the formatter that produced it: a bug in either, or a program whose numbers cannot be
changed one target at a time, becomes a refusal (``PostprocError``), never a wrong program.

* :func:`check_numbers` — the tokens at the targets' spans read as the numbers the reader
  took (a span on the wrong token), and the new tokens as the corrected values (P190);
* :func:`check_round_trip` — the new texts, read again, are the same program with only the
  corrected X/Y/Z (and, with ``--orientation``, the orientation's numbers: A,B,C, RAPID's
  q1..q4, URScript's rx,ry,rz): the same targets in the same frames, every other component
  as it was (P191). This catches what no single edit shows, e.g. a position variable that is both a
  motion target (so it is compensated) and a frame (``$BASE = XP1``, ``XP1:XP2``): changing
  its numbers would move every target programmed in that frame.

And one first check: :func:`check_memory` refuses (P111) a program too large to compensate
in this machine's memory, instead of being killed by the kernel after minutes of work.
"""
from __future__ import annotations

import contextlib
import re

import numpy as np

from ..core.diagnostics import P190, P191, PostprocError
from ..core.frames import ORIENTATION_NAMES
from ..programs import Program
from ..programs.io import read_program
from ..programs.rewrite import ORIENTATION_DECIMALS

__all__ = ["check_numbers", "check_inserted", "check_round_trip", "ROUNDING_MM"]

# New numbers are written with at least three decimals: half a µm of rounding at most.
ROUNDING_MM = 5e-4


def _where(program: Program, row: int) -> tuple[str, int, int]:
    t = program.targets
    return program.files[t.file[row]], int(t.line[row]), int(t.col[row])


def _floats(tokens: list[str]) -> np.ndarray:
    """The numbers the tokens read as (NaN where one does not); blanks after a sign allowed."""
    try:
        return np.fromiter(map(float, tokens), np.float64, len(tokens))
    except ValueError:
        out = np.full(len(tokens), np.nan)
        for i, token in enumerate(tokens):
            with contextlib.suppress(ValueError):
                out[i] = float(token.replace(" ", "").replace("\t", ""))
        return out


def check_numbers(program: Program, owners: np.ndarray, tokens: list[str], values: np.ndarray, rounding: float,
                  what: str, unit: float | None = None) -> None:
    """Refuse (P190) unless every token reads as its value to ``rounding`` (0 for the
    numbers as read; :data:`ROUNDING_MM` for replacements). ``owners`` are the target rows
    the tokens belong to (for the message); ``what`` says what a mismatch means, with a
    ``{}`` for the value. A value is its token × ``unit`` (default the program's: X/Y/Z in
    mm; 1 for the orientation's numbers)."""
    tolerance = rounding + 1e-9 * np.maximum(1.0, np.abs(values))
    read = _floats(tokens)
    unit = program.unit if unit is None else unit
    if unit != 1.0:  # tokens in the file's unit (URScript: metres), values in mm
        read = read * unit
    bad = np.flatnonzero(~(np.abs(read - values) <= tolerance))
    if len(bad):
        i = int(bad[0])
        raise PostprocError(f"refusing to write: the number {tokens[i]!r} {what.format(float(values[i]))} "
                            "(a postproc bug: please report it with this program)", *_where(program, int(owners[i])),
                            P190)


_INSERTED = re.compile(r"[ \t]*,?[ \t]*([XYZxyz])[ \t]*([+-]?[ \t]*[^\s,]+?)[ \t]*,?[ \t]*\Z")  # ('- 0.5': a sign may stand apart)


def check_inserted(program: Program, owners: np.ndarray, pieces: list[str], axes: np.ndarray,
                   values: np.ndarray) -> None:
    """Refuse (P190) unless every component written into a partial aggregate is one
    ``[sep] NAME number [sep]`` with the name of its axis and the number reading as its
    corrected value to :data:`ROUNDING_MM`."""
    numbers = []
    for i, (piece, k) in enumerate(zip(pieces, axes.tolist())):
        m = _INSERTED.match(piece)
        if m is None or m.group(1).upper() != "XYZ"[k]:
            raise PostprocError(f"refusing to write: {piece!r} is not the {'XYZ'[k]} component to insert (a postproc "
                                "bug: please report it with this program)", *_where(program, int(owners[i])), P190)
        numbers.append(m.group(2))
    check_numbers(program, owners, numbers, values, ROUNDING_MM, "does not read back as the corrected {} written in")


def _refuse(program: Program, rows: np.ndarray, message: str) -> PostprocError:
    where = _where(program, int(rows[0])) if len(rows) else (program.files[0], 1, 1)
    return PostprocError(f"refusing to write: {message}", *where, P191)


def _check_frames(program: Program, again: Program) -> None:
    """P191 unless every target of ``again`` (the program read again) is in the same base and
    tool as before (matrices compared, frame indices may differ)."""
    a, b = program.targets, again.targets
    known = a.frame >= 0
    differ = np.flatnonzero(known != (b.frame >= 0))
    if len(differ):
        raise _refuse(program, differ, "the frame of this target is not statically known in the compensated text")
    width = int(b.frame.max(initial=0)) + 1  # (one code per pair of frame indices: a 1-D unique is fast)
    codes = np.unique(a.frame[known].astype(np.int64) * width + b.frame[known])
    for i, j in zip((codes // width).tolist(), (codes % width).tolist()):
        before, after = program.frames[i], again.frames[j]
        same_tool = (before.tool is None) == (after.tool is None) and (
            before.tool is None or np.allclose(before.tool, after.tool, rtol=0.0, atol=1e-9, equal_nan=True))
        if not (same_tool and np.allclose(before.base, after.base, rtol=0.0, atol=1e-9, equal_nan=True)):
            moved = after.base[:3, 3] - before.base[:3, 3] if same_tool else np.subtract(after.tool, before.tool)[:3]
            raise _refuse(program, np.flatnonzero((a.frame == i) & (b.frame == j)),
                          f"compensating moves the {'base' if same_tool else 'tool'} of this target ({before.label}, "
                          f"by {float(np.linalg.norm(moved)):.3f} mm): a position that is compensated as a motion "
                          "target is also used as a frame")


def check_round_trip(program: Program, texts: list[str], rows: np.ndarray, new_xyz: np.ndarray,
                     filled: np.ndarray | None = None, moved: np.ndarray | None = None) -> None:
    """Read ``texts`` (the program's files with the corrected numbers, before the stamp)
    again and refuse (P191) unless they hold the same targets (file, line, motion) in the
    same frames, with ``new_xyz`` [len(rows), 3] at the compensated targets' written X/Y/Z
    (to the rounding of the format; [len(rows), 3 + k] with ``--orientation``: then the
    orientation's k numbers in the program's form too, to their form's rounding) and every
    other written component unchanged (the orientation compared as the numbers written).
    ``filled`` [len(rows), 3]: the X/Y/Z written into partial aggregates; they must now be
    written, with their ``new_xyz``."""
    a = program.targets
    try:
        again = read_program(program.files, texts, program.dialect, config=program.config, active=program.active,
                             **program.read_with)
    except PostprocError as exc:
        raise PostprocError(f"refusing to write: the compensated text does not read again ({exc.message})",
                            exc.path, exc.line, exc.col, P191) from None
    b = again.targets
    if len(a) != len(b):
        first_extra = np.array([min(len(a), len(b))])  # the first target one side lacks
        raise _refuse(program if len(a) > len(b) else again, first_extra,
                      f"the compensated text reads as {len(b)} targets, not {len(a)}")
    for column in ("file", "line", "motion"):
        differ = np.flatnonzero(getattr(a, column) != getattr(b, column))
        if len(differ):
            raise _refuse(program, differ, f"the compensated text reads as other targets ({column} differs)")
    _check_frames(program, again)
    # values: the corrected X/Y/Z (and the orientation's numbers with --orientation: new_xyz
    # [n, 3 + k]) where compensated and written, everything else as it was
    expected = np.concatenate([a.poses[:, :3], a.written_orientation()], axis=1)
    got = np.concatenate([b.poses[:, :3], b.written_orientation()], axis=1)
    names = ("X", "Y", "Z") + ORIENTATION_NAMES[program.orientation]
    expected[rows, :new_xyz.shape[1]] = new_xyz
    if moved is not None and len(moved):
        # (runs at an offset from a point compensated for its own runs, P231: its new numbers + their offset)
        new_of = {(int(a.file[r]), int(a.spans[r, k, 0])): float(new_xyz[i, k])
                  for i, r in enumerate(rows.tolist()) for k in range(3) if a.spans[r, k, 0] >= 0}
        offset = a.offset if a.offset is not None else np.zeros((len(a), 3))
        for r in moved.tolist():
            for k in range(3):
                v = new_of.get((int(a.file[r]), int(a.spans[r, k, 0])))
                if v is not None:
                    expected[r, k] = v + offset[r, k]
    written = np.zeros(expected.shape, bool)
    written[:, :3] = a.spans[:, :, 0] >= 0
    if filled is not None and len(rows):
        written[rows, :3] |= filled
        gained = np.zeros((len(a), 3), bool)
        gained[rows] = filled
        lost = np.flatnonzero((gained & (b.spans[:, :, 0] < 0)).any(axis=1))
        if len(lost):
            raise _refuse(program, lost, "a component written into this partial aggregate does not read again")
    written[:, 3:] = True  # orientation as it was, or rewritten (NaN where unknown, on both sides)
    compensated = np.zeros(len(a), bool)
    compensated[rows] = True
    if moved is not None and len(moved):
        compensated[moved] = True  # (their numbers rewritten: to the rounding too)
    # the rounding of a new number: X/Y/Z in mm, the orientation's in its form's decimals
    rounding = np.full(len(names), ROUNDING_MM)
    rounding[3:] /= ORIENTATION_DECIMALS[program.orientation]
    tolerance = np.where(compensated[:, None], rounding, 0.0) + 1e-9 * np.maximum(1.0, np.abs(expected))
    same = (np.abs(got - expected) <= tolerance) | (np.isnan(got) & np.isnan(expected))
    bad = np.flatnonzero((written & ~same).any(axis=1))
    if len(bad):
        r = int(bad[0])
        k = int(np.flatnonzero(written[r] & ~same[r])[0])
        raise _refuse(program, bad, f"the compensated text reads {names[k]} {got[r, k]!r} at this target, "
                      f"expected {expected[r, k]!r}: its numbers are shared with another target")

"""The model's commands for a selection, streamed on a background thread into the program's numbers."""
from __future__ import annotations

import threading
from typing import Iterator

import numpy as np

from ..core import frames
from ..core.progress import ProgressBar
from ..model.settle import Chain
from ..model.compensator import Compensator
from ..programs import Program
from ..programs.rewrite import ORIENTATION_DECIMALS, check_disjoint, fill_partial, format_many, splice
from .findings import Commands, Selection, model_bases
from .guards import ROUNDING_MM, check_inserted, check_numbers


def _rewrite(program: Program, selection: Selection, stream: "_CommandStream") -> list[str] | None:
    """Every file's text with the selected targets' numbers replaced (None: a chunk failed a
    guard of the model output; command_findings says which)."""
    try:
        return [_rewrite_file(program, index, text, selection.rows, stream) for index, text in enumerate(program.texts)]
    except _Unsafe:
        return None
    except BaseException:
        stream.close()
        raise


def _local_orientation(abc_base: np.ndarray, bases: list, frame_of: np.ndarray, written: np.ndarray,
                       form: str) -> np.ndarray:
    """The numbers (in the program's orientation ``form``) of commanded attitudes in the base,
    in each target's own frame, nearest the numbers as written (``frames.orientation_numbers``)."""
    out = abc_base.copy()
    for f, here in frames.frame_groups(frame_of):
        rot = bases[f][:3, :3]
        if not np.allclose(rot, np.eye(3), atol=1e-12):
            out[here] = frames.abc_from_rotation(rot.T @ frames.rotation_from_abc(abc_base[here]))
    return frames.orientation_numbers(out, written, form)


# Edits are made this many tokens at a time: a million-target program never holds all its
# tokens, their replacements and the pieces of the new text at once (peak memory).
EDIT_CHUNK = 1 << 17


class _Unsafe(Exception):
    """A chunk's commands fail a guard: stop rewriting, the caller's guards raise the error."""


class _CommandStream:
    """``model.command_chunks`` on a background thread (onnxruntime releases the GIL): the
    commands and the corrected numbers in each target's own frame, filled in row order, so
    the rewrite of the first targets overlaps the model run on the later ones."""

    def __init__(self, model: Compensator, selection: Selection, iterations: int, program: Program,
                 max_correction_mm: float, computed: Commands | None = None, orientation: bool = False,
                 chain: Chain | None = None, std: bool = False):
        poses, rows = selection.poses, selection.rows
        self.commanded = np.full((len(poses), 3), np.nan)
        # the corrected numbers in each target's frame: X,Y,Z (and with ``orientation`` the
        # orientation's numbers in the program's form: A,B,C, RAPID's q1..q4, URScript's rx,ry,rz)
        self._written_orientation = program.targets.written_orientation(rows) if orientation else None
        self._form = program.orientation
        width = 3 + (self._written_orientation.shape[1] if orientation else 0)
        self.new_xyz = np.full((len(poses), width), np.nan)
        # the targets' joint angles, only where the model card has joint ranges to check them against
        envelope = model.envelope
        wanted = model.has_joints and envelope is not None and envelope.joints is not None
        self.joints = np.full((len(poses), 6), np.nan) if wanted else None
        self.ready = 0  # rows [0, ready) are filled
        self.inside: list = []  # each chunk's Inside (models that settle the approach)
        self.std = np.full(len(poses), np.nan) if std and computed is None else None  # the model's error_std at the commands
        self.unsafe = False
        self._error: BaseException | None = None
        self._cancel = False
        self._changed = threading.Condition()
        t = program.targets
        self._frame_of = t.frame[rows]
        # the X/Y/Z tokens as written: the poses less what the program adds to them (Targets.offset)
        self._written = t.poses[rows, :3] if t.offset is None else t.poses[rows, :3] - t.offset[rows]
        self._bases = model_bases(program, model)
        self._starts = _relative_starts(t.relative, rows)
        if computed is not None:  # (commands and joints of every row, from the caller)
            chunks = iter([(0, computed.commanded, computed.joints)])
        else:  # checks ``iterations`` here, not on the thread
            chunks = model.command_chunks(poses, iterations, joints=selection.joints, tool=selection.tool, load=selection.load,
                                          with_joints=wanted,
                                          orientation=orientation, chain=chain, std=self.std is not None,
                                          order=selection.order)
        # (made on this thread: the CLI's progress switch is this thread's context)
        self._progress = ProgressBar("compensate", len(poses) if computed is None else 0, "target", scale=True)
        self._thread = threading.Thread(target=self._run, args=(chunks, poses, max_correction_mm),
                                        name="postproc-model", daemon=True)
        self._thread.start()

    def _run(self, chunks: Iterator[tuple[int, np.ndarray, np.ndarray | None]], poses: np.ndarray,
             bound: float) -> None:
        try:
            for chunk in chunks:
                start, commands, q = chunk
                self.inside.append(getattr(chunk, "inside", None))
                if self._cancel:
                    return
                end = start + len(commands)
                if self.std is not None:
                    self.std[start:end] = chunk.std
                if self._written_orientation is not None:
                    self.new_xyz[start:end, 3:] = _local_orientation(commands[:, 3:6], self._bases,
                                                                     self._frame_of[start:end],
                                                                     self._written_orientation[start:end], self._form)
                    commands = commands[:, :3]
                correction = commands - poses[start:end, :3]
                # back into each target's own frame: only the rotation of its base applies to a shift
                self.commanded[start:end] = commands[:, :3]
                if self._starts is not None:  # (a relative target moves from its start's command: less its correction)
                    at = np.flatnonzero(self._starts[start:end] >= 0)
                    froms = self._starts[start:end][at]
                    correction[at] -= self.commanded[froms] - poses[froms, :3]
                local = np.empty_like(correction)
                frame_of = self._frame_of[start:end]
                for f, here in frames.frame_groups(frame_of):
                    local[here] = frames.rotate_vectors(frames.inverse(self._bases[f]), correction[here])
                if self.joints is not None and q is not None:
                    self.joints[start:end] = q
                self.new_xyz[start:end, :3] = self._written[start:end] + local
                with np.errstate(invalid="ignore"):
                    unsafe = not (np.isfinite(correction).all() and np.linalg.norm(correction, axis=1).max(initial=0.0) <= bound)
                with self._changed:
                    self.unsafe |= unsafe
                    self.ready = end
                    self._changed.notify_all()
                self._progress.update(end - start)
        except BaseException as exc:  # re-raised on the caller's thread
            with self._changed:
                self._error = exc
                self._changed.notify_all()

    def wait(self, upto: int) -> np.ndarray:
        """The corrected numbers [N, 3], rows [0, upto) filled; _Unsafe if a guard fails so far."""
        with self._changed:
            self._changed.wait_for(lambda: self.ready >= upto or self._error is not None)
        if self._error is not None:
            raise self._error
        if self.unsafe:
            raise _Unsafe
        return self.new_xyz

    def close(self) -> None:
        """Stop after the chunk in hand (an error elsewhere) and wait for the thread."""
        self._cancel = True
        self._thread.join()
        self._progress.close()

    def result(self) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """(commanded [N, 3] in the robot base, corrected numbers [N, 3] in each target's frame,
        the targets' joint angles [N, 6] deg or None), every row, once the thread is done."""
        self._thread.join()
        self._progress.close()
        if self._error is not None:
            raise self._error
        return self.commanded, self.new_xyz, self.joints


def _relative_starts(relative: np.ndarray | None, rows: np.ndarray) -> np.ndarray | None:
    """[n] for each of ``rows`` (the selection) the position in ``rows`` of the target a relative
    target moves from (``Targets.relative``), -1 where none or where that target is left as
    written (its command is its pose: nothing to take off); None: no relative target."""
    if relative is None:
        return None
    mine = relative[rows]
    if not (mine >= 0).any():
        return None
    position = np.full(len(relative), -1, np.int64)
    position[rows] = np.arange(len(rows))
    out = np.where(mine >= 0, position[np.maximum(mine, 0)], -1)
    # (a start's command is known before the target that moves from it: the start runs first)
    assert (out < np.arange(len(rows))).all()
    return out


def _rewrite_file(program: Program, index: int, text: str, rows: np.ndarray, stream: _CommandStream) -> str:
    """``text`` (file ``index`` of the program) with the X/Y/Z tokens of targets ``rows``
    replaced by their corrected numbers from ``stream`` as they come, each token checked
    before and after (guards.check_numbers), and the X/Y/Z a partial aggregate leaves out
    written into it (:func:`fill_partial`, checked by guards.check_inserted)."""
    t = program.targets
    mine = np.flatnonzero(t.file[rows] == index)
    # X,Y,Z (and the orientation's numbers with --orientation: stream.new_xyz has their columns then)
    orientation = stream.new_xyz.shape[1] > 3
    spans = np.concatenate([t.spans, t.abc_spans], axis=1) if orientation else t.spans
    width = spans.shape[1]
    starts = spans[rows[mine], :, 0].ravel()
    ends = spans[rows[mine], :, 1].ravel()
    at_row = np.repeat(mine, width)  # position in ``rows`` (and in the stream)
    axis = np.tile(np.arange(width), len(mine))
    keep = starts >= 0  # components the aggregate leaves out have no token...
    # ...X/Y/Z are written in (A/B/C: --orientation refuses targets that leave them out)
    inserts = fill_partial(text, starts.reshape(-1, width)[:, :3], ends.reshape(-1, width)[:, :3])
    starts = np.concatenate([starts[keep], inserts.at])
    ends = np.concatenate([ends[keep], inserts.at])
    at_row = np.concatenate([at_row[keep], mine[inserts.row]])
    axis = np.concatenate([axis[keep], inserts.axis])
    piece = np.concatenate([np.full(int(keep.sum()), -1), np.arange(len(inserts.at))])
    kind = np.where(piece >= 0, axis, -1)
    # by place; inserts at one place in axis order; runs of one number in row order
    order = np.lexsort((at_row, kind, starts))
    starts, ends, at_row, axis, piece, kind = (a[order] for a in (starts, ends, at_row, axis, piece, kind))
    if not len(starts):
        return text
    # a number several rows hold (a target run more than once, copies): written once, the first
    # row's (compensate_program checks that they agree); an insert: once per aggregate and column
    first = np.r_[True, (starts[1:] != starts[:-1]) | (kind[1:] != kind[:-1])]
    if not first.all():
        starts, ends, at_row, axis, piece = (a[first] for a in (starts, ends, at_row, axis, piece))
    check_disjoint(starts, ends)
    owners = rows[at_row]
    xyz = t.poses[:, :3] if t.offset is None else t.poses[:, :3] - t.offset
    read = (np.concatenate([xyz, t.written_orientation()], axis=1) if orientation else
            np.concatenate([xyz, t.poses[:, 3:6]], axis=1))[owners, axis]
    parts, prev = [], 0
    for at in range(0, len(starts), EDIT_CHUNK):
        chunk = slice(at, at + EDIT_CHUNK)
        s, e = starts[chunk].tolist(), ends[chunk].tolist()
        values = stream.wait(int(at_row[chunk].max()) + 1)[at_row[chunk], axis[chunk]]
        new = piece[chunk] >= 0
        if not new.any():  # (the common case: no partial aggregate in the chunk)
            tokens = [text[a:b] for a, b in zip(s, e)]
            replacements = _renumber(program, owners[chunk], tokens, read[chunk], values, axis[chunk])
        else:
            replacements = [""] * len(s)
            numbers, added = np.flatnonzero(~new), np.flatnonzero(new)
            tokens = [text[s[i]:e[i]] for i in numbers.tolist()]
            formatted = _renumber(program, owners[chunk][numbers], tokens, read[chunk][numbers], values[numbers],
                                  axis[chunk][numbers])
            pieces = inserts.text(piece[chunk][added], values[added])
            check_inserted(program, owners[chunk][added], pieces, axis[chunk][added], values[added])
            for i, r in zip(numbers.tolist() + added.tolist(), formatted + pieces):
                replacements[i] = r
        parts.append(splice(text, prev, s, e, replacements))
        prev = e[-1]
    parts.append(text[prev:])
    return "".join(parts)


def _renumber(program: Program, owners: np.ndarray, tokens: list[str], read: np.ndarray, values: np.ndarray,
              axis: np.ndarray) -> list[str]:
    """The new number tokens: ``tokens`` (of the targets ``owners``; ``axis`` 0-2 X/Y/Z, from 3
    the orientation's numbers) checked to be the numbers ``read``, written as ``values`` in
    their style and checked to read back as them (guards.check_numbers, P190): X/Y/Z in the
    program's unit, the orientation's numbers with their form's decimals (ORIENTATION_DECIMALS)."""
    turn = axis >= 3
    if not turn.any():
        return _renumbered(program, owners, tokens, read, values, program.unit, program.unit)
    out = [""] * len(tokens)
    for part, unit, decimals in ((~turn, program.unit, program.unit),
                                 (turn, 1.0, ORIENTATION_DECIMALS[program.orientation])):
        idx = np.flatnonzero(part)
        new = _renumbered(program, owners[idx], [tokens[i] for i in idx.tolist()], read[idx], values[idx], unit,
                          decimals)
        for i, token in zip(idx.tolist(), new):
            out[i] = token
    return out


def _renumbered(program: Program, owners: np.ndarray, tokens: list[str], read: np.ndarray, values: np.ndarray,
                unit: float, decimals: float) -> list[str]:
    """``_renumber`` for tokens of one kind: a value is the token × ``unit``; the token is
    written with the decimals of a length in units of ``decimals`` mm (rewrite.decimal_range)."""
    check_numbers(program, owners, tokens, read, 0.0, "is not the {} read for the target", unit)
    new = format_many(tokens, values if decimals == unit else values * (decimals / unit), decimals)
    check_numbers(program, owners, new, values, ROUNDING_MM * unit / decimals, "does not read back as the corrected {}",
                  unit)
    return new

"""The compensate use case: program → robot-base poses → one batched model call →
corrected numbers in the program's own frame → new texts (+ stamp) → atomic write.

This is what the CLI (``postproc compensate``) and the CAM-hook API
(``postproc.compensate_text``; ``postproc.compensate_file`` in streaming.py) call.
"""
from __future__ import annotations

import math
import re
import sys
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import numpy as np

from collections import Counter

from . import frames
from .compensator import Chain, Compensator, Inside, load_model
from .diagnostics import (
    P105, P106, P107, P108, P201, P203, P212, P220, P221, P224, P225, P230, P231, P306, P312, P321, P322, P340,
    Diagnostic,
    LEFT_AS_WRITTEN,
    PostprocError,
)
from .findings import (
    DEFAULT_MAX_CORRECTION_MM,
    Commands,
    collect,
    execution_order,
    group_rule,
    Selection,
    Settings,
    command_findings,
    dead_band_notes,
    missing_xyz,
    outside_envelope,
    model_bases,
    robot_base_poses,
    robot_mismatch,
    select_with_findings,
    std_bound,
    tool_mismatch,
    where,
)
from .guards import ROUNDING_MM, check_inserted, check_memory, check_numbers, check_round_trip
from .outputs import check_outputs, write
from .programs import STAMP_PREFIX, ActiveFrames, Program, companion_dat, dialect_of, read_program
from .progress import ProgressBar
from .rewrite import ORIENTATION_DECIMALS, check_disjoint, format_like, format_many, insert_stamp, splice, stamp_line

__all__ = [
    "Report",
    "load_program",
    "parse_program_text",
    "robot_base_poses",
    "compensate_program",
    "rewrite_program",
    "compensate_text",
    "DEFAULT_MAX_CORRECTION_MM",
    "write_outputs",
    "tool_mismatch",
    "robot_mismatch",
]

STDIN = "<stdin>"


@dataclass
class Report:
    """What a compensation did. ``outputs`` maps each file of the program to its new text
    (unchanged, without a stamp, where no target was compensated; ``changed`` lists the
    others); ``left_codes`` counts the targets left as written by the code that says why."""

    model: str = ""
    model_sha256: str = ""
    targets: int = 0
    compensated: int = 0
    left: int = 0
    left_codes: dict[str, int] = field(default_factory=dict)
    # motions at an offset from a point compensated for its own motions, moved with its correction (P231)
    moved: int = 0
    iterations: int = 0
    max_correction_mm: float = 0.0
    mean_correction_mm: float = 0.0
    outside_envelope: int = 0
    warnings: list[Diagnostic] = field(default_factory=list)
    notes: list[Diagnostic] = field(default_factory=list)  # P224, P321 (printed with -v), P340 (printed)
    outputs: dict[str, str] = field(default_factory=dict)
    changed: list[str] = field(default_factory=list)

    @property
    def skipped(self) -> int:  # (the name before ``left``)
        return self.left

    @property
    def codes(self) -> list[str]:
        """The codes of the warnings and of the targets left as written, sorted, once each."""
        return sorted({d.code for d in self.warnings} | set(self.left_codes))

    @property
    def complete(self) -> bool:
        """Every Cartesian target was compensated (the CLI's exit 0)."""
        return self.left == 0 and self.moved == 0

    def summary(self) -> str:
        """``17 of 19 compensated, 2 left as written: P201 ×2; model …`` (one line)."""
        head = f"{self.compensated} of {self.targets} compensated"
        if self.left:
            head += f", {self.left} left as written: " + ", ".join(
                f"{code} ×{n}" for code, n in sorted(self.left_codes.items()))
        if self.moved:
            head += (f", {self.moved} motion{'s' if self.moved != 1 else ''} at an offset moved with the point's "
                     f"correction ({P231})")
        details = (f"model {self.model}, max correction {self.max_correction_mm:.3f} mm, mean "
                   f"{self.mean_correction_mm:.3f} mm, {self.iterations} iteration{'s' if self.iterations != 1 else ''}")
        if self.warnings:
            details += f", {len(self.warnings)} warning{'s' if len(self.warnings) != 1 else ''}"
        dead_band = sum(n.code == P321 for n in self.notes)
        if dead_band:
            details += f", {dead_band} in a joint's backlash dead band (P321, -v)"
        approaches = sum(n.code == P322 for n in self.notes)
        if approaches:
            details += f", {approaches} reached from several places (P322, -v)"
        if any(n.code == P224 for n in self.notes):
            details += "; robot base = world assumed: $ROBROOT not known (P224, -v)"
        if any(n.code == P340 for n in self.notes):
            details += "; a demonstration model of a simulated robot (P340)"
        if not self.changed:
            details += "; nothing changed: the output is the input as it was, unstamped"
        return f"{head}; {details}"


# --------------------------------------------------------------------------- reading


def _decode(data: bytes, path: str) -> str:
    if not data.strip():
        raise PostprocError("empty file", path, 1, 1, P105)
    if b"\x00" in data[:65536]:
        raise PostprocError("binary file (NUL bytes), not a robot program", path, 1, 1, P106)
    # latin-1 maps every byte to one character: whatever the file's encoding, bytes round-trip
    return data.decode("latin-1")


def read_text(path: str | Path) -> str:
    """A program file's text (latin-1: every byte round-trips); P107 when it cannot be read."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise PostprocError("no such file", str(path), 0, 0, P107) from None
    except OSError as exc:
        raise PostprocError(f"cannot read: {exc.strerror}", str(path), 0, 0, P107) from None
    return _decode(data, str(path))


def sniff_dialect(text: str) -> str:
    """KRL or a pose list, for text that comes without a file name (stdin)."""
    krl = re.search(r"^[ \t]*(?:&ACCESS|(?:GLOBAL\s+)?DEF(?:FCT|DAT)?\b|S?(?:LIN|PTP|CIRC)\b)", text, re.I | re.M)
    return "krl" if krl else "poses"


def parse_program_text(
    text: str,
    name: str = STDIN,
    dialect: str | None = None,
    dat_text: str | None = None,
    config_texts: list[str] | None = None,
    active: ActiveFrames | None = None,
) -> Program:
    """Parse a program given as text (a .src with optional .dat text, or a pose list);
    ``active``: the $BASE/$TOOL stated for a KRL program that does not set them."""
    dialect = dialect or (dialect_of(name) if name != STDIN and Path(name).suffix else sniff_dialect(text))
    files, texts = [name], [text]
    if dat_text is not None:
        files.append(str(Path(name).with_suffix(".dat")) if name != STDIN else "<stdin.dat>")
        texts.append(dat_text)
    return read_program(files, texts, dialect, config=config_texts, active=active)


def _config_texts(config: str | Path | list | None) -> list[str] | None:
    if config is None:
        return None
    paths = config if isinstance(config, list | tuple) else [config]
    return [read_text(Path(p)) for p in paths]


def backup_active(config: str | Path | list | None, active: ActiveFrames | None) -> ActiveFrames | None:
    """``active`` with the $ROBROOT of the controller backup a ``System/$config.dat`` of
    ``config`` belongs to (its ``Mada/$machine.dat``), unless ``active`` states one."""
    if config is None:  # no $config.dat, no backup: ``active`` as it is (and no import of the KRL reader)
        return active
    from .programs.krl.machine import with_machine

    return with_machine(active, configs=[] if config is None else (
        list(config) if isinstance(config, list | tuple) else [config]))


def load_program(path: str | Path, config: str | Path | None = None, dialect: str | None = None,
                 active: ActiveFrames | None = None) -> Program:
    """Read a program from disk: a .src with its .dat companion, a lone .dat, or a pose list.
    ``-`` reads standard input. ``config`` is a ``$config.dat`` for BASE_DATA / TOOL_DATA
    (and, in a backup, the ``Mada/$machine.dat`` beside its ``System/``: ``backup_active``);
    ``active`` the $BASE/$TOOL/$ROBROOT stated for a KRL program that does not set them."""
    if dialect in (None, "krl"):
        active = backup_active(config, active)
    if str(path) == "-":
        return parse_program_text(_decode(sys.stdin.buffer.read(), STDIN), STDIN, dialect, None, _config_texts(config),
                                  active)
    path = Path(path)
    if dialect is None:
        try:
            dialect = dialect_of(path)
        except ValueError as exc:
            raise PostprocError(str(exc), str(path), 0, 0, P108) from None
    dat = companion_dat(path) if dialect == "krl" else None
    check_memory([path] + ([dat] if dat is not None else []))
    files, texts = [str(path)], [read_text(path)]
    if dat is not None:
        files.append(str(dat))
        texts.append(read_text(dat))
    return read_program(files, texts, dialect, config=_config_texts(config), active=active)


# --------------------------------------------------------------------------- compensating


def _left_codes(program: Program, selection: Selection) -> Counter:
    """Why each target not compensated was left as written: its code, counted. Rows of the
    program's Targets are P201 (frame not known) or P212 (position not known); the reader's
    targets that never became rows (``diagnostics.LEFT_AS_WRITTEN``: P210, P211, P214, P215, P217, P223)
    count one each."""
    t = program.targets
    first = _firsts(program)
    left = first & ~_compensated_classes(program, selection)
    codes: Counter = Counter()
    unknown_frame = int((left & (t.frame < 0)).sum())
    if unknown_frame:
        # frame -1: the base (P201) or the tool (P203) is not known, or not set (P220/P221); the reader's located
        # warnings say which for each statement, the count names the codes it warned with
        said = {d.code for d in program.diagnostics} & {P201, P203, P220, P221, P225}
        codes["/".join(sorted(said)) if said else P201] = unknown_frame
    by_rule = 0
    counted = ~left  # (a target counted once: by the first code that left one of its runs)
    cls = _classes(program)
    for code, rows in selection.left.items():
        c = np.unique(cls[np.asarray(rows, int)])
        c = c[~counted[c]]
        counted[c] = True
        n = len(c)
        if n:
            codes[code] += n
        by_rule += n
    if left.sum() > unknown_frame + by_rule:
        codes[P212] = int(left.sum()) - unknown_frame - by_rule
    held = getattr(program, "held", {}) or {}
    for d in program.diagnostics:
        if d.code in LEFT_AS_WRITTEN and d.code not in held:  # (held rows: counted as rows above)
            codes[d.code] += 1
    return codes


def _classes(program: Program) -> np.ndarray:
    """[N] each row's target: the row of its first run (``Targets.twin``; itself for a first run)."""
    twin = getattr(program.targets, "twin", None)
    n = len(program.targets)
    return np.arange(n) if twin is None else np.where(twin >= 0, twin, np.arange(n))


def _compensated_classes(program: Program, selection: Selection) -> np.ndarray:
    """[N] bool: the targets (by their first run's row) of which some run is compensated."""
    out = np.zeros(len(program.targets), bool)
    out[_classes(program)[selection.rows]] = True
    return out


def _moved(program: Program, selection: Selection) -> int:
    """Motions at an offset moved with their point's correction (P231): one per offset from a
    point compensated for its own runs."""
    rows = np.asarray(selection.left.get(P231, []), int)
    if not len(rows) or program.targets.offset is None:
        return 0
    cls = _classes(program)
    rows = rows[_compensated_classes(program, selection)[cls[rows]]]
    return len({(int(cls[r]), *np.round(program.targets.offset[r], 6).tolist()) for r in rows.tolist()})


def _firsts(program: Program) -> np.ndarray:
    """[N] bool: the rows that are a target's first run (``Targets.twin`` -1): what the summary
    counts (a target in a loop or a routine called twice is one target)."""
    twin = getattr(program.targets, "twin", None)
    return np.ones(len(program.targets), bool) if twin is None else twin < 0


# the runs of one set of numbers (twins, copies) agree when the numbers each would have written
# differ by no more than this (mm; the orientation's numbers: this × their form's decimals per mm)
AGREE_MM = 0.005
# runs of one target at one pose that differ only in where they come from (the approach) are
# commanded at the middle of their commands where that is at most this far from each run's own
# (mm, as far as agreeing runs' numbers may be); further apart (another arm configuration, a
# model that depends much on the approach): left as written at every run (P230)
MIDDLE_MM = AGREE_MM
# rounds of compensating again without the targets whose runs disagree (each round removes groups)
MAX_ROUNDS = 8


def _shared_tokens(program: Program, rows: np.ndarray, width: int):
    """For the selected ``rows`` that share numbers with other rows (``Targets.group``): per
    component written or inserted, a key of what the text holds there [m] (int64 pairs flattened
    to one sortable array), the position in ``rows`` and the column; None where no row shares."""
    t = program.targets
    group = getattr(t, "group", None)
    if group is None or not len(rows):
        return None
    shared = np.flatnonzero(group[rows] >= 0)
    if not len(shared):
        return None
    r = rows[shared]
    spans = t.spans[r, :, 0]  # X, Y, Z token starts (-1 missing: written in at the aggregate)
    cols = [spans]
    if width > 3 and t.abc_spans is not None:
        cols.append(t.abc_spans[r, :width - 3, 0])
    starts = np.concatenate(cols, axis=1)
    anchor = np.where(spans >= 0, spans, np.iinfo(np.int64).max).min(axis=1)  # the aggregate (its first token)
    k = np.arange(starts.shape[1])
    key_pos = np.where(starts >= 0, starts, -1 - anchor[:, None] * 8 - k[None, :])  # an insert: per aggregate, column
    key_file = np.repeat(t.file[r].astype(np.int64)[:, None], starts.shape[1], axis=1)
    pos = np.repeat(shared[:, None], starts.shape[1], axis=1)
    col = np.broadcast_to(k, starts.shape)
    return key_file.ravel(), key_pos.ravel(), pos.ravel(), np.asarray(col).ravel()


@dataclass
class _Agreement:
    """What the runs of one set of numbers came to: ``drop`` (positions in the selection left as
    written: whole groups whose runs need other numbers: other frames, tools, offsets),
    ``warnings`` (their P230), ``written`` (the numbers the text holds for each selected row:
    its group's first run's, [len(rows), width]), ``settled`` (positions whose runs differ only in
    where they come from, the approach: commanded at the middle of the runs' commands, the
    smallest worst case) with ``commanded`` [len(settled), 3] and ``notes`` (P322)."""

    drop: np.ndarray
    warnings: list
    written: np.ndarray
    settled: np.ndarray
    commanded: np.ndarray
    notes: list
    moved: np.ndarray = field(default_factory=lambda: np.zeros(0, int))  # positions moved with the point's own (P231)


def _agreement(program: Program, selection: Selection, new_xyz: np.ndarray, commanded: np.ndarray,
               orientation: bool = False) -> _Agreement:
    """The runs of one set of numbers (``Targets.group``): they agree where the numbers each would
    write differ by no more than ``AGREE_MM``; runs of one target at one pose that differ only in
    where they come from (the approach) are commanded at the middle (P322, a note); any other
    disagreement leaves the whole group as written (P230)."""
    rows = selection.rows
    written = new_xyz.copy()
    none = np.zeros(0, int)
    found = _shared_tokens(program, rows, new_xyz.shape[1])
    if found is None:
        return _Agreement(none, [], written, none, np.zeros((0, 3)), [])
    key_file, key_pos, pos, col = found
    value = new_xyz[pos, col]
    tol = np.where(col < 3, AGREE_MM, AGREE_MM * ORIENTATION_DECIMALS[program.orientation])
    order = np.lexsort((pos, key_pos, key_file))
    kf, kp, v, p, c, tl = key_file[order], key_pos[order], value[order], pos[order], col[order], tol[order]
    new = np.r_[True, (kf[1:] != kf[:-1]) | (kp[1:] != kp[:-1])]
    starts = np.flatnonzero(new)
    lead = np.repeat(starts, np.diff(np.r_[starts, len(v)]))
    with np.errstate(invalid="ignore"):
        spread = np.abs(v - v[lead])
    bad = spread > tl
    written[p, c] = v[lead]  # (what the text holds: the first run's number)
    t = program.targets
    group = t.group[rows]
    bad_groups = np.unique(group[p[bad]])
    if not len(bad_groups):
        return _Agreement(none, [], written, none, np.zeros((0, 3)), [])
    # a group whose rows are one target at one pose, frame and tool (runs that differ in their
    # predecessor only): the middle of its runs' commands
    approach = []
    for g in ([] if orientation else bad_groups.tolist()):  # (--orientation: the middle of turns is not settled)
        members = np.flatnonzero(group == g)
        r = rows[members]
        same = ((t.poses[r] == t.poses[r[0]]) | (np.isnan(t.poses[r]) & np.isnan(t.poses[r[0]]))).all() and \
            (t.frame[r] == t.frame[r[0]]).all() and (t.twin[r] >= 0).sum() == len(r) - 1 and \
            (selection.tool is None or (selection.tool[members] == selection.tool[members[0]]).all())
        if same:
            approach.append(g)
    settled, middles, notes = [], [], []
    for g in list(approach):
        members = np.flatnonzero(group == g)
        lo, hi = commanded[members].min(axis=0), commanded[members].max(axis=0)
        mid = (lo + hi) / 2
        worst = float(np.linalg.norm((hi - lo) / 2))
        if not worst <= MIDDLE_MM:
            approach.remove(g)
            continue
        settled.extend(members.tolist())
        middles.extend([mid] * len(members))
        first = int(members[0])
        notes.append(Diagnostic(*where(program, int(rows[first])), P322,
                                f"this target runs {len(members)} times from other places (after a branch, in a loop) "
                                f"and the runs need commands up to {2 * worst:.3f} mm apart (the approach): commanded "
                                f"at the middle, at most {worst:.3f} mm from each run's own", "note"))
    other = np.setdiff1d(bad_groups, approach)
    other, moved, moved_warnings = _owned(program, selection, other, (kf, kp, v, p, tl))
    drop = np.flatnonzero(np.isin(group, other) & (group >= 0)) if len(other) else none
    warnings = moved_warnings
    if len(drop):
        worst_of = {}
        for g, d in zip(group[p[bad]].tolist(), spread[bad].tolist()):
            worst_of[g] = max(worst_of.get(g, 0.0), d)
        places = np.stack([t.file[rows[drop]], t.line[rows[drop]], t.col[rows[drop]]], axis=1)
        _, once = np.unique(places, axis=0, return_index=True)  # (one warning per target, not per run)
        said = drop[np.sort(once)]
        warnings += collect(program, rows[said], P230, lambda i: (
            "this target runs more than once (a loop, a routine called twice, after a branch, or a point copied "
            "into another) and the runs need corrections up to {:.3f} mm apart (other frames, tools, offsets, arm "
            "configurations or approaches): no one set of numbers is right for all, left as written".format(worst_of[int(group[said[i]])])))
    return _Agreement(drop, warnings, written, np.asarray(settled, int),
                      np.asarray(middles, float).reshape(-1, 3), notes, moved)


def _owned(program: Program, selection: Selection, groups: np.ndarray, entries) -> tuple:
    """Of the ``groups`` whose runs disagree, those whose runs at the point itself (no offset
    added: ``Targets.offset`` zero) agree among themselves while runs at an offset (``Offs(p, 0, 0,
    100)``, ``XA.Z = XS1.Z + 300``) need other numbers: the point's numbers are its own runs', and
    the runs at an offset move with that correction — said (P231), not compensated. ``entries``:
    _agreement's sorted token entries (file key, position key, value, position in the selection,
    tolerance). (groups left to P230, positions moved, their warnings)."""
    t = program.targets
    rows = selection.rows
    none = np.zeros(0, int)
    if not len(groups) or t.offset is None:
        return groups, none, []
    kf, kp, v, p, tl = entries
    group = t.group[rows]
    at_point = ~(np.abs(t.offset[rows]) > 1e-9).any(axis=1)
    gp = group[p]
    keep, moved, warnings = [], [], []
    for g in groups.tolist():
        members = np.flatnonzero(group == g)
        own = at_point[members]
        if not own.any() or own.all():
            keep.append(g)
            continue
        ref: dict = {}
        ent = np.flatnonzero(gp == g)
        for e in ent[at_point[p[ent]]].tolist():
            ref.setdefault((kf[e], kp[e]), v[e])
        agree, worst = True, 0.0
        for e in ent.tolist():
            r = ref.get((kf[e], kp[e]))
            if r is None:
                continue
            d = abs(v[e] - r)
            if at_point[p[e]]:
                agree &= not d > tl[e]
            elif d == d:
                worst = max(worst, d)
        if not agree:
            keep.append(g)
            continue
        off = members[~own]
        moved.extend(off.tolist())
        n = len({tuple(np.round(t.offset[rows[i]], 6)) for i in off.tolist()})
        warnings += collect(program, rows[off[:1]], P231, (
            f"this point's numbers are compensated for the motions to the point itself; {n} motion"
            f"{'s' if n != 1 else ''} to it at an offset (Offs/RelTool, a copy with a component changed) move"
            f"{'' if n != 1 else 's'} with that correction, up to {worst:.3f} mm from {'their' if n != 1 else 'its'} "
            f"own: not compensated"))
    return np.asarray(keep, int), np.asarray(moved, int), warnings


def _outside(model: Compensator, commands: Commands) -> int:
    """How many targets are outside the training envelope (box, attitude or joint ranges)."""
    outside = outside_envelope(model, commands.selection)
    envelope = model.envelope
    if envelope is not None and envelope.joints is not None and commands.joints is not None:
        outside |= envelope.outside_joints(commands.joints)
    return int(outside.sum())


def _raise_first(found: list[Diagnostic], strict: bool) -> None:
    """Refuse on the first error, and under ``strict`` on the first warning."""
    errors = [d for d in found if d.severity == "error"]
    if errors:
        first = errors[0]
        raise PostprocError(first.message, first.path, first.line, first.col, first.code)
    if strict and found:
        first = found[0]
        raise PostprocError(f"{first.message} (--strict; {len(found)} warning(s) in all)",
                            first.path, first.line, first.col, first.code)


def compensate_program(
    program: Program,
    model: Compensator,
    *,
    iterations: int | None = None,
    strict: bool = False,
    force: bool = False,
    max_correction_mm: float = DEFAULT_MAX_CORRECTION_MM,
    max_std_mm: float | None = None,
    robot: str | None = None,
    fill_partial: bool = True,
    orientation: bool = False,
    _chain: Chain | None = None,
    _stamp: bool = True,
) -> Report:
    """Compensate every resolvable target of ``program``; the new texts are in ``Report.outputs``
    (a file in which no target was compensated is returned as it was, without a stamp). With
    ``orientation`` the orientation is corrected too (A/B/C; RAPID's q1..q4, URScript's rx,ry,rz:
    ``Program.orientation``), with the model's ``rotation_error`` (P306 without it).

    Raises PostprocError for what must not be written: every error of
    :func:`postproc.findings.findings` (double compensation, a model for another robot or
    tool, unless ``force``; targets beyond reach, NaN or implausibly large corrections;
    partial aggregates with ``fill_partial=False``), under ``strict`` any warning, and
    whatever the last checks (guards.py) refuse. Targets left as written (frame or position
    not known) are counted in ``Report.left`` / ``Report.left_codes``.
    (``_chain``, ``_stamp``: streaming compensate, a part of a program continuing the parts
    before it, the texts returned unstamped.)
    """
    settings = Settings(iterations=iterations, max_correction_mm=max_correction_mm, robot=robot, force=force,
                        fill_partial=fill_partial, chain=_chain, max_std_mm=max_std_mm)
    selection, found = select_with_findings(program, model, settings)
    model_notes = [d for d in found if d.severity == "note"]  # (P340: said once, not a warning)
    found = [d for d in found if d.severity != "note"]
    warnings = list(program.diagnostics) + found
    _raise_first(found, False)
    _raise_first(warnings, strict)
    if orientation:
        _orientation_check(program, model, selection.rows)
    report = Report(model=model.name, model_sha256=model.sha256, iterations=
                    model.default_iterations if iterations is None else iterations)
    # rows in execution order: the model chains each target to its predecessor's command (the
    # approach direction, for models that learn backlash). The model runs on a background
    # thread, chunk by chunk, while this one rewrites the numbers of the chunks already done.
    approach_notes: list[Diagnostic] = []
    for attempt in range(MAX_ROUNDS):
        stream = _CommandStream(model, selection, report.iterations, program, max_correction_mm,
                                orientation=orientation, chain=_chain, std=std_bound(model, settings) is not None)
        outputs = _rewrite(program, selection, stream)
        commanded, new_xyz, joints = stream.result()
        # the runs of one set of numbers (a loop, a routine called twice, copies) must agree
        agreed = _agreement(program, selection, new_xyz, commanded, orientation)
        if (len(agreed.drop) or len(agreed.moved)) and attempt < MAX_ROUNDS - 1:
            warnings += agreed.warnings
            _raise_first(agreed.warnings, strict)
            moved_rows = selection.rows[agreed.moved]
            selection = selection.without(agreed.drop, P230)
            selection = selection.without(np.flatnonzero(np.isin(selection.rows, moved_rows)), P231)
            selection, tied = group_rule(program, selection)  # (what the rows left take with them)
            warnings += tied
            selection.order = execution_order(program, selection, selection.base_poses, model)
            continue
        written = agreed.written
        if len(agreed.settled):  # (runs that differ in their approach only: the middle command)
            commanded = commanded.copy()
            commanded[agreed.settled] = agreed.commanded
            approach_notes = agreed.notes
            again = _CommandStream(model, selection, 1, program, math.inf,
                                   Commands(selection, commanded, joints), orientation=orientation)
            outputs = _rewrite(program, selection, again)
            _, new_xyz, _ = again.result()
            written = _agreement(program, selection, new_xyz, commanded).written
        break
    commands = Commands(selection, commanded, joints, Inside.join(stream.inside), stream.std)
    after = command_findings(program, commands, model, settings)
    _raise_first(after, strict)
    assert outputs is not None  # _Unsafe is raised only for what output_rule refuses
    warnings += after
    offset = program.targets.offset
    if offset is not None:  # (the numbers read again are the tokens + what the program adds to them)
        written = written.copy()
        written[:, :3] += offset[selection.rows]
    outputs = _finish(program, model, selection, outputs, written, stamp=_stamp)

    size = np.linalg.norm(commanded - selection.poses[:, :3], axis=1)
    left = _left_codes(program, selection)
    report.compensated = int(_compensated_classes(program, selection).sum())
    report.moved = _moved(program, selection)
    report.left = sum(left.values())
    report.targets = report.compensated + report.left
    report.left_codes = dict(left)
    report.max_correction_mm = float(size.max()) if len(size) else 0.0
    report.mean_correction_mm = float(size.mean()) if len(size) else 0.0
    report.outside_envelope = _outside(model, commands)
    # (one finding once: a target run in a loop or from two places is found at each run)
    report.warnings = list(dict.fromkeys(warnings))
    report.notes = list(dict.fromkeys(program.notes + model_notes + dead_band_notes(program, commands) + approach_notes))
    report.changed = [program.files[i] for i in sorted(set(program.targets.file[selection.rows].tolist()))]
    report.outputs = dict(zip(program.files, outputs))
    return report


def rewrite_program(program: Program, commands: Commands, model: Compensator) -> dict[str, str]:
    """The new texts of ``program`` for ``commands`` (computed already, e.g. by ``check``),
    through the same rewrite and last checks (P190, P191) as :func:`compensate_program`."""
    stream = _CommandStream(model, commands.selection, 1, program, math.inf, commands)
    outputs = _rewrite(program, commands.selection, stream)
    _, new_xyz, _ = stream.result()
    return dict(zip(program.files, _finish(program, model, commands.selection, outputs, new_xyz)))


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


def _finish(program: Program, model: Compensator, selection: Selection, outputs: list[str],
            new_xyz: np.ndarray, stamp: bool = True) -> list[str]:
    """The round trip (guards.check_round_trip) and the stamp on each file that changed."""
    rows = selection.rows
    # KRL with position variables only: their numbers may be read elsewhere too (as a frame,
    # by another target), which no single edit shows. Inline aggregates belong to one motion,
    # and each of their tokens was checked when written; so were a pose list's. A Program built
    # by hand has no text to read it from.
    if program.from_text and program.dialect in ("krl", "rapid", "urscript", "fanuc") and program.named_targets:
        check_round_trip(program, outputs, rows, new_xyz, filled=missing_xyz(program, rows),
                         moved=np.asarray(selection.left.get(P231, []), int))
    if not stamp:
        return list(outputs)
    stamp = stamp_line(program.comment, STAMP_PREFIX, model.name, model.sha256)
    after = "&" if program.dialect == "krl" else None
    changed = set(program.targets.file[rows].tolist())
    out = list(outputs)
    for index in changed:
        newline = program.newlines[index] if index < len(program.newlines) else "\n"
        if program.dialect == "fanuc":  # a remark line at the end of /MN
            from .programs.fanuc import insert_stamp as insert_ls_stamp

            out[index] = insert_ls_stamp(out[index], stamp, newline)
        else:
            out[index] = insert_stamp(out[index], stamp, newline, after_headers=after)
    return out



def _orientation_check(program: Program, model: Compensator, rows: np.ndarray) -> None:
    """Refuse ``--orientation`` when it cannot be done right: no ``rotation_error`` output
    (P306), orientation numbers the reader does not locate (P312: A/B/C, RAPID's q1..q4 and
    URScript's rx,ry,rz are) or targets without all of A/B/C (P312: KRL, pose lists)."""
    if not model.has_rotation:
        raise PostprocError("the model has no output 'rotation_error': it cannot correct orientation (train it on "
                            "data with a_meas,b_meas,c_meas); compensate without --orientation", str(model.path),
                            0, 0, P306)
    spans = program.targets.abc_spans
    if spans is None:
        raise PostprocError(f"--orientation: the {program.dialect} reader does not locate the orientation's numbers",
                            program.files[0], 1, 1, P312)
    missing = rows[(spans[rows, :, 0] < 0).any(axis=1)]
    if len(missing):
        raise PostprocError("--orientation: this target does not write all of A, B, C", *where(program, int(missing[0])),
                            P312)


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
        if computed is not None:  # (commands and joints of every row, from the caller)
            chunks = iter([(0, computed.commanded, computed.joints)])
        else:  # checks ``iterations`` here, not on the thread
            chunks = model.command_chunks(poses, iterations, joints=selection.joints, tool=selection.tool, with_joints=wanted,
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
                local = np.empty_like(correction)
                frame_of = self._frame_of[start:end]
                for f, here in frames.frame_groups(frame_of):
                    local[here] = frames.rotate_vectors(frames.inverse(self._bases[f]), correction[here])
                self.commanded[start:end] = commands[:, :3]
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


@dataclass
class _Inserts:
    """The X/Y/Z components to write into partial aggregates: where (``at``, an offset in the
    text), for which row of the file's targets and axis, and how (the aggregate's style)."""

    at: np.ndarray
    row: np.ndarray
    axis: np.ndarray
    before: list[str]  # text before the name (a separator when inserted after a component)
    names: list[str]
    gaps: list[str]  # between the name and the number
    like: list[str]  # the neighbour's number token, whose style the number takes
    after: list[str]  # text after the number (a separator when inserted before a component)

    def text(self, which: np.ndarray, values: np.ndarray) -> list[str]:
        return [self.before[k] + self.names[k] + self.gaps[k] + format_like(self.like[k], v) + self.after[k]
                for k, v in zip(which.tolist(), values.tolist())]


_SEPARATOR = re.compile(r"[ \t]*,[ \t]*")


def fill_partial(text: str, starts: np.ndarray, ends: np.ndarray) -> _Inserts:
    """Where and how to write the X/Y/Z that aggregates leave out (``starts``/``ends`` [n, 3]
    their number tokens' spans, -1 where absent; at least one present per row): a missing
    component goes before the next written one (``{Z 1250}`` → ``{X …,Y …,Z 1250}``), or after
    the last (``{X 1}`` → ``{X 1,Y …,Z …}``), with the aggregate's separator (``,`` or ``, ``),
    the case of its names, the blanks between name and number, and its numbers' style.
    Only rows with a missing component are looked at (one Python step each)."""
    out = _Inserts(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64), [], [], [], [], [])
    partial = np.flatnonzero((starts < 0).any(axis=1) & (starts >= 0).any(axis=1))
    at, row, axis = [], [], []
    for r in partial.tolist():
        present = [k for k in range(3) if starts[r, k] >= 0]
        names, gaps = {}, {}
        for k in present:
            j = int(starts[r, k]) - 1
            while j >= 0 and text[j] in " \t":
                j -= 1
            names[k] = j  # offset of the component's name (one letter X/Y/Z)
            gaps[k] = text[j + 1:int(starts[r, k])]
        # the separator: between two written components, else after the last one, else ','
        sep = next((m.group() for m in (_SEPARATOR.match(text, int(ends[r, k])) for k in present) if m), ",")
        k0 = present[0]
        upper = text[names[k0]].isupper()
        for k in range(3):
            if starts[r, k] >= 0:
                continue
            later = [j for j in present if j > k]
            name = "XYZ"[k] if upper else "xyz"[k]
            if later:
                j = later[0]
                at.append(names[j]), out.before.append(""), out.after.append(sep)
            else:
                j = present[-1]
                at.append(int(ends[r, j])), out.before.append(sep), out.after.append("")
            row.append(r), axis.append(k)
            out.names.append(name), out.gaps.append(gaps[j]), out.like.append(text[int(starts[r, j]):int(ends[r, j])])
    out.at, out.row, out.axis = (np.array(a, np.int64) for a in (at, row, axis))
    return out


def _model(model: Compensator | str | Path | None) -> Compensator:
    return model if isinstance(model, Compensator) else load_model(model)


def compensate_text(
    text: str,
    model: Compensator | str | Path | None = None,
    *,
    name: str = STDIN,
    dialect: str | None = None,
    dat_text: str | None = None,
    config: str | Path | list | None = None,
    active: ActiveFrames | None = None,
    iterations: int | None = None,
    strict: bool = False,
    force: bool = False,
    max_correction_mm: float = DEFAULT_MAX_CORRECTION_MM,
    max_std_mm: float | None = None,
    robot: str | None = None,
    fill_partial: bool = True,
    orientation: bool = False,
) -> tuple[str, Report]:
    """Compensate a program given as text; returns the new text and the report.

    For a KRL module pass its .dat as ``dat_text``: the new .dat is
    ``report.outputs[<name>.dat]``. ``model`` is a loaded Compensator (reuse one for many
    calls), a path, or None for the shipped default model. ``active``: the $BASE/$TOOL in
    force where a KRL program does not set them (``ActiveFrames``; else such targets are
    left as written, P220/P221).
    """
    program = parse_program_text(text, name, dialect, dat_text, _config_texts(config), backup_active(config, active))
    report = compensate_program(program, _model(model), iterations=iterations, strict=strict, force=force,
                                max_correction_mm=max_correction_mm, robot=robot, fill_partial=fill_partial,
                                orientation=orientation, max_std_mm=max_std_mm)
    return report.outputs[program.files[0]], report


def output_paths(program: Program, out: Path) -> list[Path]:
    """Where each file of the program goes: the main file to ``out``, its .dat beside it."""
    paths = [out]
    for extra in program.files[1:]:
        paths.append(out.with_suffix(Path(extra).suffix))
    return paths


def write_outputs(outputs: list[tuple[Path, str]]) -> None:
    """:func:`postproc.outputs.write` (OS errors as P110) after the one output rule,
    :func:`postproc.outputs.check_outputs` (two files of a module onto one path, e.g. ``-o x.dat``
    for a .src; a directory; a folder that cannot be written)."""
    check_outputs([path for path, _ in outputs])
    write(outputs)

"""The compensate use case: program → robot-base poses → one batched model call →
corrected numbers in the program's own frame → new texts (+ stamp) → atomic write.

This is what the CLI (``postproc compensate``) and the CAM-hook API
(``postproc.compensate_text``; ``postproc.compensate_file`` in streaming.py) call.
"""
from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core.diagnostics import (
    INCOMPLETE, LEFT_AS_WRITTEN, P201, P203, P210, P212, P220, P221, P224, P225, P230, P231, P232, P306, P323, P312,
    P314, P321, P322, P340, Diagnostic,
    PostprocError,
)
from ..core import frames
from ..core.outputs import check_outputs, write
from ..model.settle import Chain, Inside
from ..model.compensator import Compensator
from ..programs import STAMP_PREFIX, Program
from ..programs.locate import motion_at, where
from ..programs.rewrite import insert_stamp, stamp_line
from ..settings import Settings
from .agreement import _agreement
from .commands import _CommandStream, _rewrite
from .findings import (
    Commands, Selection, command_findings, dead_band_notes, execution_order, group_rule, missing_xyz,
    outside_envelope, select_with_findings, std_bound,
)
from .guards import check_round_trip

__all__ = [
    "Report", "compensate_program", "rewrite_program", "write_outputs", "output_paths",
]


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
    # each file of the program → (targets compensated, targets left as written) in it
    per_file: dict[str, tuple[int, int]] = field(default_factory=dict)
    written: list[tuple[str, str]] = field(default_factory=list)  # (input file, the path written for it)

    @classmethod
    def merged(cls, reports: list[Report]) -> Report:
        """One report for the programs of a cell (each compensated on its own)."""
        if len(reports) == 1:
            return reports[0]
        out = cls(model=reports[0].model if reports else "", model_sha256=reports[0].model_sha256 if reports else "")
        for r in reports:
            out.targets += r.targets
            out.compensated += r.compensated
            out.left += r.left
            out.moved += r.moved
            out.outside_envelope += r.outside_envelope
            for code, n in r.left_codes.items():
                out.left_codes[code] = out.left_codes.get(code, 0) + n
            out.iterations = max(out.iterations, r.iterations)
            out.max_correction_mm = max(out.max_correction_mm, r.max_correction_mm)
            out.warnings += r.warnings
            out.notes += r.notes
            out.outputs.update(r.outputs)
            out.changed += r.changed
            out.per_file.update(r.per_file)
        weights = [r.compensated for r in reports]
        if sum(weights):
            out.mean_correction_mm = sum(r.mean_correction_mm * w for r, w in zip(reports, weights)) / sum(weights)
        out.warnings = list(dict.fromkeys(out.warnings))
        out.notes = list(dict.fromkeys(out.notes))
        return out

    def files_summary(self) -> list[str]:
        """One line per file written: ``OUT: 12 of 14 compensated, 2 left as written`` (or
        ``written unchanged``), for a run of several files."""
        lines = []
        for source, path in self.written:
            done, left = self.per_file.get(source, (0, 0))
            if done + left == 0:
                said = "no target's numbers in it" + ("" if source in self.changed else ", written unchanged")
            else:
                said = f"{done} of {done + left} compensated" + (f", {left} left as written" if left else "")
            lines.append(f"{path}: {said}")
        return lines

    @property
    def skipped(self) -> int:  # (the name before ``left``)
        return self.left

    @property
    def codes(self) -> list[str]:
        """The codes of the warnings and of the targets left as written, sorted, once each."""
        return sorted({d.code for d in self.warnings} | set(self.left_codes))

    @property
    def unread(self) -> int:
        """Calls to code that was not read (``diagnostics.INCOMPLETE``: P232), one per call."""
        return sum(d.code in INCOMPLETE for d in self.warnings)

    @property
    def complete(self) -> bool:
        """Every Cartesian target was compensated and every routine the program calls was read
        (the CLI's exit 0)."""
        return self.left == 0 and self.moved == 0 and self.unread == 0

    def summary(self) -> str:
        """``17 of 19 compensated, 2 left as written: P201 ×2; model …`` (one line)."""
        head = f"{self.compensated} of {self.targets} compensated"
        if self.left:
            head += f", {self.left} left as written: " + ", ".join(
                f"{code} ×{n}" for code, n in sorted(self.left_codes.items()))
        if self.moved:
            head += (f", {self.moved} motion{'s' if self.moved != 1 else ''} at an offset moved with the point's "
                     f"correction ({P231})")
        if self.unread:
            head += (f", {self.unread} call{'s' * (self.unread != 1)} to a routine not read ({P232}): its targets "
                     "and what it changes are not known")
        details = (f"model {self.model}, max correction {self.max_correction_mm:.3f} mm, mean "
                   f"{self.mean_correction_mm:.3f} mm, {self.iterations} iteration{'s' if self.iterations != 1 else ''}")
        if self.warnings:
            details += f", {len(self.warnings)} warning{'s' if len(self.warnings) != 1 else ''}"
        dead_band = sum(n.code == P321 for n in self.notes)
        if dead_band:
            details += f", {dead_band} in a joint's backlash dead band (P321, -v)"
        kept = sum(n.code == P314 for n in self.notes)
        if kept:
            details += (f", {kept} LIN/CIRC run{'s' * (kept == 1)} in the configuration kept, not the S/T written "
                        "(P314, -v)")
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
    for d in _reader_left(program):
        codes[d.code] += 1
    return codes


def _reader_left(program: Program) -> list[Diagnostic]:
    """The reader's warnings each of which is a target left that never became a row
    (``LEFT_AS_WRITTEN``; a held row's code is counted with the rows)."""
    held = getattr(program, "held", {}) or {}
    return [d for d in program.diagnostics if d.code in LEFT_AS_WRITTEN and d.code not in held]


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


# rounds of compensating again without the targets whose runs disagree (each round removes groups)
MAX_ROUNDS = 8


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
    settings: Settings = Settings(),
    *,
    chain: Chain | None = None,
    stamp: bool = True,
    reachable: Callable[[np.ndarray], np.ndarray] | None = None,
) -> Report:
    """Compensate every resolvable target of ``program``; the new texts are in ``Report.outputs``
    (a file in which no target was compensated is returned as it was, without a stamp). With
    ``settings.rules.orientation`` the orientation is corrected too (A/B/C; RAPID's q1..q4, URScript's rx,ry,rz:
    ``Program.orientation``), with the model's ``rotation_error`` (P306 without it).

    Raises PostprocError for what must not be written: every error of
    :func:`postproc.compensation.findings.findings` (double compensation, a model for another robot or
    tool, unless ``force``; targets beyond reach, NaN or implausibly large corrections;
    partial aggregates with ``fill_partial`` off), under ``strict`` any warning, and
    whatever the last checks (guards.py) refuse. Targets left as written (frame or position
    not known) are counted in ``Report.left`` / ``Report.left_codes``.
    (``chain``, ``stamp``: streaming compensate, a part of a program continuing the parts
    before it, the texts returned unstamped; ``reachable``: robot-base poses → bool mask, the
    nominal robot's IK, P309.)
    """
    rules = settings.rules
    strict, orientation, iterations = rules.strict, rules.orientation, rules.iterations
    selection, found = select_with_findings(program, model, settings, reachable=reachable, chain=chain)
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
        stream = _CommandStream(model, selection, report.iterations, program, rules.max_correction_mm,
                                orientation=orientation, chain=chain, std=std_bound(model, settings) is not None)
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
    after += _moved_with_start(program, selection)
    _raise_first(after, strict)
    assert outputs is not None  # _Unsafe is raised only for what output_rule refuses
    warnings += after
    offset = program.targets.offset
    if offset is not None:  # (the numbers read again are the tokens + what the program adds to them)
        written = written.copy()
        written[:, :3] += offset[selection.rows]
    if orientation and program.orientation == "abc":
        model_notes = model_notes + _gimbal_notes(program, selection.rows, written[:, 3:6])
    outputs = _finish(program, model, selection, outputs, written, stamp=stamp)

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
    report.per_file = _per_file(program, selection)
    return report


def _moved_with_start(program: Program, selection: Selection) -> list[Diagnostic]:
    """P210 at each relative target left as written (a rule after the analysis left it) whose start
    is compensated: the robot moves from the start's command, so the target moves with its correction."""
    relative = program.targets.relative
    if relative is None:
        return []
    chosen = np.zeros(len(relative), bool)
    chosen[selection.rows] = True
    rows = np.flatnonzero(~chosen & (relative >= 0))
    rows = rows[chosen[relative[rows]]]
    return [Diagnostic(*where(program, int(r)), P210, "relative motion left as written; it moves with the "
                       f"correction of the motion it starts from (at {motion_at(program, int(relative[r]))})")
            for r in rows.tolist()]


# a triple changed by this many degrees (A or C) for a rotation this many times smaller: near B = ±90°
GIMBAL_DEG, GIMBAL_RATIO = 1.0, 5.0


def _gimbal_notes(program: Program, rows: np.ndarray, new_abc: np.ndarray) -> list[Diagnostic]:
    """P323, once per file: targets whose new A,B,C differ from those written by much more than
    the rotation between them (near B = ±90°, where A and C turn about one axis: a 0.3°
    correction can read as 7° on A and C in a diff). The triple written is still the nearest."""
    old = program.targets.written_orientation(rows)
    ok = np.isfinite(old).all(axis=1) & np.isfinite(new_abc).all(axis=1)
    change = np.abs((new_abc - old + 180.0) % 360.0 - 180.0).max(axis=1)
    angle = np.full(len(rows), np.inf)
    angle[ok] = frames.rotation_angle_deg(old[ok], new_abc[ok])
    odd = np.flatnonzero(ok & (change > GIMBAL_DEG) & (change > GIMBAL_RATIO * angle))
    out = []
    files = program.targets.file[rows[odd]]
    for f in np.unique(files):
        here = odd[files == f]
        first = int(here[np.argmin(program.targets.line[rows[here]])])
        out.append(Diagnostic(*where(program, int(rows[first])), P323,
                              f"{len(here)} target{'s' * (len(here) != 1)} near B = ±90° in this file (the first "
                              f"here, B {old[first, 1]:.2f}°): A and C change by up to {change[here].max():.2f}° for a "
                              f"rotation of at most {angle[here].max():.3f}° — near B = ±90° A and C turn about one "
                              "axis, so the A,B,C triple nearest the one written moves them far; the rotation written "
                              "is the one the model asks for", "note"))
    return out


def _per_file(program: Program, selection: Selection) -> dict[str, tuple[int, int]]:
    """Each file → (targets compensated, targets left as written), counted as the summary counts
    them: a target's rows by its first run's file; a reader's warning of a target that never
    became a row (LEFT_AS_WRITTEN) at the file it names."""
    t = program.targets
    first = _firsts(program)
    done = _compensated_classes(program, selection)
    files = np.asarray(t.file, int)
    n = len(program.files)
    compensated = np.bincount(files[first & done], minlength=n)
    left = np.bincount(files[first & ~done], minlength=n)
    index = {name: i for i, name in enumerate(program.files)}
    for d in _reader_left(program):
        if d.path in index:
            left[index[d.path]] += 1
    return {name: (int(compensated[i]), int(left[i])) for i, name in enumerate(program.files)}


def rewrite_program(program: Program, commands: Commands, model: Compensator) -> dict[str, str]:
    """The new texts of ``program`` for ``commands`` (computed already, e.g. by ``check``),
    through the same rewrite and last checks (P190, P191) as :func:`compensate_program`."""
    stream = _CommandStream(model, commands.selection, 1, program, math.inf, commands)
    outputs = _rewrite(program, commands.selection, stream)
    _, new_xyz, _ = stream.result()
    return dict(zip(program.files, _finish(program, model, commands.selection, outputs, new_xyz)))


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
            from ..programs.fanuc import insert_stamp as insert_ls_stamp

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
        relative = program.targets.relative
        if relative is not None and relative[missing[0]] >= 0:
            raise PostprocError("--orientation: a relative motion turns the tool by its A, B, C from where it starts: "
                                "postproc corrects its position only; compensate without --orientation",
                                *where(program, int(missing[0])), P312)
        raise PostprocError("--orientation: this target does not write all of A, B, C", *where(program, int(missing[0])),
                            P312)


def output_paths(program: Program, out: Path) -> list[Path]:
    """Where each file of the program goes: the main file to ``out``, its .dat beside it."""
    paths = [out]
    for extra in program.files[1:]:
        paths.append(out.with_suffix(Path(extra).suffix))
    return paths


def write_outputs(outputs: list[tuple[Path, str]]) -> None:
    """:func:`postproc.core.outputs.write` (OS errors as P110) after the one output rule,
    :func:`postproc.core.outputs.check_outputs` (two files of a module onto one path, e.g. ``-o x.dat``
    for a .src; a directory; a folder that cannot be written)."""
    check_outputs([path for path, _ in outputs])
    write(outputs)

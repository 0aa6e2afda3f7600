"""The compensate use case: program → robot-base poses → one batched model call →
corrected numbers in the program's own frame → new texts (+ stamp) → atomic write.

This is what the CLI (``postproc compensate``) and the CAM-hook API
(``postproc.compensate_text`` / ``postproc.compensate_file``) call.
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

from . import frames
from .compensator import Compensator, load_model
from .diagnostics import Diagnostic, PostprocError
from .guards import ROUNDING_MM, check_memory, check_numbers, check_round_trip
from .programs import STAMP_PREFIX, Program, dialect_of, read_program
from .rewrite import check_disjoint, format_many, splice, insert_stamp, stamp_line, write_atomic

__all__ = [
    "Report",
    "load_program",
    "parse_program_text",
    "robot_base_poses",
    "compensate_program",
    "compensate_text",
    "compensate_file",
    "DEFAULT_MAX_CORRECTION_MM",
    "write_outputs",
    "tool_mismatch",
    "robot_mismatch",
]

# An error model that predicts more than this is wrong, not the robot (guard, --max-correction).
DEFAULT_MAX_CORRECTION_MM = 5.0
# Warnings of one kind listed one by one before they are summed up in one line.
MAX_LISTED = 20
STDIN = "<stdin>"


@dataclass
class Report:
    """What a compensation did; ``outputs`` maps each file of the program to its new text."""

    model: str = ""
    model_sha256: str = ""
    targets: int = 0
    compensated: int = 0
    skipped: int = 0
    iterations: int = 0
    max_correction_mm: float = 0.0
    mean_correction_mm: float = 0.0
    outside_envelope: int = 0
    warnings: list[Diagnostic] = field(default_factory=list)
    outputs: dict[str, str] = field(default_factory=dict)

    def summary(self) -> str:
        return (
            f"{self.compensated} of {self.targets} targets compensated with {self.model} "
            f"(max correction {self.max_correction_mm:.3f} mm, mean {self.mean_correction_mm:.3f} mm, "
            f"{self.iterations} iteration{'s' if self.iterations != 1 else ''}"
            + (f", {self.skipped} left as they were" if self.skipped else "")
            + (f", {len(self.warnings)} warning{'s' if len(self.warnings) != 1 else ''}" if self.warnings else "")
            + ")"
        )


# --------------------------------------------------------------------------- reading


def _decode(data: bytes, path: str) -> str:
    if not data.strip():
        raise PostprocError("empty file", path, 1, 1, "P105")
    if b"\x00" in data[:65536]:
        raise PostprocError("binary file (NUL bytes), not a robot program", path, 1, 1, "P106")
    # latin-1 maps every byte to one character: whatever the file's encoding, bytes round-trip
    return data.decode("latin-1")


def _read(path: Path) -> str:
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise PostprocError("no such file", str(path), 0, 0, "P107") from None
    except OSError as exc:
        raise PostprocError(f"cannot read: {exc.strerror}", str(path), 0, 0, "P107") from None
    return _decode(data, str(path))


def companion_dat(src: Path) -> Path | None:
    """The .dat beside a .src (same stem, any case), if there is one."""
    if src.suffix.lower() != ".src" or not src.parent.is_dir():
        return None
    for candidate in (src.with_suffix(".dat"), src.with_suffix(".DAT")):
        if candidate.is_file():
            return candidate
    stem = src.stem.lower()
    for candidate in src.parent.iterdir():
        if candidate.suffix.lower() == ".dat" and candidate.stem.lower() == stem:
            return candidate
    return None


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
) -> Program:
    """Parse a program given as text (a .src with optional .dat text, or a pose list)."""
    dialect = dialect or (dialect_of(name) if name != STDIN and Path(name).suffix else sniff_dialect(text))
    files, texts = [name], [text]
    if dat_text is not None:
        files.append(str(Path(name).with_suffix(".dat")) if name != STDIN else "<stdin.dat>")
        texts.append(dat_text)
    return read_program(files, texts, dialect, config=config_texts)


def _config_texts(config: str | Path | list | None) -> list[str] | None:
    if config is None:
        return None
    paths = config if isinstance(config, list | tuple) else [config]
    return [_read(Path(p)) for p in paths]


def load_program(path: str | Path, config: str | Path | None = None, dialect: str | None = None) -> Program:
    """Read a program from disk: a .src with its .dat companion, a lone .dat, or a pose list.
    ``-`` reads standard input. ``config`` is a ``$config.dat`` for BASE_DATA / TOOL_DATA."""
    if str(path) == "-":
        return parse_program_text(_decode(sys.stdin.buffer.read(), STDIN), STDIN, dialect, None, _config_texts(config))
    path = Path(path)
    if dialect is None:
        try:
            dialect = dialect_of(path)
        except ValueError as exc:
            raise PostprocError(str(exc), str(path), 0, 0, "P108") from None
    dat = companion_dat(path) if dialect == "krl" else None
    check_memory([path] + ([dat] if dat is not None else []))
    files, texts = [str(path)], [_read(path)]
    if dat is not None:
        files.append(str(dat))
        texts.append(_read(dat))
    return read_program(files, texts, dialect, config=_config_texts(config))


# --------------------------------------------------------------------------- frames


def robot_base_poses(program: Program) -> tuple[np.ndarray, np.ndarray]:
    """Every target's pose in the robot base frame [N, 6], and a mask of those whose frame
    is known. Unknown orientation components stay NaN; unresolved rows are NaN."""
    t = program.targets
    out = np.full((len(t), 6), np.nan)
    resolved = t.frame >= 0
    for f in np.unique(t.frame[resolved]):
        rows = np.flatnonzero(t.frame == f)
        base = program.frames[f].base
        out[rows, :3] = frames.transform_points(base, t.poses[rows, :3])
        known = rows[~np.isnan(t.poses[rows, 3:6]).any(axis=1)]
        if not len(known):
            continue
        if np.allclose(base[:3, :3], np.eye(3), atol=1e-12):
            # keep the triple as written: A,B,C and (A±180, 180−B, C±180) are one rotation,
            # but a model and its envelope see numbers
            out[known, 3:6] = t.poses[known, 3:6]
        else:
            rot = base[:3, :3] @ frames.rotation_from_abc(t.poses[known, 3:6])
            out[known, 3:6] = frames.abc_from_rotation(rot)
    return out, resolved


# --------------------------------------------------------------------------- compensating


def _where(program: Program, row: int) -> tuple[str, int, int]:
    t = program.targets
    return program.files[t.file[row]], int(t.line[row]), int(t.col[row])


def _collect(program: Program, rows: np.ndarray, code: str, message: str, severity: str = "warning") -> list[Diagnostic]:
    """One diagnostic per row up to MAX_LISTED, then one that counts the rest."""
    out = [Diagnostic(*_where(program, r), code, message, severity) for r in rows[:MAX_LISTED]]
    if len(rows) > MAX_LISTED:
        path, line, col = _where(program, rows[MAX_LISTED])
        out.append(Diagnostic(path, line, col, code, f"{message} (and {len(rows) - MAX_LISTED} more targets)", severity))
    return out


def _joints_away(q_deg: np.ndarray, ranges: np.ndarray) -> str:
    """'A4 -35.2° (trained -20.1…19.8°)' for the joint of ``q_deg`` [6] farthest out of its range."""
    lo, hi = ranges[:, 0], ranges[:, 1]
    beyond = np.maximum(lo - q_deg, q_deg - hi) / np.maximum(hi - lo, 1e-9)
    j = int(np.argmax(beyond))
    return f"A{j + 1} {q_deg[j]:.1f}°, trained {lo[j]:.1f}…{hi[j]:.1f}°"


def tool_mismatch(program: Program, model: Compensator) -> str | None:
    """Why the model's tool does not fit the program's active $TOOL (None: it fits, or unknown)."""
    frame = model.tool.get("frame") if model.tool else None
    if frame is None:
        return None
    tools = {tuple(np.round(f.tool, 3)) for f in program.frames if f.tool is not None}
    for tool in tools:
        d = np.abs(np.asarray(tool) - np.asarray(frame, float))
        if d[:3].max() > 0.5 or np.abs((d[3:] + 180) % 360 - 180).max() > 0.1:
            return f"the program's $TOOL {[float(v) for v in tool]} is not the model's tool {model.tool.get('name', '')} {list(frame)}"
    return None


def robot_mismatch(robot: str | None, model: Compensator) -> str | None:
    """Why the model (trained on its card's robot) does not fit ``robot`` (None: it does, or unknown)."""
    if not robot:
        return None
    if not model.robot:
        return f"the model does not say which robot it was trained on (the program is for {robot})"
    if model.robot.casefold() != robot.casefold():
        return f"the model was trained on robot {model.robot}, the program is for {robot}"
    return None


def compensate_program(
    program: Program,
    model: Compensator,
    *,
    iterations: int | None = None,
    strict: bool = False,
    force: bool = False,
    max_correction_mm: float = DEFAULT_MAX_CORRECTION_MM,
    robot: str | None = None,
    _commands: tuple[np.ndarray, np.ndarray | None] | None = None,
    orientation: bool = False,
) -> Report:
    """Compensate every resolvable target of ``program``; the new texts are in ``Report.outputs``.
    (``_commands``: ``model.command(poses, iterations, joints=True)`` of exactly these targets,
    already computed by ``check``, which runs this as its last safety net.) With
    ``orientation`` A/B/C are corrected too (the model's ``rotation_error``; P306 without it).

    Raises PostprocError for what must not be written (double compensation, a model for
    another robot (``robot``, the program's robot name) or tool, unless ``force``; targets
    beyond reach, NaN or implausibly large corrections, and under ``strict`` any warning).
    """
    if not (isinstance(max_correction_mm, int | float) and 0 < max_correction_mm < math.inf):
        # NaN would switch the bound off silently: every comparison with it is False
        raise PostprocError(f"--max-correction must be a positive number of mm, not {max_correction_mm}", code="P308")
    report = Report(model=model.name, model_sha256=model.sha256, targets=len(program.targets))
    warnings = list(program.diagnostics)
    if program.stamps and not force:
        index, stamp = next(iter(program.stamps.items()))
        raise PostprocError(f"already compensated ({stamp.lstrip(';# ')}); use --force to compensate again",
                            program.files[index], 1, 1, "P401")
    mismatch = None if model.wants_tool else tool_mismatch(program, model)  # (a model with a tool input: any)
    if mismatch and not force:
        raise PostprocError(mismatch + "; use --force to compensate anyway", program.files[0], 1, 1, "P304")
    mismatch = robot_mismatch(robot, model)
    if mismatch and not force:
        raise PostprocError(mismatch + "; use --force to compensate anyway", str(model.path), 0, 0, "P310")
    shared = next((d for d in program.diagnostics if d.code == "P202"), None)
    if shared is not None and not force:
        # one set of numbers, two frames: the correction written is wrong for one of the uses
        # (in a base turned by 180°, twice the error the robot had uncompensated)
        raise PostprocError(shared.message.replace(": compensated for the first", "") + ": no one correction is "
                            "right for both; give each use its own position, or --force to compensate for the first",
                            shared.path, shared.line, shared.col, "P202")

    t = program.targets
    broken = [i for i, f in enumerate(program.frames) if not np.isfinite(f.base).all()]
    in_broken = np.flatnonzero(np.isin(t.frame, broken)) if broken else []
    if len(in_broken):  # (else its targets would only be 'not fully known', P212, and skipped)
        r = int(in_broken[0])
        raise PostprocError(f"the frame of this target ({program.frames[t.frame[r]].label}) is not a finite number",
                            *_where(program, r), "P103")
    poses, resolved = robot_base_poses(program)
    no_position = resolved & np.isnan(poses[:, :3]).any(axis=1)
    if no_position.any():
        warnings += _collect(program, np.flatnonzero(no_position), "P212",
                             "position not fully known (partial aggregate with no preceding target): left as it is")
    use = resolved & ~no_position
    no_attitude = use & np.isnan(poses[:, 3:6]).any(axis=1)
    if no_attitude.any():
        nominal = model.nominal_attitude
        if nominal is None:
            raise PostprocError("target has no orientation and the model records no nominal attitude",
                                *_where(program, int(np.flatnonzero(no_attitude)[0])), "P213")
        poses[no_attitude, 3:6] = nominal
        warnings += _collect(program, np.flatnonzero(no_attitude), "P213",
                             f"orientation not known: the model's nominal attitude {list(map(float, nominal))} was assumed")
    rows = np.flatnonzero(use)
    sel = poses[rows]
    if not np.isfinite(sel).all():
        bad = rows[~np.isfinite(sel).all(axis=1)]
        raise PostprocError("target is not a finite number", *_where(program, int(bad[0])), "P103")
    too_large = np.abs(sel) >= np.finfo(np.float32).max  # the model takes float32
    if too_large.any():
        r = int(np.flatnonzero(too_large.any(axis=1))[0])
        raise PostprocError(f"target has a component too large for the model (float32): {sel[r].tolist()}",
                            *_where(program, int(rows[r])), "P103")

    far = model.beyond_reach(sel[:, :3])
    if far.any():
        path, line, col = _where(program, int(rows[far][0]))
        raise PostprocError(f"target beyond the robot's reach ({int(far.sum())} such targets): no model can compensate there",
                            path, line, col, "P302")
    if orientation:
        _orientation_check(program, model, rows)
    q_in = tool_in = None
    if model.wants_joints or model.wants_tool:
        rows, sel, q_in, tool_in, found = controller_inputs(program, model, rows, sel)
        warnings += found
    envelope = model.envelope
    if envelope is not None:
        outside = envelope.outside(sel)
        report.outside_envelope = int(outside.sum())
        if outside.any():
            warnings += _collect(program, rows[outside], "P301", "target outside the model's training envelope")

    if strict and warnings:
        first = warnings[0]
        raise PostprocError(f"{first.message} (--strict; {len(warnings)} warning(s) in all)",
                            first.path, first.line, first.col, first.code)

    # rows in program order: the model chains each target to the previous one's command (the
    # approach direction, for models that learn backlash). The model runs on a background
    # thread, chunk by chunk, while this one rewrites the numbers of the chunks already done.
    report.iterations = model.default_iterations if iterations is None else iterations
    if _commands is not None and len(_commands[0]) != len(sel):
        raise ValueError(f"_commands has {len(_commands[0])} rows for {len(sel)} targets")
    stream = _CommandStream(model, sel, report.iterations, program, rows, max_correction_mm, _commands, q_in, tool_in,
                            orientation)
    try:
        outputs = [_rewrite_file(program, index, text, rows, stream) for index, text in enumerate(program.texts)]
    except _Unsafe:
        outputs = None  # the guards below say why, for the worst target of the whole program
    except BaseException:
        stream.close()
        raise
    commanded, new_xyz, joints = stream.result()
    correction = commanded - sel[:, :3]
    size = np.linalg.norm(correction, axis=1)
    if not np.isfinite(correction).all():
        raise PostprocError("the model returned NaN or inf", *_where(program, int(rows[~np.isfinite(size)][0])), "P305")
    if len(size) and size.max() > max_correction_mm:
        worst = int(np.argmax(size))
        raise PostprocError(f"correction of {size[worst]:.3f} mm exceeds the bound of {max_correction_mm} mm: "
                            "the model is wrong here", *_where(program, int(rows[worst])), "P303")
    assert outputs is not None  # _Unsafe is raised only for what the two guards above refuse
    if envelope is not None and joints is not None:
        # in the box and attitude range but not in the joint ranges trained on (a wrist turned
        # the other way): warned as the envelope is, targets already warned for not repeated
        away = envelope.outside_joints(joints) & ~outside
        if away.any():
            report.outside_envelope += int(away.sum())
            found = _collect(program, rows[away], "P301", "target's joint angles outside those the model was trained on "
                             f"({_joints_away(joints[away][0], envelope.joints)})")
            if strict:
                first = found[0]
                raise PostprocError(f"{first.message} (--strict)", first.path, first.line, first.col, first.code)
            warnings += found

    # KRL with position variables only: their numbers may be read elsewhere too (as a frame,
    # by another target), which no single edit shows. Inline aggregates belong to one motion,
    # and each of their tokens was checked above; so were a pose list's. A Program built by
    # hand has no text to read it from.
    if program.from_text and program.dialect == "krl" and program.named_targets:
        check_round_trip(program, outputs, rows, new_xyz)

    stamp = stamp_line(program.comment, STAMP_PREFIX, model.name, model.sha256)
    after = "&" if program.dialect == "krl" else None
    for index, text in enumerate(outputs):
        newline = program.newlines[index] if index < len(program.newlines) else "\n"
        outputs[index] = insert_stamp(text, stamp, newline, after_headers=after)

    report.compensated = len(rows)
    report.skipped = len(t) - len(rows)
    report.max_correction_mm = float(size.max()) if len(size) else 0.0
    report.mean_correction_mm = float(size.mean()) if len(size) else 0.0
    report.warnings = warnings
    report.outputs = dict(zip(program.files, outputs))
    return report


# --------------------------------------------------------------------------- joints and tool


def model_description(model: Compensator):
    """The robot description of the model's robot (the shipped ``models/*.toml`` whose
    [robot] name is the card's ``robot``), or None."""
    from .resources import model_path
    from .robot import load_description

    folder = model_path("kr500.toml").parent
    for path in sorted(folder.glob("*.toml")):
        description = load_description(path)
        if model.robot and description.name.casefold() == model.robot.casefold():
            return description
    return None


def controller_inputs(program: Program, model: Compensator, rows: np.ndarray, sel: np.ndarray):
    """The model's ``joints`` / ``tool`` inputs for targets ``rows`` at base poses ``sel``:
    (rows kept, their poses, joint angles [n, 6] deg or None, TCPs [n, 6] or None, warnings).
    Targets whose configuration has no joint angles on the nominal arm (P309) are left as
    written. The tool is the program's $TOOL where known, else the model's (its card)."""
    from . import configuration
    from .robot import Robot

    description = model_description(model)
    if description is None:
        raise PostprocError(f"the model takes joint angles and postproc has no robot description for its robot "
                            f"{model.robot or '(none named)'}", str(model.path), 0, 0, "P311")
    card_tool = model.tool.get("frame") if model.tool else None
    default_tool = np.asarray(card_tool if card_tool is not None else description.tool, float)
    tools = np.tile(default_tool, (len(rows), 1))
    t = program.targets
    for f in np.unique(t.frame[rows]):
        if program.frames[f].tool is not None:
            tools[t.frame[rows] == f] = program.frames[f].tool
    warnings: list[Diagnostic] = []
    q = None
    if model.wants_joints:
        robot = Robot(description.replace(tool=default_tool))
        first = robot if np.array_equal(tools[0], default_tool) else Robot(description.replace(tool=tools[0]))
        start, _ = first.ik(sel[:1], robot.home_q)
        if model.has_joints and np.isfinite(start).all():  # the branch of the model's own IK
            _, own = model.predict(sel[:1], joints=True, q=start, tool=tools[:1] if model.wants_tool else None)
            start = own if np.isfinite(own).all() else start
        q, ok = configuration.target_joints(robot, t, rows, sel, tools,
                                            start[0] if np.isfinite(start).all() else None)
        if not ok.all():
            warnings += _collect(program, rows[~ok], "P309", "no joint angles for this target in its arm configuration "
                                 "(S/T, or the one its motion keeps) on the nominal robot: left as it is")
            rows, sel, q, tools = rows[ok], sel[ok], q[ok], tools[ok]
    return rows, sel, q, (tools if model.wants_tool else None), warnings


def _orientation_check(program: Program, model: Compensator, rows: np.ndarray) -> None:
    """Refuse ``--orientation`` when it cannot be done right: no ``rotation_error`` output
    (P306), A/B/C tokens the reader does not locate (P312) or targets without A/B/C (P312)."""
    if not model.has_rotation:
        raise PostprocError("the model has no output 'rotation_error': it cannot correct orientation (train it on "
                            "data with a_meas,b_meas,c_meas); compensate without --orientation", str(model.path),
                            0, 0, "P306")
    spans = program.targets.abc_spans
    if spans is None:
        raise PostprocError(f"--orientation: the {program.dialect} reader does not locate A/B/C numbers yet",
                            program.files[0], 1, 1, "P312")
    missing = rows[(spans[rows, :, 0] < 0).any(axis=1)]
    if len(missing):
        raise PostprocError("--orientation: this target does not write all of A, B, C", *_where(program, int(missing[0])),
                            "P312")


def _local_attitude(abc_base: np.ndarray, bases: list, frame_of: np.ndarray, written: np.ndarray) -> np.ndarray:
    """A,B,C in each target's own frame of commanded attitudes in the base, on the triple and
    turns nearest the numbers as written."""
    out = abc_base.copy()
    for f in np.unique(frame_of):
        here = frame_of == f
        rot = bases[f][:3, :3]
        if not np.allclose(rot, np.eye(3), atol=1e-12):
            out[here] = frames.abc_from_rotation(rot.T @ frames.rotation_from_abc(abc_base[here]))
    alt = np.stack([out[:, 0] + 180.0, 180.0 - out[:, 1], out[:, 2] + 180.0], axis=1)
    near = [written + (t - written + 180.0) % 360.0 - 180.0 for t in (out, alt)]
    return np.where((np.abs(near[1] - written).max(axis=1) < np.abs(near[0] - written).max(axis=1))[:, None],
                    near[1], near[0])


# Edits are made this many tokens at a time: a million-target program never holds all its
# tokens, their replacements and the pieces of the new text at once (peak memory).
EDIT_CHUNK = 1 << 17


class _Unsafe(Exception):
    """A chunk's commands fail a guard: stop rewriting, the caller's guards raise the error."""


class _CommandStream:
    """``model.command_chunks`` on a background thread (onnxruntime releases the GIL): the
    commands and the corrected numbers in each target's own frame, filled in row order, so
    the rewrite of the first targets overlaps the model run on the later ones."""

    def __init__(self, model: Compensator, poses: np.ndarray, iterations: int, program: Program,
                 rows: np.ndarray, max_correction_mm: float, computed: tuple | None = None,
                 q_deg: np.ndarray | None = None, tool: np.ndarray | None = None, orientation: bool = False):
        self.commanded = np.full((len(poses), 3), np.nan)
        # the corrected numbers in each target's frame: X,Y,Z (and A,B,C with ``orientation``)
        self.new_xyz = np.full((len(poses), 6 if orientation else 3), np.nan)
        self._written_abc = program.targets.poses[rows, 3:6] if orientation else None
        # the targets' joint angles, only where the model card has joint ranges to check them against
        envelope = model.envelope
        wanted = model.has_joints and envelope is not None and envelope.joints is not None
        self.joints = np.full((len(poses), 6), np.nan) if wanted else None
        self.ready = 0  # rows [0, ready) are filled
        self.unsafe = False
        self._error: BaseException | None = None
        self._cancel = False
        self._changed = threading.Condition()
        t = program.targets
        self._frame_of = t.frame[rows]
        self._written = t.poses[rows, :3]
        self._bases = [f.base for f in program.frames]
        if computed is not None:  # (commands and joints of every row, from the caller)
            chunks = iter([(0, *computed)])
        else:  # checks ``iterations`` here, not on the thread
            chunks = model.command_chunks(poses, iterations, joints=wanted, q_deg=q_deg, tool=tool,
                                          orientation=orientation)
        self._thread = threading.Thread(target=self._run, args=(chunks, poses, max_correction_mm),
                                        name="postproc-model", daemon=True)
        self._thread.start()

    def _run(self, chunks: Iterator[tuple[int, np.ndarray, np.ndarray | None]], poses: np.ndarray,
             bound: float) -> None:
        try:
            for start, commands, q in chunks:
                if self._cancel:
                    return
                end = start + len(commands)
                if self._written_abc is not None:
                    self.new_xyz[start:end, 3:] = _local_attitude(commands[:, 3:6], self._bases, self._frame_of[start:end],
                                                                  self._written_abc[start:end])
                    commands = commands[:, :3]
                correction = commands - poses[start:end, :3]
                # back into each target's own frame: only the rotation of its base applies to a shift
                local = np.empty_like(correction)
                frame_of = self._frame_of[start:end]
                for f in np.unique(frame_of):
                    here = frame_of == f
                    local[here] = frames.rotate_vectors(frames.inverse(self._bases[f]), correction[here])
                self.commanded[start:end] = commands
                if self.joints is not None and q is not None:
                    self.joints[start:end] = q
                self.new_xyz[start:end, :3] = self._written[start:end] + local
                with np.errstate(invalid="ignore"):
                    unsafe = not (np.isfinite(correction).all() and np.linalg.norm(correction, axis=1).max() <= bound)
                with self._changed:
                    self.unsafe |= unsafe
                    self.ready = end
                    self._changed.notify_all()
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

    def result(self) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """(commanded [N, 3] in the robot base, corrected numbers [N, 3] in each target's frame,
        the targets' joint angles [N, 6] deg or None), every row, once the thread is done."""
        self._thread.join()
        if self._error is not None:
            raise self._error
        return self.commanded, self.new_xyz, self.joints


def _rewrite_file(program: Program, index: int, text: str, rows: np.ndarray, stream: _CommandStream) -> str:
    """``text`` (file ``index`` of the program) with the X/Y/Z tokens of targets ``rows``
    replaced by their corrected numbers from ``stream`` as they come, each token checked
    before and after (guards.check_numbers)."""
    t = program.targets
    mine = np.flatnonzero(t.file[rows] == index)
    spans = t.spans if stream.new_xyz.shape[1] == 3 else np.concatenate([t.spans, t.abc_spans], axis=1)
    width = spans.shape[1]
    starts = spans[rows[mine], :, 0].ravel()
    ends = spans[rows[mine], :, 1].ravel()
    at_row = np.repeat(mine, width)  # position in ``rows`` (and in the stream)
    axis = np.tile(np.arange(width), len(mine))
    keep = starts >= 0  # components the aggregate leaves out have no token
    order = np.argsort(starts[keep], kind="stable")
    starts, ends, at_row, axis = (a[keep][order] for a in (starts, ends, at_row, axis))
    if not len(starts):
        return text
    check_disjoint(starts, ends)
    owners = rows[at_row]
    read = t.poses[owners, axis]
    parts, prev = [], 0
    for at in range(0, len(starts), EDIT_CHUNK):
        chunk = slice(at, at + EDIT_CHUNK)
        s, e = starts[chunk].tolist(), ends[chunk].tolist()
        tokens = [text[a:b] for a, b in zip(s, e)]
        check_numbers(program, owners[chunk], tokens, read[chunk], 0.0, "is not the {} read for the target")
        values = stream.wait(int(at_row[chunk].max()) + 1)[at_row[chunk], axis[chunk]]
        replacements = format_many(tokens, values)
        check_numbers(program, owners[chunk], replacements, values, ROUNDING_MM,
                      "does not read back as the corrected {}")
        parts.append(splice(text, prev, s, e, replacements))
        prev = e[-1]
    parts.append(text[prev:])
    return "".join(parts)


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
    iterations: int | None = None,
    strict: bool = False,
    force: bool = False,
    max_correction_mm: float = DEFAULT_MAX_CORRECTION_MM,
    robot: str | None = None,
    orientation: bool = False,
) -> tuple[str, Report]:
    """Compensate a program given as text; returns the new text and the report.

    For a KRL module pass its .dat as ``dat_text``: the new .dat is
    ``report.outputs[<name>.dat]``. ``model`` is a loaded Compensator (reuse one for many
    calls), a path, or None for the shipped default model.
    """
    program = parse_program_text(text, name, dialect, dat_text, _config_texts(config))
    report = compensate_program(program, _model(model), iterations=iterations, strict=strict, force=force,
                                max_correction_mm=max_correction_mm, robot=robot, orientation=orientation)
    return report.outputs[program.files[0]], report


def output_paths(program: Program, out: Path) -> list[Path]:
    """Where each file of the program goes: the main file to ``out``, its .dat beside it."""
    paths = [out]
    for extra in program.files[1:]:
        paths.append(out.with_suffix(Path(extra).suffix))
    return paths


def compensate_file(
    path: str | Path,
    out: str | Path,
    model: Compensator | str | Path | None = None,
    *,
    config: str | Path | None = None,
    iterations: int | None = None,
    strict: bool = False,
    force: bool = False,
    max_correction_mm: float = DEFAULT_MAX_CORRECTION_MM,
    robot: str | None = None,
    orientation: bool = False,
) -> Report:
    """Compensate a program file (with its .dat) into ``out`` (its .dat beside it).
    Nothing is written unless everything succeeded; the files are replaced atomically."""
    program = load_program(path, config)
    report = compensate_program(program, _model(model), iterations=iterations, strict=strict, force=force,
                                max_correction_mm=max_correction_mm, robot=robot, orientation=orientation)
    if str(out) == "-":
        if len(program.files) > 1:
            raise PostprocError("a program with a .dat cannot be written to standard output; give -o FILE",
                                program.files[0], 0, 0, "P109")
        sys.stdout.buffer.write(report.outputs[program.files[0]].encode("latin-1"))
        sys.stdout.buffer.flush()
        return report
    targets = output_paths(program, Path(out))
    write_outputs([(p, report.outputs[f]) for p, f in zip(targets, program.files)])
    return report


def write_outputs(outputs: list[tuple[Path, str]]) -> None:
    """:func:`write_atomic`, refusing what it cannot do right (two files of a module onto one
    path, e.g. ``-o x.dat`` for a .src; a directory) and reporting OS errors as P110."""
    seen: dict[Path, Path] = {}
    for path, _ in outputs:
        key = path.resolve()
        if key in seen:
            raise PostprocError(f"two files of the program would both be written to {path}: give -o a name "
                                "with the program's suffix", str(path), 0, 0, "P110")
        if path.is_dir():
            raise PostprocError("is a directory: give -o a file name", str(path), 0, 0, "P110")
        parent = next((p for p in path.parents if p.exists()), None)
        if parent is not None and not parent.is_dir():
            raise PostprocError(f"cannot write: {parent} is not a directory", str(path), 0, 0, "P110")
        seen[key] = path
    try:
        write_atomic(outputs)
    except OSError as exc:
        where = exc.filename2 or exc.filename or outputs[0][0]
        raise PostprocError(f"cannot write: {exc.strerror or exc}", str(where), 0, 0, "P110") from None

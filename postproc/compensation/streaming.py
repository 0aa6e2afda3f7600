"""Streaming compensate: a long CAM-style KRL ``.src`` a chunk of targets at a time, in memory
bounded by the chunk, not the program.

The program must be a forward stream the reader's state at each chunk does not depend on:

* a *header* (everything before the first motion) with one ``DEF``, no motion, no ``END``:
  ``$BASE``/``$TOOL``, settings, declarations: read again in front of every chunk, so every chunk starts in the same reader state the whole program's body does;
* a *body* of simple motion lines only: ``LIN``/``PTP`` with a full inline aggregate
  ``{X …,Y …,Z …,A …,B …,C …[,S …,T …]}``, an optional approximation (``C_VEL``, …) and
  comment; blank and comment lines between them;
* a *tail*: the ``END`` line, blank and comment lines after it;
* no ``.dat`` beside it (its data lists could hold points).

Each chunk (STREAM_TARGETS targets, COMMAND_CHUNK for a model that settles the approach: the
model's batches fall on the same rows as in the in-memory path, so the commands are the same
float32 numbers) is read as the program
``header + chunk + END`` and compensated by :func:`postproc.compensation.pipeline.compensate_program`
with a ``compensator.Chain``: the previous command (``previous_pose``), the approach settling
and the controller's configuration chain carry from chunk to chunk. Its guards (P190, P191)
run per chunk and their errors are located in the whole file. The new text goes to the
temporary file of the atomic write as it comes: nothing is at the output name unless every
chunk succeeded.

Anything else falls back to the in-memory path (:class:`Fallback`, before anything is at the
output name): a program of another shape, and any chunk with a finding (a warning, a target
left as written, an error other than the guards'), so that every message, and its
whole-program summaries ("and N more targets"), are the in-memory path's own. (Where that path
refuses the program as too large for memory, P111, a chunk's own error is raised instead:
``Fallback.error``, located in the whole file.)
"""
from __future__ import annotations

import re
import sys
from itertools import islice
from pathlib import Path
from typing import Iterator

from ..core.diagnostics import P109, P111, P190, P191, P321, Diagnostic, PostprocError
from ..core.progress import ProgressBar, reporting
from ..model import compensator
from ..model.compensator import Compensator
from ..model.settle import Chain
from ..programs import STAMP_PREFIX
from ..programs.io import config_texts, backup_active, companion_dat, load_program, read_program
from ..programs.rewrite import insert_stamp, stamp_line
from ..settings import Settings
from .api import model_of, settings_of
from .pipeline import Report, compensate_program, output_paths, write_outputs

__all__ = ["STREAM_BYTES", "Fallback", "compensate_stream", "streams"]

# compensate_file streams a .src larger than this (the in-memory path takes ~12 bytes of memory
# per byte of such a program: 8 MB → ~300 MB at most)
STREAM_BYTES = 8 << 20
# targets per chunk where the model does not settle the approach: a multiple of the model's
# batch (compensator.PREDICT_BATCH) that divides COMMAND_CHUNK, so each row is computed in the
# same batch as in the in-memory path (the same float32 numbers); settling models take
# COMMAND_CHUNK (the settling's passes over a chunk differ at other borders by ~1e-4 mm)
STREAM_TARGETS = 8 * compensator.PREDICT_BATCH
# a header or tail longer than this is not a CAM program's: the in-memory path
HEADER_BYTES = 1 << 20
TAIL_BYTES = 1 << 16
# the last checks, run per chunk: their errors are the stream's own
GUARDS = (P190, P191)

_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)"
_SEP = r"[ \t]*,[ \t]*"
_BITS = r"(?:\d+|'B[01]+')"
_SIMPLE = (rf"[ \t]*(?:LIN|PTP)[ \t]*\{{[ \t]*X[ \t]+{_NUM}{_SEP}Y[ \t]+{_NUM}{_SEP}Z[ \t]+{_NUM}{_SEP}"
           rf"A[ \t]+{_NUM}{_SEP}B[ \t]+{_NUM}{_SEP}C[ \t]+{_NUM}(?:{_SEP}S[ \t]+{_BITS}{_SEP}T[ \t]+{_BITS})?[ \t]*\}}"
           r"(?:[ \t]*C_(?:VEL|DIS|PTP|ORI))?[ \t]*(?:;[^\r\n]*)?\r?")
_BLANK = r"[ \t]*(?:;[^\r\n]*)?\r?"
_SIMPLE_LINE = re.compile(_SIMPLE + r"\n?", re.I)
_BLANK_LINES = re.compile(rf"^{_BLANK}\n", re.M)
_BLANK_LINE = re.compile(_BLANK + r"\n?")
_BLANKS = re.compile(rf"(?:{_BLANK}\n)*")
# the first line of a text that is neither a simple motion nor blank
_OTHER_LINE = re.compile(rf"^(?!(?:{_SIMPLE}|{_BLANK})$).", re.M | re.I)
_END_LINE = re.compile(r"[ \t]*END[ \t]*(?:;[^\r\n]*)?\r?(?:\n|\Z)", re.I)
_HEADER_REFUSED = re.compile(r"^[ \t]*(?:END\w*|GLOBAL\b.*|DEFFCT\b.*|DEFDAT\b.*)$|"
                             r"\b(?:S?LIN|S?PTP|S?CIRC|SPL|LIN_REL|PTP_REL|CIRC_REL)\b", re.M | re.I)
_DEF_LINE = re.compile(r"^[ \t]*DEF\b", re.M | re.I)


class Fallback(Exception):
    """The program is not one the stream carries exactly: compensate it in memory. ``error``:
    the error a chunk raised (located in the whole file), if that is why."""

    def __init__(self, reason: str, error: PostprocError | None = None):
        super().__init__(reason)
        self.error = error


def streams(path: str | Path, out: str | Path, orientation: bool = False) -> bool:
    """Whether ``compensate_file`` streams by default: a KRL ``.src`` larger than STREAM_BYTES
    to a file (the program's shape is checked as it is read)."""
    if str(path) == "-" or str(out) == "-" or orientation:
        return False
    path = Path(path)
    try:
        return path.suffix.lower() == ".src" and path.stat().st_size > STREAM_BYTES
    except OSError:
        return False


class _Source:
    """The program file read a chunk at a time: ``header``, then ``chunks()`` (first line
    number, text of the body's next ``size`` targets), then ``tail``."""

    def __init__(self, fh, size: int):
        self.fh, self.size = fh, size
        self.line = 1  # the next line's number
        head: list[bytes] = []
        length = 0
        for raw in fh:
            if _SIMPLE_LINE.fullmatch(raw.decode("latin-1")):
                self.first = raw.decode("latin-1")
                break
            head.append(raw)
            length += len(raw)
            if length > HEADER_BYTES:
                raise Fallback("a long header")
        else:
            raise Fallback("no simple motion")
        self.header = b"".join(head).decode("latin-1")
        if len(_DEF_LINE.findall(self.header)) != 1 or _HEADER_REFUSED.search(self.header):
            raise Fallback("a header with motions, blocks or several routines")
        self.line += self.header.count("\n")
        self.tail: str | None = None

    def chunks(self) -> Iterator[tuple[int, str, bool]]:
        """(first line number, text, last) of each chunk of the body; ``tail`` is set before the
        last is yielded. Only the chunk in hand is held (and the lines after it up to the next
        target, to know whether it is the last)."""
        parts, targets = [self.first], 1
        while True:
            raw = list(islice(self.fh, self.size - targets))
            text = b"".join(raw).decode("latin-1")
            count = len(raw)
            del raw
            other = _OTHER_LINE.search(text)
            if other is not None or not count:  # the body ends in these lines
                parts.append(text[:other.start()] if other is not None else text)
                self._tail(text[other.start():] if other is not None else "")
                yield self._emit("".join(parts), True)
                return
            parts.append(text)
            targets += count - len(_BLANK_LINES.findall(text))  # (blank and comment lines are no targets)
            if targets < self.size:
                continue
            peeked = []  # the blank lines after the chunk and the line after them
            for raw_line in self.fh:
                peeked.append(raw_line.decode("latin-1"))
                if not _BLANK_LINE.fullmatch(peeked[-1]):
                    break
            if peeked and _SIMPLE_LINE.fullmatch(peeked[-1]):
                yield self._emit("".join(parts), False)
                parts, targets = peeked, 1
            else:
                self._tail("".join(peeked))
                yield self._emit("".join(parts), True)
                return

    def _tail(self, start: str) -> None:
        """The tail: ``start`` and the rest of the file, blank lines, END, blank lines."""
        more = self.fh.read(TAIL_BYTES + 1).decode("latin-1")
        tail = start + more
        end = _END_LINE.match(tail, _BLANKS.match(tail).end())
        if len(more) > TAIL_BYTES or end is None or _OTHER_LINE.search(tail, end.end()):
            raise Fallback("not a CAM program's end")
        self.tail = tail

    def _emit(self, body: str, last: bool) -> tuple[int, str, bool]:
        first = self.line
        self.line += body.count("\n")
        return first, body, last


def _relocated(exc: PostprocError, header_lines: int, offset: int) -> PostprocError:
    line = exc.line + offset if exc.line > header_lines else exc.line
    return PostprocError(exc.message, exc.path, line, exc.col, exc.code)


def compensate_stream(
    path: str | Path,
    out: str | Path,
    model: compensator.Compensator | str | Path | None = None,
    settings: Settings = Settings(),
    *,
    chunk: int | None = None,
) -> Report:
    """Compensate ``path`` into ``out`` a chunk of ``chunk`` targets at a time (default
    STREAM_TARGETS, or the model's ``command_chunk`` when smaller or for a model that settles
    the approach: the same numbers as the in-memory path; other sizes may differ in the
    float32 model's last bits), with ``settings`` as ``compensate_program``. Raises
    :class:`Fallback` (nothing at ``out``) for what it does not carry exactly (module text),
    PostprocError for the errors of the last checks (located in the whole file) and of the write.
    ``Report.outputs`` is empty: the new text is only in the file."""
    path = Path(path)
    if path.suffix.lower() != ".src" or companion_dat(path) is not None or settings.rules.orientation:
        raise Fallback("not a lone .src")
    model = model_of(model)
    if chunk is None:
        chunk = model.command_chunk if model.settles else min(model.command_chunk, STREAM_TARGETS)
    size = chunk
    config = settings.reading.config_list
    configs = config_texts(config)
    active = backup_active(config, settings.reading.active)
    name = str(path)
    try:
        fh = path.open("rb")
    except OSError:
        raise Fallback("cannot read") from None
    with fh:
        source = _Source(fh, size)
        header = source.header
        header_lines = header.count("\n")
        chain = Chain()
        total = Report(model=model.name, model_sha256=model.sha256)
        corrections = 0.0

        def part(first: int, body: str, tail: str) -> tuple[str, Report, str]:
            offset = first - (header_lines + 1)
            try:
                with reporting(False):  # (the file's bar, not one per chunk)
                    program = read_program([name], [header + body + tail], "krl", config=configs, active=active)
                    report = compensate_program(program, model, settings, chain=chain, stamp=False)
            except PostprocError as exc:
                if exc.code in GUARDS:
                    raise _relocated(exc, header_lines, offset) from None
                raise Fallback(exc.code, _relocated(exc, header_lines, offset)) from None
            if report.warnings or report.left or program.diagnostics or not report.compensated:
                raise Fallback("findings")
            text = report.outputs[name]
            if not (text.startswith(header) and text.endswith(tail)):
                raise Fallback("the header or tail changed")
            report.notes = [Diagnostic(d.path, d.line + offset if d.line > header_lines else d.line, d.col, d.code,
                                       d.message, d.severity) for d in report.notes]
            return text[len(header):len(text) - len(tail)], report, program.comment

        def pieces() -> Iterator[str]:
            nonlocal corrections
            newline = "\r\n" if header.endswith("\r\n") else "\n"
            for first, text, last in source.chunks():
                # the chunk read as a program of its own: the header, the chunk, END (the last: the tail)
                body, report, comment = part(first, text, source.tail if last else "END" + newline)
                bar.update(len(text))
                del text
                # the header's notes (P224) come with every chunk: said once, at the first
                total.notes += [d for d in report.notes if d.code == P321 or not total.targets]
                if not total.targets:
                    yield insert_stamp(header, stamp_line(comment, STAMP_PREFIX, model.name, model.sha256), newline,
                                       after_headers="&")
                    total.iterations = report.iterations
                yield body
                total.targets += report.targets
                total.compensated += report.compensated
                total.max_correction_mm = max(total.max_correction_mm, report.max_correction_mm)
                corrections += report.mean_correction_mm * report.compensated
            yield source.tail

        with ProgressBar("compensate", path.stat().st_size, "B", scale=True) as bar:
            write_outputs([(Path(out), pieces())])
    total.mean_correction_mm = corrections / total.compensated if total.compensated else 0.0
    total.changed = [name]
    return total


def compensate_file(
    path: str | Path,
    out: str | Path,
    model: Compensator | str | Path | None = None,
    *,
    settings: Settings | None = None,
    stream: bool | None = None,
    **options,
) -> Report:
    """Compensate a program file (with its .dat) into ``out`` (its .dat beside it).
    Nothing is written unless everything succeeded; the files are replaced atomically.
    ``settings`` and ``options`` as :func:`postproc.compensate_text` (``config``, ``active``,
    ``strict``, …). ``stream`` (default: a KRL .src larger than ``STREAM_BYTES``): a chunk of
    targets at a time, in memory bounded by the chunk (this module; the same bytes;
    programs it does not carry exactly are compensated in memory); ``Report.outputs`` is then
    empty."""
    settings = settings_of(settings, options)
    reading = settings.reading
    refusal = None  # (a chunk's error: raised where the program is too large for the in-memory path)
    if streams(path, out, settings.rules.orientation) if stream is None else stream:
        model = model_of(model)
        try:
            return compensate_stream(path, out, model, settings)
        except Fallback as fallback:
            refusal = fallback.error
    try:
        program = load_program(path, reading.config_list, reading.dialect, reading.active)
    except PostprocError as exc:
        if exc.code == P111 and refusal is not None:
            raise refusal from None
        raise
    report = compensate_program(program, model_of(model), settings)
    if str(out) == "-":
        if len(program.files) > 1:
            raise PostprocError("a program with a .dat cannot be written to standard output; give -o FILE",
                                program.files[0], 0, 0, P109)
        sys.stdout.buffer.write(report.outputs[program.files[0]].encode("latin-1"))
        sys.stdout.buffer.flush()
        return report
    targets = output_paths(program, Path(out))
    write_outputs([(p, report.outputs[f]) for p, f in zip(targets, program.files)])
    report.written = [(f, str(p)) for p, f in zip(targets, program.files)]
    return report

"""The one atomic writer: all files or none (texts as latin-1, bytes as they are), with a
journal for the renames of a multi-file write (a .src/.dat pair, a cell) that :func:`recover`
completes after a crash between them. Every subcommand writes through it (``outputs.write``
adds the P110 wording of OS errors)."""
from __future__ import annotations

import os
import tempfile
from collections.abc import Sequence
from pathlib import Path

__all__ = ["write_atomic", "recover"]


def write_atomic(outputs: Sequence[tuple[Path, str | bytes]]) -> None:
    """Write all files or none: each to a temp file in its directory, then rename them all.
    Texts are written as latin-1 (a program's bytes, as read); bytes as they are; an iterable of
    str or bytes pieces is written piece by piece (a long output streamed, not joined first).

    If a rename fails, files already renamed are put back as they were. Two renames cannot
    be one atomic step, so for a module (.src + .dat) a journal naming the renames is
    written first and removed last: if the process dies between the renames (SIGKILL,
    power loss), :func:`recover` — which the next write to the same files runs first —
    completes them, so a mix of new and old files never outlives the next run.
    """
    outputs = list(outputs)
    journal = _journal(outputs[0][0]) if len(outputs) > 1 else None
    if journal is not None:
        recover(outputs[0][0])
    temps: list[tuple[Path, Path]] = []
    backups: dict[Path, Path] = {}
    try:
        for path, text in outputs:
            temps.append((_write_temp(path, text), path))
        # the old versions, kept (hard links: no copy) until every rename has succeeded; all
        # made before the first rename, so that the renames follow each other closely
        for _, path in temps:
            if path.is_file():
                backup = path.with_name(f".{path.name}.{os.getpid()}.bak")
                backup.unlink(missing_ok=True)
                os.link(path, backup)
                backups[path] = backup
        if journal is not None:
            _write_journal(journal, temps, backups)
    except BaseException:
        for tmp in [t for t, _ in temps] + list(backups.values()):
            tmp.unlink(missing_ok=True)
        raise
    _rename_all(temps, backups, journal)


def _write_temp(path: Path, text) -> Path:
    """``text`` (str, bytes or an iterable of pieces) in a new temp file beside ``path``, synced,
    with ``path``'s permissions (or the umask's for a new file); its path."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            for piece in [text] if isinstance(text, (str, bytes)) else text:  # or an iterable of pieces
                fh.write(piece.encode("latin-1") if isinstance(piece, str) else piece)
            fh.flush()
            os.fsync(fh.fileno())
        if path.exists():
            os.chmod(tmp, path.stat().st_mode & 0o777)
        else:
            os.chmod(tmp, 0o666 & ~_umask())
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return Path(tmp)


def _rename_all(temps: list[tuple[Path, Path]], backups: dict[Path, Path], journal: Path | None) -> None:
    """The renames temp → target; if one fails, the files already renamed are put back."""
    renamed: list[Path] = []
    try:
        for tmp, path in temps:
            os.replace(tmp, path)
            renamed.append(path)
    except BaseException:
        if journal is not None:  # first: a rollback must not be rolled forward later
            journal.unlink(missing_ok=True)
        for path in reversed(renamed):
            if path in backups:
                os.replace(backups.pop(path), path)
            else:
                path.unlink(missing_ok=True)
        for tmp in [t for t, _ in temps] + list(backups.values()):
            tmp.unlink(missing_ok=True)
        raise
    if journal is not None:
        journal.unlink(missing_ok=True)
    for backup in backups.values():
        backup.unlink(missing_ok=True)


def _journal(first: Path) -> Path:
    return first.with_name(f".{first.name}.postproc-journal")


def _write_journal(journal: Path, temps: list[tuple[Path, Path]], backups: dict[Path, Path]) -> None:
    """The renames to come, one 'temp<TAB>target<TAB>backup' line each; written to a temp
    file and renamed, so a journal is complete or absent."""
    lines = "".join(f"{tmp}\t{path}\t{backups.get(path, '')}\n" for tmp, path in temps)
    fd, tmp = tempfile.mkstemp(prefix=journal.name + ".", suffix=".tmp", dir=journal.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(lines)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, journal)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def recover(first: Path) -> bool:
    """Complete the renames of a write to ``first`` (and the files written with it) that
    was killed between them; True if there was one. Safe to run any number of times."""
    journal = _journal(Path(first))
    try:
        lines = journal.read_text(encoding="utf-8").splitlines()
    except FileNotFoundError:
        return False
    for line in lines:
        tmp, path, backup = line.split("\t")
        if Path(tmp).exists():
            os.replace(tmp, path)
        if backup:
            Path(backup).unlink(missing_ok=True)
    journal.unlink(missing_ok=True)
    return True


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask

"""The one rule for output paths (``-o``) of every subcommand, checked before the work.

An output is refused with ``P110`` (exit 2, nothing written) when it

* is a directory, or lies under a path that exists and is not a directory;
* would be created in a folder that cannot be written (missing folders are created,
  as :func:`postproc.core.atomic.write_atomic` does for every subcommand);
* is one of the command's inputs (the same file, also through a link), unless the command
  allows ``--in-place`` and it was given;
* is named twice (two files of one module onto one path).

:func:`check_outputs` runs before reading or fitting anything, so that ``train`` does not fit
for half a minute and then fail on its output path; :func:`write` is
:func:`~postproc.core.atomic.write_atomic` with OS errors (disk full, permissions) as ``P110``.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Iterable, Sequence

from .diagnostics import P110, PostprocError


def _same(a: Path, b: Path) -> bool:
    # realpath also folds "missing/.." (which write_atomic would create, then write through)
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    try:
        return os.path.samefile(a, b)  # hard links
    except OSError:  # one of them does not exist (yet)
        return False


def check_outputs(outputs: Iterable[str | Path], inputs: Iterable[str | Path] = (), *, in_place: bool | None = None,
                  option: str = "-o") -> list[Path]:
    """Refuse (``P110``) outputs that cannot or must not be written; return them as paths.

    ``"-"`` (standard output) and ``"-"`` inputs (standard input) are skipped. ``in_place``:
    None when the command has no ``--in-place`` (an input is then never overwritten), else
    whether it was given.
    """
    paths = [Path(p) for p in outputs if str(p) != "-"]
    sources = [Path(p) for p in inputs if p is not None and str(p) != "-"]
    seen: list[Path] = []
    for path in paths:
        if any(_same(path, other) for other in seen):
            raise PostprocError(f"two files of the program would both be written to {path}: give {option} a name "
                                "with the program's suffix", str(path), code=P110)
        seen.append(path)
        if path.is_dir():
            raise PostprocError(f"is a directory: give {option} a file name",
                                str(path), code=P110)
        parent = next((p for p in path.absolute().parents if p.exists()), None)
        if parent is not None and not parent.is_dir():
            raise PostprocError(f"cannot write: {parent} is not a directory", str(path), code=P110)
        if parent is not None and not os.access(parent, os.W_OK | os.X_OK):
            raise PostprocError(f"cannot write: no permission to write in {parent}", str(path), code=P110)
        for source in sources:
            if _same(path, source):
                if in_place:
                    continue
                how = " (or --in-place to overwrite it)" if in_place is not None else ""
                raise PostprocError(f"{option} is the input {source}: writing would overwrite it; give another "
                                    f"{option}{how}", str(path), code=P110)
    return paths


def write(outputs: Sequence[tuple[Path, str | bytes]]) -> None:
    """:func:`postproc.core.atomic.write_atomic`, OS errors reported as ``P110`` at the path."""
    from .atomic import write_atomic

    try:
        write_atomic(outputs)
    except OSError as exc:
        where = exc.filename2 or exc.filename or outputs[0][0]
        raise PostprocError(f"cannot write: {exc.strerror or exc}", str(where), code=P110) from None

"""Where a target row stands in the program's text, and located findings for rows."""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..core.diagnostics import Diagnostic
from .model import Program

__all__ = ['collect', 'motion_at', 'MAX_LISTED']


# Findings of one kind listed one by one before the next one sums up the rest.
MAX_LISTED = 20


def where(program: Program, row: int) -> tuple[str, int, int]:
    t = program.targets
    return program.files[t.file[row]], int(t.line[row]), int(t.col[row])


def motion_at(program: Program, row: int) -> str:
    """``path:line`` of the motion statement of target ``row`` (``Program.sites``; the row's own
    place where the reader gave none)."""
    sites = program.sites
    site = sites[row] if len(sites) == len(program.targets) else None
    if site is None or not 0 <= site.file < len(program.files):
        path, line, _ = where(program, row)
        return f"{path}:{line}"
    return f"{program.files[site.file]}:{site.line}"


def collect(program: Program, rows: np.ndarray, code: str, message: str | Callable[[int], str],
            severity: str = "warning") -> list[Diagnostic]:
    """One diagnostic per row up to MAX_LISTED, then one at the next row that counts the
    targets after it. ``message``: one text, or a function of the position in ``rows``."""
    text = message if callable(message) else (lambda i: message)
    out = [Diagnostic(*where(program, int(r)), code, text(i), severity) for i, r in enumerate(rows[:MAX_LISTED])]
    if len(rows) > MAX_LISTED:
        rest = len(rows) - MAX_LISTED - 1
        more = f" (and {rest} more target{'s' * (rest != 1)})" if rest else ""
        out.append(Diagnostic(*where(program, int(rows[MAX_LISTED])), code, text(MAX_LISTED) + more, severity))
    return out

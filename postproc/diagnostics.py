"""Errors and warnings that point at a place in an input: ``path:line:col: CODE message``.

Every module raises :class:`PostprocError` for bad input and collects :class:`Diagnostic`
warnings; only the CLI decides how they are printed and which exit code they map to.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

# Exit codes shared by every subcommand (documented in the README).
EXIT_OK = 0
EXIT_FINDINGS = 1  # check found problems / verify exceeded --max-mean
EXIT_ERROR = 2  # bad input, usage error, internal error: nothing was written

# Reader warnings whose target never became a row of Targets: each one is a Cartesian
# target left as written (compensate counts them and exits 1; one place for the rule).
LEFT_AS_WRITTEN = {
    "P210": "a _REL motion: its absolute target is known only at run time",
    "P211": "a target computed at run time (or an element the reader cannot enumerate)",
    "P214": "a point derived from another at run time (P2 = P1; P2.Z = …): it carries the other's correction",
    "P215": "a target name declared in none of the files read (a global whose data list was not given)",
    "P217": "a pose variable (URScript) or P[n] (Fanuc LS) that other statements read too: compensating it would change them",
    "P223": "a point an INTERRUPT handler switched on may assign (INTERRUPT DECL … DO P = … / a DEF that assigns it)",
}

_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f]")


@dataclass(frozen=True)
class Diagnostic:
    """One finding about an input, located by 1-based line and column (0 = unknown)."""

    path: str
    line: int
    col: int
    code: str
    message: str
    severity: str = "warning"  # "warning" | "error"

    def format(self) -> str:
        # one line whatever the input held: a quoted '\r' or ESC would garble the terminal
        message = _CONTROL.sub(lambda m: m.group().encode("unicode_escape").decode("ascii"), self.message)
        if self.line <= 0:  # about the whole file (unreadable, not a model, ...)
            return f"{self.path}: {self.code} {message}"
        return f"{self.path}:{self.line}:{self.col}: {self.code} {message}"


class PostprocError(Exception):
    """Bad input or an impossible request. Carries a location when there is one."""

    def __init__(self, message: str, path: str = "", line: int = 0, col: int = 0, code: str = "E000"):
        super().__init__(message)
        self.message = message
        self.path = path
        self.line = line
        self.col = col
        self.code = code

    def diagnostic(self) -> Diagnostic:
        return Diagnostic(self.path, self.line, self.col, self.code, self.message, "error")

    def __str__(self) -> str:
        if not self.path:
            return f"{self.code} {self.message}"
        return self.diagnostic().format()


def line_col(text: str, offset: int) -> tuple[int, int]:
    """1-based (line, column) of a character offset in ``text``."""
    line = text.count("\n", 0, offset) + 1
    start = text.rfind("\n", 0, offset) + 1
    return line, offset - start + 1

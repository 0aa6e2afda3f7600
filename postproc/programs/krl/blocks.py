"""The checks of the block structure the vectorised lines need (a motion inside DEF … END, SPL
inside SPLINE … ENDSPLINE) and of what a file leaves open at its end; the blocks themselves
are opened and closed by the lowering (``lower.py``)."""
from __future__ import annotations

import numpy as np

from ...core.diagnostics import P101, P104, P105, PostprocError
from .fast_path import _Shape


class Blocks:
    """Structure checks (methods of the Reader)."""

    def check_parts(self, parts) -> None:
        """Hot lines stand inside a DEF, SPL segments inside SPLINE … ENDSPLINE (the
        accelerator reads them without the interpreter, so check against the blocks)."""
        for spans, need, msg in ((self.def_lines, None, "a motion must stand inside DEF … END"),
                                 (self.spline_lines, "spl", "SPL must stand inside SPLINE … ENDSPLINE")):
            lo = np.array([a for a, _ in spans] or [0], np.int64)
            hi = np.array([b for _, b in spans] or [-1], np.int64)
            for p in parts:
                lines = p["line"] if need is None else p["line"][p["spl"]]
                if not len(lines):
                    continue
                k = np.searchsorted(lo, lines, "right") - 1
                bad = (k < 0) | (lines > hi[np.maximum(k, 0)])
                if bad.any():
                    ln = int(lines[np.flatnonzero(bad)[0]])
                    a = int(self.starts[ln - 1])
                    row = self.text[a:].split("\n", 1)[0]
                    raise PostprocError(msg, self.path, ln, len(row) - len(row.lstrip()) + 1, P101)

    def hot_line(self, i: int, sh: _Shape) -> None:
        if not self.in_def:
            self.structure_error(i, sh, "a motion must stand inside DEF … END")
        if sh.plan.spl and not any(b[0] == "SPLINE" for b in self.blocks):
            self.structure_error(i, sh, "SPL must stand inside SPLINE … ENDSPLINE")

    def structure_error(self, i, sh, msg):
        line = self.text[int(self.starts[i]):].split("\n", 1)[0]
        col = len(line) - len(line.lstrip()) + 1
        raise PostprocError(msg, self.path, i + 1, col, P101)

    def finish_file(self, nlines: int) -> None:
        if self.blocks:
            kind, line, col, detail = self.blocks[-1]
            closer = {"DEF": "END", "DEFFCT": "ENDFCT", "DEFDAT": "ENDDAT", "IF": "ENDIF", "FOR": "ENDFOR",
                      "WHILE": "ENDWHILE", "LOOP": "ENDLOOP", "REPEAT": "UNTIL", "SWITCH": "ENDSWITCH",
                      "SPLINE": "ENDSPLINE"}[kind]
            raise PostprocError(f"{kind}{' ' + detail if detail else ''} has no matching {closer}",
                                self.path, line, col, P101)
        for line, col in self.folds:
            self.warn(self.path, line, col, P105, ";FOLD without ;ENDFOLD")
        if self.role == "module" and self.fi == 0 and self.defs_seen == 0 and not (self.has_dat and self.code_in_set):
            if self.has_dat:  # alone: no motion uses its points, so none is a target
                raise PostprocError("a data list (DEFDAT) with no DEF: its points are targets only through the "
                                    "motions that use them; give the modules (.src) that use it in the same run",
                                    self.path, 1, 1, P104)
            raise PostprocError("no DEF: expected a KRL module with DEF name( ) … END", self.path, 1, 1, P104)

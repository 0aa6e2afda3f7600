"""Block structure: DEF/DEFFCT/DEFDAT, IF/FOR/WHILE/LOOP/REPEAT/SWITCH/SPLINE, folds."""
from __future__ import annotations

import numpy as np
from lark import Token, Tree

from ...diagnostics import P101, P104, P105, PostprocError
from .fast_path import _Shape
from .frames import _FrameState
from .values import _Unknown, _first_pos


class Blocks:
    """Block structure: DEF/DEFFCT/DEFDAT, IF/FOR/WHILE/LOOP/REPEAT/SWITCH/SPLINE, folds. (methods of the Reader)"""

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

    def open_block(self, kind, node, detail=""):
        self.blocks.append((kind, self.ln, self.col(_first_pos(node) or 0), detail))

    def close_block(self, kinds, node, word):
        if not self.blocks or self.blocks[-1][0] not in kinds:
            if self.blocks:
                kind, line, _, _ = self.blocks[-1]
                self.err(f"{word} does not close {kind} (line {line})", _first_pos(node) or 0)
            self.err(f"{word} without {' / '.join(sorted(kinds))}", _first_pos(node) or 0)
        return self.blocks.pop()

    def s_header(self, node):
        pass

    def s_def_head(self, node):
        self.begin_def(node)

    def s_fct_head(self, node):
        self.begin_def(node, kind="DEFFCT")

    def begin_def(self, node, kind="DEF"):
        name = next(c for c in node.children if isinstance(c, Token) and c.type == "NAME")
        if self.blocks:
            self.err(f"{kind} inside {self.blocks[-1][0]} (line {self.blocks[-1][1]}): missing "
                     f"{'END' if self.blocks[-1][0] == 'DEF' else 'end of block'}", _first_pos(node))
        self.open_block(kind, node, str(name))
        self.block_open["DEF"] = self.ln
        self.in_def = True
        self.local = {}
        self.gotos = {}
        self.fdat = None
        # the first DEF starts at $NULLFRAME; a later one (a local subroutine) inherits the
        # frames its callers had, when they all agree
        if self.defs_seen == 0 and str(name).upper() not in self.call_states:
            st = self.start_state()  # a module's main DEF, not called from a module read before
        else:
            calls = self.call_states.get(str(name).upper(), [])
            if not calls:
                st = self.start_state()
            elif all(c.same(calls[0]) for c in calls[1:]):
                st = calls[0]
            else:
                why = _Unknown(f"{kind} {name} is called with different $BASE/$TOOL", (self.ln, 1))
                st = _FrameState(why, "", calls[0].tool, calls[0].tool_label, calls[0].robroot)
        self.defs_seen += 1
        self.set_state(st)

    def s_def_end(self, node):
        self.close_block({"DEF"}, node, "END")
        self.end_def()

    def s_fct_end(self, node):
        self.close_block({"DEFFCT"}, node, "ENDFCT")
        self.end_def()

    def end_def(self):
        self.def_lines.append((self.block_open["DEF"], self.ln))
        self.in_def = False
        self.local = None
        self.barrier()

    def s_dat_head(self, node):
        if self.blocks:
            self.err(f"DEFDAT inside {self.blocks[-1][0]}", _first_pos(node))
        self.has_dat = True
        self.open_block("DEFDAT", node)

    def s_dat_end(self, node):
        self.close_block({"DEFDAT"}, node, "ENDDAT")

    def s_if_head(self, node):
        self.open_block("IF", node)
        self.flow_open("IF")

    def s_else_(self, node):
        if not self.blocks or self.blocks[-1][0] != "IF":
            self.err("ELSE without IF", _first_pos(node))
        self.flow_branch()

    def s_endif(self, node):
        self.close_block({"IF"}, node, "ENDIF")
        self.flow_close()

    def s_for_head(self, node):
        self.open_block("FOR", node)
        var = next(c for c in node.children if isinstance(c, Token) and c.type == "NAME")
        exprs = [c for c in node.children if isinstance(c, Tree)]
        step = self.int_of(exprs[2]) if len(exprs) > 2 else 1
        lo, hi = self.int_of(exprs[0]), self.int_of(exprs[1])
        self.loops.append((str(var).upper(), lo, hi, step))
        once = None not in (lo, hi, step) and ((step > 0 and lo <= hi) or (step < 0 and lo >= hi))
        self.loop_open("FOR", runs_once=once)

    def s_endfor(self, node):
        self.close_block({"FOR"}, node, "ENDFOR")
        if self.loops:
            self.loops.pop()
        self.loop_close()

    def s_while_head(self, node):
        self.open_block("WHILE", node)
        self.loop_open("WHILE")

    def s_endwhile(self, node):
        self.close_block({"WHILE"}, node, "ENDWHILE")
        self.loop_close()

    def s_loop_head(self, node):
        self.open_block("LOOP", node)
        self.loop_open("LOOP")

    def s_endloop(self, node):
        self.close_block({"LOOP"}, node, "ENDLOOP")
        self.loop_close()

    def s_repeat_head(self, node):
        self.open_block("REPEAT", node)
        self.loop_open("REPEAT")

    def s_until(self, node):
        self.close_block({"REPEAT"}, node, "UNTIL")
        self.loop_close()

    def s_exit_(self, node):
        self.loop_exit()

    def s_switch_head(self, node):
        self.open_block("SWITCH", node)
        self.flow_open("SWITCH")

    def s_case(self, node):
        if not self.blocks or self.blocks[-1][0] != "SWITCH":
            self.err("CASE outside SWITCH", _first_pos(node))
        self.flow_branch()

    def s_default(self, node):
        if not self.blocks or self.blocks[-1][0] != "SWITCH":
            self.err("CASE outside SWITCH", _first_pos(node))
        self.flow_branch(default=True)

    def s_endswitch(self, node):
        self.close_block({"SWITCH"}, node, "ENDSWITCH")
        self.flow_close()

    def s_spline_head(self, node):
        self.open_block("SPLINE", node)
        self.block_open["SPLINE"] = self.ln
        self.saved_state = self.state
        st = self.with_frames(node.children)
        if st is not self.state:
            self.set_state(st)

    def s_spline_end(self, node):
        self.close_block({"SPLINE"}, node, "ENDSPLINE")
        self.spline_lines.append((self.block_open["SPLINE"], self.ln))
        if self.saved_state is not None and self.saved_state is not self.state:
            self.set_state(self.saved_state)
        self.saved_state = None

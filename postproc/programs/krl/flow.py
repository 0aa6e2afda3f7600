"""Control flow: what IF/ELSE, SWITCH/CASE and loops leave of $BASE/$TOOL/$ROBROOT and of the
current position.

The reader goes through a DEF in textual order; the controller takes one branch of an IF or
a SWITCH, and runs a loop's body 0, 1 or more times. So:

* each branch starts from the frames in force at the IF / SWITCH; after ENDIF / ENDSWITCH a
  frame is known only when every path (an IF without ELSE, a SWITCH without DEFAULT: also the
  path through none) leaves it the same, else it is unknown (P201 base / P203 tool, with the
  line of the branch construct);
* a loop's body is first run in the calls' sandbox (its frame statements only) to learn what
  one iteration leaves; a frame that the body changes is unknown at the body's start (the
  second iteration starts where the first ended) and after the loop unless every way out
  agrees (no iteration when the bounds allow it, the body's end, each EXIT);
* a label a GOTO jumps to merges the jumps' frames (those before it as recorded, those after
  it from one run of the lines between) with the fall-through's;
* the current position (where a partial aggregate such as ``LIN {Z 5}`` takes its missing
  components from) is unknown at the start of a branch after another branch that moves, after
  a branch construct any of whose branches moves, and at the start of and after a loop whose
  body moves (the reader's barrier: such targets are left as written, P212).
"""
from __future__ import annotations

import re
from bisect import bisect_right
from dataclasses import dataclass, field

import numpy as np

from .frames import _ASSUMED_ROBROOT, _FrameState, _NotSet
from .values import _Unknown

# a motion statement at the start of a line (comments start with ';' and never match)
_MOTION = re.compile(r"^[ \t]*(?:S?(?:PTP|LIN|CIRC)(?:_REL)?|SPL|SPLINE)(?![\w$])", re.I | re.M)


@dataclass
class _Flow:
    kind: str  # IF, SWITCH, FOR, WHILE, LOOP, REPEAT
    line: int
    entry: _FrameState  # the frames where it starts
    mark: tuple  # (text offset, moves) where the current branch / body starts
    ends: list = field(default_factory=list)  # frame states at the end of each branch / each EXIT
    branch: bool = False  # a branch has started (SWITCH: the first CASE)
    moved: bool = False  # a branch so far moves the robot
    whole: bool = False  # the paths cover every case (ELSE / DEFAULT seen; a loop that runs ≥ 1 time)


def _same(a, b) -> bool:
    if isinstance(a, np.ndarray) and isinstance(b, np.ndarray):
        return a.shape == b.shape and np.allclose(a, b)
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return False
    return a is b or a == b


def merge_states(states: list, why: str, where: tuple) -> _FrameState:
    """One frame state for several paths: each of base, tool, robroot known when all agree,
    else unknown for ``why`` at ``where``."""
    first = states[0]

    def one(values):
        if all(_same(values[0], v) for v in values[1:]):
            return values[0]
        # a path on which it is already unknown: that reason (one warning for the cause); not
        # "never set" when some path sets it
        return next((v for v in values if isinstance(v, _Unknown) and not isinstance(v, _NotSet)), None) \
            or _Unknown(why, where)

    base = one([s.base for s in states])
    tool = one([s.tool for s in states])
    robroot = one([s.robroot for s in states])
    if isinstance(robroot, np.ndarray) and any(s.robroot is _ASSUMED_ROBROOT for s in states):
        robroot = _ASSUMED_ROBROOT  # (equal to a $NULLFRAME set on another path: still an assumption, P224)
    return _FrameState(base, first.base_label if base is first.base else "", tool,
                       first.tool_label if tool is first.tool else "", robroot)


class Flow:
    """Control flow (methods of the Reader): the s_… handlers of blocks.py call these."""

    def _mark(self) -> tuple:
        return (self.la, self.moves)

    def _moved_since(self, mark) -> bool:
        """Does the text from ``mark`` to the current line hold a motion (or a call that moves)?"""
        return self.moves != mark[1] or _MOTION.search(self.text, mark[0], self.la) is not None

    def _adopt(self, st) -> None:
        if st is not self.state and not (st.same(self.state) and st.base_label == self.state.base_label
                                          and st.tool_label == self.state.tool_label):
            self.set_state(st)

    # IF / SWITCH
    def flow_open(self, kind: str) -> None:
        self.flow.append(_Flow(kind, self.ln, self.state, self._mark(), branch=kind == "IF"))

    def flow_branch(self, default: bool = False) -> None:
        """ELSE, CASE or DEFAULT: the branch before it ends, a new one starts from the entry."""
        if not self.flow:
            return
        fl = self.flow[-1]
        if fl.branch:
            fl.ends.append(self.state)
            fl.moved |= self._moved_since(fl.mark)
        fl.branch = True
        fl.whole |= default or fl.kind == "IF"  # (IF: ELSE is the other path)
        fl.mark = self._mark()
        self._adopt(fl.entry)
        if fl.moved:  # this branch starts where the construct started, not where the last one ended
            self.barrier()

    def flow_close(self) -> None:
        """ENDIF / ENDSWITCH: the frames every path agrees on; the position after a move is unknown."""
        if not self.flow:
            return
        fl = self.flow.pop()
        if fl.branch:
            fl.ends.append(self.state)
            fl.moved |= self._moved_since(fl.mark)
        if not fl.whole:  # no branch taken: the entry's frames
            fl.ends.append(fl.entry)
        if fl.ends:
            why = f"the branches of the {fl.kind} at line {fl.line} leave it different"
            self._adopt(merge_states(fl.ends, why, (self.ln, 1)))
        if fl.moved:
            self.barrier()

    # loops
    def loop_open(self, kind: str, runs_once: bool = False) -> None:
        """FOR / WHILE / LOOP / REPEAT: run the body's frame statements once to see what an
        iteration changes; what it changes is unknown at the body's start."""
        entry = self.state
        fl = _Flow(kind, self.ln, entry, self._mark(), whole=runs_once or kind in ("LOOP", "REPEAT"))
        self.flow.append(fl)
        after, moved, end = self.run_body(self.ln, None, entry)
        if end is None:
            return  # no matching end: the block check reports it
        fl.moved = moved
        why = f"the body of the {kind} at line {fl.line} changes it between iterations"
        self._adopt(merge_states([entry, after], why, (self.ln, 1)))
        if moved:  # the 2nd iteration starts where the 1st ended
            self.barrier()

    def loop_exit(self) -> None:
        """EXIT: a way out of the innermost loop with the frames in force here."""
        fl = next((f for f in reversed(self.flow) if f.kind in ("FOR", "WHILE", "LOOP", "REPEAT")), None)
        if fl is not None:
            fl.ends.append(self.state)

    def loop_close(self) -> None:
        if not self.flow:
            return
        fl = self.flow.pop()
        ways = [self.state] + fl.ends + ([] if fl.whole else [fl.entry])
        why = f"the {fl.kind} at line {fl.line} may end after any iteration (or none)"
        self._adopt(merge_states(ways, why, (self.ln, 1)))
        if fl.moved or self._moved_since(fl.mark):
            self.barrier()

    # GOTO
    def s_goto(self, node):
        self.gotos.setdefault(str(node.children[-1]).upper(), []).append(self.state)

    def s_label(self, node):
        """A label some GOTO of the file jumps to: the frames of the jumps (those before it as
        recorded, those after it from one run of the lines between) merged with the fall-through;
        the current position unknown."""
        name = str(node.children[0])
        jumps = list(self.gotos.get(name.upper(), []))
        later = [m for m in re.finditer(r"^[ \t]*GOTO[ \t]+" + re.escape(name) + r"(?![\w$])", self.text, re.I | re.M)
                 if m.start() > self.la]
        if not jumps and not later:
            return
        for m in later:  # a jump back: the frames after one pass from here to it
            end = bisect_right(self.starts, m.start()) - 1
            jumps.append(self.run_body(self.ln, end, self.state)[0])
        why = f"a GOTO {name} jumps to line {self.ln} with others"
        self._adopt(merge_states([self.state] + jumps, why, (self.ln, 1)))
        self.barrier()

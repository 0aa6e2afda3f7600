"""Universal Robots URScript reader: the text of a script (.script) → the motion IR
(``lower.py``) → the analysis (``programs.analysis`` with URScript's ``semantics.py``) → Program.

Semantics (tests/test_urscript.py and tests/test_urscript_ir.py show each on a small script):

* the script's top level is the program (or, where it holds nothing but ``def``s, the ``def``
  no other calls: Polyscope's ``def prog(): … end``); ``def`` functions are followed at each
  call (parameters by value, default arguments, keyword arguments), with if/elif/else,
  while, return, break, continue and ``halt`` (the program ends) as the controller runs them;
* a target is a pose a motion moves to: ``movel``/``movep``/``servoc`` (LIN), ``movej`` (PTP:
  a pose, or ``get_inverse_kin(p, …)`` of one — the pose p, its ``tcp`` the tool),
  ``movec`` (via and end pose); inline ``p[x, y, z, rx, ry, rz]``, or a variable holding one
  (assigned at the top, in a function, copied: the analysis follows the value to each motion
  that runs, in execution order). A list of joint positions is a joint target (untouched).
  ``pose_trans(F, p[…])`` moves to p in the frame F: p is the target, F its frame;
* poses are metres and a rotation vector: held in mm and read as A,B,C degrees (``Program.unit``
  = 1000: the rewrite writes the tokens in metres); x, y, z rewritten, and with ``--orientation``
  rx, ry, rz (``Program.orientation`` "rotvec");
* the tool is what ``set_tcp`` set where the target runs (unknown after a merge of paths that set
  it differently, in a thread that may set it…: P203); before any ``set_tcp`` the installation's
  TCP, which the script does not say (P221, unless ``--tool``);
* what is known only at run time (``get_actual_tcp_pose()``, ``socket_read_…``, ``read_input_…``,
  a parameter, a function the script does not define) leaves the targets it reaches as written,
  located (P211, P212, P214, P215); a pose whose numbers other statements read too (a frame, a
  TCP, a condition, ``textmsg``) is left as written (P217).
"""
from __future__ import annotations

import re

import numpy as np

from ...core.diagnostics import P108, P222, PostprocError
from ..analysis import analyse
from ..model import STAMP_PREFIX, ActiveFrames, Program
from ..text import newline
from .lower import MOTION_OF, SCRIPT, UNIT_MM, Lowering, parser
from .semantics import UR

__all__ = ["read", "lower", "parser", "UNIT_MM", "MOTION_OF", "SCRIPT"]


def lower(files: list[str], texts: list[str], active: ActiveFrames | None = None):
    """The motion IR of a URScript program and its dialect (what ``read`` analyses)."""
    if len(files) != 1:
        raise PostprocError("a URScript program is one .script file", files[0] if files else "<none>", 0, 0, P108)
    if active is not None and active.base is not None:
        raise PostprocError("--base: a URScript pose is in the robot's base frame (no base to state)", files[0], 0, 0,
                            P222)
    lowering = Lowering(files[0], texts[0])
    unit = lowering.lower()
    return unit, UR(active, lowering.programs, lowering.threads)


def read(files: list[str], texts: list[str], active: ActiveFrames | None = None) -> Program:
    """Read a URScript program (one file). ``active`` (``ActiveFrames``): the TCP its user states
    for targets before the script's first set_tcp (only ``tool``: the base is the robot's;
    without it those targets are left as written, P221). Raises PostprocError (P101, P117,
    P103, P222 with path:line:col) on bad input."""
    unit, dialect = lower(files, texts, active)
    built = analyse(unit, dialect)
    text = texts[0]
    stamps = {}
    m = re.search(r"^[ \t]*#.*" + re.escape(STAMP_PREFIX) + r".*$", text, re.M)
    if m:
        stamps[0] = m.group().strip()
    program = Program(files=[files[0]], texts=[text], targets=built.targets, frames=built.frames,
                      diagnostics=unit.diagnostics + built.diagnostics, notes=built.notes, dialect="urscript",
                      stamps=stamps, newlines=[newline(text)], comment="#", named_targets=built.named,
                      unit=UNIT_MM, orientation="rotvec")
    program.held, program.sites = built.held, built.sites
    qnear = built.extras.get("qnear")
    if qnear is not None and any(qnear):
        # get_inverse_kin(p, qnear): the branch nearest qnear, which postproc does not map to joint angles
        program.unmapped_configuration = np.array([bool(x) for x in qnear], bool)
    return program

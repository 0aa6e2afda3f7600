"""The RAPID reader: texts → units and shapes (``syntax.py``) → the motion IR (``lower.py``)
→ the analysis (``programs.analysis``, with RAPID's ``semantics.py``) → RapidProgram."""
from __future__ import annotations

import gc
import re
from dataclasses import dataclass, field

import numpy as np

from ...core import frames as fr
from ...core.diagnostics import P103, P104, P201, P225, P233, P234, Diagnostic, PostprocError
from ..analysis import analyse
from ..analysis.values import Mat, Top
from ..ir import Call, Invoke, Unit, walk
from ..model import STAMP_PREFIX, Program
from ..text import newline  # a file's newline: \r\n if at least half its line ends are
from .lower import Lowering
from .semantics import RAPID
from .syntax import scan
from .syspar import robot_of

__all__ = ["read", "lower", "RapidProgram"]


@dataclass
class RapidProgram(Program):
    """A RAPID Program, plus each target row's configuration data as written."""

    # [N, 4] cf1, cf4, cf6, cfx per target row (NaN where not a number), aligned with the rows
    confdata: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))


def read(files: list[str], texts: list[str], config: list[str] | None = None, accelerate: bool = True,
         external: tuple = (), syspar: dict | None = None, task: str | None = None) -> RapidProgram:
    """Read RAPID module(s) ``files`` with contents ``texts`` as one task; ``config`` holds the
    texts of other modules (e.g. a .sys) whose data the motions may name and whose routines
    they may call (read-only: never rewritten). ``accelerate=False`` lowers every motion
    through its tree (no MoveRun of inline robtargets: the same result, slower; for tests).
    ``external``: the external units' kinematics (postproc.robot.external: a track, a positioner).
    ``syspar``: the controller's system parameters (a backup's ``SYSPAR``: path → text of its
    .cfg files; ``syspar.py`` says what is taken: the task's robot, its base frame, the unit that
    moves it); ``task``: the task's name (``T_ROB1``, a backup's ``RAPID/TASKn`` folder's).
    Raises PostprocError (P1xx, with path:line:col) on bad input."""
    enabled = gc.isenabled()
    gc.disable()  # (many small objects, no cycles: the collector only costs time here)
    try:
        return Reader(list(files), list(texts), list(config or []), accelerate, external, syspar, task).run()
    finally:
        if enabled:
            gc.enable()


def lower(files: list[str], texts: list[str], config: list[str] | None = None,
          accelerate: bool = True, external: tuple = (), syspar: dict | None = None,
          task: str | None = None) -> tuple[Unit, RAPID]:
    """The motion IR of RAPID module(s) and their dialect (what ``read`` analyses)."""
    reader = Reader(list(files), list(texts), list(config or []), accelerate, external, syspar, task)
    return reader.lower()


class Reader:
    def __init__(self, files, texts, config, accelerate: bool = True, external: tuple = (),
                 syspar: dict | None = None, task: str | None = None):
        if len(files) != len(texts):
            raise ValueError("files and texts differ in length")
        self.files, self.texts, self.config = files, texts, config
        self.accelerate = accelerate
        self.external = tuple(external or ())
        self.config_names = ["--config" if len(config) == 1 else f"--config[{k}]" for k in range(len(config))]
        self.syspar, self.task = syspar, task  # (what the program says it was read with: read_with)
        self.robot = robot_of(syspar, task)
        self.notes: list = []  # (P234: what the system parameters gave)

    def lower(self) -> tuple[Unit, RAPID]:
        shapes, exact = {}, {}
        config_sources = [scan(-1 - k, name, text, shapes, exact)
                          for k, (name, text) in enumerate(zip(self.config_names, self.config))]
        sources = [scan(fi, path, text, shapes, exact) for fi, (path, text) in enumerate(zip(self.files, self.texts))]
        for src in sources:
            if not src.units:
                raise PostprocError("expected a RAPID module: MODULE name … ENDMODULE", src.path, 1, 1, P104)
        unit = Unit("rapid", self.files, self.texts, config_names=self.config_names, config_texts=self.config,
                    form="quaternion")
        low = Lowering(sources, config_sources, unit, self.accelerate)
        low.declare()
        low.lower()
        self.sources = sources
        routines = unit.routines
        main = next((k for k in ("MAIN",) + tuple(k for k in routines if k.endswith("::MAIN")) if k in routines), None)
        if main is not None:
            unit.entries = [main]
        else:  # the routines nothing calls (the analysis runs the others nothing reached after them)
            called = set().union(*low.calls.values()) if low.calls else set()
            unit.entries = [k for k in routines if k not in called]
        runtime = self._runtime(low, unit)
        dialect = RAPID(readonly=low.readonly, consts=low.consts, written=low.written, external=self.external,
                        runtime=runtime, base=self._base())
        dialect.units = self.robot.units if self.robot is not None else {}
        return unit, dialect

    def _path(self, fi: int) -> str:
        return self.files[fi] if fi >= 0 else self.config_names[-1 - fi]

    def _runtime(self, low: Lowering, unit: Unit) -> dict:
        """Data a routine the entry does not run changes (``Lowering.changed_outside``): scope key →
        the Top (P233) every read of it gives."""
        changed = low.changed_outside(unit.entries)
        if not changed:
            return {}
        entry = unit.entries[0] if len(unit.entries) == 1 else ""
        sig = low.sigs.get(entry)
        entry = (sig.written if sig is not None and sig.written else entry.split("::")[-1].lower()) or "the entry"
        out = {}
        for key, (name, what, loc, routine, root) in changed.items():
            rsig = low.sigs.get(routine.name)
            rname = (rsig.written if rsig is not None and rsig.written else routine.name.split("::")[-1])
            by = "an assignment" if what == "an assignment" else what
            via = f" (which {root}() calls)" if root and root != rname else ""
            runner = root or rname
            why = (f"{name} is changed by {by} at {self._path(loc.file)}:{loc.line} in {rname}(){via}, which "
                   f"{entry} does not call but the pendant, an event routine or another task can run: a run-time "
                   "value")
            if runner != rname:
                why = why.replace(f"which {entry} does not call", f"and {runner}() {entry} does not call", 1)
            out[key] = Top(why, loc, P233)
        return out

    def _base(self):
        """What the system parameters say of the robot's base (``syspar.robot_of``): None nothing
        (the world is the robot base); a Mat robot base ← world; a Top that leaves every target."""
        robot = self.robot
        if robot is None:
            return None
        if robot.unknown:
            return Top(f"{robot.unknown}: give the task's name (a backup's RAPID/TASKn folder)", None, P201)
        if robot.moved_by:
            path, line = robot.moved_at
            unit = robot.moved_by
            track = next((u for u in self.external if u.carries == "robot"), None)
            covered = track is not None and (not track.mech_unit or track.mech_unit.upper() == unit.upper())
            if not covered:
                given = (f" (the unit given, {track.describe()}, is mech_unit {track.mech_unit})" if track is not None
                         else "")
                return Top(f"{path}:{line} says the base of robot {robot.name} is moved by the mechanical unit {unit} "
                           "(base_frame_coordinated: a track): every target moves with that unit's axis, whose "
                           f"kinematics are not given{given} (--external, a unit that carries the robot with "
                           f"mech_unit = {unit})", None, P225)
            if robot.base is not None and not np.allclose(robot.base, np.eye(4), atol=1e-9):
                bpath, bline = robot.base_at
                return Top(f"{bpath}:{bline} states the base frame of robot {robot.name} on the mechanical unit {unit}, "
                           "and --external gives that track's own flange: postproc does not take both (state where the "
                           "robot stands on the carriage once, in the unit's flange, and leave MOC.cfg's base frame at "
                           "the identity)", None, P225)
            return None
        if robot.base is None or np.allclose(robot.base, np.eye(4), atol=1e-9):
            return None
        path, line = robot.base_at
        six = fr.matrix_to_frame(robot.base)
        self.notes.append(Diagnostic(path, line, 1, P234, (
            f"robot {robot.name}'s base frame in the world ({', '.join(f'{x:g}' for x in six)}: X,Y,Z mm, A,B,C deg) as "
            "the system parameters give it: the targets' frames (wobj0 and every user frame are in the world) are "
            "taken to the robot base through it"), "note"))
        return Mat(fr.inverse(robot.base), f"{robot.name} base (MOC.cfg)")

    def run(self) -> RapidProgram:
        unit, dialect = self.lower()
        built = analyse(unit, dialect)
        t = built.targets
        _finite(self, t)
        stamps = {}
        for fi, text in enumerate(self.texts):
            m = re.search(r"^[ \t]*!.*" + re.escape(STAMP_PREFIX) + r".*$", text, re.M)
            if m:
                stamps[fi] = m.group().strip()
        conf = built.extras.get("confdata")
        confdata = np.array([np.asarray(c, float) for c in conf], float).reshape(-1, 4) if conf else np.zeros((0, 4))
        program = RapidProgram(
            files=list(self.files), texts=list(self.texts), targets=t, frames=built.frames,
            diagnostics=list(unit.diagnostics) + built.diagnostics, notes=built.notes + self.notes, dialect="rapid",
            stamps=stamps, newlines=[newline(x) for x in self.texts], comment="!", named_targets=built.named,
            confdata=confdata, orientation="quaternion")
        program.held, program.sites = built.held, built.sites
        program.read_with = {k: v for k, v in (("data", self.syspar), ("task", self.task)) if v}
        return program


def _finite(reader: Reader, t) -> None:
    """P103 at the first robtarget (in the order written) whose position or orientation as
    written is not a finite number, or whose quaternion is [0,0,0,0]."""
    n = len(t)
    if not n:
        return
    q = t.written_orientation()
    with np.errstate(invalid="ignore", over="ignore"):
        bad_xyz = ~np.isfinite(t.poses[:, :3]) & (t.spans[:, :, 0] >= 0)
        bad_q = ~np.isfinite(q)
        zero = ~bad_q.any(axis=1) & ~(np.abs(q) > 0).any(axis=1)
    bad = np.flatnonzero(bad_xyz.any(axis=1) | bad_q.any(axis=1) | zero)
    if not len(bad):
        return
    r = int(bad[np.lexsort((t.col[bad], t.line[bad], t.file[bad]))[0]])
    src = reader.sources[int(t.file[r])]
    text = src.text
    if bad_xyz[r].any() or bad_q[r].any():
        if bad_xyz[r].any():
            s, e = (int(x) for x in t.spans[r, int(np.flatnonzero(bad_xyz[r])[0])])
        else:
            j = int(np.flatnonzero(bad_q[r])[0])
            s, e = (int(x) for x in t.abc_spans[r, j]) if t.abc_spans is not None else (-1, -1)
        if s < 0:
            raise PostprocError("a robtarget's position or orientation is not a finite number", src.path,
                                int(t.line[r]), int(t.col[r]), P103)
        raise PostprocError(f"a robtarget: '{text[s:e].strip()}' is not a finite number", src.path, *src.locate(s),
                            P103)
    s = int(t.abc_spans[r, 0, 0]) if t.abc_spans is not None else -1
    where = src.locate(s) if s >= 0 else (int(t.line[r]), int(t.col[r]))
    raise PostprocError("a robtarget's quaternion [0,0,0,0] is no orientation", src.path, *where, P103)


_ = (Call, Invoke, walk)

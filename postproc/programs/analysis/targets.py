"""From the analysis's recorded motions to the program's targets: one row per executed motion
to a Cartesian target (``Targets``), its frame (``Program.frames``), its predecessor row
(``Targets.prev``), the rows that share number tokens (``Targets.twin``, ``Targets.group``),
and the located findings of what is left as written and why.

A row's X/Y/Z are known numbers with their tokens (a token + an offset: a copy of another
point moved by a constant); a row whose number is computed in another way (``P2 = F:P1``, a
product) or not known has no token to rewrite and is left as written. The rows that share a
token are one *group*: compensating the token moves every row of the group, so the rewrite
writes it only where every row agrees (``compensate``), and a group with a token that
something else reads too (a frame built from the point, a condition: ``Recorder.escapes``) is
left as written here (P217).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...core import frames as fr
from ...core.diagnostics import (
    P201, P203, P210, P211, P212, P214, P215, P217, P220, P221, P223, P224, P225, P233, Diagnostic, listed,
)
from ..ir import MOTION_INDEX, Agg, Loc
from ..model import Frame, Targets
from .execute import START, RunUse
from .values import Mat, Moving, Six, Tok, Top, number, tokens_of

__all__ = ["build", "Built"]

# what a frame code says at the targets it leaves (old wording: "frame"/"tool" not statically known)
_NAN = float("nan")
_NO_AXES = (_NAN,) * 6
_NO_LOAD = (_NAN,) * 4


class _Axes:
    """A predecessor that is a joint motion to known axis values ``q`` (deg)."""

    __slots__ = ("q",)

    def __init__(self, q):
        self.q = q
_WHAT = {P201: "frame", P203: "tool", P225: "frame"}
NEITHER_SET = ("neither $BASE nor $TOOL is set before this target (the controller uses whatever is active): set "
               "them in the program or state them with --base and --tool")


@dataclass
class Built:
    """The targets of a program and what goes with them: ``frames``, located ``diagnostics``
    (what is left and why), ``notes`` (P224), ``held`` (rows left by the analysis: code → rows),
    ``named`` (some targets are variables), ``extras`` (a dialect's own per-row columns, name →
    list aligned with the rows: ``Dialect.row_extras``, e.g. RAPID's confdata, Fanuc's CONFIG)."""

    targets: Targets
    frames: list
    diagnostics: list
    notes: list
    held: dict = field(default_factory=dict)
    named: bool = False
    extras: dict = field(default_factory=dict)
    # each row's motion statement (its Loc; a MoveRun's row: None, the row's own place): which
    # motion a row is where one declaration is the target of several (the property's oracle)
    sites: list = field(default_factory=list)


class _Rows:
    """Rows collected one use (or one run) at a time: a run's columns as a part (``add``); single
    rows (``add_one``: plain Python values) buffered and made one part of columns when a run
    comes or at the end (a program of many named targets stays cheap)."""

    def __init__(self, k_orient: int = 3):
        self.parts: list = []
        self.n = 0
        self.k_orient = k_orient
        self.singles: list = []
        self.later: dict = {}  # a motion's key → partial targets that read its command (loop back edges)

    def add(self, **cols) -> int:
        self.flush()
        m = len(cols["line"])
        self.parts.append(cols)
        self.n += m
        return self.n - m

    def add_one(self, row: dict) -> int:
        """One row: pose [6], spans [12], abc [k][2], worient [k], file, line, col, frame, motion,
        config (S, T), offset [3], prev, load [4] (NaN: not set), lcause (-1: the load is known or
        not set; else an index into the load causes), site, extras (name → value)."""
        self.singles.append(row)
        self.n += 1
        return self.n - 1

    def flush(self) -> None:
        rows, self.singles = self.singles, []
        if not rows:
            return
        m, k = len(rows), self.k_orient

        def column(name, dtype, shape=None):
            a = np.array([r[name] for r in rows], dtype)
            return a.reshape((m,) + shape) if shape is not None else a

        extras: dict = {}
        for j, r in enumerate(rows):
            for name, value in r["extras"].items():
                extras.setdefault(name, [None] * m)[j] = value
        self.parts.append(dict(pose=column("pose", float, (6,)), spans=column("spans", np.int64, (12,)),
                               abc=column("abc", np.int64, (k, 2)), worient=column("worient", float, (k,)),
                               file=column("file", np.int32), line=column("line", np.int32), col=column("col", np.int32),
                               frame=column("frame", np.int32), motion=column("motion", np.int8),
                               config=column("config", np.int16, (2,)), offset=column("offset", float, (3,)),
                               prev=column("prev", np.int32), start=column("start", float, (6,)),
                               load=column("load", float, (4,)), lcause=column("lcause", np.int32),
                               site=[r["site"] for r in rows], extras=extras))

    def tokens_of(self, row: int) -> set:
        """The X/Y/Z tokens (file, start, end) of a row added before."""
        self.flush()
        at = 0
        for p in self.parts:
            m = len(p["line"])
            if row < at + m:
                i = row - at
                f = int(p["file"][i])
                sp = p["spans"][i].reshape(-1, 2)[:3]
                return {(f, int(a), int(b)) for a, b in sp if a >= 0}
            at += m
        return set()

    def sites(self) -> list:
        """Each row's motion statement (Loc; None: a MoveRun's row)."""
        self.flush()
        out: list = []
        for p in self.parts:
            site = p.get("site")
            out.extend(site if isinstance(site, list) else [None] * len(p["line"]))
        return out

    def extras(self) -> dict:
        """The dialect's per-row columns (``row_extras``), name → list over every row."""
        out: dict = {}
        for p in self.parts:
            for name, values in (p.get("extras") or {}).items():
                out.setdefault(name, [None] * 0)
        for name in out:
            for p in self.parts:
                m = len(p["line"])
                values = (p.get("extras") or {}).get(name)
                out[name].extend(values if values is not None else [None] * m)
        return out


def _path(unit, file: int) -> str:
    return unit.files[file] if file >= 0 else unit.config_names[-1 - file]


def build(unit, dialect, rec, form: str | None = None) -> Built:
    """The targets of the recorded uses (``rec``: execute.Recorder) of ``unit``."""
    form = form or unit.form
    k_orient = 3 if form == "abc" else (4 if form == "quaternion" else 3)
    rows = _Rows(k_orient)
    frames: list[Frame] = []
    frame_ix: dict = {}
    unknown: dict = {}  # (code, why, loc) → [count, first (path, line, col)]
    key_row: dict = {}  # use key → its last row (-1: no row)
    relative: dict = {}  # a relative motion's row → the row of the motion it starts from (-1: none)
    diagnostics: list[Diagnostic] = []
    assumed: set = set()  # frame indices taken with robot base = world assumed (P224)
    named = False
    pending: dict = {}  # pred key → [(use columns without prev), …] waiting for the pred's row
    used_keys: list = []
    key_axes: dict = {}  # a joint motion's key → its known axis values (deg): where it leaves the robot
    load_causes: list = []  # why a row's payload is not known: (path, line, col, why), once each
    cause_ix: dict = {}

    def load_of(load, first) -> tuple:
        """(the row's load [4] (NaN: not set or not known), its cause's index, -1 none) of a
        motion's payload (``Use.load``: Load, None, Top); ``first``: the row's place (path, line,
        col), where a cause has no place of its own."""
        if isinstance(load, Top):
            at = (_path(unit, load.loc.file), load.loc.line, load.loc.col) if load.loc is not None else first
            key = (load.why,) + at
            ix = cause_ix.get(key)
            if ix is None:  # (a payload schedule its user may state: its number, ``fanuc.semantics.Schedule``)
                ix = cause_ix[key] = len(load_causes)
                load_causes.append(at + (load.why, getattr(load, "schedule", None)))
            return _NO_LOAD, ix
        if load is None:
            return _NO_LOAD, -1
        return tuple(float(x) for x in load), -1

    def frame_index(base, tool):
        """Program.frames index of (base Mat, tool) or (-1, the Top that leaves it, its code)."""
        for value, code in ((base, P201), (tool, P203)):
            if isinstance(value, Top):
                if value is base and isinstance(tool, Top) and (value.code or code) == P201 \
                        and tool.code in (None, P203) and tool.why != base.why:
                    # (both unknown: the finding is the base's, and names the tool's cause too)
                    value = Top(f"{base.why}; the tool is not known either: {tool.why}", base.loc, base.code,
                                base.tokens)
                return -1, value, value.code or code
        key = (base._key, None if tool is None else tuple(round(x, 9) for x in tool))
        ix = frame_ix.get(key)
        if ix is None:
            label = base.label + (f" / {tool.label}" if isinstance(tool, Six) and tool.label else "")
            ix = frame_ix[key] = len(frames)
            frames.append(Frame(base=base.m.copy(), tool=None if tool is None else np.array(tool, float), label=label))
            if "assumed-robroot" in getattr(base, "flags", ()):
                assumed.add(ix)
        return ix, None, None

    def count(top, code, targets, first, places=()):
        """One finding per cause, at its first place; ``targets`` [k, 3] (file, line, col) of the
        left targets (a target run twice is one: counted as the summary counts); ``places``: the
        left targets' motions (path:line), named in it."""
        if isinstance(top, Top) and top.code in (P220,) and _is_tool_unset(first[3]):
            top = Top(NEITHER_SET, None, P220)
        key = (code, top.why)
        entry = unknown.get(key)
        if entry is None:
            unknown[key] = [[targets], first[:3], top.loc, dict.fromkeys(places)]
        else:
            entry[0].append(targets)
            entry[3].update(dict.fromkeys(places))

    def prev_of(preds, key=None):
        """(the primary predecessor row, the others, the axis values the robot stands at before
        the primary where it is a joint motion to known ones (else None)): the others are row
        indices, -1 where nothing is known before (the program's start, a motion without a
        row), ``_Axes`` (a joint motion to known axis values), or keys of motions not emitted yet
        (a loop's back edge; ``key``: the motion itself, reached from itself)."""
        if preds is None:
            return -1, [], None
        known, unknown, later, axes = set(), False, [], []
        for p in preds:
            if p == START:
                unknown = True
                continue
            r = key_row.get(p)
            if r is None or p == key:
                later.append(p)
            elif r < 0:
                q = key_axes.get(p)
                if q is None:
                    unknown = True
                elif q not in axes:
                    axes.append(q)
            else:
                known.add(r)
        ordered = sorted(known)
        if not ordered:
            if axes:  # (the robot stands where the joint motion left it)
                return -1, [_Axes(q) for q in axes[1:]] + ([-1] if unknown else []) + later, axes[0]
            return -1, later, None
        return ordered[-1], ordered[:-1] + [_Axes(q) for q in axes] + ([-1] if unknown else []) + later, None

    for use in rec.uses:
        if isinstance(use, RunUse):
            _run_rows(unit, dialect, use, rows, frame_index, count, prev_of, key_row, form, rec, pending, load_of)
            continue
        key_row[use.key] = -1
        s = use.stmt
        loc = s.loc
        target = use.target
        if s.joint and not s.relative and hasattr(target, "fields"):
            axes = dialect.axis_values(target)
            if axes is not None:
                key_axes[use.key] = tuple(axes)
        if s.relative and isinstance(use.rel, str):  # (its start not known: execute.move_relative)
            rec.note(P210, f"relative motion {s.kind.split('-')[0]}_REL left as written: its absolute target is "
                     f"known only at run time ({use.rel}); it moves with the correction of the motion it starts from",
                     loc, True)
            continue
        if s.joint or (s.relative and use.rel is None):
            continue
        if isinstance(target, Top):
            code = target.code if target.code in (P211, P214, P215, P217, P223) else P211
            if target.code and target.code not in (P201, P203, P220, P221, P225):
                code = target.code
            what = _target(use)
            if code == P215:
                hint = f" ({dialect.undeclared_hint})" if dialect.undeclared_hint else ""
                msg = f"{what}: {target.why}{hint}: left as written"
            elif code == P223:
                msg = f"{what} is not known here ({target.why}, switched on): left as written"
            else:
                msg = f"{what} not statically known ({target.why}): left as written"
            rec.note(code, msg, loc, True)
            continue
        if not hasattr(target, "fields"):
            rec.note(P211, f"{_target(use)} is not a position: left as written", loc, True)
            continue
        view = dialect.view(target)
        if view.kind == "axis" and not s.relative:
            axes = dialect.axis_values(target)
            if axes is not None:
                key_axes[use.key] = tuple(axes)
        if view.kind != "cart":
            rec.escape(tokens_of(target), loc, f"{_target(use)} (not a Cartesian target) reads them")
            if view.kind == "other" and use.what and not isinstance(s.target, Agg):
                rec.note(P211, f"target {use.what} has type {target.type or 'unknown'}, not a position: left as "
                         "written", loc, True)
            continue
        if any(v is None for v in view.xyz) and isinstance(s.target, Agg):
            _where_it_stands(rec, rows, key_row, use.stand, loc)
        unknown_comp = next(((k, v) for k, v in zip("XYZABC", list(view.xyz) + list(view.orient)[:3])
                             if isinstance(v, Top)), None)
        if unknown_comp is not None:
            k, v = unknown_comp
            rec.note(P212, f"{_target(use)}: its {k} is not known here ({v.why}): left as written",
                     loc, True)
            # (it runs with the numbers it does hold: compensating them for another run would move it)
            rec.escape(tokens_of(target), loc, f"{_target(use)} left as written reads them")
            continue
        pose = [_NAN] * 6
        spans = [-1] * 12
        offset = [0.0, 0.0, 0.0]
        computed = []
        for k, v in enumerate(view.xyz):
            if isinstance(v, Tok):
                pose[k] = v.value
                spans[2 * k], spans[2 * k + 1] = v.token[1], v.token[2]
                offset[k] = v.offset
            elif number(v) is not None:
                pose[k] = number(v)
                if "XYZ"[k] not in use.filled:
                    computed.append("XYZ"[k])
        files = {v.token[0] for v in view.xyz if isinstance(v, Tok)}
        if computed:
            rec.escape(tokens_of(target), loc, f"{_target(use)} is computed from them")
            rec.note(P214, f"{_target(use)}: its {'/'.join(computed)} "
                     f"{'is' if len(computed) == 1 else 'are'} computed at run time from other values, not a number "
                     "of the program: left as written", loc, True)
            continue
        if any(f < 0 for f in files):  # (a configuration text is read, never written)
            rec.note(P211, f"{_target(use)}: its numbers stand in {_path(unit, min(files))}, which "
                     "is read only: left as written", loc, True)
            continue
        if len(files) > 1:
            rec.note(P214, f"{_target(use)}: its X/Y/Z come from numbers in several files: left "
                     "as written", loc, True)
            rec.escape(tokens_of(target), loc, f"{_target(use)} left as written reads them")
            continue
        orient = view.orient
        nums = [number(v) for v in orient]
        abc_spans = [[-1, -1] for _ in range(k_orient)]
        written_orient = [_NAN] * k_orient
        if all(n is not None for n in nums) and orient:
            if view.form == "abc":
                pose[3:6] = [float(x) for x in nums]
            elif view.form != form:
                with np.errstate(invalid="ignore"):
                    pose[3:6] = fr.abc_from_rotation(fr.orientation_rotation(np.array(nums, float), view.form)).tolist()
            # (in the program's form: A,B,C from the numbers as written, every row at once, _columns)
            if view.form == form:
                written_orient[:len(nums)] = [float(x) for x in nums]
                for j, v in enumerate(orient):
                    if isinstance(v, Tok) and v.offset == 0 and v.token[0] in files | {v.token[0]} and j < k_orient:
                        abc_spans[j] = list(v.token[1:])
        if view.form == "abc" and form == "abc":
            spans[6:12] = [x for pair in abc_spans for x in pair]
        file = next(iter(files)) if files else (view.loc.file if view.loc is not None else loc.file)
        if not isinstance(s.target, Agg):
            named = True
        changed = _changed_elsewhere(use.frame, use.tool)
        if changed is not None:  # (a frame or tool code the entry does not run changes: one finding a motion)
            rec.note(P233, f"{_target(use)} is left as written: {changed.why}", loc, True)
            rec.escape(tokens_of(target), loc, f"{_target(use)} left as written (P233) reads them")
            continue
        frame, covered = _moving_at(use.frame, view, use.what)
        if view.moving is not None and not (covered and set(view.external or ()) <= covered) \
                and not (isinstance(frame, Top) and frame.code == P225):  # (a unit not given: that one's why)
            frame = view.moving
        ix, why, code = frame_index(frame, use.tool)
        aloc = view.loc or loc
        first = (_path(unit, aloc.file), aloc.line, aloc.col, use)
        if ix < 0:
            at = first if why.code in (P220, P221) or why.loc is None else (
                _path(unit, why.loc.file), why.loc.line, why.loc.col, use)
            count(why, code, np.array([[aloc.file, aloc.line, aloc.col]]), at, (f"{_path(unit, loc.file)}:{loc.line}",))
        primary, others, axes = prev_of(use.preds, use.key)
        load, lcause = load_of(use.load, first[:3])
        cols = dict(pose=pose, spans=spans, abc=abc_spans, worient=written_orient, file=file, line=aloc.line,
                    col=aloc.col, frame=ix, motion=MOTION_INDEX[s.kind], config=view.config, offset=offset,
                    prev=primary, start=_NO_AXES if axes is None else axes, load=load, lcause=lcause, site=loc,
                    extras=dialect.row_extras(use, view))
        r = rows.add_one(cols)
        key_row[use.key] = r
        if s.relative:
            relative[r] = key_row.get(use.rel, -1)
        _emitted(rec, rows, use.key, r)
        used_keys.append(use.key)
        _twins_of(cols, others, rows, pending)
        for twin in pending.pop(use.key, []):
            twin["prev"] = r
            rows.add_one(twin)
    # twins whose predecessor never ran with a row: the predecessor is not known (a joint motion
    # to known axis values: where it leaves the robot)
    for key, waiting in pending.items():
        q = key_axes.get(key)
        for twin in waiting:
            twin["prev"], twin["start"] = -1, _NO_AXES if q is None else q
            rows.add_one(twin)
    rows.flush()
    targets = _columns(rows, k_orient, form)
    if relative:
        targets.relative = np.full(len(targets), -1, np.int32)
        targets.relative[list(relative)] = list(relative.values())
    if targets.load is not None:
        targets.load_causes = load_causes
    for (code, why), (left, first, wloc, places) in unknown.items():
        n = len(np.unique(np.concatenate(left).astype(np.int64), axis=0))
        if wloc is not None and code not in (P220, P221):
            path, line, col = _path(unit, wloc.file), wloc.line, wloc.col
        else:
            path, line, col = first
        what = _WHAT.get(code)
        msg = why if code in (P220, P221, P225) or what is None else f"{what} not statically known ({why})"
        motions = list(places)
        at = "" if motions == [f"{path}:{line}"] or not motions else f" (at {listed(motions)})"
        diagnostics.append(Diagnostic(path, line, col, code, f"{msg}: {n} target(s) left as written{at}"))
    sites = rows.sites()
    held = _groups(unit, targets, rec, diagnostics, sites)
    notes = []
    if assumed:
        taken = np.flatnonzero(np.isin(targets.frame, list(assumed)))
        if len(taken):
            r = int(taken[0])
            notes.append(Diagnostic(_path(unit, int(targets.file[r])), int(targets.line[r]), int(targets.col[r]), P224,
                                    "robot base = world assumed: $ROBROOT is not known (no --robroot, no machine "
                                    "data) and the program does not set it, so $NULLFRAME is taken; give --robroot "
                                    "X,Y,Z,A,B,C or the backup's Mada/$machine.dat (its System/$config.dat, or the "
                                    "backup directory)", "note"))
    for (code, loc, message), left in rec.notes.items():
        diagnostics.append(Diagnostic(_path(unit, loc.file), loc.line, loc.col, code, message))
    order = {path: k for k, path in enumerate(list(unit.files) + list(unit.config_names))}
    diagnostics.sort(key=lambda d: (order.get(d.path, len(order)), d.line, d.col))  # (in the order written)
    return Built(targets, frames, diagnostics, notes, held, named, rows.extras(), sites)


def _moving_at(frame, view, what: str):
    """A frame that moves with an external unit (``Moving``) at the axis value the target states:
    (the frame, the axes it took); a target that does not state that axis as a known number:
    Top (P225). Any other frame: (it, ())."""
    if not isinstance(frame, Moving):
        return frame, set()
    unit = frame.unit
    value = (view.external or {}).get(unit.axis)
    e = number(value)
    name = f"target {what}" if what else "the target"
    if e is None or not np.isfinite(e):
        why = value.why if isinstance(value, Top) else "not stated"
        return Top(f"{name} moves with the {unit.describe()}, and its {unit.axis} is not known ({why})", None,
                   P225), set()
    label = f"{frame.label or 'frame'} at {unit.axis} {e:g}"
    return Mat(frame.at(e), label, frame.tokens, frame.flags), {unit.axis}


def _changed_elsewhere(frame, tool):
    """The Top (P233) of a frame or tool that code the entry does not run changes, else None."""
    for v in (frame, tool):
        if isinstance(v, Top) and v.code == P233:
            return v
    return None


def _is_tool_unset(use) -> bool:
    tool = getattr(use, "tool", None)
    return isinstance(tool, Top) and tool.code == P221


def _twins_of(cols: dict, others: list, rows: _Rows, pending: dict) -> None:
    """The same target reached from its other predecessors: a row each (``prev`` that row, -1
    nothing known before), or waiting for a predecessor not emitted yet (``pending``)."""
    for o in others:
        twin = dict(cols)
        twin["start"] = _NO_AXES
        if isinstance(o, _Axes):
            twin["prev"], twin["start"] = -1, o.q
            rows.add_one(twin)
        elif isinstance(o, (int, np.integer)):
            twin["prev"] = int(o)
            rows.add_one(twin)
        else:
            pending.setdefault(o, []).append(twin)


def _where_it_stands(rec, rows: _Rows, key_row: dict, stand, loc) -> None:
    """A partial target whose missing components are not known here (the robot may come from
    several places) takes them at run time from the command before it: that command's numbers
    are read by it — compensating them would move it too (they escape). A predecessor not emitted
    yet (a loop's back edge): when it is (``rows.later``)."""
    for p in stand:
        r = key_row.get(p)
        if r is None:
            rows.later.setdefault(p, []).append(loc)
        elif r >= 0:
            rec.escape(rows.tokens_of(r), loc, "where the robot stands for a partial target after it")


def _emitted(rec, rows: _Rows, key, row: int) -> None:
    """Row ``row`` is the motion ``key``'s: the partial targets that wait for it read its numbers."""
    for loc in rows.later.pop(key, ()):
        if row >= 0:
            rec.escape(rows.tokens_of(row), loc, "where the robot stands for a partial target after it")


def _run_rows(unit, dialect, use: RunUse, rows: _Rows, frame_index, count, prev_of, key_row, form, rec, pending,
              load_of):
    """A MoveRun's rows: its frame for all, partial aggregates filled from the rows before
    (and where the robot stood before the run), the first row's predecessor."""
    r = use.run.rows
    n = len(r["line"])
    if not n:
        key_row[use.key] = key_row.get(use.key, -1)
        return
    frame = use.frame
    changed = _changed_elsewhere(frame, use.tool)
    if changed is not None:  # (each row a motion left: P233 at each, their numbers read by it)
        key_row[use.key] = -1
        spans = r["spans"]
        for i in range(n):
            at = Loc(int(r["file"][i]), int(r["line"][i]), int(r["col"][i]))
            rec.note(P233, f"the target is left as written: {changed.why}", at, True)
            rec.escape({(at.file, int(spans[i, 2 * k]), int(spans[i, 2 * k + 1])) for k in range(3)
                        if spans[i, 2 * k] >= 0}, at, "a target left as written (P233) reads them")
        return
    if isinstance(frame, Moving):  # (a run's rows carry no external axis values)
        frame = Top(f"the targets of this run move with the {frame.unit.describe()} and state no "
                    f"{frame.unit.axis}", None, P225)
    ix, why, code = frame_index(frame, use.tool)
    if ix < 0:
        first = (_path(unit, int(r["file"][0])), int(r["line"][0]), int(r["col"][0]), use)
        at = first if why.code in (P220, P221) or why.loc is None else (_path(unit, why.loc.file), why.loc.line,
                                                                         why.loc.col, use)
        count(why, code, np.stack([r["file"], r["line"], r["col"]], axis=1), at,
              [f"{first[0]}:{int(x)}" for x in np.unique(r["line"]).tolist()])
    pose = r["pose"].copy()
    written = r["written"]
    chain = r["chain"]
    if not written.all():
        ar = np.arange(n)
        cur = dict(use.cur[0]) if use.cur is not None and _same(use.cur[1], use.frame) and _same(use.cur[2], use.tool) else {}
        names = ("X", "Y", "Z", "A", "B", "C")
        for k in range(6):
            w = written[:, k]
            if w.all():
                continue
            src = np.where(chain & w, ar, -1)
            # the row before each: the last chain row that writes it (a row takes nothing from itself)
            before = np.concatenate([[-1], np.maximum.accumulate(src)[:-1]])
            need = np.flatnonzero(~w)
            prev = before[need]
            ok = prev >= 0
            pose[need[ok], k] = pose[prev[ok], k]
            start = cur.get(names[k])
            pose[need[~ok], k] = start if start is not None else np.nan
            if start is None and (~ok).any() and k < 3:
                loc = Loc(int(r["file"][need[~ok][0]]), int(r["line"][need[~ok][0]]), int(r["col"][need[~ok][0]]))
                _where_it_stands(rec, rows, key_row, use.stand, loc)
    primary, others, axes = prev_of(use.preds, use.key)
    rows.flush()
    prev = np.arange(rows.n - 1, rows.n - 1 + n, dtype=np.int32)
    prev[0] = primary
    spans = r["spans"]
    if r.get("ospans") is not None:  # (a form other than A,B,C: the run's numbers as written, located)
        abc, worient = r["ospans"], r["orient"]
    elif form == "abc":
        abc, worient = spans[:, 6:12].reshape(n, 3, 2), np.full((n, 3), np.nan)
    else:  # (the run's orientation columns hold its form's three numbers: A,B,C from them in _columns)
        abc, worient = spans[:, 6:12].reshape(n, 3, 2), pose[:, 3:6].copy()
        pose[:, 3:6] = np.nan
    extras = {k: list(v) for k, v in dialect.run_extras(use.run).items()}
    start = np.full((n, 6), np.nan)
    if axes is not None:
        start[0] = axes
    load, lcause = load_of(use.load, (_path(unit, int(r["file"][0])), int(r["line"][0]), int(r["col"][0])))
    rows.add(pose=pose, spans=spans, abc=abc, worient=worient,
             file=r["file"], line=r["line"], col=r["col"], frame=np.full(n, ix, np.int32), motion=r["motion"],
             config=r["config"], offset=np.zeros((n, 3)), prev=prev, start=start,
             load=None if lcause < 0 and np.isnan(load).all() else np.tile(np.asarray(load, float), (n, 1)),
             lcause=None if lcause < 0 else np.full(n, lcause, np.int32), site=None,  # (None: not set, no column)
             extras=extras)
    key_row[use.key] = rows.n - 1
    if others:  # (the run's first target reached from its other predecessors)
        first = dict(pose=pose[0].tolist(), spans=spans[0].tolist(), abc=abc[0].tolist(), worient=worient[0].tolist(),
                     file=int(r["file"][0]), line=int(r["line"][0]), col=int(r["col"][0]), frame=ix,
                     motion=int(r["motion"][0]), config=tuple(int(x) for x in r["config"][0]), offset=[0.0, 0.0, 0.0],
                     prev=-1, start=_NO_AXES, load=load, lcause=lcause, site=None,
                     extras={k: v[0] for k, v in extras.items()})
        _twins_of(first, others, rows, pending)
    last = key_row[use.key]
    _emitted(rec, rows, use.key, last)
    for twin in pending.pop(use.key, []):  # (twins that waited for this run: a loop's back edge)
        twin["prev"] = last
        rows.add_one(twin)


def _same(a, b) -> bool:
    if isinstance(a, Mat) and isinstance(b, Mat):
        return a == b
    if isinstance(a, tuple) and isinstance(b, tuple):  # (tools: Six, equal by their numbers)
        return a == b
    return a is b


def _columns(rows: _Rows, k_orient: int, form: str) -> Targets:
    parts = rows.parts
    n = rows.n
    if not parts:
        return Targets(poses=np.zeros((0, 6)), spans=np.zeros((0, 3, 2), np.int64),
                       abc_spans=np.zeros((0, k_orient, 2), np.int64), file=np.zeros(0, np.int32),
                       line=np.zeros(0, np.int32), col=np.zeros(0, np.int32), frame=np.zeros(0, np.int32),
                       motion=np.zeros(0, np.int8), config=np.zeros((0, 2), np.int16),
                       orientation=None if form == "abc" else np.zeros((0, k_orient)),
                       prev=np.zeros(0, np.int32), offset=None, twin=np.zeros(0, np.int32))

    def col(name):
        return np.concatenate([p[name] for p in parts]) if len(parts) > 1 else parts[0][name]

    spans = col("spans").reshape(n, 6, 2)
    offset = col("offset")
    targets = Targets(
        poses=col("pose"), spans=np.ascontiguousarray(spans[:, :3]),
        abc_spans=np.ascontiguousarray(col("abc").reshape(n, k_orient, 2)), file=col("file").astype(np.int32),
        line=col("line").astype(np.int32), col=col("col").astype(np.int32), frame=col("frame"), motion=col("motion"),
        config=col("config").astype(np.int16),
        orientation=None if form == "abc" else col("worient").reshape(n, k_orient),
        prev=col("prev"), offset=offset if offset.any() else None)
    start = col("start")
    if not np.isnan(start).all():
        targets.start = start
    if any(p["load"] is not None or p["lcause"] is not None for p in parts):  # (a program that sets none: None)
        load = np.concatenate([p["load"] if p["load"] is not None else np.full((len(p["line"]), 4), np.nan)
                               for p in parts])
        lcause = np.concatenate([p["lcause"] if p["lcause"] is not None else np.full(len(p["line"]), -1, np.int32)
                                 for p in parts]).astype(np.int32)
        if not np.isnan(load).all() or (lcause >= 0).any():
            targets.load, targets.load_cause = load, lcause
    if form != "abc":  # the rows' A,B,C from their orientation's numbers as written (build leaves them NaN)
        o = targets.orientation
        todo = np.isnan(targets.poses[:, 3]) & ~np.isnan(o).any(axis=1)
        if todo.any():
            with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
                targets.poses[todo, 3:6] = fr.abc_from_rotation(fr.orientation_rotation(o[todo], form))
    targets.twin = _twins(targets)
    return targets


def _twins(t: Targets) -> np.ndarray:
    """[N] the first row with the same X/Y/Z tokens (-1: the row is the first)."""
    n = len(t)
    twin = np.full(n, -1, np.int32)
    has = (t.spans[:, :, 0] >= 0).any(axis=1)
    if n < 2 or not has.any():
        return twin
    key = np.concatenate([t.file[:, None].astype(np.int64), t.spans[:, :, 0]], axis=1)
    rows = np.flatnonzero(has)
    order = np.lexsort(key[rows].T[::-1])
    s = key[rows][order]
    same = np.r_[False, (s[1:] == s[:-1]).all(axis=1)]
    if not same.any():
        return twin
    firsts = rows[order]
    head = np.maximum.accumulate(np.where(~same, np.arange(len(s)), 0))
    first_row = np.minimum.reduceat(firsts, np.flatnonzero(~same)) if len(s) else firsts
    grp = np.cumsum(~same) - 1
    lead = first_row[grp]
    mask = firsts != lead
    twin[firsts[mask]] = lead[mask]
    del head
    return twin


def _target(use) -> str:
    """"target XP1" (as the program names it), or "the target" (an aggregate written in the motion)."""
    return f"target {use.what}" if use.what else "the target"


def _groups(unit, t: Targets, rec, diagnostics: list, sites: list) -> dict:
    """``Targets.group``: rows that share any X/Y/Z token are one group (id: its first row; -1
    alone). A group with a token something else reads (``rec.escapes``) is held: P217 at each
    row (naming the motions to it where they stand elsewhere: ``sites``, each row's motion
    statement), the rows returned as held (code → rows)."""
    n = len(t)
    group = np.full(n, -1, np.int32)
    t.group = group
    starts = t.spans[:, :, 0]
    present = starts >= 0
    if not present.any():
        return {}
    r, c = np.nonzero(present)
    tok = np.stack([t.file[r].astype(np.int64), starts[r, c]], axis=1)
    order = np.lexsort((tok[:, 1], tok[:, 0]))
    ts, rs = tok[order], r[order]
    dup = np.r_[False, (ts[1:] == ts[:-1]).all(axis=1)]
    parent = {}

    def find(x):
        while parent.get(x, x) != x:
            parent[x] = parent.get(parent[x], parent[x])
            x = parent[x]
        return x

    shared_rows = set()
    for i in np.flatnonzero(dup).tolist():
        a, b = find(int(rs[i - 1])), find(int(rs[i]))
        shared_rows.update((int(rs[i - 1]), int(rs[i])))
        if a != b:
            parent[max(a, b)] = min(a, b)
    for x in shared_rows:
        group[x] = find(x)
    if not rec.escapes:
        return {}
    # (a token is (file, start, end); start alone names it within a file: one vectorised lookup)
    key = lambda f, s: (np.asarray(f, np.int64) << 40) | np.asarray(s, np.int64)  # noqa: E731
    escapes = key(*np.array([(f, s) for f, s, _ in rec.escapes], np.int64).T)
    escaped = (present & np.isin(key(t.file[:, None], starts), escapes)).any(axis=1)
    if not escaped.any():
        return {}
    held_groups = {int(group[i]) for i in np.flatnonzero(escaped) if group[i] >= 0}
    held = escaped | (np.isin(group, list(held_groups)) & (group >= 0))
    rows = np.flatnonzero(held)
    said = set()
    for i in rows.tolist():
        if (int(t.file[i]), int(t.line[i]), int(t.col[i])) in said:
            continue  # (another run of one target: said once)
        said.add((int(t.file[i]), int(t.line[i]), int(t.col[i])))
        token = next(((int(t.file[i]), int(t.spans[i, k, 0]), int(t.spans[i, k, 1])) for k in range(3)
                      if (int(t.file[i]), int(t.spans[i, k, 0]), int(t.spans[i, k, 1])) in rec.escapes), None)
        if token is None:
            continue
        wloc, why = rec.escapes[token]
        at = f" at {_path(unit, wloc.file)}:{wloc.line}" if wloc is not None else ""
        here = (t.file[rows] == t.file[i]) & (t.line[rows] == t.line[i]) & (t.col[rows] == t.col[i])
        motions = list(dict.fromkeys(
            f"{_path(unit, site.file)}:{site.line}" for site in (sites[k] if k < len(sites) else None
                                                                 for k in rows[here].tolist())
            if site is not None and (site.file, site.line) != (int(t.file[i]), int(t.line[i]))))
        moved = f" (moved to at {listed(motions)})" if motions else ""
        diagnostics.append(Diagnostic(_path(unit, int(t.file[i])), int(t.line[i]), int(t.col[i]), P217,
                                      f"this target's numbers{moved} are read{at} too ({why}): compensating them would "
                                      "change that as well; left as written"))
    return {P217: rows}

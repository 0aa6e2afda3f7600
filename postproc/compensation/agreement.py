"""The runs of one set of numbers (a loop, a routine called twice, copies) must agree."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..core.diagnostics import P230, P231, P322, Diagnostic, listed
from ..programs import Program
from ..programs.locate import collect, motion_at, where
from ..programs.rewrite import ORIENTATION_DECIMALS
from .findings import Selection

# the runs of one set of numbers (twins, copies) agree when the numbers each would have written
# differ by no more than this (mm; the orientation's numbers: this × their form's decimals per mm)
AGREE_MM = 0.005


# runs of one target at one pose that differ only in where they come from (the approach) are
# commanded at the middle of their commands where that is at most this far from each run's own
# (mm, as far as agreeing runs' numbers may be); further apart (another arm configuration, a
# model that depends much on the approach): left as written at every run (P230)
MIDDLE_MM = AGREE_MM


def _shared_tokens(program: Program, rows: np.ndarray, width: int):
    """For the selected ``rows`` that share numbers with other rows (``Targets.group``): per
    component written or inserted, a key of what the text holds there [m] (int64 pairs flattened
    to one sortable array), the position in ``rows`` and the column; None where no row shares."""
    t = program.targets
    group = getattr(t, "group", None)
    if group is None or not len(rows):
        return None
    shared = np.flatnonzero(group[rows] >= 0)
    if not len(shared):
        return None
    r = rows[shared]
    spans = t.spans[r, :, 0]  # X, Y, Z token starts (-1 missing: written in at the aggregate)
    cols = [spans]
    if width > 3 and t.abc_spans is not None:
        cols.append(t.abc_spans[r, :width - 3, 0])
    starts = np.concatenate(cols, axis=1)
    anchor = np.where(spans >= 0, spans, np.iinfo(np.int64).max).min(axis=1)  # the aggregate (its first token)
    k = np.arange(starts.shape[1])
    key_pos = np.where(starts >= 0, starts, -1 - anchor[:, None] * 8 - k[None, :])  # an insert: per aggregate, column
    key_file = np.repeat(t.file[r].astype(np.int64)[:, None], starts.shape[1], axis=1)
    pos = np.repeat(shared[:, None], starts.shape[1], axis=1)
    col = np.broadcast_to(k, starts.shape)
    return key_file.ravel(), key_pos.ravel(), pos.ravel(), np.asarray(col).ravel()


@dataclass
class _Agreement:
    """What the runs of one set of numbers came to: ``drop`` (positions in the selection left as
    written: whole groups whose runs need other numbers: other frames, tools, offsets),
    ``warnings`` (their P230), ``written`` (the numbers the text holds for each selected row:
    its group's first run's, [len(rows), width]), ``settled`` (positions whose runs differ only in
    where they come from, the approach: commanded at the middle of the runs' commands, the
    smallest worst case) with ``commanded`` [len(settled), 3] and ``notes`` (P322)."""

    drop: np.ndarray
    warnings: list
    written: np.ndarray
    settled: np.ndarray
    commanded: np.ndarray
    notes: list
    moved: np.ndarray = field(default_factory=lambda: np.zeros(0, int))  # positions moved with the point's own (P231)


def _agreement(program: Program, selection: Selection, new_xyz: np.ndarray, commanded: np.ndarray,
               orientation: bool = False) -> _Agreement:
    """The runs of one set of numbers (``Targets.group``): they agree where the numbers each would
    write differ by no more than ``AGREE_MM``; runs of one target at one pose that differ only in
    where they come from (the approach) are commanded at the middle (P322, a note); any other
    disagreement leaves the whole group as written (P230)."""
    rows = selection.rows
    written = new_xyz.copy()
    none = np.zeros(0, int)
    found = _shared_tokens(program, rows, new_xyz.shape[1])
    if found is None:
        return _Agreement(none, [], written, none, np.zeros((0, 3)), [])
    key_file, key_pos, pos, col = found
    value = new_xyz[pos, col]
    tol = np.where(col < 3, AGREE_MM, AGREE_MM * ORIENTATION_DECIMALS[program.orientation])
    order = np.lexsort((pos, key_pos, key_file))
    kf, kp, v, p, c, tl = key_file[order], key_pos[order], value[order], pos[order], col[order], tol[order]
    new = np.r_[True, (kf[1:] != kf[:-1]) | (kp[1:] != kp[:-1])]
    starts = np.flatnonzero(new)
    lead = np.repeat(starts, np.diff(np.r_[starts, len(v)]))
    with np.errstate(invalid="ignore"):
        spread = np.abs(v - v[lead])
    bad = spread > tl
    written[p, c] = v[lead]  # (what the text holds: the first run's number)
    t = program.targets
    group = t.group[rows]
    bad_groups = np.unique(group[p[bad]])
    if not len(bad_groups):
        return _Agreement(none, [], written, none, np.zeros((0, 3)), [])
    # a group whose rows are one target at one pose, frame and tool (runs that differ in their
    # predecessor only): the middle of its runs' commands
    approach = []
    for g in ([] if orientation else bad_groups.tolist()):  # (--orientation: the middle of turns is not settled)
        members = np.flatnonzero(group == g)
        r = rows[members]
        same = _alike(t.poses[r]) and \
            (t.frame[r] == t.frame[r[0]]).all() and (t.twin[r] >= 0).sum() == len(r) - 1 and \
            (selection.tool is None or (selection.tool[members] == selection.tool[members[0]]).all()) and \
            _same_load(selection, members)
        if same:
            approach.append(g)
    settled, middles, notes = [], [], []
    for g in list(approach):
        members = np.flatnonzero(group == g)
        lo, hi = commanded[members].min(axis=0), commanded[members].max(axis=0)
        mid = (lo + hi) / 2
        worst = float(np.linalg.norm((hi - lo) / 2))
        if not worst <= MIDDLE_MM:
            approach.remove(g)
            continue
        settled.extend(members.tolist())
        middles.extend([mid] * len(members))
        first = int(members[0])
        notes.append(Diagnostic(*where(program, int(rows[first])), P322,
                                f"this target runs {len(members)} times from other places (after a branch, in a loop"
                                f"{_motions(program, rows[members])}) "
                                f"and the runs need commands up to {2 * worst:.3f} mm apart (the approach): commanded "
                                f"at the middle, at most {worst:.3f} mm from each run's own", "note"))
    other = np.setdiff1d(bad_groups, approach)
    other, moved, moved_warnings = _owned(program, selection, other, (kf, kp, v, p, tl))
    drop = np.flatnonzero(np.isin(group, other) & (group >= 0)) if len(other) else none
    warnings = moved_warnings
    if len(drop):
        worst_of = {}
        for g, d in zip(group[p[bad]].tolist(), spread[bad].tolist()):
            worst_of[g] = max(worst_of.get(g, 0.0), d)
        places = np.stack([t.file[rows[drop]], t.line[rows[drop]], t.col[rows[drop]]], axis=1)
        _, once = np.unique(places, axis=0, return_index=True)  # (one warning per target, not per run)
        said = drop[np.sort(once)]
        def message(i):
            members = drop[group[drop] == group[said[i]]]
            motions = _motions(program, rows[members])
            return ("this target runs more than once{} and the runs need corrections up to {:.3f} mm apart: {}; no "
                    "one set of numbers is right for all, left as written — {}".format(
                        f" ({motions[2:]})" if motions else "", worst_of[int(group[said[i]])],
                        *_cause(program, selection, members)))

        warnings += collect(program, rows[said], P230, message)
    return _Agreement(drop, warnings, written, np.asarray(settled, int),
                      np.asarray(middles, float).reshape(-1, 3), notes, moved)


def _same_load(selection: Selection, members: np.ndarray) -> bool:
    """The runs (positions ``members`` in the selection) carry one payload (or the model takes none)."""
    load = selection.load
    if load is None:
        return True
    return _alike(load[members])


def _alike(values: np.ndarray) -> bool:
    """Every row of ``values`` [k, ...] equals the first, NaN equal to NaN (a component not written)."""
    v = np.asarray(values, float)
    return bool(((v == v[0]) | (np.isnan(v) & np.isnan(v[0]))).all())


def _cause(program: Program, selection: Selection, members: np.ndarray) -> tuple[str, str]:
    """Why the runs (positions ``members`` in the selection) of one set of numbers need other
    corrections, the one cause that applies, and the remedy that works for it."""
    t = program.targets
    r = selection.rows[members]
    if (t.frame[r] != t.frame[r[0]]).any():
        return ("its runs are in other frames (bases)", "give each frame its own point")
    if selection.tool is not None and (selection.tool[members] != selection.tool[members[0]]).any():
        return ("its runs are made with other tools", "give each tool its own point")
    if not _same_load(selection, members):
        return ("its runs carry other payloads (the model takes the load)", "give each payload its own point")
    if not _alike(t.poses[r]):
        return ("the point is copied into other points with other numbers (or moved to with other components)",
                "give each use its own point")
    if selection.joints is not None and not np.allclose(selection.joints[members], selection.joints[members[0]],
                                                        atol=1e-6, equal_nan=True):
        return ("its runs are made in other arm configurations", "state the configuration (S/T) at the point")
    prev = getattr(t, "prev", None)
    if prev is None:
        return ("its runs come from other places (the approach, which the model corrects)",
                "approach it the same way in every run")
    come = []
    for row in r.tolist():
        p = int(prev[row])
        come.append(f"from {motion_at(program, p)}" if p >= 0 else "from the program's start or a joint motion")
    come = list(dict.fromkeys(come))
    return (f"its runs come from other places ({', '.join(come[:3])}{' …' * (len(come) > 3)}: the approach, which the "
            "model corrects as the robot's backlash needs)",
            "approach it the same way in every run (a point before it that every run passes), or give each run "
            "its own point")


def _motions(program: Program, target_rows) -> str:
    """'; the motions at path:line, …' of the rows' motion statements ('' where they all stand at
    one place: the message's own location says it)."""
    places = list(dict.fromkeys(motion_at(program, int(r)) for r in np.asarray(target_rows).tolist()))
    return f"; the motions at {listed(places)}" if len(places) > 1 else ""


def _owned(program: Program, selection: Selection, groups: np.ndarray, entries) -> tuple:
    """Of the ``groups`` whose runs disagree, those whose runs at the point itself (no offset
    added: ``Targets.offset`` zero) agree among themselves while runs at an offset (``Offs(p, 0, 0,
    100)``, ``XA.Z = XS1.Z + 300``) need other numbers: the point's numbers are its own runs', and
    the runs at an offset move with that correction — said (P231), not compensated. ``entries``:
    _agreement's sorted token entries (file key, position key, value, position in the selection,
    tolerance). (groups left to P230, positions moved, their warnings)."""
    t = program.targets
    rows = selection.rows
    none = np.zeros(0, int)
    if not len(groups) or t.offset is None:
        return groups, none, []
    kf, kp, v, p, tl = entries
    group = t.group[rows]
    at_point = ~(np.abs(t.offset[rows]) > 1e-9).any(axis=1)
    gp = group[p]
    keep, moved, warnings = [], [], []
    for g in groups.tolist():
        members = np.flatnonzero(group == g)
        own = at_point[members]
        if not own.any() or own.all():
            keep.append(g)
            continue
        ref: dict = {}
        ent = np.flatnonzero(gp == g)
        for e in ent[at_point[p[ent]]].tolist():
            ref.setdefault((kf[e], kp[e]), v[e])
        agree, worst = True, 0.0
        for e in ent.tolist():
            r = ref.get((kf[e], kp[e]))
            if r is None:
                continue
            d = abs(v[e] - r)
            if at_point[p[e]]:
                agree &= not d > tl[e]
            elif d == d:
                worst = max(worst, d)
        if not agree:
            keep.append(g)
            continue
        off = members[~own]
        moved.extend(off.tolist())
        places = list(dict.fromkeys(motion_at(program, int(rows[i])) for i in off.tolist()))
        n = len(places)
        named = listed(places)
        warnings += collect(program, rows[off[:1]], P231, (
            f"this point's numbers are compensated for the motions to the point itself; {n} motion"
            f"{'s' if n != 1 else ''} to it at an offset (Offs/RelTool, a copy with a component changed; at {named}) move"
            f"{'' if n != 1 else 's'} with that correction, up to {worst:.3f} mm from {'their' if n != 1 else 'its'} "
            f"own: not compensated"))
    return np.asarray(keep, int), np.asarray(moved, int), warnings

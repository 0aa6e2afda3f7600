"""Arm configuration: which joint angles the controller will use for each Cartesian target.

A pose has up to 8 closed-form solutions (shoulder, elbow, wrist) and, for joints that turn
more than 360°, several turns of each. A program states which one in its controller's form —
KUKA's Status and Turn, ABB's confdata, FANUC's CONFIG (the forms, their bits and strings:
:mod:`postproc.robot.conventions`) — or leaves it to the controller's rules.

Targets without S/T follow the controller, in program order:

* a LIN/CIRC target keeps the configuration (same branch as the target before it) and every
  joint moves continuously from there (the turn nearest to the previous target's angle);
* a PTP target takes the solution nearest to the current axis position (the previous
  target's joint angles), over all branches and turns;
* the first target, if it states no S, takes the solution nearest ``initial_q``, the axis
  position before it (for a LIN too: HOME's A5 = 0 lies on the wrist-flip boundary); ``compensate``
  passes the joint angles the model's own IK gives for the first target (the model's
  ``joints`` output: today's behaviour), or HOME for a model without it.

A stated S without T keeps each joint's turn nearest to the previous angle; a stated T fixes
each joint's sign (the turn inside the limits with that sign). Targets whose configuration has
no solution (the pose unreachable on that branch, within the limits) come back NaN with
``ok`` False: the caller leaves them as written.

ABB's and FANUC's forms map on the same branch table for a description that says its
controller states them (``[robot] configuration``): the branch in S numbering plus a turn
*window* for each joint the form states. :func:`stated_configuration` reads a program's stated
forms into :class:`Stated` (branch, T, turn windows, and the rows whose form the description
cannot say: left as written, P309); the other way, joint angles → the strings / numbers a
program states, is ``conventions.fanuc_configs`` / ``conventions.abb_confdata``.

numpy only: the nominal arm is :class:`postproc.robot.arm.Robot`'s numpy kinematics (Pinocchio
only for the reference checks, postproc.robot.kinematics.reference).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core import frames
from ..core.diagnostics import P514
from . import conventions
from .arm import Robot
from .conventions import (TURN_JOINTS, UNSTATED, _abb_branch, arm_status, execution_kinds, parse_fanuc_config,
                          status_turn_of)

__all__ = ["branch_table", "stated_joints", "controller_joints", "measurement_joints", "Stated", "stated_configuration",
           "target_joints", "ordered_joints", "linear_changes"]

# rows per numpy pass over the branches: [8, BLOCK, 6] float64 (3 MB) stays in cache (~1.5x
# faster than one pass over a long program's table; the same numbers)
BLOCK = 8192
# A joint this close to 0° fits either sign of T (the turn of the written angle is kept): a
# pose written with 3 decimals moves its joint angles by ~1e-3°, and a compensated command
# (S and T left as written) by ~0.1° (a target taught at A6 −0.01° is commanded at +0.01°).
SIGN_TOLERANCE_DEG = 0.5


def _wrap(deg: np.ndarray) -> np.ndarray:
    return (deg + 180.0) % 360.0 - 180.0


def _distinct_rows(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(rows, axis=0, return_inverse=True)`` ([k, m] sorted, [N]), with the common
    case (one $TOOL for the whole program) without its sort of every row."""
    if len(rows) and (rows == rows[0]).all():
        return rows[:1].copy(), np.zeros(len(rows), int)
    distinct, which = np.unique(rows, axis=0, return_inverse=True)
    return distinct, which.ravel()


def branch_table(robot: Robot, poses: np.ndarray, tools: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Joint angles of each branch indexed by its status: [8 (S), N, 6] deg (one turn within the
    limits, NaN where that branch does not reach the pose) and the mask [8, N], every branch
    FK-checked. ``tools`` [N, 6]: each pose's TCP on the flange (default the robot's tool)."""
    branches = _Branches(robot, poses, tools, check_all=True)
    return branches.table, branches.ok


def _status_table(robot: Robot, poses: np.ndarray, check: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(table [8, N, 6], mask [8, N], rows where two branches have one status [N])."""
    n = len(poses)
    q_all, ok_all = robot.ik_branches(poses, np.zeros(6), check=check)
    b, i = np.nonzero(ok_all)
    shoulder = None if check else robot.shoulder_status(poses)
    # (only the branches that reach: ~half of them; S bit 0 from the shoulder branch where it decides)
    status, _ = robot.status_turn(q_all[b, i], None if shoulder is None else shoulder[b, i])
    table = np.full((8, n, 6), np.nan)
    ok = np.zeros((8, n), bool)
    table[status, i] = q_all[b, i]
    ok[status, i] = True
    return table, ok, ok.sum(axis=0) < ok_all.sum(axis=0)


class _Branches:
    """The branch table of a program's poses, solved and FK-checked lazily: the closed form is
    exact and the check (:meth:`Robot.reaches`) only guards the reachability masks, so only the
    entries the rules pick are checked (:meth:`confirm`, ~1 of the ~4 reaching branches of a
    target); a row with an entry that fails is solved again with every branch checked, and the
    rules run again. What the rules pick never fails its check, and they pick the same entries
    as on the fully checked table (an unchecked entry that is never picked changes no minimum),
    so the results are those of the fully checked table. Rows where two branches share a status
    are checked at once (the check decides which one stays).

    Rows are solved only as far as the rules read them: all 8 branches where a rule compares
    them (:meth:`need_rows`: a PTP without S, a pose list's row, the first target), else only
    the branch the target is on (:meth:`need`: a LIN keeps its configuration, a stated S),
    through :meth:`Robot.status_branch` where it is sure to give the full table's entry (no
    other branch of that status), all 8 where not. ``table`` and ``ok`` hold the entries solved
    so far (the others NaN / False: read only what ``need`` / ``need_rows`` solved)."""

    def __init__(self, robot: Robot, poses: np.ndarray, tools: np.ndarray | None, check_all: bool = False):
        self.poses = np.atleast_2d(np.asarray(poses, float))
        n = len(self.poses)
        if tools is None:
            self.arms, self.which = [robot], np.zeros(n, int)
        else:
            distinct, self.which = _distinct_rows(np.asarray(tools, float).reshape(n, 6))
            self.arms = [robot if np.array_equal(tool, robot.tool) else Robot(robot.description.replace(tool=tool))
                         for tool in distinct]  # (the few tools of a program)
        self.table = np.full((8, n, 6), np.nan)
        self.ok = np.zeros((8, n), bool)
        self.confirmed = np.full((8, n), check_all)
        self.check_all = check_all
        self.full = np.zeros(n, bool)  # rows with all 8 branches solved
        self.known = np.zeros((8, n), bool)  # entries solved alone (status_branch)
        if check_all:
            self.need_rows(np.arange(n))

    def need_rows(self, rows: np.ndarray) -> None:
        """Solve every branch of ``rows`` (those not solved yet)."""
        rows = np.asarray(rows, int)
        rows = rows[~self.full[rows]]
        if not len(rows):
            return
        self.full[rows] = True
        for k, arm in enumerate(self.arms):
            mine = rows[self.which[rows] == k]
            for at in range(0, len(mine), BLOCK):
                r = mine[at:at + BLOCK]
                self.table[:, r], self.ok[:, r], collide = _status_table(arm, self.poses[r], self.check_all)
                if collide.any() and not self.check_all:
                    self._check_rows(r[collide])

    def need(self, branch: np.ndarray, rows: np.ndarray) -> None:
        """Solve the entries (branch[i], rows[i]) not solved yet: alone where sure, else their rows."""
        branch, rows = (np.asarray(v, int).ravel() for v in np.broadcast_arrays(branch, rows))
        branch = branch % 8  # (as an index: UNSTATED reads the last)
        todo = np.flatnonzero(~self.full[rows] & ~self.known[branch, rows])
        if not len(todo):
            return
        branch, rows = branch[todo], rows[todo]
        code = np.unique(rows * 8 + branch)  # (each entry once)
        rows, branch = code // 8, code % 8
        unsure = []
        for k, arm, at in ((k, arm, at) for k, arm in enumerate(self.arms) for at in range(0, len(rows), BLOCK)):
            m = self.which[rows[at:at + BLOCK]] == k
            if not m.any():
                continue
            r, b = rows[at:at + BLOCK][m], branch[at:at + BLOCK][m]
            solved = arm.status_branch(self.poses[r], b)
            if solved is None:
                unsure.append(r)
                continue
            q, ok, sure = solved
            if ok.any():  # (the closed form's status of the entry: the index's, where sure)
                got = np.full(len(r), -1)
                got[ok] = arm.status_turn(q[ok], np.where(b[ok] & 1, 1, 0))[0]
                sure &= ~ok | (got == b)
            self.table[b[sure], r[sure]] = q[sure]
            self.ok[b[sure], r[sure]] = ok[sure]
            self.known[b[sure], r[sure]] = True
            unsure.append(r[~sure])
        if unsure:
            self.need_rows(np.concatenate(unsure))

    def nearest(self, rows: np.ndarray, status: np.ndarray, turn: np.ndarray, ref: np.ndarray,
                windows: np.ndarray | None = None):
        """``_choose`` for ``rows`` (their S, T, reference [m, 6]): (q [m, 6], found [m], the
        branch picked [m], sure [m]: the picked branch's Status is its index, see
        :meth:`Robot.status_branch`). A row without S or T whose nearest arm branch (A1-A3) is
        nearer than any other's by more than the float error (:meth:`Robot.nearest_pair`) compares only that
        arm's two wrists: every branch of another arm is farther (its A1-A3 alone are), so the
        pick is the same; the other rows solve all 8 (or their S's) and choose among them."""
        rows = np.asarray(rows, int)
        m = len(rows)
        ref = np.broadcast_to(np.asarray(ref, float), (m, 6))
        q, found, best = np.full((m, 6), np.nan), np.zeros(m, bool), np.zeros(m, int)
        rest = np.ones(m, bool)  # (the rows not done by pairs: also those not sure)
        free = np.flatnonzero((status < 0) & (turn < 0) & ~self.full[rows])
        for k, arm, at in ((k, arm, at) for k, arm in enumerate(self.arms) for at in range(0, len(free), BLOCK)):
            i = free[at:at + BLOCK][self.which[rows[free[at:at + BLOCK]]] == k]
            pair = arm.nearest_pair(self.poses[rows[i]], ref[i]) if len(i) else None
            if pair is None:
                continue
            q2, ok2, s2, others, sure = pair
            cand, cost = _candidates(arm, q2, ok2, turn[i], ref[i])
            pick = np.where(cost[1] < cost[0], 1, np.where(cost[1] == cost[0], (s2[1] < s2[0]).astype(int), 0))
            at_i = np.arange(len(i))
            least = cost[pick, at_i]
            alone = sure & np.isfinite(least) & (others > least * (1.0 + 1e-9) + 1e-9)  # (the float error of the sums)
            r, j = rows[i[alone]], i[alone]
            for w in (0, 1):  # the table's entries of both wrists (confirm, the rules after this read them)
                self.table[s2[w, alone], r] = q2[w, alone]
                self.ok[s2[w, alone], r] = ok2[w, alone]
                self.known[s2[w, alone], r] = True
            q[j] = cand[pick[alone], at_i[alone]]
            found[j] = True
            best[j] = s2[pick[alone], at_i[alone]]
            rest[j] = False
        if rest.any():
            r = rows[rest]
            stated = status[rest] >= 0
            self.need(status[rest][stated], r[stated])
            self.need_rows(r[~stated])
            q[rest], found[rest], best[rest] = _choose(self.arms[0], self.table, self.ok, status[rest], turn[rest], ref[rest], r,
                                                       None if windows is None else windows[rest])
        return q, found, best, ~rest

    def _check_rows(self, rows: np.ndarray) -> None:
        for k, arm in enumerate(self.arms):
            r = rows[self.which[rows] == k]
            if len(r):
                self.table[:, r], self.ok[:, r], _ = _status_table(arm, self.poses[r], True)
        self.full[rows] = True
        self.confirmed[:, rows] = True

    def confirm(self, branch: np.ndarray, rows: np.ndarray) -> bool:
        """FK-check the picked entries (branch[i], rows[i]) not checked yet; True if one failed
        (its row is then solved again with every branch checked: run the rules again)."""
        branch, rows = (np.asarray(v, int).ravel() for v in np.broadcast_arrays(branch, rows))
        pick = self.ok[branch, rows] & ~self.confirmed[branch, rows]
        branch, rows = branch[pick], rows[pick]
        if not len(rows):
            return False
        self.confirmed[branch, rows] = True
        bad = []
        for k, arm in enumerate(self.arms):
            m = self.which[rows] == k
            if m.any():
                good = arm.reaches(self.table[branch[m], rows[m]], frames.frame_to_matrix(self.poses[rows[m]]))
                bad.append(rows[m][~good])
        bad = np.unique(np.concatenate(bad))
        if len(bad):
            self._check_rows(bad)
        return bool(len(bad))


def _turn_for_sign(robot: Robot, q: np.ndarray, turn: np.ndarray) -> np.ndarray:
    """Each joint of ``q`` [..., 6] on the turn whose sign T [...] states (nearest to ``q``
    within the limits); NaN where no turn has that sign within the limits."""
    lo, hi = robot.limits[:, 0], robot.limits[:, 1]
    want_negative = ((turn[..., None] >> np.arange(6)) & 1).astype(bool)
    best = np.full(q.shape, np.nan)
    best_d = np.full(q.shape, np.inf)
    with np.errstate(invalid="ignore"):
        for k in (0, -1, 1, -2, 2):
            c = q + 360.0 * k
            sign_ok = np.where(want_negative, c < SIGN_TOLERANCE_DEG, c > -SIGN_TOLERANCE_DEG)
            fits = (c >= lo - 1e-9) & (c <= hi + 1e-9) & sign_ok
            closer = fits & (abs(k) < best_d)
            best = np.where(closer, c, best)
            best_d = np.where(closer, abs(k), best_d)
    return best


def stated_joints(robot: Robot, poses: np.ndarray, status: np.ndarray, turn: np.ndarray,
                  reference: np.ndarray | None = None, tools: np.ndarray | None = None,
                  check_all: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The joint angles [N, 6] (deg) of the branch each target's S and T state, and a mask of
    the targets that have one. Poses [N, 6] in the robot base frame (TCP with the robot's
    tool); S, T [N] ints. Joints whose T is UNSTATED take the turn nearest ``reference``
    ([6] or [N, 6], default HOME); a target whose S is UNSTATED takes the branch nearest it.
    ``tools`` [N, 6]: each target's TCP on the flange (default the robot's tool). ``check_all``:
    FK-check every branch up front instead of only those the rules pick (same result, slower:
    the reference for tests and benchmarks)."""
    poses = np.atleast_2d(np.asarray(poses, float))
    n = len(poses)
    ref = np.broadcast_to(robot.home_q if reference is None else np.asarray(reference, float), (n, 6))
    branches = _Branches(robot, poses, tools, check_all)
    status, turn = arm_status(np.asarray(status).reshape(n)), np.asarray(turn).reshape(n)
    branches.need(status[status >= 0], np.flatnonzero(status >= 0))
    branches.need_rows(np.flatnonzero(status < 0))
    while True:
        q, found, best = _choose(robot, branches.table, branches.ok, status, turn, ref)
        if not branches.confirm(best, np.arange(n)):
            return q, found


def _status_of(robot: Robot, q: np.ndarray, best: np.ndarray, sure: np.ndarray) -> np.ndarray:
    """The Status of the chosen joint angles [n, 6]: the branch picked where ``sure`` (its
    index is its Status, clear of every boundary), else :func:`status_turn_of`."""
    out = best.copy()
    if not sure.all():
        out[~sure] = status_turn_of(robot, q[~sure])[0]
    return out


def _choose(robot: Robot, table: np.ndarray, ok: np.ndarray, status: np.ndarray, turn: np.ndarray,
            ref: np.ndarray, of: np.ndarray | None = None,
            windows: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(q [n, 6], found [n], the branch picked [n]) of each row's candidate nearest ``ref``: a
    row with a stated S has the one candidate of its branch, the others 8 (one per branch).
    ``of`` [n]: the rows of ``table`` these are (default all of them); ``windows`` [n, 6, 2]
    the turn windows the rows state (:class:`Stated`)."""
    n = table.shape[1] if of is None else len(of)
    of = np.arange(n) if of is None else of
    ref = np.broadcast_to(ref, (n, 6))
    q = np.full((n, 6), np.nan)
    found = np.zeros(n, bool)
    best = np.where(status >= 0, status, 0)
    for stated in (True, False):  # (two vectorised groups, not a loop over targets)
        rows = np.flatnonzero((status >= 0) == stated)
        if not len(rows):
            continue
        for block in (rows[at:at + BLOCK] for at in range(0, len(rows), BLOCK)):
            if stated:
                cand, cost = _candidates(robot, table[status[block], of[block]][None], ok[status[block], of[block]][None],
                                         turn[block], ref[block], None if windows is None else windows[block])
                pick = np.zeros(len(block), int)
            else:
                cand, cost = _candidates(robot, table[:, of[block]], ok[:, of[block]], turn[block], ref[block],
                                         None if windows is None else windows[block])
                pick = np.argmin(cost, axis=0)
                best[block] = pick
            at = np.arange(len(block))
            found[block] = np.isfinite(cost[pick, at])
            q[block] = np.where(found[block][:, None], cand[pick, at], np.nan)
    return q, found, best


def _candidates(robot: Robot, table: np.ndarray, ok: np.ndarray, turn: np.ndarray,
                ref: np.ndarray, windows: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Candidates [B, n, 6] of the branches [B, n, 6] on the turn T states (else the turn nearest
    ``ref``; joints with a turn window [n, 6, 2]: the turn in it) and their squared distance to
    ``ref`` [B, n] (inf where none)."""
    cand, in_limits = robot.nearest_turn(table, ref)
    stated = np.flatnonzero(turn >= 0)  # (only those: most programs state no T)
    if len(stated):
        cand[:, stated] = _turn_for_sign(robot, table[:, stated], np.broadcast_to(turn[stated], table.shape[:1] + stated.shape))
    if windows is not None:
        rows = np.flatnonzero(np.isfinite(windows[..., 0]).any(axis=1))
        if len(rows):
            turned = _turn_in_window(robot, table[:, rows], windows[rows])
            free = ~np.isfinite(windows[rows, :, 0])  # (the joints the form does not state keep theirs)
            cand[:, rows] = np.where(free, cand[:, rows], turned)  # (NaN where no turn of the window: no candidate)
    good = ok & in_limits & np.isfinite(cand).all(axis=-1)
    with np.errstate(invalid="ignore"):
        cost = np.where(good, ((cand - ref) ** 2).sum(axis=-1), np.inf)
    return cand, cost


def controller_joints(robot: Robot, poses: np.ndarray, status: np.ndarray, turn: np.ndarray,
                      ptp: np.ndarray, initial_q: np.ndarray | None = None,
                      tools: np.ndarray | None = None,
                      independent: np.ndarray | None = None, check_all: bool = False,
                      chain=None, windows: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The joint angles [N, 6] (deg) the controller uses for targets in program order, and a mask
    of the targets that have them: stated S/T where given, else the controller's rules (module
    docstring). ``ptp`` [N] bool marks PTP motions (PTP, SPTP; the rest keep the configuration);
    ``initial_q`` [6] the axis position before the first target (default HOME); ``tools`` [N, 6]
    each target's TCP on the flange (default the robot's tool); ``independent`` [N] bool: rows
    solved on their own, nearest ``initial_q`` whatever came before (a pose list's rows: each
    pose reached as ``measure`` reaches it, the branch nearest HOME). ``check_all`` as in
    :func:`stated_joints`. ``chain`` (a ``compensator.Chain``, for a program fed a part at a
    time): its ``joints`` / ``branch`` (the last target's of the part before; None: this is the
    first part) continue the rules as one call would, and are set to this part's last.
    ``windows`` [N, 6, 2] deg: the turn windows a program's form states for some joints
    (ABB's quadrants, FANUC's turn numbers: :class:`Stated`; NaN = not stated)."""
    poses = np.atleast_2d(np.asarray(poses, float))
    n = len(poses)
    status = arm_status(np.asarray(status, int).reshape(n))
    turn = np.asarray(turn, int).reshape(n)
    ptp = np.asarray(ptp, bool).reshape(n)
    start = np.asarray(robot.home_q if initial_q is None else initial_q, float).reshape(6)
    if n == 0:
        return np.zeros((0, 6)), np.zeros(0, bool)
    branches = _Branches(robot, poses, tools, check_all)
    alone = np.zeros(n, bool) if independent is None else np.asarray(independent, bool).reshape(n)
    while True:
        q, found, picks, filled = _rules(robot, branches, status, turn, ptp, start, alone, chain, windows)
        if not any([branches.confirm(b, r) for b, r in picks]):  # (every pick checked)
            if chain is not None:
                last = _forward_fill_rows(q)[-1]
                chain.joints = last if np.isfinite(last).all() else chain.joints
                chain.branch = int(filled[-1])
            return q, found


def _rules(robot: Robot, branches: _Branches, status: np.ndarray, turn: np.ndarray, ptp: np.ndarray,
           start: np.ndarray, alone: np.ndarray, chain=None,
           windows: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, list]:
    """The controller's rules on a branch table: (q, found, the (branch, rows) entries picked,
    each target's branch);
    ``chain``, ``windows``: see ``controller_joints``."""
    n = len(status)
    table, ok = branches.table, branches.ok  # (solved as the rules read them: need, need_rows)
    picks = []
    continued = chain is not None and chain.joints is not None
    before = np.asarray(chain.joints, float) if continued else start  # the axis position before row 0
    start_s = chain.branch if continued else int(status_turn_of(robot, start[None])[0][0])
    # the branch each target is on: stated, else the previous target's (the first: the start's)
    branch = np.where(status >= 0, status, UNSTATED)
    free_ptp = (status < 0) & ptp
    if not continued:
        free_ptp[0] = status[0] < 0  # the first target: nearest the start position, whatever its motion
    free_ptp &= ~alone
    q_alone = ok_alone = None
    if alone.any():
        q_alone, ok_alone, best, sure = branches.nearest(np.flatnonzero(alone), status[alone], turn[alone], start,
                                                         None if windows is None else windows[alone])
        picks.append((best, np.flatnonzero(alone)))
        branch[alone] = np.where(ok_alone, _status_of(robot, q_alone, best, sure), branch[alone])
    if free_ptp.any():
        # a first guess for the free PTP targets: each one's solution nearest the start. (The
        # start's own branch forward-filled was a chain the passes undid one target at a time:
        # HOME's A5 = 0 counts as the flipped wrist.)
        q_guess, ok_guess, best, sure = branches.nearest(np.flatnonzero(free_ptp), np.full(int(free_ptp.sum()), UNSTATED),
                                                         turn[free_ptp], start)
        picks.append((best, np.flatnonzero(free_ptp)))
        branch[free_ptp] = np.where(ok_guess, _status_of(robot, q_guess, best, sure), UNSTATED)
    q = found = None
    # passes over the program for PTP targets that switch branch: each pass settles at least the
    # next target in program order, so a program of n targets needs at most n + 1; usually a few
    # (a chain of choices that each depend on the one before — a wrist flip early in a long PTP
    # program — settles one target per pass: 20 passes, the old cap, left such targets wrong)
    for _ in range(n + 1):
        filled = _forward_fill(branch, start_s)
        picks.append((filled, np.arange(n)))
        branches.need(filled, np.arange(n))
        q, found = _continue_turns(robot, table, ok, filled, turn, start, before, windows)
        if not free_ptp.any():
            break
        # PTP without S: the solution nearest the previous target's joint angles, any branch
        previous = np.vstack([before[None], _forward_fill_rows(q)[:-1]])
        q_ptp, ok_ptp, best, sure = branches.nearest(np.flatnonzero(free_ptp), np.full(int(free_ptp.sum()), UNSTATED),
                                                     turn[free_ptp], previous[free_ptp])
        picks.append((best, np.flatnonzero(free_ptp)))
        chosen = np.where(ok_ptp, _status_of(robot, q_ptp, best, sure), UNSTATED)
        new = branch.copy()
        new[free_ptp] = chosen
        if np.array_equal(new, branch):
            break
        branch = new
    if alone.any():
        q[alone], found[alone] = q_alone, ok_alone
    return q, found, picks, filled


def _forward_fill(values: np.ndarray, first: int) -> np.ndarray:
    """UNSTATED entries take the last stated value before them (``first`` before any)."""
    idx = np.where(values >= 0, np.arange(len(values)), -1)
    np.maximum.accumulate(idx, out=idx)
    return np.where(idx >= 0, values[np.maximum(idx, 0)], first)


def _forward_fill_rows(q: np.ndarray) -> np.ndarray:
    """Rows with NaN take the last finite row before them (HOME-free: the first stays NaN)."""
    good = np.isfinite(q).all(axis=1)
    idx = np.where(good, np.arange(len(q)), -1)
    np.maximum.accumulate(idx, out=idx)
    out = q[np.maximum(idx, 0)].copy()
    out[idx < 0] = np.nan
    return out


def _continue_turns(robot: Robot, table: np.ndarray, ok: np.ndarray, branch: np.ndarray, turn: np.ndarray,
                    start: np.ndarray, before: np.ndarray | None = None,
                    windows: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Joint angles on the given branches [N]: joints with a stated T on that turn, joints with
    a turn window [N, 6, 2] on the turn in it, the others continuing from the previous target
    (unwrapped from the turn before: continuous motion), brought inside the limits. A run
    restarts after a target without solution. ``before``: the axis position before the first
    row (default ``start``, the program's start position)."""
    before = start if before is None else before
    n = len(branch)
    rows = np.arange(n)
    principal = table[branch, rows]
    reached = ok[branch, rows]
    principal[~reached] = np.nan
    # the joint path: each step the shortest way round, from the start position
    anchors = np.vstack([before[None], principal])
    steps = _wrap(np.diff(anchors, axis=0))
    broken = ~np.isfinite(steps).all(axis=1)
    steps[broken] = 0.0
    path = before + np.cumsum(steps, axis=0)
    # the motion restarts at a target with a stated T (its turn) and after an unreachable
    # target (the target's own turn nearest the start position)
    stated = (turn >= 0) & reached
    restart = stated | (broken & reached)
    if restart.any():
        first_rows = np.flatnonzero(restart)
        anchor = robot.nearest_turn(principal[first_rows], np.broadcast_to(start, (len(first_rows), 6)))[0]
        signed = stated[first_rows]
        anchor[signed] = _turn_for_sign(robot, principal[first_rows[signed]], turn[first_rows[signed]])
        offset = np.zeros((len(first_rows) + 1, 6))
        fits = np.isfinite(anchor).all(axis=1)
        offset[1:][fits] = anchor[fits] - path[first_rows[fits]]
        path = path + offset[np.cumsum(restart)]
        reached[first_rows[~fits]] = False  # a stated T no turn within the limits has
    if windows is not None:  # each joint a window states restarts there on the window's turn
        framed = np.isfinite(windows[:, :, 0]) & reached[:, None]
        if framed.any():
            anchor = np.full((n, 6), np.nan)
            some = framed.any(axis=1)
            anchor[some] = _turn_in_window(robot, principal[some], windows[some])
            reached &= ~(framed & ~np.isfinite(anchor)).any(axis=1)  # no turn of the window within the limits
            for j in np.flatnonzero(framed.any(axis=0)):
                at = framed[:, j] & np.isfinite(anchor[:, j])
                last = np.maximum.accumulate(np.where(at, rows, -1))
                has = last >= 0
                path[has, j] = anchor[last[has], j] + (path[has, j] - path[last[has], j])
    # the same turns on the exact angles (no drift of the sums), brought inside the limits
    with np.errstate(invalid="ignore"):
        q = principal + 360.0 * np.rint((path - principal) / 360.0)
    q, _ = robot.nearest_turn(q, q)
    q[~reached] = np.nan
    found = reached & np.isfinite(q).all(axis=1)
    q[~found] = np.nan
    return q, found


def _turn_in_window(robot: Robot, q: np.ndarray, windows: np.ndarray) -> np.ndarray:
    """Each joint of ``q`` [..., 6] (deg) on the turn (q + k·360°, within the limits) nearest its
    window ``windows`` [..., 6, 2] (inside it where one is; ties: nearest its middle); NaN where
    no turn lies within the limits; joints without a window (NaN) as they are."""
    lo, hi = robot.limits[:, 0], robot.limits[:, 1]
    w_lo, w_hi = windows[..., 0], windows[..., 1]
    middle = (w_lo + w_hi) / 2.0
    best = np.full(np.broadcast_shapes(q.shape, w_lo.shape), np.nan)
    best_d = np.full(best.shape, np.inf)
    with np.errstate(invalid="ignore"):
        for k in (0, -1, 1, -2, 2):
            c = q + 360.0 * k
            inside = (c >= lo - 1e-9) & (c <= hi + 1e-9)
            d = np.maximum(np.maximum(w_lo - c, c - w_hi), 0.0) * 1e6 + np.abs(c - middle)
            closer = inside & (d < best_d)
            best = np.where(closer, c, best)
            best_d = np.where(closer, d, best_d)
    return np.where(np.isfinite(w_lo), best, q)


# --------------------------------------------------------------------------- what a program states


@dataclass
class Stated:
    """The arm configuration targets state, mapped on a description's branch table: ``status``
    [N] the branch (S numbering, bits 0–2; UNSTATED), ``turn`` [N] KUKA's T (UNSTATED), and
    ``windows`` [N, 6, 2] (deg) the turn windows other forms state for some joints (NaN: not
    stated; None: none at all)."""

    status: np.ndarray
    turn: np.ndarray
    windows: np.ndarray | None = None

    def take(self, rows) -> "Stated":
        return Stated(self.status[rows], self.turn[rows], None if self.windows is None else self.windows[rows])

    @classmethod
    def unstated(cls, n: int) -> "Stated":
        return cls(np.full(n, UNSTATED), np.full(n, UNSTATED))


def stated_configuration(program, description, rows: np.ndarray) -> tuple[Stated, np.ndarray, list[str]]:
    """What targets ``rows`` of a program state of their arm configuration, mapped on the branch
    table of ``description`` (a RobotDescription): (:class:`Stated`, a mask [n] of the rows whose
    stated form the description cannot say or that is malformed — left as written, P309 —, and
    the reason of each of those, in order). KUKA's S/T (``Targets.config``) is read on any arm,
    on the motions that read it (a KRL LIN or CIRC keeps the configuration the robot is in: its
    S/T count as not stated, ``conventions.ignored_status_turn``); ABB's confdata (``RapidProgram.confdata``) only for a description whose ``configuration`` is
    "abb", FANUC's CONFIG (``FanucProgram.configs``) only for "fanuc": never a guess."""
    rows = np.asarray(rows, int)
    n = len(rows)
    config = getattr(program.targets, "config", None)
    if config is None:
        stated = Stated.unstated(n)
    else:
        stated = Stated(np.asarray(config[rows, 0], int), np.asarray(config[rows, 1], int))
        ignored = conventions.ignored_status_turn(program, rows)  # (KRL's LIN, CIRC: the configuration kept)
        stated.status[ignored], stated.turn[ignored] = UNSTATED, UNSTATED
    unmapped = np.zeros(n, bool)
    why: list[str] = []
    form = getattr(description, "configuration", "")
    name = getattr(description, "name", "the robot")
    raw_conf = getattr(program, "confdata", None) if program.dialect == "rapid" else None
    raw_fanuc = getattr(program, "configs", None) if program.dialect == "fanuc" else None
    if raw_conf is not None and len(raw_conf):
        conf = np.asarray(raw_conf, float)[rows]
        given = np.isfinite(conf).any(axis=1)
        if form != "abb":
            unmapped |= given
            why += [f"the target states ABB confdata {_shown(conf[i])} and the description of {name} does not say "
                    "how its controller's configurations map on the arm ([robot] configuration = \"abb\")"
                    for i in np.flatnonzero(given)]
        else:
            status, windows, good = _abb_branch(conf)
            stated.status = np.where(good, status, stated.status)
            stated.windows = windows
            bad = given & ~good
            unmapped |= bad
            why += [f"confdata {_shown(conf[i])} is not four integers with cfx 0…7" for i in np.flatnonzero(bad)]
    if raw_fanuc is not None and len(raw_fanuc):
        texts = [raw_fanuc[r] for r in rows]
        given = np.array([bool(t.strip()) for t in texts], bool)
        if form != "fanuc":
            unmapped |= given
            why += [f"the target states FANUC CONFIG '{texts[i]}' and the description of {name} does not say how its "
                    "controller's configurations map on the arm ([robot] configuration = \"fanuc\")"
                    for i in np.flatnonzero(given)]
        else:
            windows = np.full((n, 6, 2), np.nan)
            for i in np.flatnonzero(given):
                parsed = parse_fanuc_config(texts[i])
                if parsed is None:
                    unmapped[i] = True
                    why.append(f"CONFIG '{texts[i]}' is not of the form 'F|N U|D T|B, t1, t4, t6'")
                    continue
                stated.status[i], turns = parsed
                for t, j in zip(turns, TURN_JOINTS):
                    if t != -999:
                        windows[i, j] = (360.0 * t - 180.0, 360.0 * t + 180.0)
            stated.windows = windows
    other = getattr(program, "unmapped_configuration", None)  # (a form no description maps: URScript's qnear)
    if other is not None and len(other):
        more = np.asarray(other, bool)[rows] & ~unmapped
        if more.any():
            reasons = dict(zip(np.flatnonzero(unmapped).tolist(), why))
            for i in np.flatnonzero(more).tolist():
                reasons[i] = ("the target states its arm configuration in a form postproc does not map on joint angles "
                              "(URScript's get_inverse_kin qnear: the solution nearest those joints)")
            unmapped |= more
            why = [reasons[i] for i in np.flatnonzero(unmapped).tolist()]
    return stated, unmapped, why


def _shown(conf: np.ndarray) -> str:
    return "[" + ",".join("?" if not np.isfinite(v) else f"{v:g}" for v in conf) + "]"


# --------------------------------------------------------------------------- targets of a program

def target_joints(robot: Robot, targets, rows: np.ndarray, poses: np.ndarray, tools: np.ndarray | None = None,
                  initial_q: np.ndarray | None = None, chain=None,
                  stated: Stated | None = None, order=None) -> tuple[np.ndarray, np.ndarray]:
    """The controller's joint angles [n, 6] (deg) for ``rows`` of a program's ``Targets`` (in
    program order) at ``poses`` [n, 6] (robot base, TCP) with ``tools`` [n, 6], and a mask of
    those that have them: the program's own joint angles where it gives them (``Targets.joints``),
    else its stated configuration (``stated``: :func:`stated_configuration` of these rows;
    default its S/T, ``Targets.config``), else the controller's rules (module docstring).
    ``order`` (``compensator.Order``): each row's predecessor where it is not the row before (a
    branch, a loop, a routine called from two places): the rules continue from it, run by run."""
    rows = np.asarray(rows, int)
    n = len(rows)
    if stated is None:
        config = getattr(targets, "config", None)
        stated = Stated.unstated(n) if config is None else Stated(np.asarray(config[rows, 0], int),
                                                                   np.asarray(config[rows, 1], int))
    nearest, alone = execution_kinds(np.asarray(targets.motion)[rows])
    starts = getattr(targets, "start", None)
    starts = None if starts is None else starts[rows]
    if order is not None and not order.sequential and n:
        q, ok = ordered_joints(robot, poses, stated, nearest, initial_q, tools, alone, order.prev, starts)
    else:
        if starts is not None and n and np.isfinite(starts[0]).all() and (chain is None or chain.joints is None):
            initial_q = starts[0]  # (the program's own: a joint motion to known axis values before it)
        q, ok = controller_joints(robot, poses, stated.status, stated.turn, nearest, initial_q, tools, alone,
                                  chain=chain, windows=stated.windows)
    given = getattr(targets, "joints", None)
    if given is not None:
        own = np.isfinite(given[rows]).all(axis=1)
        q[own], ok[own] = given[rows][own], True
    return q, ok


def ordered_joints(robot: Robot, poses, stated, nearest, initial_q, tools, alone, prev: np.ndarray,
                   axes: np.ndarray | None = None):
    """``controller_joints`` run by run of rows that follow each other (``prev`` [n]: each row's
    predecessor row, ``compensator.Order.prev``): each run continues from its first row's
    predecessor (its joint angles and branch), from the axis values a joint motion left the
    robot at (``axes`` [n, 6] deg, ``Targets.start``), or starts afresh (``initial_q``) where
    nothing is known before it."""
    from types import SimpleNamespace

    n = len(poses)
    q = np.full((n, 6), np.nan)
    ok = np.zeros(n, bool)
    prev = np.asarray(prev)
    starts = np.flatnonzero(np.r_[True, prev[1:] != np.arange(n - 1)])
    ends = np.r_[starts[1:], n]
    for a, b in zip(starts.tolist(), ends.tolist()):
        p = int(prev[a])
        chain = None
        first_q = initial_q
        if p >= 0 and ok[p]:
            chain = SimpleNamespace(joints=q[p].copy(), branch=int(status_turn_of(robot, q[p][None])[0][0]))
        elif p < 0 and axes is not None and np.isfinite(axes[a]).all():
            first_q = axes[a]
        part = slice(a, b)
        q[part], ok[part] = controller_joints(robot, poses[part], stated.status[part], stated.turn[part],
                                              nearest[part], first_q, None if tools is None else tools[part],
                                              alone[part], chain=chain,
                                              windows=None if stated.windows is None else stated.windows[part])
    return q, ok


def linear_changes(robot: Robot, targets, rows: np.ndarray, stated: Stated, q: np.ndarray,
                   order=None) -> np.ndarray:
    """[n] bool: linear targets (LIN, CIRC: not PTP, not a pose list's row) of ``rows`` whose
    stated branch (an ABB or FANUC form: ``stated.windows``) is not the branch of the target
    before them (its predecessor: ``order``, else the row before), whose joint angles ``q``
    [n, 6] are. A linear motion keeps the arm's configuration: the controller stops there
    (``ConfL\\On``, FANUC) or keeps its own (``ConfL\\Off``) — which one the program text does not
    say, so the caller leaves them as written (P309). KUKA's S/T on a LIN, which the controller
    ignores, is not judged here."""
    n = len(rows)
    out = np.zeros(n, bool)
    if stated.windows is None or n < 2:
        return out
    nearest, alone = execution_kinds(np.asarray(targets.motion)[np.asarray(rows, int)])
    form = np.isfinite(stated.windows[:, :, 0]).any(axis=1) & (stated.status >= 0)
    linear = form & ~nearest & ~alone
    prev = np.arange(-1, n - 1) if order is None or order.sequential else np.asarray(order.prev)
    linear &= prev >= 0
    if not linear.any():
        return out
    status = status_turn_of(robot, q)[0]  # (NaN rows: UNSTATED, not judged)
    i = np.flatnonzero(linear)
    before = status[prev[i]]
    out[i] = (before >= 0) & (before != arm_status(stated.status[i]))
    return out


def measurement_joints(description, data, tools: np.ndarray | None = None) -> tuple[np.ndarray | None, np.ndarray,
                                                                                    list[str]]:
    """The joint angles [N, 6] deg of a measurement file's rows (``measurements.Measurements``):
    its q1..q6, or from its s,t columns the nominal IK on the stated branch (``stated_joints``)
    for each row's TCP (``tools`` [N, 6], the data's tool; None: the description's);
    None without either. Also a mask of the rows to keep and warnings: rows whose S/T has no
    solution on the nominal arm (out of reach on that branch) are left out, named by their
    lines (P514); none solvable, or an arm without the closed-form IK, is refused (P514)."""
    from ..core.diagnostics import PostprocError

    keep = np.ones(len(data), bool)
    if data.joints is not None or data.status_turn is None:
        return data.joints, keep, []
    path = data.path or "<data>"
    try:
        robot = Robot(description)
    except Exception as exc:  # an arm postproc.robot.arm cannot solve in closed form
        raise PostprocError(f"s,t columns: no nominal IK of {description.name} ({exc}); give q1..q6 instead",
                            path, code=P514) from None
    if tools is None:
        q, found = stated_joints(robot, data.poses, data.status_turn[:, 0], data.status_turn[:, 1])
    else:  # (each tool's rows solved for that TCP: the flange stands elsewhere for another tool)
        q, found = np.full((len(data), 6), np.nan), np.zeros(len(data), bool)
        kinds, which = np.unique(np.round(np.asarray(tools, float), 9), axis=0, return_inverse=True)
        for k, tool in enumerate(kinds):
            rows = np.flatnonzero(which.reshape(-1) == k)
            arm = robot if np.allclose(tool, description.tool) else Robot(description.replace(tool=np.array(tool, float)))
            q[rows], found[rows] = stated_joints(arm, data.poses[rows], data.status_turn[rows, 0],
                                                 data.status_turn[rows, 1])
    if not found.any():
        raise PostprocError(f"no row's S/T has an IK solution on the nominal {description.name}: is this the robot "
                            "of the data (--robot)?", path, int(data.lines[0]), 1, P514)
    if found.all():
        return q, found, []
    lines = data.lines[~found]
    return q, found, [f"{path}:{int(lines[0])}:1: P514 warning: {len(lines)} row(s) left out, their S/T has no IK "
                      f"solution on the nominal {description.name}: line(s) "
                      f"{', '.join(str(int(n)) for n in lines[:10])}{' ...' if len(lines) > 10 else ''}"]

"""The commands of a program in execution order: each target's predecessor (Order), what a program fed a part at a time carries (Chain), and the approach settling of models that learn backlash (_Settle, Inside)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..core import frames
from ..core.frames import nearest_triple, small_transform

if TYPE_CHECKING:
    from .compensator import Compensator

# a command further than this from c = P + Ê(c) under its own joint motion is not settled (mm):
# the plain iteration leaves ~1e-6 mm where the approach signs hold still
SETTLE_TOLERANCE_MM = 1e-3
# ... and, with the orientation, an attitude further than this (deg) from its own correction: a
# wrist joint's side turns the tool about a TCP on its axis by the lost motion (~0.02°) and
# moves it by nothing, so the position alone cannot tell the sides apart
SETTLE_TOLERANCE_DEG = 1e-4


# joints whose approach sign is hypothesised per unsettled target (2^k + 1 candidates)
SETTLE_JOINTS = 3


# passes over the targets after a changed command (a run of neighbours that all barely move)
SETTLE_PASSES = 32


# a joint step below this (deg) is no motion: the model's own dead band (training.kinematic's
# SIGN_DEADBAND, 2e-6 rad) in the float32 degrees of ``ik_joints``
STILL_DEG = 1.2e-4


# ... and a step below this (deg) is the same command: float32 joint angles of one pose differ
# by ~1e-5° between rows of a batch (SIMD tails); a joint between the two has moved too little
# for the model to tell which way (both sides are taken into account)
SAME_DEG = 3e-5


@dataclass
class Chain:
    """What a program's commands carry from one target to the next, for a program fed a part at
    a time (streaming compensate): the last row of the part before after each fixed-point
    iteration (``previous_pose``; None: the program's first target comes next), the approach
    settling's last command, joint angles and sides (``_Settle.head``), and the controller's
    joint angles at the last target (``controller.controller_inputs``: the configuration chain,
    LIN keeps / PTP nearest)."""

    before: list | None = None
    settled: tuple | None = None
    joints: np.ndarray | None = None
    branch: int | None = None  # (the controller's branch at the last target)
    origin: np.ndarray | None = None  # (the controller's start position, the program's first part's)


@dataclass
class Order:
    """Which row each row is reached from (its *predecessor* in execution order): ``prev`` [n]
    the row's index (-1: nothing known before it: its own pose, as a program's first target;
    -2: a pose given in ``fixed`` [n, 6], a target left as written before it). Rows come after
    their predecessors (``prev[i] < i``). None / ``sequential``: each row's is the row before."""

    prev: np.ndarray
    fixed: np.ndarray | None = None

    @property
    def sequential(self) -> bool:
        n = len(self.prev)
        return n == 0 or (self.prev[0] in (-1, -2) and (self.fixed is None or self.prev[0] == -1)
                          and bool((self.prev[1:] == np.arange(n - 1)).all()))

    def previous(self, values: np.ndarray) -> np.ndarray:
        """Each row's predecessor's row of ``values`` [n, k] (the row itself where none is known;
        the fixed pose's first k columns where one is given)."""
        prev = self.prev
        out = values[np.maximum(prev, 0)].copy()
        own = prev == -1
        out[own] = values[own]
        given = prev == -2
        if given.any():
            out[given] = self.fixed[given, :values.shape[1]] if self.fixed is not None else values[given]
        return out

    def take(self, values: np.ndarray, missing=np.nan) -> np.ndarray:
        """``values`` [n, k] of each row's predecessor, ``missing`` where it is not a row."""
        out = values[np.maximum(self.prev, 0)].copy()
        out[self.prev < 0] = missing
        return out

    def along(self, raw: np.ndarray, seed: np.ndarray | None = None) -> np.ndarray:
        """[n, k]: per column the last value ≠ 0 (NaN counts) along each row's chain of
        predecessors, itself first (``seed`` [k] before the first row of the chain; NaN)."""
        n, k = raw.shape
        out = np.full((n, k), np.nan)
        prev = self.prev
        starts = np.flatnonzero(np.r_[True, prev[1:] != np.arange(n - 1)])
        ends = np.r_[starts[1:], n]
        for a, b in zip(starts.tolist(), ends.tolist()):
            p = int(prev[a])
            head = out[p] if p >= 0 else (np.full(k, np.nan) if seed is None else seed)
            part = raw[a:b]
            idx = np.where(part != 0, np.arange(b - a)[:, None], -1)
            last = np.maximum.accumulate(idx, axis=0)
            out[a:b] = np.where(last >= 0, np.take_along_axis(part, np.maximum(last, 0), axis=0), head)
        return out


@dataclass
class Inside:
    """Targets whose command no approach hypothesis makes self-consistent: a joint barely
    moving there sits in its backlash dead band whatever is sent. ``rows`` [k] (program rows),
    ``joints`` [k, 6] bool (the joints in their dead band), ``worst_mm`` [k] (the smallest
    worst-case error over both sides of those joints, the command sent), ``error_mm`` [k] (the
    model's error with the side the command's own motion takes)."""

    rows: np.ndarray
    joints: np.ndarray
    worst_mm: np.ndarray
    error_mm: np.ndarray

    @staticmethod
    def join(parts: list["Inside | None"]) -> "Inside":
        parts = [p for p in parts if p is not None]
        if not parts:
            return Inside(np.zeros(0, int), np.zeros((0, 6), bool), np.zeros(0), np.zeros(0))
        return Inside(*(np.concatenate([getattr(p, f) for p in parts]) for f in ("rows", "joints", "worst_mm", "error_mm")))


class CommandChunk(tuple):
    """(first row, commands, joint angles or None), as ``command_chunks`` yields it; ``inside``:
    the chunk's :class:`Inside` targets (None for models that do not settle the approach);
    ``std``: the model's ``error_std`` [n] mm at the commands (None unless asked for)."""

    inside: Inside | None
    std: np.ndarray | None

    def __new__(cls, start: int, commands: np.ndarray, q: np.ndarray | None, inside: Inside | None = None,
                std: np.ndarray | None = None):
        self = super().__new__(cls, (start, commands, q))
        self.inside, self.std = inside, std
        return self


def _wrap_deg(a: np.ndarray) -> np.ndarray:
    return (a + 180.0) % 360.0 - 180.0


class _Settle:
    """The approach settling of ``command_chunks`` (module text), chunk after chunk in program
    order: keeps the last target's command, joint angles and approach signs for the next."""

    def __init__(self, model: "Compensator", iterations: int, orientation: bool, std: bool = False,
                 order: Order | None = None):
        self.model, self.iterations, self.orientation, self.std = model, iterations, orientation, std
        self.head: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None  # (command [6], q [6], signs [6])
        self.order = order  # (one chunk of rows in this execution order: ``Compensator._ordered``)

    # -- the joint motion of a chunk's commands: signs, and what the model must be told
    def _prev_q_signs(self, q: np.ndarray, signs: np.ndarray | None = None):
        """Joint angles [n, 6] and sides [n, 6] of each row's previous command (row 0: the chunk
        before's; the program's first target: itself, unknown side)."""
        if self.order is not None:
            o = self.order
            q_prev = o.take(q)
            own = o.prev == -1
            q_prev[own] = q[own]
            return q_prev, (None if signs is None else o.take(signs))
        if self.head is None:
            return np.vstack([q[:1], q[:-1]]), (None if signs is None else np.vstack([np.full((1, 6), np.nan), signs[:-1]]))
        return (np.vstack([self.head[1][None], q[:-1]]),
                None if signs is None else np.vstack([self.head[2][None], signs[:-1]]))

    def _motion(self, q: np.ndarray):
        """(step [n, 6] deg from the previous command, sides [n, 6] (the side each joint is on:
        its last motion's, NaN where unknown), keep [n, 6] (the ``approach`` of a joint that does
        not move: it keeps its side; NaN where it moves), unsure [n, 6] (a motion too small for
        the model's float32 joint angles to tell its direction))."""
        n = len(q)
        q_prev, _ = self._prev_q_signs(q)
        s_head = np.full(6, np.nan) if self.head is None else self.head[2]
        step = _wrap_deg(q - q_prev)
        raw = np.where(np.abs(step) <= SAME_DEG, 0.0, np.where(np.abs(step) > STILL_DEG, np.sign(step), np.nan))
        unsure = np.isnan(raw)
        if self.order is not None:
            first = self.order.prev < 0  # (from where nothing is known: the model's own rule)
            raw[first], unsure[first] = np.nan, False
            signs = self.order.along(raw)
            keep = np.where(raw == 0, signs, np.nan)
            return step, signs, keep, unsure
        if self.head is None:
            raw[0], unsure[0] = np.nan, False  # (from HOME: the model's own rule)
        idx = np.where(raw != 0, np.arange(n)[:, None], -1)
        last = np.maximum.accumulate(idx, axis=0)
        signs = np.where(last >= 0, np.take_along_axis(raw, np.maximum(last, 0), axis=0), s_head)
        keep = np.where(raw == 0, signs, np.nan)
        return step, signs, keep, unsure

    def _run(self, c: np.ndarray, prev: np.ndarray | None, approach: np.ndarray, given: dict, with_joints: bool,
             std: bool = False):
        """Ê [m, 3] (and q [m, 6]; the rotation error with ``orientation``; ``error_std`` [m] with
        ``std``) at commands ``c``; ``prev`` None: each row comes from itself (the program's first
        target)."""
        prev = c if prev is None else prev
        out = self.model.predict(c, prev, with_joints=with_joints, rotation=self.orientation,
                                 approach=approach, std=std, **given)
        return out if isinstance(out, tuple) else (out,)

    def _landing(self, c, prev, approach, given, q_prev, side_prev):
        """(Ê, q, rotation or None, unsure [m, 6]) at commands ``c`` with the sides their own
        motion takes (``approach`` where not NaN): a joint that does not move from ``q_prev``
        keeps ``side_prev``."""
        out = self._run(c, prev, approach, given, True)
        e, q, rot = out[0], out[1], (out[2] if self.orientation else None)
        step = _wrap_deg(q - q_prev)
        still = (np.abs(step) <= SAME_DEG) & np.isnan(approach) & ~np.isnan(side_prev)
        rows = np.flatnonzero(still.any(axis=1))
        if len(rows):
            again = self._run(c[rows], prev[rows], np.where(still[rows], side_prev[rows], approach[rows]),
                              _rows(given, rows), False)
            e[rows] = again[0]
            if self.orientation:
                rot[rows] = again[1]
        unsure = (np.abs(step) > SAME_DEG) & (np.abs(step) <= STILL_DEG)
        return e, q, rot, unsure

    def chunk(self, start: int, part: np.ndarray, trial: np.ndarray, q_target: np.ndarray,
              given: dict) -> tuple[Inside, np.ndarray | None]:
        """Settle ``trial`` (the chunk's commands [n, 6], changed in place) on the approach.
        Returns the chunk's Inside targets and, with ``std``, the ``error_std`` [n] at the settled
        commands (``Compensator.command_std``'s numbers: each pass's run at the commands, with
        the approach the graph computes, asks for it too; rows whose command or previous command
        changed after their last such run are run again)."""
        n = len(part)
        q = np.full((n, 6), np.nan)
        inside = np.zeros(n, bool)
        dead = np.zeros((n, 6), bool)
        worst = np.zeros(n)
        error = np.zeros(n)
        check = np.arange(n)
        keep = np.full((n, 6), np.nan)
        std = np.full(n, np.nan) if self.std else None
        std_at = np.full((n, 12), np.nan)  # the command and previous command each ``std`` row is of
        for _ in range(SETTLE_PASSES):
            if not len(check):
                break
            # each command's error with the sides its own joint motion gives
            prev_rows = self._previous(trial, check)
            if self.order is not None:
                first = self.order.prev[check] < 0
            else:
                first = check == 0 if self.head is None else np.zeros(len(check), bool)
            out = self._run(trial[check], prev_rows, np.full((len(check), 6), np.nan), _rows(given, check), True,
                            self.std)
            if self.std:
                std[check], std_at[check] = out[-1], np.c_[trial[check], prev_rows]
            q[check] = out[1]
            step, signs, keep, unsure = self._motion(q)
            e, rot = out[0], (out[2] if self.orientation else None)
            still = ~np.isnan(keep[check]).all(axis=1)
            if still.any():  # a joint that does not move keeps its side (the model alone: the middle)
                again = self._run(trial[check[still]], prev_rows[still], keep[check[still]],
                                  _rows(given, check[still]), False)
                e[still] = again[0]
                if self.orientation:
                    rot[still] = again[1]
            off = np.linalg.norm(part[check, :3] + e - trial[check, :3], axis=1) > SETTLE_TOLERANCE_MM
            if self.orientation:
                off |= np.abs(_wrap_deg(_corrected_attitude(part[check, 3:6], rot) - trial[check, 3:6])).max(axis=1) > 1e-6
            off |= unsure[check].any(axis=1)
            off &= ~first  # (the first target comes from HOME, far away: no doubt)
            inside[check] = False
            bad = check[off]
            if not len(bad):
                break
            old = trial[bad].copy()
            q_prev, side_prev = self._prev_q_signs(q, signs)
            none, joints, w, err = self._hypotheses(bad, part, trial, q, q_target, step, q_prev[bad], side_prev[bad],
                                                    prev_rows[off], given)
            inside[bad[none]], dead[bad[none]], worst[bad[none]], error[bad[none]] = True, joints[none], w[none], err[none]
            # the next pass: the targets after a changed command, and where a still joint's side changed
            changed = bad[np.abs(trial[bad] - old).max(axis=1) > 0]
            keep_after = self._motion(q)[2]
            again = np.zeros(n, bool)
            if self.order is not None:
                again[np.isin(self.order.prev, changed)] = True
            else:
                after = changed + 1
                again[after[after < n]] = True
            again |= ~((keep_after == keep) | (np.isnan(keep_after) & np.isnan(keep))).all(axis=1)
            check = np.flatnonzero(again)
        if self.std:
            every = np.arange(n)
            stale = np.flatnonzero((std_at != np.c_[trial, self._previous(trial, every)]).any(axis=1))
            if len(stale):
                prev_rows = self._previous(trial, stale)
                std[stale] = self._run(trial[stale], prev_rows, np.full((len(stale), 6), np.nan), _rows(given, stale),
                                       False, True)[-1]
        signs = self._motion(q)[1]
        self.head = (trial[-1].copy(), q[-1].copy(), signs[-1].copy())
        rows = np.flatnonzero(inside)
        return Inside(start + rows, dead[rows], worst[rows], error[rows]), std

    def _previous(self, trial: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """The command before each of ``rows`` [k, 6] (the chunk before's last; the program's
        first target's: itself)."""
        if self.order is not None:
            return self.order.previous(trial)[rows]
        before = rows - 1
        out = trial[np.maximum(before, 0)]
        if self.head is not None:
            out[before < 0] = self.head[0]
        return out

    def _hypotheses(self, bad, part, trial, q, q_target, step, q_prev, side_prev, prev_rows, given):
        """Solve targets ``bad`` again under each approach hypothesis of their SETTLE_JOINTS
        joints that move least (against what the correction turns them by); write the chosen
        commands and their joint angles into ``trial`` / ``q``. Returns per row: no hypothesis
        agrees [b], the joints in doubt [b, 6], the chosen command's worst case over both sides
        of them [b] mm and its error with the side its own motion takes [b] mm."""
        m = SETTLE_JOINTS
        turn = np.abs(_wrap_deg(q[bad] - q_target[bad])) + 1e-4
        slots = np.argsort(np.abs(step[bad]) / turn, axis=1, kind="stable")[:, :m]  # [b, m]
        combos = np.array(np.meshgrid(*[[-1.0, 1.0]] * m, indexing="ij")).reshape(m, -1).T  # [2^m, m]
        # + the middle of the lost motion, + every joint on the side it is on (no joint moves:
        # a target written twice), started from the previous command
        hyps = np.vstack([combos, np.zeros((1, m)), np.full((1, m), np.nan)])
        b, h, s = len(bad), len(hyps), len(combos)
        rep = np.repeat(np.arange(b), h)
        fixed = np.full((b * h, 6), np.nan)
        np.put_along_axis(fixed, slots[rep], np.tile(hyps, (b, 1)), axis=1)
        target, prev, sub = part[bad][rep], prev_rows[rep], _rows(given, bad[rep])
        qp, sp = q_prev[rep], side_prev[rep]
        cand, q_c = trial[bad][rep].copy(), q[bad][rep]
        stay = np.arange(b) * h + h - 1
        fixed[stay] = side_prev
        cand[stay], q_c[stay] = prev_rows, q_prev
        for _ in range(self.iterations + 1):  # the fixed point under each hypothesis
            # (a joint that barely moves is held on its side: a target written twice ends on its twin)
            still = np.isnan(fixed) & (np.abs(_wrap_deg(q_c - qp)) <= STILL_DEG) & ~np.isnan(sp)
            out = self._run(cand, prev, np.where(still, sp, fixed), sub, True)
            q_c = out[1]
            cand[:, :3] = target[:, :3] + out[0]
            if self.orientation:
                cand[:, 3:6] = _corrected_attitude(target[:, 3:6], out[2])
        # (no joint moves: exactly the previous command, the float32 model leaves ~1e-4 mm)
        twin = stay[np.abs(cand[stay] - prev[stay]).max(axis=1) <= SETTLE_TOLERANCE_MM]
        cand[twin] = prev[twin]
        # where each candidate lands with the sides its own motion takes
        real, q_cand, turn_real, unsure = self._landing(cand, prev, np.full((b * h, 6), np.nan), sub, qp, sp)
        error = np.linalg.norm(target[:, :3] - cand[:, :3] + real, axis=1).reshape(b, h)
        lands = np.ones((b, h), bool)
        if self.orientation:  # (the attitude lands too: a wrist's side can turn it alone)
            lands = (np.abs(_wrap_deg(_corrected_attitude(target[:, 3:6], turn_real) - cand[:, 3:6])).max(axis=1)
                     <= SETTLE_TOLERANCE_DEG).reshape(b, h)
        moved = _wrap_deg(q_cand - qp)
        side = np.where(np.abs(moved) <= SAME_DEG, np.nan_to_num(sp), np.sign(moved))
        side = np.take_along_axis(side, slots[rep], axis=1).reshape(b, h, m)
        unsure_slot = np.take_along_axis(unsure, slots[rep], axis=1).reshape(b, h, m)
        # a joint is in doubt where the candidates take it to either side or too little to tell
        doubt = (side.max(axis=1) != side.min(axis=1)) | unsure_slot.any(axis=1)  # [b, m]
        agrees = (error <= SETTLE_TOLERANCE_MM) & lands & ~unsure.any(axis=1).reshape(b, h)
        settled = agrees.any(axis=1)
        # where one agrees: the one nearest the plain fixed point's command
        near = np.linalg.norm(cand[:, :3] - trial[bad][rep][:, :3], axis=1).reshape(b, h)
        pick = np.argmin(np.where(agrees, near, np.inf), axis=1)
        worst = np.where(agrees, error, np.inf)
        # where none does: each candidate's worst case over both sides of the joints in doubt
        lost = np.flatnonzero(~settled)
        if len(lost):
            at = (lost[:, None] * h + np.arange(h)).ravel()  # their candidates
            rep2 = np.repeat(at, s)
            sides = np.where(doubt[lost][:, None, None, :], combos[None, None], side[lost][:, :, None, :]).reshape(-1, m)
            approach = np.full((len(rep2), 6), np.nan)
            np.put_along_axis(approach, slots[rep][rep2], sides, axis=1)
            out = self._landing(cand[rep2], prev[rep2], approach, _rows(sub, rep2), qp[rep2], sp[rep2])
            w = np.linalg.norm(target[rep2, :3] - cand[rep2, :3] + out[0], axis=1).reshape(len(lost), h, s).max(axis=2)
            worst[lost] = np.maximum(w, error[lost])
            pick[lost] = np.argmin(worst[lost], axis=1)
        chosen = np.arange(b) * h + pick
        trial[bad] = cand[chosen]
        q[bad] = q_cand[chosen]
        joints = np.zeros((b, 6), bool)
        np.put_along_axis(joints, slots, doubt, axis=1)
        return ~agrees.any(axis=1), joints, worst[np.arange(b), pick], error[np.arange(b), pick]


def _rows(given: dict, rows: np.ndarray) -> dict:
    return {k: None if v is None else v[rows] for k, v in given.items()}


def _corrected_attitude(abc: np.ndarray, rotation_error_deg: np.ndarray) -> np.ndarray:
    """A,B,C [N, 3] of exp(−r)·R(abc) (r: rotation vectors [N, 3] deg, nominal → actual in the
    base frame), on the triple and turns nearest ``abc``: the robot turned by r lands on abc."""
    undo = small_transform(np.radians(-np.asarray(rotation_error_deg, float)), np.zeros(3))[:, :3, :3]  # exp(−r)
    return nearest_triple(frames.abc_from_rotation(undo @ frames.rotation_from_abc(abc)), abc)

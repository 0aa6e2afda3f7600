"""The controllers' conventions: how each controller family states an arm configuration, which
motions there are, and which controller a program or a robot description is written for.

KUKA's Status and Turn (``../shared/KRL-NOTES.md``; KSS manual, "Status and Turn"):

* S bit 0: the wrist point behind the A1 axis (overhead area), bit 1: A3 at or beyond the
  stretched-arm angle (elbow), bit 2: A5 ≤ 0 (wrist flip); the higher bits say nothing of the
  arm's configuration (real points state ``S 18``, ``'B00010110'``: bit 4 set), so only bits 0–2
  pick a branch (:func:`arm_status`, the one place a Status becomes a branch index);
* T bit i set ⇔ A(i+1) < 0 (which turn of each joint); bits 6 and up (external axes) are not
  the arm's.

For a UR-type arm (``models/ur10.toml``, no S/T on its controller) postproc uses the same bits
for the same geometric facts (:meth:`postproc.robot.arm.Robot.status_turn`): bit 0 = A6's origin
behind the shoulder-pan axis (UR "shoulder left/right"), bit 1 = the elbow branch (elbow
joint ≥ 0), bit 2 = wrist-2 ≤ 0 (wrist up/down, taken in (−180°, 180°]); T as KUKA's.

The other controllers' forms (docs/CONFIGURATIONS.md, with the sources), for a description
that says its controller states them (``[robot] configuration``, :data:`FORM_NAMES`):

* ABB RAPID ``confdata [cf1, cf4, cf6, cfx]`` (``"abb"``): cfx 0…7 = 4·(wrist centre behind
  axis 1) + 2·(wrist centre behind the lower arm, i.e. the elbow down) + (axis 5 negative);
  cf1, cf4, cf6 the quadrant of axes 1, 4, 6 (⌊q/90°⌋), a *window* [90·cf, 90·cf + 90°] each
  joint's turn is taken in (:func:`abb_confdata`, :func:`_abb_branch`);
* FANUC ``CONFIG : 'F U T, t1, t4, t6'`` (``"fanuc"``): N/F no flip / flip (F: J5 > 0 in
  FANUC's joint angles, the wrist bent the other way than in the tool-down pose J4 = 0,
  J5 = −90°), U/D the elbow up / down, T/B the wrist centre in front of / behind the J1 axis;
  t1, t4, t6 the turn numbers of J1, J4, J6 (0: −180° < q < 180°, 1: 180° ≤ q < 540°, −1:
  −540° < q ≤ −180°), windows as cf's (:func:`parse_fanuc_config`, :func:`fanuc_configs`,
  :func:`fanuc_turn`).

Motion kinds (:data:`MOTIONS`, stored per target as an index) and how the controller executes
them without a stated configuration (:func:`execution_kinds`); controller families
(:data:`DIALECT_CONTROLLERS`, :func:`controller_of`). What a program states, mapped on a
description's branch table, and the controller's rules for what it does not state:
:mod:`postproc.robot.configuration`. Light on purpose: the readers import :data:`MOTIONS`
(numpy only; the arm is imported where a function needs it).
"""
from __future__ import annotations

import re
from typing import TYPE_CHECKING

import numpy as np

from ..core.diagnostics import PostprocError

if TYPE_CHECKING:
    from .arm import Robot

__all__ = ["DIALECT_CONTROLLERS", "MOTIONS", "controller_of", "UNSTATED", "ARM_BITS", "arm_status", "status_turn_of",
           "FORM_NAMES", "TURN_JOINTS", "fanuc_turn", "parse_fanuc_config", "fanuc_configs", "abb_confdata",
           "execution_kinds"]


# --------------------------------------------------------------------------- controller families

# the controller a program's dialect is written for (a pose list: any robot's), and the one a
# description's [robot] configuration names (a UR-type arm: Universal Robots')
DIALECT_CONTROLLERS = {"krl": "KUKA", "rapid": "ABB", "urscript": "Universal Robots", "fanuc": "FANUC"}


_FORM_CONTROLLERS = {"kuka": "KUKA", "abb": "ABB", "fanuc": "FANUC"}


_DIALECT_NAMES = {"krl": "KRL", "rapid": "RAPID", "urscript": "URScript", "fanuc": "an LS program"}


def controller_of(description) -> str | None:
    """The controller family a robot description names (``[robot] configuration``, or a UR-type
    arm: Universal Robots'); None where it does not say."""
    if description is None:
        return None
    own = _FORM_CONTROLLERS.get(description.configuration)
    if own is None:
        from .arm import Robot

        try:
            own = "Universal Robots" if Robot(description).family == "ur" else None
        except PostprocError:  # (an arm postproc has no closed-form IK for: unknown)
            own = None
    return own


# --------------------------------------------------------------------------- motion kinds

# Motion kinds, stored per target as an index into this tuple.
MOTIONS = ("LIN", "PTP", "CIRC-aux", "CIRC-end", "SLIN", "SPTP", "SCIRC-aux", "SCIRC-end", "SPL", "row")
# Motions that take the solution nearest the current axis position when no S is stated; the
# others (LIN, CIRC, SLIN, SCIRC, SPL) keep the configuration.
_NEAREST = ("PTP", "SPTP")
# A pose list's rows are poses reached one by one as `measure` reaches a plan's: without s,t,
# each on the branch nearest HOME (the simulator's and today's models' choice).
_INDEPENDENT = ("row",)


# Motions on which KUKA's controller does not read Status and Turn: a CP motion (LIN, CIRC and
# their spline forms, SPL) keeps the configuration the robot is in (KSS manual, "Status and
# Turn": "only taken into account for PTP motions"), whatever its aggregate writes.
KUKA_KEEPS = ("LIN", "CIRC-aux", "CIRC-end", "SLIN", "SCIRC-aux", "SCIRC-end", "SPL")


def ignored_status_turn(program, rows: np.ndarray) -> np.ndarray:
    """[n] bool: the rows of ``rows`` whose S or T the controller does not read — in a KRL
    program, the targets of CP motions (``KUKA_KEEPS``) that write them. The arm runs them in
    the configuration it is in; what they write is kept in the text, never used."""
    rows = np.asarray(rows, int)
    config = getattr(program.targets, "config", None)
    if program.dialect != "krl" or config is None or not len(rows):
        return np.zeros(len(rows), bool)
    keeps = np.zeros(len(MOTIONS), bool)
    keeps[[MOTIONS.index(m) for m in KUKA_KEEPS]] = True
    motion = np.asarray(program.targets.motion)[rows].astype(np.intp)
    known = (motion >= 0) & (motion < len(MOTIONS))
    return known & keeps[np.where(known, motion, 0)] & (np.asarray(config)[rows] >= 0).any(axis=1)


def execution_kinds(motion: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(PTP-like, independent) masks [N] of motion kinds (indices into :data:`MOTIONS`)."""
    motion = np.asarray(motion, np.intp)
    kinds = np.zeros((2, len(MOTIONS)), bool)  # (a lookup, not np.isin: its sort of 10^6 rows)
    kinds[0, [MOTIONS.index(m) for m in _NEAREST]] = True
    kinds[1, [MOTIONS.index(m) for m in _INDEPENDENT]] = True
    known = (motion >= 0) & (motion < len(MOTIONS))
    at = np.where(known, motion, 0)
    return kinds[0][at] & known, kinds[1][at] & known


# --------------------------------------------------------------------------- KUKA Status and Turn

UNSTATED = -1  # S or T not written for a target
ARM_BITS = 0b111  # S bits 0-2: shoulder, elbow, wrist (the branch); the others are not the arm's


def arm_status(status) -> np.ndarray:
    """S as written [N] → the arm branch it states [N] (bits 0–2; UNSTATED stays): never index
    the branch table with an S unmasked (``S 18`` is branch 2 with bit 4 set)."""
    status = np.asarray(status, int)
    return np.where(status >= 0, status & ARM_BITS, UNSTATED)


def status_turn_of(robot: Robot, q_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(S, T) [N] of joint angles [N, 6] (NaN rows: UNSTATED)."""
    q = np.atleast_2d(np.asarray(q_deg, float))
    bad = ~np.isfinite(q).all(axis=1)
    s, t = robot.status_turn(np.nan_to_num(q))
    return np.where(bad, UNSTATED, s), np.where(bad, UNSTATED, t)


# --------------------------------------------------------------------------- ABB confdata, FANUC CONFIG

# the forms a description's [robot] configuration names, as messages name them
FORM_NAMES = {"kuka": "KUKA S/T", "abb": "ABB confdata", "fanuc": "FANUC CONFIG"}
# the joints whose quadrant (ABB cf1, cf4, cf6) or turn number (FANUC t1, t4, t6) a form states
TURN_JOINTS = (0, 3, 5)
# 'F U T, 0, 0, 0': flip, elbow, front/back, the turn numbers of J1, J4, J6 (optional)
_FANUC_CONFIG = re.compile(r"\s*([NF])\s*([UD])\s*([TB])\s*(?:,\s*([-+]?\d+)\s*,\s*([-+]?\d+)\s*,\s*([-+]?\d+)\s*)?$",
                           re.IGNORECASE)


def fanuc_turn(q_deg: np.ndarray) -> np.ndarray:
    """FANUC's turn number of joint angles (deg): 0 for −180° < q < 180°, k for the k-th turn
    beyond (180° ≤ q < 540°: 1; −540° < q ≤ −180°: −1), as RoboDK's FANUC post writes it."""
    q = np.asarray(q_deg, float)
    return np.where(q >= 0, np.floor((q + 180.0) / 360.0), -np.floor((180.0 - q) / 360.0)).astype(int)


def parse_fanuc_config(text: str) -> tuple[int, np.ndarray] | None:
    """A FANUC CONFIG string 'F U T, t1, t4, t6' → (the branch it states, S numbering; the turn
    numbers of J1, J4, J6 [3], −999 where not written), None if it is not of that form. S bit 0 =
    B (the wrist centre behind the J1 axis), bit 1 = U (elbow up: A3 beyond the stretched arm),
    bit 2 = N (J5 ≤ 0 in FANUC's joint angles: the tool-down wrist of J4 = 0 is J5 = −90°)."""
    m = _FANUC_CONFIG.match(text)
    if m is None:
        return None
    flip, elbow, side = (g.upper() for g in m.groups()[:3])
    status = (side == "B") | (elbow == "U") << 1 | (flip == "N") << 2
    turns = np.array([int(g) if g is not None else -999 for g in m.groups()[3:]])
    return int(status), turns


def fanuc_configs(robot: Robot, q_deg: np.ndarray) -> list[str]:
    """The FANUC CONFIG strings ('N U T, 0, 0, 0') of joint angles [N, 6] deg (NaN rows: '')."""
    q = np.atleast_2d(np.asarray(q_deg, float))
    status, _ = status_turn_of(robot, q)
    turns = fanuc_turn(np.nan_to_num(q[:, list(TURN_JOINTS)]))
    return ["" if st < 0 else f"{'N' if st & 4 else 'F'} {'U' if st & 2 else 'D'} {'B' if st & 1 else 'T'}, "
            f"{t[0]}, {t[1]}, {t[2]}" for st, t in zip(status.tolist(), turns.tolist())]


def abb_confdata(robot: Robot, q_deg: np.ndarray) -> np.ndarray:
    """ABB confdata [N, 4] (cf1, cf4, cf6, cfx) of joint angles [N, 6] deg: the quadrants
    ⌊q/90°⌋ of axes 1, 4, 6 and cfx = 4·(wrist centre behind axis 1) + 2·(behind the lower arm)
    + (axis 5 negative)."""
    q = np.atleast_2d(np.asarray(q_deg, float))
    status, _ = status_turn_of(robot, q)
    quadrants = np.floor(q[:, list(TURN_JOINTS)] / 90.0)
    cfx = 4 * (status & 1) + 2 * (1 - ((status >> 1) & 1)) + ((status >> 2) & 1)
    return np.c_[quadrants, cfx].astype(int)


def _abb_branch(conf: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """confdata [n, 4] → (the branch, S numbering [n], windows [n, 6, 2], rows well formed [n])."""
    conf = np.asarray(conf, float)
    whole = np.isfinite(conf).all(axis=1) & (conf == np.round(conf)).all(axis=1)
    cfx = np.where(whole, conf[:, 3], -1).astype(int)
    good = whole & (cfx >= 0) & (cfx <= 7)
    status = np.where(good, ((cfx >> 2) & 1) | ((1 - ((cfx >> 1) & 1)) << 1) | ((cfx & 1) << 2), UNSTATED)
    windows = np.full((len(conf), 6, 2), np.nan)
    for k, j in enumerate(TURN_JOINTS):
        windows[good, j, 0] = 90.0 * conf[good, k]
        windows[good, j, 1] = 90.0 * conf[good, k] + 90.0
    return status, windows, good

"""The controllers' conventions: how each states an arm configuration — KUKA's Status and Turn
(S bits 0–2 the branch: :func:`arm_status`), ABB's confdata, FANUC's CONFIG strings — read into
:class:`Stated` (:func:`stated_configuration`) and written from joint angles
(:func:`status_turn_of`, :func:`abb_confdata`, :func:`fanuc_configs`); the motion kinds
(``MOTIONS``: which keep the configuration, :func:`execution_kinds`); the controller families and
the dialects written for them. The rules that turn a stated configuration into joint angles are
``configuration.py``'s."""
from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from ..core.diagnostics import PostprocError
from .arm import Robot

__all__ = [
    "DIALECT_CONTROLLERS", "MOTIONS", "UNSTATED", "arm_status", "status_turn_of", "Stated", "stated_configuration",
    "parse_fanuc_config", "fanuc_configs", "fanuc_turn", "abb_confdata", "FORM_NAMES",
]


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
        try:
            own = "Universal Robots" if Robot(description).family == "ur" else None
        except PostprocError:  # (an arm postproc has no closed-form IK for: unknown)
            own = None
    return own


# Motion kinds, stored per target as an index into this tuple.
MOTIONS = ("LIN", "PTP", "CIRC-aux", "CIRC-end", "SLIN", "SPTP", "SCIRC-aux", "SCIRC-end", "SPL", "row")


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


# the forms a description's [robot] configuration names, as messages name them
FORM_NAMES = {"kuka": "KUKA S/T", "abb": "ABB confdata", "fanuc": "FANUC CONFIG"}


# the joints whose quadrant (ABB cf1, cf4, cf6) or turn number (FANUC t1, t4, t6) a form states
TURN_JOINTS = (0, 3, 5)


# 'F U T, 0, 0, 0': flip, elbow, front/back, the turn numbers of J1, J4, J6 (optional)
_FANUC_CONFIG = re.compile(r"\s*([NF])\s*([UD])\s*([TB])\s*(?:,\s*([-+]?\d+)\s*,\s*([-+]?\d+)\s*,\s*([-+]?\d+)\s*)?$",
                           re.IGNORECASE)


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


def stated_configuration(program, description, rows: np.ndarray) -> tuple[Stated, np.ndarray, list[str]]:
    """What targets ``rows`` of a program state of their arm configuration, mapped on the branch
    table of ``description`` (a RobotDescription): (:class:`Stated`, a mask [n] of the rows whose
    stated form the description cannot say or that is malformed — left as written, P309 —, and
    the reason of each of those, in order). KUKA's S/T (``Targets.config``) is read on any arm;
    ABB's confdata (``RapidProgram.confdata``) only for a description whose ``configuration`` is
    "abb", FANUC's CONFIG (``FanucProgram.configs``) only for "fanuc": never a guess."""
    rows = np.asarray(rows, int)
    n = len(rows)
    config = getattr(program.targets, "config", None)
    if config is None:
        stated = Stated.unstated(n)
    else:
        stated = Stated(np.asarray(config[rows, 0], int), np.asarray(config[rows, 1], int))
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


# Motions that take the solution nearest the current axis position when no S is stated; the
# others (LIN, CIRC, SLIN, SCIRC, SPL) keep the configuration.
_NEAREST = ("PTP", "SPTP")


# A pose list's rows are poses reached one by one as `measure` reaches a plan's: without s,t,
# each on the branch nearest HOME (the simulator's and today's models' choice).
_INDEPENDENT = ("row",)


def execution_kinds(motion: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(PTP-like, independent) masks [N] of motion kinds (indices into MOTIONS)."""
    motion = np.asarray(motion, np.intp)
    kinds = np.zeros((2, len(MOTIONS)), bool)  # (a lookup, not np.isin: its sort of 10^6 rows)
    kinds[0, [MOTIONS.index(m) for m in _NEAREST]] = True
    kinds[1, [MOTIONS.index(m) for m in _INDEPENDENT]] = True
    known = (motion >= 0) & (motion < len(MOTIONS))
    at = np.where(known, motion, 0)
    return kinds[0][at] & known, kinds[1][at] & known

"""The training envelope of a model: its box, attitude range and joint arcs, and the one rule of where they end (P301)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Joint ranges of the envelope are widened by this share of each range (+ 0.5°) before warning.
JOINT_MARGIN = 0.05


@dataclass
class Envelope:
    """The training envelope: a box of positions and a range of attitudes around a centre."""

    box: np.ndarray  # [6] x0,x1,y0,y1,z0,z1
    attitude: np.ndarray  # [3] A,B,C
    range: float  # ± deg per component
    joints: np.ndarray | None = None  # [6, 2] deg: each joint's range over the training poses

    def outside(self, poses: np.ndarray, tolerance_mm: float = 1.0, tolerance_deg: float = 0.5) -> np.ndarray:
        """Boolean mask of poses [N, 6] outside the box or the attitude range."""
        lo, hi = self.box[0::2] - tolerance_mm, self.box[1::2] + tolerance_mm
        xyz = poses[:, :3]
        out = np.any((xyz < lo) | (xyz > hi), axis=1)
        # per component; angles wrap at ±180. A rotation has two A,B,C triples, (A, B, C) and
        # (A+180, 180−B, C+180), and compensate passes the one with |B| ≤ 90: an envelope
        # around B = 90 (tool pointing down) holds half its poses in the other triple.
        abc = poses[:, 3:6]
        alt = abc + np.array([180.0, 0.0, 180.0])
        alt[:, 1] = 180.0 - abc[:, 1]
        limit = self.range + tolerance_deg
        d, d_alt = ((t - self.attitude + 180.0) % 360.0 - 180.0 for t in (abc, alt))
        return out | (np.any(np.abs(d) > limit, axis=1) & np.any(np.abs(d_alt) > limit, axis=1))

    def outside_joints(self, q_deg: np.ndarray) -> np.ndarray:
        """Boolean mask of joint angles [N, 6] (deg, any turn) outside the trained arcs widened
        by :func:`widened_arcs` (the training poses sample the box, not its joint-space hull: a
        pose inside the box may turn a joint a little past what any training pose did)."""
        if self.joints is None:
            return np.zeros(len(q_deg), bool)
        arcs = widened_arcs(self.joints)
        with np.errstate(invalid="ignore"):
            return np.any(np.mod(np.asarray(q_deg, float) - arcs[:, 0], 360.0) > arcs[:, 1] - arcs[:, 0], axis=1)


def joint_arcs(q_deg: np.ndarray) -> np.ndarray:
    """[J, 2] deg: each joint's smallest arc holding all its angles q_deg [N, J] (any turn): from
    lo in [−180, 180) counterclockwise to hi = lo + width (past 180 where the arc crosses ±180:
    a range of −170…170 is two arcs' worth apart from one of 170…190). The complement of the
    largest gap between the sorted angles on the circle."""
    w = np.sort(np.mod(np.asarray(q_deg, float).reshape(len(q_deg), -1) + 180.0, 360.0) - 180.0, axis=0)
    gaps = np.vstack([np.diff(w, axis=0), w[:1] + 360.0 - w[-1:]])  # gap after each sorted angle
    k = np.argmax(gaps, axis=0)
    cols = np.arange(w.shape[1])
    lo = w[(k + 1) % len(w), cols]
    return np.c_[lo, lo + 360.0 - gaps[k, cols]]


def widened_arcs(arcs: np.ndarray) -> np.ndarray:
    """[J, 2] deg: the trained arcs [J, 2] widened on each side by JOINT_MARGIN of their width +
    0.5°: where compensate warns P301 and the models' learned parts stop holding (one rule)."""
    lo, hi = np.asarray(arcs, float).T
    margin = JOINT_MARGIN * (hi - lo) + 0.5
    return np.c_[lo - margin, np.minimum(hi + margin, lo - margin + 360.0)]

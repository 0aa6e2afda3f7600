"""Denavit–Hartenberg rows of a chain (standard DH: θ offset, d, a, α per joint), and the DH
chain's forward kinematics — as :class:`~postproc.robot.kinematics.chain.Chain` evaluates it:
DH rows are one more way to write a chain's placements (:func:`dh_chain`), not another FK.

A UR controller's ``calibration.conf`` holds its arm as DH deltas
(:func:`postproc.calibration.export.ur_calibration`): the identified chain's axis lines at
q = 0 (:func:`axis_lines`) give its rows (:func:`dh_parameters`), their FK (:func:`dh_transforms`)
checks them against the chain."""
from __future__ import annotations

import math

import numpy as np

from .chain import Chain

__all__ = ["axis_lines", "dh_parameters", "dh_chain", "dh_transforms"]


def axis_lines(chain: Chain) -> tuple[list, np.ndarray]:
    """The joint axis lines (point, direction) [(3, 3)] × J of ``chain`` at q = 0 and its end
    frame [4, 4], in the frame of the chain's ``base``."""
    joints, end = chain.zero_frames()
    return [(m[:3, 3].copy(), m[:3, :3] @ axis) for m, axis in zip(joints, chain.axes)], end


def dh_parameters(lines: list, end: np.ndarray, parallel: float = 1e-12) -> np.ndarray:
    """[6, 4] standard DH rows (θ offset rad, d mm, a mm, α rad) of a chain whose joint axes at
    q = 0 are ``lines`` [(point, direction)] × 6 and whose end frame (DH frame 6, its z along the
    last axis) is ``end`` [4, 4], all in the DH base frame (z_0 = the first axis). Each row i
    goes from frame i−1 to frame i on the common normal of axes i and i+1 (x_i along it, turned
    the way x_{i−1} points); parallel axes (|z_{i−1} × z_i| ≤ ``parallel``) take d = 0, the last
    row ends at ``end``'s origin with its x."""
    o, x, z = np.zeros(3), np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])
    targets = [(p, w / np.linalg.norm(w)) for p, w in lines[1:]] + [(end[:3, 3], end[:3, 2])]
    rows = []
    for i, (p, w) in enumerate(targets):
        last = i == len(targets) - 1
        n = np.cross(z, w)
        if np.linalg.norm(n) > parallel:
            r = p - o
            b = z @ w
            s_, t_ = (z @ r - b * (w @ r)) / (1 - b * b), (b * (z @ r) - w @ r) / (1 - b * b)
            foot, new_o = o + s_ * z, p + t_ * w
            new_x = n / np.linalg.norm(n)
            d = s_
        else:
            if last:  # the end frame's origin on its line: d along the axis, a across
                d = (p - o) @ z
                foot, new_o = o + d * z, p
            else:
                d, foot = 0.0, o
                new_o = p + ((o - p) @ w) * w
            v = new_o - foot
            if last:  # DH frame 6 is the end frame: its x (what is left across is no DH row's)
                new_x = end[:3, 0] - (end[:3, 0] @ w) * w
                new_x = new_x / np.linalg.norm(new_x)
            elif np.linalg.norm(v) > 1e-9:
                new_x = v / np.linalg.norm(v)
            else:
                new_x = x
        if new_x @ x < 0:
            new_x = -new_x
        a = (new_o - foot) @ new_x
        alpha = math.atan2(np.cross(z, w) @ new_x, z @ w)
        theta = math.atan2(np.cross(x, new_x) @ z, x @ new_x)
        rows.append((theta, d, a, alpha))
        o, x, z = new_o, new_x, w
    return np.array(rows)


def _screw(theta: float, d: float, a: float, alpha: float) -> np.ndarray:
    """Rz(θ)·Tz(d)·Tx(a)·Rx(α) [4, 4]: one DH row at q = 0."""
    ct, st, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
    return np.array([[ct, -st * ca, st * sa, a * ct],
                     [st, ct * ca, -ct * sa, a * st],
                     [0.0, sa, ca, d],
                     [0.0, 0.0, 0.0, 1.0]])


def dh_chain(dh: np.ndarray) -> Chain:
    """The :class:`Chain` of DH rows [J, 4]: joint j turns about its frame's z; its placement is
    the row before's Tz(d)·Tx(a)·Rx(α) then Rz(θ_j) (Rz(θ + q) = Rz(θ)·Rz(q)); the end is the
    last row's Tz(d)·Tx(a)·Rx(α)."""
    dh = np.asarray(dh, float)
    rest = [_screw(0.0, d, a, alpha) for _, d, a, alpha in dh]  # Tz(d)·Tx(a)·Rx(α)
    turns = [_screw(theta, 0.0, 0.0, 0.0) for theta, *_ in dh]  # Rz(θ)
    placements = np.stack([turns[0]] + [rest[j - 1] @ turns[j] for j in range(1, len(dh))])
    return Chain(placements, np.tile([0.0, 0.0, 1.0], (len(dh), 1)), rest[-1])


def dh_transforms(dh: np.ndarray, q_rad: np.ndarray) -> np.ndarray:
    """[N, 4, 4] the DH chain's end (mm) at joint angles [N, 6] rad (:func:`dh_chain`)."""
    return dh_chain(dh).transforms(np.atleast_2d(q_rad))

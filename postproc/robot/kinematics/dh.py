"""Standard Denavit-Hartenberg rows of a chain (the UR controller's calibration layout), and a DH chain as a Chain."""
from __future__ import annotations

import math

import numpy as np

from ...core import frames
from .chain import Chain

__all__ = ["dh_parameters", "dh_chain"]


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


def dh_chain(dh: np.ndarray) -> Chain:
    """The chain of standard DH rows ``dh`` [J, 4] (θ offset rad, d mm, a mm, α rad) as a
    :class:`Chain` (the one forward kinematics): Π Rz(θ_i + q_i)·Tz(d_i)·Tx(a_i)·Rx(α_i) =
    Π Rz(q_i)·M_i, so each joint turns about z after the row before it, M_{i−1}, and the last
    row is the end frame."""
    rows = []
    for theta, d, a, alpha in np.asarray(dh, float):
        m = frames.frame_to_matrix(np.array([0.0, 0.0, 0.0, math.degrees(theta), 0.0, 0.0]))
        shift = np.eye(4)
        shift[:3, 3] = (a, 0.0, d)
        shift[:3, :3] = frames.rotation_from_abc(np.array([0.0, 0.0, math.degrees(alpha)]))
        rows.append(m @ shift)  # Rz(θ)·[Tz(d)·Tx(a)·Rx(α)]: the translation d along z, a along x (Rx leaves x)
    placements = np.stack([np.eye(4), *rows[:-1]])
    return Chain(placements, np.tile([0.0, 0.0, 1.0], (len(rows), 1)), rows[-1])

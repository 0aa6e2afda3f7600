"""Gravity torques of a description's links and payload (numpy).

A load (payload) is (mass kg, centre of mass cx, cy, cz mm in the flange frame): the
description's ``[payload]``, or per row ``loads`` [N, 4] (what the robot carries at each
target: ``load_torques``, the one formula the simulator and the identification's graph share)."""
from __future__ import annotations

import numpy as np

from ...core.frames import MM
from ..description import RobotDescription
from .chain import Chain, _times

__all__ = ['GRAVITY', 'gravity_torques', 'gravity_from_points', 'holding_torques', 'load_torques', 'LOAD_WIDTH']

LOAD_WIDTH = 4  # a load row: mass kg, centre of mass cx, cy, cz mm (flange frame)


GRAVITY = 9.81  # m/s², along −Z of the robot base frame (Pinocchio's default)


GRAVITY_ROWS = 16_384  # poses per block of the vectorised gravity torques


def holding_torques(omega, lever):
    """τ [...] (Nm) that holds weights against gravity: τ = −ω · (l × m·g), g = (0, 0, −g), for
    joint axes ``omega`` [..., 3] in the base frame and ``lever`` [..., ≥2] (kg·m) the
    mass-weighted lever Σ m_i (c_i − p_j) the joint carries (only its x, y count). Like
    :func:`gravity_from_points` it takes numpy arrays or torch tensors alike (operators and
    indexing only): one formula for the simulator and the identification's ONNX graph."""
    return GRAVITY * (omega[..., 0] * lever[..., 1] - omega[..., 1] * lever[..., 0])


def gravity_from_points(origins, centres, omega, masses, payload_mass: float = 0.0, payload=None) -> list:
    """Joint torques (J arrays [N], Nm) that hold the arm against gravity
    (``pin.computeGeneralizedGravity``) from per-joint lists of its joint origins, links'
    centres of mass (arrays [N, 3] mm) and joint axes ``omega`` [N, 3], all in the base frame,
    and link masses [J] (kg); the payload (kg, centre ``payload`` [N, 3] mm) rides on the last
    link. τ_j = −ω_j · Σ_{i≥j} (c_i − p_j) × m_i·g, summed from the tip."""
    moment, mass, torques = 0.0, payload_mass, []  # Σ_{i≥j} m_i·c_i (x, y) and Σ_{i≥j} m_i
    if payload_mass > 0:
        moment = payload_mass * payload[:, :2]
    for j in reversed(range(len(masses))):
        moment = moment + masses[j] * centres[j][:, :2]
        mass = mass + masses[j]
        torques.append(holding_torques(omega[j], (moment - mass * origins[j][:, :2]) * MM))
    return torques[::-1]


def load_torques(origins, omega, mass, centre) -> list:
    """Joint torques (J arrays [N], Nm) that hold one load against gravity: ``mass`` [N] kg at
    ``centre`` [N, 3] mm (base frame) on the last link, joint origins and axes [N, 3] per joint
    (base frame). numpy arrays or torch tensors alike (:func:`holding_torques`)."""
    return [holding_torques(w, (centre[..., :2] - p[..., :2]) * (mass[..., None] * MM)) for p, w in zip(origins, omega)]


def gravity_torques(description: RobotDescription, q_deg: np.ndarray, payload: bool = True,
                    chain: Chain | None = None, loads: np.ndarray | None = None) -> np.ndarray:
    """Joint torques [N, J] (Nm) that hold a description's arm (with its payload, or without)
    against gravity at joint angles [N, J] (deg): :func:`gravity_from_points` of the joint
    frames of its ``chain`` (default ``Chain.of(description, tool=False)``), all poses at once, a block of
    rows at a time (tests/test_kinematics.py checks it against ``pin.computeGeneralizedGravity``).
    ``loads`` [N, 4] (or [4]): each row's load (mass kg, centre of mass mm in the flange frame)
    in place of the description's payload (``payload`` is then not read)."""
    d = description
    chain = Chain.of(d, tool=False) if chain is None else chain
    q = np.radians(np.atleast_2d(np.asarray(q_deg, float)))
    coms, axes, masses, payload_com = d.coms, d.axes, d.masses, d.payload_com_in_last
    out = np.empty_like(q)
    if loads is not None:
        loads = np.broadcast_to(np.asarray(loads, float), (len(q), LOAD_WIDTH))
        if not np.isfinite(loads).all() or (loads[:, 0] < 0).any():
            raise ValueError("a load must be finite numbers with a mass >= 0 kg")
        flange = d.flange_matrix
        in_last = loads[:, 1:] @ flange[:3, :3].T + flange[:3, 3]  # [N, 3] the loads' centres in the last joint's frame
    for start in range(0, len(q), GRAVITY_ROWS):  # blocks that stay in the cache
        rows = slice(start, start + GRAVITY_ROWS)
        origins, centres, omega = [], [], []
        for j, (r, p) in enumerate(chain._walk(q[rows])):  # ([N, 3] views of the component-major walk)
            origins.append(p.T)
            centres.append((p + _times(r, coms[j])).T)
            omega.append(_times(r, axes[j]).T)
        if loads is None:
            torques = gravity_from_points(origins, centres, omega, masses, d.payload_mass if payload else 0.0,
                                          (p + _times(r, payload_com)).T)
        else:
            block = in_last[rows].T  # [3, n]
            centre = (p + r[:, 0] * block[0] + r[:, 1] * block[1] + r[:, 2] * block[2]).T
            arm = gravity_from_points(origins, centres, omega, masses)
            torques = [a + b for a, b in zip(arm, load_torques(origins, omega, loads[rows, 0], centre))]
        out[rows] = np.stack(torques, axis=1)
    return out

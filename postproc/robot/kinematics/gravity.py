"""Gravity torques of a description's links and payload (numpy)."""
from __future__ import annotations

import numpy as np

from ...core.frames import MM
from ..description import RobotDescription
from .chain import Chain, _times

__all__ = ['GRAVITY', 'gravity_torques', 'gravity_from_points', 'holding_torques']


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


def gravity_torques(description: RobotDescription, q_deg: np.ndarray, payload: bool = True,
                    chain: Chain | None = None) -> np.ndarray:
    """Joint torques [N, J] (Nm) that hold a description's arm (with its payload, or without)
    against gravity at joint angles [N, J] (deg): :func:`gravity_from_points` of the joint
    frames of its ``chain`` (default ``Chain.of(description, tool=False)``), all poses at once, a block of
    rows at a time (tests/test_kinematics.py checks it against ``pin.computeGeneralizedGravity``)."""
    d = description
    chain = Chain.of(d, tool=False) if chain is None else chain
    q = np.radians(np.atleast_2d(np.asarray(q_deg, float)))
    coms, axes, masses, payload_com = d.coms, d.axes, d.masses, d.payload_com_in_last
    out = np.empty_like(q)
    for start in range(0, len(q), GRAVITY_ROWS):  # blocks that stay in the cache
        rows = slice(start, start + GRAVITY_ROWS)
        origins, centres, omega = [], [], []
        for j, (r, p) in enumerate(chain._walk(q[rows])):  # ([N, 3] views of the component-major walk)
            origins.append(p.T)
            centres.append((p + _times(r, coms[j])).T)
            omega.append(_times(r, axes[j]).T)
        torques = gravity_from_points(origins, centres, omega, masses, d.payload_mass if payload else 0.0,
                                      (p + _times(r, payload_com)).T)
        out[rows] = np.stack(torques, axis=1)
    return out

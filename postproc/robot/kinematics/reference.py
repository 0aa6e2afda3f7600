"""Pinocchio's model of a description: the reference FK and gravity, for tests and checks only.

:func:`pin_model` builds it from the same arrays as :class:`~postproc.robot.kinematics.chain.Chain`
(metres inside); :func:`pin_fk` is its FK of a frame, one Pinocchio call per pose. The numpy
Chain, the torch twin and the exported graph's batch-last FK are checked against it
(tests/test_kinematics.py); no product code path computes with it."""
from __future__ import annotations

import numpy as np

from ...core.frames import MM
from ..description import RobotDescription

__all__ = ['pin_model', 'pin_fk']


def _pin_inertia(pin, mass: float, com_mm: np.ndarray, inertia: np.ndarray | None):
    moments = inertia if inertia is not None else np.full(3, 0.4 * mass * 0.3**2)
    return pin.Inertia(float(mass), np.asarray(com_mm, float) * MM, np.diag(moments))


def _se3(pin, matrix_mm: np.ndarray):
    return pin.SE3(matrix_mm[:3, :3].copy(), matrix_mm[:3, 3] * MM)


def pin_model(description: RobotDescription):
    """The reference: Pinocchio's model of a description (metres inside), built from the same
    arrays as :class:`Chain`, the payload a body of its own on the last joint at the flange,
    frames "flange" and "tcp". The numpy and torch kinematics are tested against it."""
    import pinocchio as pin

    d = description
    model = pin.Model()
    model.name = d.name
    parent = 0
    for spec, placement in zip(d.joints, d.placements):
        lo, hi = np.radians(spec.limits)
        parent = model.addJoint(
            parent, pin.JointModelRevoluteUnaligned(*spec.axis), _se3(pin, placement), spec.name,
            np.array([1e6]), np.array([10.0]), np.array([lo]), np.array([hi]))
        model.appendBodyToJoint(parent, _pin_inertia(pin, spec.mass, spec.com, spec.inertia), pin.SE3.Identity())
    flange = _se3(pin, d.flange_matrix)
    if d.payload_mass > 0:
        model.appendBodyToJoint(parent, _pin_inertia(pin, d.payload_mass, d.payload_com, None), flange)
    fid = model.addFrame(pin.Frame("flange", parent, flange, pin.FrameType.OP_FRAME))
    model.addFrame(pin.Frame("tcp", parent, fid, flange * _se3(pin, d.tool_matrix), pin.FrameType.OP_FRAME))
    return model


def pin_fk(model, data, q_deg: np.ndarray, frame: str = "tcp") -> np.ndarray:
    """The reference FK: transforms [N, 4, 4] (mm) of ``frame`` ("tcp", "flange") of ``model``
    (:func:`pin_model`; ``data`` its ``pin.Data``) at joint angles [N, 6] (deg), one
    ``pin.framesForwardKinematics`` per pose (for checks, not for bulk work)."""
    import pinocchio as pin

    fid = model.getFrameId(frame)
    q = np.radians(np.atleast_2d(np.asarray(q_deg, float)))
    out = np.zeros((len(q), 4, 4))
    for i, qi in enumerate(q):
        pin.framesForwardKinematics(model, data, qi)
        m = data.oMf[fid]
        out[i, :3, :3], out[i, :3, 3], out[i, 3, 3] = m.rotation, m.translation / MM, 1.0
    return out

"""Pinocchio's model of a description: the reference FK and gravity, for tests and checks."""
from __future__ import annotations

import numpy as np

from ...core.frames import MM
from ..description import RobotDescription

__all__ = ['pin_model']


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

"""The robot's kinematics: one forward kinematics per backend, one closed-form inverse
kinematics per arm family, all built from a description's arrays (``RobotDescription.placements``,
``axes``, ``flange_matrix``, ``tool_matrix``, ``masses``, ``coms``). The numpy modules never
import torch; the torch ones (``twin``, ``batch_last``) are imported only by the identification
(``postproc.model.training``) and the checks. tests/test_kinematics.py holds every FK and the
gravity torques to Pinocchio's (1e-9 mm, 1e-12 on rotation entries and relative torque).

Modules:

- ``chain`` — THE forward kinematics (numpy): ``Chain`` of joint placements, axes, end and base,
  every pose at once (``transforms``, ``joints``, ``zero_frames``); the simulator perturbs its arrays.
- ``gravity`` — joint torques holding the arm against gravity: ``gravity_from_points`` /
  ``holding_torques``, one formula for numpy and torch; ``gravity_torques`` of a description.
- ``ik`` — the controller's closed-form IK, one per arm family (KUKA-type with a spherical wrist,
  UR-type), written once over an array namespace: ``NUMPY`` (all 8 branches, ``Robot``) and
  the twin's ``TORCH`` (one branch per row, differentiable, exported).
- ``dh`` — standard DH rows of a chain and the DH chain as a ``Chain`` (the UR controller's
  calibration layout).
- ``twin`` — the torch twin: ``Arm`` (FK, gravity torques), ``KukaIK`` / ``UrIK`` / ``make_ik``
  (the ``ik`` formulas in torch), the torch rotation helpers.
- ``batch_last`` — the exported ONNX graph's layout of the same FK and torques ([3, N] vectors,
  [3, 3, N] rotations: a few onnxruntime kernels per step).
- ``reference`` — Pinocchio's model of a description (``pin_model``, ``pin_fk``): the reference,
  for tests and checks only.
"""

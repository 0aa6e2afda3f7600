"""The robot's kinematics: one forward kinematics per backend, one inverse kinematics per arm
family.

* ``chain`` — THE forward kinematics (numpy): a serial chain's joint frames for many poses at once;
* ``twin`` — the torch twin (FK, gravity terms, the IK modules): what training fits and exports;
* ``batch_last`` — the exported graph's layout of the FK (batch last: fewer, larger ONNX nodes);
* ``reference`` — Pinocchio's model and FK: the reference the others are tested against;
* ``ik`` — the controller's closed-form IK, each arm family's formulas once over an array
  namespace (numpy here, torch in ``twin``);
* ``gravity`` — gravity torques of the links and the payload (numpy);
* ``dh`` — standard Denavit-Hartenberg rows of a chain, and a DH chain as a ``chain.Chain``.
"""

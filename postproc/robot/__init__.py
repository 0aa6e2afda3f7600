"""The robot's geometry, one home: a description (TOML) → its kinematics, and the conventions
its controller states configurations in. numpy only, but for the torch twin of the kinematics
(``kinematics.twin``, which only training imports) and Pinocchio (``kinematics.reference``, for
tests and checks).

Modules, in their import order (tests/test_structure.py):

* ``external`` — external units (a track that carries the robot, a turntable or positioner):
  one axis each, ``[[external]]`` tables; ``description`` — a robot description read and
  checked, and ``--robot``'s one meaning (``robot_name``, ``robot_description``: a name, a
  shipped robot or a description file);
* ``kinematics/`` — one forward kinematics per backend, one inverse kinematics per arm family;
* ``arm`` — ``Robot``: the nominal robot (FK, IK branches, gravity, KUKA's Status/Turn);
  ``urdf`` — a description as a URDF and a URDF's arm read back; ``approach`` — the side
  each joint reaches a pose from (backlash);
* ``configuration`` — the controllers' rules: which joint angles a target gets (stated S/T,
  LIN keeps / PTP nearest, turns); ``conventions`` — how each controller states a
  configuration (KUKA S/T, ABB confdata, FANUC CONFIG), motion kinds, controller families.
"""

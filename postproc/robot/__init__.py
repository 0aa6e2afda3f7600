"""The robot's geometry, one home: what a robot description says, its kinematics (one forward
kinematics per backend, one inverse kinematics per arm family), and how the controllers state
and choose an arm configuration. Numpy only, except ``kinematics.twin`` / ``kinematics.batch_last``
(torch, for the identification and its exported graph) and ``kinematics.reference``
(Pinocchio, for tests and checks). Units at every interface: mm and degrees (radians inside the
kinematics); rotation helpers and ``MM`` are ``postproc.core.frames``'.

Modules, lowest first (tests/test_structure.py keeps the order: a module imports only modules
listed before it; description and external, then kinematics, then arm, urdf and approach, then
configuration and conventions, are a line each, and configuration imports conventions):

- ``description`` — a robot description (TOML) → ``RobotDescription``: joints, flange, tool,
  payload, workspace, ``[errors]``, ``[robot] configuration``; the arrays every chain is built from.
- ``external`` — external units (a track carrying the robot, a turntable or positioner carrying the
  workpiece): ``ExternalUnit.base_at(e)``, ``[[external]]`` tables.
- ``kinematics`` — forward kinematics (``chain``: numpy; ``twin``: torch; ``batch_last``: the
  exported graph's layout; ``reference``: Pinocchio), the closed-form IK (``ik``), gravity, DH rows.
- ``arm`` — ``Robot``: a description's FK, gravity torques and the controller's IK (all 8 branches,
  the branch of a Status, the nearest pair), Status/Turn of joint angles, the reach sphere.
- ``urdf`` — a description as a URDF (``nominal_urdf``) and a URDF's arm read back and mapped onto
  a description (``read_urdf``, ``UrdfChain``, ``mapping``; P533).
- ``approach`` — approach signs: the side each joint reaches a pose from (the backlash's lost motion).
- ``conventions`` — the controllers' conventions: KUKA Status/Turn bits, ABB confdata, FANUC CONFIG
  (both ways), motion kinds (``MOTIONS``, ``execution_kinds``), controller families.
- ``configuration`` — arm configuration: a program's stated configuration and the controller's rules
  for the rest → the joint angles at each target (``stated_joints``, ``controller_joints``,
  ``target_joints``, ``stated_configuration``).
"""

"""Calibration: measuring the robot (plans, the simulated robot and tracker) and giving its
identified arm to others.

Modules: ``planning`` (Latin hypercube plans, the plan CSV, KRL and LS measurement programs),
``plan_for`` (``plan --for``: measurement poses for the programs that will run), ``simulator``
(the "physical" robot and the laser tracker: the nominal robot + seeded errors; ``measure`` and
``verify`` run on it), ``export`` (``postproc export``: a calibrated URDF, robot_calibration's
YAML, the identified parameters as JSON, the UR controller's calibration).
"""

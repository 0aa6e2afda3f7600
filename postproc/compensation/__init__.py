"""Compensation: a read program × a model → findings and commands → the program's new text.

The use cases take a program (``postproc.programs``), a loaded model (``postproc.model``) and
the :class:`~postproc.settings.Settings` whole.

Modules:

* ``findings`` — the rules both compensate and check apply, one function per code family, in
  the order compensate applies them; ``select`` (the targets the model takes, in the robot
  base), ``run_model``.
* ``inputs`` — what the controller uses at each target besides its pose: the joint angles of
  its arm configuration and its tool (the model's ``joints`` / ``tool`` inputs).
* ``commands`` — the model's commands streamed on a background thread into the program's
  numbers, each token checked as it is written.
* ``agreement`` — the runs of one set of numbers (loops, routines called twice, copies) agree,
  or are left as written (P230, P231, P322).
* ``guards`` — the last checks before writing: every output read again (P190, P191).
* ``pipeline`` — the compensate use case: ``compensate_program`` → ``Report``; writing outputs.
* ``streaming`` — a long CAM program a chunk at a time; ``compensate_file``.
* ``cell`` — a cell or backup compensated and written together.
* ``check`` — ``postproc check`` and the pre-commit hooks: findings, stamps, freshness.
* ``api`` — the public API for CAM hooks (``compensate_text``): settings made for a library caller.
"""

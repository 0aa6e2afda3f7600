"""Acceptance: what a cell is signed off with — reports, verdicts, ISO 9283, the certificate.

Modules: ``verify`` (the verify use case: a program and its compensation run on the simulated
robot, Table 2 before and after), ``report`` (Table 2, plots and the model card from measured
errors), ``verdict`` (pass/fail JSON for a cell's CI against the ``acceptance`` settings),
``iso9283`` (the ISO 9283 pose test), ``certificate`` (the calibration certificate, Markdown and
HTML).
"""

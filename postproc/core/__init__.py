"""Core: what every other package may use — numpy and the standard library only, no postproc
concept above a number, a frame or a located message.

Modules:

* ``diagnostics`` — ``PostprocError`` / ``Diagnostic`` (``path:line:col: CODE message``), the
  exit codes, and the registry of every code (``CODES``; ``docs/codes.md`` is made from it).
* ``frames`` — every rotation helper: KUKA X,Y,Z,A,B,C ↔ 4×4 (R = Rz(A)·Ry(B)·Rx(C)), compose,
  inverse, rotation vectors, quaternions, the dialects' orientation forms, Rodrigues
  (``axis_rotations``), the nearest A,B,C triple; ``MM`` (mm → m), once.
* ``units`` — positions given in another unit than mm (P517): one check for pose lists and
  measurement CSVs.
* ``toml`` — TOML inputs read one way: located syntax errors, values checked by kind, a key's
  line (robot descriptions, [[external]] units, settings files, fleet files, frame files).
* ``stats`` — the method's Table 2 figures (max, min, mean, std, p95).
* ``registration`` — the best-fit rigid transform (Kabsch / Umeyama), tracker → robot base.
* ``atomic`` — the one atomic writer (all files or none, a journal for several).
* ``outputs`` — the one rule for output paths (``-o``), checked before any work (P110).
* ``resources`` — where grammars, shipped models and schemas are (a clone or a wheel).
* ``progress`` — progress bars on stderr (tqdm, only when asked for).
* ``extras`` — which optional extra installs a missing module, and the command.
* ``version`` — the version, once.
"""

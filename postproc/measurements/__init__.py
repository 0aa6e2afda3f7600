"""Measurements: the measurement CSV (``x,y,z,a,b,c,x_meas,y_meas,z_meas`` + optional columns
and ``# key: value`` lines, the ``# tool:`` line and ``parse_tool``) and what becomes one.

Modules: ``csv`` (reading, writing and naming the columns of the measurement CSV), ``trackers``
(the tools cells measure with: SpatialAnalyzer, RoboDK, three reflectors → ``postproc
import``), ``datasets`` (public data sets: the IPA UR10 series).
"""

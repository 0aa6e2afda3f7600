"""``postproc import``: convert a public measurement data set into a measurement CSV."""
from __future__ import annotations

import sys

from .settings import ROBOT_HELP, add

EXAMPLES = """\
Formats:
  ipa              IPA robot-accuracy data (UR10 + laser tracker, Landgraf et al. 2021): ';'-separated,
                   decimal comma, Goal pose in m / rad (extrinsic roll-pitch-yaw), measurement in mm
                   in the tracker's frame.
  spatialanalyzer  a SpatialAnalyzer point export (name, X, Y, Z) + --poses PLAN.csv (the commanded
                   poses, postproc's plan CSV), matched by name where both name their rows, else by order.
  robodk           a RoboDK-style calibration table: J1..J6 and the measured X, Y, Z; the commanded
                   pose is the nominal FK of the joints (--robot, its tool or --tool).
  reflectors       three-reflector flange measurements: x,y,z,a,b,c and r1_x..r3_z, the reflectors'
                   places on the TCP frame in a '// reflectors: x,y,z; x,y,z; x,y,z' line: each row's
                   measured TCP position and orientation (a_meas,b_meas,c_meas).
  The three state their units ('// units: mm, deg' or 'X [mm]') and frame ('// frame: tracker' or
  '// frame: base') in the file, or are refused (P530): postproc converts m, in and rad but never guesses.
  Samples: samples/import/ (made by samples/import/make_samples.py from the simulated robot).

Output: `x,y,z,a,b,c,x_meas,y_meas,z_meas,q1..q6,temperature` (mm, KUKA A,B,C and joint
angles in degrees, °C), rows in the file's order, after `# key: value` lines. The first,
`# frame: tracker`, says that x_meas..z_meas are still in the tracker's frame: train with
`postproc train --register`, which fits the tracker → base transform on the training split
only. `--register` here fits it on the rows outside `--val-fraction` (drawn with
`--split-seed`), writes `# frame: base` and a `holdout` column (1 = not used for the fit);
with the data's measured orientation it also writes `a_meas,b_meas,c_meas`: the TCP's
orientation in the base frame, the probe's fixed rotation on the flange estimated on the same
rows (`# probe_rotation`), so that `train` fits the orientation error too.

Examples:
  postproc import ipa Series_C/measurements_random_poses.csv -o measured.csv
  postproc import spatialanalyzer samples/import/sa_points.txt --poses samples/import/sa_plan.csv -o m.csv --register
  postproc import robodk samples/import/robodk_calibration.csv --robot models/kr500.toml -o m.csv --register
  postproc import reflectors samples/import/three_reflectors.csv -o m.csv --register
  postproc train measured.csv --register ...
  postproc import ipa Series_C/measurements_random_poses.csv -o base.csv --register --split-seed 0 --val-fraction 0.2
"""


def add_parser(sub, common, formatter) -> None:
    p = sub.add_parser(
        "import",
        parents=[common],
        formatter_class=formatter,
        help="convert measurements (IPA data set, SpatialAnalyzer, RoboDK-style CSV, three reflectors) into a "
        "measurement CSV",
        description="Convert measurements from a public data set or a cell's measuring tools into postproc's "
        "measurement CSV.",
        epilog=EXAMPLES,
    )
    p.add_argument("format", choices=["ipa", "spatialanalyzer", "robodk", "reflectors"], help="format of SRC")
    p.add_argument("src", metavar="SRC", help="the measurement file")
    p.add_argument("--poses", metavar="PLAN.csv", help="spatialanalyzer: the commanded poses (x,y,z,a,b,c [, name])")
    add(p, "robot", helps={"robot": ROBOT_HELP + " (robodk: the one whose nominal FK gives the commanded poses; default "
                           "models/kr500.toml)"})
    p.add_argument("--tool", metavar="X,Y,Z,A,B,C", help="robodk: the TCP on the flange (default: the description's)")
    p.add_argument("-o", "--output", required=True, metavar="OUT.csv", help="measurement CSV to write")
    p.add_argument(
        "--register",
        action="store_true",
        help="map the measurements into the robot base frame (rigid fit on the training rows)",
    )
    p.add_argument("--split-seed", type=int, default=0, metavar="S", help="seed of the hold-out draw (default 0)")
    p.add_argument(
        "--val-fraction",
        type=float,
        default=0.2,
        metavar="F",
        help="fraction of rows held out of the registration fit (default 0.2)",
    )
    p.add_argument(
        "--abc",
        choices=["nearest", "canonical"],
        default="nearest",
        help="A,B,C triple: nearest the data's own roll/pitch/yaw (default, continuous) "
        "or canonical B in [-90, 90] as a KUKA controller reports",
    )
    p.set_defaults(run=run)


def run(args) -> int:
    if args.format != "ipa":
        return run_tool(args)
    import os

    import numpy as np
    import scipy.spatial  # noqa: F401  (angle conversions; missing: postproc.cli names the extra to install)

    from ..core.outputs import check_outputs
    from ..measurements.csv import write_measurements
    from ..measurements.datasets import read_ipa

    check_outputs([args.output], [args.src])
    from ..core.registration import register_measurements
    from ..model.training.data import split_indices

    series = read_ipa(args.src, branch=args.abc)
    extra = {f"q{i + 1}": series.joints[:, i] for i in range(6)}
    if series.temperature is not None:
        extra["temperature"] = series.temperature
    metadata = {"frame": "tracker"}
    measured = series.measured
    summary = ""
    if args.register:
        held = np.zeros(len(series), dtype=bool)
        held[split_indices(len(series), args.val_fraction, args.split_seed)[1]] = True
        measured, transform, rms = register_measurements(series.commanded[:, :3], series.measured, ~held)
        metadata = {
            "frame": "base",
            "registration": f"rigid (Kabsch) fit on {int((~held).sum())} rows (holdout = 0; seed {args.split_seed}, "
            f"val fraction {args.val_fraction}), rms {rms:.3f} mm",
            "tracker_to_base": " ".join(f"{v:.9g}" for v in transform[:3].ravel()),
        }
        if series.measured_rotation is not None:
            from ..measurements.datasets import probe_orientation

            abc, probe, rms_deg = probe_orientation(series.commanded[:, 3:], transform[:3, :3] @ series.measured_rotation,
                                                    ~held)
            extra = {**dict(zip(("a_meas", "b_meas", "c_meas"), abc.T)), **extra}
            metadata["probe_rotation"] = (" ".join(f"{v:.9g}" for v in probe.ravel())
                                          + f" (probe axes on the TCP, fitted on the same rows; rms {rms_deg:.4f} deg after)")
        extra["holdout"] = held.astype(float)
        summary = f"; registration fitted on {int((~held).sum())} rows, rms {rms:.3f} mm"
    metadata["source"] = f"{os.path.basename(args.src)} (IPA robot-accuracy format, {len(series)} rows)"
    write_measurements(args.output, series.commanded, measured, extra, metadata)
    if not args.quiet:
        print(
            f"postproc import: {len(series)} rows {args.src} -> {args.output} (frame: {metadata['frame']}{summary})",
            file=sys.stderr,
        )
    return 0


def run_tool(args) -> int:
    """spatialanalyzer / robodk / reflectors: ``postproc.measurements.trackers`` → the measurement CSV (with
    ``--register``: tracker → base fitted on the rows outside ``--val-fraction``)."""
    import numpy as np

    from ..core.diagnostics import P308, P513, PostprocError
    from ..core.outputs import check_outputs
    from ..measurements import trackers as imports
    from ..measurements.csv import write_measurements

    if args.format == "spatialanalyzer" and not args.poses:
        raise PostprocError("spatialanalyzer needs --poses PLAN.csv: the commanded poses the points were measured at",
                            code=P308)
    check_outputs([args.output], [args.src, args.poses])
    if args.format == "spatialanalyzer":
        data = imports.read_spatial_analyzer(args.src, args.poses)
    elif args.format == "robodk":
        from ..robot.description import robot_description

        tool = None
        if args.tool:
            try:
                tool = np.array([float(v) for v in args.tool.split(",")], float)
            except ValueError:
                tool = np.zeros(0)
            if tool.shape != (6,) or not np.isfinite(tool).all():
                raise PostprocError(f"--tool {args.tool!r}: expected X,Y,Z,A,B,C", code=P308)
        data = imports.read_robodk(args.src, robot_description(args.robot), tool)
    else:
        data = imports.read_reflectors(args.src)
    measured, extra, metadata = data.measured, dict(data.extra), dict(data.metadata)
    orientation = data.orientation
    summary = ""
    if args.register:
        from ..core import frames
        from ..core.frames import nearest_triple
        from ..core.registration import register_measurements
        from ..model.training.data import split_indices

        if data.frame == "base":
            raise PostprocError("--register: the file states frame: base, its points are in the robot base already",
                                args.src, code=P513)
        held = np.zeros(len(data), dtype=bool)
        held[split_indices(len(data), args.val_fraction, args.split_seed)[1]] = True
        measured, transform, rms = register_measurements(data.commanded[:, :3], data.measured, ~held)
        metadata.update(frame="base", registration=f"rigid (Kabsch) fit on {int((~held).sum())} rows (holdout = 0; "
                        f"seed {args.split_seed}, val fraction {args.val_fraction}), rms {rms:.3f} mm",
                        tracker_to_base=" ".join(f"{v:.9g}" for v in transform[:3].ravel()))
        if orientation is not None:  # the measured orientation turns with the frame
            turned = transform[:3, :3] @ frames.rotation_from_abc(orientation)
            orientation = nearest_triple(frames.abc_from_rotation(turned), data.commanded[:, 3:6])
        extra["holdout"] = held.astype(float)
        summary = f"; registration fitted on {int((~held).sum())} rows, rms {rms:.3f} mm"
    if orientation is not None:
        extra = {**dict(zip(("a_meas", "b_meas", "c_meas"), orientation.T)), **extra}
    write_measurements(args.output, data.commanded, measured, extra, metadata)
    if not args.quiet:
        print(f"postproc import: {len(data)} rows {args.src} -> {args.output} (frame: {metadata['frame']}{summary})",
              file=sys.stderr)
    return 0

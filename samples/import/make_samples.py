"""Writes the import samples: one measurement campaign of the simulated KR500 in the shapes of
the tools cells use, for `postproc import` (tests/test_imports.py reads them back).

    python samples/import/make_samples.py        # rewrites samples/import/*

40 poses of a Latin hypercube in the shipped model's envelope, visited in order, measured on
the simulated robot (models/kr500.toml, its default robot, noise seed 0) with its tracker;
the tracker stands at TRACKER (the base → tracker frame, made up) so that the files are in the
tracker's frame, as a tracker's software writes them:

* sa_points.txt + sa_plan.csv: a SpatialAnalyzer point export (metres, to show a stated unit
  converted) and the plan that named the points;
* robodk_calibration.csv: J1..J6 (deg) and the measured TCP X, Y, Z (mm);
* three_reflectors.csv: the commanded pose and three SMR centres on the TCP frame (REFLECTORS).

Written by us from the simulator (nothing from a vendor's files): the formats' shapes only.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from postproc.core import frames
from postproc.calibration.planning import latin_hypercube
from postproc.calibration.simulator import SimulatedRobot

HERE = Path(__file__).resolve().parent
N = 40
TRACKER = np.array([3200.0, -1500.0, -300.0, 35.0, 0.0, 0.0])  # the tracker's frame in the robot base
REFLECTORS = np.array([[100.0, 0.0, 40.0], [-40.0, 40.0, 40.0], [-10.0, -60.0, 70.0]])  # on the TCP frame, mm: unequal sides


def main() -> None:
    poses = latin_hypercube(N, seed=21)
    sim = SimulatedRobot.from_file(None, None)
    q = sim.joint_angles(poses, None, None)
    measured = sim.measure(poses, rng_seed=0, orientation=True, q_deg=q)
    to_tracker = frames.inverse(frames.frame_to_matrix(TRACKER))
    tcp = frames.frame_to_matrix(measured[:, :6])  # the measured TCP poses in the base
    in_tracker = to_tracker @ tcp
    xyz = in_tracker[:, :3, 3]
    names = [f"P{k + 1:03d}" for k in range(N)]

    plan = ["name,x,y,z,a,b,c"] + [f"{n}," + ",".join(f"{v:.4f}" for v in p) for n, p in zip(names, poses)]
    (HERE / "sa_plan.csv").write_text("\n".join(plan) + "\n")
    order = np.random.default_rng(3).permutation(N)  # SA lists points in its own order: matched by name
    sa = ["// SpatialAnalyzer point export (sample written by postproc from its simulator)",
          "// units: m", "// frame: tracker", "Collection,Group,Point,X,Y,Z"]
    sa += [f"A,Robot TCP,A::Robot TCP::{names[k]}," + ",".join(f"{v / 1000:.7f}" for v in xyz[k]) for k in order]
    (HERE / "sa_points.txt").write_text("\n".join(sa) + "\n")

    robodk = ["// RoboDK-style calibration measurements (sample written by postproc from its simulator)",
              "// frame: tracker", "Id,J1 [deg],J2 [deg],J3 [deg],J4 [deg],J5 [deg],J6 [deg],X [mm],Y [mm],Z [mm]"]
    robodk += [f"{k + 1}," + ",".join(f"{v:.6f}" for v in q[k]) + "," + ",".join(f"{v:.4f}" for v in xyz[k])
               for k in range(N)]
    (HERE / "robodk_calibration.csv").write_text("\n".join(robodk) + "\n")

    centres = in_tracker[:, None, :3, :3] @ REFLECTORS[None, :, :, None]
    centres = centres[..., 0] + in_tracker[:, None, :3, 3]  # [N, 3, 3]
    header = "x,y,z,a,b,c," + ",".join(f"r{k}_{c}" for k in (1, 2, 3) for c in "xyz")
    refl = ["# three reflectors on the flange (sample written by postproc from its simulator)", "# units: mm, deg",
            "# frame: tracker", "# reflectors: " + "; ".join(",".join(f"{v:g}" for v in p) for p in REFLECTORS),
            header]
    refl += [",".join(f"{v:.4f}" for v in p) + "," + ",".join(f"{v:.4f}" for v in c.ravel())
             for p, c in zip(poses, centres)]
    (HERE / "three_reflectors.csv").write_text("\n".join(refl) + "\n")


if __name__ == "__main__":
    main()

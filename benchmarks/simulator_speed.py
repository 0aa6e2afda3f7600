"""How fast is the simulated robot + tracker? Prints figures (no assertions).

Budgets (docs: the simulator issue): measuring 100,000 poses ≤ 10 s on 2 cores; a 2000-pose
`postproc plan` + `postproc measure` ≤ 2 s (both commands, each a fresh process, start-up
included). Measured on whatever else the machine is doing: say so when quoting them.

Gravity torques (the compliance's input) are numpy, vectorised over poses from the chain's
joint frames; the benchmark times them against Pinocchio's computeGeneralizedGravity called
once per pose (what the simulator did before, and the tests' reference) on the same poses,
and records the ratio with the other figures in benchmarks/results/simulator_speed.json.

    python benchmarks/simulator_speed.py            # 100k in-process + 2000 through the CLI
    python benchmarks/simulator_speed.py -n 20000
"""
from __future__ import annotations

import argparse
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from _common import record

FIGURES: dict[str, float] = {}


def timed(label: str, fn, *args, key: str | None = None, repeat: int = 1):
    """fn(*args), printing (and recording under ``key``) the best wall time of ``repeat`` runs."""
    dt = math.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn(*args)
        dt = min(dt, time.perf_counter() - t0)
    print(f"  {label:52s} {dt:7.3f} s")
    if key:
        FIGURES[key] = round(dt, 3)
    return out


def pin_gravity(robot, q_deg: np.ndarray) -> np.ndarray:
    """Pinocchio's gravity torques, one call per pose (the reference)."""
    import pinocchio as pin

    from postproc.robot.kinematics.reference import pin_model

    model = pin_model(robot.description)
    data = model.createData()
    return np.array([pin.computeGeneralizedGravity(model, data, qi) for qi in np.radians(q_deg)])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("-n", type=int, default=100_000, help="poses measured in-process (default 100000)")
    args = parser.parse_args()

    from postproc.calibration.planning import latin_hypercube
    from postproc.calibration.simulator import SimulatedRobot
    from postproc.robot.approach import approach_signs

    print(f"in-process, {args.n} poses")
    sim = timed("SimulatedRobot() (build, calibrate)", SimulatedRobot, key="robot_s")
    poses = timed("latin_hypercube", latin_hypercube, args.n)
    t0 = time.perf_counter()
    q = timed("nominal IK (numpy, 8 branches)", sim.joint_angles, poses, key="ik_s")
    tau = timed("gravity torques (numpy, vectorised; best of 3)", sim.robot.gravity_torques, q, key="gravity_s",
                repeat=3)
    timed("backlash signs (np.diff + forward fill)", approach_signs, q, sim.robot.home_q)
    timed("true FK (numpy)", sim.chain.transforms, q / 57.29577951308232, key="fk_s")
    print(f"  {'(parts)':52s} {time.perf_counter() - t0:7.3f} s")
    reference = timed("gravity torques (pin, one call per pose; best of 3)", pin_gravity, sim.robot, q,
                      key="gravity_pin_s", repeat=3)
    FIGURES["gravity_speedup"] = round(FIGURES["gravity_pin_s"] / FIGURES["gravity_s"], 1)
    FIGURES["gravity_max_diff_rel"] = float(f"{np.abs(tau - reference).max() / np.abs(reference).max():.2g}")
    print(f"  gravity: numpy {FIGURES['gravity_speedup']}x as fast as the pin loop, "
          f"max |difference| {FIGURES['gravity_max_diff_rel']:.1e} of the largest torque")
    fresh = SimulatedRobot()  # no remembered IK: the end-to-end figure solves it again
    timed(f"measure({args.n}) end to end (fresh robot)", fresh.measure, poses, 0, key="measure_s")

    print("CLI, 2000 poses (fresh processes, start-up included)")
    with tempfile.TemporaryDirectory() as tmp:
        plan, measured = Path(tmp) / "plan.csv", Path(tmp) / "measured.csv"
        total = 0.0
        for argv in (["plan", "-n", "2000", "-o", str(plan), "--krl", str(Path(tmp) / "measure.src")],
                     ["measure", str(plan), "-o", str(measured)]):
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-m", "postproc", *argv, "-q"], check=True)
            dt = time.perf_counter() - t0
            total += dt
            FIGURES[f"cli_{argv[0]}_2000_s"] = round(dt, 3)
            print(f"  postproc {argv[0]:43s} {dt:7.3f} s")
        print(f"  {'plan + measure':52s} {total:7.3f} s")
        big = Path(tmp) / "big.csv"
        subprocess.run([sys.executable, "-m", "postproc", "plan", "-n", str(args.n), "-o", str(big), "-q"], check=True)
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "postproc", "measure", str(big), "-o", str(measured), "-q"], check=True)
        FIGURES["cli_measure_s"] = round(time.perf_counter() - t0, 3)
        print(f"  postproc measure, {args.n} poses (CSV in/out) {FIGURES['cli_measure_s']:7.3f} s")
    FIGURES["poses"] = args.n
    print(f"figures: {record('simulator_speed', FIGURES)}")


if __name__ == "__main__":
    main()

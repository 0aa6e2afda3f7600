"""How fast is the simulated robot + tracker? Prints figures (no assertions).

Budgets (docs: the simulator issue): measuring 100,000 poses ≤ 10 s on 2 cores; a 2000-pose
`postproc plan` + `postproc measure` ≤ 2 s (both commands, each a fresh process, start-up
included). Measured on whatever else the machine is doing: say so when quoting them.

    python benchmarks/simulator_speed.py            # 100k in-process + 2000 through the CLI
    python benchmarks/simulator_speed.py -n 20000
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def timed(label: str, fn, *args):
    t0 = time.perf_counter()
    out = fn(*args)
    print(f"  {label:42s} {time.perf_counter() - t0:7.3f} s")
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("-n", type=int, default=100_000, help="poses measured in-process (default 100000)")
    args = parser.parse_args()

    from postproc.planning import latin_hypercube
    from postproc.simulator import SimulatedRobot, approach_signs

    print(f"in-process, {args.n} poses")
    sim = timed("SimulatedRobot() (imports pin, build, calibrate)", SimulatedRobot)
    poses = timed("latin_hypercube", latin_hypercube, args.n)
    t0 = time.perf_counter()
    q = timed("nominal IK (numpy, 8 branches)", sim.joint_angles, poses)
    timed("gravity torques (pin, one call per pose)", sim.robot.gravity_torques, q)
    timed("backlash signs (np.diff + forward fill)", approach_signs, q, sim.robot.home_q)
    timed("true FK (numpy)", sim.chain.transforms, q / 57.29577951308232)
    print(f"  {'(parts)':42s} {time.perf_counter() - t0:7.3f} s")
    fresh = SimulatedRobot()  # no remembered IK: the end-to-end figure solves it again
    timed(f"measure({args.n}) end to end (fresh robot)", fresh.measure, poses, 0)

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
            print(f"  postproc {argv[0]:33s} {dt:7.3f} s")
        print(f"  {'plan + measure':42s} {total:7.3f} s")
        big = Path(tmp) / "big.csv"
        subprocess.run([sys.executable, "-m", "postproc", "plan", "-n", str(args.n), "-o", str(big), "-q"], check=True)
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "postproc", "measure", str(big), "-o", str(measured), "-q"], check=True)
        print(f"  postproc measure, {args.n} poses (CSV in/out) {time.perf_counter() - t0:7.3f} s")


if __name__ == "__main__":
    main()

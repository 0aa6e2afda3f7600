"""How long the default `postproc train` takes on 1900 training points (budget: 2 min, 2 cores).

    python benchmarks/train_speed.py [--data measured.csv] [--repeat 1] [-- extra train options]

Without --data it plans and measures 2000 poses on the default simulated robot
(`postproc plan -n 2000 --seed 0`, `postproc measure`) — or, without the simulator, writes
the synthetic error field — then runs `postproc train DATA -o …` (5 % held out → 1900
training points) as a separate process, as a user would, once with `--method gpso` (the
GPSO-DNN method with its defaults) and once with the command's default method, and prints
the wall time of each whole command (start-up, torch import, training, export) and its report.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def run_cli(*args: str, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "postproc", *args], cwd=ROOT, check=True, text=True, **kw)


def make_data(folder: Path) -> tuple[Path, str]:
    data = folder / "measured.csv"
    try:
        import postproc.calibration.simulator  # noqa: F401
    except ImportError:
        from postproc.model.training.synthetic import synthetic_measurements, to_csv

        data.write_text(to_csv(*synthetic_measurements(2000)))
        return data, "synthetic error field (no simulator), 2000 poses"
    plan = folder / "plan.csv"
    run_cli("plan", "-n", "2000", "--seed", "0", "-o", str(plan), "-q")
    run_cli("measure", str(plan), "-o", str(data), "-q")
    return data, "default simulated robot, `plan -n 2000 --seed 0` + `measure`"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("extra", nargs="*", help="more `postproc train` options (after --)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        data, source = (Path(args.data), args.data) if args.data else make_data(folder)
        print(f"data: {source}")
        print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f} (shared: timings are under that load)")
        for label, method in (("--method gpso", ["--method", "gpso"]), ("default method", [])):
            for i in range(args.repeat):
                t = time.perf_counter()
                run = run_cli("train", str(data), "-o", str(folder / "m.onnx"), *method, *args.extra, capture_output=True)
                wall = time.perf_counter() - t
                print(f"--- postproc train ({label})")
                print(run.stdout.rstrip())
                print(f"run {i + 1}: wall time {wall:.1f} s (budget 120 s), load average after {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()

"""Speed of `postproc compensate` on a generated CAM program.

    python benchmarks/compensate_speed.py [--targets 1000000] [--model models/default.onnx]

Prints targets/s and peak memory of the CLI on a program of N `LIN {X …,Y …,Z …,A …,B …,C …}
C_VEL` lines, the time of a plain Python pass that reads the file, rewrites the same X/Y/Z
numbers by regex and writes it (the floor any rewriter must pay), their ratio, and the
wall time of a 100-line program end to end (process start included).
Goals (issue 2): ≥ 100,000 targets/s, ≤ 3× the regex pass, peak ≤ 2 GB, 100 lines ≤ 0.5 s.
"""
from __future__ import annotations

import argparse
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent


def make_cam_program(path: Path, n: int, seed: int = 0) -> None:
    """A CAM-style module: header, $BASE/$TOOL at the top, n LIN lines inside the envelope."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 40 * np.pi, n)
    x = 2000 + 250 * np.cos(t) * np.linspace(0.2, 1, n)
    y = 500 * np.sin(t) * np.linspace(0.2, 1, n)
    z = 600 + 600 * np.linspace(0, 1, n) + rng.normal(0, 0.01, n)
    a, b, c = rng.uniform(-3, 3, n), 90 + rng.uniform(-3, 3, n), rng.uniform(-3, 3, n)
    body = "\n".join(
        f"LIN {{X {x[i]:.3f},Y {y[i]:.3f},Z {z[i]:.3f},A {a[i]:.3f},B {b[i]:.3f},C {c[i]:.3f}}} C_VEL"
        for i in range(n)
    )
    head = (
        "&ACCESS RVP\n&REL 1\nDEF bench()\n;CAM post-processor output\n"
        "$BASE={X 0.0,Y 0.0,Z 0.0,A 0.0,B 0.0,C 0.0}\n$VEL.CP=0.2\n$APO.CVEL=80\n"
    )
    path.write_text(head + body + "\nEND\n")


REGEX_NUMBER = re.compile(r"([XYZ] )(-?\d+\.\d+)")


def regex_pass(src: Path, dst: Path) -> float:
    """Read, add 0.1 to every X/Y/Z number by regex, write: the floor of any rewriter."""
    start = time.perf_counter()
    text = src.read_text()
    out = REGEX_NUMBER.sub(lambda m: f"{m.group(1)}{float(m.group(2)) + 0.1:.3f}", text)
    dst.write_text(out)
    return time.perf_counter() - start


def run_cli(args: list[str]) -> tuple[float, float]:
    """Wall seconds and peak RSS (MB) of one `postproc …` process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "postproc", *args], capture_output=True, text=True, cwd=REPO)
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        sys.exit(f"postproc failed: {proc.stderr}")
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    return wall, max(peak, before) / 1024


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--targets", type=int, default=1_000_000)
    parser.add_argument("--model", default=str(REPO / "models" / "default.onnx"))
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        big, small = tmp / "bench.src", tmp / "small.src"
        make_cam_program(big, args.targets)
        make_cam_program(small, 100, seed=1)
        size_mb = big.stat().st_size / 1e6
        regex_s = min(regex_pass(big, tmp / "regex.src") for _ in range(2))
        wall, peak = run_cli(["compensate", str(big), "-o", str(tmp / "out.src"), "--model", args.model, "-q"])
        small_walls = [run_cli(["compensate", str(small), "-o", str(tmp / "s.src"), "--model", args.model, "-q"])[0]
                       for _ in range(5)]
    rate = args.targets / wall
    print(f"program: {args.targets:,} LIN targets, {size_mb:.1f} MB; cores: {os.cpu_count()}")
    print(f"postproc compensate: {wall:.2f} s wall (process start included) = {rate:,.0f} targets/s "
          f"(goal >= 100,000); peak RSS {peak:,.0f} MB (goal <= 2048)")
    print(f"regex pass (read, rewrite X/Y/Z, write): {regex_s:.2f} s; ratio {wall / regex_s:.2f}x (goal <= 3x)")
    print(f"100-target program end to end: median {np.median(small_walls):.3f} s, "
          f"best {min(small_walls):.3f} s (goal <= 0.5 s)")


if __name__ == "__main__":
    main()

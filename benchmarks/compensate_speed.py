"""Speed of `postproc compensate` on a generated CAM program.

    python benchmarks/compensate_speed.py [--targets 1000000] [--model models/default.onnx] [--memory] [--poses]

Prints targets/s and peak memory of the CLI on a program of N `LIN {X …,Y …,Z …,A …,B …,C …}
C_VEL` lines, the time of a plain Python pass that reads the file, rewrites the same X/Y/Z
numbers by regex and writes it (the floor any rewriter must pay), their ratio, and the
wall time of a 100-line program end to end (process start included).
Goals (issue 2): ≥ 100,000 targets/s, ≤ 3× the regex pass, peak ≤ 2 GB, 100 lines ≤ 0.5 s.

With --poses it also compensates the same poses as a pose CSV (``x,y,z,a,b,c`` rows) and
times the regex pass on that CSV (issue 13: pose lists at KRL speed).

The figures go to benchmarks/results/compensate_speed.json (the README's are taken from there:
benchmarks/figures.py).

With --memory it also runs the in-memory path (programs above 8 MB stream by default: see
benchmarks/compensate_memory.py) on 1/10, 1/3 and all of the program and fits its peak RSS
(each process measured on its own, os.wait4) as a + b·size: b is the peak RSS per MB of
input, and (MemAvailable − a) / b the largest program that fits in this machine's memory.
"""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent


def cam_poses(n: int, seed: int = 0) -> np.ndarray:
    """The n targets [n, 6] of :func:`make_cam_program`: a spiral through the envelope."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 40 * np.pi, n)
    x = 2000 + 250 * np.cos(t) * np.linspace(0.2, 1, n)
    y = 500 * np.sin(t) * np.linspace(0.2, 1, n)
    z = 600 + 600 * np.linspace(0, 1, n) + rng.normal(0, 0.01, n)
    a, b, c = rng.uniform(-3, 3, n), 90 + rng.uniform(-3, 3, n), rng.uniform(-3, 3, n)
    return np.c_[x, y, z, a, b, c]


def make_cam_program(path: Path, n: int, seed: int = 0) -> None:
    """A CAM-style module: header, $BASE/$TOOL at the top, n LIN lines inside the envelope."""
    x, y, z, a, b, c = cam_poses(n, seed).T
    body = "\n".join(
        f"LIN {{X {x[i]:.3f},Y {y[i]:.3f},Z {z[i]:.3f},A {a[i]:.3f},B {b[i]:.3f},C {c[i]:.3f}}} C_VEL"
        for i in range(n)
    )
    head = (
        "&ACCESS RVP\n&REL 1\nDEF bench()\n;CAM post-processor output\n"
        "$BASE={X 0.0,Y 0.0,Z 0.0,A 0.0,B 0.0,C 0.0}\n$TOOL={X 300.0,Y 0.0,Z 75.0,A 0.0,B 0.0,C 0.0}\n"
        "$VEL.CP=0.2\n$APO.CVEL=80\n"
    )
    path.write_text(head + body + "\nEND\n")


def make_pose_csv(path: Path, n: int, seed: int = 0) -> None:
    """The targets of :func:`make_cam_program` as a pose CSV (header ``x,y,z,a,b,c``)."""
    krl = path.with_name(path.stem + "-poses.src")
    make_cam_program(krl, n, seed)
    rows = re.findall(r"LIN \{X (\S+),Y (\S+),Z (\S+),A (\S+),B (\S+),C (\S+)\}", krl.read_text())
    krl.unlink()
    path.write_text("x,y,z,a,b,c\n" + "\n".join(",".join(r) for r in rows) + "\n")


REGEX_NUMBER = re.compile(r"([XYZ] )(-?\d+\.\d+)")
REGEX_ROW = re.compile(r"^(-?\d+\.\d+),(-?\d+\.\d+),(-?\d+\.\d+)", re.M)


def regex_pass_csv(src: Path, dst: Path) -> float:
    """The regex pass on a pose CSV: read, add 0.1 to the x,y,z of every row, write."""
    start = time.perf_counter()
    text = src.read_text()
    out = REGEX_ROW.sub(lambda m: ",".join(f"{float(v) + 0.1:.3f}" for v in m.groups()), text)
    dst.write_text(out)
    return time.perf_counter() - start


def regex_pass(src: Path, dst: Path) -> float:
    """Read, add 0.1 to every X/Y/Z number by regex, write: the floor of any rewriter."""
    start = time.perf_counter()
    text = src.read_text()
    out = REGEX_NUMBER.sub(lambda m: f"{m.group(1)}{float(m.group(2)) + 0.1:.3f}", text)
    dst.write_text(out)
    return time.perf_counter() - start


# `python -m postproc …` that reports its own peak RSS on exit. (A child's ru_maxrss counts the
# parent's pages it shares between fork and exec: this benchmark's own 100s of MB.)
_CLI = ("import atexit, sys\n"
        "from postproc.cli import main\n"
        "atexit.register(lambda: sys.stderr.write('peak-kB ' + next(l.split()[1] for l in open('/proc/self/status')"
        " if l.startswith('VmHWM')) + '\\n'))\n"
        "sys.exit(main(sys.argv[1:]))\n")


def run_cli(args: list[str]) -> tuple[float, float]:
    """Wall seconds and peak RSS (MB) of one `postproc …` process."""
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", _CLI, *args], capture_output=True, text=True, cwd=REPO)
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        sys.exit(f"postproc failed: {proc.stderr}")
    peak = int(proc.stderr.split("peak-kB ")[-1].split()[0])
    return wall, peak / 1024


# the in-memory path (compensate_file with stream=False: a .src above 8 MB streams by default,
# benchmarks/compensate_memory.py), its peak RSS reported as by _CLI
_IN_MEMORY = ("import atexit, sys\n"
              "from postproc.compensation.streaming import compensate_file\n"
              "atexit.register(lambda: sys.stderr.write('peak-kB ' + next(l.split()[1] for l in open('/proc/self/status')"
              " if l.startswith('VmHWM')) + '\\n'))\n"
              "compensate_file(sys.argv[1], sys.argv[2], sys.argv[3], stream=False)\n")


def in_memory(src: Path, out: Path, model: str) -> tuple[float, float]:
    """Wall seconds and peak RSS (MB) of the in-memory path on ``src``, in a process of its own."""
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", _IN_MEMORY, str(src), str(out), model], capture_output=True,
                          text=True, cwd=REPO)
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        sys.exit(f"in-memory compensate failed: {proc.stderr}")
    return wall, int(proc.stderr.split("peak-kB ")[-1].split()[0]) / 1024


def _memory_run(tmp: Path, n: int, model: str, peaks: list) -> float:
    src = tmp / f"mem{n}.src"
    make_cam_program(src, n)
    wall, peak = in_memory(src, tmp / "mem_out.src", model)
    size = src.stat().st_size / 1e6
    peaks.append(peak)
    print(f"memory: {n:>9,} targets, {size:7.1f} MB in: peak RSS {peak:7,.0f} MB "
          f"({peak / size:.1f} MB per MB of input), {wall:.1f} s")
    src.unlink()
    return size


def available_mb() -> float:
    with open("/proc/meminfo") as fh:
        info = dict(line.split(":", 1) for line in fh)
    return int(info["MemAvailable"].split()[0]) / 1024


def memory(targets: int, model: str) -> dict:
    """Peak RSS against input size; what fits in this machine's memory (the fit's figures)."""
    sizes, peaks = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for n in (targets // 10, targets // 3, targets):
            sizes.append(_memory_run(Path(tmp), n, model, peaks))
    slope, intercept = np.polyfit(sizes, peaks, 1)
    free = available_mb()
    print(f"memory: peak RSS ≈ {intercept:.0f} MB + {slope:.1f} × input MB; MemAvailable {free:,.0f} MB → "
          f"largest program that fits ≈ {(free - intercept) / slope:,.0f} MB "
          f"(≈ {(free - intercept) / slope / (sizes[-1] / targets) / 1e6:,.1f} M targets of this shape)")
    return {"memory_intercept_mb": round(float(intercept)), "memory_mb_per_input_mb": round(float(slope), 1),
            "memory_peaks_mb": [round(p) for p in peaks], "memory_inputs_mb": [round(m, 1) for m in sizes]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--targets", type=int, default=1_000_000)
    parser.add_argument("--model", default=str(REPO / "models" / "default.onnx"))
    parser.add_argument("--memory", action="store_true", help="also: peak RSS against input size (3 more runs)")
    parser.add_argument("--poses", action="store_true", help="also: the same targets as a pose CSV")
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
        if args.poses:
            big.unlink()
            csv = tmp / "bench.csv"
            make_pose_csv(csv, args.targets)
            csv_regex_s = min(regex_pass_csv(csv, tmp / "regex.csv") for _ in range(2))
            csv_wall, csv_peak = run_cli(["compensate", str(csv), "-o", str(tmp / "out.csv"), "--model", args.model,
                                          "-q"])
            csv_mb = csv.stat().st_size / 1e6

    rate = args.targets / wall
    print(f"program: {args.targets:,} LIN targets, {size_mb:.1f} MB; cores: {os.cpu_count()}")
    print(f"postproc compensate: {wall:.2f} s wall (process start included) = {rate:,.0f} targets/s "
          f"(goal >= 100,000); peak RSS {peak:,.0f} MB (goal <= 2048)")
    print(f"regex pass (read, rewrite X/Y/Z, write): {regex_s:.2f} s; ratio {wall / regex_s:.2f}x (goal <= 1.5x, at least <= 2x: issue 13)")
    print(f"100-target program end to end: median {np.median(small_walls):.3f} s, "
          f"best {min(small_walls):.3f} s (goal <= 0.5 s)")
    if args.poses:
        print(f"pose CSV ({csv_mb:.1f} MB): postproc compensate {csv_wall:.2f} s, peak RSS {csv_peak:,.0f} MB "
              f"({csv_peak / csv_mb:.1f}x the input); regex pass {csv_regex_s:.2f} s; ratio {csv_wall / csv_regex_s:.2f}x "
              f"(KRL above: {wall / regex_s:.2f}x)")
    figures = {"targets": args.targets, "input_mb": round(size_mb, 1), "wall_s": round(wall, 2),
               "targets_per_s": round(rate), "peak_mb": round(peak), "regex_s": round(regex_s, 2),
               "ratio": round(wall / regex_s, 2), "small_median_s": round(float(np.median(small_walls)), 3),
               "small_best_s": round(min(small_walls), 3)}
    if args.poses:
        figures.update(csv_mb=round(csv_mb, 1), csv_wall_s=round(csv_wall, 2), csv_peak_mb=round(csv_peak),
                       csv_peak_per_mb=round(csv_peak / csv_mb, 1), csv_regex_s=round(csv_regex_s, 2),
                       csv_ratio=round(csv_wall / csv_regex_s, 2))
    if args.memory:
        figures.update(memory(args.targets, args.model))
    from _common import record  # (benchmarks/ is on sys.path: this script's own folder)

    print(f"figures: {record('compensate_speed', figures).relative_to(REPO)}")


if __name__ == "__main__":
    main()

"""Peak memory of streaming compensate (postproc/compensation/streaming.py) on long CAM programs.

    python benchmarks/compensate_memory.py [--targets 1000000 10000000] [--model models/default.onnx] [--compare]

For each size: generates the CAM program of ``compensate_speed.py`` in a temporary directory,
runs ``postproc compensate BIG.src -o OUT.src`` (a program this large streams by default) in a
process of its own and prints its wall time and peak RSS (the child's VmHWM), the time of the
regex pass (read, rewrite X/Y/Z, write) on the same file and their ratio; the files are
deleted after each size (the 10M program is ~700 MB). With ``--compare`` it also runs the
in-memory path on the smallest size and says whether the two outputs are the same bytes.
Goal (issue 13): peak RSS <= 300 MB for 1M and 10M targets.
"""
from __future__ import annotations

import argparse
import filecmp
import tempfile
from pathlib import Path

from postproc.compensation.streaming import STREAM_BYTES
from compensate_speed import REPO, in_memory, make_cam_program, regex_pass, run_cli

def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--targets", type=int, nargs="+", default=[1_000_000, 10_000_000])
    parser.add_argument("--model", default=str(REPO / "models" / "default.onnx"))
    parser.add_argument("--compare", action="store_true", help="also: the in-memory path on the smallest size")
    args = parser.parse_args()
    for n in sorted(args.targets):
        with tempfile.TemporaryDirectory() as tmp:
            tmp = Path(tmp)
            big = tmp / "bench.src"
            make_cam_program(big, n)
            size_mb = big.stat().st_size / 1e6
            regex_s = regex_pass(big, tmp / "regex.src")
            (tmp / "regex.src").unlink()
            wall, peak = run_cli(["compensate", str(big), "-o", str(tmp / "out.src"), "--model", args.model, "-q"])
            how = "streaming" if big.stat().st_size > STREAM_BYTES else "in-memory (below the size to stream)"
            print(f"{n:>11,} targets, {size_mb:7.1f} MB: compensate, {how}, {wall:7.1f} s, peak RSS {peak:5,.0f} MB "
                  f"(goal <= 300); regex pass {regex_s:6.1f} s; ratio {wall / regex_s:.2f}x", flush=True)
            if args.compare and n == min(args.targets):
                mem_wall, mem_peak = in_memory(big, tmp / "memory.src", args.model)
                same = filecmp.cmp(tmp / "out.src", tmp / "memory.src", shallow=False)
                print(f"{'':>11}  in-memory path: {mem_wall:7.1f} s, peak RSS {mem_peak:5,.0f} MB; "
                      f"same bytes as streaming: {same}", flush=True)


if __name__ == "__main__":
    main()

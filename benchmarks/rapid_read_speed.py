"""Read speed of the ABB RAPID reader (motion IR + analysis) on generated programs, against a
baseline checkout, in one run.

    python benchmarks/rapid_read_speed.py [--targets 20000] [--repeat 3] [--baseline DIR]

Two styles of ``benchmarks/dialect_read_speed.py``: a CAM module of inline robtargets (one
``MoveRun``) and a RobotStudio module of declared robtargets (one declaration and one motion
statement each, through the analysis). Each program is read in a fresh process by this tree
and, with ``--baseline DIR`` (another revision: ``git archive REV | tar -x -C DIR``), by that
tree, alternately, best of ``--repeat``; the figures are the times, the targets per second, the
cost per statement of this tree (lowered statements: declarations + motions) and the ratio to
the baseline (> 1: slower). Writes ``benchmarks/results/rapid_read_speed.json``.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from _common import ROOT, load, record

from dialect_read_speed import rapid_declared, rapid_inline

CHILD = """
import json, sys, time
from postproc.programs import read_program
text = open(sys.argv[1], encoding="latin-1").read()
start = time.perf_counter()
program = read_program([sys.argv[2]], [text], "rapid")
print(json.dumps({"seconds": time.perf_counter() - start, "targets": len(program.targets)}))
"""


def _time(tree: Path, path: Path, name: str) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree), OMP_NUM_THREADS="1")
    run = subprocess.run([sys.executable, "-c", CHILD, str(path), name], capture_output=True, text=True, env=env,
                         cwd=tree)
    if run.returncode:
        raise SystemExit(f"reading {name} with {tree} failed:\n{run.stderr[-2000:]}")
    return json.loads(run.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--targets", type=int, default=20_000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--baseline", type=Path, help="a checkout of the revision to compare with")
    args = parser.parse_args()
    figures: dict = {"targets": args.targets}
    with tempfile.TemporaryDirectory(prefix="postproc-rapid-") as tmp:
        for style, make, name, statements in (("inline", rapid_inline, "cam.mod", 1),
                                              ("declared", rapid_declared, "big.mod", 2)):
            path = Path(tmp) / name
            path.write_text(make(args.targets), encoding="latin-1")
            best = {"this": float("inf"), "baseline": float("inf")}
            for _ in range(args.repeat):
                for which, tree in (("this", ROOT), ("baseline", args.baseline)):
                    if tree is None:
                        continue
                    got = _time(tree, path, name)
                    if got["targets"] != args.targets:
                        raise SystemExit(f"{which} read {got['targets']} targets of {name}, not {args.targets}")
                    best[which] = min(best[which], got["seconds"])
            entry = {"seconds": round(best["this"], 3), "targets_per_s": round(args.targets / best["this"]),
                     "us_per_statement": round(1e6 * best["this"] / (statements * args.targets), 1)}
            if args.baseline is not None:
                entry["baseline_seconds"] = round(best["baseline"], 3)
                entry["ratio_to_baseline"] = round(best["this"] / best["baseline"], 2)
            figures[style] = entry
            print(f"{style:9s} {args.targets:>8,} targets  {best['this']:6.2f} s  "
                  f"{entry['targets_per_s']:>8,} targets/s  "
                  f"{entry['us_per_statement']:6.1f} µs/statement"
                  + (f"  baseline {best['baseline']:6.2f} s  ratio {entry['ratio_to_baseline']:.2f}"
                     if args.baseline is not None else ""))
    figures["load"] = load()
    print(f"results: {record('rapid_read_speed', figures)}")


if __name__ == "__main__":
    main()

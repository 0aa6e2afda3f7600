"""This checkout's `postproc compensate` against another checkout's on one CAM program, in one run.

    python benchmarks/compensate_ab.py BEFORE [--targets 1000000] [--rounds 2]

BEFORE is a directory holding another version of the repository (e.g. `git worktree add
/tmp/before 8837e3d`). Both versions compensate the same generated CAM program
(compensate_speed.make_cam_program) with their own shipped default model, alternately, each
process's CPU time (user + sys, os.wait4) measured; a plain regex pass over the program (read,
rewrite X/Y/Z, write) runs before each as the yardstick of this machine's speed at that moment.
The machine is shared and its speed varies 2×: the figures are the minimum of the rounds, and
what counts is the ratio of the two versions (and each one's ratio to the regex pass). The
outputs must be the same program bar the stamp's model hash (printed). Issue 24: the motion IR
and its analysis must not make the CAM path slower.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import ROOT, record  # noqa: E402  (benchmarks/ is on sys.path when run as a script)
from compensate_speed import make_cam_program, regex_pass  # noqa: E402

def cpu_seconds(repo: Path, src: Path, out: Path) -> float:
    """CPU seconds of `postproc compensate SRC -o OUT -q` run from ``repo`` (its own package)."""
    env = {**os.environ, "PYTHONPATH": str(repo)}
    proc = subprocess.Popen([sys.executable, "-m", "postproc", "compensate", str(src), "-o", str(out), "-q"],
                            cwd=repo, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    if os.waitstatus_to_exitcode(status) not in (0, 1):
        raise SystemExit(f"{repo}: postproc compensate failed:\n{proc.stderr.read().decode()}")
    return usage.ru_utime + usage.ru_stime


def regex_cpu(src: Path, out: Path) -> float:
    """CPU seconds of compensate_speed's regex pass (the floor of any rewriter)."""
    t0 = time.process_time()
    regex_pass(src, out)
    return time.process_time() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("before", type=Path, help="another checkout of the repository")
    ap.add_argument("--targets", type=int, default=1_000_000)
    ap.add_argument("--rounds", type=int, default=2)
    args = ap.parse_args()
    versions = {"before": args.before.resolve(), "this": ROOT}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        src = tmp / "cam.src"
        make_cam_program(src, args.targets)
        seconds: dict = {"before": [], "this": [], "regex": []}
        for r in range(args.rounds):
            for name, repo in versions.items():
                seconds["regex"].append(regex_cpu(src, tmp / "regex.src"))
                seconds[name].append(cpu_seconds(repo, src, tmp / f"{name}.src"))
                print(f"round {r + 1}: {name} {seconds[name][-1]:.2f} s CPU (regex pass {seconds['regex'][-1]:.2f} s)",
                      flush=True)
        outputs = [(tmp / f"{name}.src").read_text().splitlines() for name in versions]
        same = [a for a in outputs[0] if not a.startswith("; postproc:")] == \
            [b for b in outputs[1] if not b.startswith("; postproc:")]
    best = {k: min(v) for k, v in seconds.items()}
    figures = {"targets": args.targets, "rounds": args.rounds, "before": str(args.before),
               "cpu_s": {k: round(v, 2) for k, v in best.items()},
               "ratio_to_regex": {k: round(best[k] / best["regex"], 2) for k in versions},
               "this_over_before": round(best["this"] / best["before"], 3), "same_output_bar_stamp": same}
    print(f"{args.targets:,} LIN targets, min of {args.rounds} rounds: before {best['before']:.2f} s, this "
          f"{best['this']:.2f} s CPU ({figures['this_over_before']:.3f}×); to the regex pass "
          f"{figures['ratio_to_regex']['before']}× and {figures['ratio_to_regex']['this']}×; same output bar the "
          f"stamp: {same}")
    record("compensate_ab", figures)


if __name__ == "__main__":
    main()

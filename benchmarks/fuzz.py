"""Mutation fuzzing of `postproc compensate` on the sample corpus (the engine: postproc/testing/fuzz.py).

    python benchmarks/fuzz.py [--mutants 10000] [--seed 0] [--subprocess 50] [--timeout 10] [--keep DIR]
                              [--dialect krl|poses|rapid|urscript|fanuc]

Prints the outcome counts (see postproc.testing.fuzz for what each outcome means); exit 1 if any
mutant crashed, gave a wrong output or hung. With --keep, the offending mutants are saved.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from _common import record

from postproc.testing.fuzz import corpus, fuzz


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mutants", type=int, default=10_000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--subprocess", type=int, default=50, help="how many mutants also run as a real process")
    parser.add_argument("--timeout", type=float, default=10.0, help="seconds per mutant before it counts as a hang")
    parser.add_argument("--keep", type=Path, help="save crashing / wrong / hanging mutants here")
    parser.add_argument("--dialect", help="only the samples of this dialect (krl, poses, rapid, urscript, fanuc)")
    args = parser.parse_args()
    samples = corpus()
    if args.dialect:
        from postproc.programs.io import dialect_of

        samples = [s for s in samples if dialect_of(s.name) == args.dialect]
    start = time.perf_counter()
    counts, codes, bad = fuzz(args.mutants, args.seed, args.subprocess, args.timeout, args.keep, samples)
    wall = time.perf_counter() - start
    print(f"corpus: {len(samples)} programs ({', '.join(s.name for s in samples)})")
    print(f"mutants tried: {args.mutants:,} (seed {args.seed}; {counts['subprocess']} also as a subprocess) "
          f"in {wall:.0f} s")
    print(f"clean outputs (exit 0, round-trips): {counts['output']:,}")
    print(f"clean errors (exit 2, path:line:col: CODE message, nothing written): {counts['error']:,}")
    print(f"crashes: {counts['crash']}  wrong outputs: {counts['wrong']}  hangs: {counts['hang']}  "
          f"reader/formatter bugs caught by the last check (P190): {counts['caught']}")
    print("error codes: " + ", ".join(f"{c} {n}" for c, n in sorted(codes.items())))
    name = "fuzz" + (f"-{args.dialect}" if args.dialect else "")
    record(name, {"mutants": args.mutants, "seed": args.seed, "subprocess": counts["subprocess"],
                    "outputs": counts["output"], "errors": counts["error"], "crashes": counts["crash"],
                    "wrong": counts["wrong"], "hangs": counts["hang"], "caught": counts["caught"],
                    "wall_s": round(wall, 1), "codes": dict(sorted(codes.items()))})
    for where, outcome in bad[:20]:
        print(f"  {outcome.kind}: {where}: {outcome.detail}")
    if bad:
        sys.exit(1)


if __name__ == "__main__":
    main()

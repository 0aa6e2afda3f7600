"""The property "never silently wrong", checked at length: random programs (branches, loops,
jumps, calls with OUT parameters, copies with offsets, frame changes, code not read) compensated
with a model whose correction varies over space and with where the robot comes from, then the
original and the compensated program run by the IR's interpreter over several oracles' paths
(``postproc.testing.oracle.check``). Prints how many programs, paths and executed targets were
looked at and every violation; writes benchmarks/results/interpreter.json.

    python benchmarks/interpreter.py --examples 300 --seeds 4
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings

from _common import record
from postproc.compensator import load_model
from postproc.programs import ActiveFrames
from postproc.testing.generate import krl_programs
from postproc.testing.models import affine_model
from postproc.testing.oracle import check


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--examples", type=int, default=300)
    parser.add_argument("--seeds", type=int, default=4, help="oracles (paths) per program")
    parser.add_argument("--depth", type=int, default=3, help="nesting of the random statements")
    args = parser.parse_args()
    gain = np.array([[2e-3, 5e-4, 0.0], [0.0, 1.5e-3, 4e-4], [3e-4, 0.0, 2.5e-3]])
    with tempfile.TemporaryDirectory() as tmp:
        model = load_model(affine_model(Path(tmp) / "m.onnx", offset=(0.2, -0.1, 0.15), gain=gain,
                                        previous_gain=5e-5, tool={"name": "any"}))
    stated = ActiveFrames(base=0, tool="model")
    totals = dict(programs=0, paths=0, motions=0, compensated=0, untouched=0, refused=0, violations=0)
    examples: list = []
    t0 = time.perf_counter()

    @settings(max_examples=args.examples, deadline=None, suppress_health_check=list(HealthCheck), database=None)
    @given(krl_programs(depth=args.depth))
    def run(program):
        files, texts, config = program
        checked = check(files, texts, "krl", model, config=config, active=stated, seeds=range(args.seeds))
        totals["programs"] += 1
        totals["paths"] += checked.paths
        totals["motions"] += checked.motions
        totals["compensated"] += checked.compensated
        totals["untouched"] += checked.untouched
        totals["refused"] += checked.exit_code == 2
        if checked.violations:
            totals["violations"] += 1
            examples.append({"program": texts[0], "data": texts[1], "violations": checked.violations[:3]})

    try:
        run()
    except Exception as exc:  # (a crash is a finding too)
        examples.append({"crash": repr(exc)})
    seconds = time.perf_counter() - t0
    print(f"KRL: {totals['programs']} programs, {totals['paths']} paths, {totals['motions']} executed targets "
          f"({totals['compensated']} compensated, {totals['untouched']} left as written), {totals['refused']} refused; "
          f"{totals['violations']} programs with a violation; {seconds:.0f} s")
    for e in examples[:5]:
        print(e)
    record("interpreter", dict(totals, seconds=round(seconds, 1), examples=args.examples, seeds=args.seeds,
                               depth=args.depth, first_violations=examples[:5]))


if __name__ == "__main__":
    main()

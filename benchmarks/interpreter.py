"""The property "never silently wrong", checked at length on every dialect: random programs
(KRL, RAPID, URScript, Fanuc LS: branches, loops, jumps, calls with OUT / INOUT parameters,
copies with offsets, frame changes, displacements, code not read — ``postproc.testing.generate``)
compensated with a model whose correction varies over space and with where the robot comes from,
then the original and the compensated program run by the IR's interpreter over several oracles'
paths (``postproc.testing.oracle.check``). Prints per dialect how many programs, paths and executed
targets were looked at and the violations; writes benchmarks/results/interpreter.json.

    python benchmarks/interpreter.py --dialect all --examples 200 --seeds 4
    python benchmarks/interpreter.py --joints      (KRL with S/T on PTP and CP motions, a model of the joints)
    python benchmarks/interpreter.py --loads       (KRL whose payload changes, a model that takes the load)

``--joints``: KRL programs whose points and literal targets write S/T (a LIN's the controller
ignores, a PTP's it reads), compensated with a model E = G·sin(q) of the controller's joint
angles; the check evaluates it at the configuration the controller really runs on each path
(results: interpreter_joints.json).

``--loads`` (issue 33): KRL programs whose payload changes between the motions ($LOAD, $LOAD.M,
BAS(#TOOL, n) with LOAD_DATA, code not read; in branches and loops), compensated with a model
whose correction varies over space and with the mass; every executed target must be at P + Ê for
the payload the run carries there — the world's where the analysis does not know it — or be left
(results: interpreter_loads.json).
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings

from _common import record
from postproc.model.compensator import load_model
from postproc.testing.generate import dialect_cases, krl_programs
from postproc.testing.models import affine_model, joint_model
from postproc.testing.oracle import check

DIALECTS = ("krl", "rapid", "urscript", "fanuc")
# E = G·sin(q), mm: each coordinate of the correction a function of some joints (--joints)
JOINT_GAIN = np.array([[0.0, 0.3, 0.0, 0.4, 0.0, 0.5], [0.2, 0.0, 0.0, 0.0, 0.6, 0.0], [0.0, 0.0, 0.3, 0.0, 0.0, 0.4]])


def bench(dialect: str, model, examples: int, seeds: int, depth: int, dump: str | None = None,
          configurations: bool = False, loads: bool = False) -> dict:
    programs, active = dialect_cases(dialect, depth)
    if configurations or loads:
        programs = krl_programs(depth, configurations=configurations, loads=loads)
    totals = dict(programs=0, paths=0, motions=0, compensated=0, untouched=0, refused=0, violations=0)
    found: list = []
    t0 = time.perf_counter()

    @settings(max_examples=examples, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck), database=None)
    @given(programs)
    def run(program):
        files, texts, config = program
        checked = check(files, texts, dialect, model, config=config, active=active, seeds=range(seeds))
        totals["programs"] += 1
        totals["paths"] += checked.paths
        totals["motions"] += checked.motions
        totals["compensated"] += checked.compensated
        totals["untouched"] += checked.untouched
        totals["refused"] += checked.exit_code == 2
        if checked.violations:
            totals["violations"] += 1
            found.append({"files": files + ["config"], "program": texts, "config": config, "violations": checked.violations[:3]})

    try:
        run()
    except Exception as exc:  # (a crash is a finding too)
        found.append({"crash": repr(exc)})
    seconds = time.perf_counter() - t0
    print(f"{dialect}: {totals['programs']} programs, {totals['paths']} paths, {totals['motions']} executed targets "
          f"({totals['compensated']} compensated, {totals['untouched']} left as written), {totals['refused']} refused; "
          f"{totals['violations']} programs with a violation; {seconds:.0f} s")
    for k, e in enumerate(found):
        print(e.get("crash") or "\n  ".join(e["violations"]))
        if dump and "program" in e:
            for name, text in zip(e["files"], e["program"] + (e["config"] or [])):
                Path(dump, f"{dialect}_{k}_{name}").write_text(text)
    return dict(totals, seconds=round(seconds, 1), first_violations=found[:5])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dialect", choices=DIALECTS + ("all",), default="all")
    parser.add_argument("--examples", "--programs", type=int, default=200, help="programs per dialect")
    parser.add_argument("--seeds", type=int, default=4, help="oracles (paths) per program")
    parser.add_argument("--depth", type=int, default=3, help="nesting of the random statements")
    parser.add_argument("--dump", help="a directory: each program with a violation written there")
    parser.add_argument("--previous-gain", type=float, default=5e-5,
                        help="how much the model's correction depends on where the robot comes from (mm per mm): "
                             "larger makes a wrong predecessor show (5e-4: 0.1 mm over 200 mm)")
    parser.add_argument("--joints", action="store_true",
                        help="KRL with S/T, a model of the controller's joint angles (module text)")
    parser.add_argument("--loads", action="store_true",
                        help="KRL whose payload changes, a model that takes the load (module text)")
    args = parser.parse_args()
    if args.loads:
        with tempfile.TemporaryDirectory() as tmp:
            model = load_model(affine_model(Path(tmp) / "l.onnx", offset=(0.2, -0.1, 0.15),
                                            gain=np.diag([2e-3, 1.5e-3, 2.5e-3]), previous_gain=args.previous_gain,
                                            tool={"name": "any"}, load_gain=np.diag([2e-4, 5e-4, 0.0]),
                                            load_offset=(0.1, 0.05, -0.2)))
        results = {"krl": bench("krl", model, args.examples, args.seeds, args.depth, args.dump, loads=True)}
        record("interpreter_loads", dict(dialects=results, examples=args.examples, seeds=args.seeds, depth=args.depth))
        return
    if args.joints:
        with tempfile.TemporaryDirectory() as tmp:
            model = load_model(joint_model(Path(tmp) / "j.onnx", JOINT_GAIN,
                                           tool={"name": "spindle", "frame": [300, 0, 75, 0, 0, 0]}))
        results = {"krl": bench("krl", model, args.examples, args.seeds, args.depth, args.dump, configurations=True)}
        record("interpreter_joints", dict(dialects=results, examples=args.examples, seeds=args.seeds, depth=args.depth))
        return
    gain = np.array([[2e-3, 5e-4, 0.0], [0.0, 1.5e-3, 4e-4], [3e-4, 0.0, 2.5e-3]])
    with tempfile.TemporaryDirectory() as tmp:
        model = load_model(affine_model(Path(tmp) / "m.onnx", offset=(0.2, -0.1, 0.15), gain=gain,
                                        previous_gain=args.previous_gain, tool={"name": "any"}))
    chosen = DIALECTS if args.dialect == "all" else (args.dialect,)
    results = {d: bench(d, model, args.examples, args.seeds, args.depth, args.dump) for d in chosen}
    record("interpreter" if args.previous_gain == 5e-5 else "interpreter_approach",
           dict(dialects=results, examples=args.examples, seeds=args.seeds, depth=args.depth,
                previous_gain=args.previous_gain))


if __name__ == "__main__":
    main()

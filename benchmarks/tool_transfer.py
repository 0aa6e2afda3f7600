"""Any tool: how well a hybrid model compensates a program with another $TOOL than the data
were measured with, on the default simulated robot, for data of one, two and three tools.

Per data set: `postproc measure PLAN --tool A [--tool B ...]` (the plan in consecutive parts,
one tool each), `postproc train` (hybrid), then two KRL programs over the same fresh poses,
one with the description's tool and one with OTHER_TOOL, compensated and run on the simulated
robot (`verify`, tracker noise included). Prints the mean error before / after, the ratio
other / training tool (the issue's goal: ≤ 1.5) and the P319 warnings of the other tool.

Then the cost of the ``tool`` input: the same fitted model exported with and without it,
``Compensator.predict`` over 100,000 poses (best of 3, one thread), and their ratio.

    python benchmarks/tool_transfer.py [N_POSES]
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

from postproc.cli import main as cli
from postproc.compensation.pipeline import compensate_program
from postproc.programs.io import parse_program_text
from postproc.model.compensator import load_model
from postproc.calibration.planning import latin_hypercube, plan_csv_text
from postproc.robot.arm import Robot
from postproc.calibration.simulator import SimulatedRobot

OTHER_TOOL = np.array([180.0, 30.0, 160.0, 0.0, 0.0, 0.0])
LONGER = np.array([450.0, 0.0, 75.0, 0.0, 0.0, 0.0])  # the description's (300, 0, 75), 150 mm along A6
SIDEWAYS = np.array([300.0, 0.0, 200.0, 0.0, 0.0, 0.0])


def _krl(poses: np.ndarray, tool: np.ndarray) -> str:
    lines = ["DEF part( )", "$BASE = {X 0, Y 0, Z 0, A 0, B 0, C 0}",
             "$TOOL = {" + ", ".join(f"{k} {v:g}" for k, v in zip("XYZABC", tool)) + "}"]
    lines += [f"PTP {{X {p[0]:.3f}, Y {p[1]:.3f}, Z {p[2]:.3f}, A {p[3]:.4f}, B {p[4]:.4f}, C {p[5]:.4f}}}"
              for p in poses]
    return "\n".join(lines + ["END", ""])


def _run(sim: SimulatedRobot, model, poses: np.ndarray, tool: np.ndarray) -> tuple[float, float, int]:
    program = parse_program_text(_krl(poses, tool), "part.src")
    report = compensate_program(program, model)
    out = parse_program_text(report.outputs[program.files[0]], "part.src")
    result = sim.verify(poses, out.targets.poses, rng_seed=1, tools=np.tile(tool, (len(poses), 1)))
    return result["before"]["mean"], result["after"]["mean"], sum(d.code == "P319" for d in report.warnings)


def main(n: int = 400) -> None:
    sim = SimulatedRobot()
    robot = sim.robot
    tools_all = [robot.tool, LONGER, SIDEWAYS, OTHER_TOOL]
    poses = latin_hypercube(n, seed=3)
    poses = poses[np.logical_and.reduce([Robot(robot.description.replace(tool=t)).ik(poses)[1] for t in tools_all])]
    targets = latin_hypercube(150, seed=11)
    targets = targets[np.logical_and.reduce([Robot(robot.description.replace(tool=t)).ik(targets)[1]
                                             for t in tools_all])]
    print(f"{len(poses)} measured poses, {len(targets)} program targets; other tool {OTHER_TOOL[:3].tolist()}")
    print(f"{'data':<34} {'training tool mm':>18} {'other tool mm':>16} {'ratio':>6} {'P319':>5}")
    with tempfile.TemporaryDirectory() as tmp:
        plan = Path(tmp) / "plan.csv"
        plan.write_text(plan_csv_text(poses))
        for label, tools in (("one tool (description's)", [robot.tool]),
                             ("two: + 150 mm along A6", [robot.tool, LONGER]),
                             ("three: + along A6, + sideways", [robot.tool, LONGER, SIDEWAYS])):
            measured, onnx = Path(tmp) / "m.csv", Path(tmp) / "m.onnx"
            args = sum((["--tool", ",".join(f"{v:g}" for v in t)] for t in tools), [])
            assert cli(["measure", str(plan), "-o", str(measured), "-q", *args]) == 0
            assert cli(["train", str(measured), "-o", str(onnx), "-q"]) == 0
            model = load_model(onnx)
            b0, a0, _ = _run(sim, model, targets, robot.tool)
            b1, a1, warned = _run(sim, model, targets, OTHER_TOOL)
            print(f"{label:<34} {b0:7.3f} -> {a0:6.3f}  {b1:6.3f} -> {a1:6.3f} {a1 / a0:6.2f} {warned:5d}")


def speed(n: int = 100_000) -> None:
    import time

    from postproc.model.training.export import onnx_bytes
    from postproc.model.training.features import previous_poses
    from postproc.model.training.hybrid import HybridModel, _WithJoints

    sim = SimulatedRobot()
    robot = sim.robot
    poses = latin_hypercube(300, seed=5)
    model = HybridModel(robot.description, residual="none").fit(
        poses, poses[:, :3] - sim.measure(poses, rng_seed=0), previous_poses(poses))
    meta = {"name": "speed", "robot": robot.name, "method": model.label, "structure": model.structure,
            "envelope": model.envelope_, "iterations": 2}
    targets = latin_hypercube(n, seed=1)
    tools = np.tile(robot.tool, (n, 1))
    best = {}
    with tempfile.TemporaryDirectory() as tmp:
        for with_tool in (False, True):
            path = Path(tmp) / f"{with_tool}.onnx"
            path.write_bytes(onnx_bytes(_WithJoints(model.module_, with_tool), meta, True, joints=True,
                                        joints_input=True, approach_input=True, tool_input=with_tool))
            compensator = load_model(path)
            feed = {"tool": tools} if with_tool else {}
            compensator.predict(targets[:1000], **{k: v[:1000] for k, v in feed.items()})
            times = []
            for _ in range(3):
                start = time.perf_counter()
                compensator.predict(targets, **feed)
                times.append(time.perf_counter() - start)
            best[with_tool] = min(times)
    print(f"predict {n} poses: without the tool input {best[False]:.3f} s, with it {best[True]:.3f} s, "
          f"ratio {best[True] / best[False]:.2f}")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:]))
    speed()

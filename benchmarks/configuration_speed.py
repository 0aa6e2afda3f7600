"""Speed of the arm-configuration step (postproc.robot.configuration): the joint angles the controller
uses, for N targets of a LIN path (one S/T stated, the rest keep the configuration; also with every
branch FK-checked up front, the way before the lazy check, and the ratio of the two) and for N
targets that each state S/T, on the nominal KR500-sim; and the uncompensated error of the
default simulated robot in the HOME branch, the flipped wrist and another tool.

    python benchmarks/configuration_speed.py [N]
"""
from __future__ import annotations

import sys
import time

import numpy as np
from _common import record

from postproc.robot import configuration as cf
from postproc.robot import conventions as cv
from postproc.calibration.planning import latin_hypercube, plan_configurations
from postproc.robot.arm import Robot
from postproc.calibration.simulator import SimulatedRobot


def main(n: int = 100_000) -> None:
    robot = Robot()
    rng = np.random.default_rng(0)
    q = np.array([10.0, -70, 100, 20, 40, 30]) + np.cumsum(rng.normal(0, 0.05, (n, 6)), axis=0)
    q = np.clip(q, robot.limits[:, 0] + 1, robot.limits[:, 1] - 1)
    poses = robot.fk(q)
    s, t = robot.status_turn(q)
    unstated = np.full(n, cv.UNSTATED)
    s0, t0 = unstated.copy(), unstated.copy()
    s0[0], t0[0] = s[0], t[0]
    start = time.perf_counter()
    got, ok = cf.controller_joints(robot, poses, s0, t0, np.zeros(n, bool))
    lin = time.perf_counter() - start
    start = time.perf_counter()
    got2, ok2 = cf.stated_joints(robot, poses, s, t)
    stated = time.perf_counter() - start
    # the same LIN path with every branch FK-checked up front (the way before the lazy check)
    start = time.perf_counter()
    ref, ok_ref = cf.controller_joints(robot, poses, s0, t0, np.zeros(n, bool), check_all=True)
    full = time.perf_counter() - start
    print(f"{n} LIN targets, one S/T stated: {lin:.2f} s ({1e6 * lin / n:.0f} µs/target), all found {ok.all()}, "
          f"max |q - true| {np.abs(got - q).max():.1e}°")
    print(f"{n} LIN targets, every branch FK-checked: {full:.2f} s ({1e6 * full / n:.0f} µs/target): "
          f"lazy check {full / lin:.2f}× faster, same results {np.array_equal(ref, got) and np.array_equal(ok_ref, ok)}")
    print(f"{n} targets with S/T: {stated:.2f} s ({1e6 * stated / n:.0f} µs/target), all found {ok2.all()}")

    sim = SimulatedRobot()
    plan = latin_hypercube(2000, seed=5)
    home, ok_home = plan_configurations(sim.robot, plan, "home")
    flipped, ok_flip = cf.stated_joints(sim.robot, plan, home[:, 0] ^ 4, np.full(len(plan), cv.UNSTATED))
    keep = ok_home & ok_flip
    plan, flipped = plan[keep], flipped[keep]
    tool = np.array([180.0, 30.0, 160.0, 0, 0, 0])
    arm = Robot(sim.robot.description.replace(tool=tool))
    q_tool, ok_tool = arm.ik(plan)
    rows = {
        "HOME branch, spindle": sim.actual_positions(plan),
        "flipped wrist, spindle": sim.actual_positions(plan, q_deg=flipped),
    }
    errors = {k: np.linalg.norm(plan[:, :3] - v, axis=1) for k, v in rows.items()}
    errors[f"HOME branch, tool {tool[:3].tolist()}"] = np.linalg.norm(
        plan[ok_tool, :3] - sim.actual_positions(plan[ok_tool], q_deg=q_tool[ok_tool],
                                                 tools=np.tile(tool, (int(ok_tool.sum()), 1))), axis=1)
    for label, e in errors.items():
        print(f"uncompensated, default robot, {label}: mean {e.mean():.3f} max {e.max():.3f} mm ({len(e)} poses)")
    record("configuration_speed", {
        "targets": n, "lin_s": round(lin, 3), "lin_us_per_target": round(1e6 * lin / n, 2),
        "checked_s": round(full, 3), "lazy_speedup": round(full / lin, 3), "stated_s": round(stated, 3),
        "stated_us_per_target": round(1e6 * stated / n, 2),
        "uncompensated_mean_mm": {label: round(float(e.mean()), 4) for label, e in errors.items()},
    })


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 100_000)

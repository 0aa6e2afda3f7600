"""End to end on the simulated robot: a hybrid model trained on both wrist configurations
compensates a program in the flipped-wrist configuration (with S/T) and one with another
$TOOL as accurately as the training configuration and tool (within 1.5×), measured by verify.

The model is trained here by ``postproc train`` (the hybrid default, which takes the
controller's joint angles and the TCP: contract inputs ``joints`` and ``tool``) on data measured
with two tools (``postproc measure --tool A --tool B``: the plan in two parts), the
description's and one 150 mm longer along the A6 axis: one tool cannot separate the tool
mount's rotation from a shift of the TCP (the model would carry it as a shift: 6.6x the
training tool's residual at OTHER_TOOL on this robot), two can except about the line
between their TCPs.

Every case is compensated to about a twentieth of its error (0.731 -> 0.035 mm for the training
configuration), as on data of one configuration: the approach directions come from the data's
joint angles of the row before (the plan changes the wrist between rows) and the program's
previous target's joints (``previous_joints``: A4 and A6 cross ±180° between flipped targets).
"""
import os

import numpy as np
import pytest

from postproc.robot import configuration as cf
from postproc.robot import conventions as cv
from postproc.cli import main
from postproc.compensation.pipeline import compensate_program
from postproc.programs.io import parse_program_text
from postproc.model.compensator import load_model
from postproc.calibration.planning import latin_hypercube, plan_configurations, plan_csv_text
from postproc.robot.arm import Robot
from postproc.calibration.simulator import SimulatedRobot


OTHER_TOOL = np.array([180.0, 30.0, 160.0, 0.0, 0.0, 0.0])
SECOND_TOOL = np.array([450.0, 0.0, 75.0, 0.0, 0.0, 0.0])  # the description's (300, 0, 75), longer


def _pose_list(poses, config):
    return plan_csv_text(poses, config)


def _krl(poses, config, tool):
    lines = ["DEF part( )", "$BASE = {X 0, Y 0, Z 0, A 0, B 0, C 0}",
             "$TOOL = {" + ", ".join(f"{k} {v:g}" for k, v in zip("XYZABC", tool)) + "}"]
    for p, (s, t) in zip(poses, config):
        lines.append(f"PTP {{X {p[0]:.3f}, Y {p[1]:.3f}, Z {p[2]:.3f}, A {p[3]:.4f}, B {p[4]:.4f}, "
                     f"C {p[5]:.4f}, S {s}, T {t}}}")
    return "\n".join(lines + ["END", ""])


def _verified(sim, program, report, tools):
    out = parse_program_text(report.outputs[program.files[0]], program.files[0])
    t = program.targets
    commands = out.targets.poses.copy()
    result = sim.verify(t.poses, commands, rng_seed=1, config=np.asarray(t.config, int),
                        tools=np.tile(tools, (len(t), 1)), motions=t.motion)
    return result["before"]["mean"], result["after"]["mean"]


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """The simulated robot and a hybrid model trained by ``postproc train`` on a few hundred
    rows over both wrist configurations, half with the description's tool, half with SECOND_TOOL."""
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    tmp_path = tmp_path_factory.mktemp("e2e")
    sim = SimulatedRobot()
    robot = sim.robot
    poses = latin_hypercube(400, seed=3)
    config, ok = plan_configurations(robot, poses, "both")
    poses, config = poses[ok], config[ok]
    ok = sim.reachable_in(poses, config, np.tile(SECOND_TOOL, (len(poses), 1)))  # (either tool may measure it)
    poses, config = poses[ok], config[ok]
    plan = tmp_path / "plan.csv"
    plan.write_text(plan_csv_text(poses, config))
    measured = tmp_path / "m.csv"
    tools = [",".join(f"{v:g}" for v in tool) for tool in (robot.tool, SECOND_TOOL)]
    assert main(["measure", str(plan), "-o", str(measured), "-q", "--tool", tools[0], "--tool", tools[1]]) == 0
    model_path = tmp_path / "robot.onnx"
    assert main(["train", str(measured), "-o", str(model_path), "-q"]) == 0
    model = load_model(model_path)
    assert model.wants_joints and model.wants_tool
    return sim, model


def _accuracy(sim, model, cases_wanted):
    robot = sim.robot
    # programs over fresh poses: the training configuration, the flipped wrist, another tool
    targets = latin_hypercube(120, seed=11)
    home, ok_home = plan_configurations(robot, targets, "home")
    flipped, ok_flip = cf.stated_joints(robot, targets, home[:, 0] ^ 4, np.full(len(targets), cv.UNSTATED))
    arm = Robot(robot.description.replace(tool=OTHER_TOOL))
    tool_q, ok_tool = arm.ik(targets)
    keep = ok_home & ok_flip & ok_tool
    targets = targets[keep]
    flipped_config = np.stack(cv.status_turn_of(robot, flipped[keep]), axis=1)
    tool_config = np.stack(cv.status_turn_of(arm, tool_q[keep]), axis=1)
    cases = {
        "training": (_pose_list(targets, home[keep]), "t.csv", robot.tool),
        "flipped": (_pose_list(targets, flipped_config), "f.csv", robot.tool),
        "tool": (_krl(targets, tool_config, OTHER_TOOL), "part.src", OTHER_TOOL),
    }
    after = {}
    for label in cases_wanted:
        text, name, tool = cases[label]
        program = parse_program_text(text, name)
        report = compensate_program(program, model)
        assert report.compensated == len(targets), (label, report.warnings[:3])
        before, after[label] = _verified(sim, program, report, tool)
        assert after[label] < 0.1 * before, (label, before, after[label])
    return after


@pytest.mark.slow
def test_a_flipped_wrist_with_s_t_is_compensated_as_well_as_the_training_configuration(trained):
    sim, model = trained
    after = _accuracy(sim, model, ["training", "flipped"])
    assert after["flipped"] <= 1.5 * after["training"], after


def test_another_tool_is_compensated_as_well_as_the_training_tool(trained):
    sim, model = trained
    after = _accuracy(sim, model, ["training", "tool"])
    assert after["tool"] <= 1.5 * after["training"], after

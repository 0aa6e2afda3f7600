"""The nominal robot: description file, FK against hand-computed poses, IK (against Pinocchio: test_kinematics)."""
import math

import numpy as np
import pytest

from postproc.core import frames
from postproc.core.diagnostics import PostprocError
from postproc.calibration.planning import latin_hypercube
from postproc.robot.arm import Robot
from postproc.robot.description import load_description, parse_description
from postproc.core.resources import model_path

# KR 500-class datasheet dimensions the description is built from (mm)
A1_A2_OFFSET, BASE_HEIGHT, UPPER_ARM, FOREARM, FOREARM_OFFSET, WRIST_TO_FLANGE = 500, 1045, 1300, 1025, -55, 290
TOOL_X, TOOL_Z = 300, 75  # models/kr500.toml's $TOOL: 300 mm along the flange X, 75 mm off-axis


@pytest.fixture(scope="module")
def robot():
    return Robot()


def test_zero_configuration_by_hand(robot):
    # q = 0: the arm stretched forward along +X, every frame parallel to the base
    reach_x = A1_A2_OFFSET + UPPER_ARM + FOREARM + WRIST_TO_FLANGE + TOOL_X
    z = BASE_HEIGHT + FOREARM_OFFSET + TOOL_Z
    np.testing.assert_allclose(robot.fk(np.zeros((1, 6)))[0], [reach_x, 0, z, 0, 0, 0], atol=1e-9)


def test_a1_plus_90_turns_clockwise_seen_from_above(robot):
    # KUKA's A1 turns about -Z: +90° takes the stretched arm from +X to -Y, A = -90°
    reach_x = A1_A2_OFFSET + UPPER_ARM + FOREARM + WRIST_TO_FLANGE + TOOL_X
    z = BASE_HEIGHT + FOREARM_OFFSET + TOOL_Z
    np.testing.assert_allclose(robot.fk([[90, 0, 0, 0, 0, 0]])[0], [0, -reach_x, z, -90, 0, 0], atol=1e-9)


def test_home_and_tool_pointing_down_by_hand(robot):
    # HOME: upper arm vertical, forearm horizontal, flange facing +X
    wrist = np.array([A1_A2_OFFSET + FOREARM, 0, BASE_HEIGHT + UPPER_ARM + FOREARM_OFFSET])
    home = robot.fk([[0, -90, 90, 0, 0, 0]])[0]
    np.testing.assert_allclose(home, [*(wrist + [WRIST_TO_FLANGE + TOOL_X, 0, TOOL_Z]), 0, 0, 0], atol=1e-9)
    # A5 = +90 bends the wrist down: the tool's X points to -Z, its Z to +X → A 0, B 90, C 0
    down = robot.fk([[0, -90, 90, 0, 90, 0]])[0]
    np.testing.assert_allclose(down[:3], wrist + [TOOL_Z, 0, -WRIST_TO_FLANGE - TOOL_X], atol=1e-9)
    np.testing.assert_allclose(down[3:], [0, 90, 0], atol=1e-9)
    r = frames.rotation_from_abc(down[3:])
    np.testing.assert_allclose(r[:, 0], [0, 0, -1], atol=1e-12)  # tool X (working direction) down
    np.testing.assert_allclose(r[:, 2], [1, 0, 0], atol=1e-12)  # tool Z away from the robot


def test_fk_of_ik_round_trips_in_the_box(robot):
    poses = latin_hypercube(2000, seed=5)
    q, ok = robot.ik(poses)
    assert ok.all()
    back = robot.fk_matrix(q)
    target = frames.frame_to_matrix(poses)
    assert np.abs(back[:, :3, 3] - target[:, :3, 3]).max() < 1e-6  # mm
    assert np.abs(back[:, :3, :3] - target[:, :3, :3]).max() < 1e-9
    # every pose in the box on the same, natural branch: elbow up, wrist bent down (A5 > 0)
    status, _ = robot.status_turn(q)
    assert set(status.tolist()) == {0b010}
    assert np.all((q[:, 1] < -20) & (q[:, 2] > 40) & (q[:, 4] > 0))


def test_ik_of_fk_returns_the_configuration_nearest_the_reference(robot):
    rng = np.random.default_rng(2)
    q = robot.limits.mean(axis=1) + rng.uniform(-0.4, 0.4, (300, 6)) * np.ptp(robot.limits, axis=1)
    q_back, ok = robot.ik(robot.fk(q), reference_q=q)
    assert ok.all()
    np.testing.assert_allclose(q_back, q, atol=1e-7)
    # the flipped wrist reaches the same pose: asked near it, IK returns it
    flipped = np.array([[10.0, -60.0, 100.0, 180.0 - 20.0, -40.0, 180.0 - 30.0]])
    straight = np.array([[10.0, -60.0, 100.0, -20.0, 40.0, -30.0]])
    np.testing.assert_allclose(robot.fk_matrix(flipped), robot.fk_matrix(straight), atol=1e-9)
    np.testing.assert_allclose(robot.ik(robot.fk(straight), reference_q=flipped[0])[0], flipped, atol=1e-7)
    np.testing.assert_allclose(robot.ik(robot.fk(straight))[0], straight, atol=1e-7)


def test_unreachable_poses_are_flagged_not_guessed(robot):
    poses = np.array([[5000.0, 0, 1000, 0, 90, 0], [2000, 0, 900, 0, 90, 0], [0, 0, 100, 0, 90, 0]])
    q, ok = robot.ik(poses)
    assert ok.tolist() == [False, True, False]
    assert np.isnan(q[0]).all() and np.isfinite(q[1]).all()


def test_reach_sphere_is_conservative(robot):
    q = np.random.default_rng(3).uniform(robot.limits[:, 0], robot.limits[:, 1], (5000, 6))
    reach = robot.reach
    r = np.linalg.norm(robot.fk(q)[:, :3] - reach["center"], axis=1)
    assert r.max() <= reach["radius_max"] and r.min() >= reach["radius_min"]
    assert reach["radius_max"] - r.max() < 200  # conservative, not useless


def test_gravity_torques_by_hand_for_the_payload(robot):
    # stretched arm, no links: A2 holds each mass at its horizontal lever; use the payload alone
    light = Robot(robot.description.replace(
        joints=tuple(j.__class__(j.name, j.origin, j.axis, j.limits, 0.0, j.com) for j in robot.description.joints)))
    d = light.description
    tau = light.gravity_torques(np.zeros((1, 6)))[0]
    com_x = A1_A2_OFFSET + UPPER_ARM + FOREARM + WRIST_TO_FLANGE + d.payload_com[0]
    # A2 turns about +Y: a weight in front of it pulls towards +A2 (down); the motors hold it
    # with the opposite torque, g(q) of M·q̈ + C·q̇ + g(q) = τ
    assert tau[1] == pytest.approx(-d.payload_mass * 9.81 * (com_x - A1_A2_OFFSET) / 1000, rel=1e-3)
    assert tau[0] == pytest.approx(0.0, abs=1e-9)  # a vertical axis carries no gravity


def test_description_errors_point_at_the_line(tmp_path):
    text = model_path("kr500.toml").read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace('mass = 480.0', 'mass = 480.0\nlenght = 3'))
    with pytest.raises(PostprocError) as info:
        load_description(bad)
    line = text.replace('mass = 480.0', 'mass = 480.0\nlenght = 3').splitlines().index("lenght = 3") + 1
    assert (info.value.code, info.value.line, info.value.path) == ("P331", line, str(bad))
    assert "unknown key 'lenght' in [joint]" in info.value.message
    with pytest.raises(PostprocError, match="must be a list of 3 finite numbers") as info:
        parse_description(text.replace("axis = [0.0, 1.0, 0.0]", "axis = [0.0, 1.0]", 1), "x.toml")
    assert info.value.code == "P332" and info.value.line > 0
    with pytest.raises(PostprocError, match="not valid TOML") as info:
        parse_description(text + "\n[oops\n", "x.toml")
    assert info.value.line == len(text.splitlines()) + 2
    with pytest.raises(PostprocError, match="unknown table"):
        parse_description(text + "\n[wokspace]\nbox = 1\n", "x.toml")


def test_description_round_numbers_match_the_datasheet():
    d = load_description()
    o = np.array([j.origin[:3] for j in d.joints])
    assert (o[1, 0], o[1, 2]) == (A1_A2_OFFSET, BASE_HEIGHT)
    assert o[2, 0] == UPPER_ARM and o[3, 0] + o[4, 0] == FOREARM and o[3, 2] == FOREARM_OFFSET
    assert o[5, 0] + d.flange[0] == WRIST_TO_FLANGE
    assert d.payload_mass == 300 and math.isclose(d.workspace["range"], 10)

"""Kinematic identification (postproc.model.training.kinematic) and the torch arm it runs on.

The measurements come from code the identification does not share: postproc.robot.arm's numpy
chain of a *perturbed* description (link lengths, joint zero offsets), and the simulator's
own backlash / gear-ripple model with every other error switched off, all noise-free.
"""
from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest
import torch

from postproc.calibration.planning import latin_hypercube
from postproc.robot.arm import Robot
from postproc.robot.description import load_description, parse_description
from postproc.robot.kinematics.twin import Arm, KukaIK, UrIK
from postproc.model.training.kinematic import choose_branch
from postproc.model.training.features import motion_signs, previous_joints, previous_poses
from postproc.model.training.kinematic import KinematicModel

from helpers import REPO


@pytest.fixture(scope="module")
def kr500():
    return load_description()


@pytest.fixture(scope="module")
def poses():
    return latin_hypercube(300, seed=3)


def test_torch_arm_matches_the_numpy_chain_and_pinocchio(kr500, poses):
    robot, arm = Robot(kr500), Arm(kr500)
    q_deg, ok = robot.ik(poses)
    assert ok.all()
    rot, org, tcp = arm.frames(torch.as_tensor(np.radians(q_deg)))
    assert np.abs(tcp.numpy() - poses[:, :3]).max() < 1e-9
    pytest.importorskip("pinocchio")
    tau = arm.gravity_torques(rot, org).numpy()[:40]
    expected = robot.gravity_torques(q_deg[:40])
    assert np.abs(tau - expected).max() < 1e-6 * np.abs(expected).max()


def test_kuka_ik_branch_is_the_controllers(kr500, poses):
    q_deg, _ = Robot(kr500).ik(poses)
    ik, share = choose_branch(kr500, poses, q_deg)
    assert isinstance(ik, KukaIK) and share == 1.0
    with torch.no_grad():
        q = ik(torch.as_tensor(poses)).numpy()
    step = (np.degrees(q) - q_deg + 180.0) % 360.0 - 180.0  # turns are not unwrapped
    assert np.abs(step).max() < 1e-4


def test_ur_ik_inverts_the_forward_kinematics():
    ur10 = load_description(REPO / "models" / "ur10.toml")
    arm = Arm(ur10)
    q = torch.as_tensor(np.random.default_rng(0).uniform(-math.pi, math.pi, (200, 6)))
    rot, _, tcp = arm.frames(q)
    from postproc.core.frames import abc_from_rotation

    pose = torch.cat([tcp, torch.as_tensor(abc_from_rotation((rot[:, -1] @ arm.end[:3, :3]).numpy()))], dim=1)
    ik, share = choose_branch(ur10, pose.numpy(), np.degrees(q.numpy()), family="ur")
    assert isinstance(ik, UrIK)
    # random configurations lie on all 8 branches: each row is solved by the branch it is on
    solved = np.zeros(len(q), bool)
    for branch in UrIK.branches():
        with torch.no_grad():
            got = UrIK(ur10, branch)(pose)
        back = arm.tcp(got)
        solved |= (torch.linalg.norm(back - tcp, dim=1) < 1e-3).numpy()
        same = (torch.abs(torch.remainder(got - q + math.pi, 2 * math.pi) - math.pi) < 1e-4).all(dim=1).numpy()
        assert (torch.linalg.norm(back - tcp, dim=1).numpy()[same] < 1e-3).all()
    assert solved.all()
    assert 0.05 < share < 0.5  # the best single branch holds a share of random configurations


def test_motion_signs_fill_and_deadband():
    q = torch.tensor([[0.0, 1.0], [0.1, 1.0], [0.05, 1.0], [0.05, 1.2]])
    prev = torch.cat([torch.zeros(1, 2), q[:-1]])
    assert motion_signs(q, prev).tolist() == [[0, 1], [1, 0], [-1, 0], [0, 1]]
    assert motion_signs(q, prev, fill=True).tolist() == [[0, 1], [1, 1], [-1, 1], [-1, 1]]
    # a step across ±π is a small step, not a turn
    assert motion_signs(torch.tensor([[-3.1]]), torch.tensor([[3.1]])).tolist() == [[1.0]]


def _perturbed(description, joint_shift: dict[int, np.ndarray]):
    joints = list(description.joints)
    for j, shift in joint_shift.items():
        joints[j] = dataclasses.replace(joints[j], origin=joints[j].origin + np.r_[shift, 0.0, 0.0, 0.0])
    return description.replace(joints=tuple(joints))


def test_recovers_injected_zero_offsets(kr500, poses):
    zero = np.array([0.01, 0.02, -0.03, 0.025, 0.015, -0.02])  # deg
    q_deg, _ = Robot(kr500).ik(poses)
    measured = Robot(kr500).fk(q_deg + zero)[:, :3]
    # noise-free data: a negligible prior (the default 1e-3 mm² per σ² biases A6, which the TCP
    # sees only through its 75 mm offset from the A6 axis, by 2e-4°)
    km = KinematicModel(kr500, groups=("zero",), ripple=[], prior=1e-6).fit(poses, poses[:, :3] - measured)
    assert np.degrees(km.parameters()["zero"]) == pytest.approx(zero, abs=1e-6)


def test_recovers_injected_link_lengths(kr500, poses):
    # the "real" robot: upper arm 0.8 mm longer, A2 0.5 mm higher. (A shift of A4 across the
    # forearm is not identifiable apart: turning A3's placement and A4's back by the same angle
    # moves A4's origin the same way; the fit splits it, predicting right, test below.)
    shifts = {2: np.array([0.8, 0.0, 0.0]), 1: np.array([0.0, 0.0, 0.5])}
    real = Robot(_perturbed(kr500, shifts))
    q_deg, _ = Robot(kr500).ik(poses)
    km = KinematicModel(kr500, groups=("placement",), ripple=[], prior=1e-6).fit(poses, poses[:, :3] - real.fk(q_deg)[:, :3])
    offset = km.parameters()["placement"][:, 3:]  # [joint, xyz] mm, in each joint's frame (parallel at q = 0)
    assert offset[2, 0] == pytest.approx(0.8, abs=1e-3)  # A3's origin along X: the upper arm
    # A1 turns about Z: moving A1 or A2 up is one and the same, and the fit splits it
    assert offset[0, 2] + offset[1, 2] == pytest.approx(0.5, abs=1e-3)


def test_predicts_a_perturbed_robot_exactly(kr500, poses):
    real = Robot(_perturbed(kr500, {2: np.array([0.8, 0.0, 0.2]), 3: np.array([0.0, 0.0, -0.3]),
                                    4: np.array([-0.4, 0.0, 0.0])}))
    zero = np.array([0.0, 0.02, -0.03, 0.0, 0.015, 0.0])
    q_deg, _ = Robot(kr500).ik(poses)
    km = KinematicModel(kr500, ripple=[]).fit(poses, poses[:, :3] - real.fk(q_deg + zero)[:, :3])
    fresh = latin_hypercube(100, seed=9)
    truth = fresh[:, :3] - real.fk(Robot(kr500).ik(fresh)[0] + zero)[:, :3]
    assert np.abs(km.predict(fresh) - truth).max() < 1e-3


def _sim_with(kr500, errors: str):
    """The simulator with only the errors given ([errors] table replaced, no noise)."""
    from postproc.calibration.simulator import SimulatedRobot

    text = re.sub(r"\[errors\].*", "[errors]\nseed = 4\n" + errors, kr500.text, flags=re.S)
    return SimulatedRobot(parse_description(text, kr500.path))


def test_recovers_backlash_from_the_visiting_order(kr500):
    sim = _sim_with(kr500, "backlash_deg = [0.015, 0.012, 0.012, 0.02, 0.02, 0.02]\nbacklash_spread = 0.2\n")
    train = latin_hypercube(300, seed=1)
    errors = sim.true_error(train)
    km = KinematicModel(kr500, ripple=[]).fit(train, errors, previous_poses(train))
    # half the lost motion, per joint (the joint lags behind its motion by half of it)
    assert np.degrees(km.parameters()["backlash"]) == pytest.approx(sim.backlash_deg / 2, abs=3e-4)
    held = latin_hypercube(100, seed=2)
    assert np.abs(km.predict(held, previous_poses(held)) - sim.true_error(held)).max() < 2e-3
    # without the order the same errors are noise to a pose-only model
    pose_only = KinematicModel(kr500, ripple=[]).fit(train, errors)
    assert np.linalg.norm(pose_only.predict(held) - sim.true_error(held), axis=1).mean() > 0.1


def test_backlash_signs_follow_the_data_joints_across_a_wrist_flip(kr500):
    """A plan with ``--wrist both`` flips the wrist every other pair of rows: at every second
    row the previous row is in the other configuration (A4, A6 about 180° away, A5 mirrored), so
    the approach directions come from the data's joint angles of that row, not from its pose
    solved on this row's branch."""
    from postproc.calibration.planning import plan_configurations
    from postproc.robot.approach import approach_signs

    sim = _sim_with(kr500, "backlash_deg = [0.015, 0.012, 0.012, 0.02, 0.02, 0.02]\nbacklash_spread = 0.2\n")
    train = latin_hypercube(300, seed=1)
    config, ok = plan_configurations(sim.robot, train, "both")
    train, config = train[ok], config[ok]
    q = sim.joint_angles(train, config)
    assert (np.diff(np.sign(q[:, 4])) != 0).mean() > 0.45  # (the wrist does flip at every second row)
    errors = train[:, :3] - sim.actual_positions(train, q_deg=q)
    km = KinematicModel(kr500, ripple=[]).fit(train, errors, previous_poses(train), q, None, previous_q_deg=previous_joints(q))
    assert (km.train_signs_ == approach_signs(q, sim.robot.home_q)).all()
    assert np.linalg.norm(km.train_residual_, axis=1).max() < 2e-3
    # and a program in one configuration is predicted as well: the plan also steps within each
    # configuration, so A5's approach direction is not the configuration (its backlash would be
    # one with its zero offset: a mirrored A5 turns the offset's sign as a flipped approach does)
    held = latin_hypercube(100, seed=2)
    assert np.abs(km.predict(held, previous_poses(held)) - sim.true_error(held)).max() < 2e-3


def test_ripple_search_finds_the_gear_order(kr500):
    amplitudes = "[[0.0, 0.003], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]]"
    sim = _sim_with(kr500, f"ripple_orders = [1, 36]\nripple_deg = {amplitudes}\n")
    train = latin_hypercube(400, seed=1)
    km = KinematicModel(kr500).fit(train, sim.true_error(train))
    found = [pick for pick, _ in km.ripple_search_]
    assert found[0] == (0, 36)  # A1, 36 per turn
    held = latin_hypercube(100, seed=2)
    # the orders are fitted on top of the physical model, which keeps what the gear order's
    # columns share with the geometry on these 400 poses (it does not lean on the orders:
    # test_ripple_orders_leave_the_physical_fit_alone): not exact, but most of the ripple goes
    physical = KinematicModel(kr500, ripple=[]).fit(train, sim.true_error(train))
    left = np.abs(km.predict(held) - sim.true_error(held)).max()
    assert left < 0.04 and left < 0.3 * np.abs(physical.predict(held) - sim.true_error(held)).max()


def test_poses_out_of_reach_are_refused(kr500):
    from postproc.core.diagnostics import PostprocError

    far = latin_hypercube(40, seed=0)
    far[:, 0] += 5000.0
    with pytest.raises(PostprocError, match="out of reach") as err:
        KinematicModel(kr500).fit(far, np.zeros((40, 3)))
    assert err.value.code == "P508"


def test_fewer_coordinates_than_parameters_are_refused(kr500):
    """A 2-row file would give a model worse than none: refused (P505), naming the rows needed."""
    from postproc.core.diagnostics import PostprocError

    with pytest.raises(PostprocError, match="at least 26 poses") as err:
        KinematicModel(kr500, ripple=[]).fit(latin_hypercube(2, seed=0), np.zeros((2, 3)))
    assert err.value.code == "P505"


def test_ripple_orders_leave_the_physical_fit_alone(kr500):
    """Gear-ripple orders are fitted on top of the physical model, which stays as fitted without
    them: outside the trained joint ranges (where the graph leaves the gear-mesh orders out) the
    model is the physical one, not geometry that leaned on ripple terms. The prior of the fit
    is a Gaussian one at the residual variance the physical fit leaves."""
    amplitudes = "[[0.0, 0.003], [0.0, 0.0], [0.0, 0.002], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]]"
    sim = _sim_with(kr500, "zero_offset_deg = 0.04\njoint_position_mm = 0.5\n"
                    f"ripple_orders = [1, 36]\nripple_deg = {amplitudes}\n")
    train = latin_hypercube(300, seed=1)
    errors = train[:, :3] - sim.measure(train, rng_seed=1)  # (with tracker noise)
    physical = KinematicModel(kr500, ripple=[]).fit(train, errors)
    searched = KinematicModel(kr500).fit(train, errors)
    assert searched.ripple_search_ and searched.layout_.ripple  # the gear mesh is found ...
    n = physical.layout_.n
    assert np.array_equal(searched.theta_[:n], physical.theta_)  # ... and the physical part is untouched
    residual = physical.train_residual_.reshape(-1)
    assert physical.prior_ == pytest.approx(residual @ residual / (len(residual) - n), rel=0.05)
    held = latin_hypercube(100, seed=2)
    truth = sim.true_error(held)
    better = np.linalg.norm(searched.predict(held) - truth, axis=1).mean()
    assert better < 0.5 * np.linalg.norm(physical.predict(held) - truth, axis=1).mean()

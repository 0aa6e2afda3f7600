"""The model of the robot in any arm configuration: the IK branch read from the controller's
joint angles, the contract's ``joints`` input, training on the real joint angles, the envelope's
fall-back to the physical part and rows that do not fit (issue 11)."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from postproc.core import frames
from postproc.model.compensator import load_model
from postproc.robot.description import load_description
from postproc.robot.kinematics.twin import Arm, make_ik
from postproc.model.training.hybrid import HybridModel
from postproc.model.training.kinematic import KinematicErrorModule, Layout

KR500 = load_description()
UR10 = load_description("models/ur10.toml")


def fk_poses(arm: Arm, q: torch.Tensor) -> np.ndarray:
    """Poses [N, 6] (mm, KUKA A,B,C) of the nominal arm at q [N, 6] rad."""
    with torch.no_grad():
        rot, _, tcp = arm.frames(q)
        r = (rot[:, -1] @ arm.end[:3, :3]).numpy()
    return np.c_[tcp.numpy(), frames.abc_from_rotation(r)]


def reachable(description, branch, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """n poses and their IK [N, 6] rad on ``branch`` (rows the branch really reaches)."""
    arm = Arm(description)
    rng = np.random.default_rng(seed)
    home = np.radians(description.home_q)
    q0 = torch.as_tensor(home + rng.uniform(-0.6, 0.6, (4 * n, 6)))
    poses = fk_poses(arm, q0)
    ik = make_ik(description, branch=branch)
    with torch.no_grad():
        q = ik(torch.as_tensor(poses))
        back = fk_poses(arm, q)
    ok = np.linalg.norm(back[:, :3] - poses[:, :3], axis=1) < 1e-2
    ok &= np.abs(np.sin(q[:, 4].numpy())) > 0.1  # away from the wrist singularity
    return poses[ok][:n], q.numpy()[ok][:n]


@pytest.mark.parametrize("description", [KR500, UR10], ids=["kuka", "ur"])
def test_ik_follows_the_branch_of_the_given_joints(description):
    """Every branch's angles, given as ``q_in``, come back from the one IK module: the branch is
    read from the angles, row by row (NaN rows: the module's own branch)."""
    ik0 = make_ik(description)
    poses, _ = reachable(description, ik0.branch, 60, seed=1)
    pose = torch.as_tensor(poses)
    seen = 0
    for branch in ik0.branches():
        with torch.no_grad():
            q_b = make_ik(description, branch=branch)(pose)
            back = fk_poses(Arm(description), q_b)
            ok = torch.as_tensor(np.linalg.norm(back[:, :3] - poses[:, :3], axis=1) < 1e-2)
            ok &= torch.abs(torch.sin(q_b[:, 4])) > 0.05
            if not ok.any():
                continue
            seen += 1
            got = ik0(pose[ok], q_b[ok] + 0.01)  # (angles near, not at, the branch's solution)
            assert torch.allclose(torch.remainder(got - q_b[ok] + np.pi, 2 * np.pi) - np.pi,
                                  torch.zeros_like(got), atol=1e-4)
    assert seen >= 4
    with torch.no_grad():
        nan = torch.full((len(pose), 6), float("nan"), dtype=torch.float64)
        assert torch.allclose(ik0(pose, nan), ik0(pose))


def true_arm(description, seed: int) -> KinematicErrorModule:
    """A 'real' robot: the nominal arm with random joint placements and zero offsets."""
    layout = Layout(("placement", "zero"))
    rng = np.random.default_rng(seed)
    theta = np.r_[np.tile(np.r_[np.full(3, 1e-3), np.full(3, 0.5)], 6) * rng.standard_normal(36),
                  1e-3 * rng.standard_normal(6)]
    arm = Arm(description)
    return KinematicErrorModule(arm, make_ik(description), layout, theta, use_previous=False)


def test_hybrid_model_in_the_flipped_wrist_configuration(tmp_path):
    """Trained on one wrist configuration with the joint angles, the model predicts the error of
    the other configuration when given its joints (the error there differs: another q), through
    the library and the exported ONNX graph alike; without the joints it uses the trained branch."""
    truth = true_arm(KR500, seed=4)
    main = make_ik(KR500).branch
    flipped = (main[0], main[1], -main[2])
    poses, q = reachable(KR500, main, 300, seed=2)
    with torch.no_grad():
        errors = truth.error_at(torch.as_tensor(q), torch.zeros_like(torch.as_tensor(q)),
                                torch.as_tensor(poses[:, :3])).numpy()
    model = HybridModel(KR500, residual="none", kinematic={"ripple": [], "groups": ("placement", "zero")})
    model.fit(poses, errors, None, np.degrees(q))

    test_poses, _ = reachable(KR500, main, 80, seed=3)
    with torch.no_grad():
        q_flip = make_ik(KR500, branch=flipped)(torch.as_tensor(test_poses))
        e_flip = truth.error_at(q_flip, torch.zeros_like(q_flip), torch.as_tensor(test_poses[:, :3])).numpy()
    assert np.abs(e_flip - errors[:1]).max() > 0.1  # a field that varies: not a constant offset
    given = model.predict(test_poses, joints=np.degrees(q_flip.numpy()))
    assert np.abs(given - e_flip).max() < 0.02
    assert np.abs(model.predict(test_poses) - e_flip).max() > 0.1  # the trained branch: another error

    path = model.export_onnx(tmp_path / "flip.onnx", name="flip")
    comp = load_model(path)
    assert comp.wants_joints and comp.has_joints
    onnx_given, q_out = comp.predict(test_poses, joints=np.degrees(q_flip.numpy()), with_joints=True)
    assert np.abs(onnx_given - given).max() < 1e-3
    assert np.abs(np.sin(np.radians(q_out[:, 4])) - np.sin(q_flip[:, 4].numpy())).max() < 1e-4
    # the fixed point with the targets' joints: the commands put the (flipped) robot on target
    commands = comp.command(test_poses, 4, joints=np.degrees(q_flip.numpy()))
    c_pose = np.c_[commands, test_poses[:, 3:]]
    with torch.no_grad():
        q_c = make_ik(KR500, branch=flipped)(torch.as_tensor(c_pose))
        landed = c_pose[:, :3] - truth.error_at(q_c, torch.zeros_like(q_c), torch.as_tensor(c_pose[:, :3])).numpy()
    assert np.abs(landed - test_poses[:, :3]).max() < 0.02
    assert np.abs(commands - test_poses[:, :3]).max() > 0.1


def test_learned_parts_fall_back_outside_the_trained_joint_ranges():
    """Ripple orders do not extrapolate: outside the trained joint ranges the model keeps only
    its physical part (the ripple's contribution is gone, the geometry's stays)."""
    truth = true_arm(KR500, seed=5)
    poses, q = reachable(KR500, make_ik(KR500).branch, 300, seed=6)
    with torch.no_grad():
        errors = truth.error_at(torch.as_tensor(q), torch.zeros_like(torch.as_tensor(q)),
                                torch.as_tensor(poses[:, :3])).numpy()
    model = HybridModel(KR500, residual="none", kinematic={"ripple": [(0, 7)], "groups": ("placement", "zero")})
    model.fit(poses, errors, None, np.degrees(q))
    module = model.module_.kinematic
    with torch.no_grad():
        module.theta[-2:] = torch.tensor([2e-3, 1e-3], dtype=torch.float64)  # a sizeable ripple on A1
    inside = model.predict(poses[:5])
    wide = np.array(model.joint_range_)
    far = poses[:5].copy()
    far[:, :2] = -far[:, :2]  # A1 turned by 180°: outside the trained range of A1
    with torch.no_grad():
        q_far = make_ik(KR500)(torch.as_tensor(far)).numpy()
    a1 = np.degrees(q_far[:, 0])
    assert ((a1 < wide[0, 0] - 10) | (a1 > wide[0, 1] + 10)).all()
    p = module.layout.unpack(module.theta)
    with torch.no_grad():
        full = module.error_at(torch.as_tensor(q_far), torch.zeros(5, 6, dtype=torch.float64),
                               torch.as_tensor(far[:, :3])).numpy()
        no_ripple = module.error_at(torch.as_tensor(q_far), torch.zeros(5, 6, dtype=torch.float64),
                                    torch.as_tensor(far[:, :3]), torch.zeros(5, dtype=torch.float64)).numpy()
    assert np.abs(full - no_ripple).max() > 0.5  # the ripple matters there ...
    assert np.allclose(model.predict(far), no_ripple, atol=1e-9)  # ... and is left out
    assert p["ripple"].abs().sum() > 0 and np.abs(inside - model.predict(poses[:5])).max() == 0


def test_a_few_unreachable_rows_are_dropped_and_named():
    """One row off the arm among hundreds: dropped (its index in ``dropped_``), not a P508 abort."""
    truth = true_arm(KR500, seed=7)
    poses, q = reachable(KR500, make_ik(KR500).branch, 200, seed=8)
    with torch.no_grad():
        errors = truth.error_at(torch.as_tensor(q), torch.zeros_like(torch.as_tensor(q)),
                                torch.as_tensor(poses[:, :3])).numpy()
    poses[17, :3] = [9000.0, 0.0, 9000.0]  # out of reach
    model = HybridModel(KR500, residual="none", kinematic={"ripple": [], "groups": ("placement", "zero")})
    model.fit(poses, errors)
    assert list(model.dropped_) == [17]
    keep = np.arange(len(poses)) != 17
    assert np.abs(model.predict(poses[keep]) - errors[keep]).max() < 0.02


def test_ur_ik_at_the_wrist_singularity_keeps_the_given_a6():
    """A5 at 0° or 180° (the UR10's HOME): only A4 ± A6 is defined; with the controller's angles
    the IK returns them (A6 kept, A4 the rest), and the nominal arm lands on the pose."""
    arm = Arm(UR10)
    q = torch.tensor([[-90.0, -90, 0, -90, 0, 0], [-90.0, -90, 0, -90, 0, 30], [10, -80, 40, -60, 180, 20],
                      [10, -80, 40, -60, 0.003, 20]], dtype=torch.float64) * np.pi / 180
    poses = torch.as_tensor(fk_poses(arm, q))
    with torch.no_grad():
        got = make_ik(UR10)(poses, q)
        miss = torch.linalg.norm(arm.tcp(got) - poses[:, :3], dim=1)
    assert miss.max() < 1e-3
    assert torch.allclose(got, q, atol=1e-5)


def test_measurements_in_metres_are_refused_and_outliers_named():
    from postproc.core.diagnostics import PostprocError
    from postproc.model.training.data import check_errors

    rng = np.random.default_rng(0)
    positions = rng.uniform(500, 2000, (50, 3))
    lines = np.arange(50) + 2
    with pytest.raises(PostprocError, match="x_meas, y_meas, z_meas are in metres") as err:
        check_errors(positions, positions / 1000.0, lines, "m.csv")
    assert err.value.code == "P517"  # (the unit named: postproc.core.units, the one check)
    with pytest.raises(PostprocError, match="another frame") as err:  # (not metres: another frame)
        check_errors(positions, positions + [300.0, -80.0, 20.0], lines, "m.csv")
    assert err.value.code == "P509"
    measured = positions - rng.normal(0, 0.5, (50, 3))
    assert check_errors(positions, measured, lines) == []
    measured[7] += 40.0
    (warning,) = check_errors(positions, measured, lines)
    assert "line(s) 9" in warning


def test_identified_parameters_are_in_the_model_card(tmp_path):
    """The ONNX file keeps the identified parameters (the card's identified.parameters), so a
    later re-calibration can start from them."""
    truth = true_arm(KR500, seed=9)
    poses, q = reachable(KR500, make_ik(KR500).branch, 150, seed=10)
    with torch.no_grad():
        errors = truth.error_at(torch.as_tensor(q), torch.zeros_like(torch.as_tensor(q)),
                                torch.as_tensor(poses[:, :3])).numpy()
    model = HybridModel(KR500, residual="none", kinematic={"ripple": [], "groups": ("placement", "zero", "tool")})
    model.fit(poses, errors, None, np.degrees(q))
    card = load_model(model.export_onnx(tmp_path / "p.onnx", identified=model.describe())).metadata
    stored = card["identified"]["parameters"]
    assert set(stored) == {"placement", "tool", "zero"}
    p = model.kinematic_.parameters()
    assert np.allclose(stored["placement"], p["placement"].ravel()) and np.allclose(stored["tool"], p["tool"])
    assert np.abs(p["placement"]).max() > 1e-4  # (something was identified)

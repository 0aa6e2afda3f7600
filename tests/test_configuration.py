"""S/T → joint angles (postproc.robot.configuration) on the nominal KUKA-type and UR-type arms."""
import numpy as np
import pytest

from postproc.robot import configuration as cf
from postproc.robot import conventions as cv
from postproc.core.resources import model_path
from postproc.robot.arm import Robot
from postproc.robot.description import load_description


@pytest.fixture(scope="module", params=["kr500.toml", "ur10.toml"])
def arm(request):
    return Robot(load_description(model_path(request.param)))


def _random_q(robot, n, seed):
    rng = np.random.default_rng(seed)
    lo, hi = robot.limits[:, 0], robot.limits[:, 1]
    return rng.uniform(0.9 * np.maximum(lo, -170), 0.9 * np.minimum(hi, 170), (n, 6))


def test_every_branch_round_trips_through_pinocchio(arm):
    q = _random_q(arm, 4000, 1)
    status, turn = arm.status_turn(q)
    assert set(status.tolist()) == set(range(8))  # all 8 branches are exercised
    got, ok = cf.stated_joints(arm, arm.fk(q), status, turn)
    assert ok.all()
    np.testing.assert_allclose(got, q, atol=1e-6)  # the very joint angles: branch and turn
    for s in range(8):
        rows = np.flatnonzero(status == s)[:5]
        back = arm.pin_fk(got[rows])  # Pinocchio, not postproc's own chain
        want = arm.fk_matrix(q[rows])
        assert np.abs(back[:, :3, 3] - want[:, :3, 3]).max() <= 1e-6
        assert np.abs(back[:, :3, :3] - want[:, :3, :3]).max() <= 1e-9
        assert (arm.status_turn(got[rows])[0] == s).all()


def test_other_branches_are_other_joint_angles_of_the_same_pose(arm):
    q = _random_q(arm, 300, 2)
    poses = arm.fk(q)
    status, _ = arm.status_turn(q)
    flipped = status ^ 4  # the other wrist
    got, ok = cf.stated_joints(arm, poses, flipped, np.full(len(q), cv.UNSTATED))
    assert ok.mean() > 0.5
    assert (arm.status_turn(got[ok])[0] == flipped[ok]).all()
    assert np.abs(got[ok] - q[ok]).max(axis=1).min() > 1.0  # really another configuration
    np.testing.assert_allclose(arm.fk(got[ok])[:, :3], poses[ok, :3], atol=1e-6)


def test_a_turn_no_solution_has_is_not_found():
    robot = Robot()  # KR500: A5 within ±118°, so T bit 4 must agree with S bit 2
    q = np.array([[10.0, -80.0, 100.0, 20.0, 40.0, 30.0]])
    status, turn = robot.status_turn(q)
    got, ok = cf.stated_joints(robot, robot.fk(q), status, turn ^ (1 << 4))
    assert not ok[0] and np.isnan(got[0]).all()
    got, ok = cf.stated_joints(robot, robot.fk(q), status, turn ^ (1 << 5))  # A6 −330°: another turn
    assert ok[0] and got[0, 5] == pytest.approx(30.0 - 360.0)


def test_lin_keeps_the_stated_configuration_and_moves_continuously(arm):
    q0 = _random_q(arm, 1, 3)[0]
    q0[4] = -40.0 if arm.family == "kuka" else q0[4]
    path = q0 + np.linspace(0.0, 1.0, 400)[:, None] * np.array([15.0, 8.0, -10.0, 200.0, 20.0, 250.0])
    lo, hi = arm.limits[:, 0], arm.limits[:, 1]
    path = path[((path >= lo) & (path <= hi)).all(axis=1)]
    status, turn = arm.status_turn(path[:1])
    s = np.full(len(path), cv.UNSTATED)
    t = np.full(len(path), cv.UNSTATED)
    s[0], t[0] = status[0], turn[0]
    got, ok = cf.controller_joints(arm, arm.fk(path), s, t, np.zeros(len(path), bool))
    assert ok.all()
    np.testing.assert_allclose(got, path, atol=1e-6)  # A4/A6 past ±180° on their own turn
    # the controller's own IK from HOME picks another branch or turn for many of these
    nominal, _ = arm.ik(arm.fk(path))
    assert np.abs(nominal - path).max() > 10.0


def test_ptp_without_status_takes_the_solution_nearest_the_previous_axis_position():
    robot = Robot()
    a = np.array([0.0, -70.0, 95.0, 170.0, -50.0, 160.0])  # flipped wrist, far from HOME's
    b = a + np.array([5.0, 3.0, -4.0, 2.0, -3.0, 4.0])
    poses = robot.fk(np.vstack([a, b]))
    s, t = robot.status_turn(a[None])
    got, ok = cf.controller_joints(robot, poses, [s[0], cv.UNSTATED], [t[0], cv.UNSTATED], [True, True])
    assert ok.all()
    np.testing.assert_allclose(got[1], b, atol=1e-6)
    # without anything stated the start position decides: from HOME the other wrist (A4 ≈ −10°)
    got, ok = cf.controller_joints(robot, poses, [cv.UNSTATED] * 2, [cv.UNSTATED] * 2, [True, True])
    assert (robot.status_turn(got)[0] & 4 == 0).all()
    got, ok = cf.controller_joints(robot, poses, [cv.UNSTATED] * 2, [cv.UNSTATED] * 2, [True, True], initial_q=a)
    np.testing.assert_allclose(got, np.vstack([a, b]), atol=1e-6)


def test_unreachable_targets_are_not_found_and_the_motion_restarts_after_them():
    robot = Robot()
    q = np.array([[0.0, -90.0, 90.0, 0.0, 45.0, 0.0], [5.0, -85.0, 85.0, 5.0, 40.0, 5.0]])
    poses = robot.fk(q)
    poses = np.vstack([poses[:1], [[9000.0, 0, 0, 0, 0, 0]], poses[1:]])
    got, ok = cf.controller_joints(robot, poses, [cv.UNSTATED] * 3, [cv.UNSTATED] * 3, [False] * 3)
    assert ok.tolist() == [True, False, True]
    np.testing.assert_allclose(got[[0, 2]], q, atol=1e-6)


def test_configuration_does_not_import_pinocchio_or_torch():
    import subprocess
    import sys

    code = ("import sys, numpy as np; from postproc.robot import configuration as cf; from postproc.robot.arm import Robot;"
            "r = Robot(); cf.controller_joints(r, r.fk([[0, -90, 90, 0, 45, 0]]), [-1], [-1], [False]);"
            "print('pinocchio' in sys.modules, 'torch' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["False", "False"]


def test_a_long_ptp_chain_from_home_takes_each_solution_nearest_the_previous_one():
    """PTP without S from HOME over 120 targets, as verify runs a program: every target's
    angles are the solution nearest the previous target's (what it would pick on its own from
    there), however long the chain of choices that depend on each other."""
    from postproc.calibration.planning import latin_hypercube

    robot = Robot()
    poses = latin_hypercube(120, seed=11)
    poses = poses[robot.ik(poses)[1]]
    n = len(poses)
    unstated = np.full(n, cv.UNSTATED)
    q, ok = cf.controller_joints(robot, poses, unstated, unstated, np.ones(n, bool), robot.home_q)
    assert ok.all()
    previous = np.vstack([robot.home_q, q[:-1]])
    one = np.full(1, cv.UNSTATED)
    alone = np.vstack([cf.controller_joints(robot, poses[i:i + 1], one, one, np.ones(1, bool), previous[i])[0]
                       for i in range(n)])
    np.testing.assert_allclose(q, alone, atol=1e-6)


def test_status_bits_above_the_arm_are_not_a_branch():
    """Real points state S 18 / 'B00010110' (bit 4 set beside bits 0-2): the branch is bits 0-2,
    for every S and T a program can write (a property over the whole 0…32767 range)."""
    from hypothesis import given, settings, strategies as st

    robot = Robot()
    q = _random_q(robot, 64, 11)
    poses = robot.fk(q)
    status, turn = robot.status_turn(q)
    plain, ok = cf.stated_joints(robot, poses, status, turn)
    assert ok.all()

    @settings(max_examples=60, deadline=None, derandomize=True)
    @given(st.integers(0, 32767 >> 3), st.integers(0, 32767 >> 6), st.integers(0, 63))
    def high_bits_change_nothing(s_high, t_high, row):
        s = np.array([status[row] | (s_high << 3)])
        t = np.array([turn[row] | (t_high << 6)])
        got, found = cf.stated_joints(robot, poses[row:row + 1], s, t)
        assert found[0]
        np.testing.assert_array_equal(got[0], plain[row])
        ptp = np.array([True])
        got, found = cf.controller_joints(robot, poses[row:row + 1], s, t, ptp)
        assert found[0]
        np.testing.assert_array_equal(got[0], plain[row])

    high_bits_change_nothing()


def test_a_program_stating_status_bit_4_is_compensated_on_its_branch(tmp_path):
    """``S 18`` is branch 2 (bit 4 set): compensated with branch 2's joint angles, as ``S 2``
    (was an IndexError), with a model of the joints (its correction varies with them)."""
    from postproc.compensation.api import compensate_text
    from postproc.testing.models import joint_model

    robot = Robot()
    q = np.array([[10.0, -80.0, 100.0, 20.0, 40.0, 30.0], [-5.0, -70.0, 95.0, -10.0, -35.0, 60.0]])
    poses = robot.fk(q)
    status, turn = robot.status_turn(q)
    model = joint_model(tmp_path / "m.onnx", gain=np.diag([0.4, -0.3, 0.5]) @ np.ones((3, 6)) / 6)

    def program(extra):
        lines = [f"PTP {{X {p[0]:.4f}, Y {p[1]:.4f}, Z {p[2]:.4f}, A {p[3]:.4f}, B {p[4]:.4f}, C {p[5]:.4f}, "
                 f"S {s | extra}, T {t}}}" for p, s, t in zip(poses, status, turn)]
        return "DEF p()\n$BASE = $NULLFRAME\n$TOOL = {X 300, Y 0, Z 75, A 0, B 0, C 0}\n" + "\n".join(lines) + "\nEND\n"

    plain, report = compensate_text(program(0), str(model), name="p.src")
    high, report_high = compensate_text(program(16), str(model), name="p.src")
    assert report_high.compensated == report.compensated == 2 and report_high.complete
    for s in status.tolist():
        high = high.replace(f"S {s | 16},", f"S {s},")
    assert high == plain and plain != program(0)

"""The configuration step's lazy FK check (only the picked branches checked) gives exactly the
results of the fully checked branch table, on random programs of both arm types."""
import numpy as np
import pytest

from postproc.robot import configuration as cf
from postproc.robot import conventions as cv
from postproc.core import frames
from postproc.core.resources import model_path
from postproc.robot.arm import Robot
from postproc.robot.description import load_description


@pytest.fixture(scope="module", params=["kr500.toml", "ur10.toml"])
def arm(request):
    return Robot(load_description(model_path(request.param)))


def _program(robot, n, seed):
    """A random program: joint-space walk with jumps, some unreachable poses, S/T stated on some
    targets, PTP/LIN/independent rows, two tools."""
    rng = np.random.default_rng(seed)
    lo, hi = robot.limits[:, 0], robot.limits[:, 1]
    steps = rng.normal(0, 2.0, (n, 6))
    steps[rng.random(n) < 0.05] *= 40.0  # jumps: other branches nearer
    q = np.clip(rng.uniform(0.5 * np.maximum(lo, -170), 0.5 * np.minimum(hi, 170)) + np.cumsum(steps, axis=0),
                0.95 * np.maximum(lo, -350), 0.95 * np.minimum(hi, 350))
    tool = np.array([120.0, -40.0, 210.0, 0.0, 30.0, 0.0])
    tools = np.where((rng.random(n) < 0.3)[:, None], tool, robot.tool)
    poses = np.empty((n, 6))
    for t in (tool, robot.tool):
        rows = (tools == t).all(axis=1)
        poses[rows] = Robot(robot.description.replace(tool=t)).fk(q[rows])
    poses[rng.random(n) < 0.03] = [9000.0, 0.0, 0.0, 0.0, 0.0, 0.0]  # unreachable
    s, t = robot.status_turn(q)
    s = np.where(rng.random(n) < 0.2, s, cv.UNSTATED)
    t = np.where((s >= 0) & (rng.random(n) < 0.5), t, cv.UNSTATED)
    return poses, s, t, rng.random(n) < 0.3, tools, rng.random(n) < 0.05


def _solve_both(robot, args):
    fast = cf.controller_joints(robot, *args)
    fast_stated = cf.stated_joints(robot, args[0], args[1], args[2], tools=args[5])
    # the straightforward reference: every branch of every pose FK-checked up front
    ref = cf.controller_joints(robot, *args, check_all=True)
    ref_stated = cf.stated_joints(robot, args[0], args[1], args[2], tools=args[5], check_all=True)
    return fast, ref, fast_stated, ref_stated


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_lazy_check_equals_the_fully_checked_table(arm, seed):
    poses, s, t, ptp, tools, alone = _program(arm, 400, seed)
    args = (poses, s, t, ptp, None, tools, alone)
    fast, ref, fast_stated, ref_stated = _solve_both(arm, args)
    assert ref[1].mean() > 0.5 and not ref[1].all()  # found and unreachable targets both present
    for got, want in ((fast, ref), (fast_stated, ref_stated)):
        np.testing.assert_array_equal(got[0], want[0])  # bit for bit, NaN where not found
        np.testing.assert_array_equal(got[1], want[1])


def test_picked_branches_that_fail_their_check_are_replaced_as_the_full_check_would(arm, monkeypatch):
    """A check that rejects some solutions (as one at the edge of reach would fail): the fast path
    meets the rejections only on what it picks, re-solves those rows and still equals the reference."""
    real = Robot.reaches

    def picky(self, q_deg, t_tcp):  # rejects ~1 solution in 4, by its angles (deterministic)
        return real(self, q_deg, t_tcp) & (np.floor(np.abs(q_deg[:, 3]) * 7.0) % 4 != 0)

    poses, s, t, ptp, tools, alone = _program(arm, 400, 7)
    args = (poses, s, t, ptp, None, tools, alone)
    plain = cf.controller_joints(arm, *args)
    monkeypatch.setattr(Robot, "reaches", picky)
    fast, ref, fast_stated, ref_stated = _solve_both(arm, args)
    changed = ~np.isclose(plain[0], ref[0], equal_nan=True).all(axis=1)
    assert changed.mean() > 0.05  # the rejections change the answer: the test can tell
    for got, want in ((fast, ref), (fast_stated, ref_stated)):
        np.testing.assert_array_equal(got[0], want[0])
        np.testing.assert_array_equal(got[1], want[1])


def _stated_one_by_one(robot, poses, s, t, tools):
    """stated_joints written plainly: per target, over the branches its S allows, the candidate
    on the turn its T states (else nearest HOME) nearest HOME."""
    table, ok = cf.branch_table(robot, poses, tools)
    home = robot.home_q
    q, found = np.full((len(poses), 6), np.nan), np.zeros(len(poses), bool)
    for i in range(len(poses)):
        best = np.inf
        for b in (range(8) if s[i] < 0 else [s[i]]):
            if not ok[b, i]:
                continue
            if t[i] >= 0:
                cand = cf._turn_for_sign(robot, table[b, i][None], np.array([t[i]]))[0]
                inside = np.isfinite(cand).all()
            else:
                cand, inside = robot.nearest_turn(table[b, i][None], home[None])
                cand, inside = cand[0], bool(inside[0]) and np.isfinite(cand).all()
            cost = ((cand - home) ** 2).sum()
            if inside and cost < best:
                best, q[i], found[i] = cost, cand, True
    return q, found


def test_stated_joints_equals_a_target_by_target_reference(arm):
    poses, s, t, _, tools, _ = _program(arm, 300, 11)
    s[::3] = cv.UNSTATED  # both groups: S stated (one branch) and not (nearest HOME of all 8)
    got = cf.stated_joints(arm, poses, s, t, tools=tools)
    want = _stated_one_by_one(arm, poses, s, t, tools)
    assert want[1].mean() > 0.5
    np.testing.assert_array_equal(got[1], want[1])
    np.testing.assert_array_equal(got[0], want[0])


def test_one_branch_alone_is_the_full_tables_entry_and_boundaries_are_not_sure():
    """Robot.status_branch (a LIN's branch solved without the other seven) gives the full table's
    entry bit for bit where it says sure; poses on the shoulder, elbow and wrist boundaries (two
    branches may share a status there) are not sure, and the rules solve all 8 for them."""
    robot = Robot(load_description(model_path("kr500.toml")))
    rng = np.random.default_rng(3)
    q = rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (6000, 6))
    q[:500, 4] = 0.0  # wrist singular (A5 = 0)
    q[500:1000, 2] = np.degrees(robot._solver.s[2] * robot._solver.stretched)  # elbow stretched (to ~1e-8 rad)
    poses = robot.fk(q)
    on_axis = poses[1000:1010].copy()  # the same poses moved so that the wrist centre is on the A1 axis
    on_axis[:, :2] -= robot._solver._wrist_centre(frames.frame_to_matrix(on_axis))[1][:, :2]
    poses = np.vstack([poses, np.round(poses, 3), on_axis])  # + as written
    table, ok, collide = cf._status_table(robot, poses, False)
    unsure = np.zeros(len(poses), bool)
    for s in range(8):
        got, got_ok, sure = robot.status_branch(poses, np.full(len(poses), s))
        np.testing.assert_array_equal(got[sure], table[s][sure])
        np.testing.assert_array_equal(got_ok[sure], ok[s][sure])
        unsure |= ~sure
    assert not collide[~unsure].any()
    assert unsure[:500].all() and unsure[-10:].all()
    assert unsure[1000:6000].mean() < 0.05
    assert robot.status_branch(poses, np.zeros(len(poses), int)) is not None
    assert Robot(load_description(model_path("ur10.toml"))).status_branch(poses[:3], np.zeros(3, int)) is None


@pytest.mark.parametrize("ptp", [False, True])
def test_nearest_choices_by_the_nearest_arm_equal_the_full_comparison(arm, ptp):
    """A pose list's rows (nearest HOME) and PTPs without S (nearest the previous target) compare
    only the nearest arm branch's two wrists where the others are farther (Robot.nearest_pair):
    the same joints and branches as comparing all 8, bit for bit."""
    robot = arm
    rng = np.random.default_rng(5)
    size = 300 if ptp else 3000  # (a PTP chain settles in passes over the program)
    q = rng.uniform(np.maximum(robot.limits[:, 0], -300), np.minimum(robot.limits[:, 1], 300), (size, 6))
    q[:30, 4] = 0.0  # wrist singular: all 8 solved there
    poses = robot.fk(q)
    n = len(poses)
    none = np.full(n, cv.UNSTATED)
    args = (poses, none, none, np.full(n, ptp), None, None, np.full(n, not ptp))
    fast = cf.controller_joints(robot, *args)
    ref = cf.controller_joints(robot, *args, check_all=True)
    assert ref[1].mean() > 0.9
    np.testing.assert_array_equal(fast[0], ref[0])
    np.testing.assert_array_equal(fast[1], ref[1])
    if robot.family == "kuka":
        pair = robot.nearest_pair(poses, np.broadcast_to(robot.home_q, (n, 6)))
        assert pair[4][30:].mean() > 0.9 and not pair[4][:30].any()

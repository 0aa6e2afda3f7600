"""The simulated robot: the paper's uncompensated statistics, seeds, compliance, backlash,
noise, and verify on a program compensated with the true error."""
import json

import numpy as np
import pytest

from postproc.cli import main
from postproc.core.diagnostics import PostprocError
from postproc.calibration.planning import latin_hypercube, plan_csv_text
from postproc.robot.description import load_description
from postproc.calibration.simulator import SimulatedRobot
from postproc.robot.approach import approach_signs
from postproc.core.stats import table2

PAPER = {"max": 1.5, "min": 0.1, "mean": 0.754, "std": 0.34}  # Hu, Hua & Tian, Table 2, uncompensated


@pytest.fixture(scope="module")
def sim():
    return SimulatedRobot()


@pytest.mark.parametrize("plan_seed", [101, 202, 303])
def test_default_robot_reproduces_the_uncompensated_row(sim, plan_seed):
    # 100 fresh LHS points in the paper's box and attitude range, measured as the paper did
    poses = latin_hypercube(100, seed=plan_seed)
    stats = table2(np.linalg.norm(poses[:, :3] - sim.measure(poses, rng_seed=plan_seed), axis=1))
    assert stats["mean"] == pytest.approx(PAPER["mean"], rel=0.10)
    assert 1.0 < stats["max"] < 2.2
    assert stats["min"] < 0.35
    assert 0.22 < stats["std"] < 0.46


def test_other_seeds_draw_other_robots_of_the_same_size(sim):
    poses = latin_hypercube(100, seed=7)
    errors = {s: SimulatedRobot(seed=s).true_error(poses) for s in range(1, 6)}
    errors[sim.seed] = sim.true_error(poses)
    for s, e in errors.items():
        assert np.linalg.norm(e, axis=1).mean() == pytest.approx(PAPER["mean"], rel=0.15), s
    seeds = sorted(errors)
    for a, b in zip(seeds, seeds[1:]):
        assert np.linalg.norm(errors[a] - errors[b], axis=1).mean() > 0.3  # different robots
    assert SimulatedRobot(seed=3).describe() == SimulatedRobot(seed=3).describe()  # a seed is a robot


def test_gravity_deflection_grows_with_payload_and_reach():
    base = load_description()
    near, far = [[1700, 0, 900, 0, 90, 0]], [[2300, 0, 900, 0, 90, 0]]

    def sag(payload: float, pose) -> float:
        s = SimulatedRobot(base.replace(payload_mass=payload, errors={**base.errors, "target_mean_mm": 0}))
        q = s.joint_angles(np.array(pose, float))
        moved = s.robot.fk(q + s.deflection(q))[:, :3] - s.robot.fk(q)[:, :3]
        return float(np.linalg.norm(moved))

    loads = [sag(m, far) for m in (0.0, 150.0, 300.0, 500.0)]
    assert all(a < b for a, b in zip(loads, loads[1:])), loads
    assert sag(300.0, near) < sag(300.0, far)
    assert 0.2 < sag(300.0, far) < 5.0  # mm: a heavy robot under load sags, but not by centimetres


def test_backlash_depends_on_the_side_a_pose_is_approached_from(sim):
    target = np.array([2000.0, 0.0, 900.0, 0.0, 90.0, 0.0])
    below, above = target.copy(), target.copy()
    below[[0, 1, 2]] -= 60
    above[[0, 1, 2]] += 60
    from_below = sim.actual_positions(np.array([below, target]))[1]
    from_above = sim.actual_positions(np.array([above, target]))[1]
    again = sim.actual_positions(np.array([below, below, target]))[2]
    np.testing.assert_allclose(again, from_below, atol=1e-9)  # same side, same place
    assert 0.05 < np.linalg.norm(from_below - from_above) < 1.0


def test_approach_signs_forward_fill():
    q = np.array([[1.0, 0], [2.0, 0], [2.0, -1], [1.5, -1], [1.5, -1]])
    signs = approach_signs(q, start_q=np.zeros(2))
    assert signs.tolist() == [[1, 1], [1, 1], [1, -1], [-1, -1], [-1, -1]]


def test_measurement_noise_is_small_and_seeded(sim):
    poses = latin_hypercube(400, seed=9)
    a, b = sim.measure(poses, rng_seed=1), sim.measure(poses, rng_seed=2)
    np.testing.assert_array_equal(a, sim.measure(poses, rng_seed=1))
    floor = np.linalg.norm(a - sim.actual_positions(poses), axis=1).mean()
    assert 0.03 < floor < 0.04  # tracker 0.01 + repeatability 0.02 mm per axis
    assert np.std(a - b) == pytest.approx(sim.noise_mm * np.sqrt(2), rel=0.1)


def test_verify_on_true_error_compensation_reaches_the_noise_floor(sim, tmp_path, capsys):
    poses = latin_hypercube(150, seed=12)
    command = poses.copy()
    for _ in range(5):  # c ← P + E_true(c): the simulator itself as the perfect model
        command[:, :3] = poses[:, :3] + sim.true_error(command)
    assert np.abs(sim.actual_positions(command) - poses[:, :3]).max() < 1e-6
    original, compensated = tmp_path / "orig.csv", tmp_path / "comp.csv"
    original.write_text(plan_csv_text(poses))
    compensated.write_text("x,y,z,a,b,c\n" + "\n".join(",".join(f"{v:.6f}" for v in row) for row in command) + "\n")
    assert main(["verify", str(original), str(compensated), "--json", "-q"]) == 0
    figures = json.loads(capsys.readouterr().out)
    assert figures["before"]["mean"] == pytest.approx(PAPER["mean"], rel=0.15)
    assert 0.02 < figures["after"]["mean"] < 0.05  # the noise floor, nothing systematic left
    assert main(["verify", str(original), str(compensated), "--max-mean", "0.01", "-q"]) == 1
    out = capsys.readouterr().out
    assert "before" in out and "after" in out and "mean" in out
    assert main(["verify", str(original), str(original), "--max-mean", "0.3", "-q"]) == 1


def test_verify_refuses_programs_that_do_not_correspond(tmp_path, capsys):
    poses = latin_hypercube(5, seed=1)
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    a.write_text(plan_csv_text(poses))
    b.write_text(plan_csv_text(poses[:4]))
    assert main(["verify", str(a), str(b)]) == 2
    assert "ORIGINAL has 5 targets, COMPENSATED has 4" in capsys.readouterr().err


def test_error_table_keys_are_checked(tmp_path):
    text = load_description().text.replace("backlash_spread =", "backlash_sprad =")
    path = tmp_path / "r.toml"
    path.write_text(text)
    with pytest.raises(PostprocError, match="unknown key 'backlash_sprad' in \\[errors\\]") as info:
        SimulatedRobot.from_file(path)
    assert info.value.line == text.splitlines().index(next(s for s in text.splitlines() if "backlash_sprad" in s)) + 1


def test_verify_reads_krl_with_frames(capsys):
    from helpers import REPO

    krl = REPO / "samples" / "krl"
    src, config = str(krl / "weld_cell.src"), str(krl / "config" / "$config.dat")
    args = ["verify", src, src, "--config", config]
    assert main(args + ["--json", "--no-noise"]) == 0
    captured = capsys.readouterr()
    figures = json.loads(captured.out)
    assert figures["targets"] > 5 and figures["skipped"] == 0
    assert figures["before"] == figures["after"]  # the same program, no noise: the same positions
    assert 0.05 < figures["before"]["mean"] < 2.0
    assert "$TOOL" not in captured.err  # the sample uses the simulated robot's tool: nothing to warn about


def test_verify_runs_a_program_with_its_own_tool(tmp_path, capsys):
    src = tmp_path / "p.src"
    src.write_text("DEF p( )\n$BASE = $NULLFRAME\n$TOOL = {X 10, Y 0, Z 250, A 0, B 0, C 0}\n"
                   "LIN {X 2000, Y 0, Z 900, A 0, B 90, C 0}\nLIN {X 2050, Y 100, Z 950, A 0, B 90, C 0}\nEND\n")
    assert main(["verify", str(src), str(src), "--json", "--no-noise"]) == 0
    figures = json.loads(capsys.readouterr().out)
    sim = SimulatedRobot()
    poses = np.array([[2000, 0, 900, 0, 90, 0], [2050, 100, 950, 0, 90, 0]], float)
    tool = np.tile([10.0, 0, 250, 0, 0, 0], (2, 1))
    lin = np.zeros(2, np.int8)  # LIN: the second keeps the first's configuration
    own = np.linalg.norm(poses[:, :3] - sim.actual_positions(poses, tools=tool, motions=lin), axis=1)
    spindle = np.linalg.norm(poses[:, :3] - sim.actual_positions(poses), axis=1)
    assert figures["before"]["mean"] == pytest.approx(own.mean(), abs=1e-9)
    assert abs(own.mean() - spindle.mean()) > 0.01  # the tool matters: not the robot's spindle


def test_verify_reports_orientation_and_a_perfect_orientation_correction_removes_it():
    from postproc.core import frames

    sim = SimulatedRobot()
    poses = latin_hypercube(60, seed=4)
    command = poses.copy()
    for _ in range(4):  # the simulator as the perfect model, on the full pose
        actual = sim.actual_poses(command)
        command[:, :3] = poses[:, :3] + (command[:, :3] - actual[:, :3, 3])  # c = P + E(c)
        turn = actual[:, :3, :3] @ frames.rotation_from_abc(command[:, 3:6]).swapaxes(-1, -2)  # nominal → actual
        command[:, 3:6] = frames.abc_from_rotation(turn.swapaxes(-1, -2) @ frames.rotation_from_abc(poses[:, 3:6]))
    result = sim.verify(poses, command, noise=False)
    assert 0.005 < result["orientation_before"]["mean"] < 1.0  # deg: the drawn robot turns the tool too
    assert result["orientation_after"]["mean"] < 1e-4
    assert result["after"]["mean"] < 1e-3
    same = sim.verify(poses, poses, noise=False)
    assert same["orientation_before"] == same["orientation_after"]

"""Loads (issue 33, items 1, 2): the simulator deflects under each target's load, a campaign is
planned and measured at test loads (load_mass..load_cz columns), train identifies the compliance
under each row's load, and the exported graph takes the optional input ``load`` [N, 4]."""
import numpy as np
import onnxruntime
import pytest

from postproc.calibration.planning import latin_hypercube, read_plan
from postproc.calibration.simulator import SimulatedRobot
from postproc.cli import main as cli
from postproc.core.diagnostics import PostprocError
from postproc.measurements.csv import LOAD_COLUMNS, parse_measurements, read_measurements
from postproc.model.compensator import load_model
from postproc.model.training.features import previous_poses
from postproc.model.training.hybrid import HybridModel

COM = (220.0, 0.0, 40.0)
FAST = {"iterations": 6, "ripple": [], "select": "none"}  # (a small fit: no ripple search, no blocked selection)


@pytest.fixture(scope="module")
def sim():
    return SimulatedRobot()


@pytest.fixture(scope="module")
def fitted(sim, tmp_path_factory):
    """A load-aware and a load-blind model of one campaign at 0 and 300 kg (110 poses), the
    aware one exported."""
    poses = latin_hypercube(110, seed=4)
    poses = poses[sim.reachable(poses)]
    loads = np.zeros((len(poses), 4))
    loads[len(poses) // 2:] = (300.0, *COM)
    errors = poses[:, :3] - sim.measure(poses, rng_seed=3, loads=loads)
    previous = previous_poses(poses)
    aware = HybridModel(sim.description, residual="none", kinematic=FAST).fit(poses, errors, previous, loads=loads)
    blind = HybridModel(sim.description, residual="none", kinematic=FAST).fit(poses, errors, previous)
    path = tmp_path_factory.mktemp("loads") / "aware.onnx"
    aware.export_onnx(path, name="aware", robot=sim.robot.name)
    return aware, blind, path


def _csv(extra_header: str, extra: str) -> bytes:
    return (f"x,y,z,a,b,c,x_meas,y_meas,z_meas{extra_header}\n"
            f"2000,0,900,0,90,0,2000.5,0.1,899.7{extra}\n"
            f"2000,0,900,0,90,0,2000.9,0.1,899.2{extra.replace('300', '0')}\n").encode()


def test_the_load_columns_are_read_per_row_and_the_same_pose_at_two_loads_is_two_rows():
    data = parse_measurements(_csv(",load_mass,load_cx,load_cy,load_cz", ",300,220,0,40"))
    assert data.loads.tolist() == [[300, 220, 0, 40], [0, 220, 0, 40]]
    with pytest.raises(PostprocError) as same:  # (without the loads the two rows are one pose twice)
        parse_measurements(_csv("", ""))
    assert same.value.code == "P504"
    assert parse_measurements(_csv("", ""), repeats=True).loads is None
    with pytest.raises(PostprocError) as missing:
        parse_measurements(_csv(",load_mass", ",300"))
    assert missing.value.code == "P501" and "load_cx" in str(missing.value)
    with pytest.raises(PostprocError) as negative:
        parse_measurements(_csv(",load_mass,load_cx,load_cy,load_cz", ",-3,0,0,0"))
    assert negative.value.code == "P502" and negative.value.line == 2


def test_the_simulator_deflects_under_each_targets_load(sim):
    poses = latin_hypercube(60, seed=2)
    poses = poses[sim.reachable(poses)]
    default = sim.actual_positions(poses)
    stated = sim.actual_positions(poses, loads=sim.default_load)  # the description's payload, stated
    assert np.abs(default - stated).max() < 1e-9
    nan = sim.actual_positions(poses, loads=np.full(4, np.nan))
    assert np.abs(default - nan).max() < 1e-9
    empty = sim.actual_positions(poses, loads=np.zeros(4))
    moved = np.linalg.norm(default - empty, axis=1)
    assert 0.2 < moved.mean() < 2.0  # 300 kg off a 500 kg-class arm: a fraction of a millimetre to one
    # per row: rows carrying nothing are where the empty robot goes, the others where the loaded one goes
    mixed = np.where(np.arange(len(poses))[:, None] % 2 == 0, 0.0, sim.default_load)
    out = sim.actual_positions(poses, loads=mixed)
    assert np.abs(out[::2] - empty[::2]).max() < 1e-9 and np.abs(out[1::2] - default[1::2]).max() < 1e-9
    with pytest.raises(PostprocError, match="rated payload 500"):
        sim.actual_positions(poses[:2], loads=(600.0, *COM))


def test_a_model_trained_at_two_loads_predicts_a_third_load_the_blind_one_does_not(sim, fitted):
    aware, blind, _ = fitted
    targets = latin_hypercube(80, seed=9)
    targets = targets[sim.reachable(targets)]
    previous = previous_poses(targets)
    for load in ((150.0, *COM), (500.0, *COM), (450.0, 0.0, 0.0, 250.0)):
        truth = sim.true_error(targets, loads=np.tile(load, (len(targets), 1)))
        left_aware = np.linalg.norm(truth - aware.predict(targets, previous, loads=load), axis=1).mean()
        left_blind = np.linalg.norm(truth - blind.predict(targets, previous), axis=1).mean()
        assert left_aware < 0.08, (load, left_aware)  # (the tracker's noise is 0.02 mm per axis)
        # (150 kg is the mean of the two: there a blind model's average of the loads is right too)
        assert left_aware < (0.8 if load[0] == 150 else 0.3) * left_blind, (load, left_aware, left_blind)
    card = aware.loads_card()
    assert card["measured"] == [[0, 0, 0, 0], [300, *COM]] and card["reference"] == [300, *COM]
    assert blind.loads_card() is None


def test_the_load_input_absent_nan_and_the_reference_are_one_load(sim, fitted, capfd):
    aware, _, path = fitted
    model = load_model(path)
    assert model.takes_load and model.measured_loads.tolist() == [[0, 0, 0, 0], [300, *COM]]
    poses = latin_hypercube(40, seed=6)
    poses = poses[sim.reachable(poses)]
    absent = model.predict(poses)
    assert np.array_equal(absent, model.predict(poses, load=np.full((len(poses), 4), np.nan)))
    assert np.array_equal(absent, model.predict(poses, load=model.reference_load))
    heavy = model.predict(poses, load=(500.0, *COM))
    assert np.abs(heavy - absent).max() > 0.1  # (the load is read: 200 kg more deflects the arm)
    # the graph is the torch model's: each row its own load
    loads = np.where(np.arange(len(poses))[:, None] % 2 == 0, [0.0, 0, 0, 0], [500.0, *COM])
    torch_side = aware.predict(poses, previous_poses(poses), loads=loads)
    assert np.abs(model.predict(poses, previous_poses(poses), load=loads) - torch_side).max() < 2e-3
    assert model.load_reach(np.array([[0, 0, 0, 0], [600, *COM], [601, *COM], [np.nan] * 4])).tolist() == \
        [True, True, False, True]
    capfd.readouterr()
    session = onnxruntime.InferenceSession(str(path))  # a plain caller: pose alone, no warning
    assert ("load", [ "N", 4]) in [(i.name, i.shape) for i in session.get_inputs()]
    out = session.run(["error"], {"pose": poses.astype(np.float32)})[0]
    assert np.abs(out - absent).max() < 1e-4
    assert capfd.readouterr().err == ""


def test_plan_and_measure_at_test_loads_write_the_load_columns(tmp_path, sim, fitted, capsys):
    plan, measured = tmp_path / "plan.csv", tmp_path / "measured.csv"
    assert cli(["plan", "-n", "30", "-o", str(plan), "--krl", str(tmp_path / "m.src"),
                "--load", "0", "--load", "300,220,0,40", "-q"]) == 0
    loads = read_plan(plan).loads
    assert loads[:15].tolist() == [[0, 0, 0, 0]] * 15 and loads[15:].tolist() == [[300, *COM]] * 15
    src = (tmp_path / "m.src").read_text()
    assert src.count("HALT") == 1 and "$LOAD.M = 300" in src and "$LOAD.M = 0" in src
    assert cli(["measure", str(plan), "-o", str(measured), "-q"]) == 0
    data = read_measurements(measured)
    assert np.array_equal(data.loads, loads)
    assert measured.read_text().splitlines()[2].endswith(",".join(LOAD_COLUMNS))
    # what was measured is the loaded robot's: the rows' errors are the simulator's at their loads
    q = np.c_[[data.joints[:, k] for k in range(6)]].T
    expected = sim.actual_positions(data.poses, q_deg=q, loads=loads)
    assert np.linalg.norm(data.measured - expected, axis=1).max() < 0.2  # (noise only)
    assert cli(["plan", "-n", "10", "-o", str(plan), "--load", "-5", "-q"]) == 2
    # a load-aware model is not re-calibrated at one load (its torques would lose the load): refused
    capsys.readouterr()
    assert cli(["train", str(measured), "--update", str(fitted[2]), "-o", str(tmp_path / "u.onnx"), "-q"]) == 2
    assert "P317" in capsys.readouterr().err and not (tmp_path / "u.onnx").exists()


def test_a_model_measured_at_one_mass_reaches_that_load_only(tmp_path):
    """The card's rule (benchmarks/loads.py: one load measured, 5-10x the error at the others):
    two masses reach 0..k x the heaviest, one mass only itself."""
    from postproc.model.card import load_lines
    from postproc.testing.models import affine_model

    one = load_model(affine_model(tmp_path / "one.onnx", gain=np.eye(3) * 1e-3, load_gain=1e-3,
                                  loads={"measured": [[300, *COM]], "reference": [300, *COM], "extrapolate": 1.0}))
    two = load_model(affine_model(tmp_path / "two.onnx", gain=np.eye(3) * 1e-3, load_gain=1e-3))
    loads = np.array([[300, *COM], [300.5, *COM], [0, 0, 0, 0], [150, *COM], [np.nan] * 4])
    assert one.load_reach(loads).tolist() == [True, True, False, False, True]
    assert two.load_reach(loads).tolist() == [True, True, True, True, True]
    assert "reaches that load only" in "\n".join(load_lines(one))
    assert "reaches 0…600 kg" in "\n".join(load_lines(two))


"""`postproc train`'s default (hybrid: identified arm + residual networks) end to end:
simulated measurements → model → compensate a program → the simulated robot lands closer;
the ONNX graph agrees with torch; pose-only and UR-type variants; refusals."""
from __future__ import annotations

import numpy as np
import pytest

from postproc.cli import main
from postproc.compensation.api import compensate_text
from postproc.programs.io import parse_program_text
from postproc.model.compensator import load_model
from postproc.measurements.csv import write_measurements
from postproc.calibration.planning import latin_hypercube
from postproc.calibration.simulator import SimulatedRobot
from postproc.model.training.features import previous_poses
from postproc.model.training.synthetic import synthetic_measurements, to_csv

from helpers import REPO
from postproc.programs import ActiveFrames

ROBOT_SEED = 7  # a drawn robot (not the evaluation seeds 101-105 of benchmarks/accuracy.py)


@pytest.fixture(scope="module")
def sim():
    return SimulatedRobot(seed=ROBOT_SEED)


@pytest.fixture(scope="module")
def measured_csv(tmp_path_factory, sim):
    """300 LHS poses measured in plan order on the drawn robot (noise included)."""
    folder = tmp_path_factory.mktemp("data")
    poses = latin_hypercube(300, seed=0)
    measured = sim.measure(poses, rng_seed=0)
    path = folder / "measured.csv"
    write_measurements(path, poses, measured)
    return path


@pytest.fixture(scope="module")
def hybrid_model(tmp_path_factory, measured_csv):
    out = tmp_path_factory.mktemp("model") / "hybrid.onnx"
    assert main(["train", str(measured_csv), "-o", str(out), "-q", "--seed", "0"]) == 0
    return out


def krl(poses: np.ndarray) -> str:
    body = "\n".join("  LIN {" + ",".join(f"{k} {v:.4f}" for k, v in zip("XYZABC", p)) + "}" for p in poses)
    return f"DEF held( )\n{body}\nEND\n"


@pytest.mark.slow  # trains the module's model: ~5-10 s
def test_default_model_learns_backlash_from_the_visiting_order(hybrid_model):
    model = load_model(hybrid_model)
    assert model.wants_previous  # the rows' order gave the approach directions
    assert "kinematic identification" in model.metadata["method"]
    card = model.metadata["accuracy"]
    assert card["val_mean_mm"] < card["val_uncompensated_mean_mm"] / 5
    ripple = model.metadata["identified"]["ripple"]
    assert [1, 36] in ripple  # the simulator's gear mesh order of A1, found in the data


@pytest.mark.slow
def test_compensated_program_lands_on_target(hybrid_model, sim):
    targets = latin_hypercube(40, seed=1000)
    # the rows are in the robot base frame with the model's tool: stated, as a user would
    text, report = compensate_text(krl(targets), hybrid_model, active=ActiveFrames(base=0, tool="model"))
    assert report.compensated == 40
    commands = parse_program_text(text, "held.src").targets.poses
    result = sim.verify(targets, commands, rng_seed=0)
    assert result["before"]["mean"] > 0.5
    assert result["after"]["mean"] < 0.10  # target 2's 0.15 mm from 300 points, with margin
    assert result["after"]["max"] < 0.30


def test_onnx_graph_agrees_with_torch(measured_csv, tmp_path):
    from postproc.robot.description import load_description
    from postproc.measurements.csv import read_measurements
    from postproc.model.training.hybrid import HybridModel

    data = read_measurements(measured_csv)
    prev = previous_poses(data.poses)
    model = HybridModel(load_description(), residual="always", ensemble=2, epochs=50, seed=0)
    model.fit(data.poses, data.errors, prev)
    path = tmp_path / "agree.onnx"
    model.export_onnx(path, name="agree")
    onnx_model = load_model(path)
    held = latin_hypercube(200, seed=5)
    prev_held = previous_poses(held)
    prev_held[0] = held[0]  # the first target: nothing known before it (HOME assumed inside)
    held32, prev32 = held.astype(np.float32).astype(float), prev_held.astype(np.float32).astype(float)
    expected = model.predict(held32, prev32)
    got = onnx_model.predict(held32, prev32)
    # mm: float64 inside, but Atan/Acos run in float32 (onnxruntime has no float64 kernels) and
    # torch's and onnxruntime's differ by an ulp: 1e-7 rad of a joint is ~3e-4 mm at the TCP
    assert np.abs(got - expected).max() < 1e-3
    assert np.abs(expected).max() > 0.5


@pytest.mark.slow
def test_same_seed_same_bytes(measured_csv, hybrid_model, tmp_path):
    again = tmp_path / hybrid_model.name  # (the name goes into the model card)
    assert main(["train", str(measured_csv), "-o", str(again), "-q", "--seed", "0"]) == 0
    assert again.read_bytes() == hybrid_model.read_bytes()


def test_pose_only_model_takes_the_pose_alone(measured_csv, tmp_path):
    out = tmp_path / "pose.onnx"
    assert main(["train", str(measured_csv), "-o", str(out), "-q", "--method", "kinematic", "--pose-only"]) == 0
    model = load_model(out)
    assert not model.wants_previous
    # backlash is noise to a pose-only model: ~0.2-0.25 mm left, as the method's network
    assert 0.1 < model.metadata["accuracy"]["val_mean_mm"] < 0.4


def test_ur10_tracker_data_with_registration(tmp_path):
    csv = tmp_path / "ipa.csv"
    assert main(["import", "ipa", str(REPO / "samples" / "ipa" / "series_c_excerpt.csv"), "-o", str(csv), "-q"]) == 0
    out = tmp_path / "ur10.onnx"
    argv = ["train", str(csv), "-o", str(out), "-q", "--register", "--val-fraction", "0.2",
            "--robot", str(REPO / "models" / "ur10.toml")]
    assert main(argv) == 0
    model = load_model(out)
    card = model.metadata["accuracy"]
    assert card["val_uncompensated_mean_mm"] > 2.0  # the robot is mm off after registration
    assert card["val_mean_mm"] < 0.5  # 120 training rows; Series C in full: benchmarks/accuracy.py
    assert model.metadata["identified"]["ik_family"] == "ur" and model.robot == "UR10"


def test_data_the_robot_cannot_reach_is_refused(tmp_path, capsys):
    poses, measured = synthetic_measurements(60, seed=5)  # tool pointing up: not the KR500's workspace
    csv = tmp_path / "synthetic.csv"
    csv.write_text(to_csv(poses, measured))
    out = tmp_path / "m.onnx"
    assert main(["train", str(csv), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "P508" in err and "out of reach" in err and not out.exists()


def test_robot_name_instead_of_a_description_is_refused(measured_csv, tmp_path, capsys):
    assert main(["train", str(measured_csv), "-o", str(tmp_path / "m.onnx"), "--robot", "UR5"]) == 2
    assert "--robot FILE.toml" in capsys.readouterr().err

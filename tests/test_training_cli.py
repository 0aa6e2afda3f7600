"""`postproc train` end to end on small CSVs, and every kind of bad input (exit 2, nothing written)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from postproc.cli import main
from postproc.model.compensator import load_model
from postproc.measurements.csv import parse_measurements
from postproc.model.training.synthetic import synthetic_measurements, to_csv

HEADER = "x,y,z,a,b,c,x_meas,y_meas,z_meas"
FAST = ["--method", "gpso", "--hidden", "8,4", "--epochs", "15"]  # the GPSO-DNN path (default: hybrid)


@pytest.fixture(scope="module")
def csv_text() -> str:
    poses, measured = synthetic_measurements(300, seed=5)
    return to_csv(poses, measured)


@pytest.fixture
def csv_file(tmp_path, csv_text):
    path = tmp_path / "measured.csv"
    path.write_text(csv_text)
    return path


def test_train_writes_a_contract_model_and_prints_figures(csv_file, tmp_path, capsys):
    out = tmp_path / "m.onnx"
    argv = ["train", str(csv_file), "-o", str(out), "--name", "cell", "--robot", "KR500-sim", "--val-fraction", "0.1"]
    assert main(argv + FAST) == 0
    printed = capsys.readouterr()
    assert "uncompensated" in printed.out and "residual |E − Ê|" in printed.out
    comp = load_model(out)
    meta = comp.metadata
    assert comp.name == "cell" and comp.robot == "KR500-sim"
    assert meta["structure"] == "6-8-4-3" and meta["method"] == "GPSO-DNN + lm"
    assert meta["data_sha256"] == parse_measurements(csv_file.read_bytes()).sha256
    acc = meta["accuracy"]
    assert (acc["n_train"], acc["n_val"]) == (270, 30)
    assert acc["val_mean_mm"] < 0.6 * acc["val_uncompensated_mean_mm"]  # it learned something
    assert f"{acc['val_mean_mm']:.4f}" in printed.out  # the printed figures are the stored ones
    assert meta["reach"]["radius_max"] > 2000 and len(meta["tool"]["frame"]) == 6  # from the description
    data = parse_measurements(csv_file.read_bytes())
    assert np.allclose(meta["envelope"]["box"][0::2], data.poses[:, :3].min(axis=0))
    assert meta["iterations"] >= 2


def test_same_seed_same_bytes(csv_file, tmp_path):
    a, b = tmp_path / "a.onnx", tmp_path / "b.onnx"
    for out in (a, b):
        assert main(["train", str(csv_file), "-o", str(out), "-q", "--name", "m"] + FAST) == 0
    assert a.read_bytes() == b.read_bytes()


def _bad(tmp_path, capsys, text: str, *extra: str) -> str:
    src = tmp_path / "bad.csv"
    src.write_text(text)
    out = tmp_path / "never.onnx"
    assert main(["train", str(src), "-o", str(out)] + FAST + list(extra)) == 2
    assert not out.exists() and [p.name for p in tmp_path.iterdir()] == ["bad.csv"]
    return capsys.readouterr().err


def test_bad_missing_column(tmp_path, capsys, csv_text):
    err = _bad(tmp_path, capsys, csv_text.replace("y_meas,", "", 1))
    assert "bad.csv:1:1: P501 missing column(s) y_meas" in err


def test_bad_misnamed_column(tmp_path, capsys, csv_text):
    err = _bad(tmp_path, capsys, csv_text.replace("x_meas", "xmeas", 1))
    assert "bad.csv:1:13: P501" in err and "'xmeas' for 'x_meas'" in err


def test_bad_nan_row(tmp_path, capsys, csv_text):
    lines = csv_text.splitlines()
    fields = lines[7].split(",")
    fields[4] = "NaN"
    lines[7] = ",".join(fields)
    err = _bad(tmp_path, capsys, "\n".join(lines) + "\n")
    col = len(",".join(fields[:4])) + 2
    assert f"bad.csv:8:{col}: P502 column 'b': 'NaN' is not a finite number" in err


def test_too_few_points_for_the_identification_name_the_data_file(tmp_path, capsys, csv_text):
    """The identified methods' P505 (raised where the rows are fitted) says which file it is about."""
    head = "\n".join(csv_text.splitlines()[:4]) + "\n"
    err = _bad(tmp_path, capsys, head, "--method", "kinematic", "--val-fraction", "0")
    assert f"{tmp_path / 'bad.csv'}: P505" in err and "fewer than the" in err


def test_bad_duplicate_pose(tmp_path, capsys, csv_text):
    lines = csv_text.splitlines()
    lines.append(lines[3])
    err = _bad(tmp_path, capsys, "\n".join(lines) + "\n")
    assert f"bad.csv:{len(lines)}:1: P504 duplicate pose" in err and "line 4" in err


def test_bad_too_few_points(tmp_path, capsys, csv_text):
    head = "\n".join(csv_text.splitlines()[:40]) + "\n"  # 39 rows → 35 for training
    err = _bad(tmp_path, capsys, head, "--hidden", "20,10,5")
    assert "P505" in err and "at least 141" in err


def test_bad_tracker_frame_without_register(tmp_path, capsys, csv_text):
    err = _bad(tmp_path, capsys, "# frame: tracker\n" + csv_text)
    assert "P507" in err and "--register" in err


def test_bad_val_fraction(tmp_path, capsys, csv_text):
    assert "P506" in _bad(tmp_path, capsys, csv_text, "--val-fraction", "1.5")


def test_bad_hidden_is_a_usage_error(csv_file, tmp_path, capsys):
    with pytest.raises(SystemExit) as info:
        main(["train", str(csv_file), "-o", str(tmp_path / "m.onnx"), "--hidden", "20,x"])
    assert info.value.code == 2 and "20,x" in capsys.readouterr().err


def test_register_maps_tracker_measurements(tmp_path, csv_text):
    # the same data seen by a tracker standing elsewhere (rotated 30° about Z, shifted)
    poses, measured = synthetic_measurements(300, seed=5)
    t = np.radians(30)
    rot = np.array([[np.cos(t), -np.sin(t), 0], [np.sin(t), np.cos(t), 0], [0, 0, 1]])
    tracker = (measured - [500, 0, 100]) @ rot.T
    src = tmp_path / "tracker.csv"
    src.write_text("# frame: tracker\n" + to_csv(poses, tracker))
    out = tmp_path / "m.onnx"
    assert main(["train", str(src), "-o", str(out), "-q", "--register"] + FAST) == 0
    acc = json.loads(json.dumps(load_model(out).metadata["accuracy"]))
    assert acc["val_uncompensated_mean_mm"] < 3.0  # in the base frame again (the offset alone is ~500 mm)


def test_bad_search_on_too_few_points(tmp_path, capsys, csv_text):
    head = "\n".join(csv_text.splitlines()[:12]) + "\n"  # 11 rows: no candidate network fits
    err = _bad(tmp_path, capsys, head, "--search")
    assert "bad.csv" in err and "P505" in err and "too few for any candidate" in err


def test_ur10_data_without_its_robot_is_refused_and_with_it_identified(tmp_path, capsys):
    """The IPA excerpt (a UR10) with the default KR500 description: refused (P508, the joint
    angles do not put that arm on the poses); with --robot models/ur10.toml: trained on the real
    joint angles, the identifiability (rank, unseparated groups) reported, a 'joints' input."""
    data = tmp_path / "ipa.csv"
    assert main(["import", "ipa", "samples/ipa/series_c_excerpt.csv", "-o", str(data), "--register",
                 "--val-fraction", "0.2", "-q"]) == 0
    out = tmp_path / "m.onnx"
    assert main(["train", str(data), "-o", str(out), "--method", "kinematic"]) == 2
    err = capsys.readouterr().err
    assert "P508" in err and "q1..q6" in err and "--robot" in err and not out.exists()
    assert main(["train", str(data), "-o", str(out), "--method", "kinematic", "--robot", "models/ur10.toml"]) == 0
    printed = capsys.readouterr().out
    assert "identify  rank " in printed and "cannot separate" in printed
    comp = load_model(out)
    assert comp.wants_joints and comp.metadata["identified"]["identifiability"]["rank"] > 20
    assert comp.metadata["accuracy"]["val_mean_mm"] < 0.5 * comp.metadata["accuracy"]["val_uncompensated_mean_mm"]

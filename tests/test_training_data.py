"""Measurement CSV reading and checking (postproc.model.training.data): no torch needed."""
from __future__ import annotations

import hashlib

import numpy as np
import pytest

from postproc.core.diagnostics import PostprocError
from postproc.measurements.csv import parse_measurements, read_measurements
from postproc.model.training.data import check_size, envelope_of, min_points, split_indices
from postproc.model.training.synthetic import synthetic_measurements, to_csv

HEADER = "x,y,z,a,b,c,x_meas,y_meas,z_meas"


def _error(text: str, path: str = "m.csv") -> PostprocError:
    with pytest.raises(PostprocError) as info:
        parse_measurements(text.encode(), path)
    return info.value


def test_reads_rows_errors_and_sha():
    text = f"{HEADER}\n1000,0,500,0,90,0,999.5,0.25,501\n1100,10,600,1,89,2,1100,10,600\n"
    data = parse_measurements(text.encode(), "m.csv")
    assert data.poses.shape == (2, 6) and data.measured.shape == (2, 3)
    assert np.allclose(data.errors[0], [0.5, -0.25, -1.0])  # E = target − measured
    assert list(data.lines) == [2, 3]
    assert data.sha256 == hashlib.sha256(text.encode()).hexdigest()


def test_columns_in_any_order_extra_columns_comments_and_bom():
    text = "\ufeff# frame: base\n# source: test\nid,z_meas,y_meas,x_meas,c,b,a,z,y,x\n\n7,3,2,1,0,0,0,3.5,2,1\n"
    data = parse_measurements(text.encode("utf-8"), "m.csv")
    assert np.allclose(data.poses[0], [1, 2, 3.5, 0, 0, 0]) and np.allclose(data.errors[0], [0, 0, 0.5])
    assert data.meta == {"frame": "base", "source": "test"}
    assert list(data.lines) == [5]


def test_missing_column():
    err = _error("x,y,z,a,b,x_meas,y_meas,z_meas\n1,2,3,4,5,6,7,8\n")
    assert (err.code, err.line) == ("P501", 1)
    assert "missing column(s) c" in err.message


def test_misnamed_column_points_at_it():
    err = _error("x,y,z,a,b,c,x_meas,y_meas,zmeas\n1,2,3,4,5,6,7,8,9\n")
    assert (err.code, err.line, err.col) == ("P501", 1, len("x,y,z,a,b,c,x_meas,y_meas,") + 1)
    assert "'zmeas' for 'z_meas'" in err.message
    assert str(err).startswith("m.csv:1:")


def test_nan_value_located():
    err = _error(f"{HEADER}\n1,2,3,4,5,6,7,8,9\n1,2,3,4,nan,6,7,8,9\n")
    assert (err.code, err.line, err.col) == ("P502", 3, 9)
    assert "column 'b'" in err.message and "'nan'" in err.message


def test_empty_and_text_values_located():
    assert _error(f"{HEADER}\n1,2,3,4,5,6,7,,9\n").col == 15
    err = _error(f"{HEADER}\n1,2,3,4,5,6,7,8,9\n1,2,3,4,5,7,7,8,abc\n")
    assert (err.code, err.line, err.col) == ("P502", 3, 17)


def test_wrong_field_count():
    err = _error(f"{HEADER}\n1,2,3,4,5,6,7,8\n")
    assert (err.code, err.line) == ("P503", 2)


def test_duplicate_pose_names_both_lines():
    err = _error(f"{HEADER}\n1,2,3,4,5,6,7,8,9\n2,2,3,4,5,6,7,8,9\n1,2,3,4,5,6,1,1,1\n")
    assert (err.code, err.line) == ("P504", 4)
    assert "line 2" in err.message


def test_empty_file_and_header_only():
    assert _error("").code == "P500"
    assert _error(f"{HEADER}\n\n").code == "P500"


def test_unreadable_file(tmp_path):
    with pytest.raises(PostprocError) as info:
        read_measurements(tmp_path / "absent.csv")
    assert info.value.code == "P500"


def test_too_few_points_rule():
    # [20, 10, 5]: (6+1)·20 + (20+1)·10 + (10+1)·5 + (5+1)·3 = 423 weights → 141 rows
    assert min_points(423) == 141
    check_size(141, 423, "6-20-10-5-3")
    with pytest.raises(PostprocError) as info:
        check_size(140, 423, "6-20-10-5-3", "m.csv")
    assert info.value.code == "P505" and "at least 141" in info.value.message


def test_split_is_seeded_disjoint_and_complete():
    tr, va = split_indices(2000, 0.05, 0)
    assert len(va) == 100 and len(tr) == 1900
    assert np.array_equal(np.sort(np.concatenate([tr, va])), np.arange(2000))
    assert np.array_equal(va, split_indices(2000, 0.05, 0)[1])
    assert not np.array_equal(va, split_indices(2000, 0.05, 1)[1])
    # a smaller fraction with the same seed holds out a subset (import --register relies on it)
    assert set(va) <= set(split_indices(2000, 0.2, 0)[1])
    for bad in (-0.1, 1.0):
        with pytest.raises(PostprocError):
            split_indices(10, bad, 0)


def test_envelope_wraps_attitude_and_holds_the_data():
    poses, _ = synthetic_measurements(300, seed=3)  # A and C straddle ±180
    env = envelope_of(poses)
    box = np.array(env["box"])
    assert np.allclose(box[0::2], poses[:, :3].min(axis=0)) and np.allclose(box[1::2], poses[:, :3].max(axis=0))
    assert abs(abs(env["attitude"][0]) - 180) < 1 and abs(env["attitude"][1]) < 1
    assert env["range"] == 10.0  # ±10° around the centre, not 360°


def test_synthetic_csv_round_trips():
    poses, measured = synthetic_measurements(50, seed=1)
    data = parse_measurements(to_csv(poses, measured).encode())
    assert np.allclose(data.poses, poses, atol=1e-4) and np.allclose(data.measured, measured, atol=1e-4)


def test_joint_columns_are_read_with_the_file_and_are_optional():
    head = "x,y,z,a,b,c,x_meas,y_meas,z_meas,q1,q2,q3,q4,q5,q6\n"
    rows = "2000,0,900,0,90,0,2000.1,0,900,1,-40,90,0,40,-1\n# a comment\n2100,0,900,0,90,0,2100,0.2,900,2,-41,91,0,41,-2\n"
    data = parse_measurements((head + rows).encode())
    assert data.joints.tolist() == [[1, -40, 90, 0, 40, -1], [2, -41, 91, 0, 41, -2]]
    # an unreadable joint value drops the extra columns, not the data
    data = parse_measurements((head + rows.replace(",40,-1", ",nan,-1")).encode())
    assert data.joints is None and len(data) == 2
    assert parse_measurements(b"x,y,z,a,b,c,x_meas,y_meas,z_meas\n1,2,3,0,90,0,1,2,3\n").joints is None


def test_s_t_columns_are_solved_for_the_datas_tool_not_the_descriptions(tmp_path):
    """Issue 32: a KUKA measurement file with s,t and no q1..q6, trained with --tool: the joint
    angles are the IK of that TCP (before: of the description's, P508 'not where the joint
    angles put …'), and the model is the one the file's own q1..q6 give."""
    from postproc.cli import main
    from postproc.model.compensator import load_model

    def cli(*args):
        return main([str(a) for a in args])

    assert cli("plan", "-n", 120, "--seed", 3, "--tool", "250,0,0,0,0,0", "--wrist", "home", "-o",
               tmp_path / "plan.csv", "-q") == 0
    assert cli("measure", tmp_path / "plan.csv", "-o", tmp_path / "m.csv", "-q") == 0
    lines = (tmp_path / "m.csv").read_text().splitlines()
    at = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    header = lines[at].split(",")
    keep = [i for i, name in enumerate(header) if name not in {f"q{k}" for k in range(1, 7)}]
    (tmp_path / "st.csv").write_text("\n".join(
        [line for line in lines[:at] if not line.startswith("# tool")]
        + [",".join(f for i, f in enumerate(line.split(",")) if i in keep) for line in lines[at:]]) + "\n")
    assert cli("train", tmp_path / "st.csv", "--tool", "250,0,0,0,0,0", "-o", tmp_path / "st.onnx",
               "--method", "kinematic", "-q") == 0
    assert cli("train", tmp_path / "m.csv", "-o", tmp_path / "q.onnx", "--method", "kinematic", "-q") == 0
    poses = np.array([[float(v) for v in line.split(",")[:6]] for line in lines[at + 1:]])
    from_st = load_model(tmp_path / "st.onnx").predict(poses)
    from_q = load_model(tmp_path / "q.onnx").predict(poses)
    assert np.abs(from_st - from_q).max() < 0.05  # mm: the same joint angles, the same identification
    assert np.linalg.norm(from_q, axis=1).mean() > 0.3  # (a correction that varies, not zero)

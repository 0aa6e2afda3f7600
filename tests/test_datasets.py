"""IPA data → measurement CSV: columns, units, angle conventions, errors, the import command."""
from __future__ import annotations

import csv
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from postproc.cli import main
from postproc.measurements.datasets import parse_ipa, read_ipa, rpy_to_abc
from postproc.measurements.csv import COLUMNS, read_metadata
from postproc.core.diagnostics import PostprocError
from postproc.core.frames import rotation_from_abc
from postproc.core.registration import register_measurements
from postproc.core.resources import sample_path
from postproc.measurements.csv import parse_measurements
from postproc.model.training.data import split_indices

EXCERPT = sample_path("ipa/series_c_excerpt.csv")


def rx(t: float) -> np.ndarray:
    c, s = math.cos(t), math.sin(t)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def ry(t: float) -> np.ndarray:
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rz(t: float) -> np.ndarray:
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


@pytest.fixture(scope="module")
def series():
    return read_ipa(EXCERPT)


@pytest.fixture(scope="module")
def text():
    return EXCERPT.read_text(encoding="utf-8")


def test_excerpt_is_150_rows_in_file_order(series):
    assert len(series) == 150
    assert np.array_equal(series.lines, np.arange(2, 152))


def test_hand_checked_row(series):
    # file line 3, as written there (decimal comma):
    # Goal x;y;z = 0,0103459;-0,480444;1,00632  roll;pitch;yaw = 3,10253;1,66683;1,57927
    # joints = -4,08444;-2,6946;1,69873;-2,031;0,99275;-0,0673035  temperature 21,68000031
    # measurement x;y;z = 335,14778;-3134,3677;-221,16088  rx;ry;rz = -84,20352;-22,726835;-88,245609
    i = 1
    assert series.lines[i] == 3
    assert series.commanded[i, :3] == pytest.approx([10.3459, -480.444, 1006.32], abs=1e-9)  # m → mm
    roll, pitch, yaw = 3.10253, 1.66683, 1.57927
    by_hand = rz(yaw) @ ry(pitch) @ rx(roll)  # extrinsic x, then y, then z
    assert Rotation.from_euler("xyz", [roll, pitch, yaw]).as_matrix() == pytest.approx(by_hand, abs=1e-14)
    abc = series.commanded[i, 3:]
    # KUKA: R = Rz(A)·Ry(B)·Rx(C), so the planner's own numbers are a valid triple, in degrees
    assert abc == pytest.approx([math.degrees(yaw), math.degrees(pitch), math.degrees(roll)], abs=1e-9)
    assert rz(math.radians(abc[0])) @ ry(math.radians(abc[1])) @ rx(math.radians(abc[2])) == pytest.approx(by_hand, abs=1e-12)
    # pitch 95.5° > 90°: the canonical triple has B = 180 − 95.5 and A, C turned by 180°
    canonical = rpy_to_abc([[roll, pitch, yaw]], "canonical")[0]
    assert canonical == pytest.approx([math.degrees(yaw) - 180, 180 - math.degrees(pitch), math.degrees(roll) - 180], abs=1e-9)
    assert rotation_from_abc(canonical) == pytest.approx(by_hand, abs=1e-12)
    joints = [-4.08444, -2.6946, 1.69873, -2.031, 0.99275, -0.0673035]
    assert series.joints[i] == pytest.approx(np.degrees(joints), abs=1e-9)  # rad → deg
    assert series.temperature[i] == pytest.approx(21.68000031)
    assert series.measured[i] == pytest.approx([335.14778, -3134.3677, -221.16088], abs=1e-9)  # mm, as is
    # intrinsic X-Y-Z: rotate about x, then the new y, then the newest z = Rx·Ry·Rz
    r, p, y = np.radians([-84.20352, -22.726835, -88.245609])
    assert series.measured_rotation[i] == pytest.approx(rx(r) @ ry(p) @ rz(y), abs=1e-12)


def test_every_row_keeps_its_rotation(series, text):
    rows = [line.split(";") for line in text.splitlines()[1:]]
    rpy = np.array([[float(row[k].replace(",", ".")) for k in (4, 5, 6)] for row in rows])
    by_hand = np.array([rz(c) @ ry(b) @ rx(a) for a, b, c in rpy])
    assert rotation_from_abc(series.commanded[:, 3:]) == pytest.approx(by_hand, abs=1e-12)
    canonical = read_ipa(EXCERPT, branch="canonical").commanded[:, 3:]
    assert np.all(np.abs(canonical[:, 1]) <= 90.0)
    assert rotation_from_abc(canonical) == pytest.approx(by_hand, abs=1e-12)


def test_conventions_agree_with_the_measurements(series):
    """The tracker sees the probe turn with the commanded orientation only under the stated conventions.

    After registration, R_goal⁻¹ · R_reg · R_measured must be one fixed rotation (the probe's
    frame in the TCP frame, up to the robot's orientation error of some 0.05°); reading the
    measured angles as extrinsic instead of intrinsic breaks that by tens of degrees.
    """
    measured, transform, rms = register_measurements(series.commanded[:, :3], series.measured, np.ones(150, bool))
    goal = rotation_from_abc(series.commanded[:, 3:])
    relative = np.swapaxes(goal, 1, 2) @ transform[:3, :3] @ series.measured_rotation
    assert relative.std(axis=0).max() < 0.005
    wrong = Rotation.from_matrix(series.measured_rotation).as_euler("XYZ")
    wrong = Rotation.from_euler("xyz", wrong).as_matrix()
    assert (np.swapaxes(goal, 1, 2) @ transform[:3, :3] @ wrong).std(axis=0).max() > 0.05
    # the UR10's uncompensated error is millimetres (Landgraf et al. 2021), not metres or microns
    error = np.linalg.norm(series.commanded[:, :3] - measured, axis=1)
    assert 2.0 < error.mean() < 10.0 and rms < 10.0


def _corrupt(text: str, line: int, field: int, value: str) -> str:
    lines = text.splitlines()
    cells = lines[line - 1].split(";")
    cells[field] = value
    lines[line - 1] = ";".join(cells)
    return "\n".join(lines) + "\n"


def test_decimal_comma_and_point(text):
    a = parse_ipa(text)
    b = parse_ipa(text.replace(",", "."))  # a file someone re-saved with decimal points reads the same
    assert np.array_equal(a.commanded, b.commanded) and np.array_equal(a.measured, b.measured)


@pytest.mark.parametrize("value", ["0,01o3459", "", "1,234,5", "nan"])
def test_malformed_number_names_file_line_and_column(text, value):
    bad = _corrupt(text, 5, 1, value)  # Goal x of file line 5
    with pytest.raises(PostprocError) as info:
        parse_ipa(bad, "series.csv")
    err = info.value
    assert (err.path, err.line, err.code) == ("series.csv", 5, "P502")
    assert err.col == len(bad.splitlines()[4].split(";")[0]) + 2  # after the timestamp and its ';'
    assert "Goal x" in err.message
    assert str(err).startswith("series.csv:5:")


def test_blank_lines_keep_line_numbers(text):
    lines = text.splitlines()
    bad = "\n".join(lines[:3] + [""] + lines[3:])  # the old line 4 is now line 5
    bad = _corrupt(bad, 8, 14, "x")
    with pytest.raises(PostprocError) as info:
        parse_ipa(bad)
    assert info.value.line == 8 and "measurement_x" in info.value.message
    assert len(parse_ipa("\n".join(lines[:3] + [""] + lines[3:]))) == 150


def test_structural_errors(text):
    lines = text.splitlines()
    short = "\n".join(lines[:6] + [lines[6].rsplit(";", 1)[0]] + lines[7:])
    with pytest.raises(PostprocError) as info:
        parse_ipa(short)
    assert (info.value.line, info.value.code) == (7, "P503")
    with pytest.raises(PostprocError) as info:
        parse_ipa(text.replace("elbow_joint", "elbow"))
    assert (info.value.line, info.value.code) == (1, "P501") and "elbow_joint" in info.value.message
    with pytest.raises(PostprocError) as info:
        parse_ipa(",".join(COLUMNS) + "\n1,2,3,4,5,6,7,8,9\n")
    assert info.value.code == "P501"
    with pytest.raises(PostprocError) as info:
        parse_ipa(lines[0] + "\n")
    assert info.value.code == "P500"


def _read_csv(path) -> tuple[list[str], np.ndarray]:
    with open(path, encoding="utf-8") as f:
        rows = list(csv.reader(line for line in f if not line.startswith("#")))
    return rows[0], np.array(rows[1:], dtype=float)


def test_import_writes_tracker_frame_csv(tmp_path, series, capsys):
    out = tmp_path / "measured.csv"
    assert main(["import", "ipa", str(EXCERPT), "-o", str(out)]) == 0
    assert out.read_text().startswith("# frame: tracker\n")
    assert read_metadata(out)["frame"] == "tracker"
    header, table = _read_csv(out)
    assert header == list(COLUMNS) + ["q1", "q2", "q3", "q4", "q5", "q6", "temperature"]
    assert table.shape == (150, 16)
    assert np.allclose(table[:, :6], series.commanded, rtol=1e-11, atol=1e-9)
    assert np.array_equal(table[:, 6:9], series.measured)  # every digit of the source kept
    assert np.allclose(table[:, 9:15], series.joints, rtol=1e-11, atol=1e-9)
    # what `postproc train` reads: the metadata lines are skipped, the extra columns ignored
    data = parse_measurements(out.read_bytes(), str(out))
    assert np.array_equal(data.poses, table[:, :6]) and np.array_equal(data.measured, table[:, 6:9])
    assert np.array_equal(data.lines, np.arange(4, 154))  # after 2 metadata lines and the header
    assert "150 rows" in capsys.readouterr().err


def test_import_register_fits_on_training_rows(tmp_path, series):
    out = tmp_path / "base.csv"
    assert main(["import", "ipa", str(EXCERPT), "-o", str(out), "--register", "--split-seed", "3", "-q"]) == 0
    meta = read_metadata(out)
    assert meta["frame"] == "base" and "120 rows" in meta["registration"]
    header, table = _read_csv(out)
    held = table[:, header.index("holdout")].astype(bool)
    assert np.array_equal(np.flatnonzero(held), split_indices(150, 0.2, 3)[1])  # train's own split
    expected, _, _ = register_measurements(series.commanded[:, :3], series.measured, ~held)
    assert np.allclose(table[:, 6:9], expected, atol=1e-6)
    transform = np.array(meta["tracker_to_base"].split(), dtype=float).reshape(3, 4)
    assert np.allclose(series.measured @ transform[:, :3].T + transform[:, 3], expected, atol=1e-3)


def test_import_bad_file_exits_2_with_location(tmp_path, text, capsys):
    src = tmp_path / "bad.csv"
    src.write_text(_corrupt(text, 9, 3, "1,0,6"))
    out = tmp_path / "never.csv"
    assert main(["import", "ipa", str(src), "-o", str(out)]) == 2
    assert f"{src}:9:" in capsys.readouterr().err and not out.exists()

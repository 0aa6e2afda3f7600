"""`postproc import` of the tools cells use (issue 27): SpatialAnalyzer point exports (+ the plan),
RoboDK-style calibration tables, three-reflector flange measurements. Each reads its sample in
samples/import/ (made by make_samples.py from the simulated robot, the tracker at TRACKER) back to
the simulator's own measurement; a file of another shape is refused at its line; units and
frame must be stated (no silent metres)."""
from __future__ import annotations

import importlib.util

import numpy as np
import pytest
from helpers import REPO

from postproc.core import frames
from postproc.cli import main
from postproc.core.diagnostics import PostprocError
from postproc.measurements.trackers import read_reflectors, read_robodk, read_spatial_analyzer
from postproc.measurements.csv import read_measurements

SAMPLES = REPO / "samples" / "import"
_spec = importlib.util.spec_from_file_location("make_samples", SAMPLES / "make_samples.py")
make = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(make)


@pytest.fixture(scope="module")
def truth():
    """What the simulator measured (robot base) for the samples' plan, in visiting order."""
    from postproc.calibration.planning import latin_hypercube
    from postproc.calibration.simulator import SimulatedRobot

    poses = latin_hypercube(make.N, seed=21)
    sim = SimulatedRobot.from_file(None, None)
    q = sim.joint_angles(poses, None, None)
    return poses, q, sim.measure(poses, rng_seed=0, orientation=True, q_deg=q)


def _base(points):
    """Tracker-frame points [N, 3] in the robot base (the samples' made-up tracker set-up)."""
    m = frames.frame_to_matrix(make.TRACKER)
    return points @ m[:3, :3].T + m[:3, 3]


def test_spatial_analyzer_points_matched_by_name_in_visiting_order(truth):
    poses, _, measured = truth
    data = read_spatial_analyzer(SAMPLES / "sa_points.txt", SAMPLES / "sa_plan.csv")
    assert data.frame == "tracker" and len(data) == make.N
    np.testing.assert_allclose(data.commanded, poses, atol=1e-4)  # the plan's order, not the export's
    np.testing.assert_allclose(_base(data.measured), measured[:, :3], atol=1e-3)  # metres converted


def test_robodk_table_commanded_is_the_joints_fk(truth):
    poses, q, measured = truth
    data = read_robodk(SAMPLES / "robodk_calibration.csv")
    np.testing.assert_allclose(data.extra["q1"], q[:, 0], atol=1e-5)
    np.testing.assert_allclose(data.commanded[:, :3], poses[:, :3], atol=1e-3)
    np.testing.assert_allclose(_base(data.measured), measured[:, :3], atol=1e-3)


def test_three_reflectors_give_the_tcp_pose(truth):
    poses, _, measured = truth
    data = read_reflectors(SAMPLES / "three_reflectors.csv")
    np.testing.assert_allclose(_base(data.measured), measured[:, :3], atol=2e-3)
    turned = frames.frame_to_matrix(make.TRACKER)[:3, :3] @ frames.rotation_from_abc(data.orientation)
    err = frames.rotation_error_deg(frames.abc_from_rotation(turned), measured[:, 3:6])
    assert np.abs(err).max() < 5e-3  # deg: 1e-4 mm rounding over a 60 mm lever


@pytest.mark.parametrize("args", [
    ["spatialanalyzer", "sa_points.txt", "--poses", str(SAMPLES / "sa_plan.csv")],
    ["robodk", "robodk_calibration.csv"],
    ["reflectors", "three_reflectors.csv"],
])
def test_import_register_train_ready(args, tmp_path, truth):
    """The CLI with --register: a measurement CSV in the robot base that train reads."""
    out = tmp_path / "m.csv"
    args = [args[0], str(SAMPLES / args[1]), *args[2:]]
    assert main(["import", *args, "-o", str(out), "--register", "-q"]) == 0
    data = read_measurements(out)
    assert data.meta["frame"] == "base" and len(data.poses) == make.N
    # the registration recovers the tracker's set-up: every point within the robot's own error of the truth
    assert np.abs(data.measured - truth[2][:, :3]).max() < 0.5
    if args[0] == "reflectors":
        assert data.orientation is not None


def _write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_units_and_frame_must_be_stated(tmp_path):
    text = (SAMPLES / "three_reflectors.csv").read_text()
    no_units = _write(tmp_path, "a.csv", text.replace("# units: mm, deg\n", ""))
    with pytest.raises(PostprocError, match="does not state the units") as info:
        read_reflectors(no_units)
    assert info.value.code == "P530"
    no_frame = _write(tmp_path, "b.csv", text.replace("# frame: tracker\n", ""))
    with pytest.raises(PostprocError, match="does not state the frame"):
        read_reflectors(no_frame)
    sa = (SAMPLES / "sa_points.txt").read_text().replace("// units: m\n", "")
    with pytest.raises(PostprocError, match="units") as info:
        read_spatial_analyzer(_write(tmp_path, "c.txt", sa), SAMPLES / "sa_plan.csv")
    assert info.value.code == "P530"
    furlongs = text.replace("# units: mm, deg", "# units: furlong, deg")
    with pytest.raises(PostprocError, match="units"):
        read_reflectors(_write(tmp_path, "d.csv", furlongs))


def test_a_file_of_another_shape_is_refused_at_its_line(tmp_path):
    # a measurement CSV of ours given as a RoboDK table: no J1..J6 (located at the header)
    with pytest.raises(PostprocError, match="no column j1") as info:
        read_robodk(REPO / "samples" / "ipa" / "series_c_excerpt.csv")
    assert info.value.code == "P501"
    # a row with a field missing, a value that is not a number
    lines = (SAMPLES / "robodk_calibration.csv").read_text().splitlines()
    short = lines[:6] + [lines[6].rsplit(",", 1)[0]] + lines[7:]
    with pytest.raises(PostprocError) as info:
        read_robodk(_write(tmp_path, "short.csv", "\n".join(short)))
    assert (info.value.line, info.value.code) == (7, "P503")
    bad = lines[:4] + [lines[4].replace(",", ",abc,", 1).replace(",abc,", ",", 0)] + lines[5:]
    bad[4] = ",".join(["5", "x1.0"] + lines[4].split(",")[2:])
    with pytest.raises(PostprocError) as info:
        read_robodk(_write(tmp_path, "nan.csv", "\n".join(bad)))
    assert (info.value.line, info.value.col, info.value.code) == (5, 3, "P502")


def test_reflectors_that_do_not_fit_are_refused_at_their_row(tmp_path):
    lines = (SAMPLES / "three_reflectors.csv").read_text().splitlines()
    row = lines[9].split(",")
    row[6:9], row[9:12] = row[9:12], row[6:9]  # r1 and r2 swapped
    lines[9] = ",".join(row)
    with pytest.raises(PostprocError, match="do not fit") as info:
        read_reflectors(_write(tmp_path, "swap.csv", "\n".join(lines)))
    assert (info.value.line, info.value.code) == (10, "P531")
    collinear = (SAMPLES / "three_reflectors.csv").read_text().replace(
        "# reflectors: 100,0,40; -40,40,40; -10,-60,70", "# reflectors: 0,0,0; 10,0,0; 20,0,0")
    with pytest.raises(PostprocError, match="collinear") as info:
        read_reflectors(_write(tmp_path, "line.csv", collinear))
    assert (info.value.line, info.value.code) == (4, "P531")


def test_points_without_their_pose_are_refused(tmp_path):
    plan = (SAMPLES / "sa_plan.csv").read_text().replace("P017,", "P999,")
    with pytest.raises(PostprocError, match="'P017' names no pose") as info:
        read_spatial_analyzer(SAMPLES / "sa_points.txt", _write(tmp_path, "plan.csv", plan))
    assert info.value.code == "P532" and info.value.path.endswith("sa_points.txt")
    unnamed = "x,y,z,a,b,c\n" + "\n".join(ln.split(",", 1)[1] for ln in plan.splitlines()[1:-1]) + "\n"
    with pytest.raises(PostprocError, match="40 points but 39 poses"):
        read_spatial_analyzer(SAMPLES / "sa_points.txt", _write(tmp_path, "unnamed.csv", unnamed))
    assert main(["import", "spatialanalyzer", str(SAMPLES / "sa_points.txt"), "-o", str(tmp_path / "o.csv")]) == 2


def test_the_samples_are_what_make_samples_writes(tmp_path, monkeypatch):
    monkeypatch.setattr(make, "HERE", tmp_path)
    make.main()
    for name in ("sa_points.txt", "sa_plan.csv", "robodk_calibration.csv", "three_reflectors.csv"):
        assert (tmp_path / name).read_text() == (SAMPLES / name).read_text(), name

"""Orientation end to end on the simulated robot, and the measurement CSV's s,t columns.

plan → measure (a 6-DOF probe: a_meas,b_meas,c_meas) → train (the hybrid default fits the
orientation with the position) → compensate --orientation → the simulated robot reaches the
targets' orientation (and position). A model trained without orientation data has no
``rotation_error`` output, says so in its card, and --orientation refuses it (P306).
"""
import json
import os

import numpy as np
import pytest

from postproc.cli import main
from postproc.model.compensator import load_model
from postproc.calibration.planning import read_pose_csv
from postproc.calibration.simulator import SimulatedRobot
from postproc.measurements.csv import read_measurements


def _cli(*args) -> int:
    return main([str(a) for a in args])


def _rows(text: str) -> list[str]:
    """A measurement CSV's header and rows, without its '# key: value' lines (measure writes
    '# simulated: …' and '# robot_seed: …' above the header)."""
    return [line for line in text.splitlines() if not line.startswith("#")]


def _without(text: str, names: set[str]) -> str:
    """The CSV text with the columns ``names`` removed (and its '# key: value' lines)."""
    lines = _rows(text)
    keep = [i for i, h in enumerate(lines[0].split(",")) if h not in names]
    return "\n".join(",".join(f for i, f in enumerate(line.split(",")) if i in keep) for line in lines) + "\n"


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    """300 poses measured on the default simulated robot, a model trained on them by the
    default ``postproc train`` and a separate 120-pose test plan."""
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    d = tmp_path_factory.mktemp("orientation")
    assert _cli("plan", "-n", 300, "--seed", 1, "-o", d / "plan.csv", "-q") == 0
    assert _cli("measure", d / "plan.csv", "-o", d / "measured.csv", "-q") == 0
    assert _cli("train", d / "measured.csv", "-o", d / "m.onnx", "--val-fraction", 0.1, "-q") == 0
    assert _cli("plan", "-n", 120, "--seed", 7, "-o", d / "test.csv", "-q") == 0
    return d


@pytest.mark.slow
def test_orientation_compensation_reaches_the_simulated_targets(simulated):
    d = simulated
    model = load_model(d / "m.onnx")
    assert model.has_rotation
    card = model.metadata["identified"]["orientation"]
    assert card["fitted"] and card["lever_mm_per_rad"] > 0
    assert _cli("compensate", d / "test.csv", "-o", d / "test_o.csv", "--model", d / "m.onnx", "--orientation",
                "-q") in (0, 1)
    assert _cli("compensate", d / "test.csv", "-o", d / "test_p.csv", "--model", d / "m.onnx", "-q") in (0, 1)
    targets, _ = read_pose_csv(d / "test.csv")
    with_orientation, _ = read_pose_csv(d / "test_o.csv")
    position_only, _ = read_pose_csv(d / "test_p.csv")
    assert not np.allclose(with_orientation[:, 3:], targets[:, 3:])  # A,B,C were rewritten
    np.testing.assert_array_equal(position_only[:, 3:], targets[:, 3:])  # ...only with --orientation
    sim = SimulatedRobot()
    got = sim.verify(targets, with_orientation, rng_seed=1)
    ref = sim.verify(targets, position_only, rng_seed=1)
    before, after = got["orientation_before"], got["orientation_after"]
    assert before["mean"] > 0.2  # the robot's orientation error, uncompensated (deg)
    assert after["mean"] < 0.05 * before["mean"] and after["max"] < 0.2 * before["mean"]
    # the position is compensated as well as without --orientation
    assert got["after"]["mean"] < 0.15 * got["before"]["mean"]
    assert got["after"]["mean"] <= 1.1 * ref["after"]["mean"] + 0.005
    assert ref["orientation_after"]["mean"] > 0.8 * before["mean"]  # (position-only leaves the orientation)


def _pose_list_commands(d):
    """The pose list's commands with --orientation (the test plan compensated by the model)."""
    if not (d / "test_o.csv").exists():
        assert _cli("compensate", d / "test.csv", "-o", d / "test_o.csv", "--model", d / "m.onnx", "--orientation",
                    "-q") in (0, 1)
    return read_pose_csv(d / "test_o.csv")[0]


def test_krl_orientation_matches_the_pose_list_in_a_turned_base(simulated):
    """A KRL program's A/B/C are located and corrected as a pose list's (they were refused,
    P312): the same targets in a shifted and turned $BASE, compensated with --orientation, land
    on the pose list's commands once taken back to the robot base — position and orientation."""
    from postproc.core import frames
    from postproc.compensation.api import compensate_text
    from postproc.programs.io import parse_program_text

    d = simulated
    model = load_model(d / "m.onnx")
    targets, _ = read_pose_csv(d / "test.csv")
    expected = _pose_list_commands(d)
    base = np.array([100.0, -50.0, 20.0, 30.0, 0.0, 0.0])
    local = frames.matrix_to_frame(frames.inverse(frames.frame_to_matrix(base)) @ frames.frame_to_matrix(targets))
    tool = model.metadata["tool"]["frame"]
    show = lambda p: ",".join(f"{k} {v:.4f}" for k, v in zip("XYZABC", p))  # noqa: E731
    text = "\n".join([f"DEF turned( )", "  $BASE = {" + show(base) + "}", "  $TOOL = {" + show(tool) + "}",
                      *("  LIN {" + show(p) + "}" for p in local), "END", ""])
    out, report = compensate_text(text, model, name="turned.src", orientation=True)
    assert report.compensated == len(targets)
    commands = parse_program_text(out, "turned.src").targets.poses
    in_base = frames.matrix_to_frame(frames.frame_to_matrix(base) @ frames.frame_to_matrix(commands))
    assert np.abs(in_base[:, :3] - expected[:, :3]).max() < 2e-3  # mm (4 decimals in, 3 out)
    turn = np.linalg.norm(frames.rotation_error_deg(expected[:, 3:], in_base[:, 3:]), axis=-1)
    assert turn.max() < 2e-3  # deg
    assert np.linalg.norm(frames.rotation_error_deg(local[:, 3:], commands[:, 3:]), axis=-1).mean() > 0.1


def test_krl_named_targets_in_the_dat_get_their_orientation_too(simulated):
    """E6POS variables in the .dat (the round-trip guard reads the written module again, A/B/C
    included) are corrected as the pose list's targets."""
    from postproc.core import frames
    from postproc.compensation.api import compensate_text
    from postproc.programs.io import parse_program_text

    d = simulated
    model = load_model(d / "m.onnx")
    targets, _ = read_pose_csv(d / "test.csv")
    expected = _pose_list_commands(d)
    show = lambda p: ",".join(f"{k} {v:.4f}" for k, v in zip("XYZABC", p))  # noqa: E731
    src = "\n".join(["DEF named( )", "  $BASE = {X 0,Y 0,Z 0,A 0,B 0,C 0}",
                      "  $TOOL = {" + show(model.metadata["tool"]["frame"]) + "}",
                      *(f"  LIN XP{k}" for k in range(len(targets))), "END", ""])
    dat = "\n".join(["DEFDAT named", *(f"DECL E6POS XP{k}={{{show(p)}}}" for k, p in enumerate(targets)), "ENDDAT", ""])
    out, report = compensate_text(src, model, name="named.src", dat_text=dat, orientation=True)
    assert report.compensated == len(targets)
    new_dat = next(text for name, text in report.outputs.items() if name.endswith(".dat"))
    written = parse_program_text(out, "named.src", dat_text=new_dat).targets.poses
    assert np.abs(written[:, :3] - expected[:, :3]).max() < 2e-3
    assert np.linalg.norm(frames.rotation_error_deg(expected[:, 3:], written[:, 3:]), axis=-1).max() < 2e-3


def test_fanuc_ls_locates_w_p_r_in_a_b_c_order():
    """An LS position's orientation tokens, in A, B, C order (A = R, B = P, C = W): what
    --orientation rewrites, each corrected angle into its own token."""
    from postproc.programs.io import parse_program_text

    pos = ("P[1]{\n   GP1:\n\tUF : 0, UT : 1,\t\tCONFIG : 'N U T, 0, 0, 0',\n\tX =   2000.000  mm,\tY =   -10.500  mm,"
           "\tZ =   900.000  mm,\n\tW =   -4.250 deg,\tP =    97.125 deg,\tR =  -  9.500 deg\n};")
    text = "\n".join(["/PROG  T", "/ATTR", "LINE_COUNT\t= 1;", "/MN", "   1:L P[1] 100mm/sec FINE ;", "/POS", pos,
                      "/END", ""])
    t = parse_program_text(text, "t.ls", config_texts=["[utool.1]\nxyzwpr = [0, 0, 100, 0, 0, 0]\n"]).targets
    tokens = [text[a:b] for a, b in t.abc_spans[0]]
    assert [float(tok.replace(" ", "")) for tok in tokens] == [-9.5, 97.125, -4.25] == t.poses[0, 3:].tolist()


def test_report_gives_the_orientation_error_before_and_after(simulated, capsys):
    d = simulated
    assert _cli("measure", d / "test.csv", "-o", d / "before.csv", "-q") == 0
    assert _cli("report", d / "before.csv", "--model", d / "m.onnx", "-o", d / "report") == 0
    numbers = json.loads((d / "report" / "summary.json").read_text())["orientation_deg"]
    assert numbers["before"]["mean"] > 0.2 and numbers["after"]["mean"] < 0.05 * numbers["before"]["mean"]
    assert "orientation error mean" in capsys.readouterr().err
    assert "orientation error (deg" in (d / "report" / "report.md").read_text()


def test_without_orientation_data_the_model_has_no_rotation_output(simulated, capsys):
    d = simulated
    (d / "position.csv").write_text(_without((d / "measured.csv").read_text(), {"a_meas", "b_meas", "c_meas"}))
    assert _cli("train", d / "position.csv", "-o", d / "p.onnx", "--method", "kinematic", "-q") == 0
    model = load_model(d / "p.onnx")
    assert not model.has_rotation
    assert model.metadata["identified"]["orientation"] == {"fitted": False}
    capsys.readouterr()
    assert _cli("compensate", d / "test.csv", "-o", d / "no.csv", "--model", d / "p.onnx", "--orientation") == 2
    assert f"{d / 'p.onnx'}: P306" in capsys.readouterr().err
    assert not (d / "no.csv").exists()


def test_orientation_in_radians_is_refused_with_its_line(simulated, capsys):
    d = simulated
    lines = _rows((d / "measured.csv").read_text())
    header = lines[0].split(",")
    cols = [header.index(n) for n in ("a_meas", "b_meas", "c_meas")]
    out = [lines[0]]
    for line in lines[1:]:
        f = line.split(",")
        for i in cols:
            f[i] = f"{np.radians(float(f[i])):.8f}"
        out.append(",".join(f))
    (d / "radians.csv").write_text("\n".join(out) + "\n")
    assert _cli("train", d / "radians.csv", "-o", d / "r.onnx", "--method", "kinematic") == 2
    err = capsys.readouterr().err
    assert f"{d / 'radians.csv'}:" in err and "P515" in err
    assert not (d / "r.onnx").exists()


def test_status_turn_columns_become_the_stated_joint_angles(tmp_path, capsys):
    from postproc.robot.configuration import measurement_joints
    from postproc.robot.description import load_description

    assert _cli("plan", "-n", 40, "--seed", 2, "--wrist", "both", "-o", tmp_path / "plan.csv", "-q") == 0
    assert _cli("measure", tmp_path / "plan.csv", "-o", tmp_path / "m.csv", "-q") == 0
    full = read_measurements(tmp_path / "m.csv")
    text = _without((tmp_path / "m.csv").read_text(), {f"q{i}" for i in range(1, 7)})
    rows = text.splitlines()
    header = rows[0].split(",")
    s_col = header.index("s")
    fields = rows[5].split(",")  # file line 6: the overhead area (S bit 0), out of reach for this pose
    fields[s_col] = str(int(fields[s_col]) ^ 1)
    rows[5] = ",".join(fields)
    (tmp_path / "st.csv").write_text("\n".join(rows) + "\n")
    data = read_measurements(tmp_path / "st.csv")
    assert data.joints is None and data.status_turn.shape == (40, 2)
    q, keep, notes = measurement_joints(load_description(), data)
    assert keep.sum() == 39 and not keep[4]
    wrapped = (q[keep] - full.joints[keep] + 180.0) % 360.0 - 180.0
    assert np.abs(wrapped).max() < 1e-3  # the joint angles the simulated controller used
    assert {int(np.sign(v)) for v in full.joints[:, 4]} == {-1, 1}  # (both wrist configurations)
    assert len(notes) == 1 and f"{tmp_path / 'st.csv'}:6:1: P514" in notes[0]
    # and train takes them (the warning names the row)
    assert _cli("train", tmp_path / "st.csv", "-o", tmp_path / "st.onnx", "--method", "kinematic",
                "--val-fraction", 0) == 0
    assert ":6:1: P514" in capsys.readouterr().err


def test_measurement_columns_are_checked_where_they_are_wrong():
    from postproc.core.diagnostics import PostprocError
    from postproc.measurements.csv import parse_measurements

    head = "x,y,z,a,b,c,x_meas,y_meas,z_meas"
    row = "2000,0,900,0,90,0,2000.1,0,900"
    with pytest.raises(PostprocError) as partial:
        parse_measurements(f"{head},a_meas,b_meas\n{row},0.1,90\n".encode(), "m.csv")
    assert str(partial.value).startswith("m.csv:1:1: P501")
    with pytest.raises(PostprocError) as status:
        parse_measurements(f"{head},s,t\n{row},2,10\n{row.replace('2000,', '2010,', 1)},2.5,10\n".encode(), "m.csv")
    assert str(status.value).startswith("m.csv:3:") and "P502" in str(status.value) and "'s'" in str(status.value)
    m = parse_measurements(f"{head},a_meas,b_meas,c_meas,s,t\n{row},0.1,90,0,2,10\n".encode(), "m.csv")
    assert m.status_turn.tolist() == [[2, 10]]
    # the orientation error is the rotation vector commanded → measured (here 0.1° about the base Z)
    np.testing.assert_allclose(m.rotation_errors, [[0.0, 0.0, 0.1]], atol=1e-9)


def test_ipa_import_with_registration_writes_the_tcp_orientation(tmp_path):
    from postproc.core.resources import sample_path

    src = sample_path("ipa/series_c_excerpt.csv")
    assert _cli("import", "ipa", src, "-o", tmp_path / "base.csv", "--register", "-q") == 0
    data = read_measurements(tmp_path / "base.csv")
    assert "probe_rotation" in data.meta and data.orientation is not None
    angle = np.linalg.norm(data.rotation_errors, axis=1)
    # the probe's own axes are turned ~180° on the flange: taken out, the UR10's orientation error is left
    assert 0.01 < angle.mean() < 0.2 and angle.max() < 0.5
    # without --register the tracker's frame is kept and no orientation is written
    assert _cli("import", "ipa", src, "-o", tmp_path / "tracker.csv", "-q") == 0
    assert read_measurements(tmp_path / "tracker.csv").orientation is None

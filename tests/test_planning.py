"""Latin hypercube plans, the plan CSV, the KRL measurement program, and the plan/measure commands."""
import numpy as np
import pytest

from postproc.core import frames
from postproc.cli import main
from postproc.programs.io import load_program
from postproc.programs.base_poses import robot_base_poses
from postproc.core.diagnostics import PostprocError
from postproc.calibration.planning import DEFAULT_BOX, latin_hypercube, parse_pose_csv, read_pose_csv


def test_latin_hypercube_is_one_point_per_stratum_in_every_dimension():
    n = 50
    poses = latin_hypercube(n, box=(0, 100, -10, 10, 5, 6), attitude=(0, 90, 0), range_deg=10, seed=4)
    lo = np.array([0, -10, 5, -10, 80, -10])
    hi = np.array([100, 10, 6, 10, 100, 10])
    strata = np.floor((poses - lo) / (hi - lo) * n).astype(int)
    for d in range(6):
        assert sorted(strata[:, d]) == list(range(n))
    np.testing.assert_array_equal(poses, latin_hypercube(n, (0, 100, -10, 10, 5, 6), (0, 90, 0), 10, seed=4))
    assert not np.allclose(poses, latin_hypercube(n, (0, 100, -10, 10, 5, 6), (0, 90, 0), 10, seed=5))


def test_plan_writes_csv_and_a_krl_program_the_reader_understands(tmp_path):
    plan, src = tmp_path / "plan.csv", tmp_path / "measure.src"
    assert main(["plan", "-n", "40", "--seed", "3", "-o", str(plan), "--krl", str(src), "-q"]) == 0
    lines = plan.read_text().splitlines()
    assert lines[0] == "x,y,z,a,b,c" and len(lines) == 41
    poses, numbers = read_pose_csv(plan)
    assert numbers.tolist() == list(range(2, 42))
    box = np.array(DEFAULT_BOX)
    assert np.all((poses[:, :3] >= box[0::2]) & (poses[:, :3] <= box[1::2]))
    assert np.all(np.abs(poses[:, 3:] - [0, 90, 0]) <= 10)
    text = src.read_text()
    assert text.count("\nLIN {") == 41 and text.count("MEASURE_HERE( )") == 41  # + retreat; + the DEF
    assert "DEF measure( )" in text and "WAIT SEC 1.00" in text and "WAIT FOR $IN[1]" in text
    # the lead's KRL reader finds every measurement pose, in order, with the same numbers
    program = load_program(src)
    base_poses, resolved = robot_base_poses(program)
    assert resolved.all()
    # approach PTP first, retreat LIN last; A,B,C compared as rotations (the reader may write
    # B > 90° as the equivalent A±180, 180−B, C±180)
    np.testing.assert_allclose(base_poses[1:-1, :3], poses[:, :3], atol=1e-9)
    np.testing.assert_allclose(frames.rotation_from_abc(base_poses[1:-1, 3:]), frames.rotation_from_abc(poses[:, 3:]),
                               atol=1e-9)
    np.testing.assert_allclose(base_poses[0, :3], poses[0, :3] + [0, 0, 100])


def test_plan_refuses_poses_out_of_reach_and_writes_nothing(tmp_path, capsys):
    plan, src = tmp_path / "plan.csv", tmp_path / "m.src"
    code = main(["plan", "-n", "20", "--box", "3000", "3600", "-100", "100", "500", "900", "-o", str(plan),
                 "--krl", str(src)])
    assert code == 2
    assert "out of reach of KR500-sim" in capsys.readouterr().err
    assert not plan.exists() and not src.exists()
    assert list(tmp_path.iterdir()) == []


def test_measure_writes_the_training_csv_in_visiting_order(tmp_path):
    plan, out = tmp_path / "plan.csv", tmp_path / "measured.csv"
    plan.write_text("# my plan\nid,X,Y,Z,A,B,C\n1,2000,0,900,0,90,0\n\n"
                    "2,2100,100,800,2,88,-1\n3,1800,-200,1000,0,95,5\n")
    assert main(["measure", str(plan), "-o", str(out), "--seed", "4", "-q"]) == 0
    lines = out.read_text().splitlines()
    # the simulator's data say so (a model trained on them says it is a demonstration model, P340)
    assert lines[:2] == ["# simulated: KR500-sim", "# robot_seed: 8"]
    assert lines[2] == "x,y,z,a,b,c,x_meas,y_meas,z_meas,a_meas,b_meas,c_meas,q1,q2,q3,q4,q5,q6"
    table = np.loadtxt(out, delimiter=",", skiprows=3)
    np.testing.assert_array_equal(table[:, :6], [[2000, 0, 900, 0, 90, 0], [2100, 100, 800, 2, 88, -1],
                                                 [1800, -200, 1000, 0, 95, 5]])
    assert np.all(np.linalg.norm(table[:, 6:9] - table[:, :3], axis=1) < 3)
    # the probe's orientation: near the commanded, written as the program writes it (B 95, not 85)
    from postproc.core.frames import rotation_from_abc

    relative = rotation_from_abc(table[:, 3:6]).swapaxes(-1, -2) @ rotation_from_abc(table[:, 9:12])
    angle = np.degrees(np.arccos(np.clip((np.trace(relative, axis1=1, axis2=2) - 1) / 2, -1, 1)))
    assert np.all((angle > 1e-3) & (angle < 1.0))
    assert np.abs(table[:, 10] - table[:, 4]).max() < 1.0
    # the controller's joint angles: the nominal FK gives the commanded pose back
    from postproc.robot.arm import Robot

    np.testing.assert_allclose(Robot().fk(table[:, 12:18])[:, :3], table[:, :3], atol=1e-3)
    # the training reader takes it as it is
    from postproc.measurements.csv import read_measurements

    assert len(read_measurements(out)) == 3


@pytest.mark.parametrize("content, line, col, code", [
    ("x,y,z,a,b,c\n2000,0,900,0,90,0\n2000,0,900,0,90\n", 3, 1, "P503"),
    ("x,y,z,a,b,c\n2000,0,900,0,90,0\n2000,zero,900,0,90,0\n", 3, 6, "P502"),
    ("x,y,z,a,b\n2000,0,900,0,90\n", 1, 1, "P501"),
    ("x,y,z,a,b,c\n2000,0,900,0,90,0\n9000,0,900,0,90,0\n", 3, 1, "P335"),
])
def test_measure_bad_input_says_where_and_writes_nothing(tmp_path, capsys, content, line, col, code):
    plan, out = tmp_path / "plan.csv", tmp_path / "measured.csv"
    plan.write_text(content)
    assert main(["measure", str(plan), "-o", str(out)]) == 2
    assert capsys.readouterr().err.startswith(f"{plan}:{line}:{col}: {code} ")
    assert not out.exists()


def test_pose_csv_reader_ignores_extra_columns_and_comments():
    poses, lines = parse_pose_csv("# head\nc,B,a,z,y,x,note\n6,5,4,3,2,1,hello\n# mid\n\n12,11,10,9,8,7,x\n")
    np.testing.assert_array_equal(poses, [[1, 2, 3, 4, 5, 6], [7, 8, 9, 10, 11, 12]])
    assert lines.tolist() == [3, 6]
    with pytest.raises(PostprocError, match="no rows"):
        parse_pose_csv("x,y,z,a,b,c\n")


def test_plan_with_both_wrists_is_measured_in_its_configurations(tmp_path):
    from postproc.robot.arm import Robot

    plan, out, src = tmp_path / "plan.csv", tmp_path / "m.csv", tmp_path / "meas.src"
    assert main(["plan", "-n", "40", "--wrist", "both", "-o", str(plan), "--krl", str(src), "-q"]) == 0
    header = plan.read_text().splitlines()[0]
    assert header == "x,y,z,a,b,c,s,t"
    st = np.loadtxt(plan, delimiter=",", skiprows=1)[:, 6:8].astype(int)
    pairs = np.arange(len(st)) // 2 % 2 == 1  # rows 2, 3 of every four flipped: both wrists, each
    assert (st[~pairs, 0] & 4 == 0).mean() > 0.9 and (st[pairs, 0] & 4 == 4).mean() > 0.9  # approached from both
    ptp = [ln for ln in src.read_text().splitlines() if ln.startswith("PTP {X")]
    assert len(ptp) == 41 and all(",S 'B" in ln and ",T 'B" in ln for ln in ptp)
    assert main(["measure", str(plan), "-o", str(out), "-q"]) == 0
    table = np.loadtxt(out, delimiter=",", skiprows=3)  # ('# simulated: …', '# robot_seed: …', the header)
    robot = Robot()
    s, t = robot.status_turn(table[:, 12:18])
    np.testing.assert_array_equal(np.stack([s, t], axis=1), st)  # measured in the stated configurations
    np.testing.assert_array_equal(table[:, 18:20], st)


def test_measure_with_another_tool_records_it(tmp_path):
    plan, out = tmp_path / "plan.csv", tmp_path / "m.csv"
    plan.write_text("x,y,z,a,b,c\n2000,0,900,0,90,0\n2100,100,800,2,88,-1\n")
    assert main(["measure", str(plan), "-o", str(out), "--tool", "150,20,250,0,0,0", "-q"]) == 0
    # (after the lines that say the data are the simulator's: '# simulated: KR500-sim', '# robot_seed: 8')
    assert out.read_text().splitlines()[:3] == ["# simulated: KR500-sim", "# robot_seed: 8", "# tool: 150,20,250,0,0,0"]
    from postproc.robot.arm import Robot
    from postproc.robot.description import load_description

    table = np.loadtxt(out, delimiter=",", skiprows=4)
    arm = Robot(load_description().replace(tool=np.array([150.0, 20, 250, 0, 0, 0])))
    np.testing.assert_allclose(arm.fk(table[:, 12:18])[:, :3], table[:, :3], atol=1e-3)


def test_read_plan_reads_every_column_once_and_locates_a_bad_status_on_its_file_line(tmp_path):
    """read_plan: poses, s,t, labels, tools, loads and the '# key: value' lines of one file; a bad
    s value is reported at its own line, counting the lines above the header."""
    from postproc.calibration.planning import read_plan
    from postproc.core.diagnostics import PostprocError

    plan = tmp_path / "plan.csv"
    head = "# tool: 0,0,150,0,0,0\n# note: two rows\nx,y,z,a,b,c,s,t,pose,tool_x,tool_y,tool_z,tool_a,tool_b,tool_c\n"
    plan.write_text(head + "1,2,3,4,5,6,2,2,1,0,0,150,0,0,0\n\n7,8,9,10,11,12,6,58,2,0,10,150,0,0,0\n")
    p = read_plan(plan)
    assert p.poses.tolist() == [[1, 2, 3, 4, 5, 6], [7, 8, 9, 10, 11, 12]] and p.lines.tolist() == [4, 6]
    assert p.config.tolist() == [[2, 2], [6, 58]] and p.labels["pose"].tolist() == [1, 2]
    assert p.tools[:, 1].tolist() == [0, 10] and p.loads is None
    assert p.metadata == {"tool": "0,0,150,0,0,0", "note": "two rows"}
    plan.write_text(head + "1,2,3,4,5,6,2,2,1,0,0,150,0,0,0\n7,8,9,10,11,12,x,58,2,0,10,150,0,0,0\n")
    with pytest.raises(PostprocError) as err:
        read_plan(plan)
    assert err.value.line == 5 and "column s" in str(err.value)

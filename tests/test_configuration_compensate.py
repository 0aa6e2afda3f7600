"""compensate passes the controller's joint angles (from S/T) and the $TOOL to a model that takes them."""
import numpy as np
import pytest

from postproc.testing.models import joint_model
from postproc.compensation.api import compensate_text
from postproc.model.compensator import load_model
from postproc.robot.arm import Robot

GAIN = np.array([[0.3, -0.2, 0.5, 0.1, 0.4, -0.3],
                 [0.1, 0.4, -0.2, 0.3, -0.5, 0.2],
                 [-0.4, 0.2, 0.3, -0.1, 0.2, 0.5]])  # mm per unit sin(q)


def _poses(robot, q):
    return robot.fk(q)


def _csv(poses, status=None, turn=None, joints=None):
    head = "x,y,z,a,b,c" + (",s,t" if status is not None else "") + (",q1,q2,q3,q4,q5,q6" if joints is not None else "")
    lines = [head]
    for i, p in enumerate(poses):
        row = [f"{v:.6f}" for v in p]
        if status is not None:
            row += ["" if status[i] < 0 else str(status[i]), "" if turn[i] < 0 else str(turn[i])]
        if joints is not None:
            row += [f"{v:.6f}" for v in joints[i]]
        lines.append(",".join(row))
    return "\n".join(lines) + "\n"


def _read_xyz(text):
    rows = [r.split(",") for r in text.splitlines() if r and r[0] in "-0123456789"]
    return np.array([[float(v) for v in r[:3]] for r in rows])


@pytest.fixture
def q_targets():
    # wrist flipped and not, elbow both ways, in the workspace
    return np.array([[5.0, -60.0, 100.0, 30.0, 50.0, 20.0],
                     [5.0, -60.0, 100.0, -150.0, -50.0, -160.0],
                     [-10.0, -75.0, 110.0, 10.0, 40.0, 0.0],
                     [-10.0, -75.0, 110.0, -170.0, -40.0, 180.0 - 360.0]])


def test_the_joint_angles_of_each_targets_stated_branch_reach_the_model(tmp_path, q_targets):
    robot = Robot()
    model = load_model(joint_model(tmp_path / "j.onnx", GAIN))
    assert model.wants_joints and not model.wants_tool
    poses = _poses(robot, q_targets)
    status, turn = robot.status_turn(q_targets)
    out, report = compensate_text(_csv(poses, status, turn), model, name="p.csv")
    assert report.compensated == 4 and not report.warnings
    correction = _read_xyz(out) - poses[:, :3]
    # one fixed-point iteration per default (2): the joints stay the target's, so Ê is the same each time
    expected = np.sin(np.radians(q_targets)) @ GAIN.T
    np.testing.assert_allclose(correction, expected, atol=2e-6)
    # rows 0/1 and 2/3 are the same pose in two configurations: different corrections
    np.testing.assert_allclose(poses[0], poses[1], atol=1e-6)
    assert np.abs(correction[0] - correction[1]).max() > 0.1


def _krl_text(poses, motions):
    body = "".join(f"{m} {{X {p[0]:.5f}, Y {p[1]:.5f}, Z {p[2]:.5f}, A {p[3]:.5f}, B {p[4]:.5f}, C {p[5]:.5f}}}\n"
                   for p, m in zip(poses, motions))
    return "DEF p( )\n$BASE = {X 0, Y 0, Z 0, A 0, B 0, C 0}\n$TOOL = {X 300, Y 0, Z 75, A 0, B 0, C 0}\n" + body + "END\n"


def _krl_xyz(text):
    import re

    return np.array([[float(v) for v in re.findall(r"[XYZ] (-?[\d.]+)", line)[:3]]
                     for line in text.splitlines() if line.startswith(("PTP", "LIN"))])


def test_without_status_the_controllers_rule_decides(tmp_path, q_targets):
    from postproc.compensation.pipeline import compensate_program
    from postproc.programs.io import parse_program_text

    robot = Robot()
    model = load_model(joint_model(tmp_path / "j.onnx", GAIN))
    q_all = q_targets[1] + np.array([[0, 0, 0, 0, 0, 0], [1, 1, -1, 1, 1, 1], [2, 2, -2, 2, 2, 2]])
    poses = robot.fk(q_all)
    status, turn = robot.status_turn(q_all[:1])
    expected = np.sin(np.radians(q_all)) @ GAIN.T
    # KRL: the PTP states its (flipped-wrist) configuration, the LINs after it keep it
    program = parse_program_text(_krl_text(poses, ["PTP", "LIN", "LIN"]), "p.src")
    program.targets.config = np.array([[status[0], turn[0]], [-1, -1], [-1, -1]], np.int16)
    report = compensate_program(program, model)
    np.testing.assert_allclose(_krl_xyz(report.outputs["p.src"]) - poses[:, :3], expected, atol=2e-5)
    # a pose list's rows without s,t: each on the branch nearest HOME (as measure reaches a plan)
    out, _ = compensate_text(_csv(poses, np.array([status[0], -1, -1]), np.array([turn[0], -1, -1])), model,
                             name="p.csv")
    q_home, _ = robot.ik(poses)
    assert np.abs(q_home[1:] - q_all[1:]).max() > 90
    np.testing.assert_allclose(_read_xyz(out) - poses[:, :3],
                               np.vstack([expected[:1], np.sin(np.radians(q_home[1:])) @ GAIN.T]), atol=2e-5)


def test_joint_columns_are_passed_as_they_are(tmp_path, q_targets):
    robot = Robot()
    model = load_model(joint_model(tmp_path / "j.onnx", GAIN))
    poses = _poses(robot, q_targets)
    fake = q_targets + 7.0  # whatever the program says, the model gets it
    out, _ = compensate_text(_csv(poses, joints=fake), model, name="p.csv")
    np.testing.assert_allclose(_read_xyz(out) - poses[:, :3], np.sin(np.radians(fake)) @ GAIN.T, atol=2e-6)


def test_a_configuration_without_solution_is_left_as_written_with_p309(tmp_path, q_targets):
    robot = Robot()
    model = load_model(joint_model(tmp_path / "j.onnx", GAIN))
    poses = _poses(robot, q_targets)
    status, turn = robot.status_turn(q_targets)
    turn[2] ^= 1 << 4  # A5's sign against the wrist bit of S: no such joint angles
    text = _csv(poses, status, turn)
    out, report = compensate_text(text, model, name="p.csv")
    assert report.compensated == 3 and report.skipped == 1
    (w,) = [d for d in report.warnings if d.code == "P309"]
    assert (w.line, w.col) == (4, 1)
    assert text.splitlines()[3] in out.splitlines()  # (after the stamp line)
    with pytest.raises(Exception, match="P309"):
        compensate_text(text, model, name="p.csv", strict=True)


def test_a_model_with_a_tool_input_gets_each_targets_tool_and_takes_any_tool(tmp_path):
    import re

    from postproc.compensation.pipeline import compensate_program
    from postproc.programs.io import parse_program_text

    robot = Robot()
    tool_gain = np.array([[0.001, 0, 0, 0, 0, 0], [0, 0.002, 0, 0, 0, 0], [0, 0, -0.001, 0, 0, 0]])
    model = load_model(joint_model(tmp_path / "t.onnx", GAIN, tool_gain=np.asarray(tool_gain)[:, :6]))
    assert model.wants_tool
    tool = np.array([150.0, 40.0, 250.0, 0.0, 0.0, 0.0])  # not the model's spindle [300, 0, 75]
    q = np.array([[5.0, -60.0, 100.0, 30.0, 50.0, 20.0], [0.0, -70.0, 95.0, 10.0, -30.0, 5.0]])
    arm = Robot(robot.description.replace(tool=tool))
    poses = arm.fk(q)
    status, turn = arm.status_turn(q)
    src = ("DEF p( )\n$BASE = {X 0, Y 0, Z 0, A 0, B 0, C 0}\n"
           f"$TOOL = {{X {tool[0]}, Y {tool[1]}, Z {tool[2]}, A 0, B 0, C 0}}\n"
           + "".join(f"PTP {{X {p[0]:.5f}, Y {p[1]:.5f}, Z {p[2]:.5f}, A {p[3]:.5f}, B {p[4]:.5f}, C {p[5]:.5f}, "
                     f"S {s}, T {t}}}\n" for p, s, t in zip(poses, status, turn)) + "END\n")
    program = parse_program_text(src, "p.src")
    if getattr(program.targets, "config", None) is None:
        # the KRL reader states no S/T yet (the krl branch adds Targets.config): give them here
        program.targets.config = np.stack([status, turn], axis=1).astype(np.int16)
    report = compensate_program(program, model)  # no P304: the model takes the tool
    assert report.compensated == 2
    out = report.outputs["p.src"]
    got = np.array([[float(v) for v in re.findall(r"[XYZ] (-?[\d.]+)", line)[:3]]
                    for line in out.splitlines() if line.startswith("PTP")])
    expected = np.sin(np.radians(q)) @ GAIN.T + tool[:3] @ tool_gain[:, :3].T
    np.testing.assert_allclose(got - poses[:, :3], expected, atol=2e-5)


ROT = np.array([[0.02, -0.01, 0.03, 0.01, -0.02, 0.015],
                [0.01, 0.02, -0.015, 0.02, 0.01, -0.01],
                [-0.02, 0.01, 0.01, -0.01, 0.02, 0.02]])  # deg of rotation error per unit sin(q)


def test_orientation_is_corrected_by_the_models_rotation_error(tmp_path, q_targets):
    from postproc.cli import main
    from postproc.core.frames import rotation_from_abc
    from postproc.core.frames import small_transform

    robot = Robot()
    model_file = joint_model(tmp_path / "r.onnx", GAIN, rotation_gain=ROT)
    poses = robot.fk(q_targets)
    status, turn = robot.status_turn(q_targets)
    program, out = tmp_path / "p.csv", tmp_path / "out.csv"
    program.write_text(_csv(poses, status, turn))
    assert main(["compensate", str(program), "-o", str(out), "--model", str(model_file), "--orientation", "-q"]) == 0
    rows = [r.split(",") for r in out.read_text().splitlines() if r and r[0] in "-0123456789"]
    written = np.array([[float(v) for v in r[:6]] for r in rows])
    np.testing.assert_allclose(written[:, :3] - poses[:, :3], np.sin(np.radians(q_targets)) @ GAIN.T, atol=2e-6)
    # the robot turns the command by r (nominal → actual): it lands on the target's orientation
    r = np.radians(np.sin(np.radians(q_targets)) @ ROT.T)
    landed = small_transform(r, np.zeros((len(r), 3)))[:, :3, :3] @ rotation_from_abc(written[:, 3:6])
    np.testing.assert_allclose(landed, rotation_from_abc(poses[:, 3:6]), atol=2e-6)  # (6 decimals written)
    assert np.abs(written[:, 3:6] - poses[:, 3:6]).max() > 0.005  # A/B/C really changed
    assert np.abs(written[:, 3:6] - poses[:, 3:6]).max() < 1.0  # on the triple as written


def test_orientation_needs_a_model_with_rotation_error(tmp_path, q_targets, capsys):
    from postproc.cli import main

    robot = Robot()
    model_file = joint_model(tmp_path / "j.onnx", GAIN)
    program, out = tmp_path / "p.csv", tmp_path / "out.csv"
    status, turn = robot.status_turn(q_targets)
    program.write_text(_csv(robot.fk(q_targets), status, turn))
    assert main(["compensate", str(program), "-o", str(out), "--model", str(model_file), "--orientation"]) == 2
    assert "P306" in capsys.readouterr().err and not out.exists()


def test_ur_type_arm_targets_get_their_branch_joints(tmp_path):
    from postproc.core.resources import model_path
    from postproc.robot.description import load_description

    ur = Robot(load_description(model_path("ur10.toml")))
    model = load_model(joint_model(tmp_path / "ur.onnx", GAIN, robot="UR10",
                                   tool={"name": "probe", "frame": ur.tool.tolist()}))
    q = np.array([[20.0, -80.0, 70.0, -60.0, 50.0, 30.0], [20.0, -80.0, 70.0, -60.0, -50.0, 30.0],
                  [-30.0, -100.0, -60.0, 200.0, 80.0, -150.0]])
    poses = ur.fk(q)
    status, turn = ur.status_turn(q)
    out, report = compensate_text(_csv(poses, status, turn), model, name="p.csv")
    assert report.compensated == 3
    np.testing.assert_allclose(_read_xyz(out) - poses[:, :3], np.sin(np.radians(q)) @ GAIN.T, atol=2e-6)


def test_a_model_for_a_robot_without_description_is_refused(tmp_path, q_targets):
    from postproc.core.diagnostics import PostprocError

    model = load_model(joint_model(tmp_path / "x.onnx", GAIN, robot="KR1000-unknown"))
    with pytest.raises(PostprocError, match="P311"):
        compensate_text(_csv(Robot().fk(q_targets)), model, name="p.csv")


def test_a_model_without_the_joints_input_leaves_targets_in_another_configuration(tmp_path, capsys):
    # a pose-only model (no 'joints' input) evaluates its own IK's branch: a target whose S/T
    # flips the wrist is another arm configuration, left as written with P313, never
    # compensated for the wrong joints; the same pose with the S/T of that branch is compensated
    from postproc.cli import main
    from postproc.robot.arm import Robot
    from postproc.robot.description import load_description
    from postproc.core.resources import model_path
    from postproc.testing.models import affine_model

    robot = Robot(load_description(model_path("kr500.toml")))
    model = affine_model(tmp_path / "pose_only.onnx", offset=(0.2, -0.1, 0.3), gain=np.diag([1e-3, -2e-3, 5e-4]),
                         tool={"name": "spindle", "frame": [300, 0, 75, 0, 0, 0]})
    pose = np.array([[2000.0, 100.0, 900.0, 0.0, 90.0, 0.0]])
    q, _ = robot.ik(pose, robot.home_q)
    s, t = (int(v[0]) for v in robot.status_turn(q))
    flipped = q.copy()
    flipped[:, 3] += 180.0
    flipped[:, 4] *= -1.0
    flipped[:, 5] += 180.0
    flipped = (flipped + 180.0) % 360.0 - 180.0
    s_flip, t_flip = (int(v[0]) for v in robot.status_turn(flipped))
    assert s_flip != s  # the wrist bit
    for status, turn, code in ((s, t, 0), (s_flip, t_flip, 1)):
        src = tmp_path / f"p{status}.src"
        src.write_text("DEF p()\n  $BASE = {X 0,Y 0,Z 0,A 0,B 0,C 0}\n  $TOOL = {X 300,Y 0,Z 75,A 0,B 0,C 0}\n"
                       f"  PTP {{X 2000.0,Y 100.0,Z 900.0,A 0.0,B 90.0,C 0.0,S {status},T {turn}}}\nEND\n")
        assert main(["compensate", str(src), "-o", str(tmp_path / f"out{status}.src"), "--model", str(model)]) == code
        err = capsys.readouterr().err
        assert ("P313" in err) == (code == 1), err

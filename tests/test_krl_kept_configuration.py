"""KRL LIN and CIRC keep the configuration the robot is in: KUKA's controller reads Status and
Turn on PTP only (issue 39). A CP motion whose S/T state another configuration is compensated
for the one the robot keeps, with a located note (P314); its S/T stay as written."""
import re

import numpy as np

from postproc.cli import main
from postproc.compensation.api import compensate_text
from postproc.model.compensator import load_model
from postproc.programs import ActiveFrames
from postproc.programs.io import parse_program_text
from postproc.robot import conventions
from postproc.robot.arm import Robot
from postproc.robot.description import load_description
from postproc.testing.models import joint_model

TOOL = "300,0,75,0,0,0"
STATED = ActiveFrames.of(base=0, tool=TOOL)
# the issue's program: a PTP on the wrist S 2, then a LIN whose S/T state the flipped wrist
PTP = "PTP {X 2015.074,Y -315.396,Z 1235.422,A -60.2269,B 70.0575,C -75.3419,S 2,T 2}"
LIN = "LIN {X 2005.124,Y -415.386,Z 1230.742,A -69.9472,B 68.4106,C -82.2409,S 6,T 58}"


def program(*lines: str) -> str:
    return "DEF lin()\n" + "".join(f"  {line}\n" for line in lines) + "END\n"


def written(text: str, motion: int) -> list[float]:
    """X, Y, Z of the ``motion``-th motion line (1: the first; a stamp line above is not one)."""
    rows = [row for row in text.splitlines() if re.match(r"\s*(PTP|LIN|CIRC) ", row)]
    return [float(v) for v in re.findall(r"[XYZ] (-?[\d.]+)", rows[motion - 1])[:3]]


def test_the_issues_lin_is_compensated_in_the_wrist_the_robot_keeps():
    model = load_model()  # (the shipped model takes the controller's joint angles)
    out, report = compensate_text(program(PTP, LIN), model, name="lin.src", active=STATED)
    kept, _ = compensate_text(program(PTP, LIN.replace("S 6,T 58", "S 2,T 2")), model, name="lin.src", active=STATED)
    bare, _ = compensate_text(program(PTP, LIN.replace(",S 6,T 58", "")), model, name="lin.src", active=STATED)
    assert written(out, 2) == written(kept, 2) == written(bare, 2)  # the S/T written on a LIN change nothing
    # the kept wrist's correction: a PTP there with the S/T of the wrist kept, not of the one written
    ptp = lambda st: written(compensate_text(program(PTP, LIN.replace("LIN", "PTP").replace("S 6,T 58", st)),  # noqa: E731
                                             model, name="lin.src", active=STATED)[0], 2)
    assert written(out, 2) == ptp("S 2,T 2")
    assert np.linalg.norm(np.subtract(written(out, 2), ptp("S 6,T 58"))) > 0.5
    assert "S 6,T 58}" in [row for row in out.splitlines() if "LIN" in row][0]  # the S/T stay as written
    assert report.complete and report.compensated == 2
    (note,) = [n for n in report.notes if n.code == "P314"]
    assert (note.path, note.line, note.severity) == ("lin.src", 3, "note")
    assert "S 2, T 2, not the S 6, T 58 written here" in note.message
    assert "P314" in report.summary()


def test_a_ptp_reads_its_status_and_turn():
    """The same S/T on a PTP choose the flipped wrist: its correction is another (the contrast)."""
    model = load_model()
    flipped, report = compensate_text(program(PTP.replace("S 2,T 2", "S 6,T 58")), model, name="p.src", active=STATED)
    kept, _ = compensate_text(program(PTP), model, name="p.src", active=STATED)
    assert np.linalg.norm(np.subtract(written(flipped, 1), written(kept, 1))) > 1.0
    assert not [n for n in report.notes if n.code == "P314"]


def test_every_cp_motion_keeps_the_configuration_and_a_matching_s_t_says_nothing(tmp_path):
    """A model whose correction is the sine of each joint (E = G·sin q): a LIN and a CIRC after a
    PTP get the correction of the configuration the PTP left, whatever S/T they write; where
    they write the kept one, no note."""
    description = load_description()
    robot = Robot(description.replace(tool=np.array([300.0, 0, 75, 0, 0, 0])))
    gain = np.array([[0.0, 0.3, 0.0, 0.4, 0.0, 0.5], [0.2, 0.0, 0.0, 0.0, 0.6, 0.0], [0.0, 0.0, 0.3, 0.0, 0.0, 0.4]])
    model = load_model(joint_model(tmp_path / "joints.onnx", gain, tool={"name": "spindle", "frame": [300, 0, 75, 0, 0, 0]}))
    lin_pose = [2005.124, -415.386, 1230.742, -69.9472, 68.4106, -82.2409]
    aux = [2010.0, -380.0, 1232.0, -65.0, 69.0, -79.0]
    circ = "CIRC {X %.3f,Y %.3f,Z %.3f,A %.4f,B %.4f,C %.4f,S 6,T 58},{X %.3f,Y %.3f,Z %.3f,A %.4f,B %.4f,C %.4f,S 6,T 58}" % (
        *aux, *lin_pose)
    text = program(PTP, LIN, circ)
    out, report = compensate_text(text, model, name="c.src", active=STATED)
    q_ptp, _ = robot.ik(np.array([[2015.074, -315.396, 1235.422, -60.2269, 70.0575, -75.3419]]), robot.home_q)
    s_ptp, _ = conventions.status_turn_of(robot, q_ptp)
    assert s_ptp[0] == 2
    # each CP target commanded at P + G·sin(q), q its pose on the PTP's branch (the kept wrist)
    commanded = np.array(written(out, 2))
    q_kept, ok = robot.ik_branches(np.array([[*commanded, *lin_pose[3:]]]), q_ptp)
    s_all, _ = conventions.status_turn_of(robot, q_kept[:, 0])
    q = q_kept[np.flatnonzero(ok[:, 0] & (s_all == 2))[0], 0]
    np.testing.assert_allclose(commanded - lin_pose[:3], gain @ np.sin(np.radians(q)), atol=2e-3)
    notes = [n for n in report.notes if n.code == "P314"]
    assert [n.line for n in notes] == [3, 4, 4]  # the LIN, the CIRC's auxiliary point and its end
    assert report.complete
    # written with the kept S/T: the same commands, no note
    same, again = compensate_text(text.replace("S 6,T 58", "S 2,T 2"), model, name="c.src", active=STATED)
    assert [written(same, k) for k in (2, 3)] == [written(out, k) for k in (2, 3)]
    assert not [n for n in again.notes if n.code == "P314"]


def test_a_pose_only_model_does_not_leave_a_lin_for_its_s_t(tmp_path):
    """P313 judges the S/T a target's motion reads: a LIN's are not (the PTP before it is)."""
    from postproc.testing.models import affine_model

    model = load_model(affine_model(tmp_path / "a.onnx", offset=(0.1, -0.2, 0.3),
                                    gain=np.diag([1e-4, -2e-4, 1e-4]), tool={"name": "spindle",
                                                                             "frame": [300, 0, 75, 0, 0, 0]}))
    out, report = compensate_text(program(PTP.replace(",S 2,T 2", ""), LIN), model, name="l.src", active=STATED)
    assert report.complete and "P313" not in {w.code for w in report.warnings}


def test_check_says_it_and_a_stdin_filter_writes_the_same(tmp_path, capsys):
    src = tmp_path / "lin.src"
    src.write_text(program(PTP, LIN))
    assert main(["check", str(src), "--base", "0", "--tool", TOOL]) == 0
    assert f"{src}:3:" in capsys.readouterr().out
    assert main(["compensate", str(src), "-o", str(tmp_path / "out.src"), "--base", "0", "--tool", TOOL, "-v"]) == 0
    err = capsys.readouterr().err
    assert re.search(rf"{re.escape(str(src))}:3:\d+: P314 ", err), err
    text = parse_program_text((tmp_path / "out.src").read_text(), "out.src", active=STATED)
    assert text.targets.config[1].tolist() == [6, 58]

"""KRL programs as the controller runs them (issue 24): each case the issue found in real cells,
a few lines each, compensated with a model whose correction varies over space and with where the
robot comes from, checked for the commands (or the located warning and the exit) and, through the
IR's interpreter, for the property: every executed target at P + Ê from its real predecessor, or
left as written and said so (``postproc.testing.oracle.check``)."""
from __future__ import annotations

import numpy as np
import pytest

from postproc.compensation.api import compensate_text
from postproc.model.compensator import load_model
from postproc.core.diagnostics import P212, P217, P231
from postproc.programs import ActiveFrames
from postproc.testing.models import affine_model
from postproc.testing.oracle import check

STATED = ActiveFrames(base=0, tool="model")
GAIN = np.array([[2e-3, 5e-4, 0.0], [0.0, 1.5e-3, 4e-4], [3e-4, 0.0, 2.5e-3]])


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    path = tmp_path_factory.mktemp("m") / "m.onnx"
    return load_model(affine_model(path, offset=(0.2, -0.1, 0.15), gain=GAIN, previous_gain=5e-5,
                                   tool={"name": "any"}))


def run(model, src, dat="DEFDAT t\nENDDAT\n", config=None, active=STATED):
    """(new .src, new .dat, report, the property check)."""
    new, report = compensate_text(src, model, name="t.src", dat_text=dat, config=config, active=active)
    cfg = None if config is None else [open(config, encoding="latin-1").read()]
    checked = check(["t.src", "t.dat"], [src, dat], "krl", model, config=cfg, active=active)
    assert checked.violations == [], checked.violations
    return new, report.outputs["t.dat"], report, checked


def codes(report):
    return sorted({w.code for w in report.warnings})


def number(text, name, comp):
    """The number of component ``comp`` of the aggregate declared as ``name`` in ``text``."""
    import re

    line = next(x for x in text.splitlines() if re.search(rf"\b{name}\s*=", x))
    return float(re.search(rf"\b{comp}\s+(-?[\d.]+)", line.split("=", 1)[1]).group(1))


DAT = ("DEFDAT t\n  DECL E6POS XS1={X 2000.0,Y 0.0,Z 900.0,A 0.0,B 90.0,C 0.0}\n"
       "  DECL E6POS XS2={X 1900.0,Y -100.0,Z 850.0,A 0.0,B 90.0,C 0.0}\n  DECL E6POS PT[5]\nENDDAT\n")


def test_a_point_copied_through_an_array_and_offset_is_compensated_for_the_pose_it_runs_at(model):
    # the only LIN XS1 sits after a GOTO and never runs: XS1's numbers serve XA alone, 300 mm higher
    src = ("DEF t( )\n  DECL E6POS XA\n  GOTO SKIP\n  LIN XS1\nSKIP:\n  PT[1] = XS1\n  XA = PT[1]\n"
           "  XA.Z = XA.Z + 300\n  LIN XA\nEND\n")
    new, dat, report, _ = run(model, src, DAT)
    assert report.complete and (report.compensated, report.targets) == (1, 1)
    executed = np.array([2000.0, 0.0, 1200.0])
    c = executed.copy()
    for _ in range(6):  # the fixed point c = P + Ê(c), reached from where the robot stood (itself)
        c = executed + model.predict(np.r_[c, 0, 90, 0][None], np.r_[c, 0, 90, 0][None])[0]
    assert [number(dat, "XS1", k) for k in "XYZ"] == pytest.approx((c - [0, 0, 300]).tolist(), abs=1e-3)


def test_a_base_number_set_in_a_branch_is_not_known_after_it(model, tmp_path):
    cfg = tmp_path / "$config.dat"
    cfg.write_text("DEFDAT $CONFIG\nDECL GLOBAL FRAME BASE_DATA[32]\nBASE_DATA[1]={X 10,Y 0,Z 0,A 0,B 0,C 0}\n"
                   "BASE_DATA[2]={X 0,Y 20,Z 0,A 30,B 0,C 0}\nENDDAT\n")
    src = ("DEF t( )\n  DECL INT nB\n  nB = 1\n  IF $IN[1] THEN\n    nB = 2\n  ENDIF\n  BAS(#BASE, nB)\n"
           "  LIN XS1\nEND\n")
    new, dat, report, _ = run(model, src, DAT, config=str(cfg))
    assert not report.complete and codes(report) == ["P201"] and report.left_codes == {"P201": 1}
    assert next(w for w in report.warnings if w.code == "P201").line == 7
    # both ways the same number: known
    same = src.replace("nB = 2", "nB = 1")
    new, dat, report, _ = run(model, same, DAT, config=str(cfg))
    assert report.complete


def test_a_point_and_a_number_changed_through_out_parameters(model, tmp_path):
    src = ("DEF t( )\n  Raise(XS1)\n  LIN XS1\nEND\n"
           "DEF Raise(P:OUT)\n  DECL E6POS P\n  P.Z = P.Z + 300\nEND\n")
    new, dat, report, _ = run(model, src, DAT)
    assert report.complete
    c = np.array([2000.0, 0.0, 1200.0])
    for _ in range(6):
        c = np.array([2000.0, 0.0, 1200.0]) + model.predict(np.r_[c, 0, 90, 0][None], np.r_[c, 0, 90, 0][None])[0]
    assert number(dat, "XS1", "Z") == pytest.approx(c[2] - 300, abs=1e-3)
    # an index through an OUT parameter: BAS reads the callee's value
    cfg = tmp_path / "$config.dat"
    cfg.write_text("DEFDAT $CONFIG\nDECL GLOBAL FRAME BASE_DATA[32]\nBASE_DATA[2]={X 0,Y 20,Z 0,A 30,B 0,C 0}\n"
                   "ENDDAT\n")
    src = ("DEF t( )\n  DECL INT nB\n  nB = 1\n  SetN(nB)\n  BAS(#BASE, nB)\n  LIN XS1\nEND\n"
           "DEF SetN(n:OUT)\n  DECL INT n\n  n = 2\nEND\n")
    new, dat, report, _ = run(model, src, DAT, config=str(cfg))
    assert report.complete


def test_a_point_passed_to_a_routine_not_read_is_left(model):
    src = "DEF t( )\n  EXT OffsetPoint(E6POS:OUT)\n  OffsetPoint(XS1)\n  LIN XS1\n  LIN XS2\nEND\n"
    new, dat, report, _ = run(model, src, DAT)
    # XS1 may have been changed (P211); the routine may have set $BASE too: XS2's frame not known
    assert not report.complete and report.left_codes == {"P211": 1, "P201": 1}
    assert number(dat, "XS1", "X") == 2000.0


def test_a_base_on_an_external_kinematic_or_with_a_correction_is_not_known(model, tmp_path):
    cfg = tmp_path / "$config.dat"
    body = ("DEFDAT $CONFIG\nDECL GLOBAL FRAME BASE_DATA[32]\nBASE_DATA[3]={X 10,Y 0,Z 0,A 0,B 0,C 0}\n"
            "DECL GLOBAL MACHINE_FRAME_T MACHINE_FRAME_DAT[32]\n"
            "MACHINE_FRAME_DAT[3]={MACH_DEF_INDEX 2,PARENT[] \"TURNTABLE\",GEOMETRY[] \" \"}\nENDDAT\n")
    cfg.write_text(body)
    src = "DEF t( )\n  BAS(#BASE, 3)\n  LIN XS1\nEND\n"
    new, dat, report, _ = run(model, src, DAT, config=str(cfg))
    assert not report.complete and "P225" in codes(report)
    assert "external kinematic MACHINE_DEF[2]" in next(w.message for w in report.warnings if w.code == "P225")
    # BASE_CORR on top of it, set at run time
    cfg.write_text(body.replace("MACH_DEF_INDEX 2", "MACH_DEF_INDEX 0"))
    src = "DEF t( )\n  BASE_CORR_ON = TRUE\n  BAS(#BASE, 3)\n  LIN XS1\nEND\n"
    new, dat, report, _ = run(model, src, DAT, config=str(cfg))
    assert not report.complete and codes(report) == ["P201"] and "BASE_CORR" in report.warnings[0].message


RELATIVE = DAT.replace("ENDDAT", "  DECL E6POS XR={X -200.0,Y 50.0,Z 100.0,A 0.0,B 0.0,C 0.0}\nENDDAT")


def test_a_compensated_point_used_as_the_base_in_a_callee_is_held(model):
    src = "DEF t( )\n  LIN XS1\n  setb()\n  LIN XR\nEND\nDEF setb( )\n  $BASE = XS1\nEND\n"
    new, dat, report, _ = run(model, src, RELATIVE)
    assert not report.complete and report.left_codes == {"P217": 1} and report.compensated == 1
    assert number(dat, "XS1", "X") == 2000.0 and number(dat, "XR", "X") != -200.0


def test_a_point_as_the_left_operand_of_a_composition_is_held_not_refused(model):
    src = "DEF t( )\n  LIN XS1\n  LIN XS1:XR\nEND\n"
    new, dat, report, _ = run(model, src, RELATIVE)
    assert report.left_codes == {"P217": 1} and report.compensated == 1
    assert number(dat, "XS1", "X") == 2000.0 and number(dat, "XR", "X") != -200.0


def test_the_spline_inline_forms_collision_function_keeps_the_frames(model):
    src = ("DEF t( )\n  $BASE = {X 0,Y 0,Z 0,A 0,B 0,C 0}\n"
           "  SLIN XS1 WITH $VEL = SVEL_CP(0.3, , LCPDAT4), $COLLMON_TOL_PRO[1] = USE_CM_PRO_VALUES(0) C_SPL\n"
           "  LIN XS2\nEND\n")
    new, dat, report, _ = run(model, src, DAT)
    assert report.complete and report.compensated == 2


def test_a_byte_order_mark_at_the_start_reads(model):
    src = "\xef\xbb\xbfDEF t( )\n  LIN {X 2000.0,Y 0.0,Z 900.0,A 0,B 90,C 0}\nEND\n"
    new, dat, report, _ = run(model, src)
    assert report.complete and new.startswith("\xef\xbb\xbf")


def test_targets_run_in_a_loop_after_branches_are_compensated_from_their_real_predecessors(model):
    src = ("DEF t( )\n  LIN XS1\n  IF $IN[1] THEN\n    LIN {X 2100,Y 100,Z 950,A 0,B 90,C 0}\n  ELSE\n"
           "    LIN XS2\n  ENDIF\n  FOR I = 1 TO 2\n    LIN {X 1950,Y 50,Z 1000,A 0,B 90,C 0}\n    LIN {Z 1020}\n"
           "  ENDFOR\nEND\n")
    new, dat, report, checked = run(model, src, DAT.replace("ENDDAT", "  DECL INT I\nENDDAT"))
    assert checked.compensated > 0 and checked.paths == 4


def test_a_joint_motion_to_known_axis_values_is_the_arm_configuration_a_target_after_it_keeps(tmp_path):
    """PTP to axis values the program states (E6AXIS), then a LIN: the LIN keeps that arm
    configuration (wrist flipped or not), which a model of the joints corrects differently; the
    command is the pose list's with the joint angles of that configuration."""
    from postproc.programs.io import parse_program_text
    from postproc.core.resources import model_path
    from postproc.robot.arm import Robot
    from postproc.robot.description import load_description
    from postproc.testing.models import joint_model

    gain = np.array([[0.3, -0.2, 0.5, 0.1, 0.4, -0.3], [0.1, 0.4, -0.2, 0.3, -0.5, 0.2],
                     [-0.4, 0.2, 0.3, -0.1, 0.2, 0.5]])
    tool = (0.0, 0.0, 200.0, 0.0, 0.0, 0.0)
    joints = load_model(joint_model(tmp_path / "j.onnx", gain, tool={"name": "t", "frame": list(tool)}))
    robot = Robot(load_description(model_path("kr500.toml")).replace(tool=np.array(tool)))
    target = np.array([[1900.0, 100.0, 1100.0, 0.0, 90.0, 0.0]])
    commands = []
    for start in ([10.0, -80.0, 95.0, 20.0, 40.0, 10.0], [10.0, -80.0, 95.0, -160.0, -40.0, -170.0]):
        src = ("DEF t( )\n  $BASE = $NULLFRAME\n  $TOOL = {X 0,Y 0,Z 200,A 0,B 0,C 0}\n"
               "  PTP {A1 %g,A2 %g,A3 %g,A4 %g,A5 %g,A6 %g}\n" % tuple(start)
               + "  LIN {X 1900.0,Y 100.0,Z 1100.0,A 0.0,B 90.0,C 0.0}\nEND\n")
        p = parse_program_text(src, "t.src")
        assert p.targets.start.tolist() == [start]  # (where the PTP left the arm)
        new, report = compensate_text(src, joints, name="t.src")
        assert report.complete and report.compensated == 1
        commanded = parse_program_text(new, "t.src").targets.poses[0, :3]
        q, ok = robot.ik(target, np.array(start))
        assert ok.all() and np.sign(q[0, 4]) == np.sign(start[4])  # (the branch of the start: its wrist)
        rows = "x,y,z,a,b,c,q1,q2,q3,q4,q5,q6\n" + ",".join(f"{v:.6f}" for v in [*target[0], *q[0]]) + "\n"
        listed, _ = compensate_text(rows, joints, name="l.csv")
        expected = parse_program_text(listed, "l.csv").targets.poses[0, :3]
        np.testing.assert_allclose(commanded, expected, atol=2e-3)
        commands.append(commanded)
    assert np.abs(commands[0] - commands[1]).max() > 0.1  # (the two wrists: two corrections)


def test_a_partial_target_after_a_tool_change_is_left_with_the_command_it_would_read(model):
    # at run time LIN {Z 900} takes X/Y from where the new tool's point stands: not the numbers
    # commanded under the tool before (the flange stays where that tool left it)
    src = ("DEF t( )\n  $TOOL = {X 0,Y 0,Z 100,A 0,B 0,C 0}\n  LIN XS1\n  $TOOL = {X 0,Y 0,Z 150,A 0,B 0,C 0}\n"
           "  LIN {Z 900.0}\n  LIN XS2\nEND\n")
    new, dat, report, checked = run(model, src, DAT)
    left = {(w.code, w.line) for w in report.warnings}
    assert (P212, 5) in left and (P217, 2) in left  # the partial target, and XS1 whose command it reads
    assert number(dat, "XS1", "X") == 2000.0 and number(dat, "XS2", "X") != 1900.0
    assert not report.complete and checked.compensated


def test_a_partial_target_after_the_same_tool_and_a_goto_takes_the_position_every_jump_leaves(model):
    src = ("DEF t( )\n  $TOOL = {X 0,Y 0,Z 100,A 0,B 0,C 0}\n  LIN XS1\n  GOTO L0\n  LIN XS2\nL0:\n  LIN {Z 950.0}\n"
           "END\n")
    new, dat, report, _ = run(model, src, DAT)
    assert report.complete and report.compensated == 2  # XS1 and {Z 950} at XS1's X/Y (written in)
    assert "X " in new.splitlines()[-2] and number(dat, "XS1", "X") != 2000.0


def test_a_point_one_path_copies_into_another_is_held_where_the_copy_runs(model):
    # after the IF, XS2.X is XS1's X token on one path and its own on the other: LIN XS2 is not
    # known, and XS1's numbers, which it may read, are not rewritten for LIN XS1 either
    src = ("DEF t( )\n  IF $IN[1] THEN\n    XS2.X = XS1.X + 0\n    LIN XS1\n  ENDIF\n  LIN XS2\nEND\n")
    new, dat, report, _ = run(model, src, DAT)
    assert number(dat, "XS1", "X") == 2000.0 and not report.complete
    assert {w.code for w in report.warnings} >= {P212, P217}


def test_a_point_also_run_at_an_offset_is_compensated_for_itself_and_the_offset_run_said(model):
    # LIN XS1 and, 300 mm higher, LIN XA (XS1's numbers + 300): one set of numbers cannot serve
    # both; XS1 gets its own correction, XA moves with it, and says so (P231), exit 1
    src = ("DEF t( )\n  DECL E6POS XA\n  LIN XS1\n  XA = XS1\n  XA.Z = XA.Z + 300\n  LIN XA\n  LIN XS2\nEND\n")
    new, dat, report, checked = run(model, src, DAT)
    assert (report.compensated, report.moved, report.left) == (2, 1, 0) and not report.complete
    assert [w.code for w in report.warnings] == [P231] and report.warnings[0].line == 2  # at XS1's declaration
    assert "1 motion to it at an offset (Offs/RelTool, a copy with a component changed; at t.src:6)" in \
        report.warnings[0].message  # the motion involved, named (LIN XA)
    assert "1 motion at an offset moved with the point's correction (P231)" in report.summary()
    assert number(dat, "XS1", "X") != 2000.0 and checked.compensated >= 2  # (the property held: run() checks)
    # without the run at the point itself, the offset run owns the numbers (compensated for where it runs)
    alone, _, report2, _ = run(model, src.replace("  LIN XS1\n", ""), DAT)
    assert report2.complete and report2.moved == 0


def test_a_partial_target_after_code_not_read_or_many_paths_holds_every_command_it_may_read(model):
    # gripper() is not read: it may not move, and LIN {Z 900} then takes X/Y from XS1's command
    src = "DEF t( )\n  LIN XS1\n  gripper()\n  LIN {Z 900.0}\n  LIN XS2\nEND\n"
    new, dat, report, _ = run(model, src, DAT)
    assert number(dat, "XS1", "X") == 2000.0 and P217 in {w.code for w in report.warnings}
    # more ways in than the predecessors the model keeps apart: every command it may stand at is held
    branches = "".join(f"  IF $IN[{i}] THEN\n    LIN {{X {1900 + 20 * i}.0,Y 0.0,Z 900.0,A 0.0,B 90.0,C 0.0}}\n  ENDIF\n"
                       for i in range(1, 7))
    src = "DEF t( )\n  LIN XS1\n" + branches + "  LIN {Z 950.0}\n  LIN XS2\nEND\n"
    new, dat, report, _ = run(model, src, DAT)
    assert number(dat, "XS1", "X") == 2000.0 and number(dat, "XS2", "X") != 1900.0


def test_the_first_target_after_a_joint_motion_to_known_axes_comes_from_where_they_put_the_tcp(model):
    # PTP to axis values, then LIN XS1: the robot comes from the TCP those axes give on the model's
    # robot (its nominal kinematics, the model's tool), not from XS1 itself (the first-target rule)
    from postproc.compensation.inputs import model_description
    from postproc.robot.arm import Robot

    axes = [0.0, -90.0, 90.0, 0.0, 60.0, 0.0]
    src = ("DEF t( )\n  PTP {A1 0.0,A2 -90.0,A3 90.0,A4 0.0,A5 60.0,A6 0.0}\n  LIN XS1\nEND\n")
    new, dat, report, _ = run(model, src, DAT)
    assert report.complete and report.compensated == 1
    description = model_description(model)
    before = Robot(description).fk(np.array([axes]))[0]
    p = np.array([2000.0, 0.0, 900.0, 0.0, 90.0, 0.0])
    c = p.copy()
    for _ in range(20):  # c = P + Ê(c) from where the axes put the TCP
        c[:3] = p[:3] + model.predict(c[None], before[None])[0]
    written = np.array([number(dat, "XS1", k) for k in "XYZ"])
    np.testing.assert_allclose(written, c[:3], atol=6e-4)
    itself = p.copy()
    for _ in range(20):  # (the first-target rule would have given another command)
        itself[:3] = p[:3] + model.predict(itself[None], itself[None])[0]
    assert np.abs(itself[:3] - c[:3]).max() > 2e-3

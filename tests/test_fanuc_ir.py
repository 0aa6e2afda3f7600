"""Fanuc LS on the motion IR (issue 24): each /MN construct the issue names, on a few lines of
program, as the controller runs it — the rows (one per executed motion, in execution order,
with their predecessors), the located warnings of what is left as written, and the commands a
model whose correction varies over space gives (in the positions' user frames)."""
from __future__ import annotations

import numpy as np
import pytest

from postproc.core import frames
from postproc.cli import main
from postproc.compensation.api import compensate_text
from postproc.programs.io import parse_program_text
from postproc.model.compensator import load_model
from postproc.core.diagnostics import PostprocError
from postproc.programs.fanuc import read_frames

FRAMES = """[uframe.1]
xyzwpr = [1200.0, -300.0, 450.0, 0.0, 0.0, 90.0]
[uframe.2]
xyzwpr = [800.0, 400.0, 100.0, 10.0, -5.0, 30.0]
[utool.1]
xyzwpr = [0.0, 0.0, 200.0, 0.0, 0.0, 0.0]
"""
UF1 = read_frames(FRAMES)[0][1]
OFFSET = np.array([0.3, -0.2, 0.1])
GAIN = np.array([[2e-3, 0, 0], [0, -1e-3, 5e-4], [0, 0, 3e-3]])
CENTRE = np.array([1500.0, 0.0, 600.0])


def pos(n, x, y=20.0, z=30.0, uf=1, ut=1, extra=""):
    return (f"P[{n}]{{\n   GP1:\n\tUF : {uf}, UT : {ut},\t\tCONFIG : 'N U T, 0, 0, 0',\n"
            f"\tX = {x:9.3f}  mm,\tY = {y:9.3f}  mm,\tZ = {z:9.3f}  mm,\n"
            f"\tW =   180.000 deg,\tP =     0.000 deg,\tR =     0.000 deg{extra}\n}};")


def program(mn, positions):
    """/MN lines from line 6 (instruction k at line 5 + k); the records after them."""
    lines = ["/PROG  T", "/ATTR", "OWNER\t\t= MNEDITOR;", "LINE_COUNT\t= 1;", "/MN"]
    lines += [f"{k:4d}:  {line} ;" for k, line in enumerate(mn, start=1)]
    return "\n".join(lines + ["/POS", *positions, "/END", ""])


def record_line(mn, k):
    """The line of the k-th record (1-based) of ``program(mn, …)`` (six lines each)."""
    return 5 + len(mn) + 2 + 6 * (k - 1)


def read(text, frames_text=FRAMES):
    return parse_program_text(text, "t.ls", config_texts=[frames_text] if frames_text else None)


def found(p):
    return [(d.code, d.line) for d in p.diagnostics]


P4 = [pos(k, 100.0 * k) for k in (1, 2, 3, 4)]


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    from postproc.testing.models import affine_model

    path = affine_model(tmp_path_factory.mktemp("lsir") / "affine.onnx", offset=OFFSET, gain=GAIN, centre=CENTRE,
                        reach=None, tool={"name": "any"})
    return load_model(path)


@pytest.fixture(scope="module")
def frames_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("lsframes") / "frames.toml"
    path.write_text(FRAMES)
    return str(path)


def error(xyz):
    return OFFSET + GAIN @ (np.asarray(xyz, float) - CENTRE)


def commanded_in_uf1(local):
    """What a target at ``local`` (user frame 1) is commanded at, back in user frame 1."""
    base = frames.transform_points(UF1, np.asarray(local, float)[None])[0]
    return frames.transform_points(frames.inverse(UF1), (base + error(base))[None])[0]


def test_jumps_and_labels_run_as_the_controller_runs_them():
    mn = ["LBL[1]", "L P[1] 100mm/sec FINE", "L P[2] 100mm/sec FINE", "IF R[1]=1,JMP LBL[1]", "L P[3] 100mm/sec FINE",
          "JMP LBL[9]", "L P[4] 100mm/sec FINE", "LBL[9]"]
    p = read(program(mn, P4))
    t = p.targets
    # P[1] after the start and after P[2] (the jump back), P[3] after P[2]; P[4] after a JMP: never runs
    assert t.line.tolist() == [record_line(mn, k) for k in (1, 2, 1, 3)] and t.prev.tolist() == [-1, 0, 1, 1]
    assert t.group.tolist() == [0, -1, 0, -1] and found(p) == []


def test_if_select_and_for_blocks():
    mn = ["IF (DI[1]=ON) THEN", "L P[1] 100mm/sec FINE", "ELSE", "L P[2] 100mm/sec FINE", "ENDIF",
          "L P[3] 100mm/sec FINE"]
    t = read(program(mn, P4)).targets
    assert t.line.tolist() == [record_line(mn, k) for k in (1, 2, 3, 3)] and t.prev.tolist() == [-1, -1, 1, 0]
    mn = ["SELECT R[1]=1,JMP LBL[1]", "       =2,JMP LBL[2]", "       ELSE,JMP LBL[3]", "LBL[1]",
          "L P[1] 100mm/sec FINE", "JMP LBL[3]", "LBL[2]", "L P[2] 100mm/sec FINE", "LBL[3]", "L P[3] 100mm/sec FINE"]
    t = read(program(mn, P4)).targets
    # (P[3] after P[1], after P[2], and from the start: the ELSE jumps to it before any motion)
    assert t.line.tolist() == [record_line(mn, k) for k in (1, 2, 3, 3, 3)] and t.prev.tolist() == [-1, -1, 1, 0, -1]
    mn = ["FOR R[1]=1 TO 3", "L P[1] 100mm/sec FINE", "ENDFOR", "L P[2] 100mm/sec FINE"]
    t = read(program(mn, P4)).targets
    assert t.line.tolist() == [record_line(mn, k) for k in (1, 1, 1, 2)] and t.prev.tolist() == [-1, 0, 1, 2]


def test_call_run_end_abort_pause_wait():
    mn = ["L P[1] 100mm/sec FINE", "CALL SUB1(1, R[2])", "L P[2] 100mm/sec FINE", "PAUSE", "L P[3] 100mm/sec FINE",
          "END", "L P[4] 100mm/sec FINE"]
    p = read(program(mn, P4))
    # after a program not read the robot stands where it left it (not known); END: P[4] never runs
    assert p.targets.line.tolist() == [record_line(mn, k) for k in (1, 2, 3)] and p.targets.prev.tolist() == [-1, -1, 1]
    mn = ["L P[1] 100mm/sec FINE", "ABORT", "L P[2] 100mm/sec FINE"]
    assert read(program(mn, P4)).targets.line.tolist() == [record_line(mn, 1)]
    mn = ["L P[1] 100mm/sec FINE", "WAIT DI[1]=ON TIMEOUT,LBL[9]", "L P[2] 100mm/sec FINE", "LBL[9]",
          "L P[3] 100mm/sec FINE"]
    t = read(program(mn, P4)).targets  # P[3] after P[2], or after P[1] where the WAIT timed out
    assert t.line.tolist() == [record_line(mn, k) for k in (1, 2, 3, 3)] and t.prev.tolist() == [-1, 0, 1, 0]
    # a program started with RUN may set any register while it runs
    mn = ["UFRAME_NUM=1", "UTOOL_NUM=1", "RUN BGPROG", "PR[1]=P[1]", "L PR[1] 100mm/sec FINE", "L P[2] 100mm/sec FINE"]
    p = read(program(mn, P4))
    assert p.targets.line.tolist() == [record_line(mn, 2)] and found(p) == [("P223", 10)]


def test_position_registers_copies_with_an_offset_are_compensated_consistently(model, frames_file):
    mn = ["UFRAME_NUM=1", "UTOOL_NUM=1", "PR[1]=P[1]", "PR[1,3]=PR[1,3]+100", "L PR[1] 100mm/sec FINE",
          "PR[1]=PR[1]-PR[1]"]  # (cleared: no other program reads P[1] from it)
    text = program(mn, [pos(1, 300.0, 20.0, 30.0)])
    p = read(text)
    t = p.targets
    assert t.line.tolist() == [record_line(mn, 1)] and t.offset.tolist() == [[0, 0, 100]] and found(p) == []
    out, report = compensate_text(text, model, name="t.ls", iterations=1, max_correction_mm=50, config=frames_file)
    assert report.compensated == 1
    again = read(out).targets  # the row: the token P[1] (written: the command minus the offset) + the offset
    assert np.allclose(again.poses[0, :3], commanded_in_uf1([300, 20, 130]), atol=6e-4)
    s, e = again.spans[0, 2]
    assert abs(float(out[s:e]) - (commanded_in_uf1([300, 20, 130])[2] - 100)) < 6e-4
    # PR[i]=PR[j]+PR[k]: component by component (a shift built in a cleared register)
    mn2 = ["UFRAME_NUM=1", "UTOOL_NUM=1", "PR[1]=P[1]", "PR[2]=PR[2]-PR[2]", "PR[2,1]=10", "PR[2,2]=-5",
           "PR[1]=PR[1]+PR[2]", "L PR[1] 100mm/sec FINE", "PR[1]=LPOS"]
    p = read(program(mn2, [pos(1, 300.0)]))
    assert p.targets.offset.tolist() == [[10, -5, 0]] and np.allclose(p.targets.poses[0, :3], [310, 15, 30])
    assert found(p) == []
    # a register the program leaves holding the position at its end: other programs may read it (P217)
    p = read(program(mn[:-1], [pos(1, 300.0)]))
    assert found(p) == [("P217", record_line(mn[:-1], 1))] and "PR[1] holds them at the program's end" in \
        p.diagnostics[0].message
    # a register's target is in the frames selected where it runs: none selected, not known
    mn = ["PR[1]=P[1]", "L PR[1] 100mm/sec FINE", "PR[1]=LPOS"]
    p = read(program(mn, [pos(1, 300.0)]))
    assert p.targets.frame.tolist() == [-1] and found(p) == [("P201", record_line(mn, 1))]
    assert "UFRAME_NUM is not set" in p.diagnostics[0].message


def test_offsets_known_and_not(model, frames_file):
    mn = ["OFFSET CONDITION PR[2]", "PR[2]=PR[2]-PR[2]", "PR[2,2]=-50", "L P[1] 100mm/sec FINE Offset",
          "L P[5] 100mm/sec FINE Offset,PR[3]", "L P[2] 100mm/sec FINE Tool_Offset,PR[2]", "L P[3] 100mm/sec FINE INC",
          "L P[4] 100mm/sec FINE VOFFSET,VR[1]"]
    text = program(mn, P4 + [pos(5, 500.0)])
    p = read(text)
    # Offset: PR[2] (the OFFSET CONDITION's) known: P[1] + (0, -50, 0); PR[3] not known (P211); Tool_Offset:
    # the shift in P[2]'s tool frame (W = 180: Y turned to -Y), P[2] + (0, 50, 0) in UF 1; INC: relative (P210);
    # a vision offset (P211)
    assert p.targets.line.tolist() == [record_line(mn, 1), record_line(mn, 2)]
    assert np.allclose(p.targets.offset, [[0, -50, 0], [0, 50, 0]])
    assert found(p) == [("P211", 10), ("P210", 12), ("P211", 13)]
    out, report = compensate_text(text, model, name="t.ls", iterations=1, max_correction_mm=50, config=frames_file)
    assert report.compensated == 2 and report.left == 3
    again = read(out).targets.poses
    assert np.allclose(again[0, :3], commanded_in_uf1([100, -30, 30]), atol=6e-4)
    assert np.allclose(again[1, :3], commanded_in_uf1([200, 70, 30]), atol=6e-4)


def test_a_frame_built_from_a_position_and_the_frames_a_program_sets():
    mn = ["UFRAME[2]=P[2]", "L P[1] 100mm/sec FINE", "L P[2] 100mm/sec FINE"]
    p = read(program(mn, [pos(1, 1.0, uf=2), pos(2, 4.0)]))
    # P[1] in the user frame P[2] gives; P[2]'s numbers are that frame too: left (P217)
    assert p.targets.line.tolist() == [record_line(mn, 1), record_line(mn, 2)]
    assert found(p) == [("P217", record_line(mn, 2))]
    f = p.frames[p.targets.frame[0]].base
    assert np.allclose(f, frames.frame_to_matrix([4, 20, 30, 0, 0, 180]))
    mn = ["UFRAME[2]=PR[5]", "L P[1] 100mm/sec FINE", "CALL SUB", "UTOOL_NUM=1", "L P[2] 100mm/sec FINE"]
    p = read(program(mn, [pos(1, 1.0, uf=2), pos(2, 4.0, uf=2)]))
    assert p.targets.frame.tolist() == [-1, -1] and found(p) == [("P201", 6), ("P232", 8)]  # (CALL SUB: not read)


def test_a_position_in_another_frame_than_the_selected_one_is_left():
    mn = ["UFRAME_NUM=2", "UTOOL_NUM=1", "L P[1] 100mm/sec FINE", "UFRAME_NUM=1", "UTOOL_NUM=2", "L P[1] 100mm/sec FINE",
          "UTOOL_NUM=1", "L P[1] 100mm/sec FINE"]
    p = read(program(mn, [pos(1, 100.0)]))
    assert p.targets.frame.tolist()[:2] == [-1, -1] and p.targets.frame[2] >= 0
    assert [c for c, _ in found(p)] == ["P201", "P203"] and "user frame mismatch" in p.diagnostics[0].message


def test_line_tracking_leaves_the_targets():
    text = program(["L P[1] 100mm/sec FINE"], [pos(1, 100.0)]).replace("/MN", "/APPL\n  LINE_TRACK;\n"
                                                                          "  LINE_TRACK_SCHEDULE_NUMBER : 1;\n/MN")
    p = read(text)
    assert p.targets.frame.tolist() == [-1] and [c for c, _ in found(p)] == ["P201"]
    assert "LINE_TRACK" in p.diagnostics[0].message


def test_skip_jumps_where_its_condition_is_not_met():
    mn = ["L P[1] 100mm/sec FINE Skip,LBL[2],PR[3]=LPOS", "L P[2] 100mm/sec FINE", "LBL[2]", "L P[3] 100mm/sec FINE"]
    t = read(program(mn, P4)).targets
    # met: the motion stops where it is (P[2] from there: not known); not met: it ends at P[1], on to LBL[2]
    assert t.line.tolist() == [record_line(mn, k) for k in (1, 2, 3, 3)] and t.prev.tolist() == [-1, -1, 1, 0]


def test_untaught_positions_extended_axes_and_controller_sub_lines():
    untaught = pos(3, 0.0).replace("     0.000  mm", " ********  mm").replace("X =     0.000", "X =  ********")
    untaught = untaught.replace("Y =    20.000", "Y =  ********").replace("Z =    30.000", "Z =  ********")
    track = pos(4, 400.0).replace(" deg\n}", " deg,\tE1 =  1500.000  mm\n}")
    text = program(["UTOOL_NUM=1", "J P[1] 100% CNT0 ACC100 TB    .10sec,P-SPS"], [pos(1, 100.0), pos(2, 200.0), untaught,
                                                                                   track])
    text = text.replace("   2:  J P[1] 100% CNT0 ACC100 TB    .10sec,P-SPS ;\n",
                        "   2:J P[1] 100% CNT0 ACC100 TB    .10sec,P-SPS    ;\n      1:  TC_ONLINE (ON) ;\n"
                        "      2:  DO[23]=OFF ;\n      3:  WAIT (DI[23])    ;\n       ------ ;\n"
                        "   3:J P[2] 100% CNT100 ACC100 TB   0.00sec,P-SPS    ;\n      1:  TC_ONLINE (M[2]) ;\n"
                        "       ------ ;\n   4:L P[3] 100mm/sec FINE ;\n   5:L P[4] 100mm/sec FINE ;\n")
    p = read(text)
    t = p.targets
    assert t.line.tolist()[:2] == [text[:text.index("P[1]{")].count("\n") + 1, text[:text.index("P[2]{")].count("\n") + 1]
    assert t.prev.tolist()[:2] == [-1, 0] and p.configs[:2] == ["N U T, 0, 0, 0"] * 2
    codes = [d.code for d in p.diagnostics]
    assert codes == ["P225", "P212"] or codes == ["P212", "P225"]
    assert any("not taught" in d.message for d in p.diagnostics)
    assert any("extended axes E1" in d.message for d in p.diagnostics)


def test_configs_follow_the_rows_twins_included(tmp_path, frames_file):
    from postproc.testing.models import joint_model

    mn = ["LBL[1]", "L P[1] 100mm/sec FINE", "L P[2] 100mm/sec FINE", "IF R[1]=1,JMP LBL[1]"]
    no_config = pos(2, 1500.0, 0.0, 900.0, uf=0).replace("CONFIG : 'N U T, 0, 0, 0',", "")
    text = program(mn, [pos(1, 1500.0, 100.0, 900.0, uf=0), no_config])
    p = read(text)
    assert p.targets.line.tolist() == [record_line(mn, k) for k in (1, 2, 1)]
    assert p.configs == ["N U T, 0, 0, 0", "", "N U T, 0, 0, 0"]
    # a model of a KUKA arm's joints: the CONFIG does not map on it (refused, P310; forced: P309 at P[1]'s runs)
    model = load_model(joint_model(tmp_path / "j.onnx", np.diag([0.5, 0.4, 0.3]) @ np.eye(3, 6), tool={"name": "any"}))
    with pytest.raises(PostprocError, match="P310"):
        compensate_text(text, model, name="t.ls", config=frames_file)
    _, report = compensate_text(text, model, name="t.ls", config=frames_file, force=True)
    assert report.compensated == 1 and report.left_codes == {"P309": 1}  # (P[1], at both of its runs)


def test_compensate_exits_1_and_names_the_target_left(tmp_path, model, frames_file, capsys):
    good = tmp_path / "good.ls"
    good.write_text(program(["L P[1] 100mm/sec FINE", "L P[2] 100mm/sec FINE"], P4[:2]))
    out = tmp_path / "o.ls"
    assert main(["compensate", str(good), "-o", str(out), "--model", str(model.path), "--frames", frames_file]) == 0
    bad = tmp_path / "bad.ls"
    bad.write_text(program(["L P[1] 100mm/sec FINE", "L PR[7] 100mm/sec FINE"], P4[:1]))
    capsys.readouterr()
    assert main(["compensate", str(bad), "-o", str(out), "--model", str(model.path), "--frames", frames_file]) == 1
    assert f"{bad}:7:" in capsys.readouterr().err

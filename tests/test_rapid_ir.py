"""RAPID as the controller runs it (issue 24): the module lowered to the motion IR and the one
dataflow analysis. Each case of the issue on a few lines of RAPID, with a model whose
correction varies over space: the command of every compensated target is the pose-list
twin's of its executed pose in the robot base (its own frame: work object, program
displacement), and every target that cannot be is named at its line and counted (exit 1)."""
from __future__ import annotations

import numpy as np
import pytest

from postproc.core import frames
from postproc.cli import main
from postproc.compensation.api import compensate_text
from postproc.programs.io import parse_program_text
from postproc.model.compensator import load_model
from postproc.core.diagnostics import PostprocError
from postproc.programs import rapid

EAX = "[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]"
GAIN = np.array([[2e-3, 0, 0], [0, -1e-3, 5e-4], [0, 0, 3e-3]])  # a correction that varies over space
Q = "[0,0,1,0]"  # tool pointing down


def rt(x, y, z, q=Q, eax=EAX):
    return f"[[{x},{y},{z}],{q},[0,0,0,0],{eax}]"


def module(*lines, data=(), routines=()):
    return "\n".join(["MODULE m", *data, "PROC main()", *lines, "ENDPROC", *routines, "ENDMODULE", ""])


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    from postproc.testing.models import affine_model

    path = affine_model(tmp_path_factory.mktemp("rapid-ir") / "affine.onnx", offset=(0.3, -0.2, 0.1), gain=GAIN,
                        reach=None, envelope=None, tool={"name": "any"})
    return load_model(path)


def in_base(text, name="m.mod"):
    """The program read: its rows' X/Y/Z in the robot base (NaN where the frame is not known)."""
    p = parse_program_text(text, name)
    t = p.targets
    out = np.full((len(t), 3), np.nan)
    for f in np.unique(t.frame[t.frame >= 0]):
        rows = t.frame == f
        out[rows] = frames.transform_points(p.frames[f].base, t.poses[rows, :3])
    return p, out


def twin_commands(model, base_xyz):
    """The commands the pose list of these positions (tool down) gets, in the robot base."""
    text = "x,y,z,a,b,c\n" + "".join(f"{x:.6f},{y:.6f},{z:.6f},180,0,180\n" for x, y, z in base_xyz)
    out, _ = compensate_text(text, model, name="twin.csv")
    return parse_program_text(out, "twin.csv").targets.poses[:, :3]


def codes(p):
    return [(d.code, d.line) for d in p.diagnostics]


# ----------------------------------------------------------------------- program displacement


def test_pdispon_exep_point_is_read_as_a_frame_and_the_targets_after_it_are_displaced(model):
    data = [f"CONST robtarget pRef:={rt(1950, 0, 800)};",      # 2
            f"CONST robtarget pFix:={rt(1953.5, 1.25, 799)};",  # 3: where the part lies today
            f"CONST robtarget p1:={rt(2000, 40, 900)};",        # 4
            f"CONST robtarget p2:={rt(2050, -30, 950)};"]       # 5
    text = module("MoveL pFix, v100, fine, tool0;",              # 7: the robot touches the part
                  "PDispOn \\ExeP:=pFix, pRef, tool0;",        # 8
                  "MoveL p1, v100, fine, tool0;",                # 9: p1 displaced by pFix - pRef
                  "PDispOff;",
                  "MoveL p2, v100, fine, tool0;",                # 11: p2 as written
                  data=data)
    p, before = in_base(text)
    assert np.allclose(before[1], [2003.5, 41.25, 899]) and np.allclose(before[2], [2050, -30, 950])
    # pFix is read as the displacement's frame: compensating it would move every displaced
    # target by its correction again; it is left as written (P217), the rest compensated
    assert codes(p) == [("P217", 3)] and "read at m.mod:8" in p.diagnostics[0].message
    assert p.held["P217"].tolist() == [0]
    out, report = compensate_text(text, model, name="m.mod")
    assert report.left_codes == {"P217": 1} and report.compensated == 2
    assert f"pFix:={rt(1953.5, 1.25, 799)};" in out  # as written
    _, after = in_base(out.split("\n", 1)[1])
    assert np.allclose(after[1:], twin_commands(model, before[1:]), atol=1e-3)


def test_pdispon_displaced_target_gets_the_correction_of_where_it_runs(model):
    data = [f"CONST robtarget pRef:={rt(1950, 0, 800)};", f"CONST robtarget pFix:={rt(1953.5, 1.25, 799)};",
            f"CONST robtarget p1:={rt(2000, 40, 900)};"]
    text = module("PDispOn \\ExeP:=pFix, pRef, tool0;", "MoveL p1, v100, fine, tool0;", data=data)
    p, before = in_base(text)
    assert codes(p) == [] and np.allclose(before[0], [2003.5, 41.25, 899])
    out, report = compensate_text(text, model, name="m.mod")
    assert report.left == 0 and report.compensated == 1
    _, after = in_base(out)
    assert np.allclose(after[0], twin_commands(model, before)[0], atol=1e-3)


def test_pdispset_is_part_of_the_frame_until_pdispoff(model):
    turn = "[0.965925826,0,0,0.258819045]"  # 30° about Z
    data = [f"CONST pose dispF:=[[100,-50,20],{turn}];", f"CONST robtarget p1:={rt(1900, 30, 850)};",
            f"CONST robtarget p2:={rt(2050, -20, 950)};"]
    text = module("PDispSet dispF;", "MoveL p1, v100, fine, tool0;", "PDispOff;", "MoveL p2, v100, fine, tool0;",
                  data=data)
    p, before = in_base(text)
    disp = np.eye(4)
    disp[:3, :3] = frames.rotation_from_quaternion(np.array([0.965925826, 0, 0, 0.258819045]))
    disp[:3, 3] = [100, -50, 20]
    assert np.allclose(before[0], disp[:3, :3] @ [1900, 30, 850] + disp[:3, 3])
    assert np.allclose(before[1], [2050, -20, 950])
    out, report = compensate_text(text, model, name="m.mod")
    assert report.left == 0 and report.compensated == 2
    _, after = in_base(out)
    assert np.allclose(after, twin_commands(model, before), atol=1e-3)
    # (the correction at the displaced place is not the one at the numbers as written)
    assert np.linalg.norm(twin_commands(model, [[1900, 30, 850]])[0] - [1900, 30, 850]
                          - (after[0] - before[0])) > 0.05


def test_pdispon_without_exep_leaves_the_targets_after_it(model, tmp_path, capsys):
    data = [f"CONST robtarget pRef:={rt(1950, 0, 800)};", f"CONST robtarget p1:={rt(2000, 40, 900)};"]
    text = module("PDispOn pRef, tool0;", "MoveL p1, v100, fine, tool0;", "PDispOff;",
                  "MoveL Offs(p1, 0, 0, 50), v100, fine, tool0;", data=data)
    p = rapid.read(["m.mod"], [text])
    (d,) = p.diagnostics
    assert d.code == "P201" and d.line == 5 and "\\ExeP" in d.message
    assert p.targets.frame.tolist() == [-1, 0]


# ----------------------------------------------------------------------- frames built from points


def test_a_work_object_built_from_a_robtarget_holds_the_point(model, tmp_path, capsys):
    data = ['PERS wobjdata wPart:=[FALSE,TRUE,"",[[0,0,0],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];',  # 2
            f"CONST robtarget pCorner:={rt(1900, 100, 800)};",                                  # 3
            f"CONST robtarget p1:={rt(80, -120, 60)};"]                                         # 4
    text = module("MoveL pCorner, v100, fine, tool0;",             # 6: the robot touches the corner
                  "wPart.oframe.trans := pCorner.trans;",          # 7
                  "MoveL p1, v100, fine, tool0\\WObj:=wPart;",     # 8
                  data=data)
    p, before = in_base(text)
    assert np.allclose(before[1], [1980, -20, 860])
    assert codes(p) == [("P217", 3)] and "read at m.mod:8" in p.diagnostics[0].message
    src = tmp_path / "m.mod"
    src.write_text(text)
    out = tmp_path / "out.mod"
    path = tmp_path / "model.onnx"
    from postproc.testing.models import affine_model

    affine_model(path, offset=(0.3, -0.2, 0.1), gain=GAIN, reach=None, envelope=None, tool={"name": "any"})
    assert main(["compensate", str(src), "-o", str(out), "--model", str(path)]) == 1
    err = capsys.readouterr().err
    assert "1 of 2 compensated, 1 left as written: P217 ×1" in err
    new = out.read_text()
    assert f"pCorner:={rt(1900, 100, 800)};" in new
    _, after = in_base(new.split("\n", 1)[1])
    assert np.allclose(after[1], twin_commands(model, before[1:])[0], atol=1e-3)


def test_a_work_object_assigned_from_a_branch_is_not_known_after_it():
    data = ['VAR wobjdata w:=[FALSE,TRUE,"",[[0,0,0],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];',
            f"CONST robtarget p1:={rt(80, -120, 60)};"]
    text = module("IF DInput(di1) = 1 THEN", "  w.uframe.trans.x := 500;", "ENDIF",
                  "MoveL p1, v100, fine, tool0\\WObj:=w;", data=data)
    p = rapid.read(["m.mod"], [text])
    (d,) = p.diagnostics
    assert d.code == "P201" and p.targets.frame.tolist() == [-1]


# ----------------------------------------------------------------------- external axes


def test_a_robtarget_on_a_coordinated_track_is_left_with_p225(model):
    track = "[1500,9E+09,9E+09,9E+09,9E+09,9E+09]"
    data = [f"CONST robtarget pTrack:={rt(1900, 0, 900, eax=track)};", f"CONST robtarget p2:={rt(2000, 40, 900)};"]
    text = module("MoveL pTrack, v100, fine, tool0;", "MoveL p2, v100, fine, tool0;",
                  f"MoveL {rt(1950, 10, 880, eax=track)}, v100, fine, tool0;", data=data)
    for accelerate in (True, False):
        p = rapid.read(["m.mod"], [text], accelerate=accelerate)
        assert p.targets.frame.tolist() == [-1, 0, -1]
        (d,) = p.diagnostics
        assert d.code == "P225" and d.line == 2 and "eax_a 1500" in d.message and "2 target(s)" in d.message
    out, report = compensate_text(text, model, name="m.mod")
    assert report.left_codes == {"P225": 2} and report.compensated == 1
    assert f"pTrack:={rt(1900, 0, 900, eax=track)};" in out


# ----------------------------------------------------------------------- counted, located


def test_a_target_left_for_p201_is_counted(tmp_path, capsys):
    text = module(f"MoveL {rt(1900, 0, 900)}, v100, fine, tool0\\WObj:=wElsewhere;")
    src = tmp_path / "m.mod"
    src.write_text(text)
    from postproc.testing.models import affine_model

    path = affine_model(tmp_path / "model.onnx", gain=GAIN, reach=None, envelope=None, tool={"name": "any"})
    assert main(["compensate", str(src), "-o", str(tmp_path / "out.mod"), "--model", str(path)]) == 1
    err = capsys.readouterr().err
    assert f"{src}:3:9: P201" in err and "wElsewhere is not declared" in err
    assert "0 of 1 compensated, 1 left as written: P201 ×1" in err


# ----------------------------------------------------------------------- execution order


def test_rows_follow_calls_branches_loops_and_exit():
    data = [f"CONST robtarget pA:={rt(1900, 0, 900)};", f"CONST robtarget pB:={rt(1950, 0, 900)};",
            f"CONST robtarget pC:={rt(2000, 0, 900)};", f"CONST robtarget pD:={rt(2050, 0, 900)};"]
    routines = ["PROC visit(robtarget p)", "  MoveL p, v100, fine, tool0;", "ENDPROC"]
    text = module("visit pC;",                             # rows 0: pC (through the routine's parameter)
                  "FOR k FROM 1 TO 2 DO",                  # rows 1, 2: pA twice
                  "  MoveL pA, v100, z10, tool0;",
                  "ENDFOR",
                  "TEST nMode",                            # rows 3, 4: pB or pD, both after pA
                  "CASE 1:",
                  "  MoveL pB, v100, z10, tool0;",
                  "DEFAULT:",
                  "  MoveL pD, v100, z10, tool0;",
                  "ENDTEST",
                  "MoveL pC, v100, fine, tool0;",          # rows 5, 6: pC after pB or after pD
                  "EXIT;",
                  "MoveL pA, v100, fine, tool0;",          # after EXIT: never runs
                  data=data + ["VAR num nMode:=0;"], routines=routines)
    p = rapid.read(["m.mod"], [text])
    t = p.targets
    assert t.line.tolist() == [4, 2, 2, 3, 5, 4, 4]
    assert t.prev.tolist() == [-1, 0, 1, 2, 2, 4, 3]  # (pC after pD, and its twin row after pB)
    assert t.twin.tolist() == [-1, -1, 1, -1, -1, 0, 0]
    assert p.diagnostics == []


def test_inout_parameter_moves_the_point_the_caller_uses(model):
    data = [f"CONST robtarget pBase:={rt(1900, 0, 900)};"]
    routines = ["PROC lift(INOUT robtarget p, num dz)", "  p.trans.z := p.trans.z + dz;", "ENDPROC"]
    text = module("VAR robtarget pWork;", "pWork := pBase;", "lift pWork, 300;", "MoveL pWork, v100, fine, tool0;",
                  data=data, routines=routines)
    p = rapid.read(["m.mod"], [text])
    # pWork is pBase's numbers + 300 in Z: the one target is a copy of pBase, rewritten there
    assert p.targets.poses[0, :3].tolist() == [1900, 0, 1200] and p.targets.offset[0].tolist() == [0, 0, 300]
    out, report = compensate_text(text, model, name="m.mod")
    assert report.compensated == 1 and report.left == 0
    _, after = in_base(out)
    assert np.allclose(after[0], twin_commands(model, [[1900, 0, 1200]])[0], atol=1e-3)


def test_a_late_bound_call_is_code_not_read(model):
    data = ['PERS wobjdata w:=[FALSE,TRUE,"",[[0,0,0],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];',
            f"CONST robtarget p1:={rt(80, -120, 60)};", 'VAR string sName:="prep";']
    text = module("MoveL p1, v100, fine, tool0\\WObj:=w;", '%sName + "1"%;', "MoveL p1, v100, fine, tool0\\WObj:=w;",
                  data=data)
    p = rapid.read(["m.mod"], [text])
    # the routine named at run time may set any global: the work object too
    assert p.targets.frame.tolist() == [0, -1]
    assert [d.code for d in p.diagnostics] == ["P201", "P232"] and "run time" in p.diagnostics[0].message
    assert "late binding" in p.diagnostics[1].message  # (the call: a routine not read, P232)


def test_a_trap_that_assigns_a_point_leaves_it_while_connected():
    data = [f"VAR robtarget pPick:={rt(1900, 0, 900)};", "VAR intnum irSensor;"]
    routines = ["TRAP newPart", f"  pPick := {rt(1950, 5, 905)};", "ENDTRAP"]
    text = module("MoveL pPick, v100, fine, tool0;", "CONNECT irSensor WITH newPart;",
                  "ISignalDI di1, 1, irSensor;", "MoveL pPick, v100, fine, tool0;", data=data, routines=routines)
    p = rapid.read(["m.mod"], [text])
    # pPick is assigned by the program (the trap): a VAR of the module keeps the last run's value,
    # and while the interrupt is on the trap may run before any motion
    assert [d.code for d in p.diagnostics if d.code in ("P211", "P223")] == ["P211", "P223"]


def test_an_error_handler_may_run_after_each_statement():
    data = [f"CONST robtarget pA:={rt(1900, 0, 900)};", f"CONST robtarget pB:={rt(1950, 0, 900)};",
            f"CONST robtarget pSafe:={rt(2000, 0, 1100)};"]
    routines = ["PROC work()", "  MoveL pA, v100, fine, tool0;", "  MoveL pB, v100, fine, tool0;", "ERROR",
                "  MoveL pSafe, v100, fine, tool0;", "  RETRY;", "ENDPROC"]
    text = module("work;", data=data, routines=routines)
    p = rapid.read(["m.mod"], [text])
    t = p.targets
    lines = t.line.tolist()
    # pA, pB each run; after either the handler may move to pSafe and run the motion again
    assert lines.count(2) >= 1 and lines.count(3) >= 1 and lines.count(4) >= 2
    # pB is reached from pA, or from pSafe (after a retry of pB): both predecessors are rows
    pb = [k for k, line in enumerate(lines) if line == 3]
    assert {lines[t.prev[k]] for k in pb} == {2, 4}
    assert p.diagnostics == []


# ----------------------------------------------------------------------- syntax


def test_optional_parameters_without_a_comma_and_a_byte_order_mark():
    routines = ["PROC weld(\\switch Start\\switch End|switch Both, robtarget p\\num dz)",
                "  MoveL p, v100, fine, tool0;", "ENDPROC"]
    data = [f"CONST robtarget p1:={rt(1900, 0, 900)};"]
    text = "\xef\xbb\xbf" + module("weld \\Start, p1\\dz:=5;", "weld p1;", data=data, routines=routines)
    p = rapid.read(["m.mod"], [text])
    assert p.targets.line.tolist() == [2, 2] and p.diagnostics == []
    # (the byte order mark is no part of the first line's columns)
    assert p.targets.col.tolist() == [23, 23]
    assert rapid.read(["m.mod"], [text[3:]]).targets.col.tolist() == [23, 23]
    # (the byte order mark is no column of the first line)
    with pytest.raises(PostprocError) as e:
        rapid.read(["m.mod"], ["\xef\xbb\xbfMODULE m x\nENDMODULE\n"])
    assert (e.value.line, e.value.col, e.value.code) == (1, 10, "P101")


def test_fast_path_and_tree_read_inline_robtargets_alike():
    lines = [f"MoveL [[{1900 + k}.5,- {k},{800 + 2 * k}],[0,0.7071068,0.7071068,0],[0,{k % 2},0,1],{EAX}],"
             "v100,z1,tool0\\WObj:=w;" for k in range(6)]
    lines[3] = lines[3].replace("MoveL", "MoveC") .replace("v100", f"{rt(1, 2, 3)},v100")
    data = ['PERS wobjdata w:=[FALSE,TRUE,"",[[100,0,0],[0.7071068,0,0,0.7071068]],[[0,0,0],[1,0,0,0]]];']
    text = module(*lines, "IF DInput(di1) = 1 THEN", *lines[:2], "ENDIF", data=data)
    fast, slow = (rapid.read(["m.mod"], [text], accelerate=a) for a in (True, False))
    for name in ("poses", "spans", "abc_spans", "orientation", "line", "col", "frame", "motion", "prev", "twin"):
        assert np.array_equal(getattr(fast.targets, name), getattr(slow.targets, name), equal_nan=True), name
    assert np.array_equal(fast.confdata, slow.confdata) and len(fast.targets) == 9
    assert np.allclose(fast.frames[0].base, slow.frames[0].base)


def test_config_modules_are_read_only_data_and_their_routines_are_read_where_called():
    sysmod = "\n".join(["MODULE user(SYSMODULE)",
                        'PERS wobjdata wCfg:=[FALSE,TRUE,"",[[0,0,500],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];',
                        "PROC toHome()", f"  MoveJ {rt(1600, 0, 1200)}, v1000, fine, tool0;", "ENDPROC",
                        "PROC unused()", f"  MoveJ {rt(1700, 0, 1200)}, v1000, fine, tool0;", "ENDPROC", "ENDMODULE",
                        ""])
    data = [f"CONST robtarget p1:={rt(80, -120, 60)};"]
    text = module("MoveL p1, v100, fine, tool0\\WObj:=wCfg;", "toHome;", "gripperOpen;",
                  "MoveL p1, v100, fine, tool0\\WObj:=wCfg;", data=data)
    p = rapid.read(["m.mod"], [text], config=[sysmod])
    assert np.allclose(p.frames[0].base[:3, 3], [0, 0, 500])
    # toHome is read (its target left: it stands in the --config text, which is never rewritten);
    # unused is not called: no target of the program. Code not read (gripperOpen) may change the
    # program displacement (and every global but the --config modules' data): p1 after it is left
    assert p.targets.frame.tolist() == [0, -1] and len(p.targets) == 2
    assert [(d.code, d.path, d.line) for d in p.diagnostics] == [("P201", "m.mod", 6), ("P232", "m.mod", 6),
                                                             ("P211", "--config", 4)]
    assert "gripperOpen()" in p.diagnostics[0].message and "read only" in p.diagnostics[2].message


def test_components_of_a_robtarget_copied_offset_and_read_in_a_condition(model):
    data = [f"CONST robtarget pA:={rt(1900, 0, 900)};", f"CONST robtarget pB:={rt(2000, 50, 950)};"]
    text = module("VAR robtarget pT;",
                  "pT := pA;",
                  "pT.trans.x := pT.trans.x + 25;",          # a copy of pA's numbers, 25 mm further in X
                  "MoveL pT, v100, fine, tool0;",
                  "IF pB.trans.z > 900 THEN",                # pB's Z is read by the condition
                  "  MoveL pB, v100, fine, tool0;",
                  "ENDIF",
                  data=data)
    p = rapid.read(["m.mod"], [text])
    assert p.targets.poses[:, :3].tolist() == [[1925, 0, 900], [2000, 50, 950]]
    assert p.targets.offset[0].tolist() == [25, 0, 0]
    # compensating pB would change what the condition decides: left (P217), pT compensated in pA's numbers
    assert codes(p) == [("P217", 3)] and "read at m.mod:9 too (a comparison" in p.diagnostics[0].message
    out, report = compensate_text(text, model, name="m.mod")
    assert report.compensated == 1 and report.left_codes == {"P217": 1}
    _, after = in_base(out)
    assert np.allclose(after[0], twin_commands(model, [[1925, 0, 900]])[0], atol=1e-3)


def test_offs_approach_runs_move_with_the_point_compensated_for_itself(model):
    # the RAPID idiom: approach and retract at Offs(p, 0, 0, 100), the point itself in between
    text = module("MoveJ Offs(pPick,0,0,100),v1000,z10,tool0;", "MoveL pPick,v100,fine,tool0;",
                  "MoveL Offs(pPick,0,0,100),v500,z10,tool0;",
                  data=[f"CONST robtarget pPick:={rt(1800, 100, 500)};"])
    out, report = compensate_text(text, model, name="m.mod")
    assert (report.compensated, report.moved, report.left) == (1, 1, 0) and not report.complete
    (w,) = [w for w in report.warnings if w.code == "P231"]
    assert w.line == 2 and "up to" in w.message
    offs = [i + 1 for i, line in enumerate(text.splitlines()) if "Offs(pPick" in line]
    assert len(offs) == 2 and "2 motions to it at an offset" in w.message  # the approach and the retract,
    assert f"at m.mod:{offs[0]}, m.mod:{offs[1]})" in w.message              # each named at its line
    _, base = in_base(text)
    _, new = in_base(out)
    point = np.flatnonzero(np.abs(base[:, 2] - 500) < 1e-9)[0]
    np.testing.assert_allclose(new[point], twin_commands(model, base[point:point + 1])[0], atol=1e-3)

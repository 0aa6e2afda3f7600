"""A RAPID task read as the controller loads it (issue 37, items 2 and 4): several modules with
RAPID's scope rules, calls to routines not read (P232), data that a routine ``main`` does not
run changes (P233), and what the system parameters (a backup's SYSPAR: MOC.cfg, SYS.cfg) say of
the robot's base."""
from __future__ import annotations

import numpy as np
import pytest

from postproc.compensation.pipeline import compensate_program
from postproc.core import frames
from postproc.core.diagnostics import PostprocError
from postproc.model.compensator import load_model
from postproc.programs import krl, rapid
from postproc.programs.rapid import syspar as sp
from postproc.programs.urscript import read as ur_read
from postproc.robot.external import ExternalUnit

from helpers import SYS_CFG

EAX = "[9E9,9E9,9E9,9E9,9E9,9E9]"
GAIN = np.array([[2e-3, 0, 0], [0, -1e-3, 5e-4], [0, 0, 3e-3]])  # a correction that varies over space
OFFSET = np.array([0.3, -0.2, 0.1])
CENTRE = np.array([2000.0, 0.0, 900.0])  # (affine_model's: E(c) = OFFSET + GAIN·(c − CENTRE))
Q = "[0,0,1,0]"  # tool pointing down


def rt(x, y, z, eax=EAX):
    return f"[[{x},{y},{z}],{Q},[0,0,0,0],{eax}]"


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    from postproc.testing.models import affine_model

    path = affine_model(tmp_path_factory.mktemp("rapid-task") / "affine.onnx", offset=tuple(OFFSET), gain=GAIN,
                        reach=None, envelope=None, tool={"name": "any"})
    return load_model(path)


def command(p):
    """The command the affine model gives a robot-base position P: the fixed point c = P + Ê(c),
    Ê(c) = OFFSET + GAIN·(c − CENTRE), solved exactly."""
    return np.linalg.solve(np.eye(3) - GAIN, np.asarray(p, float) + OFFSET - GAIN @ CENTRE)


def codes(p):
    return [(d.code, d.path, d.line) for d in p.diagnostics]


def rows(p):
    """Each row's X/Y/Z in the robot base (NaN where its frame is not known)."""
    t = p.targets
    out = np.full((len(t), 3), np.nan)
    for f in np.unique(t.frame[t.frame >= 0]):
        sel = t.frame == f
        out[sel] = frames.transform_points(p.frames[f].base, t.poses[sel, :3])
    return out


def numbers(text, name):
    """The x, y, z written in a robtarget declaration ``name := [[x,y,z],…``."""
    import re

    m = re.search(rf"{name}\s*:=\s*\[\[([-\d.eE+]+),([-\d.eE+]+),([-\d.eE+]+)\]", text)
    return np.array([float(v) for v in m.groups()])


# ====================================================================== P232: code not read


MAIN = """MODULE MainMod
  PERS tooldata tWeldGun := [TRUE,[[10,20,300],[1,0,0,0]],[1,[0,0,1],[1,0,0,0],0,0,0]];
  CONST robtarget pPark := {park};
  PERS robtarget p1 := {p1};
  PROC main()
    MoveJ pPark, v100, fine, tool0;
    other_b;
    MoveL p1, v100, fine, tool0;
  ENDPROC
ENDMODULE
""".format(park=rt(1500, 0, 1200), p1=rt(1700, 100, 900))


def test_a_call_to_a_routine_not_read_is_said_at_the_call_with_what_it_can_see(model):
    p = rapid.read(["Main.mod"], [MAIN])
    found = [d for d in p.diagnostics if d.code == "P232"]
    assert [(d.path, d.line, d.col) for d in found] == [("Main.mod", 7, 5)]
    msg = found[0].message
    assert msg.startswith("other_b() is in none of the files read") and "tWeldGun, pPark, p1" in msg
    # P232 changes nothing of which targets are compensated: pPark (a constant) is, p1 (PERS, which
    # other_b may change) is left as before
    report = compensate_program(p, model)
    assert report.unread == 1 and not report.complete
    assert report.compensated == 1
    np.testing.assert_allclose(numbers(report.outputs["Main.mod"], "pPark"), command([1500, 0, 1200]), atol=1e-3)
    assert "P232" in report.summary()


def test_p232_once_per_call_site_however_often_it_runs_and_its_list_is_cut():
    data = "".join(f"  CONST robtarget pt{k} := {rt(1500 + k, 0, 900)};\n" for k in range(9))
    text = ("MODULE M\n" + data + "  PROC main()\n    FOR i FROM 1 TO 4 DO\n      helper;\n    ENDFOR\n"
            "    helper;\n    helper;\n  ENDPROC\n  PROC helper()\n    gripper_open;\n    MoveL pt0, v100, fine, tool0;\n"
            "  ENDPROC\nENDMODULE\n")
    p = rapid.read(["m.mod"], [text])
    found = [d for d in p.diagnostics if d.code == "P232"]
    assert [(d.line, d.col) for d in found] == [(19, 5)]  # (gripper_open, run 6 times from 3 call sites)
    assert "pt0, pt1, pt2, pt3, pt4 and 4 more" in found[0].message


def test_instructions_and_routines_read_are_not_p232_a_late_bound_call_is():
    text = f"""MODULE M
  CONST robtarget p1 := {rt(1600, 0, 900)};
  VAR num n := 2;
  PROC main()
    TPWrite "start";
    WaitTime 0.5;
    SetDO do1, 1;
    mine;
    MoveL p1, v100, fine, tool0;
    %"part" + NumToStr(n, 0)%;
    CallByVar "part", n;
  ENDPROC
  PROC mine()
    MoveL Offs(p1, 0, 0, 100), v100, fine, tool0;
  ENDPROC
ENDMODULE
"""
    p = rapid.read(["m.mod"], [text])
    found = [(d.line, d.message.split(" is in")[0]) for d in p.diagnostics if d.code == "P232"]
    assert [line for line, _ in found] == [10, 11] and all("late binding" in m for _, m in found)


def test_krl_and_urscript_calls_not_read_are_p232_their_builtins_are_not():
    src = """DEF main()
  DECL E6POS XP1
  XP1 = {X 1500, Y 0, Z 900, A 0, B 90, C 0}
  BAS(#INITMOV, 0)
  $BASE = $NULLFRAME
  $TOOL = $NULLFRAME
  PULSE($OUT[3], TRUE, 0.5)
  spot_weld(3)
  LIN XP1
END
"""
    p = krl.read(["main.src"], [src])
    assert [(d.code, d.line) for d in p.diagnostics if d.code == "P232"] == [("P232", 8)]
    script = """def prog():
  set_tcp(p[0, 0, 0.1, 0, 0, 0])
  textmsg("go")
  set_digital_out(1, True)
  rq_gripper_close()
  movel(p[0.4, 0.1, 0.3, 0, 3.14, 0], a=1.2, v=0.25)
end
"""
    p = ur_read(["p.script"], [script])
    found = [d for d in p.diagnostics if d.code == "P232"]
    assert [d.line for d in found] == [5] and found[0].message.startswith("rq_gripper_close()")


# ====================================================================== P233: changed where main does not run


CALIB = """MODULE Calib
  PROC calib()
    TPWrite "calibrating";
    BEUpdateTcp tWeldGun\\XYZOnly;
  ENDPROC
ENDMODULE
"""
WELD = """MODULE Weld
  PERS tooldata tWeldGun := [TRUE,[[10,20,300],[1,0,0,0]],[1,[0,0,1],[1,0,0,0],0,0,0]];
  CONST robtarget pA := {a};
  CONST robtarget pB := {b};
  PROC main()
    MoveJ pA, v100, fine, tWeldGun;
    MoveL pB, v100, fine, tool0;
    MoveL {c}, v100, fine, tWeldGun;
    MoveL {d}, v100, fine, tWeldGun;
  ENDPROC
ENDMODULE
""".format(a=rt(1500, 0, 1000), b=rt(1600, 50, 950), c=rt(1650, 20, 900), d=rt(1660, 20, 900))


@pytest.mark.parametrize("calib_as", ["file", "config"])
def test_a_tool_a_routine_main_does_not_call_updates_leaves_every_motion_with_it(model, calib_as):
    if calib_as == "file":
        p = rapid.read(["Weld.mod", "Calib.mod"], [WELD, CALIB])
        where = "Calib.mod:4"
    else:
        p = rapid.read(["Weld.mod"], [WELD], config=[CALIB])
        where = "--config:4"
    left = [d for d in p.diagnostics if d.code == "P233"]
    # at each motion with tWeldGun (a declared target, inline targets of the fast path), never pB's
    assert [(d.path, d.line) for d in left] == [("Weld.mod", 6), ("Weld.mod", 8), ("Weld.mod", 9)]
    assert all(f"tWeldGun is changed by BEUpdateTcp at {where} in calib(), which main does not call" in d.message
               for d in left)
    # BEUpdateTcp itself is code not read: said where the analysis runs calib (a module given; a
    # --config module's routines are read only where the program calls them)
    said = [(d.code, d.line) for d in p.diagnostics if d.code == "P232"]
    assert said == ([("P232", 4)] if calib_as == "file" else [])
    report = compensate_program(p, model)
    assert report.left_codes == {"P233": 3} and report.compensated == 1 and not report.complete
    out = report.outputs["Weld.mod"]
    np.testing.assert_allclose(numbers(out, "pB"), command([1600, 50, 950]), atol=1e-3)
    assert f"pA := {rt(1500, 0, 1000)};" in out


def test_the_same_tool_changed_in_mains_flow_is_the_flow_analysis_as_before(model):
    text = WELD.replace("    MoveJ pA, v100, fine, tWeldGun;\n",
                        "    MoveJ pA, v100, fine, tWeldGun;\n    longer;\n") + """MODULE Tools
  PROC longer()
    tWeldGun.tframe.trans.z := 350;
  ENDPROC
ENDMODULE
"""
    weld, tools = text.split("ENDMODULE\n", 1)
    p = rapid.read(["Weld.mod", "Tools.mod"], [weld + "ENDMODULE\n", tools])
    assert not any(d.code in ("P233", "P232") for d in p.diagnostics)
    # (as before: a PERS the program assigns starts a run as the last one left it — pA's tool is not
    # known; after longer() the TCP is the one assigned)
    assert [d.code for d in p.diagnostics] == ["P203"]
    t = p.targets
    tools_of = [p.frames[f].tool.tolist() if f >= 0 else None for f in t.frame]
    assert tools_of[0] is None and tools_of[1] == [0, 0, 0, 0, 0, 0]
    np.testing.assert_allclose(tools_of[2][:3], [10, 20, 350])
    report = compensate_program(p, model)
    assert report.left_codes == {"P203": 1} and report.compensated == 3 and report.unread == 0


def test_a_constant_robtarget_is_never_p233_a_var_one_is(model):
    text = f"""MODULE M
  CONST robtarget pC := {rt(1500, 0, 1000)};
  VAR robtarget pV := {rt(1550, 0, 1000)};
  PERS wobjdata wFix := [FALSE,TRUE,"",[[100,0,0],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];
  PROC main()
    MoveL pC, v100, fine, tool0;
    MoveL pV, v100, fine, tool0;
    MoveL pC, v100, fine, tool0\\WObj:=wFix;
  ENDPROC
  PROC service()
    other_c pC;
    pV := Offs(pC, 0, 0, 10);
    shift wFix;
  ENDPROC
  PROC shift(INOUT wobjdata w)
    w.uframe.trans.x := w.uframe.trans.x + 5;
  ENDPROC
ENDMODULE
"""
    p = rapid.read(["m.mod"], [text])
    left = {d.line: d.message for d in p.diagnostics if d.code == "P233"}
    assert sorted(left) == [7, 8]
    assert "pV is changed by an assignment at m.mod:12 in service()" in left[7]
    assert "wFix is changed by shift at m.mod:13 in service()" in left[8]
    report = compensate_program(p, model)
    assert report.left_codes.get("P233") == 2
    # pC is compensated for its motion in wobj0; its run in wFix is left, so its numbers are read
    # there too (P217): it is left as written at both, never P233 for its own sake
    assert not any(d.code == "P233" and d.line == 6 for d in p.diagnostics)


def test_an_unconnected_trap_is_not_run_by_main_a_connected_one_is_as_before():
    base = f"""MODULE M
  VAR intnum irSensor;
  VAR robtarget pT := {rt(1500, 0, 900)};
  PROC main()
{{connect}}
    MoveL pT, v100, fine, tool0;
  ENDPROC
  TRAP onSensor
    pT.trans.z := pT.trans.z + 5;
  ENDTRAP
ENDMODULE
"""
    connected = rapid.read(["m.mod"], [base.format(connect="    CONNECT irSensor WITH onSensor;\n"
                                                           "    ISignalDI di1, 1, irSensor;")])
    assert [d.code for d in connected.diagnostics] == ["P223"]
    alone = rapid.read(["m.mod"], [base.format(connect="    TPWrite \"no interrupt\";")])
    (d,) = alone.diagnostics
    assert d.code == "P233" and d.line == 6 and "in onSensor(), which main does not call" in d.message


def test_a_routine_a_root_calls_is_named_with_its_root():
    text = f"""MODULE M
  PERS robtarget pS := {rt(1500, 0, 900)};
  PROC main()
    MoveL pS, v100, fine, tool0;
  ENDPROC
  PROC teach()
    store;
  ENDPROC
  PROC store()
    pS := CRobT();
  ENDPROC
ENDMODULE
"""
    (d,) = rapid.read(["m.mod"], [text]).diagnostics
    assert d.code == "P233" and "in store() (which teach() calls), and teach() main does not call" in d.message


# ====================================================================== a task of several modules


def test_local_data_and_routines_stay_in_their_module_globals_cross_modules(model):
    a = f"""MODULE ModA
  LOCAL CONST robtarget pX := {rt(1500, 0, 900)};
  TASK PERS tooldata tShared := [TRUE,[[0,0,100],[1,0,0,0]],[1,[0,0,1],[1,0,0,0],0,0,0]];
  PROC main()
    MoveL pX, v100, fine, tool0;
    go;
    fromB;
    lift pX, 50;
  ENDPROC
  LOCAL PROC go()
    MoveL Offs(pX, 10, 0, 0), v100, fine, tool0;
  ENDPROC
ENDMODULE
"""
    b = f"""MODULE ModB
  CONST robtarget pX := {rt(1800, 0, 900)};
  PROC go()
    MoveL pX, v100, fine, tShared;
  ENDPROC
  PROC fromB()
    go;
  ENDPROC
ENDMODULE
"""
    s = """MODULE Util (SYSMODULE)
  PROC lift(robtarget p, num dz)
    MoveL Offs(p, 0, 0, dz), v100, fine, tool0;
  ENDPROC
ENDMODULE
"""
    p = rapid.read(["ModA.mod", "ModB.mod", "Util.sys"], [a, b, s])
    assert p.diagnostics == []
    got = rows(p)
    # main: A's pX; A's LOCAL go (A's pX); B's fromB calls B's global go (B's pX, tShared from A)
    np.testing.assert_allclose(got[:, 0], [1500, 1510, 1800, 1500])
    np.testing.assert_allclose(got[:, 2], [900, 900, 900, 950])
    assert p.frames[p.targets.frame[2]].tool.tolist()[:3] == [0, 0, 100]
    report = compensate_program(p, model)
    # (A's pX compensated for its own run, its Offs runs move with it: P231)
    assert report.compensated == 2 and report.left == 0 and report.unread == 0 and report.moved == 2
    np.testing.assert_allclose(numbers(report.outputs["ModB.mod"], "pX"), command([1800, 0, 900]), atol=1e-3)
    np.testing.assert_allclose(numbers(report.outputs["ModA.mod"], "pX"), command([1500, 0, 900]), atol=1e-3)


def test_local_data_of_another_module_is_not_visible():
    a = f"MODULE A\n  LOCAL CONST robtarget pHidden := {rt(1500, 0, 900)};\n  PROC main()\n    useIt;\n  ENDPROC\nENDMODULE\n"
    b = "MODULE B\n  PROC useIt()\n    MoveL pHidden, v100, fine, tool0;\n  ENDPROC\nENDMODULE\n"
    p = rapid.read(["A.mod", "B.mod"], [a, b])
    assert [(d.code, d.path, d.line) for d in p.diagnostics] == [("P215", "B.mod", 3)]


def test_a_sys_modules_routines_and_data_are_the_tasks_given_as_a_file_or_with_config():
    s = f"""MODULE user (SYSMODULE)
  PERS tooldata tGun := [TRUE,[[0,0,200],[1,0,0,0]],[1,[0,0,1],[1,0,0,0],0,0,0]];
  CONST robtarget pHome := {rt(1200, 0, 1300)};
  PROC toHome()
    MoveJ pHome, v100, fine, tGun;
  ENDPROC
ENDMODULE
"""
    m = f"MODULE M\n  PROC main()\n    toHome;\n    MoveL {rt(1500, 0, 900)}, v100, fine, tGun;\n  ENDPROC\nENDMODULE\n"
    as_file = rapid.read(["M.mod", "user.sys"], [m, s])
    assert as_file.diagnostics == [] and len(as_file.targets) == 2
    as_config = rapid.read(["M.mod"], [m], config=[s])
    assert len(as_config.targets) == 1 and [d.code for d in as_config.diagnostics] == ["P211"]  # (read only)
    assert as_config.frames[as_config.targets.frame[0]].tool.tolist()[:3] == [0, 0, 200]


def test_a_routine_declared_twice_in_a_task_is_refused_where_it_is_declared_again():
    a = "MODULE A\n  PROC main()\n    work;\n  ENDPROC\n  PROC work()\n  ENDPROC\nENDMODULE\n"
    b = "MODULE B\n  PROC work()\n  ENDPROC\nENDMODULE\n"
    with pytest.raises(PostprocError) as exc:
        rapid.read(["A.mod", "B.mod"], [a, b])
    assert (exc.value.code, exc.value.path, exc.value.line, exc.value.col) == ("P102", "B.mod", 2, 3)
    assert "A.mod:5" in exc.value.message
    # a LOCAL routine of the same name in each module is not a clash
    rapid.read(["A.mod", "B.mod"], [a.replace("  PROC work", "  LOCAL PROC work"),
                                    b.replace("  PROC work", "  LOCAL PROC work")])


# ====================================================================== system parameters


MOC = """MOC:CFG_1.0:6:0::
#
MECHANICAL_UNIT:

      -name "TRACK_1" -use_run_enable "" -use_single_0 "TRACK_1"\\
      -activate_at_start_up

      -name "STN1" -use_single_0 "STN1"
#
ROBOT:

      -name "ROB_1" -use_robot_type "ROB1_6700"\\
      -use_joint_0 "rob1_1" -use_joint_1 "rob1_2"\\
{base}      -base_mass 55.1 -base_mass_centre_x -0.05
#
ARM:

      -name "rob1_1" -upper_joint_bound 3.14159 -lower_joint_bound -3.14159
"""
TRACKED = f"""MODULE M
  CONST robtarget pT := {rt(1900, 0, 900, "[1500,9E9,9E9,9E9,9E9,9E9]")};
  PROC main()
    MoveL pT, v100, fine, tool0;
    MoveL {rt(1950, 0, 900, "[1600,9E9,9E9,9E9,9E9,9E9]")}, v100, fine, tool0;
  ENDPROC
ENDMODULE
"""


def test_the_cfg_text_form_is_parsed_with_its_continuations_flags_and_lines():
    cfg = sp.parse("SYSPAR/MOC.cfg", MOC.format(base='      -base_frame_coordinated "TRACK_1"\\\n'))
    (unit, stn) = cfg["MECHANICAL_UNIT"]
    assert unit.name == "TRACK_1" and unit.line == 5 and unit.get("activate_at_start_up") == ""
    (robot,) = cfg["ROBOT"]
    assert robot.get("base_frame_coordinated") == "TRACK_1" and robot.lines["base_frame_coordinated"] == 14
    assert robot.get("base_mass_centre_x") == "-0.05" and stn.line == 8


def test_a_robot_base_a_track_moves_leaves_every_target_unless_the_track_is_given(model):
    syspar = {"BACKUP/SYSPAR/MOC.cfg": MOC.format(base='      -base_frame_coordinated "TRACK_1"\\\n')}
    p = rapid.read(["m.mod"], [TRACKED], syspar=syspar, task="T_ROB1")
    (d,) = p.diagnostics
    assert d.code == "P225" and "BACKUP/SYSPAR/MOC.cfg:14" in d.message and "TRACK_1" in d.message
    assert "2 target(s)" in d.message and p.targets.frame.tolist() == [-1, -1]
    track = ExternalUnit("track", "prismatic", "E1", "robot", direction=(1.0, 0.0, 0.0), mech_unit="TRACK_1")
    p = rapid.read(["m.mod"], [TRACKED], syspar=syspar, external=(track,))
    assert p.diagnostics == []
    np.testing.assert_allclose(rows(p)[:, 0], [1900 - 1500, 1950 - 1600])
    other = ExternalUnit("track", "prismatic", "E1", "robot", direction=(1.0, 0.0, 0.0), mech_unit="TRACK_9")
    (d,) = rapid.read(["m.mod"], [TRACKED], syspar=syspar, external=(other,)).diagnostics
    assert d.code == "P225" and "mech_unit TRACK_9" in d.message


def test_a_base_frame_in_moc_takes_the_world_to_the_robot_base(model):
    base = ('      -base_frame_pos_x 0.5 -base_frame_pos_y -0.2 -base_frame_pos_z 0.1\\\n'
            '      -base_frame_orient_u0 0.707106781 -base_frame_orient_u3 0.707106781\\\n')
    syspar = {"SYSPAR/MOC.cfg": MOC.format(base=base)}
    text = f"MODULE M\n  CONST robtarget pW := {rt(1500, 300, 900)};\n  PROC main()\n" \
           f"    MoveL pW, v100, fine, tool0;\n  ENDPROC\nENDMODULE\n"
    p = rapid.read(["m.mod"], [text], syspar=syspar)
    world_base = np.eye(4)
    world_base[:3, :3] = frames.rotation_from_quaternion(np.array([0.707106781, 0, 0, 0.707106781]))
    world_base[:3, 3] = [500, -200, 100]
    in_base = np.linalg.inv(world_base) @ [1500, 300, 900, 1]
    np.testing.assert_allclose(rows(p)[0], in_base[:3], atol=1e-6)
    (note,) = p.notes
    assert note.code == "P234" and (note.path, note.line) == ("SYSPAR/MOC.cfg", 14)
    report = compensate_program(p, model)
    assert report.complete
    expected = (world_base @ np.r_[command(in_base[:3]), 1])[:3]
    np.testing.assert_allclose(numbers(report.outputs["m.mod"], "pW"), expected, atol=1e-3)


MOC2 = """MOC:CFG_1.0:6:0::
#
MECHANICAL_UNIT_GROUP:

      -name "rob1" -robot "ROB_1" -use_motion_planner "motion_planner_1"

      -name "rob2" -robot "ROB_2" -use_motion_planner "motion_planner_2"
#
ROBOT:

      -name "ROB_1" -use_robot_type "ROB1_6700"

      -name "ROB_2" -use_robot_type "ROB2_6700" -base_frame_pos_x 2
"""


def test_a_multimove_task_takes_its_own_robots_base():
    syspar = {"SYSPAR/SYS.cfg": SYS_CFG, "SYSPAR/MOC.cfg": MOC2}
    text = f"MODULE M\n  PROC main()\n    MoveL {rt(2500, 0, 900)}, v100, fine, tool0;\n  ENDPROC\nENDMODULE\n"
    np.testing.assert_allclose(rows(rapid.read(["m.mod"], [text], syspar=syspar, task="T_ROB1"))[0], [2500, 0, 900])
    np.testing.assert_allclose(rows(rapid.read(["m.mod"], [text], syspar=syspar, task="T_ROB2"))[0], [500, 0, 900])
    # no task named, two robots of which one states a base: which one is not known
    (d,) = rapid.read(["m.mod"], [text], syspar=syspar).diagnostics
    assert d.code == "P201" and "ROB_1, ROB_2" in d.message
    # system parameters that say nothing of the base: as without them
    assert rapid.read(["m.mod"], [text], syspar={"SYSPAR/MOC.cfg": MOC2.replace(" -base_frame_pos_x 2", "")}
                      ).diagnostics == []


def test_a_work_object_a_unit_moves_names_where_moc_declares_it():
    syspar = {"SYSPAR/MOC.cfg": MOC.format(base="")}
    text = f"""MODULE M
  PERS wobjdata wStn := [FALSE,FALSE,"STN1",[[0,0,0],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];
  PROC main()
    MoveL {rt(100, 0, 50)}, v100, fine, tool0\\WObj:=wStn;
  ENDPROC
ENDMODULE
"""
    (d,) = rapid.read(["m.mod"], [text], syspar=syspar).diagnostics
    assert d.code == "P225" and "STN1, declared at SYSPAR/MOC.cfg:8" in d.message

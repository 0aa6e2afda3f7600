"""Robots on tracks and parts on turntables (postproc.robot.external, issue 25): every target is
compensated in the robot's own base at the external axis value it states and written back in the
program's frame; where the unit's kinematics are not given, or the target does not state its
axis, it is left as written with a located P225 — never a guess."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from postproc.compensation.api import compensate_text
from postproc.model.compensator import load_model
from postproc.core.diagnostics import PostprocError
from postproc.robot.external import ExternalUnit, parse_external, read_external
from postproc.core.frames import frame_to_matrix, matrix_to_frame
from postproc.programs import ActiveFrames, krl

GAIN = np.diag([1e-3, 2e-3, -1e-3])  # a correction that varies over space: a frame bug shows
TOOL = (300.0, 0.0, 75.0, 0.0, 0.0, 0.0)
# a track along the world's Y, its root turned 90° about Z and raised: E1 moves the robot along world Y
TRACK = ExternalUnit("KL", "prismatic", "E1", "robot", direction=(1.0, 0.0, 0.0), mount=(500.0, -1000.0, 200.0, 90.0, 0.0, 0.0))
# a turntable 2.5 m in front of the robot, turning about its Z; the base sits on it, 300 mm off its axis
TABLE = ExternalUnit("DKP", "rotary", "E1", "workpiece", direction=(0.0, 0.0, 1.0), mount=(2500.0, 0.0, 400.0, 0.0, 0.0, 0.0),
                     machine_def=1)
# robot-base poses inside the test model's envelope
BASE_POSES = np.array([[1900.0, -200.0, 800.0, 0.0, 90.0, 0.0], [2100.0, 150.0, 950.0, 5.0, 88.0, -3.0],
                       [2000.0, 400.0, 700.0, 0.0, 90.0, 0.0]])
E1 = np.array([0.0, 1250.0, 3400.0])


def _numbers(text: str) -> list[dict]:
    """Each LIN aggregate's components as written."""
    out = []
    for agg in re.findall(r"LIN \{(?:E6POS: )?([^}]*)\}", text):
        out.append({k: float(v) for k, v in re.findall(r"([A-Z]\d?) (-?[\d.]+)", agg)})
    return out


def _lin(pose, e1=None) -> str:
    body = ",".join(f"{k} {v:.4f}" for k, v in zip("XYZABC", pose))
    return f"  LIN {{E6POS: {body},E1 {e1:g}}}\n" if e1 is not None else f"  LIN {{{body}}}\n"


def _track_program(extra: str = "") -> tuple[str, np.ndarray]:
    """Targets in $BASE = $NULLFRAME (the world) whose robot-base poses are BASE_POSES at E1."""
    world = frame_to_matrix(BASE_POSES)
    world = TRACK.base_at(E1) @ world
    poses = matrix_to_frame(world)
    tool = ",".join(f"{k} {v:g}" for k, v in zip("XYZABC", TOOL))
    src = "DEF t( )\n  $BASE = $NULLFRAME\n  $TOOL = {" + tool + "}\n"
    src += "".join(_lin(p, e) for p, e in zip(poses, E1)) + extra + "END\n"
    return src, poses


def _expected(model_path, base_poses, to_program):
    """The model's commands for the robot-base poses, back in the program's frame
    (``to_program`` [N, 4, 4]: robot base ← the program's frame at each target)."""
    model = load_model(model_path)
    c = model.command(base_poses, tool=np.tile(TOOL, (len(base_poses), 1)))
    cmd = frame_to_matrix(base_poses)
    cmd[:, :3, 3] = c
    return np.einsum("nij,njk->nik", np.linalg.inv(to_program), cmd)[:, :3, 3]


def test_a_krl_track_target_is_compensated_in_the_robots_own_base_and_written_back_in_the_world(affine):
    model = affine(gain=GAIN, tool={"name": "spindle", "frame": list(TOOL)})
    src, poses = _track_program()
    out, report = compensate_text(src, model, name="t.src", dialect="krl", active=ActiveFrames(external=(TRACK,)))
    assert report.compensated == 3 and report.left == 0, report.warnings
    got = _numbers(out)
    expected = _expected(model, BASE_POSES, np.linalg.inv(TRACK.base_at(E1)))
    np.testing.assert_allclose([[g["X"], g["Y"], g["Z"]] for g in got], expected, atol=6e-4)
    # the external axis value and the orientation are as written
    assert [g["E1"] for g in got] == E1.tolist()
    np.testing.assert_allclose([[g["A"], g["B"], g["C"]] for g in got], poses[:, 3:], atol=6e-5)
    # the same targets taken as fixed-robot ones would be other commands (the frame matters)
    wrong = _expected(model, poses, np.eye(4)[None].repeat(3, 0))
    assert np.abs(wrong - expected).max() > 0.05
    # the envelope and the reach are the robot's own: in its base every target is inside; taken
    # as a fixed robot's, the world's numbers are out of its reach (refused, P302)
    assert not {"P301", "P302"} & {d.code for d in report.warnings}
    with pytest.raises(PostprocError) as exc:
        compensate_text(src, model, name="t.src", dialect="krl")
    assert exc.value.code == "P302"


def test_without_the_tracks_kinematics_or_its_axis_the_target_is_left_located(affine):
    model = affine(gain=GAIN, tool={"name": "spindle", "frame": list(TOOL)})
    src, _ = _track_program(extra="  LIN {X 2000,Y 0,Z 900,A 0,B 90,C 0}\n")
    # the machine data say the robot is on a track, but not its kinematics: every target P225, located
    from postproc.programs import RobotRoot

    rr = RobotRoot(None, "$machine.dat", "the robot is on an external kinematic ($EX_KIN ET1 #ERSYS)")
    out, report = compensate_text(src, model, name="t.src", dialect="krl", active=ActiveFrames(robroot=rr))
    assert report.compensated == 0 and out == src
    assert {d.code for d in report.warnings} == {"P225"}
    # with the kinematics, the target that states no E1 (its track position not known here) is the one left
    out, report = compensate_text(src, model, name="t.src", dialect="krl", active=ActiveFrames(robroot=rr, external=(TRACK,)))
    assert report.compensated == 3 and report.left == 1
    (d,) = [d for d in report.warnings if d.code == "P225"]
    assert d.line == 7 and "state no E1" in d.message
    assert "  LIN {X 2000,Y 0,Z 900,A 0,B 90,C 0}" in out.splitlines()


def test_the_track_of_a_backups_machine_data(tmp_path, affine):
    from postproc.programs.krl.machine import robroot_of

    mada = ("DECL EX_KIN $EX_KIN={ET1 #ERSYS,ET2 #NONE,ET3 #NONE,ET4 #NONE,ET5 #NONE,ET6 #NONE}\n"
            "DECL ET_AX $ET1_AX={TR_A1 #E1,TR_A2 #NONE,TR_A3 #NONE}\n"
            "$AXIS_TYPE[7]=1\n"
            "FRAME $ERSYSROOT={X 500.0,Y -1000.0,Z 200.0,A 0.0,B 0.0,C 0.0}\n"
            "FRAME $ET1_TA1KR={X 0.0,Y 0.0,Z 0.0,A 90.0,B 90.0,C 0.0}\n"
            "FRAME $ET1_TFLA3={X 0.0,Y 0.0,Z 0.0,A -90.0,B 0.0,C 90.0}\n")
    rr = robroot_of(mada, "$machine.dat")
    unit = rr.unit
    assert rr.frame is None and unit.type == "prismatic" and unit.axis == "E1" and unit.carries == "robot"
    # the Z axis of $ET1_TA1KR (here world Y) is the direction of travel; TFLA3 turns the carriage back
    np.testing.assert_allclose(unit.base_at(1000.0)[:3, 3], [500.0, 0.0, 200.0], atol=1e-9)
    np.testing.assert_allclose(unit.base_at(0.0)[:3, :3], np.eye(3), atol=1e-12)
    model = affine(gain=GAIN, tool={"name": "spindle", "frame": list(TOOL)})
    src = ("DEF t( )\n  $BASE = $NULLFRAME\n  $TOOL = {X 300,Y 0,Z 75,A 0,B 0,C 0}\n"
           "  LIN {E6POS: X 2500,Y 0,Z 1000,A 0,B 90,C 0,E1 1000}\nEND\n")
    out, report = compensate_text(src, model, name="t.src", dialect="krl", active=ActiveFrames(robroot=rr))
    assert report.compensated == 1
    x, y, z = (_numbers(out)[0][k] for k in "XYZ")
    expected = _expected(model, np.array([[2000.0, 0.0, 800.0, 0.0, 90.0, 0.0]]), np.linalg.inv(unit.base_at([1000.0])))
    np.testing.assert_allclose([x, y, z], expected[0], atol=6e-4)
    # what the machine data leave out is said, never guessed
    rr = robroot_of(mada.replace("$AXIS_TYPE[7]=1\n", ""), "$machine.dat")
    assert rr.unit is None and "no $AXIS_TYPE[7]" in rr.why and "--external" in rr.why


CONFIG_TABLE = ("DEFDAT $CONFIG\n"
                "DECL FRAME BASE_DATA[32]\n"
                "BASE_DATA[1]={X 300.0,Y 0.0,Z 150.0,A 30.0,B 0.0,C 0.0}\n"
                "DECL MACHINE_FRAME_DAT MACHINE_FRAME_DAT[32]\n"
                "MACHINE_FRAME_DAT[1]={MACH_DEF_INDEX 1,PARENT[] \"WORLD\",GEOMETRY[] \" \"}\n"
                "ENDDAT\n")


def _table_program() -> tuple[str, np.ndarray]:
    """Targets in BASE_DATA[1] on the turntable, whose robot-base poses are BASE_POSES at E1 (deg)."""
    e = np.array([0.0, 90.0, -135.0])
    base = TABLE.base_at(e) @ frame_to_matrix(np.array([300.0, 0.0, 150.0, 30.0, 0.0, 0.0]))
    local = matrix_to_frame(np.linalg.inv(base) @ frame_to_matrix(BASE_POSES))
    src = "DEF t( )\n  BAS(#BASE, 1)\n  $TOOL = {X 300,Y 0,Z 75,A 0,B 0,C 0}\n"
    src += "".join(_lin(p, x) for p, x in zip(local, e)) + "END\n"
    return src, base


def test_a_krl_base_on_a_turntable_moves_with_its_axis(affine):
    model = affine(gain=GAIN, tool={"name": "spindle", "frame": list(TOOL)})
    src, base = _table_program()
    active = ActiveFrames(robroot=None, external=(TABLE,))
    p = krl.read(["t.src"], [src], config=[CONFIG_TABLE], active=active)
    assert (p.targets.frame >= 0).all() and len(p.frames) == 3
    for f, b in zip(p.frames, base):
        np.testing.assert_allclose(f.base, b, atol=1e-9)
    # compensated end to end (text in, text out)
    from postproc.compensation.pipeline import compensate_program

    report = compensate_program(p, load_model(model))
    got = _numbers(report.outputs["t.src"])
    np.testing.assert_allclose([[g["X"], g["Y"], g["Z"]] for g in got], _expected(model, BASE_POSES, base), atol=6e-4)
    # without the turntable's kinematics: P225 at the BAS that puts the base on it
    p = krl.read(["t.src"], [src], config=[CONFIG_TABLE])
    (d,) = p.diagnostics
    assert d.code == "P225" and d.line == 2 and "MACHINE_DEF[1]" in d.message and "--external" in d.message


def test_external_units_are_checked_where_they_are_written(tmp_path):
    path = tmp_path / "units.toml"
    path.write_text('[[external]]\ntype = "prismatic"\naxis = "E1"\ncarries = "robot"\n\n'
                    '[[external]]\ntype = "linear"\naxis = "E2"\ncarries = "workpiece"\n')
    with pytest.raises(PostprocError) as exc:
        read_external(path)
    assert exc.value.code == "P227" and exc.value.line == 7 and "prismatic or rotary" in str(exc.value)
    with pytest.raises(PostprocError, match="axis must be"):
        parse_external({"type": "rotary", "axis": "A7", "carries": "workpiece"})
    with pytest.raises(PostprocError, match="two external units carry the robot"):
        parse_external([{"type": "rotary", "axis": "E1", "carries": "robot"},
                        {"type": "prismatic", "axis": "E2", "carries": "robot"}])
    # a rotary unit turns about its direction by degrees
    unit = parse_external({"type": "rotary", "axis": "e2", "carries": "workpiece", "direction": [0, 0, 2]})[0]
    assert unit.axis == "E2"
    np.testing.assert_allclose(unit.base_at(90.0)[:3, :3], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-12)


# ------------------------------------------------------------------------------------ RAPID

def _rapid(poses, e1=None, wobj="") -> str:
    q = __import__("postproc.core.frames", fromlist=["x"]).quaternion_from_rotation(
        __import__("postproc.core.frames", fromlist=["x"]).rotation_from_abc(poses[:, 3:]))
    lines = ["MODULE m",
             "  PERS tooldata tS := [TRUE, [[300, 0, 75], [1, 0, 0, 0]], [10, [0, 0, 100], [1, 0, 0, 0], 0, 0, 0]];",
             "  PERS wobjdata wT := [FALSE, FALSE, \"STN1\", [[300, 0, 150], [0.9659258263, 0, 0, 0.2588190451]], "
             "[[0, 0, 0], [1, 0, 0, 0]]];",
             "  PROC main()"]
    for k, (p, qq) in enumerate(zip(poses, q)):
        eax = f"{e1[k]:g}" if e1 is not None else "9E9"
        lines.append(f"    MoveL [[{p[0]:.4f}, {p[1]:.4f}, {p[2]:.4f}], [{', '.join(f'{v:.9f}' for v in qq)}], "
                     f"[0, 0, 0, 0], [{eax}, 9E9, 9E9, 9E9, 9E9, 9E9]], v100, fine, tS{wobj};")
    return "\n".join(lines + ["  ENDPROC", "ENDMODULE", ""])


def _rapid_xyz(text):
    return np.array([[float(v) for v in m] for m in re.findall(r"MoveL \[\[([-\d.]+), ([-\d.]+), ([-\d.]+)\]", text)])


def test_a_rapid_robtarget_on_a_track_is_compensated_in_the_robots_base(affine):
    model = affine(gain=GAIN, tool={"name": "spindle", "frame": list(TOOL)})
    world = matrix_to_frame(TRACK.base_at(E1) @ frame_to_matrix(BASE_POSES))
    src = _rapid(world, E1)
    # without the track's kinematics: each robtarget that uses eax_a is left, located
    out, report = compensate_text(src, model, name="m.mod", dialect="rapid", force=True)
    assert report.compensated == 0 and {d.code for d in report.warnings} == {"P225"}
    out, report = compensate_text(src, model, name="m.mod", dialect="rapid", force=True,
                                  active=ActiveFrames(external=(TRACK,)))
    assert report.compensated == 3, report.warnings
    np.testing.assert_allclose(_rapid_xyz(out), _expected(model, BASE_POSES, np.linalg.inv(TRACK.base_at(E1))),
                               atol=6e-4)
    assert out.count("9E9, 9E9, 9E9, 9E9, 9E9]]") == 3 and all(f"[{e:g}, 9E9" in out for e in E1)


def test_a_rapid_work_object_coordinated_with_a_positioner(affine):
    model = affine(gain=GAIN, tool={"name": "spindle", "frame": list(TOOL)})
    unit = ExternalUnit("STN1", "rotary", "E1", "workpiece", direction=(0.0, 0.0, 1.0),
                        mount=(2500.0, 0.0, 400.0, 0.0, 0.0, 0.0), mech_unit="STN1")
    e = np.array([0.0, 90.0, -135.0])
    on = unit.base_at(e) @ frame_to_matrix(np.array([300.0, 0.0, 150.0, 30.0, 0.0, 0.0]))
    local = matrix_to_frame(np.linalg.inv(on) @ frame_to_matrix(BASE_POSES))
    src = _rapid(local, e, wobj="\\WObj:=wT")
    out, report = compensate_text(src, model, name="m.mod", dialect="rapid", force=True)
    assert report.compensated == 0 and {d.code for d in report.warnings} == {"P225"}
    # a unit stated for another mechanical unit: the work object's is still not known
    other = ExternalUnit("STN2", "rotary", "E1", "workpiece", mech_unit="STN2")
    out, report = compensate_text(src, model, name="m.mod", dialect="rapid", force=True,
                                  active=ActiveFrames(external=(other,)))
    assert report.compensated == 0 and any("STN1" in d.message for d in report.warnings if d.code == "P225")
    out, report = compensate_text(src, model, name="m.mod", dialect="rapid", force=True,
                                  active=ActiveFrames(external=(unit,)))
    assert report.compensated == 3, report.warnings
    np.testing.assert_allclose(_rapid_xyz(out), _expected(model, BASE_POSES, on), atol=6e-4)


# ------------------------------------------------------------------------ the simulated cell

def test_verify_runs_a_track_program_on_the_simulated_track(tmp_path, capsys):
    """compensate with the track's kinematics, verify on a KR500 whose description carries the
    track: as accurate as the fixed robot's program of the same robot-base poses."""
    import json

    from postproc.cli import main

    repo = Path(__file__).resolve().parent.parent
    track = tmp_path / "track.toml"
    track.write_text('[[external]]\ntype = "prismatic"\naxis = "E1"\ncarries = "robot"\ndirection = [1, 0, 0]\n'
                     'mount = [500, -1000, 200, 90, 0, 0]\n')
    robot = tmp_path / "kr500_track.toml"
    robot.write_text((repo / "models" / "kr500.toml").read_text() + "\n" + track.read_text())
    src, _ = _track_program()
    fixed = "DEF t( )\n  $BASE = $NULLFRAME\n  $TOOL = {X 300,Y 0,Z 75,A 0,B 0,C 0}\n" + \
        "".join(_lin(p) for p in BASE_POSES) + "END\n"
    after = {}
    for name, text, extra, cell in (("fixed", fixed, [], repo / "models" / "kr500.toml"),
                                    ("track", src, ["--external", str(track)], robot)):
        (tmp_path / f"{name}.src").write_text(text)
        assert main(["compensate", str(tmp_path / f"{name}.src"), "-o", str(tmp_path / "out" / f"{name}.src"),
                     "-q", *extra]) in (0, 1)
        capsys.readouterr()
        assert main(["verify", str(tmp_path / f"{name}.src"), str(tmp_path / "out" / f"{name}.src"), "--robot",
                     str(cell), "--json", "-q"]) == 0
        v = json.loads(capsys.readouterr().out)
        assert v["targets"] == v["compensated"] == 3
        after[name] = v["after"]["mean"]
        assert v["after"]["mean"] < 0.3 * v["before"]["mean"]
    assert after["track"] <= 1.05 * after["fixed"]


# ---------------------------------------------------------------------------------- FANUC LS

def _ls(poses, j1, group="GP2") -> str:
    mn = "".join(f"{4 + k:4d}:L P[{k + 1}] 500mm/sec FINE    ;\n" for k in range(len(poses)))
    pos = []
    for k, (p, e) in enumerate(zip(poses, j1)):
        x, y, z, a, b, c = p
        gp1 = (f"   GP1:\n\tUF : 0, UT : 1,\t\tCONFIG : 'N U T, 0, 0, 0',\n"
               f"\tX = {x:.3f} mm,\tY = {y:.3f} mm,\tZ = {z:.3f} mm,\n"
               f"\tW = {c:.3f} deg,\tP = {b:.3f} deg,\tR = {a:.3f} deg")
        if group == "E1":
            gp1 += f",\n\tE1= {e:.3f} mm"
        else:
            gp1 += f"\n   GP2:\n\tUF : 0, UT : 1,\n\tJ1= {e:.3f} mm"
        pos.append(f"P[{k + 1}]{{\n{gp1}\n}};\n")
    return ("/PROG  TRK\n/ATTR\nDEFAULT_GROUP\t= 1,1,*,*,*;\n/MN\n   1:  UFRAME_NUM=0 ;\n   2:  UTOOL_NUM=1 ;\n"
            "   3:  ! on the track ;\n" + mn + "/POS\n" + "".join(pos) + "/END\n")


@pytest.mark.parametrize("group", ["GP2", "E1"])
def test_a_fanuc_track_group_2_or_extended_axis(tmp_path, affine, group):
    model = affine(gain=GAIN, tool={"name": "spindle", "frame": list(TOOL)})
    unit = ExternalUnit("RAIL", "prismatic", "GP2.J1" if group == "GP2" else "E1", "robot", direction=(1.0, 0.0, 0.0),
                        mount=(500.0, -1000.0, 200.0, 90.0, 0.0, 0.0))
    world = matrix_to_frame(unit.base_at(E1) @ frame_to_matrix(BASE_POSES))
    src = _ls(world, E1, group)
    frames_file = tmp_path / "frames.toml"
    frames_file.write_text("[utool.1]\nxyzwpr = [300, 0, 75, 0, 0, 0]\n")
    out, report = compensate_text(src, model, name="trk.ls", dialect="fanuc", config=str(frames_file), force=True)
    assert report.compensated == 0 and {d.code for d in report.warnings} == {"P225"}
    # the track in the frame file ([[external]]) or given apart: the same commands
    frames_file.write_text(frames_file.read_text() + f'\n[[external]]\ntype = "prismatic"\naxis = "{unit.axis}"\n'
                           'carries = "robot"\ndirection = [1, 0, 0]\nmount = [500, -1000, 200, 90, 0, 0]\n')
    out, report = compensate_text(src, model, name="trk.ls", dialect="fanuc", config=str(frames_file), force=True)
    assert report.compensated == 3, report.warnings
    xyz = np.array([[float(v) for v in m] for m in re.findall(
        r"X =\s*(-?[\d.]+) mm,\s*Y =\s*(-?[\d.]+) mm,\s*Z =\s*(-?[\d.]+) mm", out)])
    np.testing.assert_allclose(xyz, _expected(model, BASE_POSES, np.linalg.inv(unit.base_at(E1))), atol=6e-4)
    assert all(f"= {e:.3f} mm" in out for e in E1)


def test_the_worked_example_of_the_docs():
    """docs/EXTERNAL.md's track and its worked example hold."""
    import tomllib

    doc = (Path(__file__).resolve().parent.parent / "docs" / "EXTERNAL.md").read_text()
    block = re.search(r"```toml\n(.*?)```", doc, re.S).group(1)
    track, table = parse_external(tomllib.loads(block)["external"])
    assert (track.carries, table.carries, table.machine_def, table.mech_unit) == ("robot", "workpiece", 1, "STN1")
    target = re.search(r"`LIN \{E6POS: ([^}]*)\}`", doc).group(1)
    values = dict(re.findall(r"(\w+) (-?[\d.]+)", target))
    pose = np.array([float(values[k]) for k in "XYZABC"])
    seen = matrix_to_frame(np.linalg.inv(track.base_at(float(values["E1"]))) @ frame_to_matrix(pose))
    np.testing.assert_allclose(seen, [2000, 0, 800, 0, 90, 0], atol=1e-9)


def test_frame_groups_are_the_rows_of_each_frame():
    from postproc.core.frames import frame_groups

    frame = np.array([2, -1, 0, 2, 5, 0, -1, 2])
    groups = frame_groups(frame)
    assert [f for f, _ in groups] == [0, 2, 5]
    for f, rows in groups:
        assert rows.tolist() == np.flatnonzero(frame == f).tolist()
    assert frame_groups(np.array([-1, -1])) == []


def test_check_reads_a_rapid_track_program_with_its_external_units_as_compensate(affine):
    """check of RAPID modules (programs.cell's parts) takes --external as compensate does: the
    track's targets are no P225 once its kinematics are given."""
    from postproc.compensation.check import check_files
    from postproc.settings import Settings

    import tempfile
    from pathlib import Path

    model = load_model(affine(gain=GAIN, tool={"name": "spindle", "frame": list(TOOL)}))
    world = matrix_to_frame(TRACK.base_at(E1) @ frame_to_matrix(BASE_POSES))
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "m.mod"
        path.write_text(_rapid(world, E1))
        plain = Settings().override(force=True)
        assert "P225" in {f.code for f in check_files([path], model, plain)}
        stated = plain.override(active=ActiveFrames(external=(TRACK,)))
        assert "P225" not in {f.code for f in check_files([path], model, stated)}

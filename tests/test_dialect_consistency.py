"""The same poses written as KRL, ABB RAPID, URScript, Fanuc LS and a pose CSV get the same
corrections from the same model (an affine one: the correction varies over space), to the
written precision.

Each program holds the poses in its own way: KRL, RAPID and LS in a frame turned 90° about Z
and shifted ($BASE / a work object's user frame / a user frame UF of the frame file),
URScript and the CSV in the robot base
(URScript in metres, orientation as a rotation vector in radians). The corrected numbers of
each are taken back into the robot base and compared."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from postproc.core import frames
from postproc.compensation.api import compensate_text
from postproc.programs.io import parse_program_text
from postproc.model.compensator import load_model

BASE = np.array([1800.0, -300.0, 600.0, 90.0, 0.0, 0.0])  # X,Y,Z,A,B,C of the frame
LOCAL = np.array([[100.0, 50.0, 320.5, 0.0, 90.0, 0.0],
                  [250.25, -120.0, 400.0, 10.0, 80.0, -5.0],
                  [-80.0, 300.0, 250.0, -30.0, 85.0, 20.0],
                  [400.0, 0.0, 500.0, 45.0, 70.0, 0.0]])
GAIN = np.array([[2e-3, 0, 0], [0, -1e-3, 5e-4], [0, 0, 3e-3]])
WRITTEN = 5e-4  # numbers are written to 3 decimals


def _quat(abc):
    q = Rotation.from_euler("ZYX", abc, degrees=True).as_quat()
    return [q[3], q[0], q[1], q[2]]


def krl():
    lines = ["DEF cons( )", "$BASE = {X %.3f,Y %.3f,Z %.3f,A %.3f,B %.3f,C %.3f}" % tuple(BASE),
             "$TOOL = {X 0.000,Y 0.000,Z 200.000,A 0.000,B 0.000,C 0.000}"]
    lines += ["LIN {X %.3f,Y %.3f,Z %.3f,A %.3f,B %.3f,C %.3f}" % tuple(p) for p in LOCAL]
    return "\n".join(lines + ["END", ""]), "cons.src"


def rapid():
    bq = ",".join(f"{v:.12f}" for v in _quat(BASE[3:]))
    lines = ["MODULE cons", "PERS tooldata t1:=[TRUE,[[0,0,200],[1,0,0,0]],[1,[0,0,1],[1,0,0,0],0,0,0]];",
             f"PERS wobjdata w1:=[FALSE,TRUE,\"\",[[{BASE[0]:.3f},{BASE[1]:.3f},{BASE[2]:.3f}],[{bq}]],"
             "[[0,0,0],[1,0,0,0]]];", "PROC main()"]
    for p in LOCAL:
        q = ",".join(f"{v:.12f}" for v in _quat(p[3:]))
        lines.append(f"MoveL [[{p[0]:.3f},{p[1]:.3f},{p[2]:.3f}],[{q}],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]],"
                     "v100,z1,t1\\WObj:=w1;")
    return "\n".join(lines + ["ENDPROC", "ENDMODULE", ""]), "cons.mod"


def urscript():
    t = frames.frame_to_matrix(BASE) @ frames.frame_to_matrix(LOCAL)
    lines = ["def cons():", "  set_tcp(p[0, 0, 0.2, 0, 0, 0])"]
    for m in t:
        rv = Rotation.from_matrix(m[:3, :3]).as_rotvec()
        lines.append("  movel(p[%.9f, %.9f, %.9f, %.12f, %.12f, %.12f], a=1.2, v=0.25)" % (*(m[:3, 3] / 1000), *rv))
    return "\n".join(lines + ["end", ""]), "cons.script"


FANUC_FRAMES = ("[uframe.3]\nxyzwpr = [%.3f, %.3f, %.3f, %.3f, %.3f, %.3f]\n"
                % (*BASE[:3], BASE[5], BASE[4], BASE[3]) + "[utool.2]\nxyzwpr = [0, 0, 200, 0, 0, 0]\n")


def fanuc():
    mn = [f"{k:4d}:L P[{k}] 100mm/sec FINE    ;" for k in range(1, len(LOCAL) + 1)]
    pos = []
    for k, p in enumerate(LOCAL, start=1):
        pos.append(f"P[{k}]{{\n   GP1:\n\tUF : 3, UT : 2,\t\tCONFIG : 'N U T, 0, 0, 0',\n"
                   f"\tX = {p[0]:9.3f}  mm,\tY = {p[1]:9.3f}  mm,\tZ = {p[2]:9.3f}  mm,\n"
                   f"\tW = {p[5]:9.3f} deg,\tP = {p[4]:9.3f} deg,\tR = {p[3]:9.3f} deg\n}};")
    return "\n".join(["/PROG  CONS", "/ATTR", "/MN", *mn, "/POS", *pos, "/END", ""]), "cons.ls"


def csv():
    t = frames.frame_to_matrix(BASE) @ frames.frame_to_matrix(LOCAL)
    base = frames.matrix_to_frame(t)
    rows = [",".join(f"{v:.6f}" for v in p) for p in base]
    return "x,y,z,a,b,c\n" + "\n".join(rows) + "\n", "cons.csv"


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    from postproc.testing.models import affine_model

    path = affine_model(tmp_path_factory.mktemp("cons") / "affine.onnx", offset=(0.3, -0.2, 0.1), gain=GAIN,
                        reach=None, tool={"name": "any"})
    return load_model(path)


def _in_base(text, name, config=None):
    p = parse_program_text(text, name, config_texts=[config.read_text()] if config else None)
    t = p.targets
    out = np.empty((len(t), 3))
    for f in np.unique(t.frame):
        rows = t.frame == f
        out[rows] = frames.transform_points(p.frames[f].base, t.poses[rows, :3])
    return out, p


def test_same_poses_same_corrections_in_every_dialect(model, tmp_path):
    results = {}
    for make in (krl, rapid, urscript, fanuc, csv):
        text, name = make()
        config = None
        if make is fanuc:  # the user and tool frames in the frame file (--frames)
            config = tmp_path / "frames.toml"
            config.write_text(FANUC_FRAMES)
        before, program = _in_base(text, name, config)
        assert len(program.targets) == len(LOCAL), name
        assert np.allclose(before, frames.transform_points(frames.frame_to_matrix(BASE), LOCAL[:, :3]), atol=1e-6)
        out, report = compensate_text(text, model, name=name, config=config)
        assert report.compensated == len(LOCAL)
        after, _ = _in_base(out, name, config)
        results[name] = after - before
    reference = results["cons.csv"]
    # the correction varies from target to target: the test can tell a wrong frame or point
    assert np.ptp(reference, axis=0).max() > 0.1
    for name, correction in results.items():
        assert np.allclose(correction, reference, atol=2 * WRITTEN), name


# --------------------------------------------------------------------------- stated configurations

JOINT_GAIN = np.array([[0.3, -0.2, 0.5, 0.1, 0.4, -0.3],
                       [0.1, 0.4, -0.2, 0.3, -0.5, 0.2],
                       [-0.4, 0.2, 0.3, -0.1, 0.2, 0.5]])  # mm per unit sin(q): a model of the joints


def _family_program(kind, robot, q):
    """The poses of joint angles ``q`` [n, 6] as a program of ``kind`` that states each one's
    configuration in its controller's form (KRL: S/T, RAPID: confdata, LS: CONFIG), in a frame
    turned and shifted (BASE), PTP / MoveJ / J motions; with its config texts."""
    from postproc.robot import conventions

    poses = robot.fk(q)
    local = frames.matrix_to_frame(frames.inverse(frames.frame_to_matrix(BASE)) @ frames.frame_to_matrix(poses))
    tool = robot.tool
    if kind == "krl":
        s, t = robot.status_turn(q)
        lines = ["DEF cons( )", "$BASE = {X %.3f,Y %.3f,Z %.3f,A %.3f,B %.3f,C %.3f}" % tuple(BASE),
                 "$TOOL = {X %g,Y %g,Z %g,A %g,B %g,C %g}" % tuple(tool)]
        lines += ["PTP {X %.4f,Y %.4f,Z %.4f,A %.4f,B %.4f,C %.4f,S %d,T %d}" % (*p, a, b) for p, a, b in zip(local, s, t)]
        return "\n".join(lines + ["END", ""]), "cons.src", None
    if kind == "rapid":
        conf = conventions.abb_confdata(robot, q)
        bq = ",".join(f"{v:.12f}" for v in _quat(BASE[3:]))
        lines = ["MODULE cons", f"PERS tooldata t1:=[TRUE,[[{tool[0]},{tool[1]},{tool[2]}],[1,0,0,0]],[1,[0,0,1],[1,0,0,0],0,0,0]];",
                 f"PERS wobjdata w1:=[FALSE,TRUE,\"\",[[{BASE[0]:.3f},{BASE[1]:.3f},{BASE[2]:.3f}],[{bq}]],"
                 "[[0,0,0],[1,0,0,0]]];", "PROC main()"]
        for p, c in zip(local, conf):
            qs = ",".join(f"{v:.12f}" for v in _quat(p[3:]))
            lines.append(f"MoveJ [[{p[0]:.4f},{p[1]:.4f},{p[2]:.4f}],[{qs}],[{c[0]},{c[1]},{c[2]},{c[3]}],"
                         "[9E9,9E9,9E9,9E9,9E9,9E9]],v100,z1,t1\\WObj:=w1;")
        return "\n".join(lines + ["ENDPROC", "ENDMODULE", ""]), "cons.mod", None
    configs = conventions.fanuc_configs(robot, q)
    mn = [f"{k:4d}:J P[{k}] 100% FINE    ;" for k in range(1, len(q) + 1)]
    pos = [f"P[{k}]{{\n   GP1:\n\tUF : 3, UT : 2,\t\tCONFIG : '{c}',\n"
           f"\tX = {p[0]:10.4f}  mm,\tY = {p[1]:10.4f}  mm,\tZ = {p[2]:10.4f}  mm,\n"
           f"\tW = {p[5]:10.4f} deg,\tP = {p[4]:10.4f} deg,\tR = {p[3]:10.4f} deg\n}};"
           for k, (p, c) in enumerate(zip(local, configs), start=1)]
    frames_text = ("[uframe.3]\nxyzwpr = [%.3f, %.3f, %.3f, %.3f, %.3f, %.3f]\n" % (*BASE[:3], BASE[5], BASE[4], BASE[3])
                   + "[utool.2]\nxyzwpr = [%g, %g, %g, 0, 0, 0]\n" % tuple(tool[:3]))
    return "\n".join(["/PROG  CONS", "/ATTR", "/MN", *mn, "/POS", *pos, "/END", ""]), "cons.ls", frames_text


@pytest.mark.parametrize("kind, description, robot_name, q", [
    ("krl", "kr500.toml", "KR500-sim", [[5.0, -60.0, 100.0, 30.0, 50.0, 20.0], [5.0, -60.0, 100.0, -150.0, -50.0, -160.0],
                                       [-10.0, -75.0, 110.0, 200.0, 40.0, 0.0]]),
    ("rapid", "irb6700.toml", "IRB6700-sim", [[5.0, 20.0, 10.0, 0.0, 60.0, 10.0], [5.0, 20.0, 10.0, 180.0, -60.0, -170.0],
                                              [-20.0, 30.0, -5.0, 100.0, 45.0, 250.0]]),
    ("fanuc", "r2000ic.toml", "R2000iC-sim", [[10.0, 20.0, -10.0, 0.0, -90.0, 30.0], [10.0, 20.0, -10.0, 180.0, 90.0, 210.0],
                                              [15.0, -20.0, -60.0, 330.0, -40.0, 10.0]]),
])
def test_stated_configurations_give_the_pose_lists_commands(tmp_path, kind, description, robot_name, q):
    """The same poses, each in a stated arm configuration (both wrists, joints on other turns), as
    a program in the controller's form and as a pose list with the joint angles q1..q6: a model
    of the joints gives them the same commands (its correction differs from branch to branch)."""
    from postproc.core.resources import model_path
    from postproc.robot.arm import Robot
    from postproc.robot.description import load_description
    from postproc.testing.models import joint_model

    robot = Robot(load_description(model_path(description)))
    q = np.array(q)
    model = load_model(joint_model(tmp_path / "j.onnx", JOINT_GAIN, robot=robot_name,
                                   tool={"name": "tool", "frame": robot.tool.tolist()}))
    text, name, frames_text = _family_program(kind, robot, q)
    config = None
    if frames_text:
        config = tmp_path / "frames.toml"
        config.write_text(frames_text)
    before, _ = _in_base(text, name, config)
    out, report = compensate_text(text, model, name=name, config=config)
    assert report.compensated == len(q) and report.left == 0, report.summary()
    after, _ = _in_base(out, name, config)
    poses = robot.fk(q)
    rows = "x,y,z,a,b,c,q1,q2,q3,q4,q5,q6\n" + "\n".join(",".join(f"{v:.6f}" for v in [*p, *j]) for p, j in zip(poses, q))
    listed, listed_report = compensate_text(rows + "\n", model, name="cons.csv")
    assert listed_report.compensated == len(q)
    reference = _in_base(listed, "cons.csv")[0] - poses[:, :3]
    assert np.abs(reference[0] - reference[1]).max() > 0.1  # (one pose, two wrists: two corrections)
    np.testing.assert_allclose(after - before, reference, atol=2e-3)  # (4 decimals written, in a turned frame)


def test_targets_declared_at_the_top_run_in_the_order_main_moves_to_them(tmp_path):
    """Issue 24: a RAPID module declares its 60 robtargets at the top and main moves to them in
    another order: each target's previous pose (the approach, for a model that takes it) is the
    one main ran before it, as in the pose list of the same poses in that order."""
    from postproc.testing.models import affine_model

    model = load_model(affine_model(tmp_path / "approach.onnx", offset=(0.3, -0.2, 0.1), gain=GAIN,
                                    previous_input=True, previous_gain=np.diag([2e-3, -3e-3, 2.5e-3]), reach=None,
                                    tool={"name": "any"}))
    rng = np.random.default_rng(24)
    n = 60
    local = np.c_[rng.uniform([-300, -250, 250], [300, 250, 450], (n, 3)), np.zeros((n, 1)), np.full((n, 1), 90.0),
                  np.zeros((n, 1))]
    order = rng.permutation(n)  # main's order; the declarations stand in index order
    bq = ",".join(f"{v:.12f}" for v in _quat(BASE[3:]))
    lines = ["MODULE cons", "PERS tooldata t1:=[TRUE,[[0,0,200],[1,0,0,0]],[1,[0,0,1],[1,0,0,0],0,0,0]];",
             f"PERS wobjdata w1:=[FALSE,TRUE,\"\",[[{BASE[0]:.3f},{BASE[1]:.3f},{BASE[2]:.3f}],[{bq}]],"
             "[[0,0,0],[1,0,0,0]]];"]
    for k, p in enumerate(local):
        q = ",".join(f"{v:.12f}" for v in _quat(p[3:]))
        lines.append(f"CONST robtarget p{k}:=[[{p[0]:.3f},{p[1]:.3f},{p[2]:.3f}],[{q}],[0,0,0,0],"
                     "[9E9,9E9,9E9,9E9,9E9,9E9]];")
    lines += ["PROC main()"] + [f"  MoveL p{k},v100,z1,t1\\WObj:=w1;" for k in order] + ["ENDPROC", "ENDMODULE", ""]
    text = "\n".join(lines)
    before, program = _in_base(text, "cons.mod")
    assert program.targets.line[:5].tolist() == [4 + k for k in order[:5]]  # rows in main's order
    out, report = compensate_text(text, model, name="cons.mod")
    assert report.compensated == n
    after, _ = _in_base(out, "cons.mod")
    base = frames.matrix_to_frame(frames.frame_to_matrix(BASE) @ frames.frame_to_matrix(local[order]))
    csv_text = "x,y,z,a,b,c\n" + "".join(",".join(f"{v:.6f}" for v in p) + "\n" for p in base)
    twin, _ = compensate_text(csv_text, model, name="cons.csv")
    reference = _in_base(twin, "cons.csv")[0] - _in_base(csv_text, "cons.csv")[0]
    assert np.allclose(after - before, reference, atol=2 * WRITTEN)
    # the approach matters here: chained in the order written, the corrections would differ
    shuffled = frames.matrix_to_frame(frames.frame_to_matrix(BASE) @ frames.frame_to_matrix(local))
    csv_written = "x,y,z,a,b,c\n" + "".join(",".join(f"{v:.6f}" for v in p) + "\n" for p in shuffled)
    other, _ = compensate_text(csv_written, model, name="cons.csv")
    wrong = (_in_base(other, "cons.csv")[0] - _in_base(csv_written, "cons.csv")[0])[order]
    assert np.abs(wrong - reference).max() > 0.1

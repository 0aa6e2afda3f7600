"""FANUC CONFIG strings and ABB confdata, both ways, on the shipped FANUC- and ABB-type
descriptions (docs/CONFIGURATIONS.md): joint angles over the whole joint space — every one of the
8 branches, turn numbers −1, 0, +1 of J1, J4, J6 (quadrants of axes 1, 4, 6) — written in the
controller's form and read back to the same joint angles; a program in the form compensated with
a model of the joints; a form the description cannot say left as written (P309), a program for
another controller refused (P310)."""
import numpy as np
import pytest

from postproc.robot import configuration, conventions
from postproc.compensation.api import compensate_text
from postproc.programs.io import parse_program_text
from postproc.model.compensator import load_model
from postproc.core.diagnostics import PostprocError
from postproc.core.resources import model_path
from postproc.robot.arm import Robot
from postproc.robot.description import load_description
from postproc.testing.models import joint_model

GAIN = np.array([[0.3, -0.2, 0.5, 0.1, 0.4, -0.3],
                 [0.1, 0.4, -0.2, 0.3, -0.5, 0.2],
                 [-0.4, 0.2, 0.3, -0.1, 0.2, 0.5]])  # mm per unit sin(q)


@pytest.fixture(scope="module")
def fanuc():
    return Robot(load_description(model_path("r2000ic.toml")))


@pytest.fixture(scope="module")
def abb():
    return Robot(load_description(model_path("irb6700.toml")))


def _drawn(robot, n=3000, seed=0):
    """Joint angles over the whole joint space (away from the wrist singularity A5 = 0, where
    only A4 + A6 is defined) and their TCP poses."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (n, 6))
    q[:, 4] = np.where(np.abs(q[:, 4]) < 1.0, 1.0, q[:, 4])
    return q, robot.fk(q)


def _read_back(robot, poses, stated):
    n = len(poses)
    return configuration.controller_joints(robot, poses, stated.status, stated.turn, np.ones(n, bool),
                                           independent=np.ones(n, bool), windows=stated.windows)


def _fanuc_stated(texts):
    n = len(texts)
    stated = configuration.Stated(np.full(n, -1), np.full(n, -1), np.full((n, 6, 2), np.nan))
    for i, text in enumerate(texts):
        stated.status[i], turns = conventions.parse_fanuc_config(text)
        for t, j in zip(turns, conventions.TURN_JOINTS):
            stated.windows[i, j] = (360.0 * t - 180.0, 360.0 * t + 180.0)
    return stated


def test_fanuc_config_both_ways_in_every_branch_and_turn(fanuc):
    q, poses = _drawn(fanuc)
    texts = conventions.fanuc_configs(fanuc, q)
    letters = {t.split(",")[0] for t in texts}
    assert letters == {f"{f} {u} {s}" for f in "NF" for u in "UD" for s in "TB"}  # all 8 branches
    turns = np.array([[int(v) for v in t.split(",")[1:]] for t in texts])
    for k in range(3):  # J1, J4, J6 each on turns -1, 0 and +1
        assert {-1, 0, 1} <= set(turns[:, k].tolist()), k
    back, ok = _read_back(fanuc, poses, _fanuc_stated(texts))
    assert ok.all()
    np.testing.assert_allclose(back, q, atol=1e-6)


def test_fanuc_letters_are_the_geometry(fanuc):
    # the tool-down pose of J4 = 0 is J5 = -90 on a FANUC: no flip, elbow up, in front
    down = np.array([[10.0, 20.0, -10.0, 0.0, -90.0, 30.0]])
    assert conventions.fanuc_configs(fanuc, down) == ["N U T, 0, 0, 0"]
    # the same pose with the wrist turned over (J4 + 180, J5 = +90, J6 + 180): flipped, J6 one turn on
    over = down + [0, 0, 0, 180.0, 180.0, 180.0]
    np.testing.assert_allclose(fanuc.fk(over), fanuc.fk(down), atol=1e-6)
    assert conventions.fanuc_configs(fanuc, over) == ["F U T, 0, 1, 1"]  # (J4 = 180: its next turn)
    # J1 and J4 past -180: turn -1; the arm leaning back over its base: B; the elbow folded under: D
    assert conventions.fanuc_configs(fanuc, [[-181.0, -50.0, 20.0, -190.0, -40.0, 0.0]]) == ["N U B, -1, -1, 0"]
    assert conventions.fanuc_configs(fanuc, [[0.0, -55.0, -120.0, 0.0, -60.0, 0.0]]) == ["N D T, 0, 0, 0"]
    assert conventions.fanuc_turn(np.array([179.9, 180.0, 539.9, -179.9, -180.0, -539.9, -540.0])).tolist() == [0, 1, 1, 0, -1, -1, -2]


@pytest.mark.parametrize("text, expected", [("N U T, 0, 0, 0", (6, [0, 0, 0])), ("F D B, -1, 1, 0", (1, [-1, 1, 0])),
                                            (" n u t ,0,0,0", (6, [0, 0, 0])), ("N U T", (6, [-999, -999, -999])),
                                            ("N, 0, 0, 0", None), ("N U T, 0, 0", None), ("X U T, 0, 0, 0", None)])
def test_parse_fanuc_config(text, expected):
    got = conventions.parse_fanuc_config(text)
    assert (got is None) if expected is None else (got[0] == expected[0] and got[1].tolist() == expected[1])


def test_abb_confdata_both_ways_in_every_branch_and_quadrant(abb):
    q, poses = _drawn(abb, seed=1)
    conf = conventions.abb_confdata(abb, q)
    assert set(conf[:, 3].tolist()) == set(range(8))  # every cfx
    for k in range(3):
        assert {-2, -1, 0, 1} <= set(conf[:, k].tolist())
    status, windows, good = conventions._abb_branch(conf)
    assert good.all()
    back, ok = _read_back(abb, poses, configuration.Stated(status, np.full(len(q), -1), windows))
    assert ok.all()
    np.testing.assert_allclose(back, q, atol=1e-6)
    # the calibration position with the tool down: [0, 0, 0, 0]; the wrist turned over: axis 5 negative
    assert conventions.abb_confdata(abb, [[0, 0, 0, 0, 90, 0], [0, 0, 0, 180, -90, 180]]).tolist() == \
        [[0, 0, 0, 0], [0, 2, 2, 1]]


# --------------------------------------------------------------------------- programs

def _ls(poses, configs, motion="J"):
    mn = [f"{k:4d}:{motion} P[{k}] 100% FINE    ;" for k in range(1, len(poses) + 1)]
    pos = []
    for k, (p, c) in enumerate(zip(poses, configs), start=1):
        pos.append(f"P[{k}]{{\n   GP1:\n\tUF : 0, UT : 1,\t\tCONFIG : '{c}',\n"
                   f"\tX = {p[0]:10.4f}  mm,\tY = {p[1]:10.4f}  mm,\tZ = {p[2]:10.4f}  mm,\n"
                   f"\tW = {p[5]:10.4f} deg,\tP = {p[4]:10.4f} deg,\tR = {p[3]:10.4f} deg\n}};")
    return "\n".join(["/PROG  CFG", "/ATTR", "/MN", *mn, "/POS", *pos, "/END", ""])


def _rapid(poses, conf, tool):
    from postproc.core import frames

    lines = ["MODULE cfg", f"PERS tooldata t1:=[TRUE,[[{tool[0]},{tool[1]},{tool[2]}],[1,0,0,0]],[1,[0,0,1],[1,0,0,0],0,0,0]];",
             "PROC main()"]
    for p, c in zip(poses, conf):
        q = ",".join(f"{v:.9f}" for v in frames.quaternion_from_rotation(frames.rotation_from_abc(p[3:])))
        lines.append(f"MoveJ [[{p[0]:.4f},{p[1]:.4f},{p[2]:.4f}],[{q}],[{c[0]},{c[1]},{c[2]},{c[3]}],"
                     "[9E9,9E9,9E9,9E9,9E9,9E9]],v100,fine,t1;")
    return "\n".join(lines + ["ENDPROC", "ENDMODULE", ""])


def _xyz(text, name, config=None):
    return parse_program_text(text, name, config_texts=config).targets.poses[:, :3]


@pytest.fixture(scope="module")
def workspace_q():
    """Joint angles of targets in front of each robot in both wrists and elbows, J1/J4/J6 on
    other turns too (each a different model input: a wrong branch or turn shows)."""
    return {"fanuc": np.array([[10.0, 20.0, -10.0, 0.0, -90.0, 30.0], [10.0, 20.0, -10.0, 180.0, 90.0, 210.0],
                               [-5.0, 10.0, 5.0, -20.0, -70.0, -200.0], [15.0, -20.0, -60.0, 330.0, -40.0, 10.0]]),
            "abb": np.array([[5.0, 20.0, 10.0, 0.0, 60.0, 10.0], [5.0, 20.0, 10.0, 180.0, -60.0, -170.0],
                             [-20.0, 30.0, -5.0, 100.0, 45.0, 250.0], [30.0, 10.0, 0.0, -200.0, 70.0, -20.0]])}


def test_an_ls_program_reaches_the_model_with_its_config_joints(tmp_path, fanuc, workspace_q):
    q = workspace_q["fanuc"]
    tool = fanuc.tool
    frames_file = tmp_path / "frames.toml"
    frames_file.write_text("[utool.1]\nxyzwpr = [%g, %g, %g, 0, 0, 0]\n" % tuple(tool[:3]))
    poses = fanuc.fk(q)
    text = _ls(poses, conventions.fanuc_configs(fanuc, q))
    model = load_model(joint_model(tmp_path / "j.onnx", GAIN, robot="R2000iC-sim",
                                   tool={"name": "UT 1", "frame": tool.tolist()}))
    out, report = compensate_text(text, model, name="t.ls", config=frames_file)
    assert report.compensated == len(q) and report.left == 0
    config = [frames_file.read_text()]
    correction = _xyz(out, "t.ls", config) - _xyz(text, "t.ls", config)
    np.testing.assert_allclose(correction, np.sin(np.radians(q)) @ GAIN.T, atol=1e-3)  # (4 decimals written)
    assert np.abs(correction[0] - correction[1]).max() > 0.1  # one pose, two wrists: two corrections


def test_a_rapid_module_reaches_the_model_with_its_confdata_joints(tmp_path, abb, workspace_q):
    q = workspace_q["abb"]
    poses = abb.fk(q)
    text = _rapid(poses, conventions.abb_confdata(abb, q), abb.tool)
    model = load_model(joint_model(tmp_path / "j.onnx", GAIN, robot="IRB6700-sim",
                                   tool={"name": "tSpindle", "frame": abb.tool.tolist()}))
    out, report = compensate_text(text, model, name="t.mod")
    assert report.compensated == len(q) and report.left == 0
    correction = _xyz(out, "t.mod") - _xyz(text, "t.mod")
    np.testing.assert_allclose(correction, np.sin(np.radians(q)) @ GAIN.T, atol=1e-3)


def test_a_form_the_description_cannot_say_is_left_as_written(tmp_path, fanuc, abb, workspace_q):
    q = workspace_q["fanuc"][:2]
    frames_file = tmp_path / "frames.toml"
    frames_file.write_text("[utool.1]\nxyzwpr = [0, 0, 300, 0, 0, 0]\n")
    text = _ls(fanuc.fk(q), ["N U T, 0, 0, 0", "N, 0, 0, 0"])  # (the second: not a six-axis arm's form)
    fanuc_model = load_model(joint_model(tmp_path / "f.onnx", GAIN, robot="R2000iC-sim",
                                         tool={"name": "UT 1", "frame": [0, 0, 300, 0, 0, 0]}))
    _, report = compensate_text(text, fanuc_model, name="t.ls", config=frames_file)
    assert report.left_codes == {"P309": 1} and report.compensated == 1
    assert "'N, 0, 0, 0' is not of the form" in [w for w in report.warnings if w.code == "P309"][0].message
    # an ABB's model: an LS program is another controller's (P310); forced, its CONFIG is not translated (P309)
    abb_model = load_model(joint_model(tmp_path / "a.onnx", GAIN, robot="IRB6700-sim",
                                       tool={"name": "UT 1", "frame": [0, 0, 300, 0, 0, 0]}))
    with pytest.raises(PostprocError, match="P310.*LS program, written for FANUC controllers.*IRB6700-sim, an arm of ABB's"):
        compensate_text(text, abb_model, name="t.ls", config=frames_file)
    _, report = compensate_text(text, abb_model, name="t.ls", config=frames_file, force=True)
    assert report.left_codes == {"P309": 2} and report.compensated == 0
    # a pose list is any robot's: no guard
    arm = Robot(abb.description.replace(tool=np.array([0, 0, 300.0, 0, 0, 0])))
    rows = "x,y,z,a,b,c\n" + "\n".join(",".join(f"{v:.4f}" for v in p) for p in arm.fk(workspace_q["abb"][:1])) + "\n"
    assert compensate_text(rows, abb_model, name="p.csv")[1].compensated == 1


def test_a_linear_motion_that_states_another_branch_is_left_as_written(tmp_path, abb, workspace_q):
    """MoveL keeps the arm's configuration: a MoveL whose confdata states another branch than
    the target before it is run so by no controller (ConfL\\On stops, ConfL\\Off keeps its own):
    left as written (P309), the others compensated; as MoveJ the same target is reached."""
    q = workspace_q["abb"][:2]  # one pose, two wrists
    poses = abb.fk(q)
    conf = conventions.abb_confdata(abb, q)
    model = load_model(joint_model(tmp_path / "j.onnx", GAIN, robot="IRB6700-sim",
                                   tool={"name": "tSpindle", "frame": abb.tool.tolist()}))
    text = _rapid(poses, conf, abb.tool)
    linear = text.replace("MoveJ", "MoveL", 2).replace("MoveL", "MoveJ", 1)  # (MoveJ, then MoveL to the other wrist)
    _, report = compensate_text(linear, model, name="t.mod")
    assert report.left_codes == {"P309": 1} and report.compensated == 1
    (warning,) = [w for w in report.warnings if w.code == "P309"]
    assert warning.line == 5 and "a linear motion cannot change the arm configuration" in warning.message
    _, report = compensate_text(text, model, name="t.mod")
    assert report.compensated == 2

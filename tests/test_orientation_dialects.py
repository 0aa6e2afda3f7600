"""--orientation in RAPID (quaternions) and URScript (rotation vectors).

The same targets as a pose list and as a RAPID module (in a turned and shifted work object,
quaternions in both hemispheres) or a URScript script (rotation vectors near 180°, on both
sides of π) get the same commands, position and orientation, with the shipped model of the
dialect's robot (``irb6700``, ``ur10``: its correction varies over space and orientation; a
model of one controller's robot refuses another's programs, P310, so the pose list and KRL
references are compensated with ``force``); the written numbers keep their hemisphere or branch
and at least six decimals; the round-trip guard reads the orientation back; a target whose
orientation is not located is still P312 at its line.
"""
import os

import numpy as np
import pytest

from postproc.core import frames
from postproc.compensation.api import compensate_text
from postproc.programs.io import parse_program_text
from postproc.model.compensator import load_model
from postproc.core.diagnostics import PostprocError
from postproc.programs.rewrite import ORIENTATION_DECIMALS, decimal_range

os.environ.setdefault("OMP_NUM_THREADS", "1")


@pytest.fixture(scope="module")
def model():
    return load_model(None)  # the shipped model: it has the output rotation_error


@pytest.fixture(scope="module")
def abb():
    return load_model("irb6700")  # the shipped IRB 6700 model (RAPID's robot), with rotation_error


@pytest.fixture(scope="module")
def ur():
    return load_model("ur10")  # the shipped UR10 model (URScript's robot), with rotation_error


def _decimals(token: str) -> int:
    return len(token.split(".")[1]) if "." in token else 0


def _pose_list_commands(model, poses: np.ndarray) -> np.ndarray:
    """The commands of ``poses`` (robot base, X,Y,Z,A,B,C) compensated as a pose list, read back."""
    frame = "" if model.in_controller_base else "# frame: controller\n"  # (the poses are the programs')
    text = frame + "x,y,z,a,b,c\n" + "".join(",".join(f"{v:.9f}" for v in p) + "\n" for p in poses)
    out, report = compensate_text(text, model, name="targets.csv", orientation=True)
    assert report.compensated == len(poses)
    return parse_program_text(out, "targets.csv").targets.poses


def _krl_lin_commands(model, poses: np.ndarray) -> np.ndarray:
    """The commands of ``poses`` (robot base) as KRL LIN motions with the model's tool: the
    controller's rules of a LIN program (each target keeps the arm configuration of the one
    before), which a URScript movel follows too, where a pose list's row takes the branch
    nearest HOME."""
    tool = ",".join(f"{k} {v}" for k, v in zip("XYZABC", model.metadata["tool"]["frame"]))
    show = lambda p: ",".join(f"{k} {v:.9f}" for k, v in zip("XYZABC", p))  # noqa: E731
    text = "\n".join(["DEF lin( )", "  $BASE = {X 0,Y 0,Z 0,A 0,B 0,C 0}", "  $TOOL = {" + tool + "}",
                      *("  LIN {" + show(p) + "}" for p in poses), "END", ""])
    out, report = compensate_text(text, model, name="lin.src", orientation=True, force=True)  # (a UR's model)
    assert report.compensated == len(poses)
    return parse_program_text(out, "lin.src").targets.poses


def _turn_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.linalg.norm(frames.rotation_error_deg(a, b), axis=-1)


def _confdata(model, targets: np.ndarray) -> list[str]:
    """The confdata of the joint angles each target (robot base) takes as a pose list's row
    (findings.select: the model's ``joints``): RAPID states them (conventions.abb_confdata)."""
    from postproc.robot import conventions
    from postproc.compensation.inputs import model_description
    from postproc.compensation.findings import select
    from postproc.robot.arm import Robot

    rows = "x,y,z,a,b,c\n" + "".join(",".join(f"{v:.9f}" for v in p) + "\n" for p in targets)
    q = select(parse_program_text(rows, "targets.csv"), model).joints
    assert q is not None and len(q) == len(targets)
    robot = Robot(model_description(model).replace(tool=np.asarray(model.metadata["tool"]["frame"], float)))
    return [",".join(str(v) for v in c) for c in conventions.abb_confdata(robot, q)]


def _rapid_module(model, local: np.ndarray, quaternions: list[str], uframe, oframe, conf: list[str]) -> str:
    tool = model.metadata["tool"]["frame"]  # (no rotation)
    quat = lambda f: ",".join(f"{v:.9f}" for v in frames.quaternion_from_rotation(frames.rotation_from_abc(f[3:])))  # noqa: E731
    xyz = [",".join(f"{v:.6f}" for v in p[:3]) for p in local]
    lines = ["MODULE turned",
             f"  PERS tooldata tSpindle:=[TRUE,[[{tool[0]},{tool[1]},{tool[2]}],[1,0,0,0]],[5,[0,0,100],[1,0,0,0],0,0,0]];",
             f'  TASK PERS wobjdata wTurned:=[FALSE,TRUE,"",[[{uframe[0]},{uframe[1]},{uframe[2]}],[{quat(uframe)}]],'
             f"[[{oframe[0]},{oframe[1]},{oframe[2]}],[{quat(oframe)}]]];"]
    storage = ("CONST", "PERS", "VAR")
    n = len(local)
    named = range(0, n, 2)  # every other target a declared robtarget, the others inline
    for k in named:
        lines.append(f"  {storage[k % 3]} robtarget p{k}:=[[{xyz[k]}],[{quaternions[k]}],[{conf[k]}],"
                     "[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];")
    lines.append("  PROC main()")
    for k in range(n):
        target = f"p{k}" if k in named else f"[[{xyz[k]}],[{quaternions[k]}],[{conf[k]}],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]]"
        lines.append(f"    MoveL {target}, v100, z1, tSpindle\\WObj:=wTurned;")
    return "\n".join(lines + ["  ENDPROC", "ENDMODULE", ""])


@pytest.mark.parametrize("seed", [13, 14, 21])
def test_rapid_quaternions_match_the_pose_list_in_a_turned_work_object(abb, seed):
    """Inline and declared (CONST/PERS/VAR) robtargets in a work object whose user and object
    frames are both shifted and turned; quaternions written with 9, 7 and 4 decimals and half
    of them as −q: the commands equal the pose list's, each quaternion is written normalised,
    in the hemisphere of the one it replaces, with as many decimals as it had (at least 6).
    (Seeds 13 and 21 have targets where a wrist joint's side is a near tie in position: the
    lost motion turns the tool about the TCP on the A6 axis and moves it by nothing. The
    settling took whichever side the ~1e-4 mm of the quaternions' conversions favoured, the
    attitude 0.018° off; it now asks the attitude to land too, settle.SETTLE_TOLERANCE_DEG.)"""
    model = abb
    rng = np.random.default_rng(seed)
    n = 18
    targets = np.c_[rng.uniform([1600, -400, 400], [2100, 400, 900], (n, 3)),
                    np.array([180.0, 0.0, 180.0]) + rng.uniform(-10, 10, (n, 3))]
    uframe, oframe = np.array([100.0, -50.0, 20.0, 30.0, 10.0, -5.0]), np.array([10.0, 20.0, 30.0, 0.0, 0.0, 15.0])
    wobj = frames.frame_to_matrix(uframe) @ frames.frame_to_matrix(oframe)
    local = frames.inverse(wobj) @ frames.frame_to_matrix(targets)
    q = frames.quaternion_from_rotation(local[:, :3, :3])
    q[1::2] *= -1  # q and −q: one rotation
    places = {9, 7, 4}
    quaternions = []
    for k, row in enumerate(q):
        d = (9, 7, 4)[k % 3]
        # (one written with blanks after its signs, as RAPID allows)
        quaternions.append(",".join(f"{v:.{d}f}".replace("-", "- ") if k == 5 else f"{v:.{d}f}" for v in row))
    text = _rapid_module(model, frames.matrix_to_frame(local), quaternions, uframe, oframe, _confdata(model, targets))
    written = parse_program_text(text, "turned.mod").targets
    before = frames.matrix_to_frame(wobj @ frames.frame_to_matrix(written.poses))  # as read, in the robot base
    expected = _pose_list_commands(model, before)

    out, report = compensate_text(text, model, name="turned.mod", orientation=True)
    assert report.compensated == n and report.left == 0
    again = parse_program_text(out, "turned.mod").targets
    commands = frames.matrix_to_frame(wobj @ frames.frame_to_matrix(again.poses))
    assert np.abs(commands[:, :3] - expected[:, :3]).max() < 1e-3  # mm
    # the pose list's 6-decimal A,B,C and the quaternions' own rounding (4 decimals in → 6 out: ≤ 1.2e-4°)
    assert _turn_deg(expected[:, 3:], commands[:, 3:]).max() < 2e-4
    assert _turn_deg(before[:, 3:], commands[:, 3:]).mean() > 0.1  # (the orientation was corrected)
    new_q = again.orientation
    assert np.abs(np.linalg.norm(new_q, axis=1) - 1.0).max() < 3e-6
    assert (np.sum(new_q * written.orientation, axis=1) > 0.99).all()  # each in its own hemisphere
    assert {1.0, -1.0} <= set(np.sign(written.orientation[:, 0]).tolist())  # (both were written)
    fewest = decimal_range(ORIENTATION_DECIMALS["quaternion"])[0]
    for k in range(n):
        tokens = [out[a:b] for a, b in again.abc_spans[k]]
        assert all(_decimals(t) == max(fewest, _decimals(text[a:b])) for t, (a, b) in zip(tokens, written.abc_spans[k]))
    assert {_decimals(text[a:b]) for a, b in written.abc_spans.reshape(-1, 2)} == set(places)
    # without --orientation the quaternions stay as written, byte for byte
    plain, _ = compensate_text(text, model, name="turned.mod")
    kept = parse_program_text(plain, "turned.mod").targets
    assert [plain[a:b] for a, b in kept.abc_spans.reshape(-1, 2)] == [text[a:b] for a, b in written.abc_spans.reshape(-1, 2)]


def _script(model, poses_m: list[str]) -> str:
    tool = np.asarray(model.metadata["tool"]["frame"]) / 1000.0
    lines = ["def cell():", f"  set_tcp(p[{tool[0]}, {tool[1]}, {tool[2]}, 0.0, 0.0, 0.0])"]
    for k, pose in enumerate(poses_m):
        if k % 3 == 0:  # a pose variable (the round-trip guard reads the script again)
            lines += [f"  global wp{k} = p[{pose}]", f"  movel(wp{k}, a=1.2, v=0.25)"]
        else:
            lines.append(f"  movel(p[{pose}], a=1.2, v=0.25)")
    return "\n".join(lines + ["end", ""])


def test_urscript_rotation_vectors_match_the_pose_list_near_180_degrees(ur):
    """Rotation vectors of ordinary attitudes and of attitudes within 0.01° of a half turn, on
    both sides of π (|v| = π − 1e-4 and 3.1416, as Polyscope writes a tool pointing down): the
    commands equal the pose list's (ordinary attitudes) and the KRL LIN program's (all: the
    configuration rule movel follows), and each new vector is the one nearest the written one —
    no jump to the opposite side where the correction crosses π."""
    model = ur
    rng = np.random.default_rng(5)
    # (URScript's base: the UR10 model's workspace, the tool down turned -45° ± 46° about the vertical)
    ordinary = np.c_[rng.uniform([-200, -550, 150], [400, -380, 400], (8, 3)),
                     np.array([-45.0, 0.0, 180.0]) + rng.uniform(-10, 10, (8, 3))]
    spins = np.radians([140.0, 150.0, 160.0, 170.0, 175.0, 320.0, 330.0, 340.0, 350.0, 355.0])
    axes = np.c_[np.cos(spins), np.sin(spins), np.zeros(len(spins))]  # (a tool pointing down)
    halves = axes * np.where(np.arange(len(spins)) % 2 == 0, np.pi - 1e-4, 3.1416)[:, None]
    down = np.c_[rng.uniform([-100, -500, 200], [300, -400, 350], (len(spins), 3)),
                 frames.abc_from_rotation(frames.rotation_from_rotvec(halves))]
    vectors = np.r_[frames.rotvec_from_rotation(frames.rotation_from_abc(ordinary[:, 3:])), halves]
    positions = np.r_[ordinary, down][:, :3] / 1000.0
    poses_m = [", ".join([f"{v:.6f}" for v in p] + [f"{v:.5f}" if k >= 8 and k % 2 else f"{v:.9f}" for v in r])
               for k, (p, r) in enumerate(zip(positions, vectors))]
    text = _script(model, poses_m)
    written = parse_program_text(text, "cell.script").targets
    rows = np.arange(8)  # the ordinary attitudes: as a pose list, each row on the branch nearest HOME
    listed = _pose_list_commands(model, written.poses[rows])
    # all, as movel moves: in the arm configuration of the target before (KRL LIN, the same rule)
    expected = _krl_lin_commands(model, written.poses)

    out, report = compensate_text(text, model, name="cell.script", orientation=True)
    assert report.compensated == len(vectors) and report.left == 0
    again = parse_program_text(out, "cell.script").targets
    for reference, got in ((listed, again.poses[rows]), (expected, again.poses)):
        assert np.abs(got[:, :3] - reference[:, :3]).max() < 1e-3  # mm (µm written)
        assert _turn_deg(reference[:, 3:], got[:, 3:]).max() < 1e-4  # deg (≤ 5e-5° each side)
    assert _turn_deg(written.poses[:, 3:], again.poses[:, 3:]).mean() > 0.03  # (the UR10 model's: ~0.06°)
    old, new = written.orientation, again.orientation
    assert np.linalg.norm(new - old, axis=1).max() < 0.02  # rad: continuous with the written vectors
    assert (np.linalg.norm(new[rows], axis=1) <= np.pi).all()
    side = np.sign(np.linalg.norm(old[8:], axis=1) - np.pi) != np.sign(np.linalg.norm(new[8:], axis=1) - np.pi)
    assert side.any()  # (some corrections cross θ = π: the vector stays on its side of the axis)
    fewest = decimal_range(ORIENTATION_DECIMALS["rotvec"])[0]
    for k in range(len(vectors)):
        tokens = [out[a:b] for a, b in again.abc_spans[k]]
        assert all(_decimals(t) == max(fewest, _decimals(text[a:b])) for t, (a, b) in zip(tokens, written.abc_spans[k]))


@pytest.mark.parametrize("form", ["quaternion", "rotvec", "abc"])
def test_orientation_numbers_are_the_rotation_nearest_the_written_ones(form):
    """frames.orientation_numbers: the new rotation exactly, in the written numbers' hemisphere
    (quaternion), branch (rotation vector) or triple and turns (A,B,C)."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(2)
    base = Rotation.random(500, random_state=3)
    nudge = Rotation.from_rotvec(rng.normal(0, 0.005, (500, 3)))  # ≈ 0.5°: a correction
    new = (nudge * base).as_matrix()
    if form == "quaternion":
        written = base.as_quat()[:, [3, 0, 1, 2]] * rng.choice([-1.0, 1.0], (500, 1))
    elif form == "rotvec":
        written = base.as_rotvec()
    else:
        written = frames.abc_from_rotation(base.as_matrix()) + rng.choice([0.0, 360.0], (500, 3))
    numbers = frames.orientation_numbers(frames.abc_from_rotation(new), written, form)
    assert np.abs(frames.orientation_rotation(numbers, form) - new).max() < 1e-12
    # none jumped to another representation (A and C apart: near |B| = 90° they are ill-conditioned)
    steady = np.abs(np.cos(np.radians(written[:, 1]))) > 0.5 if form == "abc" else slice(None)
    assert np.abs(numbers - written)[steady].max() < (2.0 if form == "abc" else 0.05)


def test_rotation_vectors_cross_pi_continuously():
    u = np.array([[0.6, 0.8, 0.0]])
    written = (np.pi - 1e-3) * u
    beyond = frames.abc_from_rotation(frames.rotation_from_rotvec((np.pi + 2e-3) * u))  # = (π − 2e-3)·(−u)
    np.testing.assert_allclose(frames.orientation_numbers(beyond, written, "rotvec"), (np.pi + 2e-3) * u, atol=1e-12)
    # away from π: the principal vector, |θ| ≤ π, whichever side it was written on before
    near = frames.abc_from_rotation(frames.rotation_from_rotvec(0.5 * u))
    np.testing.assert_allclose(frames.orientation_numbers(near, 0.49 * u, "rotvec"), 0.5 * u, atol=1e-12)
    # the rotations of half a turn and of none, exactly
    for angle in (np.pi, 0.0, 1e-9):
        r = frames.rotation_from_rotvec(angle * u)
        np.testing.assert_allclose(frames.rotvec_from_rotation(r), angle * u, atol=1e-12)
        np.testing.assert_allclose(frames.rotation_from_quaternion(frames.quaternion_from_rotation(r)), r, atol=1e-12)


@pytest.mark.parametrize("form,bound_deg", [("quaternion", 1.2e-4), ("rotvec", 5e-5)])
def test_the_fewest_decimals_leave_less_than_the_stated_rotation(form, bound_deg):
    """The rotation the rounding to the form's fewest decimals leaves (README, rewrite.py):
    ≤ 1.2e-4° for a quaternion, ≤ 5e-5° for a rotation vector."""
    from scipy.spatial.transform import Rotation

    r = Rotation.random(20000, random_state=4).as_matrix()
    numbers = frames.orientation_numbers(frames.abc_from_rotation(r), np.ones((len(r), 4 if form == "quaternion" else 3)),
                                         form)
    fewest = decimal_range(ORIENTATION_DECIMALS[form])[0]
    rounded = frames.orientation_rotation(np.round(numbers, fewest), form)
    left = np.degrees(np.linalg.norm(frames.rotvec_from_rotation(rounded @ np.swapaxes(r, -1, -2)), axis=-1))
    assert 0.2 * bound_deg < left.max() <= bound_deg


def test_the_round_trip_guard_reads_the_orientation_back(abb, ur):
    """guards.check_round_trip compares the orientation's numbers read again with those meant
    (RAPID's q1..q4, URScript's rx,ry,rz): one number off by more than its rounding is P191."""
    from postproc.compensation.guards import check_round_trip

    mod = ("MODULE m\n  PERS tooldata t1:=[TRUE,[[0,0,180.5],[1,0,0,0]],[5,[0,0,100],[1,0,0,0],0,0,0]];\n"
           "  CONST robtarget p1:=[[1900,0,700],[0.0087265,0,0.9999619,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];\n"
           "  PROC main()\n    MoveL p1, v100, fine, t1;\n  ENDPROC\nENDMODULE\n")
    script = ("def s():\n  set_tcp(p[0.0, 0.0, 0.15, 0.0, 0.0, 0.0])\n  global wp = p[0.1, -0.45, 0.25, 0.0, 3.1416, 0.0]\n"
              "  movel(wp, a=1.2, v=0.25)\nend\n")
    for name, text, column, model in (("m.mod", mod, "q3", abb), ("s.script", script, "ry", ur)):
        program = parse_program_text(text, name)
        out, report = compensate_text(text, model, name=name, orientation=True)
        assert report.compensated == 1
        again = parse_program_text(out, name).targets
        meant = np.c_[again.poses[:, :3], again.orientation]
        rows = np.array([0])
        check_round_trip(program, [out.split("\n", 1)[1]], rows, meant)  # (without the stamp line)
        k = 3 + {"q3": 2, "ry": 1}[column]
        off = meant.copy()
        off[0, k] += 1e-5  # 20× the rounding of a 6-decimal number
        with pytest.raises(PostprocError) as refused:
            check_round_trip(program, [out.split("\n", 1)[1]], rows, off)
        assert refused.value.code == "P191" and f"reads {column} " in refused.value.message


def test_a_target_without_its_orientation_is_still_p312_at_its_line(model):
    """--orientation where a target does not write its orientation (a KRL partial aggregate,
    a pose list row without A,B,C) is refused at that target's path:line:col."""
    tool = ",".join(f"{k} {v}" for k, v in zip("XYZABC", model.metadata["tool"]["frame"]))
    src = "\n".join(["DEF part( )", "  $BASE = {X 0,Y 0,Z 0,A 0,B 0,C 0}", "  $TOOL = {" + tool + "}",
                     "  LIN {X 2000,Y 0,Z 900,A 0,B 90,C 0}", "  LIN {X 2010,Y 5,Z 905}", "END", ""])
    with pytest.raises(PostprocError) as refused:
        compensate_text(src, model, name="part.src", orientation=True)
    assert str(refused.value).startswith("part.src:5:7: P312")
    out, report = compensate_text(src, model, name="part.src")  # (without --orientation: compensated)
    assert report.compensated == 2


def test_a_quaternion_written_wrong_is_refused_before_writing(abb, monkeypatch):
    """A formatter that writes a quaternion number 2e-6 off (4× its rounding): P190 at the
    target, nothing returned — the orientation's new tokens are checked like X/Y/Z."""
    import postproc.compensation.commands

    real = postproc.compensation.commands.format_many

    def off(tokens, values, unit=1.0):  # (RAPID: only the quaternion is written like metres)
        return real(tokens, values + (0.002 if unit == 1000.0 else 0.0), unit)

    monkeypatch.setattr(postproc.compensation.commands, "format_many", off)
    model = abb
    mod = ("MODULE m\n  PERS tooldata t1:=[TRUE,[[0,0,180.5],[1,0,0,0]],[5,[0,0,100],[1,0,0,0],0,0,0]];\n  PROC main()\n"
           "    MoveL [[1900,0,700],[0.0087265,0,0.9999619,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]], v100, "
           "fine, t1;\n  ENDPROC\nENDMODULE\n")
    with pytest.raises(PostprocError) as refused:
        compensate_text(mod, model, name="m.mod", orientation=True)
    assert str(refused.value).startswith("m.mod:4:13: P190 refusing to write: the number '0.010466")
    out, report = compensate_text(mod, model, name="m.mod")  # (X/Y/Z alone: written)
    assert report.compensated == 1

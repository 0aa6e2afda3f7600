"""URScript on the motion IR (issue 24): each construct the issue and the URScript manual name,
on a few lines of script, as the controller runs it — the rows (one per executed motion, in
execution order, with their predecessors), the located warnings of what is left as written, and
the commands a model whose correction varies over space gives."""
from __future__ import annotations

import numpy as np
import pytest

from postproc.core import frames
from postproc.cli import main
from postproc.compensation.api import compensate_text
from postproc.programs.io import parse_program_text
from postproc.model.compensator import load_model
from postproc.programs import MOTIONS, ActiveFrames

MODEL_TCP = ActiveFrames(tool="model")
GAIN = np.array([[2e-3, 0, 0], [0, -1e-3, 5e-4], [0, 0, 3e-3]])
OFFSET = np.array([0.3, -0.2, 0.1])
CENTRE = np.array([300.0, 0.0, 200.0])


def script(*lines):
    return "\n".join(["def prog():", *[f"  {line}" for line in lines], "end", ""])


def read(text, active=MODEL_TCP):
    return parse_program_text(text, "u.script", active=active)


def found(p):
    return [(d.code, d.line) for d in p.diagnostics]


def pose(x, y=0.2, z=0.3):
    return f"p[{x}, {y}, {z}, 0, 3.1416, 0]"


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    from postproc.testing.models import affine_model

    path = affine_model(tmp_path_factory.mktemp("urir") / "affine.onnx", offset=OFFSET, gain=GAIN, centre=CENTRE,
                        reach=None, tool={"name": "any"})
    return load_model(path)


def error(xyz):
    return OFFSET + GAIN @ (np.asarray(xyz, float) - CENTRE)


def test_targets_declared_at_the_top_are_chained_in_the_order_the_motions_run():
    """The issue's case: pose variables declared in one order, moved to in another: each target's
    predecessor is the motion before it as the program runs, so a model with a previous_pose input
    (the shipped one) gives the commands of the same poses as a pose list in that order, and not
    those of the declarations' order."""
    rng = np.random.default_rng(3)
    n = 10
    pos = np.c_[rng.uniform(1850, 2150, n), rng.uniform(-300, 300, n), rng.uniform(700, 1100, n)] / 1000
    order = rng.permutation(n)
    lines = [f"global wp{k} = p[{x:.6f}, {y:.6f}, {z:.6f}, 0, 1.5707963267948966, 0]" for k, (x, y, z) in
             enumerate(pos)] + [f"movel(wp{k}, a=1.2, v=0.25)" for k in order]
    text = script(*lines)
    p = read(text)
    assert p.targets.line.tolist() == (order + 2).tolist() and p.targets.prev.tolist() == list(range(-1, n - 1))
    model = load_model()  # (a KR 500's model: the order is what is tested here, not the robot — force)
    assert model.wants_previous
    out, report = compensate_text(text, model, name="u.script", active=MODEL_TCP, force=True)
    assert report.compensated == n and report.left == 0
    after = read(out).targets.poses[:, :3]

    def listed(rows):
        csv = "x,y,z,a,b,c\n" + "".join(f"{x * 1000:.3f},{y * 1000:.3f},{z * 1000:.3f},0,90,0\n" for x, y, z in rows)
        done, _ = compensate_text(csv, model, name="l.csv", force=True)
        return parse_program_text(done, "l.csv").targets.poses[:, :3]

    assert np.abs(after - listed(pos[order])).max() < 1e-3  # mm: µm written
    # (chained in the declarations' order, as the reader did before: each target's command differs)
    assert np.abs(after - listed(pos)[order]).max() > 0.05


def test_movej_get_inverse_kin_of_an_inline_pose_is_a_cartesian_target(model):
    text = script("set_tcp(p[0, 0, 0.1, 0, 0, 0])", f"movej(get_inverse_kin({pose(0.4)}), a=1.4, v=1.05)",
                  f"movej(get_inverse_kin({pose(0.5)}, tcp=p[0, 0, 0.2, 0, 0, 0]))",
                  f"movej(get_inverse_kin({pose(0.6)}, qnear=[0, -1.57, 1.57, 0, 0, 0]))")
    p = read(text)
    t = p.targets
    assert t.line.tolist() == [3, 4, 5] and [MOTIONS[m] for m in t.motion] == ["PTP"] * 3 and found(p) == []
    assert [tuple(p.frames[f].tool) for f in t.frame] == [(0, 0, 100, 0, 0, 0), (0, 0, 200, 0, 0, 0),
                                                          (0, 0, 100, 0, 0, 0)]
    # qnear chooses the branch: a configuration postproc does not map to joint angles
    assert p.unmapped_configuration.tolist() == [False, False, True]
    out, report = compensate_text(text, model, name="u.script", active=MODEL_TCP, iterations=1,
                                  max_correction_mm=50)
    assert report.compensated == 3
    nominal = np.array([[400, 200, 300], [500, 200, 300], [600, 200, 300]], float)
    assert np.allclose(read(out).targets.poses[:, :3], nominal + [error(x) for x in nominal], atol=6e-4)


def test_qnear_is_left_for_a_model_that_takes_joint_angles(tmp_path):
    from postproc.testing.models import joint_model

    model = load_model(joint_model(tmp_path / "j.onnx", np.diag([0.5, 0.4, 0.3]) @ np.eye(3, 6), robot="UR10",
                                   tool={"name": "any"}))
    text = script("movej(get_inverse_kin(p[0.1, -0.45, 0.3, 0, 3.1416, 0]))",
                  "movej(get_inverse_kin(p[0.1, -0.5, 0.3, 0, 3.1416, 0], qnear=[0, -1.57, 1.57, 0, 0, 0]))")
    out, report = compensate_text(text, model, name="u.script", active=MODEL_TCP)
    assert report.left_codes == {"P309": 1} and report.compensated == 1
    assert "get_inverse_kin(p[0.1, -0.5, 0.3, 0, 3.1416, 0], qnear" in out  # as written
    assert "get_inverse_kin(p[0.1, -0.45, 0.3, 0, 3.1416, 0]))" not in out  # compensated


def test_default_and_keyword_arguments_bind_the_parameters():
    text = script("def go(target, speed=0.25, lift=0.05):", "  movel(pose_trans(target, p[0, 0, -lift, 0, 0, 0]))",
                  "  movel(target, v=speed)", "end", f"go({pose(0.1)})", f"go(lift=0.1, target={pose(0.2)})")
    p = read(text)
    t = p.targets
    # each call's target (its literal); the pose_trans(target, p[0, 0, -lift, …]) at line 3: its z is computed
    # from lift (left), and it reads target as its frame: the two literals are left too (P217)
    assert t.line.tolist() == [6, 7] and found(p) == [("P214", 3), ("P217", 6), ("P217", 7)]
    p = read(script("def go(target, speed=0.25):", "  movel(target, v=speed)", "end", f"go({pose(0.1)})",
                    f"go(speed=0.1, target={pose(0.2)})", "go()"))
    assert p.targets.line.tolist() == [5, 6] and found(p) == [("P211", 3)]
    assert "parameter target of go() is not passed" in p.diagnostics[0].message


def test_a_thread_may_change_what_it_assigns_while_it_runs():
    p = read(script(f"global wp = {pose(0.1)}", "thread worker():", f"  wp = {pose(0.2)}", "  sync()", "end",
                    "movel(wp)", "thrd = run worker()", "movel(wp)", "kill thrd", "movel(wp)", f"wp = {pose(0.3)}",
                    "movel(wp)"))
    # before run: known; while it runs and after kill (it may have set it): left, located; set again: known
    assert p.targets.line.tolist() == [2, 12] and found(p) == [("P223", 9), ("P223", 11)]
    assert "thread declared at line 8" in p.diagnostics[0].message
    p = read(script("set_tcp(p[0, 0, 0.1, 0, 0, 0])", "thread worker():", "  set_tcp(p[0, 0, 0.2, 0, 0, 0])", "end",
                    f"movel({pose(0.1)})", "thrd = run worker()", f"movel({pose(0.2)})", "join thrd",
                    f"movel({pose(0.3)})", "set_tcp(p[0, 0, 0.1, 0, 0, 0])", f"movel({pose(0.4)})"))
    assert p.targets.frame.tolist() == [0, -1, -1, 0] and found(p) == [("P203", 7)]
    assert "2 target(s) left as written" in p.diagnostics[0].message


def test_halt_ends_the_program_and_dead_code_is_no_target():
    p = read(script(f"movel({pose(0.1)})", "halt", f"movel({pose(0.2)})"))
    assert p.targets.line.tolist() == [2] and found(p) == []
    p = read(script("if read_input_boolean_register(0):", "  halt", "end", f"movel({pose(0.2)})", "return",
                    f"movel({pose(0.3)})"))
    assert p.targets.line.tolist() == [5]


def test_branches_join_and_loops_repeat():
    p = read(script("if read_input_boolean_register(0):", f"  wp = {pose(0.1)}", "elif get_standard_digital_in(1):",
                    f"  wp = {pose(0.2)}", "else:", f"  wp = {pose(0.3)}", "end", "movel(wp)"))
    assert len(p.targets) == 0 and found(p) == [("P212", 9)]
    assert "the branches of the IF at line" in p.diagnostics[0].message
    p = read(script("if read_input_boolean_register(0):", f"  wp = {pose(0.1)}", "else:", f"  wp = {pose(0.1)}", "end",
                    "movel(wp)"))  # one value, from either token: known, no one token to rewrite
    assert len(p.targets) == 0 and found(p) == [("P214", 7)]
    p = read(script("i = 0", "while i < 3:", "  i = i + 1", "  if i == 2:", "    continue", "  end",
                    f"  movel({pose(0.1)})", "  if read_input_boolean_register(0):", "    break", "  end", "end",
                    f"movel({pose(0.2)})"))
    t = p.targets
    # the loop's target after the start and after itself (the next pass); the one after the loop after it or,
    # a pass that skips the motion (the continue: i is not known at the head), from the start
    assert t.line.tolist() == [8, 8, 13, 13] and t.prev.tolist() == [-1, 0, 0, -1] and t.twin.tolist() == [-1, 0, -1, 2]
    # a WHILE whose condition holds where it is entered runs at least once: never left from its entry
    t = read(script("i = 0", "while i < 3:", "  i = i + 1", f"  movel({pose(0.1)})", "end", f"movel({pose(0.2)})")).targets
    assert t.line.tolist() == [5, 5, 7] and t.prev.tolist() == [-1, 0, 0]


def test_values_known_only_at_run_time_are_left_located():
    p = read(script("movel(get_actual_tcp_pose())", "movel(get_target_tcp_pose())", "x = socket_read_ascii_float(6)",
                    f"movel(p[0.1, 0.2, x[1], 0, 3.1416, 0])", "movel(pose_add(get_actual_tcp_pose(), p[0, 0, 0.1, 0, 0, 0]))",
                    f"movel(pose_add({pose(0.1)}, p[0, 0, 0.1, 0, 0, 0]))", "rq_open()", f"movel({pose(0.5)})"))
    assert len(p.targets) == 1 and p.targets.frame.tolist() == [-1]
    # (P201 at its cause: the call of code not read)
    assert found(p) == [("P211", 2), ("P211", 3), ("P212", 5), ("P211", 6), ("P214", 7), ("P201", 8), ("P232", 8)]
    assert "get_actual_tcp_pose() gives a value known only at run time" in p.diagnostics[0].message
    assert "rq_open() called at line 8 is not in the files read" in p.diagnostics[-2].message
    assert p.diagnostics[-1].message.startswith("rq_open() is in none of the files read")


def test_a_pose_other_statements_read_too_is_p217():
    p = read(script(f"wp = {pose(0.1)}", "textmsg(wp)", "movel(wp)", "tcp = p[0, 0, 0.1, 0, 0, 0]", "set_tcp(tcp)",
                    "movel(tcp)", f"up = {pose(0.2)}", "if up[2] > 0:", "  sleep(1)", "end", "movel(up)"))
    assert p.targets.line.tolist() == [2, 5, 8]
    assert found(p) == [("P217", 2), ("P217", 5)]  # (up[2]: a pose is no list, its z is not read: see below)
    assert "passed to textmsg()" in p.diagnostics[0].message and "a frame" in p.diagnostics[1].message
    # a copy is the same numbers: both runs are one group, rewritten where they agree
    p = read(script(f"wp = {pose(0.1)}", "copy = wp", "movel(wp)", "movel(copy)"))
    assert p.targets.line.tolist() == [2, 2] and p.targets.group.tolist() == [0, 0] and found(p) == []


def test_pose_trans_moves_to_the_pose_in_the_frame(model):
    feature = "p[0.05, -0.1, 0.02, 0, 0, 0.5]"
    text = script("set_tcp(p[0, 0, 0.1, 0, 0, 0])", f"plane = {feature}", f"movel(pose_trans(plane, {pose(0.3)}))",
                  f"movel(pose_trans(plane, pose_trans(pose_inv({feature}), {pose(0.4)})))")
    p = read(text)
    t = p.targets
    f = frames.frame_to_matrix([50, -100, 20, np.degrees(0.5), 0, 0])
    assert t.line.tolist() == [4, 5] and found(p) == []
    assert np.allclose(p.frames[t.frame[0]].base, f) and np.allclose(p.frames[t.frame[1]].base, np.eye(4))
    out, report = compensate_text(text, model, name="u.script", active=MODEL_TCP, iterations=1,
                                  max_correction_mm=50)
    assert report.compensated == 2
    again = read(out).targets.poses[:, :3]
    in_base = frames.transform_points(f, np.array([[300, 200, 300]], float))[0]
    assert np.allclose(frames.transform_points(f, again[:1])[0], in_base + error(in_base), atol=6e-4)
    assert np.allclose(again[1], [400, 200, 300] + error([400, 200, 300]), atol=6e-4)


def test_scopes_of_the_program_and_its_functions():
    # a function's free variable is the program's global; `local` makes its own; `global` in a function sets one
    p = read(script(f"wp = {pose(0.1)}", "def lift():", "  wp = pose_add(wp, p[0, 0, 0.05, 0, 0, 0])", "end",
                    "def mine():", f"  local wp = {pose(0.5)}", "  movel(wp)", "end", "def put():",
                    f"  global other = {pose(0.6)}", "end", "mine()", "movel(wp)", "put()", "movel(other)", "lift()",
                    "movel(wp)"))
    # (wp's numbers are read by lift()'s pose_add too: the row of line 2 is left, P217; after lift() wp is computed)
    assert p.targets.line.tolist() == [7, 2, 11] and found(p) == [("P217", 2), ("P214", 18)]


def test_what_moves_the_path_leaves_its_targets(model):
    p = read(script(f"movel({pose(0.1)})", "track_conveyor_linear(p[1, 0, 0, 0, 0, 0], 1000)", f"movel({pose(0.2)})",
                    "stop_conveyor_tracking()", f"movel({pose(0.3)})", "speedl([0, 0, 0.1, 0, 0, 0], 0.5, 1)",
                    f"movel({pose(0.4)})"))
    assert p.targets.frame.tolist() == [0, -1, 0, 0] and found(p) == [("P201", 3)]
    assert "conveyor tracking" in p.diagnostics[0].message
    assert p.targets.prev.tolist() == [-1, 0, 1, -1]  # (after speedl the robot is somewhere not known)


def test_syntax_gaps_of_the_issue_parse():
    p = read(script("def f(a=1, b=p[0, 0, 0.1, 0, 0, 0]):", "  return a", "end", "thread t():", "  sync()", "end",
                    "h = run t()", "run t()", "kill h", "x = f()", f"movel({pose(0.1)})"))
    assert p.targets.line.tolist() == [12] and found(p) == []


def test_compensate_exits_1_and_names_the_target_left(tmp_path, model, capsys):
    good = tmp_path / "good.script"
    good.write_text(script("set_tcp(p[0, 0, 0.1, 0, 0, 0])", f"global wp = {pose(0.3)}", "movel(wp)", f"movel({pose(0.4)})"))
    assert main(["compensate", str(good), "-o", str(tmp_path / "g.script"), "--model", str(model.path)]) == 0
    bad = tmp_path / "bad.script"
    bad.write_text(script("set_tcp(p[0, 0, 0.1, 0, 0, 0])", f"movel({pose(0.3)})",
                          "movel(pose_add(get_actual_tcp_pose(), p[0, 0, 0.1, 0, 0, 0]))"))
    capsys.readouterr()
    assert main(["compensate", str(bad), "-o", str(tmp_path / "b.script"), "--model", str(model.path)]) == 1
    assert f"{bad}:4:9: P211" in capsys.readouterr().err

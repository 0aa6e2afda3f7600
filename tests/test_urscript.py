"""URScript reader (postproc/programs/urscript.py): each construct on a small script, bad
input located at path:line:col, and the round trip through compensate (zero, constant and
affine models) on generated scripts, in metres and rotation vectors."""
from __future__ import annotations

import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from postproc.core import frames
from postproc.compensation.api import compensate_text
from postproc.programs.io import parse_program_text
from postproc.model.compensator import load_model
from postproc.core.diagnostics import PostprocError
from postproc.programs import MOTIONS, ActiveFrames
from postproc.programs.io import dialect_of
from postproc.core.resources import sample_path
from postproc.programs.rewrite import format_many

OFFSET = np.array([0.3, -0.2, 0.1])
GAIN = np.array([[2e-3, 0, 0], [0, -1e-3, 5e-4], [0, 0, 3e-3]])
CENTRE = np.array([300.0, 0.0, 200.0])  # a UR10's working space (mm)


def script(*lines):
    return "\n".join(["def prog():", *[f"  {line}" for line in lines], "end", ""])


# the scripts below mostly set no TCP: the installation's, stated as the model's own (else P221)
MODEL_TCP = ActiveFrames(tool="model")


def read(text, active=MODEL_TCP):
    return parse_program_text(text, "u.script", active=active)


def codes(program):
    return [d.code for d in program.diagnostics]


def test_suffix_is_urscript():
    assert dialect_of("a.script") == dialect_of("B.SCRIPT") == "urscript"


def test_metres_and_rotation_vectors_are_held_as_mm_and_kuka_abc():
    rv = Rotation.from_euler("ZYX", [30, -20, 10], degrees=True).as_rotvec()
    p = read(script(f"movel(p[0.5, -0.25, 0.125, {rv[0]:.12f}, {rv[1]:.12f}, {rv[2]:.12f}], a=1.2, v=0.25)"))
    assert p.unit == 1000.0
    assert np.allclose(p.targets.poses[0], [500, -250, 125, 30, -20, 10], atol=1e-6)
    s, e = p.targets.spans[0, 1]
    assert p.texts[0][s:e] == "-0.25"  # the sign is part of the token the rewriter replaces


def test_sample_targets_kinds_tool_and_warnings():
    path = sample_path("urscript/pick_place.script")
    p = parse_program_text(path.read_text(encoding="latin-1"), str(path))
    t = p.targets
    # in the order the motions run (issue 24): wp_approach (declared at line 7), wp_pick, wp_approach again,
    # movep, movec via + end, wp_place, the p[…] of pose_trans(feature, p[…]) (in the frame feature) and
    # movej(get_inverse_kin(wp_approach)) (the pose wp_approach: a Cartesian target); movej(home_q) and
    # movej([…]) are joint space
    assert t.line.tolist() == [7, 8, 7, 18, 19, 19, 9, 21, 7]
    assert [MOTIONS[m] for m in t.motion] == ["LIN", "LIN", "LIN", "LIN", "CIRC-aux", "CIRC-end", "LIN", "LIN", "PTP"]
    assert t.prev.tolist() == [-1, 0, 1, 2, 3, 4, 5, 6, 7]
    assert t.group.tolist() == [0, -1, 0, -1, -1, -1, -1, -1, 0]  # wp_approach runs three times: one group
    assert p.frames[0].tool == pytest.approx((0, 0, 150, 0, 0, 0))
    rot = frames.orientation_rotation(np.array([[3.1416, 0, 0]]), "rotvec")[0]
    feature = np.eye(4)
    feature[:3, :3], feature[:3, 3] = rot, (300, -450, 100)  # p[0.3, -0.45, 0.1, 3.1416, 0, 0]: x, y, z in mm
    assert np.allclose(p.frames[t.frame[7]].base, feature) and p.frames[t.frame[7]].tool == pytest.approx(
        (0, 0, 150, 0, 0, 0))
    assert codes(p) == []


def test_formatting_in_metres_keeps_style_at_micrometre_resolution():
    assert format_many(["0.5", "-.25", "1.2500000", "5e-1"], np.array([500.0123, -250.5, 1250.0, 499.9996]),
                       unit=1000.0) == ["0.500012", "-.250500", "1.2500000", "5.00000e-1"]


def test_tool_follows_set_tcp_in_text_order_on_the_straight_line():
    p = read(script("movel(p[0.1,0,0.3,0,3.1416,0])", "set_tcp(p[0,0,0.1,0,0,0])", "movel(p[0.2,0,0.3,0,3.1416,0])",
                    "tcp2 = p[0,0.05,0.2,0,0,0]", "set_tcp(tcp2)", "movel(p[0.3,0,0.3,0,3.1416,0])"), active=None)
    # before any set_tcp: the installation's TCP, which the script does not say: left as written
    assert p.targets.frame[0] == -1 and codes(p) == ["P221"]
    assert [d.line for d in p.diagnostics] == [2]
    tools = [p.frames[f].tool for f in p.targets.frame[1:]]
    assert tools[0] == pytest.approx((0, 0, 100, 0, 0, 0)) and tools[1] == pytest.approx((0, 50, 200, 0, 0, 0))


@pytest.mark.parametrize("stated, expected", [("model", None), ("0,0,150,0,0,0", (0, 0, 150, 0, 0, 0))])
def test_the_tcp_before_the_first_set_tcp_may_be_stated(stated, expected):
    from postproc.programs.io import read_program

    text = script("movel(p[0.1,0,0.3,0,3.1416,0])", "movel(p[0.2,0,0.3,0,3.1416,0])", "set_tcp(p[0,0,0.1,0,0,0])",
                  "movel(p[0.3,0,0.3,0,3.1416,0])")
    p = read(text, active=None)
    assert p.targets.frame.tolist()[:2] == [-1, -1] and codes(p) == ["P221"]
    assert "2 target(s) left as written" in p.diagnostics[0].message
    p = read_program(["u.script"], [text], "urscript", active=ActiveFrames(tool=ActiveFrames.parse(stated, "tool")))
    assert codes(p) == [] and (p.targets.frame >= 0).all()
    tools = [p.frames[f].tool for f in p.targets.frame]
    assert (tools[0] is None) if expected is None else tools[0] == pytest.approx(expected)
    assert tools[2] == pytest.approx((0, 0, 100, 0, 0, 0))
    for bad in (ActiveFrames(tool=1), ActiveFrames(base=0)):  # TOOL_DATA[n] / a base: not URScript's
        with pytest.raises(PostprocError) as err:
            read_program(["u.script"], [text], "urscript", active=bad)
        assert err.value.code == "P222"


@pytest.mark.parametrize("lines", [
    ["if x:", "  set_tcp(p[0,0,0.2,0,0,0])", "end", "movel(p[0.1,0,0.3,0,3.1416,0])"],
    ["set_tcp(get_tcp_offset())", "movel(p[0.1,0,0.3,0,3.1416,0])"],
    ["set_tcp(p[0,0,0.1,0,0,0])", "while True:", "  movel(p[0.1,0,0.3,0,3.1416,0])", "  set_tcp(p[0,0,0.2,0,0,0])",
     "end"],
])
def test_tool_not_known_leaves_the_target_as_written(lines):
    p = read(script(*lines))
    # (in the while loop: the target runs first after the start, then after itself: two rows, issue 24)
    assert p.targets.frame.tolist() in ([-1], [-1, -1]) and "P203" in codes(p)


def test_one_tool_set_everywhere_is_known_inside_blocks():
    p = read(script("set_tcp(p[0,0,0.1,0,0,0])", "def sub():", "  movel(p[0.1,0,0.3,0,3.1416,0])", "end",
                    "if a > 1:", "  set_tcp(p[0,0,0.1,0,0,0])", "  movel(p[0.2,0,0.3,0,3.1416,0])", "end", "sub()"))
    # (sub()'s target after the IF's, or from the start where the IF is not taken: two rows)
    assert p.targets.frame.tolist() == [0, 0, 0] and not codes(p)


def test_pose_variables_and_run_time_targets():
    p = read(script("global wp1 = p[0.1,0.2,0.3,0,3.1416,0]", "local wp2 = p[0.1,0.2,0.3,0,3.1416,0]",
                    "wp3 = p[0.1,0.2,0.3,0,3.1416,0]", "wp3 = p[0.2,0.2,0.3,0,3.1416,0]",
                    "wp4 = pose_add(get_actual_tcp_pose(), p[0,0,0.1,0,0,0])", "movel(wp1)", "movej(wp1)", "movel(wp2)", "movel(wp3)",
                    "movel(wp4)", "movel(nowhere)", "movel(p[0.1,0.2,d2r(90),0,0,0])",
                    "movel(pose_trans(wp2, p[0,0,0.01,0,0,0]))", "q = [0,-1.57,1.57,0,0,0]", "movej(q)",
                    "movej(get_inverse_kin(p[0.1,0.2,0.3,0,3.1416,0]))"))
    # as the program runs (issue 24): wp1 twice, wp2 (left: its numbers are the frame of the pose_trans at line
    # 14 too), wp3 as its second assignment sets it, the p[…] of pose_trans(wp2, p[…]) in the frame wp2, the pose
    # get_inverse_kin(p[…]) is (a Cartesian target); wp4 (run time), nowhere (assigned nowhere), a Z of d2r(90)
    # (computed) are left as written; movej(q) is a joint motion
    assert p.targets.line.tolist() == [2, 2, 3, 5, 14, 17]
    assert [MOTIONS[m] for m in p.targets.motion] == ["LIN", "PTP", "LIN", "LIN", "LIN", "PTP"]
    assert np.allclose(p.targets.poses[3, :3], [200, 200, 300])
    assert [(d.code, d.line) for d in p.diagnostics] == [("P217", 3), ("P211", 11), ("P215", 12), ("P214", 13)]
    assert p.held == {"P217": [2]}


@pytest.mark.parametrize("text, line, col, code", [
    (script("movel(p[0.1,0.2,0.3,0,0])"), 2, 9, "P117"),
    (script("movel(p[0.1,0.2,0.3,0,0,0]"), 2, 3, "P101"),
    (script("movel(p[0.1,0.2,0.3,0,0,0]) +"), 2, 31, "P101"),
    (script("if x:", "  movel(p[0.1,0.2,0.3,0,0,0])"), 1, 1, "P101"),
    ("def a():\n  movel(p[0.1,0.2,0.3,0,0,0])\nend\nend\n", 4, 1, "P101"),
    (script('textmsg("not closed)'), 2, 11, "P101"),
    (script("movel(p[0.1,1e999,0.3,0,0,0])"), 2, 9, "P103"),
    (script("movel(p[0.1,1e306,0.3,0,0,0])"), 2, 9, "P103"),
])
def test_bad_input_is_located(text, line, col, code):
    with pytest.raises(PostprocError) as exc:
        read(text)
    assert (exc.value.line, exc.value.col, exc.value.code) == (line, col, code), str(exc.value)


def test_a_function_parameter_is_the_argument_of_each_call_even_if_a_global_has_its_name():
    # (issue 24: calls are followed; the parameter holds the pose the call passes, not the global wp)
    p = read(script("global wp = p[0.1,0.2,0.3,0,3.1416,0]", "def go(wp, speed):", "  movel(wp, v=speed)", "end",
                    "go(p[0.2,0.2,0.3,0,3.1416,0], 0.1)", "movel(wp)"))
    assert p.targets.line.tolist() == [6, 2] and codes(p) == []
    assert np.allclose(p.targets.poses[:, :3], [[200, 200, 300], [100, 200, 300]])


def test_blocks_comments_strings_and_continued_lines():
    text = script("# movel(p[9,9,9,0,0,0]) in a comment", 'textmsg("movel(p[9,9,9,0,0,0]) # not code")',
                  "$ 3 \"MoveL\" \"breakAfter\"", "thread t():", "  sleep(1)", "end", "movel(p[0.1,", "      0.2, 0.3,",
                  "      0, 3.1416, 0], a=1.2, v=0.25)  # end of move")
    p = read(text)
    assert p.targets.poses[:, :3].round(6).tolist() == [[100, 200, 300]] and p.targets.line.tolist() == [8]


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    from postproc.testing.models import affine_model

    folder = tmp_path_factory.mktemp("ur")
    kw = dict(reach=None, tool={"name": "any"}, centre=CENTRE)
    return {"zero": load_model(affine_model(folder / "zero.onnx", **kw)),
            "offset": load_model(affine_model(folder / "offset.onnx", offset=OFFSET, **kw)),
            "affine": load_model(affine_model(folder / "affine.onnx", offset=OFFSET, gain=GAIN, **kw))}


@st.composite
def ur_script(draw):
    n = draw(st.integers(1, 6))
    nl = draw(st.sampled_from(["\n", "\r\n"]))
    head, body = ["def gen():"], []
    out = []
    for i in range(n):
        rv = draw(st.sampled_from(["3.1416, 0, 0", "0, 3.1416, 0", "2.2214, -2.2214, 0.0", "0,0,0"]))
        # µm or nm tokens, as Polyscope writes them (shorter tokens gain decimals up to µm when rewritten)
        um = [draw(st.integers(-800_000, 800_000)) for _ in range(3)]
        toks = [f"{u / 1e6:.6f}" if draw(st.booleans()) else f"{(u * 1000 + draw(st.integers(0, 999))) / 1e9:.9f}"
                for u in um]
        xyz = [float(t) for t in toks]
        pose = f"p[{toks[0]}, {toks[1]},{toks[2]}, {rv}]"
        if draw(st.booleans()):
            head.append(f"  global wp{i} = {pose}")
            body.append(f"  movel(wp{i}, a=1.2, v=0.25)  # wp{i}")
            out.append((0, i, np.array(xyz) * 1000))
        else:
            body.append(f"  movej({pose}, a=1.4, v=1.05)")
            out.append((1, i, np.array(xyz) * 1000))
    text = nl.join(head + body + ["end", ""])
    return text, [x for _, _, x in out]  # in the order the motions run (the declarations stand first in the text)


def _strip_stamp(text):
    first, rest = text.split("\n", 1)
    assert first.startswith("# postproc: compensated with model")
    return rest


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(ur_script())
def test_round_trip_zero_offset_and_affine(models, case):
    text, targets = case
    out, _ = compensate_text(text, models["zero"], name="gen.script", active=MODEL_TCP)
    assert _strip_stamp(out) == text
    pat = re.compile(r"-?\d*\.?\d+(?:[eE][-+]?\d+)?")
    for kind in ("offset", "affine"):
        out, report = compensate_text(text, models[kind], name="gen.script", active=MODEL_TCP, iterations=1,
                                         max_correction_mm=50)
        assert report.compensated == len(targets)
        after = _strip_stamp(out)
        assert pat.sub("#", after) == pat.sub("#", text)  # every byte but numbers unchanged
        p_in, p_out = read(text), read(after)
        for k, xyz in enumerate(targets):
            error = OFFSET + (GAIN @ (xyz - CENTRE) if kind == "affine" else 0)
            assert np.allclose(p_out.targets.poses[k, :3], xyz + error, atol=6e-4), (k, kind)
        assert np.array_equal(p_in.targets.poses[:, 3:], p_out.targets.poses[:, 3:])


def test_constant_offset_is_the_change_in_metres_and_the_stamp_is_a_comment(models):
    text = script("set_tcp(p[0,0,0.1,0,0,0])", "movel(p[0.5000, -0.2500, 0.3000, 0, 3.1416, 0], a=1.2, v=0.25)")
    out, report = compensate_text(text, models["offset"], name="u.script", active=MODEL_TCP)
    assert report.compensated == 1
    assert out.splitlines()[0].startswith("# postproc: compensated with model")
    assert "movel(p[0.500300, -0.250200, 0.300100, 0, 3.1416, 0], a=1.2, v=0.25)" in out
    again = read(out)
    assert again.stamps and np.allclose(frames.transform_points(np.eye(4), again.targets.poses[:, :3]),
                                        [[500.3, -250.2, 300.1]])


def test_check_reports_warnings_and_a_second_compensation(models, tmp_path):
    import yaml

    from postproc.compensation.check import check_program

    text = script("movel(p[0.5000, -0.2500, 0.3000, 0, 3.1416, 0])",
                  "movel(pose_add(get_actual_tcp_pose(), p[0,0,0.1,0,0,0]))")
    found = check_program(read(text), models["offset"])
    assert sorted(d.code for d in found) == ["P211", "P301"]  # (outside the test model's box)
    out, _ = compensate_text(text, models["offset"], name="u.script", active=MODEL_TCP)
    twice = "# postproc: compensated with model other 0123456789ab\n" + out
    assert {"P402", "P403"} <= {d.code for d in check_program(read(twice), models["offset"])}
    hooks = yaml.safe_load(sample_path("..").joinpath(".pre-commit-hooks.yaml").read_text())
    assert re.search(hooks[0]["files"], "cell/pick.script")

"""ABB RAPID reader (postproc/programs/rapid.py): each construct on a small module, bad
input located at path:line:col, and the round trip through compensate (zero, constant and
affine models) on generated modules."""
from __future__ import annotations

import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from postproc.compensation.api import compensate_text
from postproc.programs.io import parse_program_text
from postproc.model.compensator import load_model
from postproc.core.diagnostics import PostprocError
from postproc.programs import MOTIONS
from postproc.programs.io import dialect_of
from postproc.core.frames import rotation_from_quaternion as quaternion_matrix
from postproc.core.resources import sample_path

EAX = "[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]"


def rt(x, y, z, q=(0, 0, 1, 0), cf=(0, 0, 0, 0)):
    return f"[[{x},{y},{z}],[{','.join(map(str, q))}],[{','.join(map(str, cf))}],{EAX}]"


def module(*lines, data=()):
    return "\n".join(["MODULE m", *data, "PROC main()", *lines, "ENDPROC", "ENDMODULE", ""])


def read(text, config=None):
    return parse_program_text(text, "m.mod", config_texts=config)


def codes(program):
    return [d.code for d in program.diagnostics]


# --------------------------------------------------------------------------- constructs


def test_suffixes_are_rapid():
    assert {dialect_of(f"a{s}") for s in (".mod", ".MOD", ".prg", ".sys", ".modx")} == {"rapid"}


def test_quaternion_is_w_x_y_z_and_held_as_kuka_abc():
    q = Rotation.from_euler("ZYX", [30, -20, 10], degrees=True).as_quat()  # scipy: x, y, z, w
    wxyz = [q[3], q[0], q[1], q[2]]
    assert np.allclose(quaternion_matrix(np.array(wxyz)), Rotation.from_quat(q).as_matrix())
    p = read(module(f"MoveL {rt(1, 2, 3, q=[f'{v:.9f}' for v in wxyz])}, v100, fine, tool0;"))
    assert np.allclose(p.targets.poses[0], [1, 2, 3, 30, -20, 10], atol=1e-6)


def test_sample_module_targets_frames_and_configuration():
    path = sample_path("rapid/weld_cell.mod")
    p = parse_program_text(path.read_text(encoding="latin-1"), str(path))
    t = p.targets
    # one row per motion in the order main runs them (the motion IR: not the order of the
    # declarations): pHome, Offs(p10,0,0,100), p10, p20, pCirc, pEnd, RelTool(pEnd,0,0,-50) and
    # the FOR's three elements of seam{}; each row at the robtarget's numbers
    assert t.line.tolist() == [6, 7, 7, 8, 9, 10, 10, 11, 12, 13]
    assert [MOTIONS[m] for m in t.motion] == ["PTP", "PTP", "LIN", "LIN", "CIRC-aux", "CIRC-end", "LIN", "LIN", "LIN",
                                              "LIN"]
    assert t.prev.tolist() == [-1, 0, 1, 2, 3, 4, 5, 6, 7, 8]
    assert t.poses[2, :3].tolist() == [150.5, 200, 50]
    # Offs(p10, 0,0,100) is p10's numbers + 100 in Z of the work object; RelTool(pEnd, 0,0,-50)
    # pEnd's + 50 mm along its tool's Z (its quaternion turns the tool 180° about (1,1,0)):
    # both share the numbers of the point they are computed from
    assert t.poses[1, :3].tolist() == [150.5, 200, 150] and t.offset[1].tolist() == [0, 0, 100]
    assert np.allclose(t.poses[6, :3], [350, 300, 100], atol=1e-5) and np.allclose(t.offset[6], [0, 0, 50], atol=1e-5)
    assert t.twin.tolist() == [-1, -1, 1, -1, -1, -1, 5, -1, -1, -1]
    assert p.confdata[4].tolist() == [0, -1, 0, 1] and len(p.confdata) == len(t)
    home, table = p.frames
    assert np.allclose(home.base, np.eye(4)) and home.tool == pytest.approx((0, 0, 200, 0, 0, 0))
    assert table.label == "wTable / tWeld"
    # wTable: uframe 90° about Z at (1800, -300, 600)
    assert np.allclose(table.base[:3, 3], [1800, -300, 600]) and np.allclose(table.base[:2, :2], [[0, -1], [1, 0]])
    assert t.frame.tolist() == [0, 1, 1, 1, 1, 1, 1, 1, 1, 1]
    assert p.diagnostics == []


def test_inline_targets_with_options_and_spanning_lines():
    text = module(f"MoveL\\Conc, {rt(10, -20.5, 30)}, v100\\T:=2, z10, tool0;",
                  "MoveJ [[1,2,3],[1,0,0,0],",
                  "       [0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]], v100, z10, tool0; ! one target, two lines",
                  f"MoveC {rt(4, 5, 6)}, {rt(7, 8, 9)}, v100, z1, tool0; MoveL {rt(0, 0, 1)}, v1, fine, tool0;")
    p = read(text)
    assert p.targets.poses[:, :3].tolist() == [[10, -20.5, 30], [1, 2, 3], [4, 5, 6], [7, 8, 9], [0, 0, 1]]
    assert [MOTIONS[m] for m in p.targets.motion] == ["LIN", "PTP", "CIRC-aux", "CIRC-end", "LIN"]
    # the span of a negative number covers its sign: the corrected value may be positive
    s, e = p.targets.spans[0, 1]
    assert text[s:e] == "-20.5"
    assert p.targets.line.tolist() == [3, 4, 6, 6, 6]


def test_arrays_literal_index_and_run_time_index():
    data = [f"CONST robtarget a{{3}}:=[{rt(1, 0, 0)},{rt(2, 0, 0)},{rt(3, 0, 0)}];",
            f"CONST robtarget b{{2}}:=[{rt(4, 0, 0)},{rt(5, 0, 0)}];"]
    p = read(module("MoveL a{2}, v100, z1, tool0;", "MoveL b{i}, v100, z1, tool0;", "MoveL a{7}, v1, z1, tool0;",
                    data=data))
    # (an index known only at run time names no one element: b{i} is left as written where the
    # old reader compensated every element, each without knowing its predecessor)
    assert p.targets.poses[:, 0].tolist() == [2]
    assert [(d.code, d.line) for d in p.diagnostics] == [("P211", 6), ("P211", 7)]
    assert "run-time index" in p.diagnostics[0].message
    assert "a{…} is not set (or outside the array)" in p.diagnostics[1].message


def test_work_object_frames_compose_user_and_object_frame():
    uq = Rotation.from_euler("z", 30, degrees=True).as_quat()
    oq = Rotation.from_euler("x", 90, degrees=True).as_quat()
    fmt = lambda q: ",".join(f"{v:.9f}" for v in (q[3], q[0], q[1], q[2]))  # noqa: E731
    data = [f"PERS wobjdata w1:=[FALSE,TRUE,\"\",[[100,200,300],[{fmt(uq)}]],[[10,0,5],[{fmt(oq)}]]];",
            "PERS tooldata t1:=[TRUE,[[0,0,150],[1,0,0,0]],[1,[0,0,1],[1,0,0,0],0,0,0]];"]
    p = read(module(f"MoveL {rt(1, 2, 3)}, v100, z1, t1\\WObj:=w1;", data=data))
    want = np.eye(4)
    want[:3, :3] = Rotation.from_euler("z", 30, degrees=True).as_matrix() @ Rotation.from_euler(
        "x", 90, degrees=True).as_matrix()
    want[:3, 3] = [100, 200, 300] + Rotation.from_euler("z", 30, degrees=True).apply([10, 0, 5])
    assert np.allclose(p.frames[0].base, want, atol=1e-8)
    assert p.frames[0].tool == pytest.approx((0, 0, 150, 0, 0, 0))


def test_tool_and_work_object_from_config_modules():
    sysmod = "MODULE user(SYSMODULE)\nPERS wobjdata w1:=[FALSE,TRUE,\"\",[[0,0,500],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];\n" \
             "ENDMODULE\n"
    p = read(module(f"MoveL {rt(1, 2, 3)}, v100, z1, tool0\\WObj:=w1;"), config=[sysmod])
    assert np.allclose(p.frames[0].base[:3, 3], [0, 0, 500]) and p.targets.frame.tolist() == [0]


@pytest.mark.parametrize("data, wobj, why, code", [
    ([], "wNone", "not declared", "P201"),
    (["PERS wobjdata w:=[TRUE,TRUE,\"\",[[0,0,0],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];"], "w", "held by the robot", "P201"),
    # (a user frame a mechanical unit moves: P225, the code of a base that moves with external axes)
    (["PERS wobjdata w:=[FALSE,FALSE,\"STN1\",[[0,0,0],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];"], "w", "mechanical unit STN1",
     "P225"),
    (["PERS wobjdata w:=[FALSE,TRUE,\"\",[[0,0,0],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];"], "w", "assigned at run time",
     "P201"),
])
def test_unknown_work_objects_leave_targets_as_written(data, wobj, why, code):
    lines = [f"MoveL {rt(1, 2, 3)}, v100, z1, tool0\\WObj:={wobj};"]
    if why.startswith("assigned"):
        lines.append("w.uframe.trans.x := 5;")
    p = read(module(*lines, data=data))
    # the target is a row left as written (frame -1: counted by compensate, exit 1)
    assert len(p.targets) == 1 and p.targets.frame.tolist() == [-1]
    (d,) = p.diagnostics
    assert d.code == code and why in d.message and "1 target(s) left as written" in d.message
    if why.startswith("assigned"):  # at the cause: the PERS the program assigns
        assert (d.line, d.col) == (2, 15)
    else:
        assert (d.line, d.col) == (3 + len(data), 9)  # at its X


def test_named_targets_not_statically_known_are_warned():
    data = [f"VAR robtarget pv:={rt(1, 0, 0)};", f"CONST robtarget unused:={rt(2, 0, 0)};",
            f"CONST robtarget pe:=[[xx,0,0],[1,0,0,0],[0,0,0,0],{EAX}];"]
    p = read(module("MoveL pv, v100, z1, tool0;", "pv := CRobT();", "MoveL pOther, v100, z1, tool0;",
                    "MoveL pe, v1, z1, tool0;", "MoveL CRobT(), v1, z1, tool0;", "MoveAbsJ jHome, v1, z1, tool0;",
                    data=data))
    assert len(p.targets) == 0
    # each at the motion that moves to it (a robtarget no motion runs is no target: not said)
    messages = [(d.code, d.line) for d in p.diagnostics]
    assert messages == [("P211", 6), ("P215", 8), ("P212", 9), ("P211", 10)]
    # module data the program assigns: a run (main again, in continuous mode) starts with the last run's value
    assert "VAR pv is assigned at run time" in p.diagnostics[0].message
    assert "pOther is not declared" in p.diagnostics[1].message
    assert "its X is not known here (xx is not declared" in p.diagnostics[2].message
    assert "CRobT() is where the robot is at run time" in p.diagnostics[3].message


def test_one_robtarget_in_two_frames_is_left_with_p230(affine):
    # (P202 is retired: one set of numbers the two motions need different corrections for is
    # left as written at both, a warning, and the rest compensated; exit 1)
    data = [f"CONST robtarget p1:={rt(1800, 2, 900)};", f"CONST robtarget p2:={rt(1900, 50, 950)};",
            "PERS wobjdata w:=[FALSE,TRUE,\"\",[[0,0,100],[0.7071068,0,0,0.7071068]],[[0,0,0],[1,0,0,0]]];"]
    text = module("MoveL p1, v100, z1, tool0;", "MoveL p1, v100, z1, tool0\\WObj:=w;", "MoveL p2, v100, z1, tool0;",
                  data=data)
    p = read(text)
    assert len(p.targets) == 3 and p.targets.frame.tolist() == [0, 1, 0] and p.targets.twin.tolist() == [-1, 0, -1]
    model = load_model(affine(offset=(0.1, 0, 0), gain=np.diag([1e-3, 2e-3, -1e-3]), reach=None, envelope=None,
                              tool={"name": "any"}))
    out, report = compensate_text(text, model, name="m.mod")
    assert [(w.code, w.line) for w in report.warnings] == [("P230", 2)]  # at p1's numbers
    assert "the motions at m.mod:6, m.mod:7)" in report.warnings[0].message  # each run's motion, named
    assert report.compensated == 1 and report.left_codes == {"P230": 1}
    assert f"{rt(1800, 2, 900)};" in out and f"{rt(1900, 50, 950)};" not in out


def test_header_of_older_controllers_and_stamp_detection():
    text = "%%%\n  VERSION:1\n  LANGUAGE:ENGLISH\n%%%\n\n" + module(f"MoveL {rt(1, 2, 3)}, v1, z1, tool0;")
    assert len(read(text).targets) == 1
    stamped = "! postproc: compensated with model m 0123456789ab\n" + module()
    assert read(stamped).stamps == {0: "! postproc: compensated with model m 0123456789ab"}


@pytest.mark.parametrize("text, line, col, code", [
    ("MODULE m\nPROC main()\nMoveL p10, v100, z1, tool0\nENDPROC\nENDMODULE\n", 3, 1, "P101"),  # no ';'
    ("MODULE m\nPROC main()\nMoveL p10 v100, z1, tool0;\nENDPROC\nENDMODULE\n", 3, 11, "P101"),
    ("MODULE m\nPROC main()\nTPWrite \"open;\nENDPROC\nENDMODULE\n", 3, 9, "P101"),
    ("MODULE m\nPROC main()\nMoveL p10, v100, z1, tool0;\nENDMODULE\n", 4, 1, "P102"),
    ("MODULE m\nPROC main()\nENDPROC\n", 4, 1, "P102"),
    ("PROC main()\nENDPROC\n", 1, 1, "P102"),
    ("! only a comment\n", 1, 1, "P104"),
    (module(f"MoveL {rt(1, '9E999', 3)}, v1, z1, tool0;"), 3, 11, "P103"),
    (module(f"MoveL {rt(1, 2, 3, q=(0, 0, 0, 0))}, v1, z1, tool0;"), 3, 17, "P103"),  # at q1
])
def test_bad_input_is_located(text, line, col, code):
    with pytest.raises(PostprocError) as exc:
        read(text)
    assert (exc.value.path, exc.value.line, exc.value.col, exc.value.code) == ("m.mod", line, col, code)


# --------------------------------------------------------------------------- round trip

OFFSET = np.array([0.3, -0.2, 0.1])
GAIN = np.array([[2e-3, 0, 0], [0, -1e-3, 5e-4], [0, 0, 3e-3]])
CENTRE = np.array([2000.0, 0.0, 900.0])


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    from postproc.testing.models import affine_model

    folder = tmp_path_factory.mktemp("rapid-models")
    kw = dict(reach=None, tool={"name": "any"}, centre=CENTRE)
    return {"zero": load_model(affine_model(folder / "zero.onnx", **kw)),
            "offset": load_model(affine_model(folder / "offset.onnx", offset=OFFSET, **kw)),
            "affine": load_model(affine_model(folder / "affine.onnx", offset=OFFSET, gain=GAIN, **kw))}


number = st.floats(-1500, 1500, allow_nan=False).map(lambda v: round(v, 3) + 0.0)
blank = st.sampled_from(["", " ", "  "])


@st.composite
def rapid_module(draw):
    """A module with declared and inline targets in wobj0 and in a turned work object. Returns
    (text, [(x, y, z) written, rotation of its frame, position in the robot base] per target,
    in the order main moves to them)."""
    rot = Rotation.from_euler("ZYX", draw(st.tuples(*[st.integers(-180, 180)] * 3)), degrees=True)
    origin = np.array(draw(st.tuples(number, number, number)))
    qw = rot.as_quat()
    wq = ",".join(f"{v:.12f}" for v in (qw[3], qw[0], qw[1], qw[2]))
    rot = Rotation.from_quat(qw / np.linalg.norm(qw))
    nl = draw(st.sampled_from(["\n", "\r\n"]))
    head = ["MODULE gen", "  ! generated", f'  PERS wobjdata w1:=[FALSE,TRUE,"",[[{origin[0]},{origin[1]},{origin[2]}],'
            f"[{wq}]],[[0,0,0],[1,0,0,0]]];"]
    body = ["  PROC main()"]
    targets = []  # (line list, index in line list, tokens, frame rotation, origin, declared name)
    n = draw(st.integers(1, 8))
    for i in range(n):
        xyz = draw(st.tuples(number, number, number))
        in_w = draw(st.booleans())
        declared = draw(st.booleans())
        s = draw(blank)
        toks = [f"{v:.3f}" if draw(st.booleans()) else f"{v:.4f}" for v in xyz]
        agg = f"[[{toks[0]},{s}{toks[1]},{toks[2]}],[0,0,1,0],[0,0,0,0],{EAX}]"
        where = "\\WObj:=w1" if in_w else ""
        if declared:
            head.append(f"  CONST robtarget p{i}:={agg};")
            body.append(f"    MoveL p{i},{s}v100, z1, tool0{where};  ! p{i}")
        else:
            body.append(f"    MoveJ {agg}, v100,{s}fine, tool0{where};")
        targets.append((declared, i, np.array(xyz, float), in_w))
    body += ["  ENDPROC", "ENDMODULE", ""]
    text = nl.join(head + body)
    # rows in the order main runs its motions
    out = []
    for declared, i, xyz, in_w in targets:
        r = rot.as_matrix() if in_w else np.eye(3)
        o = origin if in_w else np.zeros(3)
        out.append((xyz, r, o + r @ xyz))
    return text, out


def _numbers_changed(before: str, after: str):
    """The numbers of ``after`` that differ from ``before`` token by token (same token count)."""
    pat = re.compile(r"-?\d+\.\d+(?:[eE][-+]?\d+)?|-?\d+")
    a, b = pat.findall(before), pat.findall(after)
    assert len(a) == len(b)
    assert pat.sub("#", before) == pat.sub("#", after)  # every other byte unchanged
    return a, b


def _strip_stamp(text):
    first, rest = text.split("\n", 1)
    assert first.startswith("! postproc: compensated with model")
    return rest


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(rapid_module())
def test_round_trip_zero_offset_and_affine(models, case):
    text, targets = case
    out, _ = compensate_text(text, models["zero"], name="gen.mod")
    assert _strip_stamp(out) == text
    for kind in ("offset", "affine"):
        out, report = compensate_text(text, models[kind], name="gen.mod", iterations=1, max_correction_mm=50)
        assert report.compensated == len(targets)
        p_in, p_out = read(text), read(_strip_stamp(out))
        _numbers_changed(text, _strip_stamp(out))
        got = p_out.targets.poses[:, :3]
        for k, (xyz, r, base) in enumerate(targets):
            error = OFFSET + (GAIN @ (base - CENTRE) if kind == "affine" else 0)
            assert np.allclose(got[k], xyz + r.T @ error, atol=6e-4), (k, kind)
        assert np.array_equal(p_in.targets.poses[:, 3:], p_out.targets.poses[:, 3:])


def test_repeated_motions_read_alike_and_a_bad_number_later_is_located():
    # the second and later motions of one exact shape take the reader's fast path
    lines = [f"MoveL [[{i}.5,- {i},{2 * i}],[0,0,1,0],[0,{i % 2},0,1],{EAX}],v100,z1,tool0;" for i in range(1, 6)]
    p = read(module(*lines))
    assert p.targets.poses[:, :3].tolist() == [[i + 0.5, -i, 2 * i] for i in range(1, 6)]
    assert p.confdata[:, 1].tolist() == [1, 0, 1, 0, 1]
    assert p.targets.line.tolist() == [3, 4, 5, 6, 7] and set(p.targets.col.tolist()) == {9}
    s, e = p.targets.spans[3, 1]
    assert p.texts[0][s:e] == "- 4"  # sign and blank: one token for the rewriter
    lines[3] = lines[3].replace("4.5", "4e999")
    with pytest.raises(PostprocError) as exc:
        read(module(*lines))
    assert (exc.value.line, exc.value.col, exc.value.code) == (6, 9, "P103")

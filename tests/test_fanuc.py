"""Fanuc LS reader (postproc/programs/fanuc.py): each construct on a small program, bad
input located at path:line:col, the W,P,R convention, frames from the frame file, and the
round trip through compensate (zero, constant and affine models) on generated programs."""
from __future__ import annotations

import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from postproc.core import frames
from postproc.compensation.check import check_program
from postproc.compensation.api import compensate_text
from postproc.programs.io import parse_program_text
from postproc.model.compensator import load_model
from postproc.core.diagnostics import PostprocError
from postproc.programs import MOTIONS
from postproc.programs.io import dialect_of
from postproc.programs.fanuc import read_frames, wpr_to_abc
from postproc.core.resources import sample_path

OFFSET = np.array([0.3, -0.2, 0.1])
GAIN = np.array([[2e-3, 0, 0], [0, -1e-3, 5e-4], [0, 0, 3e-3]])
CENTRE = np.array([1500.0, 0.0, 600.0])
FRAMES = """[uframe.1]
xyzwpr = [1200.0, -300.0, 450.0, 0.0, 0.0, 90.0]
[uframe.2]
xyzwpr = [800.0, 400.0, 100.0, 10.0, -5.0, 30.0]
[utool.1]
xyzwpr = [0.0, 0.0, 200.0, 0.0, 0.0, 0.0]
"""


def pos(n, x, y, z, w=180.0, p=0.0, r=0.0, uf=1, ut=1, fmt="{:9.3f}"):
    f = fmt.format
    return (f"P[{n}]{{\n   GP1:\n\tUF : {uf}, UT : {ut},\t\tCONFIG : 'N U T, 0, 0, 0',\n"
            f"\tX = {f(x)}  mm,\tY = {f(y)}  mm,\tZ = {f(z)}  mm,\n"
            f"\tW = {f(w)} deg,\tP = {f(p)} deg,\tR = {f(r)} deg\n}};")


def program(mn, positions=(), name="T"):
    lines = [f"/PROG  {name}", "/ATTR", "OWNER\t\t= MNEDITOR;", "LINE_COUNT\t= 1;", "/MN"]
    lines += [f"{k:4d}:{line} ;" if not line.startswith("    :") else line for k, line in enumerate(mn, start=1)]
    lines += ["/POS", *positions, "/END", ""]
    return "\n".join(lines)


def read(text, frames_text=FRAMES):
    return parse_program_text(text, "t.ls", config_texts=[frames_text] if frames_text else None)


def codes(p):
    return [d.code for d in p.diagnostics]


def test_suffix_is_fanuc():
    assert dialect_of("a.ls") == dialect_of("A.LS") == "fanuc"


def test_wpr_is_fixed_xyz_r_rz_ry_rx():
    w, p, r = 20.0, -35.0, 110.0
    fixed_xyz = Rotation.from_euler("xyz", [w, p, r], degrees=True).as_matrix()  # extrinsic X, then Y, then Z
    assert np.allclose(frames.rotation_from_abc(wpr_to_abc(np.array([w, p, r]))), fixed_xyz)
    t = read(program(["L P[1] 100mm/sec FINE"], [pos(1, 10, 20, 30, w, p, r)])).targets
    assert np.allclose(t.poses[0], [10, 20, 30, r, p, w])


def test_sample_targets_frames_and_configuration():
    path = sample_path("fanuc/weld_seam.ls")
    p = parse_program_text(path.read_text(encoding="latin-1"), str(path),
                           config_texts=[sample_path("fanuc/frames.toml").read_text()])
    t = p.targets
    # P[1] joint representation; P[3] (line 45) also read by the Offset,PR[1] motion of line 30 (PR[1] not known
    # there): its row is left as written (P217); PR[2] is not known (P211)
    assert t.line.tolist() == [39, 45, 51, 57]
    assert [MOTIONS[m] for m in t.motion] == ["LIN", "LIN", "CIRC-aux", "CIRC-end"]
    assert p.configs == ["N U T, 0, 0, 0"] * 4  # (a circular motion keeps the arm's configuration)
    assert [(d.code, d.line) for d in p.diagnostics] == [("P211", 30), ("P211", 31), ("P217", 45)]
    assert p.held["P217"].tolist() == [1]
    assert np.allclose(p.frames[0].base, frames.frame_to_matrix([1650, 0, -450, -90, 0, 0]))
    assert p.frames[0].tool == pytest.approx((0, 0, 300, 0, 0, 0))


def test_frames_per_position_and_unknown_frames():
    p = read(program(["J P[1] 50% FINE", "L P[2] 100mm/sec FINE", "L P[3] 100mm/sec FINE", "L P[4] 10mm/sec FINE",
                      "L P[5] 10mm/sec FINE"],
                     [pos(1, 1, 2, 3, uf=0, ut=0), pos(2, 1, 2, 3, uf=2), pos(3, 1, 2, 3, uf=3), pos(4, 1, 2, 3, ut=9),
                      pos(5, 1, 2, 3, uf="F")]))
    t = p.targets
    assert [p.frames[f].label if f >= 0 else None for f in t.frame] == ["UF 0 / UT 0", "UF 2 / UT 1", None, None, None]
    assert codes(p) == ["P201", "P203", "P201"]
    assert read(program(["L P[1] 100mm/sec FINE"], [pos(1, 1, 2, 3, uf=1)]), None).targets.frame.tolist() == [-1]


def test_run_time_and_shared_positions_are_left_as_written():
    p = read(program(["L P[1] 100mm/sec FINE", "L PR[4] 100mm/sec FINE", "L P[2] 100mm/sec FINE INC",
                      "PR[1]=P[3]", "L P[3] 100mm/sec FINE", "L P[9] 100mm/sec FINE",
                      "! L P[1] in a remark", "L P[4] 100mm/sec FINE Tool_Offset,PR[2]", "L P[R[2]] 100mm/sec FINE"],
                     [pos(k, k, 2, 3) for k in (1, 2, 3, 4)]))
    # P[1] and P[3] (records from line 16 on, six lines each); P[3] is copied into PR[1], which holds it at the
    # program's end where other programs may read it: left as written (P217); INC is relative (P210)
    assert p.targets.line.tolist() == [16, 28] and p.held["P217"].tolist() == [1]
    assert [(d.code, d.line) for d in p.diagnostics] == [("P211", 7), ("P210", 8), ("P215", 11), ("P211", 13),
                                                         ("P211", 14), ("P217", 28)]


def test_joint_representation_is_no_target_and_other_groups_are_left():
    joint = "P[1]{\n   GP1:\n\tUF : 1, UT : 1,\n\tJ1=  10.000 deg,\tJ2= -20.000 deg\n};"
    two = pos(2, 5, 6, 7).replace("};", "   GP2:\n\tUF : 1, UT : 1,\n\tJ1=  100.000 mm\n};")
    p = read(program(["J P[1] 50% FINE", "L P[2] 100mm/sec FINE"], [joint, two]))
    # a second group (a track, a positioner: issue 25) moves too: without its kinematics, left as written (P225)
    assert p.targets.poses[:, :3].tolist() == [[5, 6, 7]] and p.targets.frame.tolist() == [-1]
    assert codes(p) == ["P225"] and "GP2" in p.diagnostics[0].message


@pytest.mark.parametrize("text, line, col, code", [
    ("/ATTR\n/MN\n/END\n", 1, 1, "P101"),
    (program(["L P[1] 100mm/sec FINE"], [pos(1, 1, 2, 3).replace("X =", "X ==")]), 11, 5, "P101"),
    (program(["L P[1] 100mm/sec FINE"], [pos(1, 1, 2, 3).replace("Z = ", "Z = 1e999 + ")]), 11, 50, "P101"),
    (program(["L P[1] 100mm/sec FINE"], [pos(1, 1, 2, 3).replace("  mm,\tY", " deg,\tY")]), 11, 10, "P118"),
    (program(["L P[1] 100mm/sec FINE"], [pos(1, 1, 2, 3).replace("Y = ", "Q = ")]), 11, 21, "P101"),
    (program(["L P[1] 100mm/sec FINE"], [pos(1, 1, 2, 3), pos(1, 1, 2, 3)]), 14, 1, "P101"),
    (program(["L P[1] 100mm/sec FINE"], [pos(1, 1, 2, 3).replace("};", "}")]), 8, 1, "P101"),
    (program(["L P[1] 100mm/sec FINE"], [pos(1, 1, 2, 3, fmt="{}").replace("X = 1", "X = 1e999")]), 8, 1, "P103"),
    (program(["L P[1] 100mm/sec FINE"]).replace("/END\n", "/END\nL P[2]\n"), 9, 1, "P101"),
    (program(["L P[1] 100mm/sec FINE"]).replace("   1:L", "   1 L"), 6, 4, "P101"),
])
def test_bad_input_is_located(text, line, col, code):
    with pytest.raises(PostprocError) as exc:
        read(text)
    assert (exc.value.line, exc.value.col, exc.value.code) == (line, col, code), str(exc.value)


@pytest.mark.parametrize("frames_text, message, line", [
    ("[uframe.1\n", "not valid TOML", 1), ("[uframe.2]\nxyzwpr = [0, 0, 0, 0, 0, 0]\n[uframe.1]\nxyzwpr = [1, 2, 3]\n",
                                          "six finite", 3),
    ("# frames\n[uframes.1]\nxyzwpr = [0, 0, 0, 0, 0, 0]\n", "unknown table", 2),
])
def test_bad_frame_file_is_refused_at_its_line(frames_text, message, line):
    with pytest.raises(PostprocError, match=message) as exc:
        read_frames(frames_text)
    assert (exc.value.code, exc.value.line) == ("P118", line)


@pytest.fixture(scope="module")
def frames_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("frames") / "frames.toml"
    path.write_text(FRAMES)
    return str(path)


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    from postproc.testing.models import affine_model

    folder = tmp_path_factory.mktemp("ls")
    kw = dict(reach=None, tool={"name": "any"}, centre=CENTRE)
    return {"zero": load_model(affine_model(folder / "zero.onnx", **kw)),
            "offset": load_model(affine_model(folder / "offset.onnx", offset=OFFSET, **kw)),
            "affine": load_model(affine_model(folder / "affine.onnx", offset=OFFSET, gain=GAIN, **kw))}


@st.composite
def ls_program(draw):
    n = draw(st.integers(1, 6))
    nl = draw(st.sampled_from(["\n", "\r\n"]))
    mn, records, out = [], [], []
    uframes, _ = read_frames(FRAMES)
    for i in range(1, n + 1):
        xyz = [draw(st.integers(-800_000, 800_000)) / 1000 for _ in range(3)]
        uf = draw(st.sampled_from([0, 1, 2]))
        fmt = draw(st.sampled_from(["{:9.3f}", "{:.4f}"]))
        records.append(pos(i, *xyz, uf=uf, fmt=fmt))
        mn.append(f"{draw(st.sampled_from('JL'))} P[{i}] 100mm/sec CNT50")
        out.append((np.array(xyz), uframes[uf]))
    return program(mn, records).replace("\n", nl), out


def _strip_stamp(text):
    """The text without the stamp line, and /ATTR's LINE_COUNT one less (the stamp counted it)."""
    m = re.search(r"^ *\d+:  ! postproc: compensated with model .* ;\r?\n", text, re.M)
    assert m, "no stamp"
    text = text[:m.start()] + text[m.end():]
    return re.sub(r"^(LINE_COUNT\t= )(\d+)", lambda c: f"{c.group(1)}{int(c.group(2)) - 1}", text, count=1, flags=re.M)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(ls_program())
def test_round_trip_zero_offset_and_affine(models, frames_file, case):
    text, targets = case
    out, _ = compensate_text(text, models["zero"], name="gen.ls", config=frames_file)
    assert _strip_stamp(out) == text
    pat = re.compile(r"-?\d*\.?\d+")
    for kind in ("offset", "affine"):
        out, report = compensate_text(text, models[kind], name="gen.ls", iterations=1, max_correction_mm=50,
                                      config=frames_file)
        assert report.compensated == len(targets)
        after = _strip_stamp(out)
        assert pat.sub("#", after) == pat.sub("#", text)
        p_in, p_out = read(text), read(after)
        for k, (xyz, base) in enumerate(targets):
            in_base = frames.transform_points(base, xyz[None])[0]
            error = OFFSET + (GAIN @ (in_base - CENTRE) if kind == "affine" else 0)
            assert np.allclose(p_out.targets.poses[k, :3], xyz + base[:3, :3].T @ error, atol=6e-4), (k, kind)
        assert np.array_equal(p_in.targets.poses[:, 3:], p_out.targets.poses[:, 3:])


def test_stamp_is_a_numbered_remark_and_check_sees_it(models, frames_file):
    text = program(["L P[1] 100mm/sec FINE", "L P[2] 100mm/sec FINE"], [pos(1, 10, 20, 30), pos(2, 40, 50, 60)])
    out, report = compensate_text(text, models["offset"], name="t.ls", config=frames_file)
    assert report.compensated == 2
    assert "   3:  ! postproc: compensated with model test-model" in out
    assert "LINE_COUNT\t= 1;" in text and "LINE_COUNT\t= 2;" in out  # one numbered line more
    again = read(out)
    assert again.stamps
    twice = out.replace("/POS", "   4:  ! postproc: compensated with model other 0123456789ab ;\n/POS")
    assert "P403" in {d.code for d in check_program(read(twice), models["offset"])}  # two stamps


def test_config_is_not_guessed_for_a_model_that_takes_joint_angles(tmp_path, frames_file):
    from postproc.testing.models import joint_model

    model = load_model(joint_model(tmp_path / "j.onnx", np.diag([0.5, 0.4, 0.3]) @ np.eye(3, 6), tool={"name": "any"}))
    no_config = pos(2, 1500, 0, 900, uf=0).replace("CONFIG : 'N U T, 0, 0, 0',", "")
    text = program(["L P[1] 100mm/sec FINE", "L P[2] 100mm/sec FINE"], [pos(1, 1500, 100, 900, uf=0), no_config])
    # a model of a KUKA (its description states KUKA S/T) is no model of a FANUC's program: refused
    with pytest.raises(PostprocError, match="P310.*FANUC controllers.*KR500-sim"):
        compensate_text(text, model, name="t.ls", config=frames_file)
    out, report = compensate_text(text, model, name="t.ls", config=frames_file, force=True)
    assert report.left_codes == {"P309": 1} and report.compensated == 1
    assert "X =  1500.000  mm,\tY =   100.000" in out  # P[1] (CONFIG 'N U T, 0, 0, 0') as written

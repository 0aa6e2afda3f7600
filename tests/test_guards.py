"""Every guard of `postproc compensate`, through the CLI: a refusal is exit 2 with one
`path:line:col: CODE message` (or `path: CODE message`) line on stderr, and nothing written
(the previous output byte-identical, no temporary file left); a warning is exit 0 with the
warning located on stderr."""
import math
import re

import numpy as np
import onnx
import pytest
from onnx import TensorProto, helper, numpy_helper

from postproc.cli import main

GOOD = "name,x,y,z,a,b,c\nP1,2000.000,0.000,900.000,0,90,0\nP2,2100.000,100.000,950.000,1,89,0\n"
PREVIOUS = b"previous output\n"


@pytest.fixture
def run(tmp_path, capsys):
    """run(text, model, *options) → (exit code, stderr, output text or None); the output
    directory starts with a previous output that a refusal must leave alone."""
    out_dir = tmp_path / "out"
    out_dir.mkdir()

    def go(text, model, *options, name="prog.csv", output=None):
        src = tmp_path / name
        src.write_bytes(text.encode("latin-1") if isinstance(text, str) else text)
        out = out_dir / name if output is None else output
        if output is None:
            out.write_bytes(PREVIOUS)
        code = main(["compensate", str(src), "-o", str(out), "--model", str(model), *options])
        err = capsys.readouterr().err
        written = out.read_bytes().decode("latin-1") if out.is_file() and out.read_bytes() != PREVIOUS else None
        return code, err, written

    go.out_dir = out_dir
    go.src = lambda name="prog.csv": tmp_path / name
    return go


def refused(result, run, code, path, line=None, col=None, message=""):
    """Exit 2, one located message with ``code``, nothing written."""
    status, err, written = result
    assert status == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    where = f"{path}:{line}:{col}: " if line is not None else f"{path}: "
    assert lines[0].startswith(where + code + " "), lines[0]
    assert re.search(message, lines[0]), lines[0]
    assert written is None
    # the previous output is intact and no temporary file is left beside it
    assert [(p.name, p.read_bytes()) for p in run.out_dir.iterdir()] == [("prog.csv", PREVIOUS)]


# --------------------------------------------------------------------------- inputs


@pytest.mark.parametrize("bad, col, message", [
    ("nan", 4, "column x is not a number: 'nan'"),
    ("inf", 4, "column x is not a number"),
    ("1e999", 4, "x is not finite: 1e999"),
    ("-1E+400", 4, "x is not finite"),
])
def test_non_finite_input_is_refused(run, affine, bad, col, message):
    text = GOOD.replace("P2,2100.000", f"P2,{bad}")
    refused(run(text, affine()), run, "P103", run.src(), 3, col, re.escape(message))


# --------------------------------------------------------------------------- model outputs


@pytest.mark.parametrize("offset", [(math.nan, 0, 0), (0, math.inf, 0), (0, 0, -math.inf)])
def test_model_returning_nan_or_inf_is_refused(run, affine, offset):
    refused(run(GOOD, affine(offset=offset)), run, "P305", run.src(), 2, 1, "NaN or inf")


def test_model_nan_only_at_one_target_points_at_it(run, affine):
    # E = gain · (x − 2000) overflows float32 at P2 (x = 2100) only: P1 sits on the centre
    model = affine(gain=np.diag([3e38, 0, 0]), centre=(2000.0, 0.0, 900.0))
    refused(run(GOOD, model), run, "P305", run.src(), 3, 1, "NaN or inf")


def test_correction_above_the_bound_is_refused(run, affine):
    model = affine(offset=(4.0, 3.0, 0.0))  # 5.000 mm: at the bound, accepted
    status, err, written = run(GOOD, model, "-q")
    assert status == 0 and "2004.000,3.000,900.000" in written
    model = affine(offset=(4.0, 3.1, 0.0))  # 5.061 mm
    refused(run(GOOD, model), run, "P303", run.src(), 2, 1, r"correction of 5\.061 mm exceeds the bound of 5\.0 mm")
    # a larger bound lets it through; a smaller one refuses what the default accepts
    assert run(GOOD, model, "--max-correction", "6", "-q")[0] == 0
    refused(run(GOOD, affine(offset=(0.3, 0, 0)), "--max-correction", "0.2"), run, "P303", run.src(), 2, 1, "0.300 mm")


def test_only_the_target_with_a_large_correction_is_named(run, affine):
    # E = 0.003·y: 0 at P1, 0.3 mm at P2, 6 mm at P3 (y = 2000, still within reach)
    text = GOOD + "P3,2000.000,2000.000,900.000,0,90,0\n"
    model = affine(gain=np.diag([0, 3e-3, 0]))
    refused(run(text, model, "--max-correction", "5"), run, "P303", run.src(), 4, 1, "exceeds the bound")


@pytest.mark.parametrize("value", ["nan", "inf", "0", "-1"])
def test_bound_must_be_a_positive_number(run, affine, value):
    # NaN used to switch the bound off silently (every comparison with NaN is False)
    refused_without_path(run(GOOD, affine(offset=(6.0, 0, 0)), "--max-correction", value), run, "P308",
                         "--max-correction must be a positive number of mm")


def refused_without_path(result, run, code, message):
    status, err, written = result
    assert status == 2 and err.strip().startswith(code + " ") and re.search(message, err), err
    assert written is None
    assert [(p.name, p.read_bytes()) for p in run.out_dir.iterdir()] == [("prog.csv", PREVIOUS)]


@pytest.mark.parametrize("value", ["0", "101", "1000000000"])
def test_iterations_are_bounded(run, affine, value):
    refused_without_path(run(GOOD, affine(), "--iterations", value), run, "P308", "between 1 and 100")


# --------------------------------------------------------------------------- envelope and reach


def test_outside_the_envelope_warns_and_strict_refuses(run, affine):
    text = GOOD + "P3,1500.000,0.000,900.000,0,90,0\nP4,2000.000,0.000,900.000,0,70,0\n"
    status, err, written = run(text, affine(offset=(0.1, 0, 0)))
    assert status == 0
    src = run.src()
    assert f"{src}:4:1: P301 target outside the model's training envelope" in err
    assert f"{src}:5:1: P301 " in err  # attitude B = 70 is outside 90 ± 10
    assert "1500.100,0.000,900.000" in written  # compensated all the same
    refused(run(text, affine(offset=(0.1, 0, 0)), "--strict"), run, "P301", src, 4, 1, "--strict; 2 warning")


def test_beyond_reach_is_refused(run, affine):
    # reach: 300-2700 mm from (500, 0, 1045)
    for x, line in (("3300.000", 3), ("600.000", 3)):
        text = GOOD.replace("2100.000,100.000,950.000", f"{x},0.000,1045.000")
        refused(run(text, affine()), run, "P302", run.src(), line, 1, "beyond the robot's reach")


# --------------------------------------------------------------------------- robot, stamp


def test_model_for_another_robot_is_refused_unless_forced(run, affine):
    model = affine(robot="KR500-sim")
    assert run(GOOD, model, "--robot", "kr500-SIM", "-q")[0] == 0  # names compare case-insensitively
    refused(run(GOOD, model, "--robot", "KR16-R1610"), run, "P310", model, message="trained on robot KR500-sim")
    assert run(GOOD, model, "--robot", "KR16-R1610", "--force", "-q")[0] == 0
    anonymous = affine(robot="")
    refused(run(GOOD, anonymous, "--robot", "KR16"), run, "P310", anonymous, message="does not say which robot")


def test_double_compensation_is_refused_unless_forced(run, affine, tmp_path):
    model = affine(offset=(0.1, 0, 0))
    status, _, once = run(GOOD, model, "-q")
    assert status == 0 and "2000.100" in once
    refused(run(once, model), run, "P401", run.src(), 1, 1, "already compensated")
    status, _, twice = run(once, model, "--force", "-q")
    assert status == 0 and "2000.200" in twice


# --------------------------------------------------------------------------- not a compensator


def _save(tmp_path, name, graph, **meta):
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    for key, value in meta.items():
        model.metadata_props.add(key=key, value=value)
    path = tmp_path / name
    onnx.save(model, path)
    return path


def _slice_graph(in_name="pose", out_name="error", in_type=TensorProto.FLOAT, in_shape=("N", 6), out_shape=("N", 3),
                 stop=3):
    """error = pose[:, 0:stop] with the given names, types and declared shapes."""
    inits = [numpy_helper.from_array(np.array([v], np.int64), n) for n, v in (("s0", 0), ("s1", stop), ("ax", 1))]
    return helper.make_graph([helper.make_node("Slice", [in_name, "s0", "s1", "ax"], [out_name])], "g",
                             [helper.make_tensor_value_info(in_name, in_type, list(in_shape))],
                             [helper.make_tensor_value_info(out_name, in_type, list(out_shape) if out_shape else None)],
                             inits)


@pytest.mark.parametrize("graph, message", [
    (_slice_graph(in_name="x"), r"no input 'pose' \(has \['x'\]\)"),
    (_slice_graph(out_name="y"), r"no output 'error' \(has \['y'\]\)"),
    (_slice_graph(in_shape=("N", 7)), r"input 'pose' has shape \['N', 7\], expected \[N, 6\]"),
    (_slice_graph(in_shape=(1, 6), out_shape=(1, 3)), r"input 'pose' has shape \[1, 6\]"),
    (_slice_graph(out_shape=("N", 6), stop=6), r"output 'error' has shape \['N', 6\], expected \[N, 3\]"),
    (_slice_graph(in_type=TensorProto.DOUBLE), r"'pose' is tensor\(double\), expected tensor\(float\)"),
])
def test_onnx_file_that_is_not_a_compensator(run, tmp_path, graph, message):
    model = _save(tmp_path, "wrong.onnx", graph)
    refused(run(GOOD, model), run, "P306", model, message="not a postproc compensator: " + message)


def test_model_that_fails_or_lies_about_its_shape_at_run_time(run, tmp_path):
    # declared [N, 3] but really [N, 2]: the contract check cannot see it, the run does
    lies = _save(tmp_path, "lies.onnx", _slice_graph(stop=2))
    refused(run(GOOD, lies), run, "P306", lies, message=r"model returned shape \(2, 2\), expected \(2, 3\)")
    # a graph that only runs on one pose (Reshape to [1, 6]) fails on the program's two
    shape = numpy_helper.from_array(np.array([1, 6], np.int64), "shape")
    inits = [shape] + [numpy_helper.from_array(np.array([v], np.int64), n) for n, v in (("s0", 0), ("s1", 3), ("ax", 1))]
    graph = helper.make_graph([helper.make_node("Reshape", ["pose", "shape"], ["one"]),
                               helper.make_node("Slice", ["one", "s0", "s1", "ax"], ["error"])], "g",
                              [helper.make_tensor_value_info("pose", TensorProto.FLOAT, ["N", 6])],
                              [helper.make_tensor_value_info("error", TensorProto.FLOAT, ["N", 3])], inits)
    fails = _save(tmp_path, "fails.onnx", graph)
    refused(run(GOOD, fails), run, "P306", fails, message="the model failed on 2 poses")


@pytest.mark.parametrize("content, message", [
    (b"", "not an ONNX model"),
    (b"not onnx at all", "not an ONNX model"),
    (b"\x08\x07\x12\x04junk\x3a\x02\x0a\x00", "not an ONNX model"),
])
def test_file_that_is_not_onnx(run, tmp_path, content, message):
    model = tmp_path / "junk.onnx"
    model.write_bytes(content)
    refused(run(GOOD, model), run, "P306", model, message=message)


def test_missing_model(run, tmp_path):
    refused(run(GOOD, tmp_path / "none.onnx"), run, "P307", tmp_path / "none.onnx", message="model not found")


@pytest.mark.parametrize("key, value, message", [
    ("envelope", '{"box": [1, 2]}', "'envelope' needs box"),
    ("envelope", '{"box": [2300, 1700, -600, 600, 500, 1300], "attitude": [0, 90, 0], "range": 10}',
     "lower bound above its upper bound"),
    ("reach", '{"center": "x", "radius_max": 2700}', "'reach' needs center"),
    ("reach", '{"center": [0, 0, 0], "radius_max": "NaN"}', "'reach' needs center"),
    ("tool", '{"name": "t", "frame": [0, 0, 200]}', "'tool' frame must be"),
    ("iterations", "1000000000", "'iterations' must be a whole number from 1 to 100"),
])
def test_malformed_model_card(run, tmp_path, key, value, message):
    # these crashed (KeyError, ValueError) or hung (10^9 iterations) before they were checked at load
    model = _save(tmp_path, "card.onnx", _slice_graph(stop=3), **{key: value})
    refused(run(GOOD, model), run, "P306", model, message=r"model card \(metadata_props\) is malformed: .*" + re.escape(message))


def test_model_name_cannot_break_the_stamp_line(run, affine):
    # the name goes into the stamp comment: a newline would have put model text into the program
    model = affine(name="cell 7\nPTP {X 0} ;模型")
    status, err, written = run(GOOD, model, "-q")
    assert status == 0, err
    first, second = written.splitlines()[:2]
    assert first.startswith("# postproc: compensated with model cell 7\\nPTP {X 0} ;\\u6a21\\u578b ")
    assert second == "name,x,y,z,a,b,c"


# --------------------------------------------------------------------------- where the output goes


def test_output_that_cannot_be_written(run, affine, tmp_path):
    status, err, _ = run(GOOD, affine(), output=run.out_dir)
    assert status == 2 and err.strip() == f"{run.out_dir}: P110 is a directory: give -o a file name"
    blocker = tmp_path / "file"
    blocker.write_text("x")
    status, err, _ = run(GOOD, affine(), output=blocker / "sub" / "out.csv")
    assert status == 2 and f"P110 cannot write: {blocker} is not a directory" in err
    assert list(run.out_dir.iterdir()) == [] and blocker.read_text() == "x"


# --------------------------------------------------------------------------- the last checks


KRL_FRAME_VARIABLE = ("DEF cell( )\r\nLIN XP1\r\n$BASE = XP1\r\nLIN XP2\r\nEND\r\n",
                      "DEFDAT cell\r\nDECL E6POS XP1={X 1900.0,Y 0.0,Z 900.0,A 0.0,B 90.0,C 0.0}\r\n"
                      "DECL E6POS XP2={X 10.0,Y 20.0,Z 30.0,A 0.0,B 0.0,C 0.0}\r\nENDDAT\r\n")


def krl_run(tmp_path, capsys, src, dat, model, *options, output="cell.src"):
    """Compensate cell.src/.dat into tmp_path/out/``output``: (exit code, stderr, files in out/)."""
    (tmp_path / "cell.src").write_text(src, newline="")
    (tmp_path / "cell.dat").write_text(dat, newline="")
    out = tmp_path / "out"
    out.mkdir(exist_ok=True)
    code = main(["compensate", str(tmp_path / "cell.src"), "-o", str(out / output), "--model", str(model), *options,
                 "--base", "0", "--tool", "model"])  # (made-up programs that set no $BASE/$TOOL: stated, as a user would)
    return code, capsys.readouterr().err, sorted(p.name for p in out.iterdir())


def test_position_used_as_a_frame_is_not_compensated(tmp_path, capsys, affine):
    # XP1 is a motion target and, after it, the base of XP2: correcting XP1's numbers would
    # move XP2 by the same amount (and XP2's own correction on top): XP1 is left as written
    # (P217, at its declaration), XP2 compensated in the base XP1 is
    model = affine(offset=(0.3, -0.2, 0.1), tool={"name": "any"})
    code, err, written = krl_run(tmp_path, capsys, *KRL_FRAME_VARIABLE, model)
    assert code == 1 and written == ["cell.dat", "cell.src"]
    assert err.startswith(f"{tmp_path / 'cell.dat'}:2:16: P217 this target's numbers (moved to at "
                          f"{tmp_path / 'cell.src'}:2) are read at {tmp_path / 'cell.src'}:4 too (a frame)")  # each line
    dat = (tmp_path / "out" / "cell.dat").read_text()
    assert "XP1={X 1900.0,Y 0.0,Z 900.0," in dat and "XP2={X 9.900,Y 19.800,Z 30.300," in dat
    # the same with XP1 as the tool
    src = KRL_FRAME_VARIABLE[0].replace("$BASE = XP1", "$TOOL = XP1")
    code, err, written = krl_run(tmp_path, capsys, src, KRL_FRAME_VARIABLE[1], model)
    assert code == 1 and "P217" in err and "XP1={X 1900.0,Y 0.0,Z 900.0," in (tmp_path / "out" / "cell.dat").read_text()
    # used as a frame only (not a motion target), XP1 stays as it is and XP2 is compensated in it
    src = KRL_FRAME_VARIABLE[0].replace("LIN XP1\r\n", "")
    code, err, written = krl_run(tmp_path, capsys, src, KRL_FRAME_VARIABLE[1], model, "-q")
    assert code == 0 and written == ["cell.dat", "cell.src"]
    dat = (tmp_path / "out" / "cell.dat").read_text()
    # base XP1 is turned by B = 90 (Ry(90)): the robot-base offset (0.3, -0.2, 0.1) is
    # Ry(90)ᵀ·offset = (-0.1, -0.2, 0.3) in it
    assert "XP1={X 1900.0,Y 0.0,Z 900.0," in dat and "XP2={X 9.900,Y 19.800,Z 30.300," in dat


@pytest.mark.parametrize("number", ["1.5E+3.0", "1e+5.0", "20e+00.5"])
def test_malformed_number_is_refused_whichever_check_sees_it(tmp_path, capsys, affine, number):
    # the KRL reader took the digits after 'e+' for the number (Z 1.5E+3.0 read as 3.0 with
    # its span on '1.5'): the last check refuses it (P190) if the reader does not (P101)
    src = f"DEF cell( )\nLIN {{X 2000.0,Y 0.0,Z {number}}}\nEND\n"
    dat = "DEFDAT cell\nENDDAT\n"
    code, err, written = krl_run(tmp_path, capsys, src, dat, affine(tool={"name": "any"}))
    assert code == 2 and written == [], err
    assert re.match(rf"{re.escape(str(tmp_path / 'cell.src'))}:2:\d+: P(101|190) ", err), err


def test_formatter_bug_is_refused(run, affine, monkeypatch):
    import postproc.compensation.commands

    real = postproc.compensation.commands.format_many

    def off_by_two_microns(tokens, values, unit=1.0):
        return real(tokens, values + np.where(np.arange(len(values)) == 4, 0.002, 0.0), unit)

    monkeypatch.setattr(postproc.compensation.commands, "format_many", off_by_two_microns)
    refused(run(GOOD, affine(offset=(0.1, 0, 0))), run, "P190", run.src(), 3, 1,
            r"the number '100\.002' does not read back as the corrected 100\.0")


def test_program_too_large_for_memory_is_refused_before_reading(run, affine, monkeypatch):
    import postproc.programs.io

    monkeypatch.setattr(postproc.programs.io, "_available_bytes", lambda: 1_000)  # 1 kB left
    refused(run(GOOD, affine()), run, "P111", run.src(),
            message=r"too large to compensate here: 0 MB of program needs about 0\.0 GB of memory, 0\.0 GB are available")
    monkeypatch.setattr(postproc.programs.io, "_available_bytes", lambda: None)  # not known: go ahead
    assert run(GOOD, affine(), "-q")[0] == 0


def test_robot_from_the_settings(run, affine, tmp_path):
    model = affine(robot="KR500-sim")
    settings = tmp_path / "postproc.toml"
    settings.write_text('robot = "KR16-R1610"\n')
    refused(run(GOOD, model, "--settings", str(settings)), run, "P310", model, message="the program is for KR16-R1610")
    # the option overrides the settings; --force overrides both
    assert run(GOOD, model, "--settings", str(settings), "--robot", "KR500-sim", "-q")[0] == 0
    assert run(GOOD, model, "--settings", str(settings), "--force", "-q")[0] == 0
    settings.write_text("robot = 500\n")
    refused(run(GOOD, model, "--settings", str(settings)), run, "P610", settings, 1, 1, message="expected the robot's name")


def test_non_finite_frame_or_float32_overflow_is_refused(tmp_path, capsys, run, affine):
    # a base with an infinite angle: its targets used to be skipped as 'not fully known'
    src = "DEF cell( )\n$BASE = {X 0.0,Y 0.0,Z 0.0,A 1E999,B 0.0,C 0.0}\nLIN {X 10.0,Y 0.0,Z 900.0}\nEND\n"
    code, err, written = krl_run(tmp_path, capsys, src, "DEFDAT cell\nENDDAT\n", affine(tool={"name": "any"}))
    assert code == 2 and written == [] and re.match(rf"{re.escape(str(tmp_path / 'cell.src'))}:\d+:\d+: P103 ", err)
    # finite in float64, infinite for the model's float32 input
    text = GOOD.replace("P2,2100.000,100.000,950.000,1,89,0", "P2,2100.000,100.000,950.000,1e300,89,0")
    refused(run(text, affine()), run, "P103", run.src(), 3, 1, "too large for the model")


def test_position_used_in_two_frames_is_left_where_the_runs_disagree(tmp_path, capsys, affine):
    src = ("DEF cell( )\n$BASE = {X 0.0,Y 0.0,Z 0.0,A 0.0,B 0.0,C 0.0}\nLIN XP1\n"
           "$BASE = {X 0.0,Y 0.0,Z 0.0,A 180.0,B 0.0,C 0.0}\nLIN XP1\nEND\n")
    dat = "DEFDAT cell\nDECL E6POS XP1={X 1900.0,Y 0.0,Z 900.0,A 0.0,B 90.0,C 0.0}\nENDDAT\n"
    model = affine(offset=(0.3, -0.2, 0.1), tool={"name": "any"})
    code, err, written = krl_run(tmp_path, capsys, src, dat, model)
    # in the base turned by 180° the same correction is (−0.3, 0.2, 0.1) in XP1's numbers
    assert code == 1 and err.count("P230 this target runs more than once") == 1
    assert "need corrections up to 0.600 mm apart" in err
    assert "XP1={X 1900.0,Y 0.0,Z 900.0," in (tmp_path / "out" / "cell.dat").read_text()
    assert "0 of 1 compensated, 1 left as written: P230 ×1" in err
    # in one frame the two runs agree: compensated once
    same = src.replace("A 180.0", "A 0.0")
    code, err, written = krl_run(tmp_path, capsys, same, dat, model, "-q")
    assert code == 0 and "XP1={X 1900.300,Y -0.200,Z 900.100," in (tmp_path / "out" / "cell.dat").read_text()


def test_module_files_onto_one_path_are_refused(tmp_path, capsys, affine):
    # '-o x.dat' for a .src: the .dat would overwrite the .src just written
    code, err, written = krl_run(tmp_path, capsys, "DEF cell( )\nLIN XP1\nEND\n",
                                 "DEFDAT cell\nDECL E6POS XP1={X 1900.0,Y 0.0,Z 900.0}\nENDDAT\n",
                                 affine(tool={"name": "any"}), output="x.dat")
    out = tmp_path / "out"
    assert code == 2 and err.startswith(f"{out / 'x.dat'}: P110 two files of the program would both be written")
    assert written == []

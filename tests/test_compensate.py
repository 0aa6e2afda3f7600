"""The compensate pipeline on pose programs and hand-built frames; CLI exit codes."""
import re
import subprocess
import sys

import numpy as np
import pytest

from postproc.cli import main
from postproc.compensation.pipeline import compensate_program
from postproc.compensation.api import compensate_text
from postproc.programs.base_poses import robot_base_poses
from postproc.model.compensator import load_model
from postproc.programs import ActiveFrames
from postproc.core.diagnostics import PostprocError
from postproc.programs import STAMP_PREFIX

from helpers import REPO, program_in_base

CSV = "# part\r\nname,x,y,z,a,b,c,feed\r\nP1,1950.1,12.5,880,0,90,0,100\r\nP2,2001.250,-12.5,900.,2,88,1,120\r\n"


def without_stamp(text):
    return "".join(line for line in text.splitlines(keepends=True) if STAMP_PREFIX not in line)


def test_zero_model_changes_nothing_but_the_stamp(affine):
    out, report = compensate_text(CSV, affine(), name="p.csv")
    assert report.compensated == 2
    # the numbers are rewritten in their style (≥ 3 decimals) but keep their values
    assert without_stamp(out) == CSV.replace("1950.1,12.5,880,", "1950.100,12.500,880.000,").replace(
        ",-12.5,900.,", ",-12.500,900.000,")
    assert out.splitlines()[0] == f"# {STAMP_PREFIX} test-model {load_model(affine()).sha256[:12]}"


def test_constant_offset_moves_exactly_xyz(affine):
    out, report = compensate_text(CSV, affine(offset=(0.25, -0.5, 1.0)), name="p.csv")
    rows = [line.split(",") for line in without_stamp(out).splitlines()[2:]]
    assert [list(map(float, r[1:4])) for r in rows] == [[1950.35, 12.0, 881.0], [2001.5, -13.0, 901.0]]
    assert [r[4:] for r in rows] == [["0", "90", "0", "100"], ["2", "88", "1", "120"]]
    assert report.max_correction_mm == pytest.approx(np.linalg.norm([0.25, 0.5, 1.0]), abs=1e-6)


def test_fixed_point_solves_c_equals_p_plus_error_of_c(affine):
    gain = np.array([[2e-3, 0, 0], [0, -1e-3, 5e-4], [0, 0, 3e-3]])
    centre = np.array([2000.0, 0.0, 900.0])
    offset = np.array([0.3, -0.2, 0.1])
    model = load_model(affine(offset=offset, gain=gain, centre=centre))
    p = np.array([[2100.0, 300.0, 1000.0, 0, 90, 0]])
    # c = p + offset + G (c − centre)  ⇔  (I − G) c = p + offset − G centre
    exact = np.linalg.solve(np.eye(3) - gain, p[0, :3] + offset - gain @ centre)
    assert np.allclose(model.command(p, iterations=8)[0], exact, atol=1e-4)
    one_step = p[0, :3] + offset + gain @ (p[0, :3] - centre)
    assert np.allclose(model.command(p, iterations=1)[0], one_step, atol=1e-4)


def test_correction_is_mapped_back_into_the_program_base(affine):
    # base turned 90° about Z: a robot-base correction (0.3, −0.2, 0.1) is (−0.2, −0.3, 0.1) in it
    program = program_in_base([1800, -400, 600, 90, 0, 0], [300.0, -100.0, 200.0, 0, 90, 0])
    poses, resolved = robot_base_poses(program)
    assert resolved.all() and np.allclose(poses[0, :3], [1800 + 100, -400 + 300, 800])
    report = compensate_program(program, load_model(affine(offset=(0.3, -0.2, 0.1))))
    values = report.outputs["p.csv"].splitlines()[-1].split(",")
    assert np.allclose(list(map(float, values)), [299.8, -100.3, 200.1], atol=1e-9)


def test_refuses_double_compensation_unless_forced(affine):
    model = affine(offset=(0.1, 0, 0))
    once, _ = compensate_text(CSV, model, name="p.csv")
    with pytest.raises(PostprocError) as info:
        compensate_text(once, model, name="p.csv")
    assert info.value.code == "P401" and info.value.line == 1
    twice, _ = compensate_text(once, model, name="p.csv", force=True)
    assert "1950.300" in twice


def test_outside_envelope_warns_and_strict_refuses(affine):
    text = "x,y,z,a,b,c\n2000,0,900,0,90,0\n1000,0,900,0,90,0\n"
    model = affine()
    _, report = compensate_text(text, model, name="p.csv")
    assert [(w.code, w.line) for w in report.warnings] == [("P301", 3)]
    with pytest.raises(PostprocError) as info:
        compensate_text(text, model, name="p.csv", strict=True)
    assert (info.value.code, info.value.line) == ("P301", 3)


def test_beyond_reach_is_an_error(affine):
    with pytest.raises(PostprocError) as info:
        compensate_text("x,y,z,a,b,c\n2000,0,900,0,90,0\n5000,0,900,0,90,0\n", affine(), name="p.csv")
    assert (info.value.code, info.value.line) == ("P302", 3)


def test_implausible_or_nan_corrections_are_refused(affine):
    with pytest.raises(PostprocError) as info:
        compensate_text(CSV, affine(offset=(6.0, 0, 0)), name="p.csv")
    assert info.value.code == "P303"
    with pytest.raises(PostprocError) as info:
        compensate_text(CSV, affine(offset=(float("nan"), 0, 0)), name="p.csv")
    assert info.value.code == "P305"


def test_missing_orientation_takes_nominal_attitude_with_warning(affine):
    _, report = compensate_text("2000 0 900\n", affine(offset=(0.1, 0, 0)), name="p.txt")
    assert report.compensated == 1 and [w.code for w in report.warnings] == ["P213"]


def test_not_a_compensator(tmp_path, affine):
    junk = tmp_path / "junk.onnx"
    junk.write_bytes(b"not onnx at all")
    with pytest.raises(PostprocError, match="not an ONNX model"):
        load_model(junk)
    import onnx
    from onnx import TensorProto, helper

    g = helper.make_graph([helper.make_node("Identity", ["x"], ["y"])], "g",
                          [helper.make_tensor_value_info("x", TensorProto.FLOAT, ["N", 6])],
                          [helper.make_tensor_value_info("y", TensorProto.FLOAT, ["N", 6])])
    wrong = tmp_path / "wrong.onnx"
    m = helper.make_model(g, opset_imports=[helper.make_opsetid("", 17)])
    m.ir_version = 8
    onnx.save(m, wrong)
    with pytest.raises(PostprocError, match="no input 'pose'.*no output 'error'"):
        load_model(wrong)
    with pytest.raises(PostprocError, match="P307 model not found"):
        load_model(tmp_path / "missing.onnx")


def test_cli_exit_codes_and_nothing_written_on_error(tmp_path, affine, capsys):
    src = tmp_path / "p.csv"
    src.write_bytes(CSV.encode())
    out = tmp_path / "out.csv"
    model = str(affine(offset=(0.1, 0, 0)))
    assert main(["compensate", str(src), "-o", str(out), "--model", model, "-q"]) == 0
    first = out.read_bytes()
    assert capsys.readouterr().err == ""
    # a second run on the compensated output refuses: exit 2, message with location, nothing written
    again = tmp_path / "again.csv"
    assert main(["compensate", str(out), "-o", str(again), "--model", model]) == 2
    assert capsys.readouterr().err.startswith(f"{out}:1:1: P401 ")
    assert not again.exists()
    # bad input does not touch an existing output
    bad = tmp_path / "bad.csv"
    bad.write_text("x,y,z\n1,zz,3\n")
    assert main(["compensate", str(bad), "-o", str(out), "--model", model]) == 2
    assert f"{bad}:2:3: P103" in capsys.readouterr().err
    assert out.read_bytes() == first
    for content, code in [(b"", "P105"), (b"\x00\x01binary", "P106")]:
        bad.write_bytes(content)
        assert main(["compensate", str(bad), "-o", str(out), "--model", model]) == 2
        assert code in capsys.readouterr().err
    assert main(["compensate", str(tmp_path / "nope.csv"), "-o", str(out), "--model", model]) == 2
    assert main(["compensate", str(src), "-o", str(out), "--model", str(tmp_path / "none.onnx")]) == 2
    assert out.read_bytes() == first


def test_stdin_to_stdout_filter(affine):
    model = str(affine(offset=(0.1, 0, 0)))
    run = subprocess.run([sys.executable, "-m", "postproc", "compensate", "-", "-o", "-", "--model", model, "-q"],
                         input=CSV.encode(), capture_output=True, cwd=REPO)
    assert run.returncode == 0, run.stderr
    assert run.stderr == b""
    assert b"1950.200,12.500,880.000" in run.stdout and run.stdout.endswith(b",120\r\n")


def test_robot_base_keeps_the_written_attitude_when_the_base_does_not_rotate():
    # B = 95 is the same rotation as (A+180, 85, C+180); the numbers as written must reach the model
    program = program_in_base([100, 0, 0, 0, 0, 0], [2000.0, 0.0, 900.0, 3.0, 95.0, -2.0])
    poses, _ = robot_base_poses(program)
    assert np.allclose(poses[0], [2100, 0, 900, 3, 95, -2])


def test_reader_says_when_targets_are_variables():
    # compensate reads a program with variables again before writing (guards.check_round_trip)
    from postproc.programs.io import load_program

    assert load_program(REPO / "samples/krl/cam_pocket.src").named_targets is False
    assert load_program(REPO / "samples/krl/weld_cell.src", REPO / "samples/krl/config/$config.dat").named_targets


def test_batches_run_in_parallel_give_the_one_call_result(affine):
    gain = np.array([[2e-3, 0, 0], [0, -1e-3, 5e-4], [0, 0, 3e-3]])
    model = load_model(affine(offset=(0.3, -0.2, 0.1), gain=gain))
    rng = np.random.default_rng(3)
    poses = np.c_[rng.uniform(1800, 2200, (1000, 3)), np.zeros((1000, 3))]
    whole = model.predict(poses)
    model.predict_batch = 64  # 16 batches on a thread pool
    assert np.array_equal(model.predict(poses), whole)
    expected = np.array([0.3, -0.2, 0.1]) + (poses[:, :3] - [2000, 0, 900]) @ gain.T
    assert np.allclose(whole, expected, atol=1e-4)


def _cam_path(n: int, seed: int = 0) -> np.ndarray:
    """n poses along a CAM-like path in the shipped model's envelope (program order)."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 6 * np.pi, n)
    return np.c_[2000 + 200 * np.cos(t), 400 * np.sin(t), np.linspace(600, 1200, n),
                 rng.uniform(-3, 3, n), 90 + rng.uniform(-3, 3, n), rng.uniform(-3, 3, n)]


def test_commands_in_chunks_equal_the_whole_program_fixed_point():
    # the shipped model chains each target to its predecessor's command (backlash): a chunk
    # border must carry the last command of every iteration over, or its first target's
    # approach direction (and so its correction) would change
    model = load_model()
    assert model.wants_previous
    # (the plain fixed point: a model with an ``approach`` input then settles a few targets on
    # their approach, chunk by chunk too: tests/test_approach.py)
    model.settle = False
    poses = _cam_path(300)
    trial = poses.copy()
    for _ in range(model.default_iterations):  # the fixed point written out, whole program at once
        trial[:, :3] = poses[:, :3] + model.predict(trial, np.vstack([trial[:1], trial[:-1]]))
    # 64 rows: onnxruntime's float32 atan2 gives a row ~1e-4 mm apart in a batch's SIMD tail,
    # so chunks are a multiple of the vector width, as the default command_chunk and predict_batch are
    model.command_chunk = 64
    chunks = list(model.command_chunks(poses))
    assert [start for start, _, _ in chunks] == list(range(0, 300, 64))
    assert np.allclose(model.command(poses), trial[:, :3], rtol=0, atol=1e-9)
    # a chunk that ignored its predecessor (took its first row as coming from itself) differs
    alone = model.command(poses[64:128])
    assert np.abs(alone - trial[64:128, :3]).max() > 1e-3


def test_rewrite_overlapping_the_model_writes_what_one_pass_writes(monkeypatch):
    import postproc.compensation.commands as commands
    poses = _cam_path(500, seed=1)
    text = "DEF cam()\n" + "".join(
        "LIN {X %.3f,Y %.3f,Z %.3f,A %.3f,B %.3f,C %.3f} C_VEL\n" % tuple(p) for p in poses) + "END\n"
    stated = ActiveFrames(base=0, tool="model")  # (a made-up CAM program that sets neither)
    whole, report = compensate_text(text, name="cam.src", active=stated)
    model = load_model()
    model.command_chunk = 16  # 32 model chunks
    monkeypatch.setattr(commands, "EDIT_CHUNK", 50)  # 30 rewrite chunks waiting on them
    chunked, again = compensate_text(text, model, name="cam.src", active=stated)
    assert chunked == whole and again.max_correction_mm == report.max_correction_mm
    assert report.compensated == 500 and whole != text


def test_a_guard_failing_in_a_late_chunk_names_the_worst_target(affine, monkeypatch):
    import postproc.compensation.commands as commands
    # E = 0.01·(x − 2000): 0 … 3 mm along the program, largest at its last line
    xs = np.linspace(2000, 2300, 200)
    text = "x,y,z,a,b,c\n" + "".join(f"{x:.3f},0,900,0,90,0\n" for x in xs)
    model = affine(gain=np.diag([1e-2, 0, 0]), centre=(2000.0, 0.0, 900.0))
    model = load_model(model)
    model.command_chunk = 8
    monkeypatch.setattr(commands, "EDIT_CHUNK", 6)
    with pytest.raises(PostprocError) as info:
        compensate_text(text, model, name="p.csv", max_correction_mm=2.0)
    assert (info.value.code, info.value.line) == ("P303", 201)
    assert "correction of 3.0" in info.value.message


def test_shipped_model_outputs_the_controllers_joint_angles():
    # the graph's own IK, exported as ``joints``: the nominal robot's (Pinocchio model) IK
    from postproc.robot.arm import Robot
    from postproc.robot.description import load_description

    model = load_model()
    assert model.has_joints and model.envelope.joints.shape == (6, 2)
    poses = _cam_path(200, seed=2)
    error, q = model.predict(poses, joints=True)
    assert np.array_equal(error, model.predict(poses))
    expected, ok = Robot(load_description()).ik(poses)
    assert ok.all() and np.abs(q - expected).max() < 2e-3  # deg (float32 output)


def _with_joint_ranges(tmp_path, ranges):
    """The shipped model with other trained joint ranges in its card."""
    import json

    import onnx

    from postproc.core.resources import model_path

    graph = onnx.load(str(model_path()))
    prop = next(p for p in graph.metadata_props if p.key == "envelope")
    envelope = json.loads(prop.value)
    envelope["joints"] = ranges
    prop.value = json.dumps(envelope)
    path = tmp_path / "narrow.onnx"
    onnx.save(graph, str(path))
    return path


def test_targets_outside_the_trained_joint_ranges_warn(tmp_path):
    from postproc.compensation.check import check_files

    trained = load_model().envelope.joints.tolist()
    narrow = [list(r) for r in trained]
    narrow[0] = [-2.0, 2.0]  # A1 trained only near 0: the box's sides (A1 ≈ ±11°) lie outside
    model = load_model(_with_joint_ranges(tmp_path, narrow))
    text = "x,y,z,a,b,c\n2000,0,900,0,90,0\n2000,400,900,0,90,0\n2000,-20,900,0,90,0\n"
    new, report = compensate_text(text, model, name="p.csv")
    assert [(w.code, w.line) for w in report.warnings] == [("P301", 3)]
    # (KUKA's A1 turns about the downward axis: +Y is a negative A1)
    assert re.search(r"joint angles outside .* \(A1 -11\.\d°, trained -2\.0…2\.0°\)$", report.warnings[0].message)
    assert report.outside_envelope == 1 and new.count("\n") == text.count("\n") + 1
    with pytest.raises(PostprocError) as info:
        compensate_text(text, model, name="p.csv", strict=True)
    assert (info.value.code, info.value.line) == ("P301", 3)
    path = tmp_path / "p.csv"
    path.write_text(text)
    assert [(d.code, d.line) for d in check_files([path], model) if d.severity != "note"] == [("P301", 3)]
    # the trained ranges themselves: nothing to say
    assert compensate_text(text, load_model(), name="p.csv")[1].warnings == []


def test_malformed_joint_ranges_in_the_card_are_refused(tmp_path):
    with pytest.raises(PostprocError) as info:
        load_model(_with_joint_ranges(tmp_path, [[0, 1]] * 5))
    assert info.value.code == "P306" and "joints" in info.value.message

"""Streaming compensate (postproc/compensation/streaming.py): the same bytes and refusals as the in-memory path,
a chunk of targets at a time (chunks made small here: COMMAND_CHUNK, the unit both paths batch by)."""
import numpy as np
import pytest

from postproc.testing.models import affine_model, joint_model
from postproc.model import compensator
from postproc.compensation import streaming
from postproc.cli import main
from postproc.compensation.streaming import compensate_file
from postproc.core.diagnostics import PostprocError
from postproc.robot.arm import Robot

GAIN = np.array([[0.3, -0.2, 0.5, 0.1, 0.4, -0.3],
                 [0.1, 0.4, -0.2, 0.3, -0.5, 0.2],
                 [-0.4, 0.2, 0.3, -0.1, 0.2, 0.5]])  # mm per unit sin(q)
HEADER = ("&ACCESS RVP\r\n&REL 1\r\nDEF cam()\r\n;CAM output\r\n$BASE={X 0.0,Y 0.0,Z 0.0,A 0.0,B 0.0,C 0.0}\r\n"
          "$TOOL={X 300.0,Y 0.0,Z 75.0,A 0.0,B 0.0,C 0.0}\r\n$VEL.CP=0.2\r\n")


def cam_program(n: int, seed: int = 0, newline: str = "\n", ptp: bool = False, extra: dict | None = None,
                flip: bool = False) -> str:
    """A CAM-style module: n motion lines in runs broken by blank and comment lines; with ``ptp``
    some PTP lines without S/T and some with (``flip``: the wrist flipped, which the LIN after
    them keep); ``extra`` maps a line index to a line put there."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 6 * np.pi, n)
    x, y, z = 2000 + 200 * np.cos(t), 400 * np.sin(t), 700 + 400 * np.linspace(0, 1, n)
    a, b, c = rng.uniform(-3, 3, n), 90 + rng.uniform(-3, 3, n), rng.uniform(-3, 3, n)
    lines = []
    robot = Robot()
    for i in range(n):
        if i in (extra or {}):
            lines.append(extra[i])
        if i % 11 == 5:
            lines.append("" if i % 2 else "; next run")
        motion = "PTP" if ptp and i % 7 == 3 else "LIN"
        st = ""
        if ptp and i % 14 == 3:  # the S/T of the branch nearest HOME (the default model's own)
            q, _ = robot.ik(np.array([[x[i], y[i], z[i], a[i], b[i], c[i]]]), robot.home_q)
            if flip:  # the same pose, the wrist flipped
                q = q + np.array([0, 0, 0, 180.0, 0, 180.0]) * [1, 1, 1, 1, 0, 1]
                q[:, 4] *= -1
                q[:, 3:6:2] = (q[:, 3:6:2] + 180.0) % 360.0 - 180.0
            status, turn = robot.status_turn(q)
            st = f",S {int(status[0])},T {int(turn[0])}"
        lines.append(f"{motion} {{X {x[i]:.3f},Y {y[i]:.3f},Z {z[i]:.3f},A {a[i]:.3f},B {b[i]:.3f},C {c[i]:.2f}{st}}}"
                     + (" C_VEL" if motion == "LIN" else ""))
    return (HEADER.replace("\r\n", newline) + newline.join(lines) + newline + "END" + newline).replace("\r\r", "\r")


@pytest.fixture
def small_chunks(monkeypatch):
    monkeypatch.setattr(compensator, "COMMAND_CHUNK", 7)


def _both(tmp_path, text: str, model, **kwargs):
    src = tmp_path / "cam.src"
    src.write_bytes(text.encode("latin-1"))
    memory = compensate_file(src, tmp_path / "memory.src", model, stream=False, **kwargs)
    streamed = compensate_file(src, tmp_path / "streamed.src", model, stream=True, **kwargs)
    return memory, streamed, (tmp_path / "memory.src").read_bytes(), (tmp_path / "streamed.src").read_bytes()


def _models(tmp_path):
    return {"default": None,
            "joints": compensator.load_model(joint_model(tmp_path / "j.onnx", GAIN)),
            "previous": compensator.load_model(affine_model(tmp_path / "a.onnx", offset=(0.2, -0.1, 0.3),
                                                            gain=np.diag([0.004, -0.003, 0.002]),
                                                            previous_input=True,
                                                            tool={"name": "spindle", "frame": [300, 0, 75, 0, 0, 0]}))}


@pytest.mark.parametrize("name", ["default", "joints", "previous"])
@pytest.mark.parametrize("newline,ptp", [("\n", False), ("\r\n", True)])
def test_streaming_writes_the_in_memory_bytes(tmp_path, small_chunks, name, newline, ptp):
    model = _models(tmp_path)[name]
    text = cam_program(60, newline=newline, ptp=ptp, flip=ptp and name == "joints")
    memory, streamed, want, got = _both(tmp_path, text, model)
    assert streamed.outputs == {} and memory.outputs  # (one streamed, the other not)
    assert memory.compensated == 60 and memory.complete
    assert got == want
    assert streamed.summary() == memory.summary()


def test_a_guard_failing_in_a_late_chunk_leaves_nothing_and_is_located(tmp_path, small_chunks, monkeypatch):
    from postproc.compensation import commands

    real = commands.format_many
    calls = []

    def broken(tokens, values, unit=1.0):
        calls.append(len(tokens))
        out = real(tokens, values, unit)
        if len(calls) == 6:  # the 6th chunk's first X: off by 1 mm
            out[0] = f"{float(out[0]) + 1:.3f}"
        return out

    monkeypatch.setattr(commands, "format_many", broken)
    src = tmp_path / "cam.src"
    text = cam_program(60)
    src.write_text(text)
    with pytest.raises(PostprocError) as err:
        compensate_file(src, tmp_path / "out.src", stream=True)
    assert err.value.code == "P190"
    # the 6th chunk's first target: the 36th motion line of the file
    motion_lines = [i + 1 for i, line in enumerate(text.splitlines()) if line.startswith("LIN")]
    assert err.value.line == motion_lines[35]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cam.src"]


def test_an_error_in_a_late_chunk_is_the_in_memory_paths_and_nothing_is_written(tmp_path, small_chunks):
    far = "LIN {X 2000.0,Y 0.0,Z 3900.0,A 0.0,B 90.0,C 0.0} C_VEL"  # beyond reach: P302
    src = tmp_path / "cam.src"
    src.write_text(cam_program(60, extra={50: far}))
    errors = []
    for stream in (False, True):
        with pytest.raises(PostprocError) as err:
            compensate_file(src, tmp_path / "out.src", stream=stream)
        errors.append(str(err.value))
    assert errors[0] == errors[1] and "P302" in errors[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cam.src"]


@pytest.mark.parametrize("line", [
    "LIN {X 1500.0,Y 0.0,Z 900.0,A 0.0,B 90.0,C 0.0} C_VEL",  # outside the envelope: a P301 warning
    "LIN {X 2000.0,Z 900.0} C_VEL",  # a partial aggregate, filled from the previous target
    "$BASE={X 10.0,Y 0.0,Z 0.0,A 0.0,B 0.0,C 0.0}",  # a frame set inside the body
    "sub()",  # a call
])
def test_what_the_stream_does_not_carry_is_compensated_in_memory(tmp_path, small_chunks, line):
    memory, streamed, want, got = _both(tmp_path, cam_program(40, extra={30: line}),
                                        _models(tmp_path)["previous"])
    assert streamed.outputs  # (fell back)
    assert got == want
    assert [w.format() for w in streamed.warnings] == [w.format() for w in memory.warnings]


def test_large_programs_stream_by_default_through_the_cli(tmp_path, small_chunks, monkeypatch):
    src = tmp_path / "cam.src"
    src.write_text(cam_program(30))
    monkeypatch.setattr(streaming, "STREAM_BYTES", 100)
    used = []
    real = streaming.compensate_stream
    monkeypatch.setattr(streaming, "compensate_stream", lambda *a, **k: used.append(1) or real(*a, **k))
    assert main(["compensate", str(src), "-o", str(tmp_path / "out.src"), "-q"]) == 0
    assert used
    monkeypatch.setattr(streaming, "STREAM_BYTES", 1 << 30)
    assert main(["compensate", str(src), "-o", str(tmp_path / "mem.src"), "-q"]) == 0
    assert len(used) == 1
    assert (tmp_path / "out.src").read_bytes() == (tmp_path / "mem.src").read_bytes()


def test_chunks_smaller_than_the_models_write_the_same_bytes(tmp_path, monkeypatch):
    # a model that does not settle (the shipped one does): chunks of STREAM_TARGETS, a multiple
    # of the model's batch, each row computed in the batch the in-memory path computes it in
    monkeypatch.setattr(compensator, "COMMAND_CHUNK", 32)
    monkeypatch.setattr(compensator, "PREDICT_BATCH", 8)
    monkeypatch.setattr(streaming, "STREAM_TARGETS", 8)
    chunks = []
    real = streaming._Source.chunks
    monkeypatch.setattr(streaming._Source, "chunks", lambda self: (chunks.append(self.size), *real(self))[1:])
    model = _models(tmp_path)["previous"]
    assert not model.settles
    memory, streamed, want, got = _both(tmp_path, cam_program(70), model)
    assert chunks == [8] and streamed.outputs == {}
    assert got == want


def test_a_chunks_error_stands_where_the_program_is_too_large_for_memory(tmp_path, small_chunks, monkeypatch):
    from postproc.programs import io

    def too_large(paths):
        raise PostprocError("too large", str(paths[0]), 0, 0, "P111")

    far = "LIN {X 2000.0,Y 0.0,Z 3900.0,A 0.0,B 90.0,C 0.0} C_VEL"  # beyond reach: P302
    src = tmp_path / "cam.src"
    text = cam_program(60, extra={50: far})
    src.write_text(text)
    monkeypatch.setattr(io, "check_memory", too_large)
    with pytest.raises(PostprocError) as err:
        compensate_file(src, tmp_path / "out.src", stream=False)
    assert err.value.code == "P111"
    with pytest.raises(PostprocError) as err:
        compensate_file(src, tmp_path / "out.src", stream=True)
    assert err.value.code == "P302" and err.value.line == text.splitlines().index(far) + 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cam.src"]

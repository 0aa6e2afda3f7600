"""$ROBROOT, the robot's base in $WORLD, for KRL programs that do not set it: stated
(--robroot, settings `robroot`), from a controller backup's machine data (Mada/$machine.dat:
$ROBROOT_C; $EX_KIN … #ERSYS: a robot on a track, P225), or assumed = world and said once
(P224, a note: exit 0 stays 0)."""
import re

import numpy as np
import pytest

from postproc.cli import main
from postproc.core.diagnostics import PostprocError
from postproc.core.frames import compose, frame_to_matrix, inverse, matrix_to_frame
from postproc.programs.krl.machine import robroot_of
from postproc.compensation.streaming import compensate_stream

# a correction that varies over space: where the targets are in the model matters
GAIN = np.array([[1e-3, 2e-3, 0.0], [-2e-3, 0.0, 3e-3], [0.0, 1e-3, -2e-3]])
TOOL = {"name": "torch", "frame": [300.0, 0.0, 75.0, 0.0, 0.0, 0.0]}
ROBROOT = (150.0, -80.0, 400.0, 30.0, 0.0, 0.0)  # a robot on a pedestal, turned
BASE_RB = (1850.0, -300.0, 650.0, 0.0, 0.0, 0.0)  # the workpiece's base in the robot base
POSES = [(100.0, 300.0, 300.0), (200.0, 250.0, 250.0), (250.0, 450.0, 150.0), (150.0, 350.0, 350.0)]


def _frame(six) -> str:
    return "{" + ",".join(f"{k} {v:.6f}" for k, v in zip("XYZABC", six)) + "}"


def _world_base() -> tuple:
    return tuple(matrix_to_frame(compose(frame_to_matrix(np.array(ROBROOT)), frame_to_matrix(np.array(BASE_RB)))))


def program(base, extra="") -> str:
    lines = "".join(f"  LIN {{X {x},Y {y},Z {z},A 0.0,B 90.0,C 0.0}}\n" for x, y, z in POSES)
    return (f"DEF job( )\n  $TOOL={_frame(TOOL['frame'])}\n  $BASE={_frame(base)}\n{extra}{lines}END\n")


def machine(robroot=ROBROOT, kin="#NONE") -> str:
    return ("&ACCESS RV\nDEFDAT  $MACHINE PUBLIC\n;FOLD robot in world\n"
            f"FRAME $ROBROOT_C={_frame(robroot)}\n;ENDFOLD\n"
            f"DECL EX_KIN $EX_KIN={{ET1 {kin},ET2 #NONE,ET3 #NONE,ET4 #NONE,ET5 #NONE,ET6 #NONE}}\nENDDAT\n")


def xyz(text: str) -> np.ndarray:
    return np.array([[float(v) for v in m] for m in re.findall(r"LIN \{X ([-\d.]+),Y ([-\d.]+),Z ([-\d.]+)", text)])


@pytest.fixture
def backup(tmp_path):
    """KRC/R1/{Program/job.src, System/$config.dat, Mada/$machine.dat}: the program's base in $WORLD."""
    r1 = tmp_path / "KRC" / "R1"
    for sub in ("Program", "System", "Mada"):
        (r1 / sub).mkdir(parents=True)
    (r1 / "Program" / "job.src").write_text(program(_world_base()))
    (r1 / "System" / "$config.dat").write_text("DEFDAT $CONFIG PUBLIC\nDECL GLOBAL FRAME TOOL_DATA[16]\nENDDAT\n")
    (r1 / "Mada" / "$machine.dat").write_text(machine())
    return r1


@pytest.fixture
def model(affine):
    return str(affine(gain=GAIN, tool=TOOL))


def compensate(*args) -> int:
    return main(["compensate", *map(str, args)])


def test_machine_data_puts_the_targets_where_the_robot_is(backup, model, tmp_path, capsys):
    src = backup / "Program" / "job.src"
    # the reference: the same targets with their base given in the robot base, robroot null
    reference = tmp_path / "rb.src"
    reference.write_text(program(BASE_RB))
    assert compensate(reference, "-o", tmp_path / "rb_out.src", "--model", model, "--robroot", "0,0,0,0,0,0") == 0
    expected = xyz((tmp_path / "rb_out.src").read_text())
    # the backup directory (Mada/$machine.dat found), one .src with the backup's System/$config.dat,
    # and the same frame stated: the corrections of the robot base, in the program's own base
    assert compensate(backup, "-o", tmp_path / "cell", "--model", model) == 0
    assert compensate(src, "-o", tmp_path / "one.src", "--model", model, "--config",
                      backup / "System" / "$config.dat") == 0
    assert compensate(src, "-o", tmp_path / "stated.src", "--model", model, "--robroot", ",".join(map(str, ROBROOT))) == 0
    assert "P224" not in capsys.readouterr().err
    for out in (tmp_path / "cell" / "Program" / "job.src", tmp_path / "one.src", tmp_path / "stated.src"):
        np.testing.assert_allclose(xyz(out.read_text()), expected, atol=2e-3)
    # robot base = world assumed: other corrections (the model evaluated elsewhere, the vector turned)
    assert compensate(src, "-o", tmp_path / "assumed.src", "--model", model) == 0
    written = np.array(POSES)
    assumed = xyz((tmp_path / "assumed.src").read_text()) - written
    assert np.abs(assumed - (expected - written)).max() > 0.1
    # the Mada/$machine.dat is read, never written
    assert not (tmp_path / "cell" / "Mada").exists()
    # check finds it the same ways: the directory, the .src with --config; without either, the note
    assert main(["check", str(backup), "--model", model]) == 0
    assert main(["check", str(src), "--model", model, "--config", str(backup / "System" / "$config.dat")]) == 0
    assert capsys.readouterr().out == ""
    assert main(["check", str(src), "--model", model]) == 0
    assert " P224 " in capsys.readouterr().out


def test_the_assumption_is_said_once_and_exit_0_stays(model, tmp_path, capsys):
    src = tmp_path / "job.src"  # (no backup: nothing tells $ROBROOT)
    src.write_text(program(BASE_RB))
    assert compensate(src, "-o", tmp_path / "a.src", "--model", model) == 0
    err = capsys.readouterr().err
    assert "P224" in err.splitlines()[-1] and len(err.splitlines()) == 1  # the summary says it; the note with -v
    assert compensate(src, "-o", tmp_path / "b.src", "--model", model, "-v", "--strict") == 0
    notes = [line for line in capsys.readouterr().err.splitlines() if " P224 " in line]
    assert len(notes) == 1 and notes[0].startswith(f"{src}:4:7: P224 robot base = world assumed")
    assert main(["check", str(src), "--model", model, "--strict"]) == 0
    captured = capsys.readouterr()
    assert [line.split(" ")[1] for line in captured.out.splitlines()] == ["P224"]
    assert "clean (1 note)" in captured.err
    assert main(["check", str(src), "--model", model, "--ignore", "P224"]) == 0
    assert capsys.readouterr().out == ""


def test_a_program_that_sets_robroot_needs_no_machine_data(model, tmp_path, capsys):
    src = tmp_path / "own.src"
    src.write_text(program(_world_base(), extra=f"  $ROBROOT={_frame(ROBROOT)}\n"))
    assert compensate(src, "-o", tmp_path / "own_out.src", "--model", model, "-v") == 0
    assert "P224" not in capsys.readouterr().err
    reference = tmp_path / "rb.src"
    reference.write_text(program(BASE_RB))
    assert compensate(reference, "-o", tmp_path / "rb_out.src", "--model", model, "--robroot", "0,0,0,0,0,0") == 0
    np.testing.assert_allclose(xyz((tmp_path / "own_out.src").read_text()), xyz((tmp_path / "rb_out.src").read_text()),
                               atol=2e-3)


def test_a_robot_on_a_track_is_left_as_written(backup, model, tmp_path, capsys):
    (backup / "Mada" / "$machine.dat").write_text(machine(kin="#ERSYS"))
    assert compensate(backup, "-o", tmp_path / "cell", "--model", model) == 1
    err = capsys.readouterr().err
    (warning, *files, summary) = err.splitlines()
    assert warning.startswith(f"{backup / 'Program' / 'job.src'}:4:7: P225") and "ET1 #ERSYS" in warning
    assert "4 left as written: P225 ×4" in summary
    assert f"postproc:   {tmp_path / 'cell' / 'Program' / 'job.src'}: 0 of 4 compensated, 4 left as written" in files
    assert (tmp_path / "cell" / "Program" / "job.src").read_text() == (backup / "Program" / "job.src").read_text()
    # the track parked where the user says: stated, compensated
    assert compensate(backup, "-o", tmp_path / "cell2", "--model", model, "--robroot", ",".join(map(str, ROBROOT))) == 0


def test_robroot_inputs_that_are_not_a_frame_are_refused(backup, model, tmp_path, capsys):
    src = backup / "Program" / "job.src"
    for bad in ("1,2,3", "1,2,3,4,5,x", "nowhere.dat", "1,2,3,4,5,inf"):
        assert compensate(src, "-o", tmp_path / "x.src", "--model", model, "--robroot", bad) == 2
        assert "P226" in capsys.readouterr().err
    (backup / "Mada" / "$machine.dat").write_text("DEFDAT $MACHINE PUBLIC\nFRAME $ROBROOT_C={X 0.0,Y 0.0,Z 1.5}\nENDDAT\n")
    assert compensate(backup, "-o", tmp_path / "cell", "--model", model) == 2
    assert "$machine.dat:2:19: P226 $ROBROOT_C lacks A, B, C" in capsys.readouterr().err
    assert not (tmp_path / "cell").exists()


def test_settings_robroot_is_a_frame_or_machine_data(backup, model, tmp_path, monkeypatch, capsys):
    src = backup / "Program" / "job.src"
    assert compensate(src, "-o", tmp_path / "stated.src", "--model", model, "--robroot", ",".join(map(str, ROBROOT))) == 0
    monkeypatch.chdir(tmp_path)
    (tmp_path / "postproc.toml").write_text('robroot = "KRC/R1/Mada/$machine.dat"\n')
    assert compensate(src, "-o", tmp_path / "set.src", "--model", model) == 0
    assert (tmp_path / "set.src").read_text() == (tmp_path / "stated.src").read_text()
    # the command line wins over the settings
    assert compensate(src, "-o", tmp_path / "null.src", "--model", model, "--robroot", "0,0,0,0,0,0") == 0
    assert (tmp_path / "null.src").read_text() != (tmp_path / "stated.src").read_text()
    (tmp_path / "postproc.toml").write_text('robroot = [0, 0, 400]\n')
    assert compensate(src, "-o", tmp_path / "bad.src", "--model", model) == 2
    assert "P610" in capsys.readouterr().err


def test_pose_lists_are_in_the_robot_base_whatever_robroot(model, tmp_path):
    poses = tmp_path / "p.csv"
    poses.write_text("x,y,z,a,b,c\n" + "".join(f"{1900 + x},{y},{700 + z},0,90,0\n" for x, y, z in POSES))
    assert compensate(poses, "-o", tmp_path / "a.csv", "--model", model) == 0
    assert compensate(poses, "-o", tmp_path / "b.csv", "--model", model, "--robroot", ",".join(map(str, ROBROOT))) == 0
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()


def test_streaming_says_it_once(model, tmp_path):
    src = tmp_path / "cam.src"
    body = "".join(f"LIN {{X {1900 + i},Y {i},Z 800.0,A 0.0,B 90.0,C 0.0}} C_VEL\n" for i in range(7))
    src.write_text(f"DEF cam( )\n$TOOL={_frame(TOOL['frame'])}\n$BASE={{X 0,Y 0,Z 0,A 0,B 0,C 0}}\n{body}END\n")
    report = compensate_stream(src, tmp_path / "out.src", model, chunk=2)
    assert report.compensated == 7 and [(n.code, n.line) for n in report.notes] == [("P224", 4)]


def test_machine_data_forms():
    assert robroot_of("DECL FRAME $ROBROOT_C={X 1.5E+02,Y -.5,Z 0,A 90.,B 0.0,C -180.0}\n", "m").frame == (
        150.0, -0.5, 0.0, 90.0, 0.0, -180.0)
    # an older machine data ($ROBROOT); $ROBROOT_C first where both are
    assert robroot_of("FRAME $ROBROOT={X 1,Y 2,Z 3,A 0,B 0,C 0}\n", "m").frame == (1, 2, 3, 0, 0, 0)
    assert robroot_of("FRAME $ROBROOT={X 1,Y 2,Z 3,A 0,B 0,C 0}\nFRAME $ROBROOT_C={X 4,Y 5,Z 6,A 0,B 0,C 0}\n",
                      "m").frame == (4, 5, 6, 0, 0, 0)
    # a comment is not a declaration
    with pytest.raises(PostprocError, match="no \\$ROBROOT_C") as e:
        robroot_of(";FRAME $ROBROOT_C={X 1,Y 2,Z 3,A 0,B 0,C 0}\n", "m")
    assert e.value.code == "P226"
    with pytest.raises(PostprocError, match="not a frame") as e:
        robroot_of("FRAME $ROBROOT_C={X 1,Y 2,Z 3,A 0,B 0,X 0}\n", "m")
    track = robroot_of("FRAME $ROBROOT_C={X 0,Y 0,Z 0,A 0,B 0,C 0}\nDECL EX_KIN $EX_KIN={ET1 #NONE,ET2 #ERSYS}\n", "m")
    assert track.frame is None and "ET2 #ERSYS" in track.why
    # (the frames of the transform tests above are each other's inverse)
    np.testing.assert_allclose(compose(inverse(frame_to_matrix(np.array(ROBROOT))), frame_to_matrix(np.array(_world_base()))),
                               frame_to_matrix(np.array(BASE_RB)), atol=1e-9)

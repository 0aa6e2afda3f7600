"""Double compensation is refused at its line (issue 27): a program postproc stamped already (P401,
at the stamp), and a KRL program of a controller backup whose machine data switch on the
controller's own absolute-accuracy model ($ABS_ACCUR in Mada/$machine.dat or $custom.dat: P408;
#SUPPRESSED: P409, a warning); --force overrides both. Real cells' points carry S 18 (bit 4 set),
which decides nothing here."""
import shutil

import numpy as np
import pytest
from helpers import REPO

from postproc.cli import main
from postproc.core.diagnostics import PostprocError
from postproc.programs.krl.machine import accuracy_model, backup_accuracy

GAIN = np.array([[1e-3, 2e-3, 0.0], [-2e-3, 0.0, 3e-3], [0.0, 1e-3, -2e-3]])
CUSTOM = "&ACCESS RV\nDEFDAT  $CUSTOM PUBLIC\n;FOLD absolute accuracy\n{line}\n;ENDFOLD\nENDDAT\n"


@pytest.fixture
def model(affine):
    return str(affine(gain=GAIN, tool={"name": "spindle", "frame": [300.0, 0.0, 75.0, 0.0, 0.0, 0.0]}))


@pytest.fixture
def backup(tmp_path):
    """The shipped sample backup (a robot on a pedestal), copied: its points with S 18."""
    r1 = tmp_path / "KRC" / "R1"
    shutil.copytree(REPO / "samples" / "krl" / "backup" / "KRC" / "R1", r1)
    dat = r1 / "Program" / "pedestal.dat"
    dat.write_text(dat.read_text().replace("S 2,T 35", "S 18,T 35"))  # bit 4 set, as real cells' points
    return r1


def _one(r1) -> list[str]:
    """One module of the backup, with the backup's $config.dat."""
    return [str(r1 / "Program" / "pedestal.src"), "--config", str(r1 / "System" / "$config.dat")]


def _custom(r1, line: str):
    (r1 / "Mada" / "$custom.dat").write_text(CUSTOM.format(line=line))
    return r1 / "Mada" / "$custom.dat"


def test_a_backup_without_the_model_compensates(backup, model, tmp_path):
    assert main(["compensate", str(backup), "-o", str(tmp_path / "out"), "--model", model, "-q"]) == 0
    assert backup_accuracy([backup / "Program" / "pedestal.src"]) is None


@pytest.mark.parametrize("line", ["DECL ABS_ACCUR_STATE $ABS_ACCUR=#ACTIVATED", "BOOL $ABS_ACCUR=TRUE"])
def test_the_controllers_accuracy_model_active_is_refused_at_its_line(backup, model, tmp_path, capsys, line):
    custom = _custom(backup, line)
    for target in ([str(backup)], _one(backup)):  # a whole cell, and one module of the backup
        out = tmp_path / ("cell" if len(target) == 1 else "one.src")
        assert main(["compensate", *target, "-o", str(out), "--model", model]) == 2
        err = capsys.readouterr().err
        assert f"{custom}:4:" in err and " P408 " in err and "compensated twice" in err
        assert not out.exists()
    assert main(["check", *_one(backup), "--model", model]) == 1
    assert " P408 " in capsys.readouterr().out
    # --force: the user says the controller's model is off where the program runs
    assert main(["compensate", *_one(backup), "-o", str(tmp_path / "forced.src"), "--model", model, "--force",
                 "-q"]) == 0
    written = (tmp_path / "forced.src").read_text()
    assert "LIN {X 100.0,Y 300.0" not in written and "compensated with model" in written


def test_the_machine_data_states_it_too(backup, model, tmp_path, capsys):
    machine = backup / "Mada" / "$machine.dat"
    machine.write_text(machine.read_text().replace(";ENDFOLD\nENDDAT", ";ENDFOLD\nBOOL $ABS_ACCUR=TRUE\nENDDAT"))
    assert main(["compensate", *_one(backup), "-o", str(tmp_path / "o.src"), "--model", model]) == 2
    assert f"{machine}:11:" in capsys.readouterr().err


def test_suppressed_is_a_warning(backup, model, tmp_path, capsys):
    custom = _custom(backup, "DECL ABS_ACCUR_STATE $ABS_ACCUR=#SUPPRESSED")
    assert main(["compensate", *_one(backup), "-o", str(tmp_path / "o.src"), "--model", model]) == 0
    assert main(["compensate", *_one(backup), "-o", str(tmp_path / "s.src"), "--model", model, "--strict"]) == 2
    assert f"{custom}:4:" in capsys.readouterr().err


@pytest.mark.parametrize("line", ["DECL ABS_ACCUR_STATE $ABS_ACCUR=#NONE", "BOOL $ABS_ACCUR=FALSE",
                                  ";BOOL $ABS_ACCUR=TRUE"])
def test_off_or_commented_out_is_no_finding(backup, model, tmp_path, line):
    _custom(backup, line)
    assert main(["compensate", *_one(backup), "-o", str(tmp_path / "o.src"), "--model", model, "-q"]) == 0


def test_forms_of_the_variable():
    assert accuracy_model("BOOL $ABS_ACCUR=TRUE\n", "m").state == "active"
    assert accuracy_model("DECL ABS_ACCUR_STATE $ABS_ACCUR = #activated ; on\n", "m").state == "active"
    assert accuracy_model("BOOL $ABS_ACCUR=TRUE\nBOOL $SUPPRESS_ABS_ACCUR=TRUE\n", "m").state == "suppressed"
    assert accuracy_model("$ABS_ACCUR=#NONE\n", "m") is None and accuracy_model("X=1\n", "m") is None
    with pytest.raises(PostprocError, match="none of TRUE") as info:
        accuracy_model("\nDECL ABS_ACCUR_STATE $ABS_ACCUR=#MAYBE\n", "m.dat")
    assert (info.value.line, info.value.col, info.value.code) == (2, 33, "P408")


def test_a_stamped_program_is_refused_at_the_stamp(model, tmp_path, capsys):
    src = REPO / "samples" / "krl" / "cam_pocket.src"
    once = tmp_path / "once.src"
    assert main(["compensate", str(src), "-o", str(once), "--model", model, "-q"]) == 0
    stamp_line = next(i for i, text in enumerate(once.read_text().splitlines(), 1) if "postproc: compensated" in text)
    assert stamp_line > 1  # (below the module's header)
    assert main(["compensate", str(once), "-o", str(tmp_path / "twice.src"), "--model", model]) == 2
    assert f"{once}:{stamp_line}:" in capsys.readouterr().err and not (tmp_path / "twice.src").exists()

"""The one output-path rule (postproc.core.outputs), through every subcommand that writes a file:
checked before the work, P110, exit 2, nothing written; -o equal to the input refused."""
import os

import pytest

from postproc.cli import main
from postproc.core.diagnostics import PostprocError
from postproc.core.outputs import check_outputs
from postproc.programs.io import check_program_outputs

from helpers import REPO

SAMPLE = REPO / "samples" / "krl" / "cam_pocket.src"
IPA = REPO / "samples" / "ipa" / "series_c_excerpt.csv"


def _p110(capsys, argv):
    status = main(argv)
    err = capsys.readouterr().err
    assert status == 2, err
    assert " P110 " in err and "internal error" not in err, err
    return err


@pytest.fixture
def plan(tmp_path):
    path = tmp_path / "plan.csv"
    path.write_text("x,y,z,a,b,c\n2000,0,900,0,90,0\n")
    return path


@pytest.fixture
def never_read(monkeypatch):
    """The work must not start: reading the data fails the test."""
    import postproc.measurements.csv as measurements

    def fail(*a, **k):
        raise AssertionError("read the data before checking the output path")

    monkeypatch.setattr(measurements, "read_measurements", fail)


def test_a_directory_is_refused_by_every_subcommand_before_the_work(capsys, tmp_path, plan, never_read):
    folder = tmp_path / "folder"
    folder.mkdir()
    for argv in (["plan", "-n", "5", "-o", str(folder)],
                 ["plan", "-n", "5", "-o", str(tmp_path / "p.csv"), "--krl", str(folder)],
                 ["measure", str(plan), "-o", str(folder)],
                 ["train", str(plan), "-o", str(folder)],  # never_read: refused before the fit
                 ["import", "ipa", str(IPA), "-o", str(folder)],
                 ["compensate", str(SAMPLE), "-o", str(folder)]):
        err = _p110(capsys, argv)
        assert err.strip() == f"{folder}: P110 is a directory: give -o a file name"
    assert sorted(os.listdir(tmp_path)) == ["folder", "plan.csv"] and not os.listdir(folder)


def test_the_output_equal_to_the_input_is_refused_unless_in_place(capsys, tmp_path, plan, never_read):
    before = plan.read_bytes()
    for argv in (["measure", str(plan), "-o", str(plan)], ["train", str(plan), "-o", str(plan)]):
        err = _p110(capsys, argv)
        assert "is the input" in err and "--in-place" not in err  # no such option there
    assert plan.read_bytes() == before

    src = tmp_path / "cam_pocket.src"
    src.write_bytes(SAMPLE.read_bytes())
    link = tmp_path / "link.src"
    link.symlink_to(src)
    for out in (src, tmp_path / "missing" / ".." / "cam_pocket.src", link):  # also through a link
        err = _p110(capsys, ["compensate", str(src), "-o", str(out)])
        assert "is the input" in err and "(or --in-place to overwrite it)" in err
    assert src.read_bytes() == SAMPLE.read_bytes()
    assert main(["compensate", str(src), "-o", str(src), "--in-place", "-q"]) == 0
    assert src.read_bytes() != SAMPLE.read_bytes() and b"; postproc: compensated" in src.read_bytes()


def test_the_dat_beside_is_part_of_the_rule(tmp_path):
    src, dat = tmp_path / "weld.src", tmp_path / "weld.dat"
    src.write_text("DEF weld()\nEND\n")
    dat.write_text("DEFDAT weld\nENDDAT\n")
    with pytest.raises(PostprocError, match="two files of the program would both be written"):
        check_program_outputs(src, tmp_path / "out.dat")  # the .src and the .dat onto out.dat
    with pytest.raises(PostprocError, match="is the input"):  # the output's .dat is the input's
        check_program_outputs(src, tmp_path / "sub" / ".." / "weld.src")
    assert check_program_outputs(src, tmp_path / "out" / "weld.src") == [tmp_path / "out" / "weld.src",
                                                                         tmp_path / "out" / "weld.dat"]
    assert check_program_outputs("-", "-") == []


def test_missing_folders_are_created_and_unwritable_ones_refused(tmp_path):
    assert check_outputs([tmp_path / "a" / "b" / "m.onnx"]) == [tmp_path / "a" / "b" / "m.onnx"]
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(PostprocError, match="is not a directory") as info:
        check_outputs([blocker / "sub" / "out.csv"])
    assert info.value.code == "P110"
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    if os.geteuid() != 0:  # root writes anywhere
        with pytest.raises(PostprocError, match="no permission"):
            check_outputs([locked / "new" / "out.csv"])


def test_train_creates_a_missing_folder_like_plan_and_compensate(tmp_path):
    """The export used to refuse a missing folder (P500) after the fit; now one rule creates it."""
    from postproc.model.training.export import write_atomic

    path = write_atomic(tmp_path / "new" / "deeper" / "m.onnx", b"bytes")
    assert path.read_bytes() == b"bytes"


def test_a_write_that_fails_is_p110_not_an_internal_error(tmp_path, monkeypatch):
    from postproc.core import atomic, outputs

    def full(outputs):
        raise OSError(28, "No space left on device", str(tmp_path / "x.csv"))

    monkeypatch.setattr(atomic, "write_atomic", full)
    with pytest.raises(PostprocError, match="No space left on device") as info:
        outputs.write([(tmp_path / "x.csv", "x")])
    assert info.value.code == "P110" and info.value.path == str(tmp_path / "x.csv")

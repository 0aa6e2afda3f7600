"""Honest results of `postproc compensate`, through the CLI: exit 0 only when every
Cartesian target was compensated, 1 when the output was written with targets left as
written (the summary line says how many and why), 2 refused with nothing written; a file
in which nothing changed gets no stamp."""
import numpy as np
import pytest

from postproc.cli import main
from postproc.compensation.api import compensate_text
from postproc.programs import STAMP_PREFIX

from helpers import REPO
from postproc.programs import ActiveFrames

# made-up programs that set no $BASE/$TOOL: stated, as a user would (--base 0 --tool model)
STATED = ActiveFrames(base=0, tool="model")

GAIN = np.diag([1e-3, 2e-3, -1e-3])  # a correction that varies over space
# 2 targets in a base the reader knows, then 2 after a BAS call whose BASE_DATA is unknown
SRC = """DEF mixed()
  LIN {X 2000.0,Y 0.0,Z 900.0,A 0.0,B 90.0,C 0.0}
  LIN {X 2050.0,Y 20.0,Z 910.0,A 0.0,B 90.0,C 0.0}
  BAS(#BASE, 3)
  LIN {X 10.0,Y 0.0,Z 100.0,A 0.0,B 90.0,C 0.0}
  LIN {X 20.0,Y 0.0,Z 100.0,A 0.0,B 90.0,C 0.0}
END
"""


@pytest.fixture
def cli(tmp_path, capsys):
    def go(*args):
        code = main(["compensate", *map(str, args), "--base", "0", "--tool", "model"])  # (made-up programs that set no $BASE/$TOOL: stated, as a user would)
        captured = capsys.readouterr()
        return code, captured.out, captured.err
    return go


def test_all_compensated_is_exit_0(tmp_path, affine, cli):
    src = tmp_path / "a.src"
    src.write_text(SRC.split("  BAS")[0] + "END\n")
    code, _, err = cli(src, "-o", tmp_path / "out.src", "--model", affine(offset=(0.1, 0, 0), gain=GAIN))
    assert code == 0, err
    assert err.startswith("postproc: 2 of 2 compensated; model test-model")


def test_targets_left_as_written_are_exit_1_with_the_output_written(tmp_path, affine, cli):
    src = tmp_path / "a.src"
    src.write_text(SRC)
    out = tmp_path / "out.src"
    code, _, err = cli(src, "-o", out, "--model", affine(offset=(0.1, 0, 0), gain=GAIN))
    assert code == 1, err
    assert "P201" in err and "postproc: 2 of 4 compensated, 2 left as written: P201 ×2; model test-model" in err
    text = out.read_text()
    assert text.startswith(f"; {STAMP_PREFIX} test-model ")
    assert "LIN {X 10.0,Y 0.0,Z 100.0" in text and "LIN {X 2000.0," not in text
    # --strict refuses instead: exit 2, nothing written
    out.unlink()
    code, _, err = cli(src, "-o", out, "--model", affine(), "--strict")
    assert code == 2 and "P201" in err and not out.exists()


def test_a_tool_not_known_is_counted_by_its_code(tmp_path, affine, cli):
    src = tmp_path / "a.src"
    src.write_text(SRC.replace("BAS(#BASE, 3)", "BAS(#TOOL, 6)"))
    code, _, err = cli(src, "-o", tmp_path / "out.src", "--model", affine(offset=(0.1, 0, 0), gain=GAIN))
    assert code == 1 and "a.src:4:3: P203" in err, err
    assert "2 of 4 compensated, 2 left as written: P203 ×2;" in err


def test_nothing_compensated_writes_the_input_unchanged_and_unstamped(tmp_path, affine, cli):
    # weld_cell without its $config.dat: every target's BASE_DATA is unknown
    src = REPO / "samples/krl/weld_cell.src"
    code, _, err = cli(src, "-o", tmp_path / "w.src", "--model", affine(gain=GAIN))
    assert code == 1
    assert "0 of 19 compensated, 19 left as written: P201 ×19" in err
    assert "nothing changed: the output is the input as it was, unstamped" in err
    assert (tmp_path / "w.src").read_bytes() == src.read_bytes()
    assert (tmp_path / "w.dat").read_bytes() == src.with_suffix(".dat").read_bytes()


def test_a_cam_filter_still_gets_its_program_on_stdout(tmp_path, affine, capfdbinary, monkeypatch):
    import io
    import sys

    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(SRC.encode())))
    code = main(["compensate", "-", "-o", "-", "--model", str(affine(gain=GAIN)), "--base", "0", "--tool", "model"])
    out = capfdbinary.readouterr().out
    assert code == 1 and out.count(STAMP_PREFIX.encode()) == 1 and b"LIN {X 10.0,Y 0.0" in out


def test_only_files_that_changed_are_stamped(tmp_path, affine):
    # the .dat holds only an axis position: nothing in it is compensated, so no stamp
    dat = "DEFDAT m\n  DECL E6AXIS XHOME={A1 0,A2 -90,A3 90,A4 0,A5 0,A6 0}\nENDDAT\n"
    src = "DEF m()\n  PTP XHOME\n  LIN {X 2000.0,Y 0.0,Z 900.0,A 0.0,B 90.0,C 0.0}\nEND\n"
    text, report = compensate_text(src, affine(gain=GAIN), name="m.src", dat_text=dat, active=STATED)
    assert report.changed == ["m.src"] and report.complete and report.codes == []
    assert report.outputs["m.dat"] == dat and STAMP_PREFIX in text
    # and check accepts the pair (the unstamped .dat is no P404)
    from postproc.compensation.check import check_program
    from postproc.programs.io import parse_program_text
    from postproc.model.compensator import load_model

    program = parse_program_text(text, "m.src", dat_text=dat, active=STATED)
    assert [d.code for d in check_program(program, load_model(affine(gain=GAIN)))] == ["P224"]  # (a note only)


def test_report_counts_and_codes(affine):
    _, report = compensate_text(SRC, affine(gain=GAIN), name="a.src", active=STATED)
    assert (report.targets, report.compensated, report.left, report.left_codes) == (4, 2, 2, {"P201": 2})
    assert report.codes == ["P201"] and not report.complete

"""Progress bars: shown stage by stage when asked for, silent otherwise (not a terminal, -q)."""
from __future__ import annotations

import sys

import pytest

from postproc.cli import main
from postproc.core.progress import stages


def test_stages_show_each_stage_then_clear_the_line(capsys):
    with stages(["read", "fit", "write"], "train", True) as start:
        for name in ("read", "fit", "write"):
            start(name)
    err = capsys.readouterr().err
    assert [name in err for name in ("train", "read", "fit", "write")] == [True] * 4
    assert "1/3" in err and "2/3" in err and err.endswith("\r")  # counted, then cleared (leave=False)


def test_disabled_stages_write_nothing_and_do_not_load_tqdm(capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "tqdm", None)  # an import of tqdm would raise
    with stages(["a", "b"], "plan", False) as start:
        start("a")
        start("b")
    assert capsys.readouterr().err == ""


def test_errors_propagate_through_a_bar():
    with pytest.raises(ValueError), stages(["a"], "measure", True) as start:
        start("a")
        raise ValueError("bad plan")


@pytest.mark.parametrize("quiet", [[], ["-q"]])
def test_plan_and_measure_off_a_terminal_print_no_bar(tmp_path, capsys, quiet):
    # pytest's captured stderr is not a terminal: one summary line each (none with -q), no bar
    plan, measured = tmp_path / "plan.csv", tmp_path / "m.csv"
    assert main(["plan", "-n", "50", "-o", str(plan), *quiet]) == 0
    assert main(["measure", str(plan), "-o", str(measured), *quiet]) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == (0 if quiet else 2) and "\r" not in err and "measure " not in err


def _terminal(monkeypatch):
    """stderr as a terminal and no delay before a bar shows (the run here is short)."""
    import postproc.core.progress as progress

    monkeypatch.setattr(sys.stderr, "isatty", lambda: True, raising=False)
    monkeypatch.setattr(progress, "DELAY_S", 0.0)
    monkeypatch.setattr(progress, "REFRESH_S", 0.0)  # (every update drawn: the last count shows)


def test_compensate_counts_its_targets_on_a_terminal_and_nothing_with_q(tmp_path, capsys, monkeypatch):
    import numpy as np

    xyz = np.random.default_rng(0).uniform([1800, -400, 600], [2200, 400, 1200], (3000, 3))
    src = tmp_path / "cam.src"
    src.write_text("DEF cam( )\n" + "".join(f"  LIN {{X {x:.3f},Y {y:.3f},Z {z:.3f},A 0,B 90,C 0}}\n"
                                             for x, y, z in xyz) + "END\n")
    _terminal(monkeypatch)
    assert main(["compensate", str(src), "-o", str(tmp_path / "out.src"), "--base", "0", "--tool", "model"]) in (0, 1)
    err = capsys.readouterr().err
    assert "compensate" in err and "3.00k/3.00k" in err and "target" in err  # the bar counted every target
    assert main(["compensate", str(src), "-o", str(tmp_path / "out2.src"), "-q", "--base", "0", "--tool", "model"]) in (0, 1)
    assert "\r" not in capsys.readouterr().err  # -q: no bar
    assert (tmp_path / "out.src").read_text() == (tmp_path / "out2.src").read_text()  # the bar changes nothing


def test_ctrl_c_exits_130_with_nothing_written(tmp_path, capsys, monkeypatch):
    import postproc.compensation.pipeline as compensate

    src = tmp_path / "cam.src"
    src.write_text("DEF cam( )\n  LIN {X 2000,Y 0,Z 900,A 0,B 90,C 0}\nEND\n")

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(compensate, "_finish", interrupted)  # Ctrl-C just before the texts are complete
    assert main(["compensate", str(src), "-o", str(tmp_path / "out" / "cam.src"), "--base", "0", "--tool", "model"]) == 130
    assert "interrupted" in capsys.readouterr().err
    assert not (tmp_path / "out" / "cam.src").exists()

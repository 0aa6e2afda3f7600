"""Progress bars: shown stage by stage when asked for, silent otherwise (not a terminal, -q)."""
from __future__ import annotations

import sys

import pytest

from postproc.cli import main
from postproc.progress import stages


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

"""A plan keeps its tool (issue 38, item 2): `plan --tool X,Y,Z,A,B,C` (one tool) writes it in the plan
(`# tool:`), and `measure plan.csv` simulates that tool as getting-started.md writes the command —
it used to simulate the description's tool while the measurement program used the given one, without
a word; a --tool that contradicts the plan is refused at the plan."""
from __future__ import annotations

import numpy as np

from postproc.cli import main
from postproc.measurements.csv import read_measurements, read_metadata


def test_measure_simulates_the_tool_the_plan_was_made_for(tmp_path, capsys):
    plan = tmp_path / "plan.csv"
    assert main(["plan", "-n", "30", "--seed", "4", "--tool", "250,0,0,0,0,0", "-o", str(plan), "-q"]) == 0
    assert read_metadata(plan)["tool"] == "250,0,0,0,0,0"
    assert main(["measure", str(plan), "-o", str(tmp_path / "m.csv"), "-q"]) == 0
    assert main(["measure", str(plan), "-o", str(tmp_path / "given.csv"), "--tool", "250,0,0,0,0,0", "-q"]) == 0
    m, given = read_measurements(tmp_path / "m.csv"), read_measurements(tmp_path / "given.csv")
    assert np.array_equal(m.measured, given.measured) and read_metadata(tmp_path / "m.csv")["tool"] == "250,0,0,0,0,0"
    # the description's tool gives other measurements of the same poses (the tool shapes them)
    bare = tmp_path / "bare.csv"
    plan.write_text("".join(line for line in plan.read_text().splitlines(True) if not line.startswith("#")))
    assert main(["measure", str(plan), "-o", str(bare), "-q"]) == 0
    assert np.abs(read_measurements(bare).measured - m.measured).max() > 0.01


def test_a_tool_that_contradicts_the_plan_is_refused_at_the_plan(tmp_path, capsys):
    plan = tmp_path / "plan.csv"
    assert main(["plan", "-n", "10", "--tool", "250,0,0,0,0,0", "-o", str(plan), "-q"]) == 0
    out = tmp_path / "m.csv"
    assert main(["measure", str(plan), "-o", str(out), "--tool", "200,0,0,0,0,0"]) == 2
    err = capsys.readouterr().err
    assert f"{plan}:1:1: P320 " in err and "# tool:" in err and not out.exists()


def test_a_plan_with_the_descriptions_tool_says_none(tmp_path):
    plan = tmp_path / "plan.csv"
    assert main(["plan", "-n", "10", "-o", str(plan), "-q"]) == 0
    assert "tool" not in read_metadata(plan) and plan.read_text().startswith("x,y,z,a,b,c")

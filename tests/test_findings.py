"""The rules compensate and check share (postproc/compensation/findings.py): one list of findings,
compensate refusing on its errors and check reporting them all."""
import numpy as np
import pytest

from postproc.compensation.check import check_program
from postproc.compensation.pipeline import compensate_program
from postproc.programs.io import parse_program_text
from postproc.model.compensator import load_model
from postproc.core.diagnostics import PostprocError
from postproc.programs.locate import MAX_LISTED
from postproc.compensation.findings import findings, run_model, select
from postproc.settings import Settings


def csv(rows):
    return "x,y,z,a,b,c\n" + "".join(f"{x},{y},{z},0,90,0\n" for x, y, z in rows)


def test_many_findings_are_listed_then_counted_the_same_in_compensate_and_check(affine):
    # 25 targets outside the box (x > 2300), the correction varying over space
    program = parse_program_text(csv([(2400 + 10 * i, 0, 900) for i in range(25)]), "p.csv")
    model = load_model(affine(gain=np.diag([1e-3, 0, 0])))
    report = compensate_program(program, model)
    listed = [d for d in report.warnings if d.code == "P301"]
    checked = [d for d in check_program(program, model) if d.code == "P301"]
    assert listed == checked and len(listed) == MAX_LISTED + 1
    # the last one is the 21st target and counts the 4 after it
    assert listed[-1].line == MAX_LISTED + 2 and listed[-1].message.endswith("(and 4 more targets)")
    assert report.outside_envelope == 25


def test_compensate_refuses_on_the_first_error_check_lists_every_one(affine):
    # two targets beyond reach and one good one
    program = parse_program_text(csv([(2000, 0, 900), (5000, 0, 900), (6000, 0, 900)]), "p.csv")
    model = load_model(affine())
    with pytest.raises(PostprocError) as info:
        compensate_program(program, model)
    assert (info.value.code, info.value.line) == ("P302", 3)
    found = [(d.code, d.line) for d in check_program(program, model)]
    assert found == [("P302", 3), ("P302", 4), ("P301", 3), ("P301", 4)]  # (outside the box too)
    settings = Settings()
    commands = run_model(model, select(program, model, settings), None)
    assert [(d.code, d.line) for d in findings(program, commands, model, settings)] == found


def test_the_largest_correction_is_named_first(affine):
    program = parse_program_text(csv([(2000, 0, 900), (2100, 0, 900), (2290, 0, 900)]), "p.csv")
    model = load_model(affine(offset=(5.0, 0, 0), gain=np.diag([0.01, 0, 0])))
    with pytest.raises(PostprocError) as info:
        compensate_program(program, model, Settings().override(iterations=1))
    assert (info.value.code, info.value.line) == ("P303", 4) and "correction of 7.900 mm" in info.value.message
    assert [(d.code, d.line) for d in check_program(program, model, Settings().override(iterations=1))] == [("P303", 4), ("P303", 3)]

"""Relative motions from a known start (issue 34, item 2): KRL LIN_REL / CIRC_REL / SLIN_REL after a
motion that is the same on every path are targets of their own, compensated so that their end lands
at P + Ê; where the start is not known they are left as written (P210, saying why), and the
interpreter's property (the compensated program run on every path) holds either way."""
from __future__ import annotations

import numpy as np
import pytest

from postproc.compensation.pipeline import compensate_program
from postproc.core import frames as fr
from postproc.core.diagnostics import P210
from postproc.model.compensator import load_model
from postproc.programs.io import read_program
from postproc.testing.models import affine_model
from postproc.testing.oracle import check

# a correction that varies over space (a constant offset would hide a wrong start)
GAIN = np.array([[2e-3, 5e-4, 0.0], [0.0, 1.5e-3, 4e-4], [3e-4, 0.0, 2.5e-3]])

DEBURR = """DEF deburr()
  $BASE = {X 1800, Y 0, Z 0, A 0, B 0, C 0}
  $TOOL = {X 0, Y 0, Z 200, A 0, B 0, C 0}
  PTP {X 100, Y -100, Z 900, A 0, B 90, C 0}
  LIN {X 100, Y 0, Z 900, A 0, B 90, C 0}
  CIRC {X 150, Y 50, Z 900}, {X 200, Y 0, Z 900}
  CIRC_REL {X 20,Y 20,Z 0},{X 40,Y 0,Z 0},CA 45
  LIN {Z 1100}
  LIN_REL {Z -50} #TOOL
  SLIN_REL {X 10, A 0}
  LIN {X 100, Y 0, Z 900, A 0, B 90, C 0}
END
"""


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    path = tmp_path_factory.mktemp("rel") / "m.onnx"
    return load_model(affine_model(path, offset=(0.2, -0.1, 0.15), gain=GAIN, tool={"name": "any"}))


def _compensate(text, model, name="deburr.src"):
    program = read_program([name], [text], "krl")
    return program, compensate_program(program, model)


def test_relative_motions_after_a_known_start_are_compensated(model):
    program, report = _compensate(DEBURR, model)
    t = program.targets
    # every motion is a target: the CIRC_REL's two points, LIN {Z 1100} after it, both _RELs after that
    assert t.line.tolist() == [4, 5, 6, 6, 7, 7, 8, 9, 10, 11]
    assert report.complete and report.compensated == 10 and not [w for w in report.warnings if w.code == P210]
    # the CIRC_REL's points are relative to the CIRC's end (row 3), the _RELs to the motion before them
    assert t.relative.tolist() == [-1, -1, -1, -1, 3, 3, -1, 6, 7, -1]
    # what the robot runs, the compensated program on every path, is at P + Ê
    checked = check(["deburr.src"], [DEBURR], "krl", model)
    assert checked.violations == [] and checked.compensated == 4 * 10 and checked.exit_code == 0


def test_a_relative_target_s_numbers_are_the_move_between_the_corrected_commands(model):
    program, report = _compensate(DEBURR, model)
    out = read_program(["deburr.src"], [report.outputs["deburr.src"]], "krl")
    t0, t1 = program.targets, out.targets

    def in_robot(p, r):
        return (p.frames[p.targets.frame[r]].base @ np.r_[p.targets.poses[r, :3], 1.0])[:3]

    for r in range(len(t0)):
        nominal, commanded = in_robot(program, r), in_robot(out, r)
        e = model.predict(np.r_[commanded, t0.poses[r, 3:6] if t0.relative[r] < 0 else [0, 90, 0]][None])[0]
        assert np.linalg.norm(commanded - nominal - e) < 2e-3, r
    # LIN_REL {Z -50} #TOOL: the move along the start's tool axes (B 90: tool Z is the base's X)
    start = in_robot(out, 6)
    rot = fr.rotation_from_abc(np.array([[0.0, 90.0, 0.0]]))[0]
    assert np.allclose(rot.T @ (in_robot(out, 7) - start), t1.poses[7, :3], atol=1e-9)
    # the X/Y/Z a relative aggregate leaves out are written in: the SLIN_REL reads X, Y, Z now
    line = report.outputs["deburr.src"].splitlines()[10]
    assert line.strip().startswith("SLIN_REL {X ") and ", Y " in line and ", Z " in line and line.endswith(", A 0}")


@pytest.mark.parametrize("body, why", [
    ("  IF $IN[1] THEN\n    LIN {X 100, Y 0, Z 900, A 0, B 90, C 0}\n  ELSE\n    LIN {X 150, Y 0, Z 900, A 0, B 90, C 0}\n"
     "  ENDIF\n  LIN_REL {Z 50}\n", "it is reached from several motions"),
    ("  PTP {A1 0,A2 -90,A3 90,A4 0,A5 0,A6 0}\n  LIN_REL {Z 50}\n", "where the robot stands before it is not known"),
    ("  LIN {X 100, Y 0, Z 900, A 0, B 90, C 0}\n  $TOOL = {X 0, Y 0, Z 250, A 0, B 0, C 0}\n  LIN_REL {Z 50}\n",
     "the tool changed since"),
    ("  LIN {X 100, Y 0, Z 900, A 0, B 90, C 0}\n  LIN_REL {Z 50, C 5}\n", "it turns the tool"),
])
def test_a_relative_motion_whose_start_is_not_known_is_left_and_said(model, body, why):
    text = ("DEF r()\n  $BASE = {X 1800, Y 0, Z 0, A 0, B 0, C 0}\n  $TOOL = {X 0, Y 0, Z 200, A 0, B 0, C 0}\n"
            f"  PTP {{X 100, Y -100, Z 900, A 0, B 90, C 0}}\n{body}END\n")
    program, report = _compensate(text, model, "r.src")
    said = [w for w in report.warnings if w.code == P210]
    assert len(said) == 1 and why in said[0].message and not report.complete
    rel = text.splitlines().index(next(s for s in text.splitlines() if "_REL" in s))
    assert said[0].line == rel + 1
    assert report.outputs["r.src"].splitlines()[rel + 1] == text.splitlines()[rel]  # (+1: the stamp line)
    # it moves with its start's correction, as said; everything else is at P + Ê
    checked = check(["r.src"], [text], "krl", model)
    assert checked.violations == [] and checked.exit_code == 1


def test_a_routine_of_relative_moves_called_from_two_places(model):
    # one LIN_REL's numbers run from two starts: with a correction affine in the position both runs
    # need the same move (E(end) − E(start) depends on the move only), so it is compensated for both
    text = ("DEF r()\n  $BASE = {X 1800, Y 0, Z 0, A 0, B 0, C 0}\n  $TOOL = {X 0, Y 0, Z 200, A 0, B 0, C 0}\n"
            "  LIN {X 100, Y 0, Z 900, A 0, B 90, C 0}\n  up()\n  LIN {X 300, Y 200, Z 950, A 0, B 90, C 0}\n"
            "  up()\nEND\nDEF up()\n  LIN_REL {Z 100}\nEND\n")
    program, report = _compensate(text, model, "r.src")
    assert report.complete and report.compensated == 3 and (program.targets.relative >= 0).sum() == 2
    checked = check(["r.src"], [text], "krl", model)
    assert checked.violations == [] and checked.compensated == 4 * 4


def test_a_relative_target_left_for_another_reason_takes_its_start_with_it(tmp_path):
    # a load-aware model that extrapolates to 600 kg: the LIN_REL carries 2000 kg (P338, left as
    # written); its start is left too (P230), so that it lands where the program says
    model = load_model(affine_model(tmp_path / "m.onnx", offset=(0.2, -0.1, 0.15), gain=GAIN, tool={"name": "any"},
                                    load_gain=np.diag([2e-4, 5e-4, 0.0]), load_offset=(0.1, 0.05, -0.2)))
    text = ("DEF r()\n  $BASE = {X 1800, Y 0, Z 0, A 0, B 0, C 0}\n  $TOOL = {X 0, Y 0, Z 200, A 0, B 0, C 0}\n"
            "  $LOAD = {M 300,CM {X 0,Y 0,Z 0,A 0,B 0,C 0},J {X 0,Y 0,Z 0}}\n"
            "  LIN {X 100, Y 0, Z 900, A 0, B 90, C 0}\n  LIN {X 100, Y 0, Z 1000, A 0, B 90, C 0}\n"
            "  $LOAD = {M 2000,CM {X 0,Y 0,Z 0,A 0,B 0,C 0},J {X 0,Y 0,Z 0}}\n"
            "  LIN_REL {Z 100}\nEND\n")
    program, report = _compensate(text, model, "r.src")
    out = report.outputs["r.src"].splitlines()
    assert out[-2] == "  LIN_REL {Z 100}" and out[-4] == "  LIN {X 100, Y 0, Z 1000, A 0, B 90, C 0}"
    assert report.compensated == 1 and not report.complete
    assert {w.code for w in report.warnings} >= {"P338", "P230"}


def test_orientation_is_not_corrected_on_relative_motions(tmp_path, capsys):
    from postproc.cli import main

    src = tmp_path / "r.src"
    src.write_text("DEF r()\n  $BASE = {X 1800, Y 0, Z 0, A 0, B 0, C 0}\n  $TOOL = {X 0, Y 0, Z 200, A 0, B 0, C 0}\n"
                   "  LIN {X 100, Y 0, Z 900, A 0, B 90, C 0}\n  LIN_REL {Z 50}\nEND\n")
    out = tmp_path / "out.src"
    assert main(["compensate", str(src), "-o", str(out), "--orientation"]) == 2 and not out.exists()
    err = capsys.readouterr().err
    assert f"{src}:5:11: P312 --orientation: a relative motion" in err

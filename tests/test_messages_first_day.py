"""Messages a new user reads on the first day (issue 38, item 8), each naming the one cause and the
fix: an aggregate written in the motion is "the target" (not "target the target"); a misspelt closer
is named; "Universal Robots'"; P406 names the fix P405 names; P303 says whether the target is
outside the model's data."""
from __future__ import annotations

import numpy as np

from postproc.cli import main
from postproc.compensation.api import compensate_text
from postproc.core.diagnostics import PostprocError
from postproc.model.compensator import load_model
from postproc.programs import ActiveFrames, krl

import pytest


def test_an_aggregate_in_the_motion_is_the_target(affine):
    p = krl.read(["t.src"], ["DEF t( )\n  DECL REAL v\n  $BASE = $NULLFRAME\n  LIN {X 2000,Y v,Z 900,A 0,B 90,C 0}\nEND\n"])
    (d,) = [d for d in p.diagnostics if d.code == "P212"]
    assert d.message.startswith("the target: its Y is not known here") and "target the target" not in d.message


def test_a_misspelt_closer_is_named():
    with pytest.raises(PostprocError) as info:
        krl.read(["t.src"], ["DEF t( )\n  DECL INT i\n  FOR i = 1 TO 3\n    LIN {X 2000,Y 0,Z 900,A 0,B 90,C 0}\n"
                             "  ENDFRO\nEND\n"])
    assert info.value.code == "P101" and "ENDFRO at line 5: ENDFOR, misspelt?" in str(info.value)


def test_another_family_is_named_in_good_english(tmp_path, capsys):
    (tmp_path / "u.src").write_text("DEF u( )\n  LIN {X 500,Y 0,Z 400,A 0,B 90,C 0}\nEND\n")
    from postproc.core.resources import model_path

    main(["check", str(tmp_path / "u.src"), "--model", str(model_path("ur10.onnx"))])
    printed = capsys.readouterr()
    text = printed.out + printed.err
    assert "an arm of Universal Robots' (its description ur10.toml)" in text and "Robots's" not in text


def test_a_missing_output_names_the_fix(tmp_path, capsys, affine):
    model = affine(offset=(0.1, 0.0, 0.0), tool={"name": "any"})
    (tmp_path / "src").mkdir()
    (tmp_path / "src" / "a.src").write_text("DEF a( )\n  $BASE = $NULLFRAME\n  $TOOL = $NULLFRAME\n"
                                            "  LIN {X 2000,Y 0,Z 900,A 0,B 90,C 0}\nEND\n")
    (tmp_path / "postproc.toml").write_text(f'model = "{model.as_posix()}"\n'
                                            'fresh = [{ source = "src/*.src", output = "out/*.src" }]\n')
    import os

    here = os.getcwd()
    os.chdir(tmp_path)
    try:
        assert main(["check", "--fresh"]) == 1
        printed = capsys.readouterr()
        assert "P406 no compensated output" in printed.out + printed.err
        assert "`postproc check --fresh --fix` writes it" in printed.out + printed.err
        assert main(["check", "--fresh", "--fix"]) == 0 and (tmp_path / "out" / "a.src").is_file()
    finally:
        os.chdir(here)


def test_a_correction_too_large_says_whether_the_target_is_outside_the_models_data(tmp_path):
    from postproc.testing.models import affine_model

    # E grows 10 mm per metre from the envelope's centre: 8 mm at 800 mm from it
    model = load_model(affine_model(tmp_path / "m.onnx", gain=np.eye(3) * 0.01, tool={"name": "any"}, reach=None))
    inside = "  LIN {X 2000,Y 580,Z 1290,A 0,B 90,C 0}\n"   # in the box, 7.1 mm
    outside = "  LIN {X 2000,Y 0,Z 1800,A 0,B 90,C 0}\n"    # above the box, 9 mm
    for line, says in ((inside, "inside its training data"), (outside, "outside the data the model was trained on")):
        with pytest.raises(PostprocError) as info:
            compensate_text(f"DEF t( )\n{line}END\n", model, name="t.src", active=ActiveFrames(base=0, tool="model"))
        assert info.value.code == "P303" and says in str(info.value), str(info.value)


@pytest.mark.parametrize("first, what, suffixes", [
    ("MODULE Weld", "an ABB RAPID module", ".mod, .prg, .sys"),
    ("DEF t( )", "a KUKA KRL program", ".src, .dat"),
    ("/PROG  WELD", "a FANUC LS program", ".ls"),
    ("def main():", "a URScript program", ".script")])
def test_a_program_saved_with_a_pose_lists_suffix_is_named(first, what, suffixes):
    """A RAPID module saved as .txt used to be "P104 header has no column x, y, z": now its dialect
    and the suffix to give it."""
    from postproc.programs.io import parse_program_text

    with pytest.raises(PostprocError) as info:
        parse_program_text(first + "\n  MoveL p1, v100, fine, tool0;\nENDMODULE\n", "weld.txt")
    assert info.value.code == "P104" and (info.value.line, info.value.col) == (1, 1)
    assert f"reads like {what}'s first line" in str(info.value) and suffixes in str(info.value)
    assert "a .txt is read as a pose list" in str(info.value)


def test_an_unknown_base_and_tool_are_both_named():
    """P201 named BASE_DATA but not an equally unknown TOOL_DATA: the finding names both causes."""
    p = krl.read(["t.src"], ["DEF t( )\n  $BASE = BASE_DATA[1]\n  $TOOL = TOOL_DATA[1]\n"
                             "  LIN {X 2000,Y 0,Z 900,A 0,B 90,C 0}\nEND\n"])
    (d,) = [d for d in p.diagnostics if d.code == "P201"]
    assert "BASE_DATA" in d.message and "the tool is not known either: TOOL_DATA" in d.message


def test_a_configuration_no_joint_angles_reach_names_one_that_does(tmp_path, capsys):
    """(issue 38, item 4) P309 for a point whose S/T no joint angles reach says the joint angles of a
    configuration that reaches it and the S/T that state it; writing those, the target compensates."""
    import re

    src = ("DEF t( )\n  $BASE = $NULLFRAME\n  $TOOL = {X 300,Y 0,Z 75,A 0,B 0,C 0}\n"
           "  PTP {X 2000,Y 0,Z 900,A 0,B 90,C 0,S 6,T 35}\n  LIN {X 2010,Y 0,Z 900,A 0,B 90,C 0}\nEND\n")
    (tmp_path / "t.src").write_text(src)
    assert main(["compensate", str(tmp_path / "t.src"), "-o", str(tmp_path / "o1" / "t.src")]) == 1
    err = capsys.readouterr().err
    said = re.search(r"t\.src:4:7: P309 .*another configuration reaches it: joint angles \(([^)]*)\) deg, "
                     r"which S (\d+) T (\d+) states", err)
    assert said, err
    fixed = src.replace("S 6,T 35", f"S {said.group(2)},T {said.group(3)}")
    (tmp_path / "t.src").write_text(fixed)
    assert main(["compensate", str(tmp_path / "t.src"), "-o", str(tmp_path / "o2" / "t.src")]) == 0
    assert "P309" not in capsys.readouterr().err


def test_p201_counts_targets_as_the_summary_does(affine):
    """Issue 38, item 8: a target run in a loop is one target in P201's count, as in the summary
    (it said one per run: '6 target(s)' where the summary said 3 left)."""
    model = load_model(affine(gain=np.diag([1e-3, 2e-3, -1e-3]), tool={"name": "any"}))
    src = ("DEF t( )\n  DECL INT I\n  BAS(#BASE, 3)\n"
           "  FOR I = 1 TO 2\n"
           "    LIN {X 2000,Y 0,Z 900,A 0,B 90,C 0}\n"
           "    LIN {X 2010,Y 0,Z 900,A 0,B 90,C 0}\n"
           "  ENDFOR\n"
           "  LIN {X 2020,Y 0,Z 900,A 0,B 90,C 0}\n"
           "END\n")
    _, report = compensate_text(src, model, name="t.src", active=ActiveFrames(tool="model"))
    (w,) = [w for w in report.warnings if w.code == "P201"]
    assert report.left == 3 and "3 target(s) left as written" in w.message

"""RAPID read as the free-form language it is (issue 36; what is done so far): a GOTO label on a line
of its own in a file saved with CRLF line endings, and a routine head whose parameters go on over
lines (issue 34's `\\tasks tasksScan{*}` head: tests/test_controller_syntax.py)."""
from __future__ import annotations

import numpy as np
import pytest

from postproc.compensation.api import compensate_text
from postproc.model.compensator import load_model
from postproc.programs.io import parse_program_text

EAX = "[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]"
LINES = ["MODULE Spindle",
         f"  CONST robtarget p1:=[[1800,100,500],[0,0,1,0],[0,0,0,0],{EAX}];",
         f"  CONST robtarget p2:=[[1850,120,520],[0,0,1,0],[0,0,0,0],{EAX}];",
         "  PROC main()",
         "    VAR num n:=0;",
         "  again:",
         "    MoveJ p1,v1000,fine,tool0;",
         "    MoveL p2,v100,fine,tool0;",
         "    n:=n+1;",
         "    IF n<3 GOTO again;",
         "  ENDPROC",
         "ENDMODULE", ""]


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    """A correction that varies over space, for any tool."""
    from postproc.testing.models import affine_model

    return load_model(affine_model(tmp_path_factory.mktemp("freeform") / "m.onnx", offset=(0.3, -0.2, 0.1),
                                   gain=np.diag([2e-3, -1e-3, 3e-3]), reach=None, envelope=None, tool={"name": "any"}))


def _reads_the_same(first: str, second: str, model, at_least: int) -> None:
    """One program in two layouts: the same targets, findings and numbers written (p1's, moved)."""
    a, b = parse_program_text(first, "m.mod"), parse_program_text(second, "m.mod")
    assert not [d for d in b.diagnostics if d.code == "P101"]
    assert len(a.targets) == len(b.targets) >= at_least and np.array_equal(a.targets.poses, b.targets.poses)
    out_a, rep_a = compensate_text(first, model, name="m.mod")
    out_b, rep_b = compensate_text(second, model, name="m.mod")
    assert rep_a.compensated == rep_b.compensated > 0
    assert sorted(w.code for w in rep_a.warnings) == sorted(w.code for w in rep_b.warnings)
    numbers = lambda text: [line.split("=", 1)[1] for line in text.splitlines() if "robtarget p1" in line]  # noqa: E731
    assert numbers(out_a) == numbers(out_b) and numbers(out_a) != numbers(first)


def test_a_label_in_a_crlf_file_reads_as_in_an_lf_one(model):
    lf, crlf = "\n".join(LINES), "\r\n".join(LINES)
    a, b = parse_program_text(lf, "spindle.mod"), parse_program_text(crlf, "spindle.mod")
    assert not [d for d in b.diagnostics if d.code == "P101"]
    assert np.array_equal(a.targets.poses, b.targets.poses) and len(b.targets) >= 2
    out_lf, rep_lf = compensate_text(lf, model, name="spindle.mod")
    out_crlf, rep_crlf = compensate_text(crlf, model, name="spindle.mod")
    assert rep_crlf.compensated == rep_lf.compensated == 2
    assert out_crlf.replace("\r\n", "\n") == out_lf and out_crlf.count("\r\n") == crlf.count("\r\n") + 1  # (+ the stamp)


SPLIT = ["MODULE M",
         f"  CONST robtarget p1:=[[1800,100,500],[0,0,1,0],[0,0,0,0],{EAX}];",
         "  PROC main()",
         "    VAR num x:=1;",
         "    VAR num i;",
         "    IF x=1 THEN",
         "      MoveL Offs(p1,0,0,10),v100,fine,tool0;",
         "    ENDIF",
         "    IF x=2 THEN",
         "      MoveL p1,v100,fine,tool0;",
         "    ELSE",
         "      WaitTime 0.1;",
         "    ENDIF",
         "    FOR i FROM 1 TO 3 DO",
         "      MoveL Offs(p1,0,0,30),v100,fine,tool0;",
         "    ENDFOR",
         "    TEST x",
         "    CASE 1:",
         "      MoveL Offs(p1,0,0,40),v100,fine,tool0;",
         "    DEFAULT:",
         "      MoveL Offs(p1,0,0,50),v100,fine,tool0;",
         "    ENDTEST",
         "    MoveL p1,v100,fine,tool0;",
         "  ENDPROC",
         "ENDMODULE", ""]
JOINED = ["MODULE M",
          f"  CONST robtarget p1:=[[1800,100,500],[0,0,1,0],[0,0,0,0],{EAX}];",
          "  PROC main()",
          "    VAR num x:=1;",
          "    VAR num i;",
          "    IF x=1 THEN MoveL Offs(p1,0,0,10),v100,fine,tool0;",
          "    ENDIF",
          "    IF x=2 THEN",
          "      MoveL p1,v100,fine,tool0;",
          "    ELSE WaitTime 0.1;",
          "    ENDIF",
          "    FOR i FROM 1 TO 3 DO MoveL Offs(p1,0,0,30),v100,fine,tool0; ENDFOR",
          "    TEST x",
          "    CASE 1: MoveL Offs(p1,0,0,40),v100,fine,tool0;",
          "    DEFAULT: MoveL Offs(p1,0,0,50),v100,fine,tool0;",
          "    ENDTEST",
          "    MoveL p1,v100,fine,tool0;",
          "  ENDPROC",
          "ENDMODULE", ""]


def test_statements_on_the_line_of_then_else_do_and_case_read_as_on_their_own_lines(model):
    """(issue 36, item 2) The same program with each statement on its own line and with statements
    joined onto the line of THEN, ELSE, DO, CASE …: and DEFAULT: (ENDFOR after the loop's statement):
    the same targets, frames and findings, and the same numbers written."""
    split, joined = "\n".join(SPLIT), "\n".join(JOINED)
    _reads_the_same(split, joined, model, 4)


ONE_LINE = ["MODULE M",
            f"  CONST robtarget p1:=[[1800,100,500],[0,0,1,0],[0,0,0,0],{EAX}];",
            "  FUNC num CalcSpeed(num Vg_init, num ratio, num maxIter)",
            "    RETURN Vg_init * ratio;",
            "  ENDFUNC",
            "  PROC main()",
            "    VAR num x:=1;",
            "    VAR num i:=0;",
            "    VAR num v;",
            "    v := CalcSpeed(100, 2, 5);",
            "    IF x=1 MoveL Offs(p1,0,0,10),v100,fine,tool0;",
            "    WHILE (i < 2) AND (x = 1) DO",
            "      MoveL Offs(p1,0,0,20),v100,fine,tool0;",
            "      i := i + 1;",
            "    ENDWHILE",
            "    IF (x = 1) AND (i = 2) THEN",
            "      MoveL p1,v100,fine,tool0;",
            "    ENDIF",
            "  ENDPROC",
            "ENDMODULE", ""]
OVER_LINES = ["MODULE M",
              f"  CONST robtarget p1:=[[1800,100,500],[0,0,1,0],[0,0,0,0],{EAX}];",
              "  FUNC num CalcSpeed(",
              "    num Vg_init,",
              "    num ratio,",
              "    num maxIter)",
              "    RETURN Vg_init * ratio;",
              "  ENDFUNC",
              "  PROC main()",
              "    VAR num x:=1;",
              "    VAR num i:=0;",
              "    VAR num v;",
              "    v := CalcSpeed(100, 2, 5);",
              "    IF x=1",
              "      MoveL Offs(p1,0,0,10),v100,fine,tool0;",
              "    WHILE (i < 2) AND",
              "          (x = 1) DO",
              "      MoveL Offs(p1,0,0,20),v100,fine,tool0;",
              "      i := i + 1;",
              "    ENDWHILE",
              "    IF (x = 1)",
              "       AND (i = 2) THEN MoveL p1,v100,fine,tool0;",
              "    ENDIF",
              "  ENDPROC",
              "ENDMODULE", ""]


def test_routine_heads_compact_ifs_and_conditions_over_several_lines(model):
    """(issue 36, items 5 and 6) A FUNC head whose parameters go on over lines, a compact IF whose
    statement is on the next line, WHILE and IF conditions continued on the next line: the same
    targets, findings and numbers as the program on one line each."""
    one, over = "\n".join(ONE_LINE), "\n".join(OVER_LINES)
    _reads_the_same(one, over, model, 3)


def test_editor_placeholders_are_read_and_what_depends_on_them_is_said(model):
    """(issue 36, item 4) RobotStudio's placeholders: a module holding <SMT>, <EXP>, <ARG> is read; a
    target whose value or frame depends on one is left as written and said at its line; the others
    are compensated."""
    text = "\n".join([
        "MODULE Ph",                                                         # 1
        f"  CONST robtarget p1:=[[1800,100,500],[0,0,1,0],[0,0,0,0],{EAX}];",  # 2
        f"  CONST robtarget p3:=[[1700,50,600],[0,0,1,0],[0,0,0,0],{EAX}];",   # 3
        "  VAR robtarget p2;",                                               # 4
        "  PROC r()",                                                        # 5
        "    <SMT>",                                                         # 6
        "  ENDPROC",                                                         # 7
        "  PROC main()",                                                     # 8
        "    MoveL p1,v100,fine,tool0;",                                     # 9
        "    p2 := <EXP>;",                                                  # 10
        "    MoveL p2,v100,fine,tool0;",                                     # 11
        "    r;",                                                            # 12
        "    MoveL p3,v100,fine,tool0;",                                     # 13
        "  ENDPROC",                                                         # 14
        "ENDMODULE", ""])
    p = parse_program_text(text, "ph.mod")
    assert not [d for d in p.diagnostics if d.code in ("P101", "P102")]
    out, report = compensate_text(text, model, name="ph.mod")
    said = {(w.code, w.line): w.message for w in report.warnings}
    assert report.compensated == 1  # p1, before anything depends on a placeholder
    assert "<EXP>" in said[("P211", 11)]  # p2's value is the placeholder's
    (frame,) = [m for (code, line), m in said.items() if code == "P201"]
    assert "<SMT> at line 6" in frame and "ph.mod:13" in frame  # what r's <SMT> does is not known: p3 left


def _named_program(by_name: bool) -> str:
    def call(positional: str, named: str) -> str:
        return named if by_name else positional
    return "\n".join([
        "MODULE Named",
        f"  CONST robtarget p1:=[[1800,100,500],[0,0,1,0],[0,0,0,0],{EAX}];",
        f"  CONST robtarget p2:=[[1850,120,520],[0,0,1,0],[0,0,0,0],{EAX}];",
        f"  CONST robtarget p3:=[[1700,60,560],[0,0,1,0],[0,0,0,0],{EAX}];",
        "  PERS tooldata tSpindle:=[TRUE,[[0,0,150],[1,0,0,0]],[5,[0,0,50],[1,0,0,0],0,0,0]];",
        "  TASK PERS wobjdata wobj1:=[FALSE,TRUE,\"\",[[500,0,0],[0.9659258,0,0,0.2588190]],[[0,0,0],[1,0,0,0]]];",
        "  PROC Place(robtarget Where, tooldata T)",
        "    " + call("MoveL Where,v100,fine,T\\WObj:=wobj1;", "MoveL ToPoint:=Where,Speed:=v100,Zone:=fine,Tool:=T\\WObj:=wobj1;"),
        "  ENDPROC",
        "  PROC main()",
        "    " + call("MoveL p1,v100,fine,tSpindle;", "MoveL ToPoint:=p1,Speed:=v100,Zone:=fine,Tool:=tSpindle;"),
        "    " + call("MoveJ p2,v100,z10,tSpindle\\WObj:=wobj1;", "MoveJ p2,v100,Zone:=z10,Tool:=tSpindle\\WObj:=wobj1;"),
        "    " + call("Place p3, tSpindle;", "Place T:=tSpindle, Where:=p3;"),
        "  ENDPROC",
        "ENDMODULE", ""])


def test_required_arguments_given_by_name_are_compensated_as_the_positional_form(model):
    """(issue 36, item 3) MoveL ToPoint:=…, Speed:=…, Zone:=…, Tool:=… and a routine's arguments
    given by name: the same targets in the same frames with the same tools as the positional form,
    and the same numbers written."""
    positional, by_name = _named_program(False), _named_program(True)
    a, b = parse_program_text(positional, "named.mod"), parse_program_text(by_name, "named.mod")
    assert not [d for d in b.diagnostics if d.code == "P101"] and len(a.targets) == len(b.targets) == 3
    assert np.array_equal(a.targets.poses, b.targets.poses) and np.array_equal(a.targets.frame, b.targets.frame)
    assert [f.base.tolist() for f in a.frames] == [f.base.tolist() for f in b.frames]
    assert [None if f.tool is None else f.tool.tolist() for f in a.frames] == \
        [None if f.tool is None else f.tool.tolist() for f in b.frames]
    out_a, rep_a = compensate_text(positional, model, name="named.mod")
    out_b, rep_b = compensate_text(by_name, model, name="named.mod")
    assert rep_a.compensated == rep_b.compensated == 3
    numbers = lambda text: [line.split(":=", 1)[1] for line in text.splitlines() if "CONST robtarget" in line]  # noqa: E731
    assert numbers(out_a) == numbers(out_b) and numbers(out_a) != numbers(positional)


def test_an_argument_given_by_a_name_postproc_cannot_place_leaves_the_target_and_says_why():
    text = "\n".join([
        "MODULE N",
        f"  CONST robtarget p1:=[[1800,100,500],[0,0,1,0],[0,0,0,0],{EAX}];",
        "  VAR robtarget p9;",
        "  PROC main()",
        "    MoveL p1,v100,fine,tool0;",
        "    ArcL ToPoint:=p1,Speed:=v100,Seam:=sm1,Weld:=wd1,Weave:=wv1,Zone:=fine,Tool:=tool0;",  # 6
        "    p9 := CalcRobT(jTemp, Tool:=tool0\\WObj:=wobj0);",                                    # 7
        "    MoveL p9,v100,fine,tool0;",                                                          # 8
        "  ENDPROC",
        "ENDMODULE", ""])
    p = parse_program_text(text, "n.mod")
    said = {(d.code, d.line): d.message for d in p.diagnostics}
    assert "ArcL is given ToPoint:=" in said[("P211", 6)]
    assert any(line == 8 and "CalcRobT() is given Tool:= by name" in m for (code, line), m in said.items())


def test_statements_after_end_words_labels_and_whole_routines_on_one_line(model):
    """Free-form to the end: a statement after ENDIF on its line, a label after a statement, TEST
    with its CASEs on one line, a routine and the whole module on one line — all read as the same
    program laid out one statement a line."""
    p1 = f"CONST robtarget p1:=[[1800,100,500],[0,0,1,0],[0,0,0,0],{EAX}];"
    p2 = f"CONST robtarget p2:=[[1850,120,520],[0,0,1,0],[0,0,0,0],{EAX}];"
    lines = ["MODULE M (SYSMODULE, NOSTEPIN)", p1, p2, "PROC r()", "<SMT>", "ENDPROC", "PROC main()", "VAR num n:=1;",
             "IF n=1 THEN", "MoveL p1,v100,fine,tool0;", "ENDIF", "MoveL p2,v100,fine,tool0;",
             "again:", "MoveL Offs(p1,0,0,10),v100,fine,tool0;", "TEST n", "CASE 1:", "MoveL Offs(p2,0,0,10),v100,fine,tool0;",
             "DEFAULT:", "MoveL p1,v100,fine,tool0;", "ENDTEST", "ENDPROC", "ENDMODULE", ""]
    text = "\n".join(lines)
    flat = " ".join(lines[:-1]) + "\n"  # the whole module on one line
    mixed = "\n".join(["MODULE M (SYSMODULE, NOSTEPIN)", p1, p2, "PROC r() <SMT> ENDPROC", "PROC main()",
                       "VAR num n:=1;", "IF n=1 THEN MoveL p1,v100,fine,tool0; ENDIF MoveL p2,v100,fine,tool0; again:",
                       "MoveL Offs(p1,0,0,10),v100,fine,tool0;",
                       "TEST n CASE 1: MoveL Offs(p2,0,0,10),v100,fine,tool0; DEFAULT: MoveL p1,v100,fine,tool0; ENDTEST",
                       "ENDPROC ENDMODULE", ""])
    a = parse_program_text(text, "m.mod")
    assert len(a.targets) >= 4
    out_a, rep_a = compensate_text(text, model, name="m.mod")
    for other in (flat, mixed):
        b = parse_program_text(other, "m.mod")
        assert not [d for d in b.diagnostics if d.code in ("P101", "P102")]
        assert np.array_equal(a.targets.poses, b.targets.poses)
        out_b, rep_b = compensate_text(other, model, name="m.mod")
        assert rep_b.compensated == rep_a.compensated > 0 and rep_b.left_codes == rep_a.left_codes
        assert parse_program_text(out_b, "m.mod").targets.poses.tolist() == \
            parse_program_text(out_a, "m.mod").targets.poses.tolist()

"""Syntax real controllers accept (issue 34, item 1), each read or refused located, never a P101:
RAPID conditional arguments (`\\Switch?Switch`, `\\WObj?WObj`), a RAPID routine head whose
parameters (an optional open array among them) go on over lines, and a FANUC /POS record in the
RX … RR form, refused at its line with the form named."""
from __future__ import annotations

import numpy as np
import pytest

from postproc.cli import main
from postproc.compensation.api import compensate_text
from postproc.model.compensator import load_model
from postproc.programs.io import parse_program_text

GAIN = np.array([[2e-3, 0, 0], [0, -1e-3, 5e-4], [0, 0, 3e-3]])  # a correction that varies over space
EAX = "[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]"


def rt(x, y, z):
    return f"[[{x},{y},{z}],[0,0,1,0],[0,0,0,0],{EAX}]"


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    from postproc.testing.models import affine_model

    path = affine_model(tmp_path_factory.mktemp("syntax") / "affine.onnx", offset=(0.3, -0.2, 0.1), gain=GAIN,
                        reach=None, envelope=None, tool={"name": "any"})
    return load_model(path)


SHARED = "\n".join([
    "MODULE SharedModule",                                                   # 1
    f"  CONST robtarget p10:={rt(1800, 100, 500)};",                          # 2
    f"  CONST robtarget p20:={rt(1850, 120, 520)};",                          # 3
    "  TASK PERS wobjdata wTable:=[FALSE,TRUE,\"\",[[500,0,0],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];",  # 4
    "  PROC MyProc(\\switch Fast | switch Slow, \\num Speed)",                # 5
    "    MoveL p10, v100, fine, tool0;",                                     # 6
    "  ENDPROC",                                                             # 7
    "  PROC Caller(\\switch Fast, \\num Speed)",                              # 8
    "    MyProc \\Fast?Fast, \\Speed?Speed;",                                 # 9
    "  ENDPROC",                                                             # 10
    "  PROC Place(\\wobjdata WObj)",                                         # 11
    "    MoveL p20, v100, fine, tool0\\WObj?WObj;",                           # 12
    "  ENDPROC",                                                             # 13
    "  PROC SyncAll(\\switch All,",                                          # 14
    "               bool WaitSync\\tasks tasksScan{*})",                     # 15
    "    WaitTime 0.1;",                                                     # 16
    "  ENDPROC",                                                             # 17
    "  PROC main()",                                                         # 18
    "    Caller \\Fast;",                                                    # 19
    "    Place \\WObj:=wTable;",                                             # 20
    "  ENDPROC",                                                             # 21
    "ENDMODULE", ""])


def test_rapid_conditional_arguments_and_a_routine_head_over_lines_are_read(model):
    p = parse_program_text(SHARED, "SharedModule.mod")
    assert not [d for d in p.diagnostics if d.code == "P101"]
    out, report = compensate_text(SHARED, model, name="SharedModule.mod")
    # p10 through MyProc (called with \Fast?Fast: a switch, nothing to do with the frame): compensated
    assert report.compensated == 1
    before = parse_program_text(SHARED, "SharedModule.mod").targets.poses[:, :3]
    after = parse_program_text(out, "SharedModule.mod").targets.poses[:, :3]
    moved = np.abs(after - before).max(axis=1) > 1e-3
    assert moved.tolist() == [True, False]  # p10 moved; p20 left as written
    # p20 runs in the work object the caller may or may not have passed on: which one is known at run
    # time only, so it is left as written and said at the motion, with the argument named
    (w,) = [w for w in report.warnings if w.code == "P201"]
    assert w.line == 12 and "\\WObj?WObj" in w.message


def test_a_conditional_argument_of_a_motion_in_a_module_that_calls_nothing_is_no_syntax_error(tmp_path, capsys):
    """check reads it (exit 0 on syntax grounds: no P101)."""
    (tmp_path / "m.mod").write_text(SHARED)
    main(["check", str(tmp_path / "m.mod")])
    printed = capsys.readouterr()
    assert "P101" not in printed.out + printed.err


LS = """/PROG  RXFORM
/ATTR
OWNER\t\t= MNEDITOR;
DEFAULT_GROUP\t= 1,*,*,*,*;
/MN
   1:  UFRAME_NUM=0 ;
   2:  UTOOL_NUM=1 ;
   3:L P[1] 100mm/sec FINE    ;
   4:L P[2] 100mm/sec FINE    ;
/POS
P[1]{
   GP1:
\tUF : 0, UT : 1,\t\tCONFIG : 'N U T, 0, 0, 0',
\tX =  1230.365  mm,\tY =  1488.208  mm,\tZ =   676.258  mm,
\tW =   177.600 deg,\tP =     2.907 deg,\tR =    50.828 deg
};
P[2]{
   GP1:
\tUF : 0, UT : 1,\t\tCONFIG : 'N U T, 0, 0, 0',
\tRX =  1230.365  mm,\tRY =  1488.208  mm,\tRZ =   676.258  mm,
\tRW =   177.600 deg,\tRP =     2.907 deg,\tRR =    50.828 deg
};
/END
"""


def test_a_fanuc_position_in_the_rx_form_is_refused_at_its_line_naming_the_form(tmp_path, capsys):
    (tmp_path / "rx.ls").write_text(LS)
    out = tmp_path / "out" / "rx.ls"
    code = main(["compensate", str(tmp_path / "rx.ls"), "-o", str(out)])
    printed = capsys.readouterr()
    assert code == 2 and not out.exists()
    assert "rx.ls:20:" in printed.err and "P118 P[2] is written in the RX, RY, RZ, RW, RP, RR form" in printed.err
    assert "P101" not in printed.err
    # the same record in the X … R form reads
    (tmp_path / "xr.ls").write_text(LS.replace("\tRX =", "\tX =").replace("\tRY =", "\tY =").replace("\tRZ =", "\tZ =")
                                    .replace("\tRW =", "\tW =").replace("\tRP =", "\tP =").replace("\tRR =", "\tR ="))
    assert len(parse_program_text((tmp_path / "xr.ls").read_text(), "xr.ls").targets) == 2

"""A KRL data list holds constants (issue 34, item 4): the controller does not load a .dat whose
declaration names a variable (`Y NaN`: KRL has no NaN constant) or calls a function. postproc
refuses it at the .dat's own line and column — compensate writes nothing (exit 2), check reports
it as an error — where it used to read the name as a run-time unknown and leave the target at the
motion's line. A name in a .src aggregate stays a located warning: a program sets variables."""
from __future__ import annotations

import numpy as np
import pytest

from postproc.cli import main

E6 = ",A 0.0,B 90.0,C 0.0,S 2,T 35,E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}"
SRC = ("DEF nan_in_dat( )\n"                                     # 1
       "  $BASE = $NULLFRAME\n"                                  # 2
       "  $TOOL = {X 0,Y 0,Z 200,A 0,B 0,C 0}\n"                 # 3
       "  PTP XP1\n"                                             # 4
       "  LIN XP1\n"                                             # 5
       "  LIN XP2\n"                                             # 6
       "END\n")
DAT = ("DEFDAT nan_in_dat\n"                                     # 1
       "  DECL E6POS XP1={X 2000.0,Y 0.0,Z 900.0" + E6 + "\n"    # 2
       "  DECL E6POS XP2={X 1950.0,Y NaN,Z 900.0" + E6 + "\n"    # 3
       "ENDDAT\n")


@pytest.fixture
def cell(tmp_path, affine):
    def make(src=SRC, dat=DAT):
        (tmp_path / "nan_in_dat.src").write_text(src)
        (tmp_path / "nan_in_dat.dat").write_text(dat)
        return tmp_path
    model = affine(gain=np.diag([1e-3, -2e-3, 1e-3]), offset=(0.2, -0.1, 0.3))
    return make, model


def run(argv, capsys):
    code = main(argv)
    printed = capsys.readouterr()
    return code, printed.out + printed.err  # (check prints its findings on stdout)


def test_a_name_in_a_data_lists_declaration_is_refused_at_the_dat(cell, capsys):
    make, model = cell
    d = make()
    out = d / "out" / "nan_in_dat.src"
    code, err = run(["compensate", str(d / "nan_in_dat.src"), "-o", str(out), "--model", str(model),
                     "--base", "0", "--tool", "model"], capsys)
    assert code == 2 and not out.exists() and not out.with_suffix(".dat").exists()
    col = DAT.splitlines()[2].index("NaN") + 1
    assert f"nan_in_dat.dat:3:{col}: P103 " in err and "'NaN', which is no constant" in err
    assert "P212" not in err  # (no longer read as a value known only at run time)
    # check, as a pre-commit hook runs it on the .dat alone: an error at the same place
    code, err = run(["check", str(d / "nan_in_dat.dat")], capsys)
    assert code == 1 and f"nan_in_dat.dat:3:{col}: P103 " in err


def test_a_function_call_in_a_data_list_is_refused_too(cell, capsys):
    make, model = cell
    d = make(dat=DAT.replace("Y NaN", "Y SIN(30)"))
    code, err = run(["check", str(d / "nan_in_dat.dat")], capsys)
    col = DAT.splitlines()[2].index("NaN") + 1
    assert code == 1 and f"nan_in_dat.dat:3:{col}: P103 " in err and "a call of SIN" in err


def test_constants_of_every_kind_in_a_data_list_are_read(cell, capsys):
    """What KUKA's own data lists hold — enums, strings, bits, TRUE/FALSE, signed numbers, nested
    aggregates — is constant: read and compensated as before."""
    make, model = cell
    dat = (DAT.replace("Y NaN", "Y -12.5")
           .replace("ENDDAT", "  DECL FDAT FP2={TOOL_NO 1,BASE_NO 0,IPO_FRAME #BASE,POINT2[] \" \",TQ_STATE FALSE}\n"
                              "  DECL BOOL DONE=TRUE\n  DECL INT MASK='B0101'\nENDDAT"))
    d = make(dat=dat)
    out = d / "out" / "nan_in_dat.src"
    code, err = run(["compensate", str(d / "nan_in_dat.src"), "-o", str(out), "--model", str(model),
                     "--base", "0", "--tool", "model"], capsys)
    assert code == 0, err
    written = out.with_suffix(".dat").read_text()
    assert "IPO_FRAME #BASE" in written and "Y -12.5," not in written  # XP2 compensated (its Y moved)


def test_a_name_in_a_src_aggregate_stays_a_located_warning(cell, capsys):
    """In a .src, a name in an aggregate is a variable the program may set at run time: the target
    is left as written and said at its line (P212), the rest compensated, exit 1."""
    make, model = cell
    src = SRC.replace("  LIN XP2\n", "  LIN {X 1950.0,Y NaN,Z 900.0,A 0.0,B 90.0,C 0.0}\n")
    d = make(src=src, dat=DAT.replace("Y NaN", "Y 0.0"))
    out = d / "out" / "nan_in_dat.src"
    code, err = run(["compensate", str(d / "nan_in_dat.src"), "-o", str(out), "--model", str(model),
                     "--base", "0", "--tool", "model"], capsys)
    assert code == 1 and out.exists()
    assert "nan_in_dat.src:6:" in err and "P212" in err and "P103" not in err
    assert "\n  LIN {X 1950.0,Y NaN,Z 900.0,A 0.0,B 90.0,C 0.0}\n" in out.read_text()  # as written

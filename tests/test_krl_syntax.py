"""KSS 8.x statement forms: every sample under samples/krl/syntax reads without P101, with
the targets expected; handlers of INTERRUPT/TRIGGER that set a frame make it unknown."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from postproc.core.diagnostics import PostprocError
from postproc.programs import krl
from postproc.programs.krl.syntax import parser

SYN = Path(__file__).resolve().parent.parent / "samples" / "krl" / "syntax"


def _read(*names):
    files = [str(SYN / n) for n in names]
    return krl.read(files, [Path(f).read_text() for f in files])


@pytest.mark.parametrize("line", [
    "GLOBAL DEFFCT CHAR[15] K_ADDR(ADDR:IN)", "IF (I MOD 2) == 1 THEN", "WAIT FOR $IN[21] DELAY=0.2",
    "IMPORT INT I IS /R1/PROG1..I1", "EXTFCT CHAR[10] F(INT:IN)", "X = A*B MOD 3 + MODE",
    "IF NOT $IN[1] AND B_NOT M B_AND 3 <> 0 OR X EXOR Y THEN",
    "TRIGGER WHEN PATH=-20 ONSTART DELAY=10 DO $OUT[2]=TRUE PRIO=-1",
    "ANOUT ON $ANOUT[1] = 0.5 * $VEL_ACT + 0.1 DELAY=0.2 MINIMUM=0.1 MAXIMUM=0.9",
    "SPTP XP1 WITH $TOOL = STOOL2(FP1), $BASE = SBASE(FP1.BASE_NO)", "BRAKE F", "CONST INT N = 3",
    "INTERRUPT DECL 11 WHEN $IN[11] DO BRAKE F", "SLIN XP3 WITH $VEL = SVEL_CP(2.0, , LCPDAT1)",
    "TRIGGER WHEN PATH = GET_TRIG_PATH() DELAY=0 DO PULSE($OUT[3], TRUE, 0.1)",
])
def test_valid_lines_parse(line):
    parser().parse(line)


def test_mod_binds_like_multiplication():
    tree = parser().parse("X = A + B MOD 3")
    binop = tree.children[0].children[1]
    assert binop.data == "binop" and str(binop.children[1]) == "+"
    assert binop.children[2].data == "binop" and str(binop.children[2].children[1]).upper() == "MOD"


def test_statements_sample():
    p = _read("statements.src", "statements.dat")
    assert all(d.code != "P101" for d in p.diagnostics)
    t = p.targets
    # LIN literal (src 21), XP1/XP2 from the .dat (16, 17), SPTP … WITH $TOOL (49), LIN (50);
    # XP2 runs after line 21 or XP1 (the IF's branches): a second row from the other predecessor; the SPTP
    # (49) after XP2, after line 21 or XP1 (the SWITCH's CASE 3 and DEFAULT go on) or after the LOOP's LIN_REL
    # (where that leaves the robot is not known): a row for each
    assert list(t.line) == [21, 16, 17, 17, 49, 49, 49, 49, 50]
    assert t.twin.tolist() == [-1, -1, -1, 2, -1, 4, 4, 4, -1] and t.prev.tolist()[2:4] == [1, 0]
    assert sorted(t.prev.tolist()[4:8]) == [-1, 0, 1, 2]
    # PULSE cannot set a frame; the WITH $TOOL (the model's tool) is for its motion only
    assert list(t.frame) == [0] * 9
    np.testing.assert_allclose(p.frames[0].tool, [0, 0, 200, 0, 0, 0])
    assert {d.code for d in p.diagnostics} == {"P210"}


def test_handlers_make_frames_unknown():
    p = _read("handlers.src")
    t = p.targets
    assert list(t.line) == [6, 9, 12, 15, 17]
    # trigger with $OUT / a callee not touching frames: known; interrupt setting $BASE: unknown until
    # $BASE is set again; trigger calling a DEF that sets $TOOL: tool unknown
    assert t.frame[0] >= 0 and t.frame[1] >= 0 and t.frame[2] == -1 and t.frame[3] >= 0 and t.frame[4] == -1
    msgs = {d.code: d for d in p.diagnostics}
    assert msgs["P201"].line == 10 and "INTERRUPT" in msgs["P201"].message
    assert msgs["P203"].line == 16 and "NEW_TOOL()" in msgs["P203"].message


def test_brake_handler_keeps_frames():
    text = ("DEF brk( )\n  $BASE = {X 1800.0,Y 0.0,Z 600.0,A 0.0,B 0.0,C 0.0}\n  $TOOL = {X 0.0,Y 0.0,Z 200.0,A 0.0,B 0.0,C 0.0}\n"
            "  INTERRUPT DECL 6 WHEN $IN[6] DO BRAKE F\n  INTERRUPT ON 6\n"
            "  LIN {X 100.0,Y 200.0,Z 300.0,A 0.0,B 90.0,C 0.0}\nEND\n")
    p = krl.read(["brk.src"], [text])
    assert list(p.targets.frame) == [0] and not p.diagnostics


@pytest.mark.parametrize("line,col", [("WAIT FOR $IN[1] DELAY 0.2", 25), ("IF (I MOD) == 1 THEN", 12),
                                      ("IMPORT INT I IS R1..I1", 19)])
def test_invalid_krl_is_located(line, col):
    text = f"DEF bad( )\n  {line}\nEND\n"
    with pytest.raises(PostprocError) as e:
        krl.read(["bad.src"], [text])
    assert (e.value.code, e.value.line, e.value.col) == ("P101", 2, col)


@pytest.mark.parametrize("names", [("statements.src", "statements.dat"), ("handlers.src",)])
def test_zero_model_keeps_the_bytes(affine, names):
    from postproc.compensation.pipeline import compensate_program
    from postproc.model.compensator import load_model
    from postproc.programs import STAMP_PREFIX

    def values(text):  # numbers are rewritten in the writer's style (≥ 3 decimals), same value
        return re.sub(r"\d+\.\d*", lambda m: f"{float(m.group()):.6f}", text)

    report = compensate_program(_read(*names), load_model(affine()))
    assert report.compensated > 0 and report.outputs
    for path, text in report.outputs.items():
        kept = "".join(x for x in text.splitlines(keepends=True) if STAMP_PREFIX not in x)
        assert values(kept) == values(Path(path).read_text())

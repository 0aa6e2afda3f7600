"""Never silently wrong on real KRL: frames a program never sets (P220/P221) and how a user
states them (--base/--tool, settings), malformed numbers located at read time."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from postproc.cli import main
from postproc.compensation.api import compensate_text
from postproc.core.diagnostics import PostprocError
from postproc.core.frames import frame_to_matrix
from postproc.programs import ActiveFrames, krl

SAMPLES = Path(__file__).resolve().parent.parent / "samples" / "krl"
CONFIG = (SAMPLES / "config" / "$config.dat").read_bytes().decode("latin-1")
GAIN = np.diag([1e-3, 2e-3, -1e-3])  # a correction that varies over space

# a CAM-style program with the INI fold and no $BASE / $TOOL
CAM = ("DEF cam( )\n"                                            # 1
       ";FOLD INI\n"                                             # 2
       "  BAS (#INITMOV,0 )\n"                                   # 3
       ";ENDFOLD (INI)\n"                                        # 4
       "  $VEL.CP = 0.2\n"                                       # 5
       "  LIN {X 2000.0,Y 0.0,Z 900.0,A 0.0,B 90.0,C 0.0}\n"     # 6
       "  LIN {X 2050.0,Y 20.0,Z 910.0,A 0.0,B 90.0,C 0.0}\n"    # 7
       "END\n")


def codes(p):
    return [(d.code, d.line, d.col) for d in p.diagnostics]


@pytest.mark.parametrize("accelerate", [True, False])
def test_a_program_that_sets_neither_frame_leaves_its_targets_located(accelerate):
    p = krl.read(["cam.src"], [CAM], accelerate=accelerate)
    assert (p.targets.frame == -1).all() and p.frames == []
    # BAS(#INITMOV, 0) sets motion parameters, not $BASE/$TOOL: the first target is the place
    (d,) = p.diagnostics
    assert (d.code, d.line, d.col) == ("P220", 6, 7)
    assert "neither $BASE nor $TOOL" in d.message and "2 target(s) left as written" in d.message


def test_base_set_but_tool_not_is_p221_at_the_first_target_and_vice_versa():
    src = CAM.replace("  $VEL.CP = 0.2\n", "  $BASE = {X 0.0,Y 0.0,Z 0.0,A 0.0,B 0.0,C 0.0}\n")
    p = krl.read(["cam.src"], [src])
    assert codes(p) == [("P221", 6, 7)] and (p.targets.frame == -1).all()
    src = CAM.replace("  $VEL.CP = 0.2\n", "  $TOOL = {X 300.0,Y 0.0,Z 75.0,A 0.0,B 0.0,C 0.0}\n")
    p = krl.read(["cam.src"], [src])
    assert codes(p) == [("P220", 6, 7)] and "$BASE is not set" in p.diagnostics[0].message


def test_only_the_targets_before_the_frames_are_set_are_left():
    # a large program (fast path) whose first targets come before $TOOL is set
    body = "".join(f"  LIN {{X {2000 + k}.0,Y 0.0,Z 900.0,A 0.0,B 90.0,C 0.0}}\n" for k in range(3000))
    src = ("DEF big( )\n  BAS(#BASE, 0)\n" + body + "  BAS(#TOOL, 1)\n" + body + "END\n")
    for accelerate in (True, False):
        p = krl.read(["big.src"], [src], config=[CONFIG], accelerate=accelerate)
        t = p.targets
        assert (t.frame[:3000] == -1).all() and (t.frame[3000:] == 0).all()
        assert codes(p) == [("P221", 3, 7)] and "3000 target(s)" in p.diagnostics[0].message
        np.testing.assert_allclose(p.frames[0].tool, [300, 0, 75, 0, 0, 0])


def test_stated_frames_resolve_from_config_data_or_numbers():
    p = krl.read(["cam.src"], [CAM], config=[CONFIG], active=ActiveFrames(base=2, tool=1))
    assert p.diagnostics == [] and (p.targets.frame == 0).all()
    (f,) = p.frames
    np.testing.assert_allclose(f.base, frame_to_matrix(np.array([1780, 150, 700, 90, 0, 0.0])), atol=1e-12)
    np.testing.assert_allclose(f.tool, [300, 0, 75, 0, 0, 0])
    assert f.label == "BASE_DATA[2] / TOOL_DATA[1]"
    p = krl.read(["cam.src"], [CAM], active=ActiveFrames.of(base="10,20,30,0,0,90", tool="model"))
    (f,) = p.frames
    assert p.diagnostics == [] and f.tool is None  # the model's tool, stated
    np.testing.assert_allclose(f.base, frame_to_matrix(np.array([10, 20, 30, 0, 0, 90.0])), atol=1e-12)
    # what the program sets still wins from its line on
    src = CAM.replace("  $VEL.CP = 0.2\n", "  BAS(#BASE, 1)\n")
    p = krl.read(["cam.src"], [src], config=[CONFIG], active=ActiveFrames(base=2, tool=1))
    np.testing.assert_allclose(p.frames[0].base[:3, 3], [1850, -300, 650])


def test_a_stated_frame_that_cannot_be_resolved_is_refused():
    with pytest.raises(PostprocError) as e:
        krl.read(["cam.src"], [CAM], active=ActiveFrames(base=0, tool=6))  # no $config.dat
    assert e.value.code == "P222" and "--tool 6" in e.value.message and "$config.dat" in e.value.message
    with pytest.raises(PostprocError) as e:
        krl.read(["cam.src"], [CAM], config=[CONFIG], active=ActiveFrames(base=9, tool=1))  # not set in it
    assert e.value.code == "P222" and "BASE_DATA[9]" in e.value.message
    for bad in ("1,2,3", "x", "-1", "1,2,3,4,5,inf"):
        with pytest.raises(ValueError):
            ActiveFrames.of(base=bad)
    with pytest.raises(ValueError):
        ActiveFrames.of(base="model")  # only a tool can be the model's


def test_compensate_exits_1_unless_the_frames_are_stated(tmp_path, affine, capsys):
    src = tmp_path / "cam.src"
    src.write_text(CAM)
    model = str(affine(gain=GAIN))
    out = tmp_path / "out.src"
    assert main(["compensate", str(src), "-o", str(out), "--model", model]) == 1
    err = capsys.readouterr().err
    assert f"{src}:6:7: P220 neither $BASE nor $TOOL" in err and "0 of 2 compensated, 2 left as written: P220 ×2" in err
    assert out.read_text() == CAM  # written, unchanged, unstamped
    assert main(["compensate", str(src), "-o", str(out), "--model", model, "--base", "0", "--tool", "model"]) == 0
    assert "2 of 2 compensated" in capsys.readouterr().err and out.read_text() != CAM
    # check says the same, and takes the same options
    assert main(["check", str(src), "--model", model]) == 0  # (a warning: clean unless --strict)
    assert f"{src}:6:7: P220" in capsys.readouterr().out
    assert main(["check", str(src), "--model", model, "--strict"]) == 1
    capsys.readouterr()
    assert main(["check", str(src), "--model", model, "--base", "0", "--tool", "model", "--strict"]) == 0
    # a bad value is refused before any work
    assert main(["compensate", str(src), "-o", str(tmp_path / "x.src"), "--model", model, "--base", "1,2"]) == 2
    assert "P222" in capsys.readouterr().err and not (tmp_path / "x.src").exists()


def test_settings_state_the_frames_and_the_command_line_wins(tmp_path, affine, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "cam.src").write_text(CAM)
    (tmp_path / "config").mkdir()
    (tmp_path / "config" / "$config.dat").write_text(CONFIG)
    model = str(affine(gain=GAIN, tool={"name": "spindle", "frame": [300, 0, 75, 0, 0, 0]}))
    (tmp_path / "postproc.toml").write_text(f'model = "{model}"\nconfig = "config/$config.dat"\nbase = 0\ntool = 1\n')
    assert main(["compensate", "cam.src", "-o", "a.src"]) == 0
    # the command line's --tool wins over the settings' (a tool that is not the model's: P304)
    assert main(["compensate", "cam.src", "-o", "b.src", "--tool", "2"]) == 2
    assert "P304" in capsys.readouterr().err
    (tmp_path / "postproc.toml").write_text('base = "1,2"\n')
    assert main(["compensate", "cam.src", "-o", "c.src", "--model", model]) == 2
    assert "P610" in capsys.readouterr().err


def test_the_stated_frames_hold_when_the_output_is_read_again(affine):
    # the last checks read the new text again (P191): with the same stated frames
    out, report = compensate_text(CAM, str(affine(gain=GAIN)), name="cam.src",
                                  active=ActiveFrames(base=0, tool="model"))
    assert report.complete and report.compensated == 2 and out != CAM


def test_other_dialects_refuse_stated_frames():
    from postproc.programs.io import read_program

    with pytest.raises(PostprocError) as e:
        read_program(["p.csv"], ["x,y,z\n1,2,3\n"], "poses", active=ActiveFrames(base=0))
    assert e.value.code == "P222"


@pytest.mark.parametrize("number", ["1.5E+3.0", "1e+5.0", "20e+00.5"])
@pytest.mark.parametrize("accelerate", [True, False])
def test_a_malformed_exponent_is_a_located_syntax_error(number, accelerate):
    # the tail of 1.5E+3.0 is a number token (3.0): it used to be read as Z 3.0
    lines = ["DEF t( )", "  BAS(#BASE, 0)"] + ["  LIN {X 2000.0,Y 0.0,Z 900.0}"] * 5000
    lines[3000] = f"  LIN {{X 2000.0,Y 0.0,Z {number}}}"
    with pytest.raises(PostprocError) as e:
        krl.read(["t.src"], ["\n".join(lines + ["END", ""])], accelerate=accelerate)
    assert (e.value.code, e.value.line, e.value.col) == ("P101", 3001, 25)
    assert f"malformed number '{number}'" in e.value.message
    # in a .dat declaration too; in a comment it is text
    with pytest.raises(PostprocError) as e:
        krl.read(["t.src", "t.dat"], ["DEF t( )\nEND\n", f"DEFDAT t\nDECL E6POS XP1={{X {number},Y 0}}\nENDDAT\n"])
    assert (e.value.line, e.value.col) == (2, 19)
    krl.read(["t.src"], [f"DEF t( )\n  ; Z {number}\n  X1E = X1E+3\nEND\n"])


# ---------------------------------------------------------------- control flow

STATED = ActiveFrames(base=0, tool="model")
P = "LIN {X 1,Y 2,Z 3,A 0,B 90,C 0}"
B10 = "$BASE = {X 10,Y 0,Z 0,A 0,B 0,C 0}"


def flow(*lines, accelerate=True, **kw):
    src = "DEF t( )\n  DECL INT i, n\n" + "".join(f"  {x}\n" for x in lines) + "END\n"
    return krl.read(["t.src"], [src], active=STATED, accelerate=accelerate, **kw)


def bases(p):
    return [None if f < 0 else float(p.frames[f].base[0, 3]) for f in p.targets.frame]


def test_if_branches_start_from_the_entry_and_merge_at_endif():
    p = flow("IF $IN[1] THEN", B10, P, "ELSE", P, "ENDIF", P)  # lines 3..9
    # the ELSE branch runs in the entry's base; the last target comes after either branch (two rows)
    assert bases(p) == [10.0, 0.0, None, None] and p.targets.prev.tolist() == [-1, -1, 1, 0]
    assert codes(p) == [("P201", 3, 3)] and "IF at line 3" in p.diagnostics[0].message
    # without ELSE the path through no branch keeps the entry's base
    assert bases(flow("IF $IN[1] THEN", B10, "ENDIF", P)) == [None]
    # every path agrees: known
    assert bases(flow("IF $IN[1] THEN", B10, "ELSE", B10, "ENDIF", P)) == [10.0]
    assert bases(flow("IF $IN[1] THEN", "$OUT[1] = TRUE", "ENDIF", P)) == [0.0]


def test_switch_merges_its_cases_and_the_path_through_none():
    cases = ["SWITCH n", "CASE 1", B10, "CASE 2", B10]
    assert bases(flow(*cases, "ENDSWITCH", P)) == [None]  # no DEFAULT: the entry's base too
    assert bases(flow(*cases, "DEFAULT", B10, "ENDSWITCH", P)) == [10.0]
    p = flow(*cases, "DEFAULT", "BAS(#TOOL, 0)", "ENDSWITCH", P)
    assert bases(p) == [None] and "SWITCH at line 3" in p.diagnostics[0].message


def test_a_call_in_a_branch_and_a_branch_in_a_callee():
    src = ("DEF t( )\n  IF $IN[1] THEN\n    setb()\n  ENDIF\n  " + P + "\n  setc()\n  " + P + "\nEND\n"
           "DEF setb( )\n  " + B10 + "\nEND\n"
           "DEF setc( )\n  IF $IN[2] THEN\n    " + B10 + "\n  ELSE\n    BAS(#BASE, 0)\n  ENDIF\nEND\n")
    p = krl.read(["t.src"], [src], active=STATED)
    assert bases(p) == [None, None]
    assert [d.code for d in p.diagnostics] == ["P201", "P201"]
    assert "in setc() called at line 6" in p.diagnostics[1].message


@pytest.mark.parametrize("accelerate", [True, False])
def test_a_loop_body_that_changes_the_base(accelerate):
    # FOR with constant bounds: each pass runs (unrolled); the first target runs in the entry's
    # base in the first pass and in the body's afterwards (rows of one target in two frames:
    # compensate writes it only where they agree); after the loop, the body's base
    p = flow("FOR i = 1 TO 3", P, B10, P, "ENDFOR", P, accelerate=accelerate)
    assert bases(p) == [0.0, 10.0, 10.0, 10.0, 10.0, 10.0, 10.0] and codes(p) == []
    assert p.targets.twin.tolist() == [-1, -1, 0, 1, 0, 1, -1]
    # a loop whose passes are not known: its head joins the entry's frames with the body's end's
    p = flow("WHILE $IN[2]", P, B10, P, "ENDWHILE", P, accelerate=accelerate)
    # (the body's first target from before the loop and, a second row, from the body's end; the one
    # after the loop from the body's end or, the loop not run, from before it)
    assert bases(p) == [None, 10.0, None, None, None] and codes(p) == [("P201", 3, 3)]
    assert p.targets.prev.tolist() == [-1, 0, 1, 1, -1]
    assert "WHILE at line 3" in p.diagnostics[0].message
    # a WHILE may run 0 times; an EXIT leaves with the base in force there
    assert bases(flow("WHILE $IN[1]", B10, "ENDWHILE", P)) == [None]
    # (the only way out of this LOOP is its EXIT, right after the base is set)
    assert bases(flow("LOOP", B10, "IF $IN[1] THEN", "EXIT", "ENDIF", "BAS(#BASE, 0)", "ENDLOOP", P)) == [10.0]
    assert bases(flow("LOOP", "IF $IN[1] THEN", "EXIT", "ENDIF", B10, "ENDLOOP", P)) == [None]
    assert bases(flow("REPEAT", B10, "UNTIL $IN[1]", P)) == [10.0]
    # a body that does not touch the frames changes nothing
    assert bases(flow("FOR i = 1 TO n", P, "$VEL.CP = 0.1", "ENDFOR", P)) == [0.0] * 4  # (+ twins: a loop)


def test_loop_data_assigned_in_the_body_is_unknown_for_the_next_iteration():
    # unrolled: the first pass in BASE_DATA[1] as configured, the others in the one the body set
    p = flow("FOR i = 1 TO 3", "BAS(#BASE, 1)", P, "BASE_DATA[1] = {X 20,Y 0,Z 0,A 0,B 0,C 0}", "ENDFOR",
             "BAS(#BASE, 1)", P, config=[CONFIG])
    assert bases(p) == [1850.0, 20.0, 20.0, 20.0]
    # passes not known: unknown in the body, known after it only where every way out agrees
    p = flow("WHILE $IN[1]", "BAS(#BASE, 1)", P, "BASE_DATA[1] = {X 20,Y 0,Z 0,A 0,B 0,C 0}", "ENDWHILE",
             "BAS(#BASE, 1)", P, config=[CONFIG])
    assert bases(p) == [None] * 4


@pytest.mark.parametrize("accelerate", [True, False])
def test_the_current_position_after_control_flow_is_unknown(accelerate):
    body = ["LIN {X %d,Y 2,Z 3,A 0,B 90,C 0}" % (100 + k) for k in range(5000)]  # (fast path)
    p = flow("IF $IN[1] THEN", *body, "ELSE", "LIN {Z 5}", "ENDIF", "LIN {Z 6}", P, "LIN {Z 7}",
             accelerate=accelerate)
    t = p.targets
    assert np.isnan(t.poses[5000, :2]).all() and np.isnan(t.poses[5001, :2]).all()
    np.testing.assert_allclose(t.poses[5003, :3], [1, 2, 7])
    # a loop body that moves: its first partial target comes from before the loop in the first
    # pass, from the body's last target in the others (rows of one aggregate that get other X, Y:
    # compensate leaves it where they disagree); after the loop: the body's last
    p = flow(P, "FOR i = 1 TO 3", "LIN {Z 8}", "LIN {X 5,Y 5,Z 5,A 0,B 90,C 0}", "ENDFOR", "LIN {Z 9}")
    np.testing.assert_allclose(p.targets.poses[[1, 3, 5, 7], :3], [[1, 2, 8], [5, 5, 8], [5, 5, 8], [5, 5, 9]])
    p = flow(P, "WHILE $IN[1]", "LIN {Z 8}", "LIN {X 5,Y 5,Z 5,A 0,B 90,C 0}", "ENDWHILE", "LIN {Z 9}")
    assert np.isnan(p.targets.poses[1, :2]).all() and np.isnan(p.targets.poses[3, :2]).all()
    # branches without motions keep it
    p = flow(P, "IF $IN[1] THEN", "$OUT[2] = TRUE", "ENDIF", "WHILE $IN[3]", "WAIT SEC 0.1", "ENDWHILE", "LIN {Z 8}")
    np.testing.assert_allclose(p.targets.poses[1, :3], [1, 2, 8])


def test_compensate_leaves_the_unknown_position_located(tmp_path, affine, capsys):
    src = tmp_path / "b.src"
    src.write_text("DEF b( )\n  " + B10 + "\n  $TOOL = {X 0,Y 0,Z 200,A 0,B 0,C 0}\n  IF $IN[1] THEN\n    " + P + "\n  ENDIF\n"
                   "  LIN {Z 5}\nEND\n")
    assert main(["compensate", str(src), "-o", str(tmp_path / "o.src"), "--model", str(affine(gain=GAIN))]) == 1
    err = capsys.readouterr().err
    # {Z 5} takes X, Y from where the robot stands: after P, or not: not known, left (P212); on the
    # IF's path it takes them from P's command, so P is left too (P217): compensating it would move {Z 5}
    assert f"{src}:7:7: P212" in err and f"{src}:5:9: P217" in err and "0 of 2 compensated" in err


# ---------------------------------------------------------------- functions and handlers


def test_a_function_in_an_expression_is_followed_like_a_call():
    src = ("DEF t( )\n  DECL INT n\n  " + P + "\n  n = SetB(3) + ABS(-2)\n  " + P + "\n"
           "  WAIT FOR Ready()\n  " + P + "\nEND\n"
           "DEFFCT INT SetB(k:IN)\n  INT k\n  " + B10 + "\n  RETURN k\nENDFCT\n")
    p = krl.read(["t.src"], [src], active=STATED)
    assert bases(p) == [0.0, 10.0, None]  # ABS is KRL's own; Ready() is not in the files read
    assert codes(p) == [("P201", 6, 12), ("P232", 6, 12)] and "Ready() called at line 6" in p.diagnostics[0].message
    # in a callee too, and in a loop's condition
    src = ("DEF t( )\n  helper()\n  " + P + "\nEND\nDEF helper( )\n  IF SetB(1) > 0 THEN\n  ENDIF\nEND\n"
           "DEFFCT INT SetB(k:IN)\n  INT k\n  " + B10 + "\n  RETURN k\nENDFCT\n")
    assert bases(krl.read(["t.src"], [src], active=STATED)) == [10.0]


HANDLED = ("DEF t( )\n"                                                                  # 1
           "  INTERRUPT DECL 5 WHEN $IN[5] DO $BASE = {X 0,Y 0,Z 0,A 0,B 0,C 0}\n"       # 2
           "  INTERRUPT DECL 6 WHEN $IN[6] DO catch()\n"                                 # 3
           "  " + B10 + "\n"                                                              # 4
           "  LIN XP1\n"                                                                  # 5
           "  INTERRUPT ON\n"                                                             # 6
           "  " + B10 + "\n"                                                              # 7
           "  " + P + "\n"                                                                # 8: may be in the handler's base
           "  LIN XP1\n"                                                                  # 9: may be assigned by catch()
           "  LIN XP2\n"                                                                  # 10
           "  INTERRUPT OFF 5\n"                                                          # 11
           "  " + P + "\n"                                                                # 12: it may have run
           "  " + B10 + "\n"                                                              # 13
           "  " + P + "\n"                                                                # 14
           "  LIN XP1\n"                                                                  # 15: 6 still on
           "  INTERRUPT OFF 6\n"                                                          # 16
           "  LIN XP2\n"                                                                  # 17
           "END\n"
           "DEF catch( )\n  DECL E6POS XLOC\n  XLOC = $POS_INT\n  XP1 = $POS_INT\n  BRAKE\nEND\n")
DAT = ("DEFDAT t\n  DECL E6POS XP1={X 1,Y 2,Z 3,A 0,B 90,C 0}\n  DECL E6POS XP2={X 4,Y 5,Z 6,A 0,B 90,C 0}\n"
       "ENDDAT\n")


def test_an_interrupt_switched_on_leaves_what_its_handler_sets_unknown_until_off():
    p = krl.read(["t.src", "t.dat"], [HANDLED, DAT], active=STATED)
    t = p.targets
    # XP1 at 5 (before ON), the aggregate at 8, XP2 at 10, the aggregates at 12 and 14, XP2 at 17
    assert list(zip(t.line.tolist(), t.file.tolist())) == [(2, 1), (8, 0), (3, 1), (12, 0), (14, 0), (3, 1)]
    assert bases(p) == [10.0, None, None, None, 10.0, 10.0]
    found = codes(p)
    assert ("P223", 9, 7) in found and ("P223", 15, 7) in found  # XP1 while catch() is on
    assert ("P201", 2, 35) in found  # the base: at the handler's declaration
    assert "INTERRUPT handler declared at line 3" in next(d.message for d in p.diagnostics if d.code == "P223")
    # an interrupt declared but never switched on never runs
    quiet = HANDLED.replace("  INTERRUPT ON\n", "  ; no ON\n")
    p = krl.read(["t.src", "t.dat"], [quiet, DAT], active=STATED)
    assert -1 not in p.targets.frame.tolist() and not p.diagnostics


def test_p223_counts_as_left_as_written(tmp_path, affine, capsys):
    (tmp_path / "t.src").write_text(HANDLED.replace("  INTERRUPT DECL 5 WHEN $IN[5] DO $BASE = {X 0,Y 0,Z 0,A 0,B 0,C 0}\n",
                                                    "  ;\n"))
    (tmp_path / "t.dat").write_text(DAT)
    code = main(["compensate", str(tmp_path / "t.src"), "-o", str(tmp_path / "o.src"), "--model", str(affine(gain=GAIN)),
                 "--tool", "model"])
    err = capsys.readouterr().err
    assert code == 1 and "P223 ×2" in err and f"{tmp_path / 't.src'}:9:7: P223" in err


def test_the_public_api_states_frames_too(affine):
    import postproc

    with pytest.raises(AttributeError):
        postproc.no_such_name  # noqa: B018
    out, report = postproc.compensate_text(CAM, str(affine(gain=GAIN)), name="cam.src",
                                           active=postproc.ActiveFrames.of(base="0", tool="model"))
    assert report.complete and out != CAM


def test_verify_runs_the_program_in_the_stated_frames(tmp_path, capsys):
    pytest.importorskip("pinocchio")
    src, out = tmp_path / "cam.src", tmp_path / "out.src"
    src.write_text(CAM)
    stated = ["--base", "0", "--tool", "300,0,75,0,0,0"]  # the shipped model's spindle, written out
    assert main(["compensate", str(src), "-o", str(out), *stated]) == 0
    assert main(["verify", str(src), str(out), "--no-noise"]) == 2  # no frame known: nothing to verify
    assert "P601" in capsys.readouterr().err
    assert main(["verify", str(src), str(out), "--no-noise", "--json", *stated]) == 0


def test_a_label_a_goto_jumps_to_merges_the_frames_of_the_jumps():
    p = flow(P, "M1:", P, B10, P, "IF $IN[1] THEN", "GOTO M2", "ENDIF", "IF $IN[2] THEN", "GOTO M1", "ENDIF",
             "BAS(#BASE, 0)", "M2:", P, "M3:", P)
    # M1: the jump back comes with base 10; M2: the jump from base 10 and the fall-through from 0;
    # a label no GOTO names changes nothing; the target at M1 a second time from the jump back
    assert bases(p) == [0.0, None, 10.0, None, None, None]
    assert [(c, line) for c, line, _ in codes(p)] == [("P201", 4), ("P201", 15)]
    assert "GOTO M1 jumps to line 4" in p.diagnostics[0].message
    assert bases(flow(P, "GOTO M1", "M1:", P)) == [0.0, 0.0]


def test_a_frame_variable_an_interrupt_handler_assigns_is_unknown_while_it_is_on():
    src = ("DEF t( )\n  DECL FRAME XB\n  XB = {X 10,Y 0,Z 0,A 0,B 0,C 0}\n"
           "  INTERRUPT DECL 7 WHEN $IN[7] DO XB = $POS_INT\n  $BASE = XB\n  " + P + "\n"
           "  INTERRUPT ON 7\n  $BASE = XB\n  " + P + "\nEND\n")
    p = krl.read(["t.src"], [src], active=STATED)
    assert bases(p) == [10.0, None] and codes(p) == [("P201", 8, 3)]

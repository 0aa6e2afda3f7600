"""The IR's reference interpreter (``postproc.programs.interpreter``) and the property it checks:
random KRL, RAPID, URScript and Fanuc LS programs with branches, loops, jumps, calls with OUT /
INOUT parameters, copies and frame changes, compensated, then the original and the compensated
program run over several oracles' paths: every executed target at P + Ê from its real predecessor,
or left as written and said so (``postproc.testing.oracle.check``). A fast profile here;
``benchmarks/interpreter.py --dialect all`` runs many more."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings

from postproc.model.compensator import load_model
from postproc.programs import ActiveFrames
from postproc.programs.io import lower
from postproc.programs.interpreter import Oracle, run
from postproc.testing.generate import (
    LS_FRAMES, dialect_cases, krl_programs, ls_programs, rapid_programs, urscript_programs,
)
from postproc.testing.models import affine_model, joint_model
from postproc.testing.oracle import check

STATED = ActiveFrames(base=0, tool="model")
GAIN = np.array([[2e-3, 5e-4, 0.0], [0.0, 1.5e-3, 4e-4], [3e-4, 0.0, 2.5e-3]])


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    path = tmp_path_factory.mktemp("m") / "m.onnx"
    return load_model(affine_model(path, offset=(0.2, -0.1, 0.15), gain=GAIN, previous_gain=5e-5,
                                   tool={"name": "any"}))


def motions(src, seed=0, dat="DEFDAT t\nENDDAT\n"):
    unit, dialect = lower(["t.src", "t.dat"], [src, dat], "krl", active=STATED)
    return run(unit, dialect, Oracle(seed))


def test_the_interpreter_runs_one_path_the_oracle_chooses():
    src = ("DEF t( )\n  IF $IN[1] THEN\n    LIN {X 1,Y 0,Z 0,A 0,B 0,C 0}\n  ELSE\n    LIN {X 2,Y 0,Z 0,A 0,B 0,C 0}\n  ENDIF\n"
           "  FOR I = 1 TO 3\n    LIN {X 10,Y 0,Z 0,A 0,B 0,C 0}\n  ENDFOR\n  GOTO E\n  LIN {X 99,Y 0,Z 0,A 0,B 0,C 0}\nE:\n  LIN {Z 5}\nEND\n")
    xs = {tuple(m.base[0, 3] for m in motions(src, seed)) for seed in range(8)}
    # the IF's two branches across oracles; the FOR three times; nothing after the GOTO; {Z 5} at X 10
    assert xs == {(1.0, 10.0, 10.0, 10.0, 10.0), (2.0, 10.0, 10.0, 10.0, 10.0)}
    last = motions(src, 0)[-1]
    assert last.base[2, 3] == 5.0


def test_the_interpreter_follows_out_parameters_and_code_not_read():
    src = ("DEF t( )\n  DECL E6POS P\n  P = {X 100,Y 0,Z 0,A 0,B 0,C 0}\n  Raise(P)\n  LIN P\n"
           "  gripper()\n  LIN {X 1,Y 2,Z 3,A 0,B 0,C 0}\nEND\nDEF Raise(Q:OUT)\n  DECL E6POS Q\n  Q.Z = Q.Z + 300\nEND\n")
    ms = motions(src)
    np.testing.assert_allclose(ms[0].base[:3, 3], [100, 0, 300])
    # code not read changes $BASE: the world's frame, not the identity
    assert not np.allclose(ms[1].base[:3, 3], [1, 2, 3])
    assert [m.base[:3, 3].tolist() for m in motions(src, 1)] != [m.base[:3, 3].tolist() for m in motions(src, 5)]



def test_the_interpreter_starts_programs_activates_routines_and_binds_arguments_as_the_analysis_does():
    """One activation for both engines (issue 31): the program's start, a routine's activation,
    a call's binding and which variables code not read touches are the analysis's; the
    interpreter replaces how statements run and the values it gives."""
    from postproc.programs.analysis.execute import Analysis
    from postproc.programs.interpreter import Interpreter

    for name in ("declare_data", "start", "routine", "call", "invoke", "havoc", "lookup", "write"):
        assert getattr(Interpreter, name) is getattr(Analysis, name), name
    # KRL: OUT copied back, IN copied in (the callee's assignment to it stays its own)
    src = ("DEF t( )\n  DECL E6POS P\n  DECL REAL D\n  P = {X 100,Y 0,Z 0,A 0,B 0,C 0}\n  D = 5\n  Lift(P, D)\n"
           "  LIN P\n  P.X = D\n  LIN P\nEND\n"
           "DEF Lift(Q:OUT, E:IN)\n  DECL E6POS Q\n  DECL REAL E\n  Q.Z = Q.Z + E * 60\n  E = 99\nEND\n")
    assert [m.base[:3, 3].tolist() for m in motions(src)] == [[100, 0, 300], [5, 0, 300]]
    # URScript: a default and keyword arguments
    text = "\n".join(["def prog():", "  def go(target, lift=0.05):",
                      "    movel(pose_trans(target, p[0, 0, -lift, 0, 0, 0]))", "  end",
                      "  go(p[0.1, 0.2, 0.3, 0, 0, 0])", "  go(lift=0.1, target=p[0.4, 0.2, 0.3, 0, 0, 0])", "end", ""])
    unit, dialect = lower(["u.script"], [text], "urscript", active=ActiveFrames(tool="model"))
    np.testing.assert_allclose([m.base[:3, 3] for m in run(unit, dialect, Oracle(0))], [[100, 200, 250], [400, 200, 200]])

@settings(max_examples=25, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(krl_programs())
def test_never_silently_wrong_on_random_krl_programs(model, program):
    files, texts, config = program
    checked = check(files, texts, "krl", model, config=config, active=STATED, seeds=range(3))
    assert checked.violations == [], "\n".join(checked.violations) + "\n" + texts[0]


@pytest.fixture(scope="module")
def joints(tmp_path_factory):
    """E = G·sin(q): a model of the controller's joint angles (the configuration decides it)."""
    gain = np.array([[0.0, 0.3, 0.0, 0.4, 0.0, 0.5], [0.2, 0.0, 0.0, 0.0, 0.6, 0.0], [0.0, 0.0, 0.3, 0.0, 0.0, 0.4]])
    path = tmp_path_factory.mktemp("j") / "j.onnx"
    return load_model(joint_model(path, gain, tool={"name": "spindle", "frame": [300, 0, 75, 0, 0, 0]}))


@settings(max_examples=20, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(krl_programs(configurations=True))
def test_never_silently_wrong_where_the_controller_keeps_or_reads_the_configuration(joints, program):
    """KRL points and literal targets writing S/T (a PTP's read, a LIN's not: the robot keeps the
    configuration it is in), a model of the joints: every executed target at P + Ê(q) for the q
    the controller really runs on its path (issue 39)."""
    files, texts, config = program
    checked = check(files, texts, "krl", joints, config=config, active=STATED, seeds=range(3))
    assert checked.violations == [], "\n".join(checked.violations) + "\n" + texts[0] + texts[1]


def _property(model, program, dialect):
    files, texts, config = program
    checked = check(files, texts, dialect, model, config=config, active=dialect_cases(dialect)[1], seeds=range(3))
    assert checked.violations == [], "\n".join(checked.violations) + "\n" + texts[0]


PROFILE = settings(max_examples=20, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])


@PROFILE
@given(rapid_programs())
def test_never_silently_wrong_on_random_rapid_programs(model, program):
    _property(model, program, "rapid")


@PROFILE
@given(urscript_programs())
def test_never_silently_wrong_on_random_urscript_programs(model, program):
    _property(model, program, "urscript")


@PROFILE
@given(ls_programs())
def test_never_silently_wrong_on_random_ls_programs(model, program):
    _property(model, program, "fanuc")


def test_a_point_copied_on_one_path_only_is_left_with_the_target_that_may_be_it(model):
    """Found by the property: ``IF … XP1 = XP2 ENDIF; LIN XP1`` — XP1 is not known after the IF
    (P212), but where the branch ran the robot goes to XP2's numbers: compensating XP2 moved
    that motion by XP2's correction (for XP2's own predecessor) while it was said left as
    written. The join keeps the tokens either path holds: XP2 is left too (P217)."""
    src = ("DEF t( )\n  BAS(#BASE, 0)\n  LIN XP2\n  IF $IN[1] THEN\n    XP1 = XP2\n  ENDIF\n  LIN XP3\n  LIN XP1\nEND\n")
    dat = ("DEFDAT t\n  DECL E6POS XP1={X 2100.0,Y 10.5,Z 900.0,A 0.0,B 90.0,C 0.0}\n"
           "  DECL E6POS XP2={X 1700.0,Y -300.5,Z 1100.0,A 0.0,B 90.0,C 0.0}\n"
           "  DECL E6POS XP3={X 2300.0,Y 300.5,Z 700.0,A 0.0,B 90.0,C 0.0}\nENDDAT\n")
    from postproc.programs.io import read_program

    p = read_program(["t.src", "t.dat"], [src, dat], "krl", active=STATED)
    assert [(d.code, d.line) for d in p.diagnostics] == [("P212", 8), ("P217", 3)]
    checked = check(["t.src", "t.dat"], [src, dat], "krl", model, active=STATED, seeds=range(6))
    assert checked.violations == [] and checked.exit_code == 1 and checked.paths == 6


def test_an_ls_position_in_another_frame_than_the_selected_one_stops_the_controller():
    """The frame check ($MCR.$UFRCHK, on by default): a position taught in UF 1 run while
    UFRAME_NUM=2 is selected stops the program (INTP-250/252): nothing after it runs."""
    pos = ("P[1]{\n   GP1:\n\tUF : 1, UT : 1,\t\tCONFIG : 'N U T, 0, 0, 0',\n"
           "\tX = 100.000  mm,\tY = 20.000  mm,\tZ = 30.000  mm,\n"
           "\tW =   180.000 deg,\tP =     0.000 deg,\tR =     0.000 deg\n};")
    mn = ["UFRAME_NUM=1", "UTOOL_NUM=1", "L P[1] 100mm/sec FINE", "UFRAME_NUM=2", "L P[1] 100mm/sec FINE",
          "UFRAME_NUM=1", "L P[1] 100mm/sec FINE"]
    text = "\n".join(["/PROG  T", "/ATTR", "/MN"] + [f"{k:4d}:  {m} ;" for k, m in enumerate(mn, 1)] +
                     ["/POS", pos, "/END", ""])
    unit, dialect = lower(["t.ls"], [text], "fanuc", config=[LS_FRAMES])
    ms = run(unit, dialect, Oracle(0))
    assert [m.site.line for m in ms] == [6]

"""The IR's reference interpreter (``postproc.programs.interpreter``) and the property it checks:
random KRL programs with branches, loops, jumps, calls with OUT parameters, copies and frame
changes, compensated, then the original and the compensated program run over several oracles'
paths: every executed target at P + Ê from its real predecessor, or left as written and said so
(``postproc.testing.oracle.check``). A fast profile here; ``benchmarks/interpreter.py`` runs many
more."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings

from postproc.compensator import load_model
from postproc.programs import ActiveFrames, lower
from postproc.programs.interpreter import Oracle, run
from postproc.testing.generate import krl_programs
from postproc.testing.models import affine_model
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


@settings(max_examples=25, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(krl_programs())
def test_never_silently_wrong_on_random_krl_programs(model, program):
    files, texts, config = program
    checked = check(files, texts, "krl", model, config=config, active=STATED, seeds=range(3))
    assert checked.violations == [], "\n".join(checked.violations) + "\n" + texts[0]

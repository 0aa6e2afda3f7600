"""KRL reader: STRUC arrays written by converters (members of type FRAME/POS/E6POS), used
as ``LIN gs[i].fCNC`` inside a FOR with constant bounds."""
from __future__ import annotations

import numpy as np
import pytest

from postproc.programs import ActiveFrames, krl

# converter output that sets $BASE but not $TOOL: the tool is stated as the user would
# (--tool model), the assumption the reader made silently before P221
STATED = ActiveFrames(tool="model")

N = 40
DAT = ("DEFDAT mill PUBLIC\n"
       "  DECL GLOBAL STRUC MillPoint FRAME fCNC, REAL grFeedrate, E6AXIS aJoints\n"
       f"  DECL GLOBAL MillPoint gsMill_TOP1[{N}]\n"
       + "".join(f"  gsMill_TOP1[{i}]={{fCNC {{X {100 + i}.5,Y -{i}.25,Z {300 + 2 * i},A 0,B 90,C 0}},grFeedrate 0.1}}\n"
                 for i in range(1, N + 1))
       + "ENDDAT\n")


def src(loop: str, body: str = "    LIN gsMill_TOP1[counter].fCNC C_DIS\n") -> str:
    return ("DEF mill( )\n  DECL INT counter, n\n  BAS(#BASE, 0)\n"
            f"  {loop}\n{body}  ENDFOR\n  LIN {{X 1,Y 2,Z 3,A 0,B 90,C 0}}\nEND\n")


@pytest.mark.parametrize("accelerate", [True, False])
def test_struc_array_elements_behind_a_constant_for_are_targets(accelerate):
    p = krl.read(["mill.src", "mill.dat"], [src(f"FOR counter = 1 TO {N}"), DAT], accelerate=accelerate, active=STATED)
    t = p.targets
    assert len(t) == N + 1 and p.diagnostics == []
    np.testing.assert_allclose(t.poses[:N, :3], [[100 + i + 0.5, -i - 0.25, 300 + 2 * i] for i in range(1, N + 1)])
    assert (t.file[:N] == 1).all() and t.line[:N].tolist() == list(range(4, N + 4))  # spans in the .dat
    text = p.texts[1]
    for i in (0, N - 1):
        assert [text[a:b] for a, b in t.spans[i]] == [f"{101 + i}.5", f"-{i + 1}.25", f"{302 + 2 * i}"]
    assert (t.frame >= 0).all()


def test_a_part_of_the_array_and_a_step():
    p = krl.read(["mill.src", "mill.dat"], [src("FOR counter = 10 TO 2 STEP -4"), DAT], active=STATED)
    assert p.targets.poses[:-1, 0].tolist() == [110.5, 106.5, 102.5] and p.diagnostics == []


@pytest.mark.parametrize("loop,why", [
    ("FOR counter = 1 TO n", "bounds known only at run time"),
    ("FOR n = 1 TO 3", "counter is not initialised"),
])
def test_struc_arrays_that_cannot_be_enumerated_are_left_alone(loop, why):
    p = krl.read(["mill.src", "mill.dat"], [src(loop), DAT], active=STATED)
    assert len(p.targets) == 1  # only the inline LIN after the loop
    assert [(d.code, d.line) for d in p.diagnostics] == [("P211", 5)] and why in p.diagnostics[0].message


def test_an_element_not_initialised_is_left_the_others_are_targets():
    p = krl.read(["mill.src", "mill.dat"], [src(f"FOR counter = 1 TO {N + 1}"), DAT], active=STATED)
    assert len(p.targets) == N + 1  # the N elements, the inline LIN after the loop
    assert [(d.code, d.line) for d in p.diagnostics] == [("P211", 5)]
    assert "gsMill_TOP1[…] is not set in the data given" in p.diagnostics[0].message


def test_a_struc_member_of_axis_type_is_not_a_target():
    body = "    PTP gsMill_TOP1[counter].aJoints\n"
    dat = DAT.replace("grFeedrate 0.1}", "grFeedrate 0.1,aJoints {A1 0,A2 -90,A3 90,A4 0,A5 0,A6 0}}")
    p = krl.read(["mill.src", "mill.dat"], [src("FOR counter = 1 TO 3", body), dat], active=STATED)
    assert len(p.targets) == 1 and p.diagnostics == []


def test_converter_output_in_a_cell_with_config():
    from pathlib import Path

    from postproc.core.frames import frame_to_matrix

    config = (Path(__file__).resolve().parent.parent / "samples" / "krl" / "config" / "$config.dat").read_bytes()
    main = src(f"FOR counter = 1 TO {N}").replace("BAS(#BASE, 0)", "BAS(#BASE, 2)\n  BAS(#TOOL, 2)")
    p = krl.read(["KRC/R1/Program/mill.src", "KRC/R1/Program/mill_TOP1_data.dat", "KRC/R1/System/$config.dat"],
                 [main, DAT.replace("DEFDAT mill", "DEFDAT mill_TOP1_data"), config.decode("latin-1")])
    t = p.targets
    assert len(t) == N + 1 and p.diagnostics == [] and (t.file[:N] == 1).all()
    assert set(t.frame.tolist()) == {0}
    np.testing.assert_allclose(p.frames[0].base, frame_to_matrix(np.array([1780.0, 150.0, 700.0, 90.0, 0, 0])))
    np.testing.assert_allclose(p.frames[0].tool, [0, 0, 185, 0, 0, 0])

"""Messages that point at every line involved (issue 34, item 3): a finding located at its cause
names the motions it leaves, a point's finding names the motions to it (P201 after a call here;
P217, P230 and P231 in tests/test_guards.py, test_rapid.py, test_execution.py, test_rapid_ir.py)."""
from __future__ import annotations

import numpy as np

from postproc.compensation.api import compensate_text
from postproc.model.compensator import load_model
from postproc.programs import ActiveFrames


def test_a_frame_a_call_may_change_names_the_motions_it_leaves(tmp_path):
    from postproc.testing.models import affine_model

    model = load_model(affine_model(tmp_path / "m.onnx", offset=(0.2, -0.1, 0.3), gain=np.diag([1e-3, -2e-3, 1e-3]),
                                    tool={"name": "any"}))
    src = ("DEF t( )\n"                                              # 1
           "  EXT Other( )\n"                                        # 2
           "  $BASE = $NULLFRAME\n"                                  # 3
           "  LIN {X 2000,Y 0,Z 900,A 0,B 90,C 0}\n"                 # 4
           "  Other( )\n"                                            # 5
           "  LIN {X 2010,Y 0,Z 900,A 0,B 90,C 0}\n"                 # 6
           "  IF $IN[1] THEN\n"                                      # 7
           "    LIN {X 2020,Y 5,Z 900,A 0,B 90,C 0}\n"               # 8
           "  ENDIF\n"                                               # 9
           "END\n")
    out, report = compensate_text(src, model, name="t.src", active=ActiveFrames(tool="model"))
    (w,) = [w for w in report.warnings if w.code == "P201"]
    # at the call (the cause), with the two motions it leaves named at their lines
    assert (w.line, w.col) == (5, 3) and "2 target(s) left as written (at t.src:6, t.src:8)" in w.message
    assert report.compensated == 1


def test_a_point_run_from_two_places_names_both_motions(tmp_path):
    """P322 (commanded at the middle of its runs' approaches) says which motions run the point."""
    from postproc.testing.models import affine_model

    model = load_model(affine_model(tmp_path / "p.onnx", offset=(0.2, -0.1, 0.3), gain=np.diag([1e-3, -2e-3, 1e-3]),
                                    previous_gain=3e-5, tool={"name": "any"}))  # runs 0.006 mm apart
    e6 = ",A 0.0,B 90.0,C 0.0,S 2,T 35,E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}"
    src = ("DEF t( )\n  $BASE = $NULLFRAME\n"
           "  LIN XA\n"                                              # 3
           "  LIN XP1\n"                                             # 4
           "  LIN XB\n"                                              # 5
           "  LIN XP1\n"                                             # 6
           "END\n")
    dat = ("DEFDAT t\n"
           f"  DECL E6POS XP1={{X 2000.0,Y 0.0,Z 900.0{e6}\n"
           f"  DECL E6POS XA={{X 1900.0,Y 0.0,Z 900.0{e6}\n"
           f"  DECL E6POS XB={{X 2100.0,Y 0.0,Z 900.0{e6}\n"
           "ENDDAT\n")
    out, report = compensate_text(src, model, name="t.src", dat_text=dat, active=ActiveFrames(tool="model"))
    (note,) = [n for n in report.notes if n.code == "P322"]
    assert note.line == 2 and "the motions at t.src:4, t.src:6" in note.message


def test_p230_names_the_one_cause_that_applies_and_its_remedy(tmp_path):
    """Issue 38, item 5: a two-point FOR loop leaves its first point because its runs come from
    other places (the start, the loop's last point) — said, with where each run comes from and
    what works; a point run in two bases says the bases, not the approach."""
    from postproc.testing.models import affine_model

    model = load_model(affine_model(tmp_path / "a.onnx", offset=(0.2, -0.1, 0.3), gain=np.diag([1e-3, -2e-3, 1e-3]),
                                    previous_gain=2e-3, tool={"name": "any"}))  # the approach matters: 0.1 mm and more
    loop = ("DEF t( )\n  DECL INT I\n  $BASE = $NULLFRAME\n"
            "  PTP {A1 0,A2 -90,A3 90,A4 0,A5 0,A6 0}\n"              # 4
            "  FOR I = 1 TO 2\n"
            "    LIN {X 1900,Y 100,Z 1000,A 0,B 90,C 0}\n"            # 6
            "    LIN {X 2100,Y -200,Z 1100,A 0,B 90,C 0}\n"           # 7
            "  ENDFOR\nEND\n")
    _, report = compensate_text(loop, model, name="t.src", active=ActiveFrames(tool="model"))
    (w,) = [w for w in report.warnings if w.code == "P230"]
    assert w.line == 6 and "its runs come from other places (from the program's start or a joint motion, from t.src:7" \
        in w.message and "approach it the same way in every run" in w.message
    assert "other frames" not in w.message
    bases = ("DEF t( )\n  $BASE = $NULLFRAME\n"
             "  LIN XP1\n"
             "  $BASE = {X 10,Y 20,Z 0,A 5,B 0,C 0}\n"
             "  LIN XP1\n"
             "END\n")
    dat = "DEFDAT t\n  DECL E6POS XP1={X 2000.0,Y 0.0,Z 900.0,A 0.0,B 90.0,C 0.0,S 2,T 35}\nENDDAT\n"
    _, report = compensate_text(bases, model, name="t.src", dat_text=dat, active=ActiveFrames(tool="model"))
    (w,) = [w for w in report.warnings if w.code == "P230"]
    assert "its runs are in other frames (bases)" in w.message and "give each frame its own point" in w.message

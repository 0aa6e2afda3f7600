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

"""The interpreter's check ("never silently wrong", ``postproc.testing.oracle.check``) on what a
controller backup adds: a Fanuc backup's programs with the frames and registers of its .va files
(registers "backup" and "runtime"), a RAPID task of several modules, a routine main does not run
changing a tool (P233), a call to a routine not read (P232) and a task whose robot base the
system parameters move. The original and the compensated programs run on every oracle's path:
every executed target at P + Ê, or left as written and said (then never exit 0)."""
from __future__ import annotations

import numpy as np
import pytest

from postproc.core.resources import sample_path
from postproc.model.compensator import load_model
from postproc.settings import Settings
from postproc.testing.models import affine_model
from postproc.testing.oracle import check

GAIN = np.array([[2e-3, 5e-4, 0.0], [0.0, 1.5e-3, 4e-4], [3e-4, 0.0, 2.5e-3]])
FANUC = sample_path("fanuc/backup")
ROBTARGET = "[[{x},{y},{z}],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]]"


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    path = tmp_path_factory.mktemp("m") / "m.onnx"
    return load_model(affine_model(path, offset=(0.2, -0.1, 0.15), gain=GAIN, previous_gain=5e-5, reach=None,
                                   tool={"name": "any"}))


def _holds(found, exit_code):
    assert found.violations == [], found.violations[:3]
    assert found.paths > 0 and found.motions > 0 and found.compensated > 0
    assert found.exit_code == exit_code


@pytest.mark.parametrize("registers, exit_code", [("backup", 1), ("runtime", 1)])
def test_a_fanuc_backup_with_its_va_files(model, registers, exit_code):
    names = sorted(p.name for p in FANUC.glob("*.ls"))
    files = [str(FANUC / n) for n in names]
    data = {str(p): p.read_text() for p in FANUC.glob("*.va")}
    found = check(files, [(FANUC / n).read_text() for n in names], "fanuc", model, seeds=range(3),
                  data=data, registers=registers)
    _holds(found, exit_code)


def test_a_rapid_task_of_modules_with_p232_and_p233(model):
    data = ("MODULE Data\n"
            "  PERS tooldata tGun := [TRUE,[[0,0,150],[1,0,0,0]],[5,[0,0,100],[1,0,0,0],0,0,0]];\n"
            "  PERS tooldata tSpindle := [TRUE,[[0,0,200],[1,0,0,0]],[5,[0,0,100],[1,0,0,0],0,0,0]];\n"
            f"  CONST robtarget p1 := {ROBTARGET.format(x=1500, y=100, z=900)};\n"
            f"  CONST robtarget p2 := {ROBTARGET.format(x=1600, y=-100, z=950)};\n"
            f"  CONST robtarget p3 := {ROBTARGET.format(x=1550, y=0, z=1000)};\n"
            "ENDMODULE\n")
    main = ("MODULE Main\n"
            "  PROC main()\n"
            "    MoveL p1, v100, fine, tSpindle;\n"
            "    IF DInput(di1) = 1 THEN\n"
            "      MoveL Offs(p2, 0, 0, 50), v100, fine, tSpindle;\n"
            "    ENDIF\n"
            "    MoveL p2, v100, fine, tGun;\n"
            "    MoveL p3, v100, fine, tSpindle;\n"
            "    other_b;\n"
            "    MoveL p1, v100, fine, tSpindle;\n"
            "  ENDPROC\n"
            "  PROC calib()\n"
            "    BEUpdateTcp tGun\\XYZOnly;\n"
            "  ENDPROC\n"
            "ENDMODULE\n")
    found = check(["Data.mod", "Main.mod"], [data, main], "rapid", model, seeds=range(4))
    _holds(found, 1)  # (tGun: P233; other_b: P232)


def test_a_rapid_task_whose_base_the_system_parameters_place(model):
    moc = ("MOC:CFG_1.0:6:0::\n#\nROBOT:\n\n      -name \"ROB_1\" -use_robot_type \"ROB1\" -base_frame_pos_x 0.25"
           " -base_frame_orient_u0 0.707106781 -base_frame_orient_u3 0.707106781\n")
    text = ("MODULE M\n"
            f"  CONST robtarget pA := {ROBTARGET.format(x=1500, y=300, z=900)};\n"
            "  PROC main()\n"
            "    MoveL pA, v100, fine, tool0;\n"
            f"    MoveL {ROBTARGET.format(x=1700, y=0, z=1000)}, v100, fine, tool0;\n"
            "  ENDPROC\nENDMODULE\n")
    found = check(["m.mod"], [text], "rapid", model, seeds=range(2), data={"SYSPAR/MOC.cfg": moc},
                  settings=Settings().override(max_correction_mm=50.0))  # (the base turned: far from the centre)
    _holds(found, 0)

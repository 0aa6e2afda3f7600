"""Several files of every family are one run (issue 37, item 1): RAPID modules given together
are one task, a directory of modules or a backup's RAPID/TASKn folders are tasks, several LS
programs are one program, URScript programs and pose lists each their own; files of two robot
families, a file no reader takes, binary TP programs without their .ls are refused; never
``0 of 0`` over files that were not read. The summary says per file what was compensated."""
import re
import shutil

import numpy as np
import pytest

from postproc.cli import main
from postproc.programs import STAMP_PREFIX

from helpers import REPO, SYS_CFG

GAIN = np.diag([1e-3, 2e-3, -1e-3])  # a correction that varies over space: a frame or file mix-up shows
WELD = REPO / "samples/rapid/weld_cell.mod"
FANUC = REPO / "samples/fanuc"


def split_module(text: str) -> tuple[str, str]:
    """weld_cell.mod as two modules: its data (the declarations before the first PROC) and its routines."""
    lines = text.splitlines(keepends=True)
    first_proc = next(i for i, line in enumerate(lines) if line.lstrip().startswith("PROC"))
    data = [line for line in lines[1:first_proc] if not line.lstrip().startswith("!")]
    return ("MODULE Data\n" + "".join(data) + "ENDMODULE\n",
            "MODULE Main\n" + "".join(lines[first_proc:]))


def robtargets(text: str) -> dict[str, str]:
    """Each declared robtarget's name → its value as written (the declarations, in any module)."""
    return {m.group(1): re.sub(r"\s+", "", m.group(2))
            for m in re.finditer(r"robtarget\s+(\w+)(?:\{\d+\})?\s*:=\s*(\[.*?\]);", text, re.S)}


def compensate(*args):
    return main(["compensate", *map(str, args)])


@pytest.fixture
def model(affine):
    return affine(gain=GAIN, tool={"name": "weld", "frame": [0.0, 0.0, 200.0, 0.0, 0.0, 0.0]})


@pytest.fixture
def task(tmp_path):
    data, main_module = split_module(WELD.read_text())
    folder = tmp_path / "task"
    folder.mkdir()
    (folder / "Data.mod").write_text(data)
    (folder / "Main.mod").write_text(main_module)
    return folder


def test_rapid_modules_given_together_are_one_task(task, model, tmp_path, capsys):
    alone = tmp_path / "alone.mod"
    assert compensate(WELD, "-o", alone, "--model", model) == 1  # (RelTool's target: P231, as alone)
    err_alone = capsys.readouterr().err
    out = tmp_path / "out"
    assert compensate(task / "Data.mod", task / "Main.mod", "-o", out, "--model", model) == 1
    err = capsys.readouterr().err
    summary = err.splitlines()[-1]
    assert summary.split(";")[0] == next(line for line in err_alone.splitlines()
                                         if line.startswith("postproc: ")).split(";")[0]
    assert not summary.startswith("postproc: 0 of 0")
    # the data module's numbers are the single module's, compensated in the frames of the other module's motions
    assert robtargets((out / "Data.mod").read_text()) == robtargets(alone.read_text())
    assert robtargets((out / "Data.mod").read_text()) != robtargets((task / "Data.mod").read_text())
    assert STAMP_PREFIX in (out / "Data.mod").read_text()
    assert (out / "Main.mod").read_text() == (task / "Main.mod").read_text()  # (no numbers in it: as it was)
    # per file, what was compensated
    assert f"postproc:   {out / 'Data.mod'}: " in err and f"postproc:   {out / 'Main.mod'}: " in err
    # a directory of modules: the same task
    assert compensate(task, "-o", tmp_path / "dir", "--model", model) == 1
    assert (tmp_path / "dir" / "Data.mod").read_bytes() == (out / "Data.mod").read_bytes()


def test_check_reads_rapid_modules_as_one_task(task, model, capsys):
    assert main(["check", str(task / "Main.mod"), str(task / "Data.mod"), "--model", str(model)]) == 0
    out = capsys.readouterr().out
    assert "P215" not in out  # (p10 … are declared in Data.mod, given with it)
    assert main(["check", str(task / "Main.mod"), "--model", str(model)]) == 0
    assert "P215" in capsys.readouterr().out  # (alone: not declared in the files read, said)


def backup_tree(root, weld_text):
    """RAPID/TASK1/PROGMOD + SYSMOD and RAPID/TASK2/PROGMOD: two motion tasks whose data share names."""
    data, main_module = split_module(weld_text)
    for task, shift in (("TASK1", 0.0), ("TASK2", 400.0)):
        prog = root / "RAPID" / task / "PROGMOD"
        prog.mkdir(parents=True)
        (root / "RAPID" / task / "SYSMOD").mkdir()
        (prog / "Main.mod").write_text(main_module)
        # the second task's robot works elsewhere: its p10 has other numbers than the first's
        (prog / "Data.mod").write_text(data.replace("[[150.5,200,50]", f"[[{150.5 + shift},200,50]"))
        (root / "RAPID" / task / "SYSMOD" / "user.sys").write_text("MODULE user(SYSMODULE)\n  VAR num reg1:=0;\nENDMODULE\n")
    (root / "BACKINFO").mkdir()
    (root / "BACKINFO" / "backinfo.txt").write_text(">>TASK1: (T_ROB1,,)\n>>TASK2: (T_ROB2,,)\n")
    return root


def test_a_rapid_backup_is_its_tasks_each_read_as_one_and_written_as_a_mirrored_tree(model, tmp_path, capsys):
    backup = backup_tree(tmp_path / "BACKUP", WELD.read_text())
    out = tmp_path / "out"
    assert compensate(backup, "-o", out, "--model", model) == 1
    err = capsys.readouterr().err
    written = sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file())
    assert written == ["RAPID/TASK1/PROGMOD/Data.mod", "RAPID/TASK1/PROGMOD/Main.mod", "RAPID/TASK1/SYSMOD/user.sys",
                       "RAPID/TASK2/PROGMOD/Data.mod", "RAPID/TASK2/PROGMOD/Main.mod", "RAPID/TASK2/SYSMOD/user.sys"]
    one = robtargets((out / "RAPID/TASK1/PROGMOD/Data.mod").read_text())
    two = robtargets((out / "RAPID/TASK2/PROGMOD/Data.mod").read_text())
    # each task's p10 compensated for its own numbers (the model's correction varies over space)
    assert one["p10"] != two["p10"] and one["p20"] == two["p20"]
    alone = tmp_path / "alone.mod"
    assert compensate(WELD, "-o", alone, "--model", model) == 1
    assert one == robtargets(alone.read_text())
    # (the summary counts both tasks; a file line for each file written)
    assert sum(line.startswith("postproc:   ") for line in err.splitlines()) == 6


def test_several_ls_programs_are_one_run(model, tmp_path, capsys):
    r2000 = "r2000ic"
    one, two = tmp_path / "a.ls", tmp_path / "b.ls"
    text = (FANUC / "weld_seam.ls").read_text()
    one.write_text(text)
    two.write_text(text.replace("WELD_SEAM", "WELD_TWO").replace("X =   250.000", "X =   290.000"))
    out = tmp_path / "out"
    code = compensate(one, two, "-o", out, "--model", r2000, "--frames", FANUC / "frames.toml")
    err = capsys.readouterr().err
    assert code in (0, 1) and " 0 of 0 " not in err
    done = {line[len("postproc:   "):].split(": ")[0]: line for line in err.splitlines() if line.startswith("postproc:   ")}
    assert set(done) == {str(out / "a.ls"), str(out / "b.ls")}
    assert all(" compensated" in line and not line.endswith(": 0 of 0 compensated") for line in done.values())
    assert (out / "a.ls").read_text() != one.read_text() and (out / "b.ls").read_text() != two.read_text()


def test_urscript_programs_and_pose_lists_are_each_their_own_program(tmp_path, affine, capsys):
    model = affine(gain=GAIN)
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    a.write_text("x,y,z,a,b,c\n1500,0,1000,0,90,0\n1600,100,1100,0,90,0\n")
    b.write_text("x,y,z,a,b,c\n1400,-100,900,0,90,0\n")
    out = tmp_path / "out"
    assert compensate(a, b, "-o", out, "--model", model) == 0
    err = capsys.readouterr().err
    assert "postproc: 3 of 3 compensated" in err
    assert f"{out / 'a.csv'}: 2 of 2 compensated" in err and f"{out / 'b.csv'}: 1 of 1 compensated" in err
    # each file compensated as it is alone
    alone = tmp_path / "b_alone.csv"
    assert compensate(b, "-o", alone, "--model", model) == 0
    assert (out / "b.csv").read_bytes() == alone.read_bytes()


@pytest.mark.parametrize("names", [("a.script", "b.ls"), ("a.src", "b.mod"), ("a.mod", "b.script")])
def test_programs_of_two_robot_families_are_refused_and_nothing_is_written(names, tmp_path, capsys):
    texts = {".script": "def prog():\n  movel(p[0.5,0.1,0.4,0,3.14,0], a=1, v=0.1)\nend\n",
             ".ls": (FANUC / "weld_seam.ls").read_text(), ".src": "DEF a()\n  LIN {X 1500,Y 0,Z 1000,A 0,B 90,C 0}\nEND\n",
             ".mod": "MODULE b\n  PROC main()\n    MoveL [[1500,0,1000],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]],v100,fine,tool0;\n  ENDPROC\nENDMODULE\n"}
    paths = []
    for name in names:
        path = tmp_path / name
        path.write_text(texts[path.suffix])
        paths.append(path)
    out = tmp_path / "out"
    assert compensate(*paths, "-o", out) == 2
    err = capsys.readouterr().err
    assert "P119 programs of 2 robot families given as one run" in err
    assert not out.exists()


def test_a_file_no_reader_takes_and_binary_tp_programs_are_refused(tmp_path, capsys):
    good = tmp_path / "a.ls"
    good.write_text((FANUC / "weld_seam.ls").read_text())
    odd = tmp_path / "notes.doc"
    odd.write_text("x")
    assert compensate(good, odd, "-o", tmp_path / "out") == 2
    assert f"{odd}: P108 unknown program type '.doc'" in capsys.readouterr().err
    backup = tmp_path / "MD"
    backup.mkdir()
    shutil.copy(good, backup / "A.LS")
    (backup / "A.TP").write_bytes(b"\x00\x01")
    (backup / "B.TP").write_bytes(b"\x00\x01")  # (no B.LS: its targets would not be read)
    assert compensate(backup, "-o", tmp_path / "out2", "--frames", FANUC / "frames.toml") == 2
    err = capsys.readouterr().err
    assert f"{backup / 'B.TP'}: P107 1 binary TP program (.tp) without its ASCII .ls (B.TP)" in err
    assert not (tmp_path / "out2").exists()
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "readme.txt").write_text("nothing here")
    assert compensate(empty, "-o", tmp_path / "out3") == 2
    assert "P107 no programs here" in capsys.readouterr().err


MOC_CFG = """MOC:CFG_1.0:6:0::
#
MECHANICAL_UNIT:

      -name "TRACK_1" -use_single_0 "TRACK_1"
#
MECHANICAL_UNIT_GROUP:

      -name "rob1" -robot "ROB_1"

      -name "rob2" -robot "ROB_2" -mech_unit_1 "TRACK_1"
#
ROBOT:

      -name "ROB_1" -use_robot_type "ROB1_6700" -base_frame_pos_x 0.2

      -name "ROB_2" -use_robot_type "ROB2_6700" -base_frame_coordinated "TRACK_1"
"""


def test_a_multimove_backup_reads_each_tasks_robot_from_its_system_parameters(model, tmp_path, capsys):
    """A backup of two motion tasks with SYSPAR: T_ROB1's robot stands 200 mm along the world's x
    (its targets compensated in its own base), T_ROB2's base rides a track (every target left,
    MOC.cfg's line named); one output tree, a line per file."""
    backup = backup_tree(tmp_path / "BACKUP", WELD.read_text())
    (backup / "SYSPAR").mkdir()
    (backup / "SYSPAR" / "SYS.cfg").write_text(SYS_CFG)
    (backup / "SYSPAR" / "MOC.cfg").write_text(MOC_CFG)
    out = tmp_path / "out"
    assert compensate(backup, "-o", out, "--model", model) == 1
    err = capsys.readouterr().err
    assert f"{backup / 'SYSPAR' / 'MOC.cfg'}:17" in err and "P225" in err and "TRACK_1" in err
    two = robtargets((out / "RAPID/TASK2/PROGMOD/Data.mod").read_text())
    assert two == robtargets((backup / "RAPID/TASK2/PROGMOD/Data.mod").read_text())  # (left as written)
    # T_ROB1: the same as the task alone with the world shifted by its base frame
    one = robtargets((out / "RAPID/TASK1/PROGMOD/Data.mod").read_text())
    plain = tmp_path / "plain"
    backup_tree(plain, WELD.read_text())
    assert compensate(plain, "-o", tmp_path / "plain_out", "--model", model) == 1
    unshifted = robtargets((tmp_path / "plain_out/RAPID/TASK1/PROGMOD/Data.mod").read_text())
    assert one["pHome"] != unshifted["pHome"]  # (pHome is in wobj0: the world, 200 mm from this robot's base)
    assert not (out / "SYSPAR").exists()  # (system parameters: read, not written)


def test_modules_beside_a_backups_tasks_are_each_read_alone(model, tmp_path, capsys):
    """A backup's HOME/ may hold copies of modules no task loads: each is read alone (two copies
    declaring the same routine are not one task), compensated or left as it says, written too."""
    backup = backup_tree(tmp_path / "BACKUP", WELD.read_text())
    (backup / "HOME").mkdir()
    for name in ("old.mod", "older.mod"):
        shutil.copy(WELD, backup / "HOME" / name)
    out = tmp_path / "out"
    assert compensate(backup, "-o", out, "--model", model) == 1
    alone = tmp_path / "alone.mod"
    assert compensate(WELD, "-o", alone, "--model", model) == 1
    assert (out / "HOME/old.mod").read_bytes() == (out / "HOME/older.mod").read_bytes() == alone.read_bytes()
    assert "P102" not in capsys.readouterr().err

"""A FANUC backup read as one unit (issue 37, item 3): every .ls together (a CALL runs the
program called), the frames of sysframe.va, the registers of posreg.va / numreg.va where no TP
program read sets them — each use said at its line (P234) —, registers = "runtime", malformed
.va files refused at their line. The sample is samples/fanuc/backup/; what the reader gives is
compared with the same frames stated in a frame file, with frames composed by hand (scipy), and
with the commands an affine model (a correction that varies over space) gives."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from postproc.compensation.api import settings_of
from postproc.compensation.pipeline import compensate_program
from postproc.core.diagnostics import PostprocError
from postproc.core.resources import sample_path
from postproc.model.compensator import load_model
from postproc.programs import fanuc
from postproc.programs.base_poses import robot_base_poses

SAMPLE = sample_path("fanuc/backup")
PROGRAMS = ("main.ls", "pick.ls", "place.ls", "service.ls")
VA = ("sysframe.va", "posreg.va", "numreg.va")
# the frames the sample's sysframe.va holds ($MNUFRAME[1,n], $MNUTOOL[1,n]: x, y, z mm, w, p, r deg)
UF = {1: [1250.0, -350.0, -420.0, 0.0, 0.0, 90.0], 2: [900.0, 600.0, -380.5, 1.25, -0.75, -30.0]}
UT = {1: [0.0, 0.0, 250.0, 0.0, 0.0, 0.0], 2: [12.5, 0.0, 185.0, 0.0, -30.0, 0.0], 3: [0.0, 45.0, 120.0, 0.0, 0.0, 90.0]}
OFFSET = np.array([0.3, -0.2, 0.1])
GAIN = np.array([[2e-3, 0, 0], [0, -1e-3, 5e-4], [0, 0, 3e-3]])
CENTRE = np.array([1500.0, 0.0, 0.0])


def toml(uf=UF, ut=UT) -> str:
    out = [f"[uframe.{n}]\nxyzwpr = {v}" for n, v in uf.items()]
    return "\n".join(out + [f"[utool.{n}]\nxyzwpr = {v}" for n, v in ut.items()]) + "\n"


def text(name: str) -> str:
    return (SAMPLE / name).read_text(encoding="latin-1")


def files(names=PROGRAMS):
    return [str(SAMPLE / n) for n in names], [text(n) for n in names]


def va(names=VA, **edited) -> dict:
    out = {str(SAMPLE / n): text(n) for n in names}
    for name, new in edited.items():
        out[str(SAMPLE / name.replace("_", "."))] = new
    return out


def read(names=PROGRAMS, backup=None, **options):
    paths, texts = files(names)
    return fanuc.read(paths, texts, va=va() if backup is None else backup, **options)


def line_of(name: str, needle: str) -> int:
    """The line of ``name`` that holds ``needle`` (1-based)."""
    return next(k for k, line in enumerate(text(name).splitlines(), 1) if needle in line)


def record(name: str, n: int) -> tuple[np.ndarray, np.ndarray]:
    """P[n] of ``name``'s /POS as written: (x, y, z), (w, p, r)."""
    body = text(name)[text(name).index("/POS"):]
    block = re.search(r"P\[%d\]\{(.*?)\};" % n, body, re.S).group(1)
    v = {k: float(x) for k, x in re.findall(r"\b([XYZWPR])\s*=\s*(-?[\d.]+)", block)}
    return np.array([v["X"], v["Y"], v["Z"]]), np.array([v["W"], v["P"], v["R"]])


def matrix(xyzwpr) -> np.ndarray:
    """A FANUC x, y, z, w, p, r as 4×4 (w, p, r: fixed angles about X, Y, Z), composed with scipy."""
    m = np.eye(4)
    m[:3, :3] = Rotation.from_euler("xyz", xyzwpr[3:], degrees=True).as_matrix()
    m[:3, 3] = xyzwpr[:3]
    return m


def rows_of(p, name: str) -> np.ndarray:
    return np.flatnonzero(np.array(p.files)[p.targets.file] == str(SAMPLE / name))


def said(p, code):
    return [(d.path.split("/")[-1], d.line, d.message) for d in p.diagnostics + p.notes if d.code == code]


def test_frames_of_sysframe_va_are_the_frames_of_a_frame_file():
    a = read()
    b = read(backup=va(("posreg.va", "numreg.va")), frames=[toml()])
    ta, tb = a.targets, b.targets
    assert len(ta) == len(tb) == 7 and (ta.frame >= 0).all()
    for column in ("file", "line", "motion"):
        assert getattr(ta, column).tolist() == getattr(tb, column).tolist()
    assert np.allclose(ta.poses, tb.poses) and np.allclose(ta.offset, tb.offset)
    for r in range(len(ta)):
        fa, fb = a.frames[ta.frame[r]], b.frames[tb.frame[r]]
        assert np.allclose(fa.base, fb.base) and np.allclose(fa.tool, fb.tool)
    assert np.allclose(robot_base_poses(a)[0], robot_base_poses(b)[0])
    # the frame file states its frames: no note says they are the backup's
    assert [m for _, _, m in said(b, "P234") if m.startswith(("UF", "UT"))] == []
    # by hand: PICK's P[2] (selected by MAIN: UF 1, UT 2) in the world
    row = rows_of(a, "pick.ls")[1]
    xyz, _ = record("pick.ls", 2)
    assert np.allclose(robot_base_poses(a)[0][row, :3], (matrix(UF[1]) @ np.r_[xyz, 1])[:3])
    assert np.allclose(a.frames[ta.frame[row]].tool, np.r_[UT[2][:3], UT[2][3:][::-1]])


def test_tool_offset_of_a_register_the_backup_holds_is_the_shift_in_the_tool_frame():
    p = read()
    main = rows_of(p, "main.ls")
    base = robot_base_poses(p)[0]
    # MAIN: L P[1] … Tool_Offset,PR[16] (posreg.va: X, Y, Z = 0, 0, -100 in the tool frame of P[1])
    xyz, wpr = record("main.ls", 1)
    shifted = matrix(np.r_[xyz, wpr]) @ matrix([0, 0, -100.0, 0, 0, 0])
    assert np.allclose(base[main[0], :3], (matrix(UF[1]) @ shifted)[:3, 3])
    assert np.allclose(p.targets.offset[main[0]], shifted[:3, 3] - xyz)
    # L P[2] … Tool_Offset,PR[15]: a zero offset, P[2] itself (its numbers are rewritten as they stand)
    xyz, _ = record("main.ls", 2)
    assert np.allclose(p.targets.poses[main[1], :3], xyz) and not p.targets.offset[main[1]].any()


def test_a_register_a_tp_program_sets_stays_a_run_time_value():
    p = read()
    # SERVICE moves to PR[20], which PICK sets (PR[20]=LPOS): posreg.va's value is what the last run left
    line = line_of("service.ls", "L PR[20]")
    (found,) = [m for f, n, m in said(p, "P211") if f == "service.ls" and n == line]
    assert "PICK" in found.upper() and "pick.ls" in found and "posreg.va" in found
    assert not any("PR[20]" in m for _, _, m in said(p, "P234"))
    # read without PICK, no TP program read sets it: the backup's value, said (a register's value in a .va file
    # is no number of the program: its motion is left as written, P211, naming the file)
    q = read(("service.ls",))
    assert any(f == "service.ls" and n == line and "PR[20]" in m for f, n, m in said(q, "P234"))
    assert any(n == line and "posreg.va" in m and "read only" in m for _, n, m in said(q, "P211"))


def test_each_use_of_a_backup_value_is_a_located_note_once_per_register_and_file():
    p = read()
    notes = said(p, "P234")
    assert all(d.severity == "note" for d in p.notes if d.code == "P234")
    pr1 = [(f, n) for f, n, m in notes if m.startswith("PR[1] ")]
    # PR[1] (HOME): MAIN moves to it twice, SERVICE once: said once in each file, at the first
    assert pr1 == [("main.ls", line_of("main.ls", "J PR[1:HOME]")), ("service.ls", line_of("service.ls", "J PR[1"))]
    assert any(f == "place.ls" and n == line_of("place.ls", "IF R[5") and "numreg.va" in m for f, n, m in notes)
    assert any(f == "main.ls" and "PR[16]" in m and "posreg.va" in m for f, n, m in notes)
    assert any(f == "pick.ls" and m.startswith("UF 1 ") and "sysframe.va" in m for f, n, m in notes)
    # R[5] = 1 (numreg.va): PLACE jumps over its P[1]
    assert len(rows_of(p, "place.ls")) == 2


def test_registers_runtime_leaves_what_depends_on_them():
    p = read(registers="runtime")
    left = {(f, n) for f, n, _ in said(p, "P211")}
    for needle in ("Tool_Offset,PR[16]", "Tool_Offset,PR[15]"):
        assert ("main.ls", line_of("main.ls", needle)) in left
    assert not [m for _, _, m in said(p, "P234") if m.startswith(("PR[", "R["))]
    # R[5] not known: PLACE's P[1] may run, and P[2] is reached from it or from the start of PLACE
    place = rows_of(p, "place.ls")
    assert len(rows_of(p, "main.ls")) == 0 and len(set(p.targets.line[place].tolist())) == 3
    assert len(rows_of(p, "pick.ls")) == 3  # (the frames are still sysframe.va's)


def test_call_across_files_runs_the_program_called():
    alone = read(("pick.ls",))
    assert alone.targets.prev[0] == -1  # (where the robot stands before PICK is not known)
    p = read(("main.ls", "pick.ls"))
    t = p.targets
    main, pick = rows_of(p, "main.ls"), rows_of(p, "pick.ls")
    # in execution order: MAIN's two motions, then PICK's (CALL PICK), its first after MAIN's last
    assert main.tolist() == [0, 1] and pick.tolist() == [2, 3, 4] and t.prev[pick[0]] == main[-1]
    assert np.allclose(t.poses[pick], alone.targets.poses) and (t.frame >= 0).all()
    # two files of one program
    paths, texts = files(("pick.ls", "pick.ls"))
    with pytest.raises(PostprocError) as e:
        fanuc.read(paths, texts, va=va())
    assert e.value.line == 1 and "PICK" in e.value.message


def test_a_frame_file_that_contradicts_sysframe_va_is_said_not_chosen():
    agree = read(frames=[toml()])
    assert (agree.targets.frame >= 0).all()
    other = dict(UF)
    other[1] = [1250.0, -350.0, -419.0, 0.0, 0.0, 90.0]
    p = read(frames=[toml(uf=other)])
    uf1 = np.flatnonzero(p.targets.frame < 0)
    assert len(uf1) == 5 and not len(np.intersect1d(uf1, rows_of(p, "place.ls")))
    (message,) = {m for _, _, m in said(p, "P201")}
    assert "UF 1" in message and "-419" in message and "-420" in message and "$MNUFRAME[1,1]" in message


def test_a_frame_a_tp_program_sets_is_not_the_backups():
    setter = text("service.ls").replace("/PROG  SERVICE", "/PROG  SETUF").replace("UFRAME_NUM=1", "UFRAME[2]=PR[15]")
    paths, texts = files(("place.ls",))
    p = fanuc.read(paths + ["setuf.ls"], texts + [setter], va=va())
    assert (p.targets.frame[rows_of(p, "place.ls")] < 0).all()
    assert any("setuf.ls" in m and "UF 2" in m for _, _, m in said(p, "P201"))


SYSFRAME = text("sysframe.va")
POSREG = text("posreg.va")


def _edit(source: str, old: str, new: str) -> str:
    assert old in source
    return source.replace(old, new, 1)


@pytest.mark.parametrize("name, edited, needle, message", [
    ("posreg.va", _edit(POSREG, "  W:     0.000   P:     0.000   R:     0.000\n", ""), "    [1,16]",
     "expected 'W: …"),
    ("posreg.va", _edit(POSREG, "X:     0.000   Y:     0.000   Z:  -100.000", "X:     0.000   Y:  0.0.0   Z:  -100.000"),
     "Y:  0.0.0", "not a component"),
    ("sysframe.va", _edit(SYSFRAME, "    [1,2] = \n  Group: 1", "    [1,2] = \n  Group: 2"), "  Group: 2",
     "says Group: 2"),
    ("sysframe.va", _edit(SYSFRAME, "    [1,3] = ", "    [1,2] = "), "    [1,2] = ", "twice"),
    ("numreg.va", _edit(text("numreg.va"), "[5] = 1  'PLACE MODE'", "[5] = one  'PLACE MODE'"), "[5] = one",
     "$NUMREG element"),
])
def test_a_malformed_va_is_refused_at_its_line(name, edited, needle, message):
    backup = va()
    backup[str(SAMPLE / name)] = edited
    with pytest.raises(PostprocError) as e:
        read(backup=backup)
    lines = edited.splitlines()
    want = [k for k, line in enumerate(lines, 1) if needle in line]
    assert e.value.code == "P118" and e.value.path == str(SAMPLE / name) and message in e.value.message
    assert e.value.line in want or e.value.line - 1 in want  # (at the element, or the line where its value breaks)
    assert e.value.col >= 1


def test_a_va_of_another_kind_is_not_read():
    p = read(backup={**va(), str(SAMPLE / "system.va"): "anything at all\n"})
    assert len(p.targets) == len(read().targets)


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    from postproc.testing.models import affine_model

    path = affine_model(tmp_path_factory.mktemp("lsbackup") / "affine.onnx", offset=OFFSET, gain=GAIN, centre=CENTRE,
                        reach=None, tool={"name": "any"})
    return load_model(path)


def test_the_backup_compensates_as_the_same_programs_with_a_frame_file(model):
    """The commands of the backup read with sysframe.va equal those of the programs read with the same
    frames in a frame file, and each equals c = P + E(P) composed by hand (one iteration)."""
    settings = settings_of(None, {"iterations": 1, "max_correction_mm": 50.0})
    reports = []
    for options in ({"va": va()}, {"va": va(("posreg.va", "numreg.va")), "frames": [toml()]}):
        program = fanuc.read(*files(), **options)
        program.config = options.get("frames")
        reports.append(compensate_program(program, model, settings))
    a, b = reports
    assert a.compensated == b.compensated == 6 and a.outputs == b.outputs  # (SERVICE's PR[20] is left in both)
    # by hand: MAIN's P[1] with Tool_Offset,PR[16]: the controller's target, commanded, back in UF 1, minus the shift
    xyz, wpr = record("main.ls", 1)
    target = matrix(np.r_[xyz, wpr]) @ matrix([0, 0, -100.0, 0, 0, 0])
    world = (matrix(UF[1]) @ target)[:3, 3]
    commanded = world + OFFSET + GAIN @ (world - CENTRE)
    local = (np.linalg.inv(matrix(UF[1])) @ np.r_[commanded, 1])[:3]
    new = a.outputs[str(SAMPLE / "main.ls")]
    block = re.search(r"P\[1\]\{(.*?)\};", new[new.index("/POS"):], re.S).group(1)
    got = np.array([float(re.search(k + r"\s*=\s*(-?[\d.]+)", block).group(1)) for k in "XYZ"])
    assert np.allclose(got, local - (target[:3, 3] - xyz), atol=6e-4)


def test_the_backup_directory_through_the_cli_is_one_run_mirrored(model, tmp_path, capsys):
    """`postproc compensate BACKUP/ -o OUT`: every .ls with the .va files (programs.cell), the
    outputs as the API's, the .va files read and not written, a line per file written."""
    from postproc.cli import main

    out = tmp_path / "out"
    assert main(["compensate", str(SAMPLE), "-o", str(out), "--model", str(model.path), "--iterations", "1",
                 "--max-correction", "50", "--max-std", "inf"]) == 1  # (SERVICE's PR[20]: run-time, left)
    err = capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == sorted(p.name for p in SAMPLE.glob("*.ls"))
    settings = settings_of(None, {"iterations": 1, "max_correction_mm": 50.0})
    report = compensate_program(fanuc.read(*files(), va=va()), model, settings)
    for name, text in report.outputs.items():
        assert (out / Path(name).name).read_text() == text
    assert "P234" not in err or "-v" in err  # (notes: printed with -v)
    assert sum(line.startswith("postproc:   ") for line in err.splitlines()) == len(list(SAMPLE.glob("*.ls")))
    # registers = runtime: the Tool_Offset motions are left too
    assert main(["compensate", str(SAMPLE), "-o", str(tmp_path / "rt"), "--model", str(model.path), "--iterations",
                 "1", "--max-correction", "50", "--max-std", "inf", "--registers", "runtime"]) == 1
    assert "P211" in capsys.readouterr().err

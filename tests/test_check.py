"""postproc check: findings on pose programs, stamps, settings, freshness of outputs; CLI exit codes."""
import os
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from postproc.compensation.check import check_files, check_fresh, check_program, failed, find_stamps, program_paths
from postproc.cli import main
from postproc.compensation.api import compensate_text
from postproc.programs.io import parse_program_text
from postproc.model.compensator import load_model
from postproc.settings import Settings, load_settings
from postproc.core.diagnostics import PostprocError
from postproc.programs import STAMP_PREFIX, Program, TargetsBuilder

from postproc.testing.models import DEFAULT_ENVELOPE, DEFAULT_REACH

# rows 2..6: inside everything / outside the envelope box / beyond the reach sphere / inside the
# reach sphere's hole / attitude out of the envelope's range
ROWS = [
    (2000, 0, 900, 0, 90, 0),
    (1000, 0, 900, 0, 90, 0),
    (5000, 0, 900, 0, 90, 0),
    (600, 0, 1100, 0, 90, 0),
    (2000, 0, 900, 0, 60, 0),
]
TEXT = "x,y,z,a,b,c\n" + "".join(",".join(map(str, r)) + "\n" for r in ROWS)


def expected_codes():
    """Per-row findings computed from the model's metadata by hand, not by postproc."""
    box = np.array(DEFAULT_ENVELOPE["box"], float)
    out = set()
    for line, row in enumerate(ROWS, start=2):
        p = np.array(row, float)
        r = np.linalg.norm(p[:3] - DEFAULT_REACH["center"])
        if r > DEFAULT_REACH["radius_max"] or r < DEFAULT_REACH["radius_min"]:
            out.add((line, "P302"))
        inside = np.all(p[:3] >= box[0::2] - 1) and np.all(p[:3] <= box[1::2] + 1)
        if not inside or np.any(np.abs(p[3:] - DEFAULT_ENVELOPE["attitude"]) > DEFAULT_ENVELOPE["range"] + 0.5):
            out.add((line, "P301"))
    return out


def write(path, text):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(text.encode("latin-1"))
    return path


def test_reach_and_envelope_findings_point_at_their_rows(affine, tmp_path):
    path = write(tmp_path / "p.csv", TEXT)
    found = check_files([path], load_model(affine()))
    assert {(d.line, d.code) for d in found} == expected_codes()
    assert {d.code for d in found if d.severity == "error"} == {"P302"}
    assert all(d.path == str(path) and d.col == 1 for d in found)
    assert failed(found) and failed([d for d in found if d.code == "P301"], strict=True)
    assert not failed([d for d in found if d.code == "P301"])


def test_model_nan_and_implausible_corrections(affine, tmp_path):
    path = write(tmp_path / "p.csv", "x,y,z,a,b,c\n2000,0,900,0,90,0\n")
    assert [d.code for d in check_files([path], load_model(affine(offset=(6.0, 0, 0))))] == ["P303"]
    assert check_files([path], load_model(affine(offset=(6.0, 0, 0))), Settings().override(max_correction_mm=7.0)) == []
    assert [d.code for d in check_files([path], load_model(affine(offset=(float("nan"), 0, 0))))] == ["P305"]


def test_ik_reachability_is_passed_in(affine):
    program = parse_program_text(TEXT, "p.csv")
    rejected = []

    def reachable(poses):
        rejected.append(poses.copy())
        return poses[:, 0] < 1500  # pretend only the near targets have an IK solution

    found = check_program(program, load_model(affine()), reachable=reachable)
    # rows beyond the reach sphere are P302 only; the others the callable rejects are P309
    assert sorted(d.line for d in found if d.code == "P309") == [2, 6]
    assert np.allclose(rejected[0][:, :3], np.array(ROWS, float)[:, :3])


def test_stamps_other_model_twice_and_mixed_module(affine):
    model, other = load_model(affine(offset=(0.1, 0, 0))), load_model(affine(offset=(0.2, 0, 0), name="cell 7"))
    good = TEXT.splitlines(keepends=True)[0] + TEXT.splitlines(keepends=True)[1]
    once, _ = compensate_text(good, model, name="p.csv")
    assert check_program(parse_program_text(once, "p.csv"), model) == []
    by_other, _ = compensate_text(good, other, name="p.csv")
    (d,) = check_program(parse_program_text(by_other, "p.csv"), model)
    assert (d.code, d.line, d.col) == ("P402", 1, 1) and f"cell 7 {other.sha256[:12]}" in d.message
    twice, _ = compensate_text(once, model, name="p.csv", force=True)
    found = check_program(parse_program_text(twice, "p.csv"), model)
    assert [(d.code, d.line) for d in found] == [("P403", 2)]
    # a module whose .src and .dat carry different stamps (or one carries none)
    stamp = f"; {STAMP_PREFIX} {model.name} {model.sha256[:12]}"
    empty = TargetsBuilder().build()
    # (a .dat without targets is not stamped: compensate changed nothing in it)
    for dat, expected in (("DEFDAT a\nENDDAT\n", []),
                          (f"&ACCESS RVP\n; {STAMP_PREFIX} {other.name} {other.sha256[:12]}\nDEFDAT a\n",
                           [("a.src", "P404"), ("a.dat", "P404")])):
        program = Program(["a.src", "a.dat"], [f"{stamp}\nDEF a()\nEND\n", dat], empty)
        found = [(d.path, d.code) for d in check_program(program, model) if d.code == "P404"]
        assert found == expected
    assert [(s.file, s.line, s.name) for s in find_stamps(program)] == [(0, 1, model.name), (1, 2, other.name)]


def test_syntax_errors_and_unreadable_files_are_findings(affine, tmp_path):
    bad = write(tmp_path / "bad.csv", "x,y,z\n1,zz,3\n")
    found = check_files([bad, tmp_path / "none.csv", write(tmp_path / "a.xyz.doc", "1 2 3\n")], load_model(affine()))
    assert [(d.path, d.line, d.col, d.code) for d in found] == [
        (str(tmp_path / "a.xyz.doc"), 0, 0, "P108"),
        (str(bad), 2, 3, "P103"),
        (str(tmp_path / "none.csv"), 0, 0, "P107"),
    ]


def test_a_directory_is_searched_for_every_dialects_programs(affine, tmp_path):
    """``check DIR`` finds RAPID, URScript and Fanuc LS programs beside KRL ones (it found KRL
    only: the others were skipped without a word), not pose lists (a folder holds measurement
    CSVs and notes too); each file's findings are those of checking it alone."""
    import shutil

    from helpers import REPO

    folder = tmp_path / "cell"
    folder.mkdir()
    for sample in ("rapid/weld_cell.mod", "urscript/pick_place.script", "fanuc/weld_seam.ls"):
        shutil.copy(REPO / "samples" / sample, folder)
    broken = write(folder / "broken.script", "def broken():\n  movel(p[0.5, 0.1, 0.4, 0, 3.14, 0]\nend\n")
    write(folder / "measured.csv", "x,y,z\n1,zz,3\n")  # not a program: not checked
    model = load_model(affine())
    found = check_files([folder], model)
    alone = sorted((d for f in sorted(folder.iterdir()) if f.suffix != ".csv" for d in check_files([f], model)),
                   key=lambda d: (d.path, d.line, d.col, d.code))
    assert [(d.path, d.line, d.code) for d in found] == [(d.path, d.line, d.code) for d in alone]
    assert any(d.path == str(broken) and d.code.startswith("P1") for d in found)
    assert {Path(d.path).suffix for d in found} >= {".script"}
    assert not any(d.path.endswith(".csv") for d in found)


def test_a_dat_is_checked_with_its_src(tmp_path):
    src, dat, lone = (write(tmp_path / n, "x") for n in ("Weld.SRC", "weld.dat", "other.dat"))
    assert program_paths([dat, src, lone, tmp_path / "p.csv"]) == [src, lone, tmp_path / "p.csv"]


# --------------------------------------------------------------------------- settings


def test_settings_from_pyproject_or_postproc_toml(tmp_path):
    write(tmp_path / "pyproject.toml", '[project]\nname = "cell"\n[tool.postproc]\nmodel = "m/cell.onnx"\n'
          'config = ["KRC/$config.dat"]\nstrict = true\nmax_correction = 3\nignore = ["P301"]\n'
          '[[tool.postproc.fresh]]\nsource = "src/**/*.src"\noutput = "out/**/*_c.src"\n')
    sub = tmp_path / "src" / "deep"
    sub.mkdir(parents=True)
    cfg = load_settings(start=sub)
    assert cfg.path == tmp_path / "pyproject.toml"
    assert (cfg.model, cfg.reading.config, cfg.rules.strict, cfg.rules.max_correction_mm, cfg.check.ignore) == (
        tmp_path / "m/cell.onnx", (tmp_path / "KRC/$config.dat",), True, 3.0, {"P301"})
    for name in ("src/a.src", "src/deep/er/b.src", "src/c.dat"):
        write(tmp_path / name, "x")
    assert [(s.relative_to(tmp_path).as_posix(), o.relative_to(tmp_path).as_posix()) for s, o in cfg.check.fresh[0].matches()] \
        == [("src/a.src", "out/a_c.src"), ("src/deep/er/b.src", "out/deep/er/b_c.src")]
    # postproc.toml in a nearer folder wins, keys at its top level
    write(sub / "postproc.toml", 'iterations = 3\n')
    assert (load_settings(start=sub).rules.iterations, load_settings(start=sub).model) == (3, None)


@pytest.mark.parametrize("text, message, line", [
    ("modle = 'x.onnx'\n", "unknown setting 'modle' in postproc.toml; did you mean 'model'?", 1),
    ("model = 'x.onnx'\nstrict = 1\n", "strict must be true or false, not 1", 2),
    ("fresh = [{ source = 'src/*.src', output = 'out/x.src' }]\n", "same wildcards", 1),
    ("iterations = 3\nmax_correction = -1\n", "max_correction must be a positive number of mm, not -1", 2),
    ("model = \n", "not valid TOML", 1),
])
def test_bad_settings_are_located(tmp_path, text, message, line):
    write(tmp_path / "postproc.toml", text)
    with pytest.raises(PostprocError) as info:
        load_settings(tmp_path / "postproc.toml")
    assert message in info.value.message and info.value.code == "P610" and info.value.line == line


# --------------------------------------------------------------------------- freshness


@pytest.fixture
def cell(tmp_path, affine, monkeypatch):
    """A repository: pyproject with a model and a src → out pair, two compensated programs."""
    monkeypatch.chdir(tmp_path)
    affine(offset=(0.05, -0.02, 0.01))
    os.replace(next(tmp_path.glob("model*.onnx")), tmp_path / "cell.onnx")
    write(tmp_path / "pyproject.toml", '[tool.postproc]\nmodel = "cell.onnx"\n'
          'fresh = [{ source = "src/*.csv", output = "out/*.csv" }]\n')
    model = load_model(tmp_path / "cell.onnx")
    for name, rows in (("a", ROWS[:1]), ("b", [(2100, 100, 1000, 0, 90, 0), (2150, 50, 950, 1, 91, 0)])):
        text = "x,y,z,a,b,c\n" + "".join(",".join(map(str, r)) + "\n" for r in rows)
        write(tmp_path / "src" / f"{name}.csv", text)
        write(tmp_path / "out" / f"{name}.csv", compensate_text(text, model, name=f"{name}.csv")[0])
    return tmp_path


def test_fresh_outputs_are_clean_whatever_their_mtimes(cell):
    cfg = load_settings()
    past = time.time() - 3600
    for out in (cell / "out").iterdir():
        os.utime(out, (past, past))  # outputs older than their sources: still fresh
    assert check_fresh(cfg, load_model(cfg.model)) == ([], [])


def test_stale_missing_and_orphan_outputs(cell, capsys):
    source = cell / "src" / "b.csv"
    source.write_text(source.read_text().replace("2150,50,950", "2150,50,951"))
    (cell / "out" / "a.csv").unlink()
    write(cell / "out" / "c.csv", "x,y,z\n1,2,3\n")
    cfg = load_settings()
    found, written = check_fresh(cfg, load_model(cfg.model))
    # the stale output is located at its first differing byte: row 2's z (line 4 after the stamp)
    assert [(d.path, d.line, d.code, d.severity) for d in found] == [
        (os.path.join("out", "b.csv"), 4, "P405", "error"),
        (os.path.join("out", "c.csv"), 0, "P407", "warning"),
        (os.path.join("src", "a.csv"), 0, "P406", "error"),
    ]
    # (2150, 50, 950) + (0.05, −0.02, 0.01) was written 2150.050,49.980,950.010: "95" is common
    assert found[0].col == len("2150.050,49.980,95") + 1
    assert main(["check", "--fresh", "-q"]) == 1
    assert main(["check", "--fresh", "--fix", "-q"]) == 0
    assert sorted(p.name for p in (cell / "out").iterdir()) == ["a.csv", "b.csv", "c.csv"]
    assert main(["check", "--fresh", "-q", "--ignore", "P407"]) == 0
    capsys.readouterr()


def test_fresh_reports_a_source_that_cannot_be_compensated(cell):
    write(cell / "src" / "d.csv", "x,y,z,a,b,c\n5000,0,900,0,90,0\n")
    found, _ = check_fresh(load_settings(), load_model(cell / "cell.onnx"))
    assert [(d.path, d.line, d.code) for d in found] == [(os.path.join("src", "d.csv"), 2, "P302")]
    assert "while compensating it for out" in found[0].message


# --------------------------------------------------------------------------- command line


def test_cli_output_and_exit_codes(affine, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("NO_COLOR", "1")
    model = str(affine())
    write(tmp_path / "p.csv", TEXT)
    write(tmp_path / "ok.csv", TEXT.splitlines(keepends=True)[0] + TEXT.splitlines(keepends=True)[1])
    assert main(["check", "ok.csv", "--model", model]) == 0
    assert capsys.readouterr() == ("", "postproc check: clean\n")
    assert main(["check", "p.csv", "ok.csv", "--model", model]) == 1
    out, err = capsys.readouterr()
    want = sorted(expected_codes())
    assert [line.split(" ")[:2] for line in out.splitlines()] == [[f"p.csv:{n}:1:", c] for n, c in want]
    assert err.startswith("postproc check: 2 errors, ")
    # warnings alone pass unless --strict; -q prints errors only and no summary
    assert main(["check", "p.csv", "--model", model, "--ignore", "P302"]) == 0
    capsys.readouterr()
    assert main(["check", "p.csv", "--model", model, "--ignore", "P302", "--strict"]) == 1
    capsys.readouterr()
    assert main(["check", "p.csv", "--model", model, "-q"]) == 1
    out, err = capsys.readouterr()
    assert err == "" and {line.split(" ")[1] for line in out.splitlines()} == {"P302"}
    # usage and internal errors are 2
    assert main(["check"]) == 2
    assert main(["check", "ok.csv", "--model", str(tmp_path / "none.onnx")]) == 2
    assert main(["check", "ok.csv", "--fix", "--model", model]) == 2
    # no fresh pairs configured: nothing to compare, said on stderr, not an error (postproc-fresh
    # in a cell repository that only wants postproc-check)
    capsys.readouterr()
    assert main(["check", "--fresh", "--model", model]) == 0
    assert "no fresh pairs configured" in capsys.readouterr().err


def test_a_model_for_another_robot_is_a_finding(affine, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    write(tmp_path / "ok.csv", TEXT.splitlines(keepends=True)[0] + TEXT.splitlines(keepends=True)[1])
    model = str(affine())  # robot "KR500-sim" in its card
    assert main(["check", "ok.csv", "--model", model, "--robot", "kr500-SIM", "-q"]) == 0  # names: any case
    assert main(["check", "ok.csv", "--model", model, "--robot", "UR10"]) == 1
    assert capsys.readouterr().out.startswith(f"{model}: P310 the model was trained on robot KR500-sim")
    write(tmp_path / "postproc.toml", 'robot = "UR10"\n')
    assert main(["check", "ok.csv", "--model", model, "-q"]) == 1  # the robot from the settings
    assert capsys.readouterr().out.startswith(f"{model}: P310 the model was trained on robot KR500-sim")


def test_cli_robot_option_uses_the_nominal_ik(affine, tmp_path, capsys):
    pytest.importorskip("pinocchio")
    robot = pytest.importorskip("postproc.robot.arm")
    path = write(tmp_path / "p.csv", TEXT)
    _, ok = robot.Robot().ik(np.array(ROWS, float))
    far = {line for line, code in expected_codes() if code == "P302"}
    want = [line for line, reach in enumerate(ok, start=2) if not reach and line not in far]
    from postproc.core.resources import model_path

    assert main(["check", str(path), "--model", str(affine()), "--robot", str(model_path("kr500.toml"))]) == 1
    got = [int(line.split(":")[1]) for line in capsys.readouterr().out.splitlines() if " P309 " in line]
    assert got == want and want  # the KR500's IK rejects at least one target the reach sphere lets through


# --------------------------------------------------------------------------- KRL modules

SRC = ("&ACCESS RVP\r\n&REL 1\r\nDEF weld( )\r\n$BASE = $NULLFRAME\r\n$TOOL = {X 0.0,Y 0.0,Z 200.0,A 0.0,B 0.0,C 0.0}\r\n"
       "PTP XP1\r\nLIN XP2 C_DIS\r\nLIN {X 2100.0,Y 50.0,Z 950.0,A 0.0,B 90.0,C 0.0}\r\nEND\r\n")
E6 = ",A 0.0,B 90.0,C 0.0,S 2,T 2,E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}"
DAT = ("&ACCESS RVP\r\n&REL 1\r\nDEFDAT weld\r\nDECL E6POS XP1={X 2000.0,Y 0.0,Z 900.0" + E6 + "\r\n"
       "DECL E6POS XP2={X 2050.0,Y -100.0,Z 900.0" + E6 + "\r\nENDDAT\r\n")
krl = pytest.mark.skipif(not __import__("importlib").util.find_spec("postproc.programs.krl"),
                         reason="the KRL reader is not there yet")


@krl
def test_krl_module_findings_via_src_or_dat(affine, tmp_path):
    far = SRC.replace("END\r\n", "LIN {X 5000.0,Y 0.0,Z 900.0,A 0.0,B 90.0,C 0.0}\r\nEND\r\n")
    src, dat = write(tmp_path / "weld.src", far), write(tmp_path / "weld.dat", DAT)
    model = load_model(affine())
    for given in ([src], [dat], [src, dat]):
        found = check_files(given, model)
        # (and once, at the first target, XP1 in the .dat: robot base = world assumed, a note)
        assert [(d.path, d.line, d.col, d.code) for d in found] == [
            (str(dat), 4, 16, "P224"), (str(src), 9, 5, "P301"), (str(src), 9, 5, "P302")], given
    write(tmp_path / "weld.dat", DAT.replace("Z 900.0", "Z 900.0.0", 1))
    (d,) = check_files([dat], model)
    assert (d.path, d.line, d.code) == (str(dat), 4, "P101")


@krl
def test_krl_module_stamps_and_freshness(affine, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    os.replace(affine(offset=(0.1, 0, 0)), tmp_path / "cell.onnx")
    write(tmp_path / "postproc.toml", 'model = "cell.onnx"\nfresh = [{ source = "src/*.src", output = "out/*.src" }]\n')
    write(tmp_path / "src" / "weld.src", SRC)
    write(tmp_path / "src" / "weld.dat", DAT)
    assert main(["check", "--fresh", "--fix", "-q"]) == 0
    model = load_model(tmp_path / "cell.onnx")
    out_src, out_dat = tmp_path / "out" / "weld.src", tmp_path / "out" / "weld.dat"
    # both files of the module are written and stamped alike; XP1 moved by 0.1 mm in X
    assert "DECL E6POS XP1={X 2000.100,Y 0.000,Z 900.000," in out_dat.read_text()
    assert [d.code for d in check_files([out_src], model)] == ["P224"]  # (a note: robot base = world assumed)
    # an edited .dat makes the output .dat stale, located at the changed number
    write(tmp_path / "src" / "weld.dat", DAT.replace("Y -100.0", "Y -101.0"))
    found, _ = check_fresh(load_settings(), model)
    assert [(d.path, d.line, d.code) for d in found] == [(os.path.join("out", "weld.dat"), 6, "P405")]
    # the uncompensated .dat copied over the compensated one: a mixed module
    write(out_dat, DAT)
    assert sorted((Path(d.path).name, d.code) for d in check_files([out_dat], model)) == [
        ("weld.dat", "P224"), ("weld.dat", "P404"), ("weld.src", "P404")]


def test_what_else_compensate_refuses_is_a_finding(affine):
    # a frame that is not finite: compensate refuses the program (P103, one rule for both),
    # its targets are not also 'position not known' (P212)
    from helpers import program_in_base

    base = np.eye(4)
    base[0, 3] = np.nan
    program = program_in_base(base, [2000.0, 0.0, 900.0, 0.0, 90.0, 0.0], "BASE_DATA[3]")
    found = check_program(program, load_model(affine()))
    assert [(d.code, d.severity) for d in found] == [("P103", "error")]
    assert "BASE_DATA[3]" in found[0].message and failed(found)


def test_colour_only_on_a_terminal_without_no_color(affine, tmp_path, capsys, monkeypatch):
    path = write(tmp_path / "p.csv", TEXT)
    model = str(affine())
    monkeypatch.setattr(sys.stdout, "isatty", lambda: True)
    monkeypatch.delenv("NO_COLOR", raising=False)
    assert main(["check", str(path), "--model", model, "-q"]) == 1
    assert "\033[31mP302\033[0m" in capsys.readouterr().out
    monkeypatch.setenv("NO_COLOR", "1")
    assert main(["check", str(path), "--model", model, "-q"]) == 1
    assert "\033[" not in capsys.readouterr().out


def test_check_runs_the_model_once_for_a_clean_program(tmp_path, monkeypatch):
    # the safety net (compensate_program) reuses check's commands instead of a second fixed point
    from postproc.model.compensator import Compensator

    path = tmp_path / "p.csv"
    path.write_text("x,y,z,a,b,c\n2000,0,900,0,90,0\n2050,100,950,0,90,0\n")
    model = load_model()
    calls = []
    real = Compensator.predict
    monkeypatch.setattr(Compensator, "predict", lambda self, *a, **k: calls.append(1) or real(self, *a, **k))
    points = []
    chunks = Compensator.command_chunks
    monkeypatch.setattr(Compensator, "command_chunks", lambda self, *a, **k: points.append(1) or chunks(self, *a, **k))
    assert [d.code for d in check_files([path], model)] == ["P340"]  # (the demonstration model's note only)
    assert len(points) == 1  # one fixed point
    # (a model that settles the approach runs once more, to check the commands it settled)
    assert len(calls) == model.default_iterations or model.settles


def test_a_point_whose_runs_need_other_numbers_is_a_finding_as_compensate_says(affine, tmp_path):
    """One position moved to under two bases (a varying model: two corrections): compensate
    leaves it (P230, exit 1), and check says so at the same place — a clean check means
    compensate succeeds."""
    model = load_model(affine(gain=np.diag([2e-3, 1e-3, 3e-3])))
    src = ("DEF t( )\n  $TOOL = {X 0,Y 0,Z 200,A 0,B 0,C 0}\n  $BASE = {X 0,Y 0,Z 0,A 0,B 0,C 0}\n  LIN XP1\n"
           "  $BASE = {X 0,Y 300,Z 0,A 0,B 0,C 0}\n  LIN XP1\nEND\n")
    dat = "DEFDAT t\n  DECL E6POS XP1={X 2000,Y 0,Z 900,A 0,B 90,C 0}\nENDDAT\n"
    _, report = compensate_text(src, model, name="t.src", dat_text=dat)
    left = [(d.line, d.code) for d in report.warnings if d.code == "P230"]
    assert left and report.compensated == 0
    program = parse_program_text(src, "t.src", dat_text=dat)
    found = check_program(program, model)
    assert [(d.line, d.code) for d in found if d.code == "P230"] == left and failed(found, strict=True)
    # the same position under one base: clean, as compensate
    one = src.replace("  $BASE = {X 0,Y 300,Z 0,A 0,B 0,C 0}\n", "")
    assert [d for d in check_program(parse_program_text(one, "t.src", dat_text=dat), model) if d.severity != "note"] == []

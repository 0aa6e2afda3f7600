"""Issue 12, item 7 and the README: messages that do not mislead, bounded plans, digits that mean
something, and README and docs facts a new user relies on (commands, rev:, figures' commands)."""
import re
import subprocess

import numpy as np
import pytest

from postproc.cli import main
from postproc.compensation.api import compensate_text
from postproc.core.diagnostics import PostprocError

from helpers import REPO, pages
from postproc.testing.models import affine_model

README = (REPO / "README.md").read_text()


def test_plan_is_bounded_and_streamed_in_chunks(capsys, tmp_path):
    pytest.importorskip("scipy")
    from postproc.calibration import planning
    from postproc.robot.arm import Robot
    from postproc.robot.description import load_description

    assert main(["plan", "-n", str(planning.MAX_POSES + 1), "-o", str(tmp_path / "p.csv")]) == 2
    err = capsys.readouterr().err
    assert "P512 a plan holds at most 10,000,000 poses" in err and "internal error" not in err
    assert not (tmp_path / "p.csv").exists()
    # in chunks: the same bytes and the same reach mask as all at once
    poses = planning.round_poses(planning.latin_hypercube(50, seed=2, range_deg=60))
    whole = "".join(planning.plan_csv_chunks(poses, chunk=len(poses)))
    assert "".join(planning.plan_csv_chunks(poses, chunk=7)) == whole == planning.plan_csv_text(poses)
    assert whole.count("\n") == 51 and whole.startswith("x,y,z,a,b,c\n")
    robot = Robot(load_description())
    ok = robot.ik(poses)[1]
    assert np.array_equal(planning.reachable(robot, poses, chunk=7), ok)
    assert main(["plan", "-n", "200", "--seed", "1", "-o", str(tmp_path / "q.csv"), "-q"]) == 0
    assert (tmp_path / "q.csv").read_text() == planning.plan_csv_text(
        planning.round_poses(planning.latin_hypercube(200, seed=1)))


def test_32_decimals_come_back_capped_not_as_float_noise(tmp_path):
    gain = np.diag([1e-3, -2e-3, 5e-4])  # a correction that varies over space
    model = affine_model(tmp_path / "m.onnx", offset=(0.1, -0.2, 0.05), gain=gain)
    token = "2000.12345678901234567890123456789012"
    text = f"x,y,z\n{token},0.5,900.25\n1800.000,100.000,1000.000\n"
    out, _ = compensate_text(text, model, name="p.csv")
    row1, row2 = out.splitlines()[2:4]
    x = row1.split(",")[0]
    assert re.fullmatch(r"\d+\.\d{6}", x), x  # 1 nm: beyond it a float has nothing to say
    p = 2000.12345678901234
    expected = 2000.0 + (p - 2000.0 + 0.1) / (1 - 1e-3)  # the fixed point c = P + offset + gain·(c − centre)
    assert abs(float(x) - expected) < 1e-5, (x, expected)
    assert all(re.fullmatch(r"-?\d+\.\d{3}", v) for v in row2.split(","))  # 3 decimals stay 3


def test_a_pose_header_with_a_b_but_no_c_is_one_located_message(tmp_path):
    model = affine_model(tmp_path / "m.onnx", offset=(0.1, 0.0, 0.0))
    rows = "".join(f"{2000 + i},0,900,0,90\n" for i in range(50))
    with pytest.raises(PostprocError) as info:
        compensate_text("x,y,z,a,b\n" + rows, model, name="p.csv")
    assert (info.value.code, info.value.line, info.value.col) == ("P104", 1, 1)
    assert "has a,b but no c" in info.value.message
    rows = "".join(f"{2000 + i},0,900\n" for i in range(50))
    out, report = compensate_text("x,y,z\n" + rows, model, name="p.csv")  # no attitude at all: as before
    assert "2000.100,0.000,900.000" in out


def test_measure_says_what_it_compares(capsys, tmp_path):
    pytest.importorskip("pinocchio")
    plan = tmp_path / "plan.csv"
    plan.write_text("x,y,z,a,b,c\n2000,0,900,0,90,0\n2100,100,1000,0,90,0\n")
    assert main(["measure", str(plan), "-o", str(tmp_path / "m.csv")]) == 0
    err = capsys.readouterr().err
    assert "measured vs commanded (the rows' x,y,z): mean" in err and "--after" in err


def test_docs_pre_commit_rev_is_not_a_tag_that_does_not_exist():
    revs = [rev for text in pages().values() for rev in re.findall(r"^\s*rev:\s*(\S+)", text, re.M)]
    assert revs
    tags = subprocess.run(["git", "tag", "--list"], cwd=REPO, capture_output=True, text=True).stdout.split()
    for rev in revs:
        assert rev.startswith("<") or rev in tags, f"docs rev: {rev} is no tag of this repository"


def test_readme_names_no_index_install_and_every_figure_its_command():
    # postproc is on no index: the README says so, and never tells to `pip install postproc`
    assert "`pip install postproc` finds nothing" in README
    for name, text in pages().items():
        assert "pip install postproc" not in text.replace("`pip install postproc` finds nothing", ""), name
    # every headline figure (mm) of the README's first section (and the docs' home page, the same
    # text) comes with the command printing it; a figure may carry its marker (benchmarks/figures.py)
    for name in ("README.md", "docs/index.md"):
        intro = re.sub(r"<!-- fig [^>]*-->", "", pages()[name].split("## Set-up")[0].split("## Where to start")[0])
        assert re.findall(r"\d\.\d{3} mm", intro), name
        for paragraph in intro.split("\n\n"):
            if re.search(r"\d\.\d{3} mm", paragraph):
                assert "`python benchmarks/" in paragraph or "`postproc " in paragraph, paragraph


def test_real_data_benchmark_without_its_data_set_says_so(tmp_path):
    import sys

    done = subprocess.run([sys.executable, str(REPO / "benchmarks" / "real_data.py"), "--data", str(tmp_path)],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 1 and "Traceback" not in done.stderr
    assert "measurements_random_poses.csv not found" in done.stderr and "--data DIR or $POSTPROC_IPA_DATA" in done.stderr

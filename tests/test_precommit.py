"""The pre-commit hooks, run by pre-commit itself on a temporary cell repository.

pre-commit builds a virtualenv and `pip install`s the hook repository, as it does for any
user: this checkout's working tree (tracked and untracked, not ignored files) is copied into
a temporary git repository that serves as the hook repository. The install takes 15–25 s on
this machine (pip resolves from the configured indexes / find-links), hence `slow`.
"""
import os
import re
import shutil
import subprocess
import sys

import pytest

from postproc.compensate import compensate_text
from postproc.compensator import load_model

from conftest import REPO
from model_factory import DEFAULT_REACH, affine_model

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(shutil.which("pre-commit") is None, reason="pre-commit is not installed (pip install 'postproc[test]')"),
]

FINDING = re.compile(r"^(\S+):(\d+):(\d+): (P\d{3}) ", re.M)
GOOD = "x,y,z,a,b,c\n2000,0,900,0,90,0\n2100,150,1000,2,88,0\n"
FAR = (5000.0, 0.0, 900.0)  # |FAR − reach centre| > radius_max: beyond reach
BAD = "x,y,z,a,b,c\n2000,0,900,0,90,0\n" + ",".join(map(str, FAR)) + ",0,90,0\n"


def _env(home):
    env = {k: v for k, v in os.environ.items() if not k.startswith("GIT_")}  # e.g. when run from a hook
    env.update(PRE_COMMIT_HOME=str(home), PRE_COMMIT_COLOR="never", NO_COLOR="1",
               GIT_AUTHOR_NAME="t", GIT_AUTHOR_EMAIL="t@example.com",
               GIT_COMMITTER_NAME="t", GIT_COMMITTER_EMAIL="t@example.com")
    return env


def run(cmd, cwd, env):
    return subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=240)


@pytest.fixture(scope="module")
def cell(tmp_path_factory):
    """(cell repository, env): hook repo from this checkout, pre-commit installed in the cell."""
    env = _env(tmp_path_factory.mktemp("pre-commit-home"))
    hook = tmp_path_factory.mktemp("hook-repo")
    listed = run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], REPO, env)
    assert listed.returncode == 0, listed.stderr
    for name in filter(None, listed.stdout.split("\0")):
        if (REPO / name).is_file():
            (hook / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(REPO / name, hook / name)
    for cmd in (["git", "init", "-q"], ["git", "add", "-A"], ["git", "commit", "-qm", "hook"]):
        assert run(cmd, hook, env).returncode == 0
    rev = run(["git", "rev-parse", "HEAD"], hook, env).stdout.strip()

    repo = tmp_path_factory.mktemp("cell")
    affine_model(repo / "cell.onnx", offset=(0.05, -0.02, 0.01), name="cell-model")
    (repo / "pyproject.toml").write_text(
        '[tool.postproc]\nmodel = "cell.onnx"\nfresh = [{ source = "src/*.csv", output = "out/*.csv" }]\n')
    (repo / ".pre-commit-config.yaml").write_text(
        f"repos:\n- repo: {hook}\n  rev: {rev}\n  hooks:\n"
        "  - id: postproc-check\n    files: '\\.csv$'\n"  # pose lists are not checked by default
        "  - id: postproc-fresh\n")
    for cmd in (["git", "init", "-q"], [sys.executable, "-m", "pre_commit", "install"]):
        done = run(cmd, repo, env)
        assert done.returncode == 0, done.stdout + done.stderr
    return repo, env


def commit(repo, env, message):
    assert run(["git", "add", "-A"], repo, env).returncode == 0
    done = run(["git", "commit", "-m", message], repo, env)
    return done.returncode, done.stdout + done.stderr


def hook_section(output, name):
    """The output pre-commit shows for one hook (from its status line to the next)."""
    m = re.search(rf"^{re.escape(name)}\.+(Passed|Failed)$(.*?)(?=^\S[^\n]*\.{{3,}}(?:Passed|Failed|Skipped)$|\Z)",
                  output, re.M | re.S)
    assert m, output
    return m.group(1), m.group(2)


def test_hooks_pass_good_programs_and_stop_bad_ones(cell):
    repo, env = cell
    model = load_model(repo / "cell.onnx")
    (repo / "src").mkdir()
    (repo / "out").mkdir()
    (repo / "src" / "part.csv").write_text(GOOD)
    (repo / "out" / "part.csv").write_text(compensate_text(GOOD, model, name="part.csv")[0])
    code, output = commit(repo, env, "good")
    assert code == 0, output
    assert hook_section(output, "postproc check (robot programs)")[0] == "Passed"
    assert hook_section(output, "postproc compensated outputs up to date")[0] == "Passed"

    # a program with a target beyond the robot's reach: the commit is refused, the line named
    far = sum((a - b) ** 2 for a, b in zip(FAR, DEFAULT_REACH["center"])) ** 0.5
    assert far > DEFAULT_REACH["radius_max"]
    (repo / "programs").mkdir()
    (repo / "programs" / "bad.csv").write_text(BAD)
    code, output = commit(repo, env, "bad")
    assert code == 1
    status, section = hook_section(output, "postproc check (robot programs)")
    assert status == "Failed" and "- exit code: 1" in section
    findings = FINDING.findall(section)
    assert ("programs/bad.csv", "3", "1", "P302") in findings
    assert {f[0] for f in findings} == {"programs/bad.csv"}
    assert run(["git", "reset", "-q", "HEAD", "programs"], repo, env).returncode == 0
    shutil.rmtree(repo / "programs")

    # a source edited without re-compensating its output: the fresh hook names the output line
    (repo / "src" / "part.csv").write_text(GOOD.replace("2100,150,1000", "2100,150,1001"))
    code, output = commit(repo, env, "stale")
    assert code == 1
    assert hook_section(output, "postproc check (robot programs)")[0] == "Passed"
    status, section = hook_section(output, "postproc compensated outputs up to date")
    assert status == "Failed" and "- exit code: 1" in section
    # line 1 is the stamp, 2 the header, 4 the edited row
    assert [f[:2] + f[3:] for f in FINDING.findall(section)] == [("out/part.csv", "4", "P405")]

    # the fix the message suggests makes the commit go through
    fixed = run([sys.executable, "-m", "postproc", "check", "--fresh", "--fix"], repo, env)
    assert fixed.returncode == 0, fixed.stderr
    code, output = commit(repo, env, "stale, fixed")
    assert code == 0, output

"""The pre-commit hooks, run by pre-commit itself on a temporary cell repository.

pre-commit builds a virtualenv and `pip install`s the hook repository, as it does for any
user: this checkout's tracked files (`git ls-files --cached`, as a clone of the commit would
hold them, in their working-tree state) are copied into a temporary git repository that
serves as the hook repository — never untracked files such as the README's `.venv/` (1.8 GB).
The install takes 15–25 s on this machine (pip resolves from the configured indexes /
find-links), hence `slow`.
"""
import os
import re
import shutil
import subprocess
import sys

import pytest

from postproc.compensation.streaming import compensate_file
from postproc.model.compensator import load_model

from helpers import REPO
from postproc.testing.models import DEFAULT_REACH, affine_model

PRE_COMMIT = shutil.which("pre-commit")
pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(PRE_COMMIT is None, reason="pre-commit is not installed (pip install 'postproc[test]')"),
]

FINDING = re.compile(r"^(\S+):(\d+):(\d+): (P\d{3}) ", re.M)
FAR = (5000.0, 0.0, 900.0)  # |FAR − reach centre| > radius_max: beyond reach
E6 = ",A 0.0,B 90.0,C 0.0,S 2,T 35,E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}"
SRC = ("&ACCESS RVP\r\n&REL 1\r\nDEF weld( )\r\n$BASE = $NULLFRAME\r\n"
       "$TOOL = {X 0.0,Y 0.0,Z 200.0,A 0.0,B 0.0,C 0.0}\r\nPTP XP1\r\nLIN XP2 C_DIS\r\n"
       "LIN {X 2100.0,Y 50.0,Z 950.0,A 0.0,B 90.0,C 0.0}\r\nEND\r\n")
DAT = ("&ACCESS RVP\r\n&REL 1\r\nDEFDAT weld\r\nDECL E6POS XP1={X 2000.0,Y 0.0,Z 900.0" + E6 + "\r\n"
       "DECL E6POS XP2={X 2050.0,Y -100.0,Z 900.0" + E6 + "\r\nENDDAT\r\n")
# a module without a .dat: inline targets only, the last one (line 8) beyond reach
BAD = (SRC.replace("DEF weld", "DEF far").replace("PTP XP1\r\nLIN XP2 C_DIS\r\n", "PTP {X 2000.0,Y 0.0,Z 900.0,A 0.0,B 90.0,C 0.0}\r\n")
       .replace("END\r\n", "LIN {X %.1f,Y %.1f,Z %.1f,A 0.0,B 90.0,C 0.0}\r\nEND\r\n" % FAR))


def _env(home):
    env = {k: v for k, v in os.environ.items() if not k.startswith("GIT_")}  # e.g. when run from a hook
    # (PIP_NO_COMPILE: the hook's pip does not compile the bytecode of every dependency, a third
    # of the install; Python compiles what it imports)
    env.update(PRE_COMMIT_HOME=str(home), PRE_COMMIT_COLOR="never", NO_COLOR="1", PIP_NO_COMPILE="1",
               GIT_AUTHOR_NAME="t", GIT_AUTHOR_EMAIL="t@example.com",
               GIT_COMMITTER_NAME="t", GIT_COMMITTER_EMAIL="t@example.com")
    return env


def run(cmd, cwd, env):
    return subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=240)


def hook_files(env) -> list[str]:
    """The checkout's tracked files that exist (a deletion not yet committed is left out)."""
    listed = run(["git", "ls-files", "-z", "--cached"], REPO, env)
    assert listed.returncode == 0, listed.stderr
    return [name for name in filter(None, listed.stdout.split("\0")) if (REPO / name).is_file()]


def test_the_hook_repository_holds_tracked_files_only(tmp_path):
    """An untracked file (e.g. the README's .venv/, 1.8 GB) never reaches the hook repository."""
    names = hook_files(_env(tmp_path))
    assert "setup.cfg" in names and ".pre-commit-hooks.yaml" in names
    assert not any(n.startswith((".venv/", "out/")) or "/__pycache__/" in n for n in names)
    size = sum((REPO / n).stat().st_size for n in names)
    assert size < 50e6, f"the hook repository would hold {size / 1e6:.0f} MB"
    ignored = run(["git", "check-ignore", "-q", ".venv/bin/python"], REPO, _env(tmp_path))
    assert ignored.returncode == 0, ".venv/ must be in .gitignore"


@pytest.fixture(scope="module")
def cell(tmp_path_factory):
    """(cell repository, env): hook repo from this checkout, pre-commit installed in the cell."""
    home = tmp_path_factory.mktemp("pre-commit-home")
    env = _env(home)
    hook = tmp_path_factory.mktemp("hook-repo")
    for name in hook_files(env):
        (hook / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(REPO / name, hook / name)
    for cmd in (["git", "init", "-q"], ["git", "add", "-A"], ["git", "commit", "-qm", "hook"]):
        assert run(cmd, hook, env).returncode == 0
    rev = run(["git", "rev-parse", "HEAD"], hook, env).stdout.strip()

    repo = tmp_path_factory.mktemp("cell")
    affine_model(repo / "cell.onnx", offset=(0.05, -0.02, 0.01), name="cell-model")
    (repo / "pyproject.toml").write_text(
        '[tool.postproc]\nmodel = "cell.onnx"\nfresh = [{ source = "src/*.src", output = "out/*.src" }]\n')
    (repo / ".pre-commit-config.yaml").write_text(
        f"repos:\n- repo: {hook}\n  rev: {rev}\n  hooks:\n"
        "  - id: postproc-check\n  - id: postproc-fresh\n")  # as a user writes it: default files
    for cmd in (["git", "init", "-q"], [PRE_COMMIT, "install"]):
        done = run(cmd, repo, env)
        assert done.returncode == 0, done.stdout + done.stderr
    yield repo, env
    shutil.rmtree(home, ignore_errors=True)  # the hook's virtualenv (~0.3 GB): not left in the temp dir


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
    (repo / "src").mkdir()
    (repo / "src" / "weld.src").write_bytes(SRC.encode())
    (repo / "src" / "weld.dat").write_bytes(DAT.encode())
    compensate_file(repo / "src" / "weld.src", repo / "out" / "weld.src", load_model(repo / "cell.onnx"))
    assert (repo / "out" / "weld.dat").is_file()
    code, output = commit(repo, env, "good")
    assert code == 0, output
    assert hook_section(output, "postproc check (robot programs)")[0] == "Passed"
    assert hook_section(output, "postproc compensated outputs up to date")[0] == "Passed"

    # a module with a target beyond the robot's reach: the commit is refused, the line named
    far = sum((a - b) ** 2 for a, b in zip(FAR, DEFAULT_REACH["center"])) ** 0.5
    assert far > DEFAULT_REACH["radius_max"]
    (repo / "programs").mkdir()
    (repo / "programs" / "far.src").write_bytes(BAD.encode())
    code, output = commit(repo, env, "bad")
    assert code == 1
    status, section = hook_section(output, "postproc check (robot programs)")
    assert status == "Failed" and "- exit code: 1" in section
    findings = FINDING.findall(section)
    assert ("programs/far.src", "8", "5", "P302") in findings  # at the aggregate of "LIN {X 5000.0,…"
    assert {f[0] for f in findings} == {"programs/far.src"}
    assert run(["git", "reset", "-q", "HEAD", "programs"], repo, env).returncode == 0
    shutil.rmtree(repo / "programs")

    # a .dat edited without re-compensating: the fresh hook names the output line
    (repo / "src" / "weld.dat").write_bytes(DAT.replace("Y -100.0", "Y -101.0").encode())
    code, output = commit(repo, env, "stale")
    assert code == 1
    assert hook_section(output, "postproc check (robot programs)")[0] == "Passed"
    status, section = hook_section(output, "postproc compensated outputs up to date")
    assert status == "Failed" and "- exit code: 1" in section
    # &ACCESS, &REL, the stamp, DEFDAT, XP1, then XP2 on line 6
    assert [f[:2] + f[3:] for f in FINDING.findall(section)] == [("out/weld.dat", "6", "P405")]

    # the fix the message suggests makes the commit go through
    fixed = run([sys.executable, "-m", "postproc", "check", "--fresh", "--fix"], repo, env)
    assert fixed.returncode == 0, fixed.stderr
    code, output = commit(repo, env, "stale, fixed")
    assert code == 0, output

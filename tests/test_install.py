"""Installing as a user does: a wheel built with `python -m build` from the tracked files,
installed into a fresh virtualenv outside the checkout, compensates the shipped sample with
the shipped model (grammars and models found under <prefix>/share/postproc). ~10 s: slow."""
import configparser
import os
import re
import shutil
import subprocess
import sys

import pytest

from helpers import REPO

pytestmark = pytest.mark.slow


def run(cmd, cwd, **kw):
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV") and not k.startswith("GIT_")}
    done = subprocess.run([str(c) for c in cmd], cwd=cwd, env=env, capture_output=True, text=True, timeout=240, **kw)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    return done


@pytest.fixture
def scratch(tmp_path):
    yield tmp_path
    shutil.rmtree(tmp_path / "venv", ignore_errors=True)  # ~0.3 GB: not left in the temp dir


def test_a_built_wheel_installs_outside_the_checkout_and_compensates(scratch):
    pytest.importorskip("build", reason="python -m build is in the test extra: pip install -e '.[test]'")
    tmp_path = scratch
    source = tmp_path / "source"  # what a clone holds: tracked files only
    listed = run(["git", "ls-files", "-z", "--cached"], REPO).stdout
    for name in filter(None, listed.split("\0")):
        if (REPO / name).is_file():
            (source / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(REPO / name, source / name)
    run([sys.executable, "-m", "build", "--wheel", "--outdir", tmp_path / "dist", source], tmp_path)
    (wheel,) = (tmp_path / "dist").glob("postproc-*.whl")

    venv = tmp_path / "venv"
    # a fresh virtualenv; this pip installs into it (pip >= 22.3: --python), without compiling
    # bytecode: seeding the venv with its own pip and compiling took 9 of this test's 14 s
    run([sys.executable, "-m", "venv", "--without-pip", venv], tmp_path)
    bin_ = venv / "bin"
    run([sys.executable, "-m", "pip", "--python", bin_ / "python", "install", "-q", "--no-compile", wheel], tmp_path)
    work = tmp_path / "work"
    work.mkdir()
    sample = REPO / "samples" / "krl" / "cam_pocket.src"
    shutil.copy2(sample, work / "cam_pocket.src")
    done = run([bin_ / "postproc", "compensate", "cam_pocket.src", "-o", "out/cam_pocket.src"], work)
    # (after the note that the default model is a demonstration model, P340)
    assert re.search(r"^postproc: (\d+) of \1 compensated; model default, ", done.stderr, re.M), done.stderr
    out = (work / "out" / "cam_pocket.src").read_text("latin-1")
    assert out != sample.read_text("latin-1") and "; postproc: compensated with model default " in out

    where = run([bin_ / "python", "-c", "import postproc, postproc.core.resources as r; "
                 "print(postproc.__file__); print(r.grammar_path('krl.lark')); print(r.model_path())"], work)
    package, grammar, model = where.stdout.split()
    for path in (package, grammar, model):
        assert path.startswith(str(venv)), where.stdout  # the wheel's files, not the checkout's
    assert grammar.endswith("share/postproc/grammars/krl.lark") and model.endswith("share/postproc/models/default.onnx")


def test_python_requires_covers_the_standard_library_used():
    """tomllib is 3.11+: python_requires must say so (no tomli fallback is kept)."""
    cfg = configparser.ConfigParser()
    cfg.read(REPO / "setup.cfg")
    required = cfg["options"]["python_requires"]
    uses_tomllib = any("import tomllib" in p.read_text() for p in (REPO / "postproc").rglob("*.py"))
    assert uses_tomllib and required == ">=3.11"
    assert "build" in cfg["options.extras_require"]["test"]

"""A plain `postproc compensate` imports what it uses and nothing else (issue 13: a short
program costs little more than `import numpy, onnxruntime, lark`). Each case runs the CLI in
a fresh interpreter with the shipped model and lists the modules loaded at its exit."""
import importlib.util
import json
import os
import subprocess
import sys

import pytest

from helpers import REPO
from postproc.programs import STAMP_PREFIX

spec = importlib.util.spec_from_file_location("fake_cam_post", REPO / "samples" / "cam_hook" / "fake_cam_post.py")
fake_cam_post = importlib.util.module_from_spec(spec)
spec.loader.exec_module(fake_cam_post)

# optional extras and the parts of postproc that a compensate of one program never needs
NEVER = ("torch", "scipy", "pinocchio", "pin", "matplotlib", "onnx", "dask", "distributed", "tqdm", "pandas",
         "sklearn", "difflib", "postproc.model.training", "postproc.acceptance.report", "postproc.calibration.simulator", "postproc.acceptance.certificate",
         "postproc.measurements.csv", "postproc.calibration.planning", "postproc.fleet", "postproc.compensation.cell", "postproc.compensation.check",
         "postproc.testing")
OTHER_DIALECTS = ("postproc.programs.poses", "postproc.programs.rapid", "postproc.programs.urscript",
                  "postproc.programs.fanuc")

RUN = """
import atexit, json, sys
atexit.register(lambda: print(json.dumps(sorted(sys.modules)), file=sys.stderr))
from postproc.cli import main
sys.exit(main(sys.argv[1:]))
"""


def loaded(args: list[str], stdin: str | None, cwd, cache) -> tuple[set[str], str]:
    """The modules a CLI run has loaded at its exit, and its stdout."""
    done = subprocess.run([sys.executable, "-c", RUN, *args], input=stdin, capture_output=True, text=True,
                          encoding="latin-1", cwd=cwd, env={**os.environ, "POSTPROC_CACHE_DIR": str(cache)})
    assert done.returncode == 0, done.stderr
    return set(json.loads(done.stderr.splitlines()[-1])), done.stdout


def unneeded(modules: set[str], extra: tuple[str, ...] = ()) -> list[str]:
    return sorted(m for m in modules if any(m == n or m.startswith(n + ".") for n in NEVER + extra))


def moved_targets(before: str, after: str) -> int:
    """How many lines the compensation changed (the stamp line left out)."""
    lines = [line for line in after.splitlines() if STAMP_PREFIX not in line]
    return sum(a != b for a, b in zip(before.splitlines(), lines, strict=True))


@pytest.mark.parametrize("source", ["stdin", "file"])
def test_krl_compensate_imports_only_what_it_uses(tmp_path, source):
    text = fake_cam_post.post("pocket", 12)
    if source == "stdin":  # the CAM filter; no settings file in tmp_path
        modules, out = loaded(["compensate", "-", "-o", "-", "-q"], text, tmp_path, tmp_path / "cache")
    else:  # a file: compensated through streaming.compensate_file
        (tmp_path / "pocket.src").write_text(text, encoding="latin-1")
        modules, _ = loaded(["compensate", "pocket.src", "-o", "out.src", "-q"], None, tmp_path, tmp_path / "cache")
        out = (tmp_path / "out.src").read_text(encoding="latin-1")
    assert moved_targets(text, out) == 12  # every target compensated
    assert "postproc.programs.krl" in modules and "onnxruntime" in modules
    assert unneeded(modules, OTHER_DIALECTS + (("postproc.compensation.streaming",) if source == "stdin" else ())) == []


def test_pose_list_compensate_does_not_import_the_krl_reader(tmp_path):
    text = fake_cam_post.post("pocket", 12, as_csv=True)
    modules, out = loaded(["compensate", "-", "-o", "-", "-q", "--dialect", "poses"], text, tmp_path,
                          tmp_path / "cache")
    assert moved_targets(text, out) == 12
    assert "postproc.programs.poses" in modules
    assert unneeded(modules, ("postproc.programs.krl", "postproc.programs.rapid", "postproc.programs.urscript",
                              "postproc.programs.fanuc", "postproc.compensation.streaming")) == []

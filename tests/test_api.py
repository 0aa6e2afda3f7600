"""The CAM-hook interface: the Python API without heavy imports, the samples/cam_hook
examples end to end, and the CLI conventions (--version, --help with examples)."""
import importlib.util
import json
import os
import re
import subprocess
import sys

import numpy as np
import pytest

import postproc
from postproc.cli import SUBCOMMANDS, build_parser
from postproc.model.compensator import load_model

from helpers import REPO

HOOK = REPO / "samples" / "cam_hook"
CSV = "x,y,z,a,b,c\n2000,0,900,0,90,0\n2100.5,-20.25,950,1,89,0\n"
OFFSET = (0.25, -0.125, 0.5)
HEAVY = ("torch", "pinocchio", "pin", "matplotlib", "scipy")  # none is needed to compensate (setup.cfg)

spec = importlib.util.spec_from_file_location("fake_cam_post", HOOK / "fake_cam_post.py")
fake_cam_post = importlib.util.module_from_spec(spec)
spec.loader.exec_module(fake_cam_post)


def cam_model(affine, offset):
    """An affine model measured with the fake CAM post's tool (else postproc refuses: P304)."""
    return affine(offset=offset, tool={"name": "spindle", "frame": list(fake_cam_post.TOOL)})


def krl_available() -> bool:
    return importlib.util.find_spec("postproc.programs.krl") is not None


FORMATS = ["csv", pytest.param("krl", marks=pytest.mark.skipif(not krl_available(), reason="the KRL reader is not there yet"))]


def test_api_compensates_without_importing_torch_pinocchio_matplotlib(affine, tmp_path):
    model = affine(offset=OFFSET)
    src = tmp_path / "p.csv"
    src.write_text(CSV)
    code = f"""
import json, sys
import postproc
m = postproc.load_model({str(model)!r})
text, report = postproc.compensate_text({CSV!r}, m, name="p.csv")
report2 = postproc.compensate_file({str(src)!r}, {str(tmp_path / "out.csv")!r}, m)
heavy = sorted(k for k in sys.modules if k.split(".")[0] in {HEAVY!r})
print(json.dumps([heavy, text, report.compensated, report2.compensated]))
"""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    heavy, text, n1, n2 = json.loads(done.stdout)
    assert heavy == [] and (n1, n2) == (2, 2)
    rows = [list(map(float, r.split(","))) for r in text.splitlines()[2:]]
    assert np.allclose(np.array(rows)[:, :3], np.array([[2000, 0, 900], [2100.5, -20.25, 950]]) + OFFSET)
    assert (tmp_path / "out.csv").read_text() == text


def test_one_loaded_model_serves_every_call(affine, monkeypatch):
    model = load_model(affine(offset=OFFSET))

    def no_reload(*args, **kwargs):
        raise AssertionError("a loaded model must not be loaded again")

    monkeypatch.setattr("postproc.compensation.api.load_model", no_reload)
    outputs = {postproc.compensate_text(CSV, model, name="p.csv")[0] for _ in range(3)}
    assert len(outputs) == 1


def test_public_names():
    assert all(getattr(postproc, name) is not None for name in postproc.__all__)
    with pytest.raises(postproc.PostprocError):
        postproc.load_model("/nonexistent/model.onnx")


# --------------------------------------------------------------------------- samples/cam_hook


def compensated_xyz(text: str, fmt: str) -> np.ndarray:
    """X,Y,Z of every target in a program, read independently of postproc's readers."""
    if fmt == "csv":
        rows = [line.split(",") for line in text.splitlines() if line[:1] == "N"]
        return np.array([[float(v) for v in r[1:4]] for r in rows])
    found = re.findall(r"^(?:PTP|LIN) \{X ([-\d.]+),Y ([-\d.]+),Z ([-\d.]+),", text, re.M)
    return np.array(found, dtype=float)


def expected_xyz(points: int, offset) -> np.ndarray:
    return np.array(fake_cam_post.toolpath(points))[:, :3] + offset


def cli_env(**extra):
    env = dict(os.environ, POSTPROC=f"{sys.executable} -m postproc", NO_COLOR="1", **extra)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO), env.get("PYTHONPATH")]))
    return env


@pytest.mark.parametrize("fmt", FORMATS)
def test_pipe_filter_example(affine, tmp_path, fmt):
    out = tmp_path / f"pocket.{'csv' if fmt == 'csv' else 'src'}"
    env = cli_env(CAM_FORMAT="--csv" if fmt == "csv" else "")
    done = subprocess.run(["sh", str(HOOK / "pipe_filter.sh"), str(out), str(cam_model(affine, OFFSET))],
                          capture_output=True, text=True, env=env)
    assert done.returncode == 0, done.stderr
    text = out.read_bytes().decode("latin-1")
    assert np.allclose(compensated_xyz(text, fmt), expected_xyz(100, OFFSET), atol=1e-9)
    # a model postproc refuses (6 mm > max correction): non-zero exit, message, no output file
    out.unlink()
    done = subprocess.run(["sh", str(HOOK / "pipe_filter.sh"), str(out), str(cam_model(affine, (6, 0, 0)))],
                          capture_output=True, text=True, env=env)
    assert done.returncode != 0 and " P303 " in done.stderr
    assert not out.exists() and not list(tmp_path.glob("pocket.*"))


@pytest.mark.parametrize("fmt", FORMATS)
def test_api_hook_example(affine, tmp_path, fmt):
    args = [sys.executable, str(HOOK / "api_hook.py"), str(tmp_path / "out"), "--model", str(cam_model(affine, OFFSET))]
    done = subprocess.run(args + (["--csv"] if fmt == "csv" else []), capture_output=True, text=True, env=cli_env())
    assert done.returncode == 0, done.stderr
    for name, points in (("roughing", 100), ("semi", 250), ("finishing", 1000)):
        text = (tmp_path / "out" / f"{name}.{'csv' if fmt == 'csv' else 'src'}").read_bytes().decode("latin-1")
        assert np.allclose(compensated_xyz(text, fmt), expected_xyz(points, OFFSET), atol=1e-9)
    done = subprocess.run(args[:-1] + [str(tmp_path / "none.onnx")], capture_output=True, text=True, env=cli_env())
    assert done.returncode == 2 and "P307 model not found" in done.stderr


# --------------------------------------------------------------------------- CLI conventions


def test_version_and_help_with_examples(capsys):
    with pytest.raises(SystemExit) as info:
        build_parser().parse_args(["--version"])
    assert info.value.code == 0 and capsys.readouterr().out.strip() == f"postproc {postproc.__version__}"
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    built = [name for name in SUBCOMMANDS if name.replace("_", "-") in sub.choices or name in sub.choices]
    assert {"compensate", "check", "report"} <= set(built)
    for name, parser in sub.choices.items():
        text = parser.format_help()
        assert "examples:" in text.lower(), f"postproc {name} --help shows no examples"
        assert "-q, --quiet" in text and "-v, --verbose" in text, f"postproc {name} lacks -q/-v"


def test_help_names_every_dialect_and_quotes_config_dat():
    """`postproc --help` names every dialect it reads; compensate's examples quote '$config.dat'
    (the shell would turn an unquoted $config.dat into .dat)."""
    text = " ".join(build_parser().format_help().split())
    for dialect in ("KUKA KRL", "ABB RAPID", "URScript", "FANUC LS", "pose lists"):
        assert dialect in text, dialect
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    examples = sub.choices["compensate"].format_help().split("examples:", 1)[1]
    configs = [line.split("--config", 1)[1].split()[0] for line in examples.splitlines() if "--config " in line]
    assert configs and all(c.startswith("'") and c.endswith("$config.dat'") for c in configs), configs

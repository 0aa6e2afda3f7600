"""A missing optional part (sim, train, report extra) is named with its install command,
never an 'internal error: ModuleNotFoundError'. Each case runs in its own process with the
module made unimportable (sys.modules[name] = None), as on an install without the extra."""
import subprocess
import sys

import pytest

from postproc.core.extras import install_command, missing_extra

from helpers import REPO

SAMPLE = REPO / "samples" / "krl" / "cam_pocket.src"
RUN = "import sys; sys.modules[sys.argv[1]] = None; from postproc.cli import main; sys.exit(main(sys.argv[2:]))"
TRAIN = "pip install torch==2.13.0 && pip install -e '.[train]'"


def without(module, *argv, cwd):
    done = subprocess.run([sys.executable, "-c", RUN, module, *map(str, argv)], cwd=cwd, capture_output=True,
                          text=True, timeout=60)
    return done.returncode, done.stderr


@pytest.fixture(scope="module")
def measured(tmp_path_factory):
    folder = tmp_path_factory.mktemp("extras")
    (folder / "m.csv").write_text("x,y,z,a,b,c,x_meas,y_meas,z_meas\n"
                                  + "".join(f"{2000 + i},{i},900,0,90,0,{2000.5 + i},{i},900\n" for i in range(30)))
    return folder


@pytest.mark.parametrize("module, argv, extra, command", [
    ("scipy", ["plan", "-n", "5", "-o", "p.csv"], "sim", "pip install -e '.[sim]'"),
    ("torch", ["train", "m.csv", "-o", "m.onnx", "--method", "gpso"], "train", TRAIN),
    ("matplotlib", ["report", "m.csv", "-o", "report"], "report", "pip install -e '.[report]'"),
])
def test_missing_extra_names_it_and_the_install_command(measured, module, argv, extra, command):
    status, err = without(module, *argv, cwd=measured)
    assert status == 2
    assert err.strip() == (f"postproc {argv[0]}: needs the '{extra}' extra (module '{module}' is not installed); "
                           f"in the postproc checkout run: {command}")
    assert not (measured / argv[argv.index("-o") + 1]).exists() if "-o" in argv else True


def test_the_simulator_needs_no_pinocchio(measured):
    # kinematics and gravity torques are numpy (Pinocchio is the tests' reference only)
    status, err = without("pinocchio", "measure", "m.csv", "-o", "sim.csv", "-q", cwd=measured)
    # (30 rows, the header, '# simulated: …' and '# robot_seed: …')
    assert (status, err) == (0, "") and (measured / "sim.csv").read_text().count("\n") == 33
    status, err = without("pinocchio", "verify", SAMPLE, SAMPLE, "-q", cwd=measured)
    assert (status, err) == (0, "")


def test_only_optional_modules_get_the_hint():
    assert missing_extra(ModuleNotFoundError("x", name="lark"), "compensate") is None  # a core dependency: a bug
    assert missing_extra(ModuleNotFoundError("x", name="postproc.nothing"), "plan") is None
    assert "pip install -e '.[sim]'" in missing_extra(ModuleNotFoundError("x", name="pinocchio.utils"), "train")
    # the train extra's torch>=2.3 alone would pull a multi-GB CUDA build: the CPU one first
    assert install_command("train") == TRAIN and install_command("all").startswith("pip install torch==2.13.0 && ")

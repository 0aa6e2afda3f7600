"""postproc fleet on a real cluster: a ``dask scheduler`` and two ``dask worker`` processes
started as separate processes on 127.0.0.1, each worker in a folder of its own (as on other
machines: the client's relative paths mean nothing there). The fleet file and ``-o`` are
given relative to the client's folder; the outputs must land in the client's ``-o``, nothing
in the workers' folders, and a rerun must see what is done — and what was deleted."""
import json
import os
import shutil
import signal
import subprocess
import sys
import time

import pytest

pytest.importorskip("dask.distributed")
pytest.importorskip("torch")

from postproc.cli import main  # noqa: E402
from postproc.core.resources import model_path  # noqa: E402

STARTUP_S = 60


def _start(argv, cwd, log):
    return subprocess.Popen([sys.executable, "-m", "dask", *argv], cwd=cwd, stdout=log, stderr=subprocess.STDOUT,
                            start_new_session=True, env={**os.environ, "OMP_NUM_THREADS": "1"})


def _stop(procs):
    for p in procs:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGTERM)
    for p in procs:
        try:
            p.wait(timeout=20)
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait(timeout=10)


@pytest.fixture
def cluster(tmp_path):
    """(scheduler address, the two workers' folders): three processes, stopped afterwards."""
    from dask.distributed import Client

    info = tmp_path / "scheduler.json"
    folders = [tmp_path / "worker-1", tmp_path / "worker-2"]
    for f in folders:
        f.mkdir()
    log = open(tmp_path / "cluster.log", "w")
    procs = [_start(["scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard", "--scheduler-file",
                     str(info)], tmp_path, log)]
    try:
        deadline = time.monotonic() + STARTUP_S
        while not info.is_file() and time.monotonic() < deadline:
            time.sleep(0.2)
        address = json.loads(info.read_text())["address"]
        procs += [_start(["worker", address, "--host", "127.0.0.1", "--nthreads", "1", "--no-dashboard",
                          "--memory-limit", "0", "--local-directory", str(f)], f, log) for f in folders]
        with Client(address, timeout=STARTUP_S) as client:
            client.wait_for_workers(2, timeout=STARTUP_S)
        yield address, folders
    finally:
        _stop(procs)
        log.close()


@pytest.mark.slow
def test_fleet_on_an_external_scheduler_and_workers(cluster, tmp_path, monkeypatch, capsys):
    from postproc.model.training.synthetic import synthetic_measurements, to_csv

    address, worker_folders = cluster
    here = tmp_path / "client"
    (here / "cells").mkdir(parents=True)
    for s in (1, 2):
        poses, measured = synthetic_measurements(80, seed=s)
        (here / "cells" / f"r{s}.csv").write_text(to_csv(poses, measured))
    shutil.copy(model_path().parent / "kr500.toml", here / "cells" / "kr500.toml")
    (here / "cells" / "fleet.toml").write_text(
        '[defaults]\nmethod = "plain"\nrobot = "kr500.toml"\nargs = ["--hidden", "3", "--epochs", "5", '
        '"--val-fraction", "0.2"]\n\n' + "".join(f'[[robot]]\nname = "r{s}"\ndata = "r{s}.csv"\n\n' for s in (1, 2))
        + '[[robot]]\nname = "gone"\ndata = "missing.csv"\n')
    monkeypatch.chdir(here)
    fleet = ["fleet", "cells/fleet.toml", "-o", "out", "--scheduler", address, "--format", "csv"]
    assert main(fleet) == 1  # the robot without data fails (on the client: P500 naming its path)
    rows = {line.split(",")[0]: line for line in (here / "out" / "fleet.csv").read_text().splitlines()[1:]}
    assert "P500" in rows["gone"] and str(here / "cells" / "missing.csv") in rows["gone"]
    for s in ("r1", "r2"):
        card = json.loads((here / "out" / s / "model-card.json").read_text())
        assert card["name"] == s and card["robot"] == "KR500-sim" and card["accuracy"]["n_val"] == 16
        assert (here / "out" / s / "model.onnx").is_file() and (here / "out" / s / "report" / "report.md").is_file()
        assert rows[s].split(",")[-1] == ""
    # the workers wrote nothing where they run (their scratch folders are gone too)
    assert not [p for f in worker_folders for p in f.rglob("*") if p.suffix in (".onnx", ".csv", ".md")]
    # a rerun sees what is done; a robot whose outputs were deleted is done again
    capsys.readouterr()
    (here / "out" / "r2" / "model.onnx").unlink()
    assert main(fleet) == 1
    rows = {line.split(",")[0]: line for line in (here / "out" / "fleet.csv").read_text().splitlines()[1:]}
    assert set(rows) == {"r1 (unchanged)", "r2", "gone"} and (here / "out" / "r2" / "model.onnx").is_file()

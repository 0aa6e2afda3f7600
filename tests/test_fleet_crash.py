"""A robot whose job kills its worker process fails alone: the nanny restarts the worker, the
task is tried once more, then that robot's row carries the failure and the others finish."""
import os

import pytest

pytest.importorskip("dask.distributed")
pytest.importorskip("torch")

from dask.distributed import WorkerPlugin  # noqa: E402


class CrashOn(WorkerPlugin):
    """Worker plugin (set up again in every restarted worker): robot ``name``'s job ends its process."""

    def __init__(self, name):
        self.name = name

    def setup(self, worker):
        import postproc.fleet.tasks as fleet

        real = getattr(fleet.train_robot, "real", fleet.train_robot)

        def train_robot(job, inputs):
            if job.name == self.name:
                os._exit(3)  # as a torch abort or the OOM killer would
            return real(job, inputs)

        train_robot.real = real
        fleet.train_robot = train_robot


@pytest.mark.slow
def test_a_robot_that_kills_its_worker_fails_alone(tmp_path):
    import dask
    from dask.distributed import Client, LocalCluster

    from postproc.fleet.cluster import run_fleet
    from postproc.fleet.jobs import RobotJob
    from postproc.model.training.synthetic import synthetic_measurements, to_csv

    poses, measured = synthetic_measurements(80, seed=2)
    (tmp_path / "a.csv").write_text(to_csv(poses, measured))
    jobs = [RobotJob(n, tmp_path / "a.csv", method="plain", args=["--hidden", "3", "--epochs", "5"])
            for n in ("good", "crash")]
    with dask.config.set({"distributed.scheduler.allowed-failures": 1}), \
            LocalCluster(n_workers=2, threads_per_worker=1, processes=True, memory_limit=0,
                         dashboard_address=":0") as cluster, Client(cluster) as client:
        client.register_plugin(CrashOn("crash"), name="crash-on")
        results = {r["name"]: r for r in run_fleet(jobs, tmp_path / "out", address=cluster.scheduler_address)}
    assert results["good"]["ok"] and (tmp_path / "out" / "good" / "model.onnx").is_file()
    assert not results["crash"]["ok"] and "KilledWorker" in results["crash"]["error"]

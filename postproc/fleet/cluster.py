"""The fleet on a task engine: Dask distributed (``address`` for a real scheduler; else a local
cluster, :func:`_local_cluster`). Each robot is two tasks (``tasks.train_robot``, then
``tasks.report_robot``); a rerun skips a robot whose inputs are unchanged and whose outputs are
still where they were written (``fleet-state.json``); ``tasks.task_map`` runs a ``train --search``'s
candidates as tasks on the same cluster.

The local cluster has two kinds of worker process, one task at a time each (Dask worker
resources): one training worker per core, which never imports onnxruntime (once it is loaded,
a training takes ~25 % more CPU here, in torch's ONNX export; the two share pybind11's internals
and perf shows C++ exception unwinding there only then, the cause is not pinned down), and a third
as many report workers (onnxruntime, matplotlib, no torch); their nannies set OMP/MKL/OpenBLAS
threads to 1 (torch runs one thread) and restart a worker a robot's crash killed.

Measured here (2 cores shared by six developers, load 2.2-3.1; benchmarks/fleet_engines.py, 200 no-op
tasks after 10 warm-up ones): Ray ``ray.init(num_cpus=2)`` import+start 4.4-7.5 s, 1.0-3.3 ms
per task; Dask ``LocalCluster(processes=False)`` import+start 0.4-0.9 s, 2.0-2.7 ms per task;
``pip install "dask[distributed]"`` 6 s, ``pip install ray`` 32 s. A robot's job takes seconds
(training, report), so the per-task cost of either is noise; Dask starts faster, installs faster
and is the one picked. The fleet's speed against ``postproc train`` 16 times in a row:
benchmarks/fleet_speed.py.
"""
from __future__ import annotations

import json
import os
import sys
from pathlib import Path

from ..core.diagnostics import PostprocError
from ..core.progress import ProgressBar
from . import tasks
from .jobs import STATE_FILE, RobotJob, read_inputs
from .tasks import _outputs_there, write_outputs

__all__ = ["run_fleet", "TRAIN", "REPORT"]


# the local cluster's two kinds of worker processes (Dask worker resources)
TRAIN, REPORT = "postproc-train", "postproc-report"


def _local_cluster(workers: int | None, robots: int | None = None):
    """``workers`` (default: one per core; no more than ``robots``) training worker processes and a
    third as many report workers, one thread each (the module's docstring says why two kinds)."""
    import logging

    from dask.distributed import Nanny, Scheduler, SpecCluster

    n = min(workers or os.cpu_count() or 1, robots or sys.maxsize)
    worker = {"nthreads": 1, "memory_limit": 0, "host": "127.0.0.1", "dashboard": False, "silence_logs": logging.WARN}
    specs = {f"train-{i}": {"cls": Nanny, "options": {**worker, "resources": {TRAIN: 1}}} for i in range(n)}
    specs.update({f"report-{i}": {"cls": Nanny, "options": {**worker, "resources": {REPORT: 1}}}
                  for i in range((n + 2) // 3)})
    # (its HTTP endpoints on a free port: two fleets on one machine do not ask for the same one)
    scheduler = {"cls": Scheduler, "options": {"host": "127.0.0.1", "dashboard": False, "dashboard_address": "127.0.0.1:0"}}
    return SpecCluster(workers=specs, scheduler=scheduler, silence_logs=logging.WARN)


def run_fleet(jobs: list[RobotJob], outdir: str | Path, address: str | None = None, workers: int | None = None,
              force: bool = False) -> list[dict]:
    """Every robot as two tasks on Dask, :func:`train_robot` then :func:`report_robot` (on the local
    cluster each on its kind of worker); robots with unchanged inputs skipped."""
    import dask
    from dask.distributed import Client

    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    state_path = outdir / STATE_FILE
    state = json.loads(state_path.read_text()) if state_path.is_file() else {}
    digests = {j.name: j.digest() for j in jobs}
    results, todo, inputs = {}, [], []
    for job in jobs:
        old = state.get(job.name)
        if (not force and old and old.get("digest") == digests[job.name] and old["result"].get("ok")
                and _outputs_there(old["result"], outdir)):
            results[job.name] = {**old["result"], "skipped": True}
            continue
        try:
            inputs.append(read_inputs(job))  # (on the client: the workers get the bytes)
            todo.append(job)
        except PostprocError as exc:
            results[job.name] = {"name": job.name, "ok": False, "error": str(exc), "warnings": []}
    if todo:
        if address:
            client, kinds = Client(address), (None, None)
        else:
            # each worker process imports its libraries once and runs robot after robot in itself; a
            # robot that kills its process is retried once, then fails alone
            with dask.config.set({"distributed.scheduler.allowed-failures": 1}):
                client, kinds = Client(_local_cluster(workers, len(todo))), ({TRAIN: 1}, {REPORT: 1})
        try:
            # the bytes go in the tasks themselves (not scattered: a worker that dies would take
            # scattered data with it, and with it every robot whose inputs it held)
            trained = client.map(tasks.train_robot, todo, inputs, pure=False, resources=kinds[0])
            futures = [client.submit(tasks.report_robot, t, job, i, pure=False, resources=kinds[1])
                       for t, job, i in zip(trained, todo, inputs)]
            with ProgressBar("fleet", len(todo), "robot") as bar:
                for job, fut in zip(todo, futures):
                    try:
                        results[job.name] = write_outputs(fut.result(), outdir)
                    except Exception as exc:  # the task itself broke (worker lost): this robot fails alone
                        results[job.name] = {"name": job.name, "ok": False, "error": f"{type(exc).__name__}: {exc}",
                                             "warnings": []}
                    bar.update(1)
        finally:
            cluster = getattr(client, "cluster", None)
            client.close()
            if cluster is not None:
                cluster.close()
    ordered = [results[j.name] for j in jobs]
    state = {r["name"]: {"digest": digests[r["name"]], "result": {k: v for k, v in r.items() if k != "skipped"}}
             for r in ordered}
    state_path.write_text(json.dumps(state, indent=2, default=str), encoding="utf-8")
    return ordered

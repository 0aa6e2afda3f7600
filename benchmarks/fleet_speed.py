"""postproc fleet on 2 cores: 16 simulated robots (plan + measure --robot-seed S, 200 rows,
--method kinematic) on the local Dask cluster against the same work one robot after another.

    OMP_NUM_THREADS=1 python benchmarks/fleet_speed.py [--robots 16] [--rows 200]

Prints: Dask start-up and per-task overhead (no-op tasks), the sequential wall times
(`postproc train` alone 16 times in a row; train+report through the adapter, i.e. as
subprocesses), the fleet's wall time (one worker process per core, robots run in the workers),
the ratio, and the overhead per robot; `uptime` beside each (the machine is shared).
`--one-worker` adds the fleet on one worker process (the same in-process work in a row).

Measured 2026-12-01, robots as subprocesses on a threaded in-process cluster (1-min load in brackets):
  run 2: train x16 in a row 53.9 s (2.1); train+report x16 in a row 88.4 s (1.7); fleet 60.2 s (2.1):
         1.47x against the same work in a row, overhead ~1.0 s per robot.
Measured 2026-12-02, robots in the worker processes (`--one-worker`, each run back to back):
  run 1: start 2.90 s, no-op task 6.4 ms (8.9); train x16 in a row 127.9 s (7.3);
         train+report x16 in a row 135.9 s (4.8); fleet 69.3 s (5.7): 1.96x (1.85x vs train alone);
         fleet on one worker 67.1 s (4.6): the other developers' jobs held the second core.
  run 2: start 0.44 s, no-op task 1.6 ms (1.8); train x16 in a row 45.0 s (1.5); train+report x16 in a
         row 65.5 s (1.5); fleet 41.0 s (3.4): 1.60x (1.10x vs train alone); one worker 47.8 s (3.8).
  Overhead per robot ((wall - in a row / 2) / 16): 0.09 s (run 1), 0.52 s (run 2), was ~1.0 s.
  Per robot in a warm worker: ~2.2 s of CPU (os.times; about half train, half report, mostly
  matplotlib drawing the plots), against 4.1 s wall for the two subprocesses at load 1.5 (torch,
  pinocchio, matplotlib imported each time); in run 2 the fleet's tasks got ~30 % of a core
  each (load 3.4-5 while it ran), hence the small gain of 2 workers over 1.
"""
import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

from postproc.cli import main
from postproc.fleet import RobotJob, _run_cli, run_fleet, train_robot

from _common import load  # benchmarks/ is on sys.path when a benchmark runs as a script


def engine_overhead(n=200):
    from dask.distributed import Client, LocalCluster

    t0 = time.perf_counter()
    cluster = LocalCluster(n_workers=os.cpu_count(), threads_per_worker=1, processes=True, memory_limit=0,
                           dashboard_address=":0")
    client = Client(cluster)
    start = time.perf_counter() - t0
    client.gather(client.map(lambda i: i, range(10), pure=False))
    t0 = time.perf_counter()
    client.gather(client.map(lambda i: i, range(n), pure=False))
    per_task = (time.perf_counter() - t0) / n
    client.close()
    cluster.close()
    return start, per_task


def main_(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--robots", type=int, default=16)
    ap.add_argument("--rows", type=int, default=200)
    ap.add_argument("--one-worker", action="store_true", help="also the fleet on one worker process (robots in a row)")
    a = ap.parse_args(argv)
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    d = Path(tempfile.mkdtemp(prefix="fleet-bench-"))
    main(["plan", "-n", str(a.rows), "--seed", "1", "-o", str(d / "plan.csv"), "-q"])
    jobs = []
    for s in range(1, a.robots + 1):
        main(["measure", str(d / "plan.csv"), "--robot-seed", str(s), "-o", str(d / f"r{s}.csv"), "-q"])
        jobs.append(RobotJob(f"r{s}", d / f"r{s}.csv", method="kinematic", args=["--val-fraction", "0.2"]))
    start, per_task = engine_overhead()
    print(f"dask LocalCluster start {start:.2f} s, per no-op task {per_task * 1e3:.2f} ms  (load {load()})")
    (d / "seq-train").mkdir()
    t0 = time.perf_counter()
    for j in jobs:
        code, err = _run_cli(j.train_argv(d / "seq-train" / f"{j.name}.onnx"))
        assert code == 0, err
    seq_train = time.perf_counter() - t0
    print(f"postproc train x{a.robots} in a row: {seq_train:.1f} s  (load {load()})")
    t0 = time.perf_counter()
    for j in jobs:
        assert train_robot(j, d / "seq")["ok"]
    seq = time.perf_counter() - t0
    print(f"adapter (train + report) x{a.robots} in a row: {seq:.1f} s  (load {load()})")
    cores = os.cpu_count()
    t0 = time.perf_counter()
    results = run_fleet(jobs, d / "fleet")
    wall = time.perf_counter() - t0
    assert all(r["ok"] for r in results)
    print(f"fleet on dask ({cores} worker processes): {wall:.1f} s  (load {load()})")
    if a.one_worker:
        t0 = time.perf_counter()
        assert all(r["ok"] for r in run_fleet(jobs, d / "fleet1", workers=1))
        one = time.perf_counter() - t0
        print(f"fleet on dask (1 worker process): {one:.1f} s  (load {load()}); {cores} workers against 1: "
              f"{one / wall:.2f}x")
    print(f"ratio vs adapter in a row {seq / wall:.2f}x, vs train alone in a row {seq_train / wall:.2f}x")
    print(f"overhead per robot (wall - sequential/{cores}) / robots: {(wall - seq / cores) / a.robots:.2f} s "
          f"(negative: the workers import torch, matplotlib once, the subprocesses in a row once per robot)")


if __name__ == "__main__":
    sys.exit(main_())

"""Task engines for `postproc fleet`: start-up and per-task overhead of Dask and Ray here.

    python benchmarks/fleet_engines.py       # Ray is measured only when installed (pip install ray)
"""
import importlib.util
import time

from _common import load

N = 200


def noop(i):
    return i


def dask_threads():
    t0 = time.perf_counter()
    from dask.distributed import Client, LocalCluster

    cluster = LocalCluster(n_workers=1, threads_per_worker=2, processes=False, dashboard_address=None)
    client = Client(cluster)
    start = time.perf_counter() - t0
    client.gather(client.map(noop, range(10), pure=False))
    t0 = time.perf_counter()
    client.gather(client.map(noop, range(N), pure=False))
    per = (time.perf_counter() - t0) / N
    client.close()
    cluster.close()
    print(f"dask LocalCluster(processes=False): import+start {start:.2f} s, per no-op task {per * 1e3:.2f} ms "
          f"(load {load()})")


def ray_local():
    t0 = time.perf_counter()
    import ray

    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    start = time.perf_counter() - t0
    f = ray.remote(noop)
    ray.get([f.remote(i) for i in range(10)])
    t0 = time.perf_counter()
    ray.get([f.remote(i) for i in range(N)])
    per = (time.perf_counter() - t0) / N
    ray.shutdown()
    print(f"ray.init(num_cpus=2): import+start {start:.2f} s, per no-op task {per * 1e3:.2f} ms (load {load()})")


if __name__ == "__main__":
    dask_threads()
    if importlib.util.find_spec("ray"):
        ray_local()

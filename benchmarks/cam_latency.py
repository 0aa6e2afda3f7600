"""Latency of compensating a small CAM program from process start (goal: 100 targets ≤ 0.5 s).

    python benchmarks/cam_latency.py [--targets 100] [--runs 10] [--model models/default.onnx] [--csv]

Each figure is the wall time of a fresh process (median, min and max of --runs) with this
interpreter (sys.executable; a pyenv/conda shim in front of it adds its own start-up):

* floor: `python -c pass`, `python -c "import numpy, onnxruntime"` and with lark (what any caller pays);
* filter: `python -m postproc compensate - -o - -q` with the program on stdin, without and with
  the session cache (postproc/session.py), and its ratio to the import floor with lark;
* script: the `postproc` console script, same arguments;
* API: `import postproc; m = postproc.load_model(); postproc.compensate_text(text, m)`;
* warm API: per-call time of compensate_text with the model already loaded (CAM posts that
  keep one process for a job pay only this after the first program);

then the imports of one filter run by `python -X importtime`, the largest first. The program
is the fake CAM post's pocket (samples/cam_hook/fake_cam_post.py): KRL when the KRL reader is
there, else (or with --csv) the pose-list form.
"""
from __future__ import annotations

import argparse
import importlib.util
import os
import re
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "samples" / "cam_hook"))
from fake_cam_post import post  # noqa: E402


def wall(cmd: list[str], stdin: bytes, runs: int, env: dict | None = None) -> tuple[float, float, float, float]:
    """Median, min and max wall time of ``runs`` processes, and their median CPU time (user +
    system: less sensitive than wall time to the other processes of a shared machine)."""
    times, cpu = [], []
    for _ in range(runs):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        done = subprocess.run(cmd, input=stdin, capture_output=True, env=env)
        times.append(time.perf_counter() - start)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu.append(after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime)
        if done.returncode != 0:
            raise SystemExit(f"{' '.join(cmd)} failed:\n{done.stderr.decode(errors='replace')}")
    return statistics.median(times), min(times), max(times), statistics.median(cpu)


def import_costs(cmd: list[str], stdin: bytes, top: int = 10) -> list[tuple[str, float]]:
    """(package, cumulative ms) of the top-level imports of one run, largest first."""
    done = subprocess.run([cmd[0], "-X", "importtime", *cmd[1:]], input=stdin, capture_output=True)
    costs: dict[str, float] = {}
    for line in done.stderr.decode(errors="replace").splitlines():
        m = re.match(r"import time:\s+\d+ \|\s+(\d+) \| ( *)(\S+)", line)
        if m and len(m.group(2)) <= 2:  # a module imported by the program or by postproc directly
            name = m.group(3).split(".")[0] if not m.group(3).startswith("postproc") else m.group(3)
            costs[name] = max(costs.get(name, 0.0), int(m.group(1)) / 1000)
    return sorted(costs.items(), key=lambda kv: -kv[1])[:top]


FLOOR = "floor: import numpy, onnxruntime, lark"
FILTER = "filter: python -m postproc compensate - -o -"
FILTER_UNCACHED = "filter, no session cache (POSTPROC_CACHE_DIR='')"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--targets", type=int, default=100)
    parser.add_argument("--runs", type=int, default=10)
    parser.add_argument("--model", default=str(REPO / "models" / "default.onnx"))
    parser.add_argument("--csv", action="store_true", help="use the pose-list form even if KRL can be read")
    args = parser.parse_args()

    krl = importlib.util.find_spec("postproc.programs.krl") is not None and not args.csv
    name = "pocket.src" if krl else "pocket.csv"
    text = post("pocket", args.targets, as_csv=not krl)
    data = text.encode("latin-1")
    py = sys.executable
    filter_cmd = [py, "-m", "postproc", "compensate", "-", "-o", "-", "-q", "--model", args.model]
    api = (f"import sys, postproc; m = postproc.load_model({args.model!r}); "
           f"t, r = postproc.compensate_text(sys.stdin.read(), m, name={name!r}); sys.stdout.write(t)")
    rows = [
        ("floor: python -c pass", [py, "-c", "pass"]),
        ("floor: import numpy, onnxruntime", [py, "-c", "import numpy, onnxruntime"]),
        (FLOOR, [py, "-c", "import numpy, onnxruntime, lark"]),
        (FILTER_UNCACHED, filter_cmd, {**os.environ, "POSTPROC_CACHE_DIR": ""}),
        (FILTER, filter_cmd),
    ]
    subprocess.run(filter_cmd, input=data, capture_output=True)  # the first use writes the session cache
    script = Path(py).parent / "postproc"
    if script.is_file():
        rows.append(("script: postproc compensate - -o -", [str(script), *filter_cmd[3:]]))
    rows.append(("API: load_model + compensate_text", [py, "-c", api]))

    print(f"{args.targets}-target {'KRL' if krl else 'pose-list'} program, {args.runs} runs each, "
          f"model {Path(args.model).name}, {py}")
    if os.environ.get("PYTHONDONTWRITEBYTECODE") and not (REPO / "postproc" / "__pycache__").is_dir():
        print("note: PYTHONDONTWRITEBYTECODE is set and postproc has no .pyc: each run compiles its modules "
              "(~0.07 s here; `python -m compileall -q postproc` first for a user's figure)")
    print(f"{'':48} {'median':>8} {'min':>8} {'max':>8}  (s, wall from process start) {'CPU':>8} (median)")
    medians, cpus = {}, {}
    for label, cmd, *env in rows:
        med, lo, hi, cpu = wall(cmd, data, args.runs, *env)
        medians[label], cpus[label] = med, cpu
        print(f"{label:48} {med:8.3f} {lo:8.3f} {hi:8.3f} {cpu:45.3f}")
    print(f"ratio filter / import floor (numpy, onnxruntime, lark), medians of this run: "
          f"{medians[FILTER] / medians[FLOOR]:.2f}× wall, {cpus[FILTER] / cpus[FLOOR]:.2f}× CPU (goal ≤ 1.3×; "
          f"without the session cache {medians[FILTER_UNCACHED] / medians[FLOOR]:.2f}× wall, "
          f"{cpus[FILTER_UNCACHED] / cpus[FLOOR]:.2f}× CPU)")

    sys.path.insert(0, str(REPO))
    import postproc

    model = postproc.load_model(args.model)
    postproc.compensate_text(text, model, name=name)  # first call builds the parsers
    calls = []
    for _ in range(args.runs):
        start = time.perf_counter()
        postproc.compensate_text(text, model, name=name)
        calls.append(time.perf_counter() - start)
    print(f"{'warm API: compensate_text, model loaded':48} {statistics.median(calls):8.4f} {min(calls):8.4f} "
          f"{max(calls):8.4f}")

    from _common import record  # (benchmarks/ is on sys.path: this script's own folder)

    figures = {"targets": args.targets, "runs": args.runs, "floor_s": round(medians[FLOOR], 3),
               "filter_s": round(medians[FILTER], 3), "filter_uncached_s": round(medians[FILTER_UNCACHED], 3),
               "ratio": round(medians[FILTER] / medians[FLOOR], 2), "ratio_cpu": round(cpus[FILTER] / cpus[FLOOR], 2),
               "ratio_uncached": round(medians[FILTER_UNCACHED] / medians[FLOOR], 2),
               "warm_api_s": round(statistics.median(calls), 4)}
    print(f"figures: {record('cam_latency', figures).relative_to(REPO)}")
    print("\nimports of one filter run (python -X importtime, cumulative ms):")
    for package, ms in import_costs(filter_cmd, data):
        print(f"  {package:40} {ms:8.1f}")


if __name__ == "__main__":
    main()

"""Latency of compensating a small CAM program from process start (goal: 100 targets ≤ 0.5 s).

    python benchmarks/cam_latency.py [--targets 100] [--runs 10] [--model models/default.onnx] [--csv]
                                     [--against PYTHON] [--sessions]

Each figure is the wall time of a fresh process (median, min and max of --runs) with this
interpreter (sys.executable; a pyenv/conda shim in front of it adds its own start-up):

* floor: `python -c pass`, `python -c "import numpy, onnxruntime"` and with lark (what any caller pays);
* filter: `python -m postproc compensate - -o - -q` with the program on stdin, without and with
  the session cache (postproc/model/session.py), and its ratio to the import floor with lark;
* script: the `postproc` console script, same arguments;
* API: `import postproc; m = postproc.load_model(); postproc.compensate_text(text, m)`;
* warm API: per-call time of compensate_text with the model already loaded (CAM posts that
  keep one process for a job pay only this after the first program);

then where a filter run's CPU time goes, stage by stage (median of --runs fresh processes:
the imports beyond the floor's, reading the program, loading the model = its session, the
compensation), and the imports of one filter run by `python -X importtime`, the largest first.
The program is the fake CAM post's pocket (samples/cam_hook/fake_cam_post.py): KRL when the
KRL reader is there, else (or with --csv) the pose-list form. The processes of all rows run
round-robin (one of each row, then the next round), so that a change of the machine's load
falls on every row alike.

--against PYTHON: the filter rows also with another interpreter (e.g. a venv whose postproc
is another checkout), in the same rounds: the before/after ratios of one run. --sessions: the
session's start-up alone, from the ONNX file, from session.py's cached optimised graph (also
with intra-op spinning off) and from that graph in ORT format.
"""
from __future__ import annotations

import argparse
import importlib.util
import json
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


def run_once(cmd: list[str], stdin: bytes, env: dict | None = None) -> tuple[float, float]:
    """Wall and CPU time (user + system: less sensitive than wall time to the other processes
    of a shared machine) of one process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run(cmd, input=stdin, capture_output=True, env=env)
    seconds = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{done.stderr.decode(errors='replace')}")
    return seconds, after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime


def measure(rows: list[tuple], stdin: bytes, runs: int) -> dict[str, tuple[float, float, float, float]]:
    """Each row's median, min and max wall time and median CPU time over ``runs`` rounds; a
    round runs every row once."""
    times: dict[str, list[tuple[float, float]]] = {row[0]: [] for row in rows}
    for _ in range(runs):
        for label, cmd, *env in rows:
            times[label].append(run_once(cmd, stdin, *env))
    out = {}
    for label, pairs in times.items():
        walls = [w for w, _ in pairs]
        out[label] = (statistics.median(walls), min(walls), max(walls), statistics.median(c for _, c in pairs))
    return out


# One filter run's stages in a fresh process, CPU ms each (the CLI's path: settings, program
# from text, model, compensate_program); the modules imported first, the floor's apart.
STAGES = """
import json, sys, time
clock = time.process_time
t0 = clock()
import numpy, onnxruntime, lark
t1 = clock()
import postproc.cli.compensate, postproc.compensation.pipeline, postproc.model.compensator, postproc.settings.file, postproc.compensation.inputs
import postproc.robot.configuration, postproc.model.session, postproc.programs.{reader}
from postproc.compensation.pipeline import compensate_program
from postproc.programs.io import parse_program_text
t2 = clock()
cfg = postproc.settings.file.load_settings(None)
program = parse_program_text(sys.stdin.read(), {name!r})
t3 = clock()
model = postproc.model.compensator.load_model({model!r})
t4 = clock()
report = compensate_program(program, model)
t5 = clock()
assert report.complete
print(json.dumps([t1 - t0, t2 - t1, t3 - t2, t4 - t3, t5 - t4]))
"""
STAGE_NAMES = {"floor_imports": "floor's imports: numpy, onnxruntime, lark",
               "postproc_imports": "postproc's imports (the modules a run uses)",
               "read": "settings + reading the program (its parser from lark's cache)",
               "model": "loading the model (file, session from the cache, card)",
               "compensate": "compensate_program (controller rules, model runs, rewrite, guards)"}


def stages(py: str, stdin: bytes, runs: int, name: str, model: str) -> list[float]:
    """Median CPU seconds of each stage (STAGE_NAMES) over ``runs`` fresh processes."""
    code = STAGES.format(reader="krl" if name.endswith(".src") else "poses", name=name, model=model)
    rows = []
    for _ in range(runs):
        done = subprocess.run([py, "-c", code], input=stdin, capture_output=True)
        if done.returncode != 0:
            raise SystemExit(f"stages failed:\n{done.stderr.decode(errors='replace')}")
        rows.append(json.loads(done.stdout))
    return [statistics.median(column) for column in zip(*rows)]


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
AGAINST_FLOOR = "--against: floor (numpy, onnxruntime, lark)"
AGAINST = "--against: filter"
AGAINST_UNCACHED = "--against: filter, no session cache"


# Session start-up, one variant per fresh process (--sessions): CPU ms of InferenceSession() only.
SESSION = """
import sys, time
import onnxruntime as ort
variant, path = sys.argv[1], sys.argv[2]
data = open(path, "rb").read()
options = ort.SessionOptions()
options.log_severity_level = 3
options.intra_op_num_threads = options.inter_op_num_threads = 1
if variant != "original":
    options.graph_optimization_level = ort.GraphOptimizationLevel.ORT_DISABLE_ALL
if variant == "no spinning":
    options.add_session_config_entry("session.intra_op.allow_spinning", "0")
if variant == "ORT format":
    options.add_session_config_entry("session.load_model_format", "ORT")
start = time.process_time()
ort.InferenceSession(data, options, providers=["CPUExecutionProvider"])
print(time.process_time() - start)
"""


def session_costs(py: str, model: str, runs: int) -> dict[str, float]:
    """Median CPU seconds of creating the model's session: from the ONNX file (optimised at
    creation), from the optimised graph (session.py's cache; with intra-op spinning off), and
    from that graph in ORT format (the same optimisation, saved by ORT in its own format)."""
    import tempfile

    import onnxruntime as ort

    with tempfile.TemporaryDirectory() as folder:
        saved = {}
        for kind, suffix in (("ONNX", ".onnx"), ("ORT", ".ort")):
            options = ort.SessionOptions()
            options.log_severity_level = 3
            options.intra_op_num_threads = options.inter_op_num_threads = 1
            options.optimized_model_filepath = saved[kind] = str(Path(folder) / f"optimised{suffix}")
            ort.InferenceSession(model, options, providers=["CPUExecutionProvider"])
        variants = {"original": model, "cached graph": saved["ONNX"], "no spinning": saved["ONNX"],
                    "ORT format": saved["ORT"]}
        times: dict[str, list[float]] = {v: [] for v in variants}
        for _ in range(runs):
            for variant, path in variants.items():
                done = subprocess.run([py, "-c", SESSION, variant, path], capture_output=True, text=True)
                if done.returncode != 0:
                    raise SystemExit(f"session {variant} failed:\n{done.stderr}")
                times[variant].append(float(done.stdout))
    return {variant: statistics.median(t) for variant, t in times.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--targets", type=int, default=100)
    parser.add_argument("--runs", type=int, default=10)
    parser.add_argument("--model", default=str(REPO / "models" / "default.onnx"))
    parser.add_argument("--csv", action="store_true", help="use the pose-list form even if KRL can be read")
    parser.add_argument("--against", metavar="PYTHON", help="also the filter rows with this interpreter, interleaved")
    parser.add_argument("--sessions", action="store_true", help="also the session start-up of each variant (ORT format...)")
    args = parser.parse_args()

    krl = importlib.util.find_spec("postproc.programs.krl") is not None and not args.csv
    name = "pocket.src" if krl else "pocket.csv"
    text = post("pocket", args.targets, as_csv=not krl)
    data = text.encode("latin-1")
    py = sys.executable
    filter_args = ["-m", "postproc", "compensate", "-", "-o", "-", "-q", "--model", args.model]
    filter_cmd = [py, *filter_args]
    api = (f"import sys, postproc; m = postproc.load_model({args.model!r}); "
           f"t, r = postproc.compensate_text(sys.stdin.read(), m, name={name!r}); sys.stdout.write(t)")
    uncached = {**os.environ, "POSTPROC_CACHE_DIR": ""}
    rows = [
        ("floor: python -c pass", [py, "-c", "pass"]),
        ("floor: import numpy, onnxruntime", [py, "-c", "import numpy, onnxruntime"]),
        (FLOOR, [py, "-c", "import numpy, onnxruntime, lark"]),
        (FILTER_UNCACHED, filter_cmd, uncached),
        (FILTER, filter_cmd),
    ]
    subprocess.run(filter_cmd, input=data, capture_output=True)  # the first use writes the session cache
    if args.against:
        rows += [(AGAINST_FLOOR, [args.against, "-c", "import numpy, onnxruntime, lark"]),
                 (AGAINST_UNCACHED, [args.against, *filter_args], uncached),
                 (AGAINST, [args.against, *filter_args])]
        subprocess.run([args.against, *filter_args], input=data, capture_output=True)
    script = Path(py).parent / "postproc"
    if script.is_file():
        rows.append(("script: postproc compensate - -o -", [str(script), *filter_args[2:]]))
    rows.append(("API: load_model + compensate_text", [py, "-c", api]))

    print(f"{args.targets}-target {'KRL' if krl else 'pose-list'} program, {args.runs} runs each (round-robin), "
          f"model {Path(args.model).name}, {py}")
    if os.environ.get("PYTHONDONTWRITEBYTECODE") and not (REPO / "postproc" / "__pycache__").is_dir():
        print("note: PYTHONDONTWRITEBYTECODE is set and postproc has no .pyc: each run compiles its modules "
              "(~0.07 s here; `python -m compileall -q postproc` first for a user's figure)")
    print(f"{'':48} {'median':>8} {'min':>8} {'max':>8}  (s, wall from process start) {'CPU':>8} (median)")
    results = measure(rows, data, args.runs)
    medians = {label: r[0] for label, r in results.items()}
    cpus = {label: r[3] for label, r in results.items()}
    for label, (med, lo, hi, cpu) in results.items():
        print(f"{label:48} {med:8.3f} {lo:8.3f} {hi:8.3f} {cpu:45.3f}")

    def ratios(filter_row: str, uncached_row: str, floor_row: str) -> str:
        return (f"{medians[filter_row] / medians[floor_row]:.2f}× wall, {cpus[filter_row] / cpus[floor_row]:.2f}× CPU "
                f"(without the session cache {medians[uncached_row] / medians[floor_row]:.2f}× wall, "
                f"{cpus[uncached_row] / cpus[floor_row]:.2f}× CPU)")

    print(f"ratio filter / import floor (numpy, onnxruntime, lark), medians of this run: "
          f"{ratios(FILTER, FILTER_UNCACHED, FLOOR)}; goal ≤ 1.3×")
    if args.against:
        print(f"  the same with {args.against}, in the same rounds: {ratios(AGAINST, AGAINST_UNCACHED, AGAINST_FLOOR)}")

    print(f"\nwhere a filter run's CPU time goes (median of {args.runs} fresh processes, ms):")
    spent = stages(py, data, args.runs, name, args.model)
    for label, seconds in zip(STAGE_NAMES.values(), spent):
        print(f"  {label:70} {1000 * seconds:7.1f}")

    if args.sessions:
        print(f"\nsession start-up, CPU ms (median of {args.runs} fresh processes, round-robin):")
        for variant, seconds in session_costs(py, args.model, args.runs).items():
            print(f"  {variant:70} {1000 * seconds:7.1f}")

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
               "warm_api_s": round(statistics.median(calls), 4),
               "stages_cpu_ms": {key: round(1000 * seconds, 1) for key, seconds in zip(STAGE_NAMES, spent)}}
    print(f"figures: {record('cam_latency', figures).relative_to(REPO)}")
    print("\nimports of one filter run (python -X importtime, cumulative ms):")
    for package, ms in import_costs(filter_cmd, data):
        print(f"  {package:40} {ms:8.1f}")


if __name__ == "__main__":
    main()

"""A fleet of robots: the fleet file → one job per robot, run on a task engine, → the fleet table.

The fleet file (TOML)::

    [defaults]                       # optional; every robot inherits these
    method = "kinematic"             # postproc train --method
    robot = "models/kr500.toml"      # nominal description (--robot)
    args = ["--val-fraction", "0.2"] # further `postproc train` arguments

    [[robot]]
    name = "cell1"                   # required, unique; the output folder's name
    data = "cell1.csv"               # required: the measurement CSV
    previous = "old/cell1.onnx"      # optional: the robot's previous model: train --update it

Paths are relative to the fleet file, resolved where ``postproc fleet`` runs (the client). A
bad file is refused with P610 at its line.

Where things happen: the client reads each robot's files (data, description, previous model)
and sends their bytes to the cluster; a task puts them in a scratch folder of its own worker,
works there and sends back the files it made (the model, its card, the held-out rows, the
report), which the client writes into ``-o`` (each robot's folder whole or not at all). So a
real cluster — ``dask scheduler`` and ``dask worker`` processes started elsewhere, with other
working directories or other disks — reads and writes exactly what the local one does, and
messages name the client's paths. A rerun skips a robot only when its inputs are unchanged and
the outputs recorded for it are still in ``-o`` as written.

Engine: Dask distributed (``address`` for a real scheduler; else a local cluster,
:func:`_local_cluster`). Each robot is two tasks: :func:`train_robot`, the one adapter to the
training (``postproc train``, ``--update`` with a previous model), then :func:`report_robot`
(the model card, the table's figures, ``postproc report``'s library on the held-out rows).
The local cluster has two kinds of worker process, one task at a time each (Dask worker
resources): one training worker per core, which never imports onnxruntime (once it is loaded,
a training takes ~25 % more CPU here, in torch's ONNX export; the two share pybind11's internals
and perf shows C++ exception unwinding there only then, the cause is not pinned down), and a third
as many report workers (onnxruntime, matplotlib, no torch). A training worker runs ``postproc train`` in its
own process (:func:`_run_cli`): the imports (torch alone ~2 s here) are paid once per worker,
and a robot whose training crashes the process (a torch abort, out of memory) fails alone, its
worker restarted by the nanny (which also sets OMP/MKL/OpenBLAS threads to 1: torch runs one
thread). Elsewhere (a worker running several tasks at a time) it is a subprocess. When a
library training API exists (issue 16.2) this adapter is the one place to switch to it. The
structure search of ``train --search`` (:func:`task_map`) runs its candidates as tasks on the
same cluster.

Measured here (2 cores shared by six developers, load 2.2-3.1; benchmarks/fleet_engines.py, 200 no-op
tasks after 10 warm-up ones): Ray ``ray.init(num_cpus=2)`` import+start 4.4-7.5 s, 1.0-3.3 ms
per task; Dask ``LocalCluster(processes=False)`` import+start 0.4-0.9 s, 2.0-2.7 ms per task;
``pip install "dask[distributed]"`` 6 s, ``pip install ray`` 32 s. A robot's job takes seconds
(subprocess start, training, report), so the per-task cost of either is noise; Dask starts
faster, installs faster and is the one picked.
The fleet's speed against ``postproc train`` 16 times in a row: benchmarks/fleet_speed.py.
A rerun skips robots whose inputs (sha256 of the data,
robot description, method/arguments, previous model) did not change and whose outputs are still
there (their sha256 recorded): ``fleet-state.json`` beside the outputs.
"""
from __future__ import annotations

import contextlib
import csv
import hashlib
import html
import io
import json
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import tomllib
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

from ..core.diagnostics import P500, P610, PostprocError, toml_error
from ..core.progress import ProgressBar

STATE_FILE = "fleet-state.json"
ROBOT_KEYS = {"name", "data", "robot", "method", "args", "previous"}
DEFAULT_KEYS = {"robot", "method", "args"}


@dataclass
class RobotJob:
    name: str
    data: Path
    robot: Path | None = None
    method: str | None = None
    args: list[str] = field(default_factory=list)
    previous: Path | None = None

    def files(self) -> dict[str, Path]:
        """The robot's input files by role (``data``, ``robot``, ``previous``), as the client names them."""
        return {role: path for role, path in (("data", self.data), ("robot", self.robot), ("previous", self.previous))
                if path is not None}

    def train_argv(self, model: Path, files: dict[str, Path] | None = None) -> list[str]:
        """``postproc train`` for this robot, its inputs at ``files`` (by role; default its own paths)."""
        files = files or self.files()
        argv = ["train", str(files["data"]), "-o", str(model), "--name", self.name]
        if self.method:
            argv += ["--method", self.method]
        if "robot" in files:
            argv += ["--robot", str(files["robot"])]
        if "previous" in files:  # re-calibration: OLD's base, zero offsets and tool re-fitted, the rest kept
            argv += ["--update", str(files["previous"])]
        return argv + list(self.args)

    def digest(self) -> str:
        """sha256 over everything the robot's result depends on."""
        h = hashlib.sha256()
        for p in (self.data, self.robot, self.previous):
            h.update(_file_sha(p).encode() if p else b"-")
        h.update(json.dumps([self.method, self.args]).encode())
        return h.hexdigest()


def read_inputs(job: RobotJob) -> dict[str, tuple[str, bytes]]:
    """The robot's input files as the client reads them: role → (file name, bytes); what a task
    takes to its worker. PostprocError P500 naming the file when one cannot be read."""
    out = {}
    for role, path in job.files().items():
        try:
            out[role] = (path.name, path.read_bytes())
        except OSError as exc:
            raise PostprocError(f"cannot read the robot's {role} file: {exc.strerror or exc}", str(path),
                                code=P500) from None
    return out


@contextlib.contextmanager
def _scratch(inputs: dict[str, tuple[str, bytes]]):
    """A scratch folder on this worker with the robot's inputs written into it (each role in a
    folder of its own, under its file name): yields (folder, role → path); removed afterwards."""
    folder = Path(tempfile.mkdtemp(prefix="postproc-fleet-"))
    try:
        placed = {}
        for role, (name, data) in inputs.items():
            (folder / role).mkdir()
            placed[role] = folder / role / name
            placed[role].write_bytes(data)
        yield folder, placed
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def _client_paths(text: str, job: RobotJob, placed: dict[str, Path]) -> str:
    """A worker's message with its scratch paths replaced by the client's own."""
    for role, path in placed.items():
        text = text.replace(str(path), str(job.files()[role]))
    return text


def _file_sha(path: Path) -> str:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return "missing"


def _line_of(text: str, needle: str, nth: int = 0) -> int:
    count = 0
    for i, line in enumerate(text.splitlines(), 1):
        if line.strip().startswith(needle):
            if count == nth:
                return i
            count += 1
    return 0


def load_fleet(path: str | Path) -> list[RobotJob]:
    """The fleet file's robots as jobs; PostprocError P610 (located) on a bad file."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise PostprocError(f"cannot read fleet file: {exc.strerror or exc}", str(path), 0, 0, P610) from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise toml_error(exc, str(path), P610) from None
    base = path.resolve().parent  # (the client's: workers elsewhere get the files, not the paths)

    def bad(message: str, line: int) -> PostprocError:
        return PostprocError(message, str(path), line, 1 if line else 0, P610)

    unknown = set(data) - {"defaults", "robot"}
    if unknown:
        key = sorted(unknown)[0]
        raise bad(f"unknown key '{key}' (expected [defaults] and [[robot]] tables)", _line_of(text, key) or _line_of(text, f"[{key}"))
    defaults = data.get("defaults", {})
    if not isinstance(defaults, dict) or set(defaults) - DEFAULT_KEYS:
        raise bad(f"[defaults] takes only {', '.join(sorted(DEFAULT_KEYS))}", _line_of(text, "[defaults]"))
    robots = data.get("robot")
    if not isinstance(robots, list) or not robots:
        raise bad("no robots: add [[robot]] tables with name and data", 0)
    jobs, names = [], set()
    for i, entry in enumerate(robots):
        line = _line_of(text, "[[robot]]", i)
        merged = {**defaults, **entry}
        extra = set(entry) - ROBOT_KEYS
        if extra:
            raise bad(f"robot {i + 1}: unknown key '{sorted(extra)[0]}'", line)
        for key in ("name", "data"):
            if not isinstance(merged.get(key), str) or not merged[key]:
                raise bad(f"robot {i + 1}: '{key}' (a string) is required", line)
        if merged["name"] in names or "/" in merged["name"] or merged["name"] in (".", ".."):
            raise bad(f"robot name '{merged['name']}' is repeated or not a folder name", line)
        names.add(merged["name"])
        args = merged.get("args", [])
        if not isinstance(args, list) or not all(isinstance(a, str) for a in args):
            raise bad(f"robot {i + 1}: 'args' must be a list of strings", line)
        rel = lambda k: (base / merged[k]) if merged.get(k) else None  # noqa: E731
        jobs.append(RobotJob(merged["name"], rel("data"), rel("robot"), merged.get("method"), args, rel("previous")))
    return jobs


def _run_cli(argv: list[str]) -> tuple[int, str]:
    """``postproc ARGV`` → (exit code, stderr). In a fleet worker process (:func:`_own_process`) it
    runs right here: torch, pinocchio and matplotlib are imported once per worker, not once per
    robot, and the worker process is the robot's isolation (a crash kills it, its nanny starts a
    new one, the task fails alone). Anywhere else (a worker that runs several tasks at a time, no
    worker) it is a subprocess."""
    if not _own_process():
        env = {**os.environ, "OMP_NUM_THREADS": os.environ.get("OMP_NUM_THREADS", "1")}
        proc = subprocess.run([sys.executable, "-m", "postproc", *argv], capture_output=True, text=True, env=env)
        return proc.returncode, proc.stderr.strip()
    from ..cli import main

    _ThreadStreams.install()
    out, err = io.StringIO(), io.StringIO()
    _ThreadStreams.local.streams = (out, err)
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse: a bad argument in the fleet file's args
        code = exc.code if isinstance(exc.code, int) else 2
    finally:
        _ThreadStreams.local.streams = None
    return code, err.getvalue().strip()


def _own_process() -> bool:
    """True in a Dask worker process of its own (started by a nanny) that runs one task at a time."""
    try:
        from distributed import get_worker

        worker = get_worker()
    except (ImportError, ValueError):
        return False
    return bool(worker.nanny) and worker.state.nthreads == 1


@contextlib.contextmanager
def task_map(address: str | None = None):
    """A ``map(fn, *iterables)`` whose calls are Dask tasks (results in order): on the scheduler
    at ``address``; else, inside a Dask worker (a fleet's robot), on that worker's own cluster,
    the calling task seceded from its thread while it waits; else None (run in place)."""
    if address is None:
        try:
            from distributed import get_worker, worker_client

            get_worker()
        except (ImportError, ValueError):
            yield None
            return
        with worker_client() as client:
            yield partial(_client_map, client)
        return
    from dask.distributed import Client

    with Client(address) as client:
        yield partial(_client_map, client)


def _client_map(client, fn, *iterables):
    for future in client.map(fn, *iterables, pure=False):
        yield future.result()


class _ThreadStreams:
    """sys.stdout/sys.stderr of a worker process: each thread's own buffer while it runs a
    robot's command (a search's candidate tasks run beside a seceded robot), else the real stream."""

    local = threading.local()

    def __init__(self, index: int, real):
        self.index, self.real = index, real

    @classmethod
    def install(cls) -> None:
        if not isinstance(sys.stdout, cls):
            sys.stdout = cls(0, sys.stdout)
        if not isinstance(sys.stderr, cls):
            sys.stderr = cls(1, sys.stderr)

    def _target(self):
        streams = getattr(self.local, "streams", None)
        return streams[self.index] if streams else self.real

    def write(self, text: str) -> int:
        return self._target().write(text)

    def flush(self) -> None:
        self._target().flush()

    def isatty(self) -> bool:
        return False

    def __getattr__(self, name):  # encoding, fileno, …: the stream's the thread writes to
        return getattr(self._target(), name)


def _held_out(job: RobotJob, data: Path, path: Path) -> Path:
    """The held-out rows of the robot's data (at ``data``; the split `postproc train` draws) as a CSV."""
    from ..measurements.csv import read_measurements
    from ..model.training.data import default_val_fraction, split_indices

    m = read_measurements(data)
    frac, seed = None, 0
    for opt, conv in (("--val-fraction", float), ("--split-seed", int)):
        if opt in job.args and job.args.index(opt) + 1 < len(job.args):
            value = conv(job.args[job.args.index(opt) + 1])
            frac, seed = (value, seed) if opt == "--val-fraction" else (frac, value)
    _, val = split_indices(len(m), default_val_fraction(len(m), frac), seed)
    lines = data.read_text(encoding="utf-8").splitlines()
    head = next(i for i, line in enumerate(lines) if line.strip() and not line.startswith("#"))
    # the '# key: value' lines and the header as they are, then the held-out rows
    path.write_text("\n".join([*lines[:head + 1], *(lines[int(m.lines[i]) - 1] for i in val)]) + "\n",
                    encoding="utf-8")
    return path


def moved_parameters(card: dict, previous: dict | None) -> list[str]:
    """The parameters that moved since the previous model: those ``train --update`` found moved
    (its card's ``update`` entry), else the identified entries whose value differs from the
    previous card's."""
    if not previous:
        return []
    update = card.get("update")
    if isinstance(update, dict) and isinstance(update.get("parameters"), list):
        return [p["name"] for p in update["parameters"] if isinstance(p, dict) and p.get("moved")]
    new, old = card.get("identified") or {}, previous.get("identified") or {}
    return sorted(k for k in new if k in old and new[k] != old[k])


MODEL = "model.onnx"


def train_robot(job: RobotJob, inputs: dict[str, tuple[str, bytes]]) -> dict:
    """A robot's first step, the adapter to training: ``postproc train`` (``--update`` with a
    previous model) on its ``inputs`` (:func:`read_inputs`) in a scratch folder of this worker;
    never raises. Its result (``ok`` still False, or ``error`` set; ``files``: the model's bytes
    under its name in the robot's folder) goes to :func:`report_robot`."""
    result = {"name": job.name, "ok": False, "points": None, "warnings": [], "error": "", "files": {}}
    with _scratch(inputs) as (folder, placed):
        model = folder / MODEL
        code, err = _run_cli(job.train_argv(model, placed))
        _settle()
        err = _client_paths(err, job, placed)
        result["warnings"] = [ln for ln in err.splitlines() if "warning" in ln.lower() or ": W" in ln]
        if code != 0 or not model.is_file():
            result["error"] = (err.splitlines() or [f"postproc train exited {code}"])[-1]
        else:
            result["files"] = {MODEL: model.read_bytes()}
    return result


def report_robot(result: dict, job: RobotJob, inputs: dict[str, tuple[str, bytes]]) -> dict:
    """A robot's second step, on the model :func:`train_robot` made, in a scratch folder of this
    worker: the model card (``model-card.json``, the table's figures, the moved parameters) and
    the report on the held-out rows (``held-out.csv``, ``report/``: ``postproc report``'s library
    calls, the model loaded once for both), added to ``files``; never raises. Nothing is done for
    a robot whose training failed."""
    if result.get("error"):
        return result
    from ..acceptance.report import read_report_data, write_report
    from ..model.compensator import load_model

    with _scratch(inputs) as (folder, placed):
        out = folder / "out"
        out.mkdir()
        (out / MODEL).write_bytes(result["files"][MODEL])
        try:
            model = load_model(out / MODEL)
            prev = load_model(placed["previous"]).metadata if "previous" in placed else None
        except PostprocError as exc:
            return {**result, "error": _client_paths(str(exc), job, placed)}
        card = model.metadata
        (out / "model-card.json").write_text(json.dumps(card, indent=2, default=str), encoding="utf-8")
        acc = card.get("accuracy") or {}
        result = {**result, "points": (acc.get("n_train") or 0) + (acc.get("n_val") or 0),
                  "unc_mean": acc.get("val_uncompensated_mean_mm"), "unc_max": acc.get("val_uncompensated_max_mm"),
                  "comp_mean": acc.get("val_mean_mm"), "comp_max": acc.get("val_max_mm"),
                  "moved": moved_parameters(card, prev), "warnings": list(result["warnings"])}
        try:
            write_report(read_report_data(_held_out(job, placed["data"], out / "held-out.csv"), model), out / "report")
        except PostprocError as exc:
            result["warnings"].append(f"report: {_client_paths(str(exc), job, placed)}")
        except Exception as exc:  # noqa: BLE001 - as `postproc report` would end: the robot's model stands, its report not
            from ..core.extras import missing_extra

            hint = missing_extra(exc, "report") if isinstance(exc, ModuleNotFoundError) else None  # matplotlib
            result["warnings"].append(f"report: {hint or f'internal error: {type(exc).__name__}: {exc}'}")
        files = {p.relative_to(out).as_posix(): p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}
    _settle()
    result["files"] = files
    result["ok"] = True
    return result


def write_outputs(result: dict, outdir: str | Path) -> dict:
    """On the client: the files a robot's tasks made (``result["files"]``), written into
    ``OUTDIR/NAME/`` all or none (the atomic writer); the result without them, with ``model``
    (its path) and ``outputs`` (each file's sha256, what a rerun checks)."""
    from ..core.atomic import write_atomic

    files = result.get("files") or {}
    result = {k: v for k, v in result.items() if k != "files"}
    folder = Path(outdir) / result["name"]
    result["model"] = str(folder / MODEL)
    if not files:
        return result
    paths = [(folder / name, data) for name, data in files.items()]
    for path, _ in paths:
        path.parent.mkdir(parents=True, exist_ok=True)
    try:
        write_atomic(paths)
    except OSError as exc:
        return {**result, "ok": False, "error": f"{folder}: cannot write the outputs: {exc.strerror or exc}"}
    result["outputs"] = {name: hashlib.sha256(data).hexdigest() for name, data in files.items()}
    return result


def _outputs_there(result: dict, outdir: Path) -> bool:
    """The outputs recorded for a robot (``write_outputs``' sha256s) are in ``outdir`` as written."""
    recorded = result.get("outputs")
    return bool(recorded) and all(_file_sha(outdir / result["name"] / name) == sha for name, sha in recorded.items())


def _settle() -> None:
    """In a worker process of its own, after its first robot: what is alive then (the imported
    libraries, their caches) is moved out of the garbage collector's sight (``gc.freeze``), so
    that the full collections later robots trigger scan only their own objects (measured in one
    warm process, 8 robots: ~0.3 s per full collection, one every second robot, before; the
    collector's time per robot 0.01-0.1 s after)."""
    if not _own_process() or getattr(_settle, "done", False):
        return
    import gc

    gc.collect()
    gc.freeze()
    _settle.done = True


def robot(job: RobotJob, outdir: str | Path) -> dict:
    """One robot's whole job in this process: :func:`train_robot` then :func:`report_robot`,
    the outputs written into ``outdir``."""
    try:
        inputs = read_inputs(job)
    except PostprocError as exc:
        return {"name": job.name, "ok": False, "error": str(exc), "warnings": []}
    return write_outputs(report_robot(train_robot(job, inputs), job, inputs), outdir)


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
    scheduler = {"cls": Scheduler, "options": {"host": "127.0.0.1", "dashboard": False}}
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
            trained = client.map(train_robot, todo, inputs, pure=False, resources=kinds[0])
            futures = [client.submit(report_robot, t, job, i, pure=False, resources=kinds[1])
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


COLUMNS = ["robot", "points", "uncomp. mean mm", "uncomp. max mm", "comp. mean mm", "comp. max mm",
           "moved parameters", "warnings", "failure"]


def _row(r: dict) -> list[str]:
    f = lambda v: "" if v is None else f"{v:.3f}"  # noqa: E731
    return [r["name"] + (" (unchanged)" if r.get("skipped") else ""), "" if r.get("points") is None else str(r["points"]),
            f(r.get("unc_mean")), f(r.get("unc_max")), f(r.get("comp_mean")), f(r.get("comp_max")),
            ", ".join(r.get("moved") or []), "; ".join(r.get("warnings") or []), r.get("error") or ""]


def fleet_table(results: list[dict], fmt: str = "md") -> str:
    """The fleet table as Markdown (``md``), ``csv`` or ``html``."""
    rows = [_row(r) for r in results]
    if fmt == "csv":
        buf = io.StringIO()
        csv.writer(buf, lineterminator="\n").writerows([COLUMNS, *rows])
        return buf.getvalue()
    if fmt == "html":
        cell = lambda tag, v: f"<{tag}>{html.escape(v)}</{tag}>"  # noqa: E731
        body = "\n".join("<tr>" + "".join(cell("td", v) for v in row) + "</tr>" for row in rows)
        return f"<table>\n<tr>{''.join(cell('th', c) for c in COLUMNS)}</tr>\n{body}\n</table>\n"
    esc = lambda v: v.replace("|", "\\|").replace("\n", " ")  # noqa: E731
    lines = ["| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
    lines += ["| " + " | ".join(esc(v) for v in row) + " |" for row in rows]
    return "\n".join(lines) + "\n"

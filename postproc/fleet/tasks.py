"""A robot's tasks: :func:`train_robot` (the training, a library call: ``model.training.fit``
with the robot's settings) then :func:`report_robot` (the model card, the table's figures,
``postproc report``'s library on the held-out rows), each in a scratch folder of its worker
with the robot's input files (the client sends their bytes; the tasks return the files they
made, which :func:`write_outputs` writes on the client); :func:`robot` runs both here.

Where the training runs: a training worker of the local cluster is a process of its own that
runs one task at a time (:func:`_own_process`): the training runs right there — torch,
pinocchio and the rest imported once per worker, not once per robot — and the worker process
is the robot's isolation (a crash kills it, its nanny starts a new one, the task fails alone).
Anywhere else (a worker that runs several tasks at a time, no worker at all) the same library
call runs in a child process of its own (spawned, one torch thread), for the same isolation.
"""
from __future__ import annotations

import contextlib
import hashlib
import json
import shutil
import tempfile
from functools import partial
from pathlib import Path

from ..core.diagnostics import PostprocError
from .jobs import RobotJob, _file_sha, read_inputs

__all__ = ["train_robot", "report_robot", "robot", "write_outputs", "moved_parameters", "task_map", "MODEL"]

MODEL = "model.onnx"


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


def _held_out(job: RobotJob, data: Path, path: Path) -> Path:
    """The held-out rows of the robot's data (at ``data``; the split `postproc train` draws) as a CSV."""
    from ..measurements.csv import read_measurements
    from ..model.training.data import default_val_fraction, split_indices

    m = read_measurements(data)
    t = job.settings().training
    _, val = split_indices(len(m), default_val_fraction(len(m), t.val_fraction), t.split_seed)
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


def train_robot(job: RobotJob, inputs: dict[str, tuple[str, bytes]]) -> dict:
    """A robot's first step: its training (``model.training.fit`` with ``job.settings``; a
    re-calibration with a previous model) on its ``inputs`` (``jobs.read_inputs``) in a scratch
    folder of this worker; never raises. Its result (``ok`` still False, or ``error`` set;
    ``files``: the model's bytes under its name in the robot's folder) goes to :func:`report_robot`."""
    result = {"name": job.name, "ok": False, "points": None, "warnings": [], "error": "", "files": {}}
    with _scratch(inputs) as (folder, placed):
        model = folder / MODEL
        settings = job.settings(placed)
        notes, error = (_train if _own_process() else _train_apart)(placed["data"], model, settings)
        _settle()
        result["warnings"] = [_client_paths(n, job, placed) for n in notes if "warning" in n.lower() or ": W" in n]
        if error or not model.is_file():
            result["error"] = _client_paths(error or "the training wrote no model", job, placed)
        else:
            result["files"] = {MODEL: model.read_bytes()}
    return result


def _train(data: Path, model: Path, settings) -> tuple[list[str], str]:
    """Fit and export here: (the fit's notes, the error as ``postproc train`` says it; "": none)."""
    from ..core.extras import missing_extra
    from ..model.training.fitting import fit

    try:
        trained = fit(data, settings, search_engine=partial(task_map, settings.training.scheduler))
        trained.export(model)
    except PostprocError as exc:
        return [], str(exc)
    except ModuleNotFoundError as exc:
        return [], missing_extra(exc, "train") or f"internal error: {type(exc).__name__}: {exc}"
    except Exception as exc:  # noqa: BLE001 - as `postproc train` would end: this robot fails, the others go on
        return [], f"internal error: {type(exc).__name__}: {exc}"
    return list(trained.notes), ""


def _train_apart(data: Path, model: Path, settings) -> tuple[list[str], str]:
    """:func:`_train` in a child process of its own (spawned; one torch thread unless
    OMP_NUM_THREADS says otherwise): a crash there fails this robot, not its caller."""
    import multiprocessing
    import os
    from concurrent.futures import ProcessPoolExecutor
    from concurrent.futures.process import BrokenProcessPool

    os.environ.setdefault("OMP_NUM_THREADS", "1")  # (the child's torch threads)
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        try:
            return pool.submit(_train, data, model, settings).result()
        except BrokenProcessPool:
            return [], "the training process died (killed, out of memory, or a crash in torch)"


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

"""ONNX Runtime sessions that start fast: each model's graph is optimised once and kept.

Creating a session spends most of its time optimising the graph (constant folding, fusions);
the result depends only on the model's bytes, the onnxruntime version and the session options.
On first use ORT writes the optimised graph (``SessionOptions.optimized_model_filepath``) into
the user cache dir under a name keyed by all three; later sessions load that file with graph
optimisation off, which gives the same outputs bit for bit (tests/test_session.py). A cache
file is used only with the sha256 of its own bytes recorded beside it (written after it, both
by rename): a partial, foreign or changed file is never loaded, it is made again.

The cache dir: ``$POSTPROC_CACHE_DIR`` (empty: no cache), else ``$XDG_CACHE_HOME/postproc``,
else ``~/.cache/postproc``. A cache that cannot be written costs only the speed.

What is left of a session's start (``benchmarks/cam_latency.py --sessions``: ~35 ms CPU for the
shipped model's 1,724 optimised nodes, against ~150 ms optimising at each start) grows with the
graph's nodes; the same graph in ORT format starts no faster, nor does a cached graph of a
lower optimisation level, and with one thread there is no pool to spin (allow_spinning: no
change). ORT holds the GIL while it builds a session: a thread would not overlap it with reading.

A session of the graph cut to some of its outputs (``inference_session(data, outputs)``):
onnxruntime runs every node of a graph whichever outputs a run asks for, so the fixed-point
iterations, which need ``error`` (and ``ik_joints``) only, paid for the ``error_std`` Jacobian
too. The cut keeps the nodes those outputs need (the ``onnx`` package: ``_cut``) and is cached
like the whole graph, keyed by the model's bytes and the outputs; the numbers are the whole
graph's bit for bit (tests/test_session.py). It takes every optional input (contract 3: ONNX
optional type) as a plain tensor, which ``Compensator`` always feeds: the ``If`` choosing the
fed value or the default is an ``Identity`` there (``_fed``; the If cost ~5 % of a run). Every session of the process draws on one CPU arena
registered with onnxruntime's environment (``session.use_env_allocators``): with one arena per
session the cut graphs added ~85 MB to a streamed 1M-target program's peak (202 → 287 MB; one
arena: 241 MB), for the same speed.
"""
from __future__ import annotations

import functools
import hashlib
import os
import tempfile
from pathlib import Path

__all__ = ["cache_dir", "inference_session"]

_THREADS = 1  # small graphs: thread start-up costs more than it saves on a 2-core machine


def cache_dir() -> Path | None:
    """Where optimised graphs are kept (None: no cache)."""
    env = os.environ.get("POSTPROC_CACHE_DIR")
    if env is not None:
        return Path(env) if env else None
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "postproc"


@functools.cache
def _shared_arena(ort) -> bool:
    """Register one CPU arena allocator for every session of this process (a model's whole and
    cut graphs run one after the other: one arena, not one per session), once; False where this
    onnxruntime cannot."""
    try:
        info = ort.OrtMemoryInfo("Cpu", ort.OrtAllocatorType.ORT_ARENA_ALLOCATOR, 0, ort.OrtMemType.DEFAULT)
        ort.create_and_register_allocator(info, ort.OrtArenaCfg(0, -1, -1, -1))
        return True
    except Exception:  # noqa: BLE001 - an older or other build: each session keeps its own arena
        return False


def _options(ort, optimise: bool):
    options = ort.SessionOptions()
    if _shared_arena(ort):
        options.add_session_config_entry("session.use_env_allocators", "1")
    options.log_severity_level = 3
    options.intra_op_num_threads = _THREADS
    options.inter_op_num_threads = _THREADS
    if not optimise:
        options.graph_optimization_level = ort.GraphOptimizationLevel.ORT_DISABLE_ALL
    return options


def _key(ort, data: bytes, outputs: tuple[str, ...] | None = None) -> str:
    h = hashlib.sha256(data)
    h.update(f"\0onnxruntime {ort.__version__}\0threads {_THREADS}\0level all\0cpu".encode())
    if outputs is not None:
        h.update("\0outputs".join(["", *outputs]).encode())
        h.update(b"\0fed")  # (the cut graph takes its optional inputs as tensors: _fed)
    return h.hexdigest()


def inference_session(data: bytes, outputs: tuple[str, ...] | None = None):
    """An ``onnxruntime.InferenceSession`` (CPU) of the model ``data``; raises what ORT raises
    for a model it cannot load. With ``outputs``: of the graph cut to what they need, or None
    where it cannot be cut here (no ``onnx`` package)."""
    import onnxruntime as ort

    folder = cache_dir()
    if folder is not None:
        key = _key(ort, data, outputs)
        cached, digest = folder / f"{key}.onnx", folder / f"{key}.sha256"
        try:
            optimised = cached.read_bytes()
            if hashlib.sha256(optimised).hexdigest() == digest.read_text().strip():
                return ort.InferenceSession(optimised, _options(ort, False), providers=["CPUExecutionProvider"])
        except Exception:  # noqa: BLE001 - not there yet, unreadable, or a cache ORT refuses (its own types): made again below
            pass
    if outputs is not None:
        data = _cut(data, outputs)
        if data is None:
            return None
    if folder is None:
        return ort.InferenceSession(data, _options(ort, True), providers=["CPUExecutionProvider"])
    options = _options(ort, True)
    tmp = None
    try:
        folder.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{key}.", suffix=".onnx", dir=folder)
        os.close(fd)
        options.optimized_model_filepath = tmp
    except OSError:
        tmp = None
    try:
        session = ort.InferenceSession(data, options, providers=["CPUExecutionProvider"])
        if tmp is not None:
            _keep(Path(tmp), cached, digest)
    finally:
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)
    return session


def _keep(written: Path, cached: Path, digest: Path) -> None:
    """The optimised graph ORT wrote into the cache, its sha256 beside it (each by rename)."""
    try:
        text = hashlib.sha256(written.read_bytes()).hexdigest()
        os.replace(written, cached)
        fd, tmp = tempfile.mkstemp(prefix=f".{digest.stem}.", suffix=".sha256", dir=digest.parent)
        with os.fdopen(fd, "w") as f:
            f.write(text + "\n")
        os.replace(tmp, digest)
    except OSError:
        pass


def _cut(data: bytes, outputs: tuple[str, ...]) -> bytes | None:
    """The model ``data`` with only the graph outputs ``outputs`` and the nodes and initializers
    they need (every input kept, each optional one as a plain tensor: ``_fed``); None without
    the ``onnx`` package."""
    try:
        import onnx
    except ImportError:
        return None
    model = onnx.load_from_string(data)
    graph = model.graph
    _fed(onnx, graph)
    needed, keep = set(outputs), []
    for node in reversed(graph.node):
        if any(name in needed for name in node.output):
            keep.append(node)
            needed.update(_reads(onnx, node))
    kept_outputs = [o for o in graph.output if o.name in outputs]
    if len(kept_outputs) != len(set(outputs)):
        return None
    inputs = {i.name for i in graph.input}  # (an optional input's default kept with it: contract.py)
    initializers = [i for i in graph.initializer if i.name in needed or i.name in inputs]
    del graph.node[:], graph.output[:], graph.initializer[:]
    graph.node.extend(reversed(keep))
    graph.output.extend(kept_outputs)
    graph.initializer.extend(initializers)
    return model.SerializeToString()


def _fed(onnx, graph) -> None:
    """``graph`` (changed in place) taking each of its optional inputs (ONNX optional type,
    contract 3) as a plain tensor: ``Compensator`` feeds every input the graph takes, so the
    ``If`` that chooses between the fed value and the default (``contract.with_defaults``)
    becomes an ``Identity`` of the input, its ``then`` branch (~5 % of a run of the shipped
    model's graph; the same numbers). A graph that reads an optional input otherwise is left
    as it is."""
    optional = {value.name: value for value in graph.input if value.type.HasField("optional_type")}
    if not optional:
        return
    has = {node.output[0]: node.input[0] for node in graph.node
           if node.op_type == "OptionalHasElement" and list(node.input) == [node.input[0]] and node.input[0] in optional}

    def chooses(node) -> str | None:  # the input an If of contract 3 chooses a value for
        if node.op_type != "If" or node.input[0] not in has:
            return None
        then = next((a.g for a in node.attribute if a.name == "then_branch"), None)
        name = has[node.input[0]]
        if (then is None or len(then.node) != 1 or then.node[0].op_type != "OptionalGetElement"
                or list(then.node[0].input) != [name] or [o.name for o in then.output] != list(then.node[0].output)):
            return None
        return name

    nodes = []
    for node in graph.node:
        if node.op_type == "OptionalHasElement" and node.output[0] in has:
            continue
        name = chooses(node)
        nodes.append(node if name is None else onnx.helper.make_node("Identity", [name], list(node.output), name=node.name))
    if any((name in optional and node.op_type != "Identity") or name in has
           for node in nodes for name in _reads(onnx, node)):
        return  # (an optional input read otherwise: the graph as it is)
    del graph.node[:]
    graph.node.extend(nodes)
    for value in optional.values():
        tensor = onnx.TypeProto()
        tensor.CopyFrom(value.type.optional_type.elem_type)
        value.type.CopyFrom(tensor)


def _reads(onnx, node) -> set[str]:
    """The names ``node`` reads: its inputs and, for a node with subgraphs (contract 3's ``If``
    of an optional input), every name its subgraphs' nodes read (outer ones among them)."""
    names = {name for name in node.input if name}
    for attr in node.attribute:
        graphs = [attr.g] if attr.type == onnx.AttributeProto.GRAPH else list(attr.graphs)
        for sub in graphs:
            for inner in sub.node:
                names |= _reads(onnx, inner)
    return names

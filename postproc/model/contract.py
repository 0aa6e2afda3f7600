"""The contract's graph side: every optional input optional in the ONNX sense, and the versions.

The contract's text is ``compensator.py``'s module docstring; this module holds what a graph must
carry so that a caller with onnxruntime alone can run it feeding only ``pose`` (issue 27), finds
every input it may feed with the standard API and opens it without a warning (issue 34):

* each optional input (``previous_pose``, ``joints``, ``tool``, ``approach``,
  ``previous_joints``, ``load``) a graph takes is a graph input of ONNX optional type,
  ``optional(tensor(float))`` [N, 6] (``load``: [N, 4], ``INPUT_WIDTH``; IR 8, opset ≥ 15): onnxruntime lists it in
  ``get_inputs()`` (C API: ``SessionGetInputTypeInfo`` says ``ONNX_TYPE_OPTIONAL``) and takes a
  plain float tensor for it or nothing. The graph reads it through
  ``If(OptionalHasElement(x))``: the fed tensor, else ``x__default`` (an initializer, float32
  [1, 6] NaN, [1, 4] for ``load``), broadcast to the rows of ``pose`` (``Expand`` to ``Shape(pose)``) before the graph
  reads it, so an omitted input is a NaN row per target = "unknown", the contract's meaning of
  NaN for each;
* ``previous_pose``: a row with a NaN is the pose itself (the contract's "nothing is known
  before it", what ``Compensator`` feeds for the first target), chosen row by row in the graph;
* ``postproc_contract`` "3" in ``metadata_props``. Contract 1 (written before issue 27) takes
  the same inputs but requires all of them; contract 2 (issue 27 to 34) gives each optional
  input its default as an initializer of the input's name (ONNX: a graph input with an
  initializer is optional), which onnxruntime lists only in ``get_overridable_initializers()``
  and warns about at every session ("Initializer … appears in graph inputs and will not be
  treated as constant value/weight"): a caller reading ``get_inputs()`` never saw ``joints``.
  ``Compensator`` feeds every input either way and reads all three. ``upgrade`` turns a
  contract-1 or -2 file into a contract-3 one (the same nodes and numbers for a caller feeding
  every input; the graph's own nodes untouched); a file of a newer contract than
  ``CONTRACT_VERSIONS`` is refused by ``compensator.load_model`` naming its version.

Why this form (onnxruntime 1.32, measured): a graph input of optional type is the one form in
which an input may be omitted from the feed and is still in ``get_inputs()``; an initializer
of the input's name is what the warning is about (graph.cc warns for every such input, at the
default log level), and a plain tensor input is required. The ``If`` costs ~5 % of a run of
the shipped model's graph for a caller of the file; ``Compensator``'s large runs use a graph
without it (``session._fed``: it feeds every input).

``with_defaults`` is the one function every exported graph goes through: ``training/export.py``
(hybrid, kinematic, dnn-joints and the pose-only networks), ``postproc.testing.models``, and
``postproc model upgrade`` for older files. Needs the ``onnx`` package (not ``compensate``).
"""
from __future__ import annotations

import json

import numpy as np

from ..settings import MAX_ITERATIONS

__all__ = [
    "OPTIONAL_INPUTS", "DEFAULT_MEANING", "with_defaults", "upgrade", "optional_inputs", "CONTRACT_VERSION",
    "CONTRACT_VERSIONS", "INPUT_POSE", "INPUT_PREVIOUS", "INPUT_JOINTS", "INPUT_TOOL", "INPUT_APPROACH",
    "INPUT_PREVIOUS_JOINTS", "INPUT_LOAD", "INPUT_WIDTH", "OUTPUT_ERROR", "OUTPUT_JOINTS", "LEGACY_OUTPUT_JOINTS", "OUTPUT_ROTATION", "OUTPUT_STD",
    "contract_version", "contract_metadata",
]

CONTRACT_VERSION = "3"
# the contract versions this postproc reads: 1 (every input a graph takes required), 2 (the
# optional inputs' defaults initializers of their names), 3 (the optional inputs of ONNX optional
# type: module text); a newer file is refused naming its version
CONTRACT_VERSIONS = ("1", "2", "3")
INPUT_POSE = "pose"
INPUT_PREVIOUS = "previous_pose"
OUTPUT_ERROR = "error"
INPUT_JOINTS = "joints"
INPUT_TOOL = "tool"
INPUT_PREVIOUS_JOINTS = "previous_joints"
OUTPUT_JOINTS = "ik_joints"
LEGACY_OUTPUT_JOINTS = "joints"  # (the output's name before the ``joints`` input existed)
OUTPUT_ROTATION = "rotation_error"
OUTPUT_STD = "error_std"
INPUT_APPROACH = "approach"
INPUT_LOAD = "load"  # (mass kg, centre of mass cx, cy, cz mm in the flange frame) [N, 4]
# the columns of each input ([N, 6] unless here)
INPUT_WIDTH = {INPUT_LOAD: 4}

# the optional inputs and what an omitted one means (the contract's NaN rows)
DEFAULT_MEANING = {
    INPUT_PREVIOUS: "the pose itself (nothing known before it)",
    INPUT_JOINTS: "NaN rows: the branch the model identified",
    INPUT_APPROACH: "NaN rows: the approach signs from previous_pose",
    INPUT_TOOL: "NaN rows: the model's own tool (card tool.frame)",
    INPUT_PREVIOUS_JOINTS: "NaN rows: unknown (previous_pose solved on the target's branch)",
    INPUT_LOAD: "NaN rows: the load the model was measured with (its reference, card loads.reference)",
}
OPTIONAL_INPUTS = tuple(DEFAULT_MEANING)
_SUFFIX = "__given"  # the name the graph reads an optional input by once broadcast
_VALUE = "__value"  # an optional input's tensor: the caller's where fed, else the default
_DEFAULT = "__default"  # its default, float32 [1, width] (NaN)
MIN_OPSET = 15  # ONNX's optional type and its operators (OptionalHasElement, OptionalGetElement)


def _is_optional(value_info) -> bool:
    return value_info.type.HasField("optional_type")


def optional_inputs(model) -> list[str]:
    """The contract inputs of ``model`` (onnx.ModelProto) that a caller may already omit: of
    ONNX optional type (contract 3) or with a default initializer of the same name (contract 2)."""
    inits = {i.name for i in model.graph.initializer}
    return [i.name for i in model.graph.input
            if i.name in OPTIONAL_INPUTS and (_is_optional(i) or i.name in inits)]


def _rename_reads(graph, old: str, new: str, skip=()) -> None:
    """Every node of ``graph`` (and of its subgraphs) but ``skip`` that reads ``old`` reads ``new``."""
    from onnx import AttributeProto

    for node in graph.node:
        if any(node is s for s in skip):
            continue
        for k, value in enumerate(node.input):
            if value == old:
                node.input[k] = new
        for attr in node.attribute:
            if attr.type == AttributeProto.GRAPH:
                _rename_reads(attr.g, old, new)
            elif attr.type == AttributeProto.GRAPHS:
                for sub in attr.graphs:
                    _rename_reads(sub, old, new)


def with_defaults(model):
    """``model`` (onnx.ModelProto, changed in place and returned) with each optional input it
    takes of ONNX optional type and its default in the graph (module text), ``postproc_contract``
    set to this contract. A graph of contract 1 (the inputs required) or 2 (defaults as
    initializers of the inputs' names) is brought to it with its nodes and numbers. Idempotent."""
    from onnx import TensorProto, helper, numpy_helper

    graph = model.graph
    names = {i.name for i in graph.input}
    if INPUT_POSE not in names:
        raise ValueError(f"the graph has no input '{INPUT_POSE}'")
    opset = next((o for o in model.opset_import if o.domain in ("", "ai.onnx")), None)
    if opset is None or opset.version < MIN_OPSET:
        raise ValueError(f"the graph's opset {opset.version if opset else '(none)'} has no optional inputs "
                         f"(ONNX opset {MIN_OPSET} or later)")
    model.ir_version = max(model.ir_version, 8)  # (optional types: IR 8 on)
    inits = {i.name: i for i in graph.initializer}
    todo = [i for i in graph.input if i.name in OPTIONAL_INPUTS and not _is_optional(i)]
    nodes = []
    shape = f"{INPUT_POSE}{_SUFFIX}_shape"
    if todo and not any(shape in n.output for n in graph.node):
        nodes.append(helper.make_node("Shape", [INPUT_POSE], [shape], name="postproc_default_shape"))
    for value_info in todo:
        name = value_info.name
        for out in graph.output:  # (an input passed straight through: not in the contract's graphs)
            if out.name == name:
                raise ValueError(f"input '{name}' is also a graph output")
        default, chosen = name + _DEFAULT, name + _VALUE
        if name in inits:  # contract 2: its default is the initializer of its name, broadcast already
            old = inits[name]
            graph.initializer.remove(old)
            value = numpy_helper.to_array(old)
        else:  # contract 1: broadcast to pose's rows (previous_pose: a row with a NaN is the pose)
            value = np.full((1, INPUT_WIDTH.get(name, 6)), np.nan, np.float32)
            given = name + _SUFFIX
            _rename_reads(graph, name, given)
            if name == INPUT_PREVIOUS:
                wide, ones, total, unknown = (f"{name}{_SUFFIX}_{s}" for s in ("wide", "ones", "sum", "unknown"))
                graph.initializer.append(numpy_helper.from_array(np.ones((6, 1), np.float32), ones))
                nodes += [helper.make_node("Expand", [chosen, shape], [wide], name=f"postproc_default_{name}"),
                          helper.make_node("MatMul", [wide, ones], [total]),  # NaN where the row has one
                          helper.make_node("IsNaN", [total], [unknown]),
                          helper.make_node("Where", [unknown, INPUT_POSE, wide], [given])]
            else:
                rows = shape
                if INPUT_WIDTH.get(name, 6) != 6:  # (pose's rows, this input's columns)
                    rows = f"{name}{_SUFFIX}_shape"
                    graph.initializer.append(numpy_helper.from_array(np.array([INPUT_WIDTH[name]], np.int64),
                                                                     f"{name}{_SUFFIX}_width"))
                    nodes += [helper.make_node("Slice", [shape, f"{name}{_SUFFIX}_zero", f"{name}{_SUFFIX}_one"],
                                               [f"{name}{_SUFFIX}_rows"]),
                              helper.make_node("Concat", [f"{name}{_SUFFIX}_rows", f"{name}{_SUFFIX}_width"], [rows],
                                               axis=0)]
                    graph.initializer.extend([numpy_helper.from_array(np.array([0], np.int64), f"{name}{_SUFFIX}_zero"),
                                              numpy_helper.from_array(np.array([1], np.int64), f"{name}{_SUFFIX}_one")])
                nodes.append(helper.make_node("Expand", [chosen, rows], [given], name=f"postproc_default_{name}"))
        graph.initializer.append(numpy_helper.from_array(np.asarray(value, np.float32), default))
        # the value the graph reads: the caller's tensor where fed, else the default
        fed, unfed, has = (f"{name}{s}" for s in ("__fed", "__unfed", "__has"))
        out_type = [helper.make_tensor_value_info(v, TensorProto.FLOAT, [None, INPUT_WIDTH.get(name, 6)])
                    for v in (fed, unfed)]
        choose = [helper.make_node("OptionalHasElement", [name], [has], name=f"postproc_has_{name}"),
                  helper.make_node("If", [has], [chosen], name=f"postproc_default_or_{name}",
                                   then_branch=helper.make_graph(
                                       [helper.make_node("OptionalGetElement", [name], [fed])],
                                       f"{name}_fed", [], [out_type[0]]),
                                   else_branch=helper.make_graph(
                                       [helper.make_node("Identity", [default], [unfed])],
                                       f"{name}_omitted", [], [out_type[1]]))]
        _rename_reads(graph, name, chosen)
        nodes[:0] = choose
        tensor = value_info.type.tensor_type
        optional = helper.make_optional_type_proto(helper.make_tensor_type_proto(tensor.elem_type, None))
        optional.optional_type.elem_type.tensor_type.shape.CopyFrom(tensor.shape)
        value_info.type.CopyFrom(optional)
    if nodes:
        rest = list(graph.node)
        del graph.node[:]
        graph.node.extend(nodes + rest)
    _set_meta(model, "postproc_contract", CONTRACT_VERSION)
    return model


def _set_meta(model, key: str, value: str) -> None:
    for prop in model.metadata_props:
        if prop.key == key:
            prop.value = value
            return
    model.metadata_props.add(key=key, value=value)


def upgrade(data: bytes) -> bytes:
    """An older compensator's bytes (contract 1: every input required; 2: the defaults
    initializers of the inputs' names) as this contract's: the same graph with
    ``with_defaults`` (the same numbers for a caller feeding every input)."""
    import onnx

    model = onnx.load_from_string(data)
    with_defaults(model)
    onnx.checker.check_model(model)
    return model.SerializeToString()




def _json_or_text(value: str):
    try:
        return json.loads(value)
    except (ValueError, TypeError):
        return value


def _interface_problems(inputs: dict, outputs: dict, joints_output: str) -> list[str]:
    """What makes a session's inputs and outputs (name → node) not the contract's: names,
    shapes ([N, k] with a free batch size), float32."""
    problems = []
    if INPUT_POSE not in inputs:
        problems.append(f"no input '{INPUT_POSE}' (has {sorted(inputs)})")
    extra = set(inputs) - {INPUT_POSE, INPUT_PREVIOUS, INPUT_JOINTS, INPUT_TOOL, INPUT_APPROACH, INPUT_PREVIOUS_JOINTS,
                           INPUT_LOAD}
    if extra:
        problems.append(f"unexpected inputs {sorted(extra)}")
    if OUTPUT_ERROR not in outputs:
        problems.append(f"no output '{OUTPUT_ERROR}' (has {sorted(outputs)})")
    if INPUT_APPROACH in inputs and INPUT_PREVIOUS not in inputs:
        problems.append(f"input '{INPUT_APPROACH}' without '{INPUT_PREVIOUS}'")
    for name, expected in ((INPUT_POSE, 6), (INPUT_PREVIOUS, 6), (INPUT_JOINTS, 6), (INPUT_TOOL, 6),
                           (INPUT_APPROACH, 6), (INPUT_PREVIOUS_JOINTS, 6), (INPUT_LOAD, 4)):
        if name in inputs and (len(inputs[name].shape) != 2 or inputs[name].shape[1] not in (expected, None, str(expected))
                               or isinstance(inputs[name].shape[0], int)):
            problems.append(f"input '{name}' has shape {inputs[name].shape}, expected [N, {expected}]")
    if OUTPUT_ERROR in outputs and (len(outputs[OUTPUT_ERROR].shape) != 2 or outputs[OUTPUT_ERROR].shape[1] not in (3, None)):
        problems.append(f"output '{OUTPUT_ERROR}' has shape {outputs[OUTPUT_ERROR].shape}, expected [N, 3]")
    if joints_output in outputs and (len(outputs[joints_output].shape) != 2
                                     or outputs[joints_output].shape[1] not in (6, None)):
        problems.append(f"output '{joints_output}' has shape {outputs[joints_output].shape}, expected [N, 6]")
    if OUTPUT_ROTATION in outputs and (len(outputs[OUTPUT_ROTATION].shape) != 2
                                       or outputs[OUTPUT_ROTATION].shape[1] not in (3, None)):
        problems.append(f"output '{OUTPUT_ROTATION}' has shape {outputs[OUTPUT_ROTATION].shape}, expected [N, 3]")
    if OUTPUT_STD in outputs and (len(outputs[OUTPUT_STD].shape) != 2 or outputs[OUTPUT_STD].shape[1] not in (1, None)):
        problems.append(f"output '{OUTPUT_STD}' has shape {outputs[OUTPUT_STD].shape}, expected [N, 1]")
    for node in (*inputs.values(), *outputs.values()):
        if node.name in (INPUT_POSE, INPUT_PREVIOUS, INPUT_JOINTS, INPUT_TOOL, INPUT_APPROACH, INPUT_PREVIOUS_JOINTS,
                         INPUT_LOAD, OUTPUT_ERROR, joints_output, OUTPUT_ROTATION, OUTPUT_STD) and node.type != "tensor(float)":
            if node.type == "optional(tensor(float))" and node.name in OPTIONAL_INPUTS and node in inputs.values():
                continue  # (an optional input, contract 3)
            problems.append(f"'{node.name}' is {node.type}, expected tensor(float) (float32)")
    return problems


def contract_version(meta: dict) -> str:
    """The contract version of a model card (``postproc_contract``; a file without one, made by
    other tools, is read as version 1)."""
    value = meta.get("postproc_contract", "1")
    return str(value) if not isinstance(value, float) else f"{value:g}"


def _version_problem(meta: dict) -> str | None:
    version = contract_version(meta)
    if version in CONTRACT_VERSIONS:
        return None
    newer = version.isdigit() and int(version) > int(CONTRACT_VERSIONS[-1])
    return (f"model contract version {version!r} (metadata postproc_contract) is "
            + ("newer than this postproc reads" if newer else "not a contract version")
            + f" (it reads {', '.join(CONTRACT_VERSIONS)}){': update postproc' if newer else ''}")


def _numbers(value, n: int) -> bool:
    """``value`` is a list of ``n`` finite numbers."""
    try:
        return isinstance(value, list) and len(value) == n and bool(np.isfinite(np.asarray(value, float)).all())
    except (TypeError, ValueError):
        return False


def _metadata_problem(meta: dict) -> str | None:
    """What is wrong with the parts of a model card that ``compensate`` relies on, if anything."""
    env = meta.get("envelope")
    if env is not None:
        if not (isinstance(env, dict) and _numbers(env.get("box"), 6) and _numbers(env.get("attitude"), 3)
                and _numbers([env.get("range")], 1) and env["range"] >= 0):
            return "'envelope' needs box [x0,x1,y0,y1,z0,z1], attitude [A,B,C] and range ≥ 0"
        if any(lo > hi for lo, hi in zip(env["box"][0::2], env["box"][1::2])):
            return f"'envelope' box {env['box']} has a lower bound above its upper bound"
        joints = env.get("joints")
        if joints is not None and not (isinstance(joints, list) and len(joints) == 6
                                       and all(_numbers(r, 2) and r[0] <= r[1] for r in joints)):
            return "'envelope' joints must be six [lo, hi] ranges (deg)"
    reach = meta.get("reach")
    if reach is not None and not (isinstance(reach, dict) and _numbers(reach.get("center"), 3)
                                  and _numbers([reach.get("radius_max"), reach.get("radius_min", 0.0)], 2)
                                  and reach["radius_max"] > 0):
        return "'reach' needs center [x,y,z], radius_max > 0 and optionally radius_min"
    if meta.get("controller_base") is not None and not _numbers(meta["controller_base"], 6):
        return "'controller_base' must be [X,Y,Z,A,B,C]"
    tool = meta.get("tool")
    if isinstance(tool, dict) and tool.get("frame") is not None and not _numbers(tool["frame"], 6):
        return "'tool' frame must be [X,Y,Z,A,B,C]"
    card = meta.get("uncertainty")
    if card is not None and not (isinstance(card, dict) and _numbers([card.get("max_std_mm")], 1)
                                 and card["max_std_mm"] > 0):
        return "'uncertainty' needs max_std_mm > 0"
    iterations = meta.get("iterations")
    if iterations is not None and not (isinstance(iterations, int) and 1 <= iterations <= MAX_ITERATIONS):
        return f"'iterations' must be a whole number from 1 to {MAX_ITERATIONS}, not {iterations!r}"
    return None


def contract_metadata(**fields) -> dict[str, str]:
    """metadata_props for a compensator: structured values JSON-encoded, contract stamped."""
    out = {"postproc_contract": CONTRACT_VERSION}
    for key, value in fields.items():
        if value is None:
            continue
        out[key] = value if isinstance(value, str) else json.dumps(value, default=float)
    return out

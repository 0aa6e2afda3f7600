"""The contract's graph side: every optional input optional in the ONNX sense, and the versions.

The contract's text is ``compensator.py``'s module docstring; this module holds what a graph must
carry so that a caller with onnxruntime alone can run it feeding only ``pose`` (issue 27):

* each optional input (``previous_pose``, ``joints``, ``tool``, ``approach``,
  ``previous_joints``) a graph takes is also an initializer of the same name, float32 [1, 6] NaN
  (ONNX: a graph input with an initializer is optional; onnxruntime uses the initializer when
  the caller omits the input, ``InferenceSession.get_overridable_initializers``), broadcast to
  the rows of ``pose`` (``Expand`` to ``Shape(pose)``) before the graph reads it, so an omitted
  input is a NaN row per target = "unknown", the contract's meaning of NaN for each;
* ``previous_pose``: a row with a NaN is the pose itself (the contract's "nothing is known
  before it", what ``Compensator`` feeds for the first target), chosen row by row in the graph;
* ``postproc_contract`` "2" in ``metadata_props``: the graphs of contract 1 (written before
  this) take the same inputs but require all of them; ``Compensator`` feeds every input either
  way and reads both. ``upgrade`` turns a contract-1 file into a contract-2 one (the same nodes
  and numbers for a caller feeding every input); a file of a newer contract than
  ``CONTRACT_VERSIONS`` is refused by ``compensator.load_model`` naming its version.

``with_defaults`` is the one function every exported graph goes through: ``training/export.py``
(hybrid, kinematic, dnn-joints and the pose-only networks), ``postproc.testing.models``, and
``postproc model upgrade`` for older files. Needs the ``onnx`` package (not ``compensate``).
"""
from __future__ import annotations

import numpy as np

from .compensator import (
    CONTRACT_VERSION,
    INPUT_APPROACH,
    INPUT_JOINTS,
    INPUT_POSE,
    INPUT_PREVIOUS,
    INPUT_PREVIOUS_JOINTS,
    INPUT_TOOL,
)

__all__ = ["OPTIONAL_INPUTS", "DEFAULT_MEANING", "with_defaults", "upgrade", "optional_inputs"]

# the optional inputs and what an omitted one means (the contract's NaN rows)
DEFAULT_MEANING = {
    INPUT_PREVIOUS: "the pose itself (nothing known before it)",
    INPUT_JOINTS: "NaN rows: the branch the model identified",
    INPUT_APPROACH: "NaN rows: the approach signs from previous_pose",
    INPUT_TOOL: "NaN rows: the model's own tool (card tool.frame)",
    INPUT_PREVIOUS_JOINTS: "NaN rows: unknown (previous_pose solved on the target's branch)",
}
OPTIONAL_INPUTS = tuple(DEFAULT_MEANING)
_SUFFIX = "__given"  # the name the graph reads an optional input by once broadcast


def optional_inputs(model) -> list[str]:
    """The contract inputs of ``model`` (onnx.ModelProto) that already have a default initializer."""
    inits = {i.name for i in model.graph.initializer}
    return [i.name for i in model.graph.input if i.name in OPTIONAL_INPUTS and i.name in inits]


def with_defaults(model):
    """``model`` (onnx.ModelProto, changed in place and returned) with a default for each optional
    input it takes (module text) and ``postproc_contract`` set to this contract. Idempotent."""
    from onnx import helper, numpy_helper

    graph = model.graph
    names = {i.name for i in graph.input}
    if INPUT_POSE not in names:
        raise ValueError(f"the graph has no input '{INPUT_POSE}'")
    have = set(optional_inputs(model))
    todo = [n for n in OPTIONAL_INPUTS if n in names and n not in have]
    if model.ir_version < 4:  # (an input with an initializer is optional from IR 4 on)
        model.ir_version = 4
    nodes = []
    shape = f"{INPUT_POSE}{_SUFFIX}_shape"
    if todo:
        nodes.append(helper.make_node("Shape", [INPUT_POSE], [shape], name="postproc_default_shape"))
    for name in todo:
        given = name + _SUFFIX
        for node in graph.node:  # the graph reads the broadcast value
            for k, value in enumerate(node.input):
                if value == name:
                    node.input[k] = given
        for out in graph.output:  # (an input passed straight through: not in the contract's graphs)
            if out.name == name:
                raise ValueError(f"input '{name}' is also a graph output")
        graph.initializer.append(numpy_helper.from_array(np.full((1, 6), np.nan, np.float32), name))
        if name == INPUT_PREVIOUS:
            wide, ones, total, unknown = (f"{name}{_SUFFIX}_{s}" for s in ("wide", "ones", "sum", "unknown"))
            graph.initializer.append(numpy_helper.from_array(np.ones((6, 1), np.float32), ones))
            nodes += [helper.make_node("Expand", [name, shape], [wide], name=f"postproc_default_{name}"),
                      helper.make_node("MatMul", [wide, ones], [total]),  # NaN where the row has one
                      helper.make_node("IsNaN", [total], [unknown]),
                      helper.make_node("Where", [unknown, INPUT_POSE, wide], [given])]
        else:
            nodes.append(helper.make_node("Expand", [name, shape], [given], name=f"postproc_default_{name}"))
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
    """An older compensator's bytes (contract 1: every input required) as this contract's: the
    same graph with ``with_defaults`` (the same numbers for a caller feeding every input)."""
    import onnx

    model = onnx.load_from_string(data)
    with_defaults(model)
    onnx.checker.check_model(model)
    return model.SerializeToString()

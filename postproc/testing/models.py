"""Small ONNX compensators built with onnx.helper, for tests and benchmarks (no torch needed).

``affine_model(offset, gain)`` predicts E = offset + gain · (xyz − centre): zero, constant
and position-dependent models with the full contract metadata; with ``load_gain`` a
load-aware one (optional input ``load`` [N, 4] and the card's ``loads``), whose error grows
with the payload's mass and varies over space. Each optional input has its
default (``contract.with_defaults``), as in every exported graph; ``defaults=False`` writes a
file as contract 1 did (every input required), ``as_contract_2`` rewrites a file as contract 2
did (each optional input's default an initializer of its name, which onnxruntime warns about).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

from ..model.contract import contract_metadata
from ..model.contract import with_defaults

DEFAULT_ENVELOPE = {"box": [1700, 2300, -600, 600, 500, 1300], "attitude": [0, 90, 0], "range": 10}
DEFAULT_REACH = {"center": [500, 0, 1045], "radius_min": 300, "radius_max": 2700}


def _save(model, meta: dict, path, defaults: bool = True) -> Path:
    """Add the contract metadata, check and write the model; its path."""
    for k, v in meta.items():
        model.metadata_props.add(key=k, value=v)
    if defaults:
        with_defaults(model)  # (the optional inputs optional, as every exported graph's)
    else:  # a file as contract 1 wrote it: every input required
        next(p for p in model.metadata_props if p.key == "postproc_contract").value = "1"
    onnx.checker.check_model(model)
    path = Path(path)
    onnx.save(model, path)
    return path


def affine_model(
    path: Path,
    offset=(0.0, 0.0, 0.0),
    gain: np.ndarray | None = None,
    centre=(2000.0, 0.0, 900.0),
    name: str = "test-model",
    robot: str = "KR500-sim",
    tool: dict | None = None,
    envelope: dict | None = DEFAULT_ENVELOPE,
    reach: dict | None = DEFAULT_REACH,
    previous_input: bool = False,
    method: str = "affine-test",
    defaults: bool = True,
    previous_gain=None,
    load_gain=None,
    load_offset=(0.0, 0.0, 0.0),
    loads: dict | None = None,
    **extra_meta,
) -> Path:
    """E = offset + gain · (xyz − centre) [+ previous_gain · (xyz − previous xyz): a model whose
    correction depends on where the robot comes from (the approach), for tests of execution
    order; ``previous_gain`` a number (times the identity) or [3, 3]; it implies
    ``previous_input``] [+ (m − m_ref) · (load_offset + load_gain · (xyz − centre)) / 100 with m
    the ``load``'s mass (kg; a row with a NaN: m_ref, the card's ``loads.reference`` mass):
    ``load_gain`` a number (times the identity) or [3, 3] implies the ``load`` input; ``loads``
    the card's ``loads`` (default measured at 0 and 300 kg, reference 300 kg, extrapolate 2)]."""
    if previous_gain is not None and not np.any(previous_gain):
        previous_gain = None
    if previous_gain is not None:
        previous_input = True
        previous_gain = np.asarray(previous_gain, float) * (np.eye(3) if np.ndim(previous_gain) == 0 else 1.0)
    gain = np.zeros((3, 3)) if gain is None else np.asarray(gain, float)
    # error = (xyz - centre) @ gain.T + offset, computed on the first 3 columns of pose
    nodes = [
        helper.make_node("Slice", ["pose", "s0", "s3", "ax1"], ["xyz"]),
        helper.make_node("Sub", ["xyz", "centre"], ["dx"]),
        helper.make_node("MatMul", ["dx", "gainT"], ["lin"]),
        helper.make_node("Add", ["lin", "offset"], ["error"]),
    ]
    inits = [
        numpy_helper.from_array(np.array([0], np.int64), "s0"),
        numpy_helper.from_array(np.array([3], np.int64), "s3"),
        numpy_helper.from_array(np.array([1], np.int64), "ax1"),
        numpy_helper.from_array(np.asarray(centre, np.float32), "centre"),
        numpy_helper.from_array(gain.T.astype(np.float32), "gainT"),
        numpy_helper.from_array(np.asarray(offset, np.float32), "offset"),
    ]
    inputs = [helper.make_tensor_value_info("pose", TensorProto.FLOAT, ["N", 6])]
    if previous_input:
        inputs.append(helper.make_tensor_value_info("previous_pose", TensorProto.FLOAT, ["N", 6]))
        if previous_gain is not None:
            nodes[-1] = helper.make_node("Add", ["lin", "offset"], ["base_error"])
            nodes += [helper.make_node("Slice", ["previous_pose", "s0", "s3", "ax1"], ["pxyz"]),
                      helper.make_node("Sub", ["xyz", "pxyz"], ["step"]),
                      helper.make_node("MatMul", ["step", "prevT"], ["plin"]),
                      helper.make_node("Add", ["base_error", "plin"], ["error"])]
            inits.append(numpy_helper.from_array(previous_gain.T.astype(np.float32), "prevT"))
    if load_gain is None and loads is not None:  # (a load-blind model whose card says what it was measured with)
        extra_meta["loads"] = loads
    if load_gain is not None:
        load_gain = np.asarray(load_gain, float) * (np.eye(3) if np.ndim(load_gain) == 0 else 1.0)
        loads = loads or {"measured": [[0, 0, 0, 0], [300, 0, 0, 250]], "reference": [300, 0, 0, 250],
                          "extrapolate": 2.0}
        extra_meta["loads"] = loads
        nodes[-1] = helper.make_node("Add", [nodes[-1].input[0], nodes[-1].input[1]], ["plain_error"])
        inputs.append(helper.make_tensor_value_info("load", TensorProto.FLOAT, ["N", 4]))
        nodes += [helper.make_node("Slice", ["load", "s0", "ax1", "ax1"], ["mass"]),  # [N, 1]
                  helper.make_node("ReduceSum", ["load", "ax1"], ["load_sum"], keepdims=1),
                  helper.make_node("IsNaN", ["load_sum"], ["load_unknown"]),
                  helper.make_node("Where", ["load_unknown", "ref_mass", "mass"], ["m"]),
                  helper.make_node("Sub", ["m", "ref_mass"], ["dm"]),
                  helper.make_node("MatMul", ["dx", "loadT"], ["load_lin"]),
                  helper.make_node("Add", ["load_lin", "load_offset"], ["load_per_kg"]),
                  helper.make_node("Mul", ["dm", "load_per_kg"], ["load_error"]),
                  helper.make_node("Add", ["plain_error", "load_error"], ["error"])]
        inits += [numpy_helper.from_array(np.array([[loads["reference"][0]]], np.float32), "ref_mass"),
                  numpy_helper.from_array((load_gain.T / 100).astype(np.float32), "loadT"),
                  numpy_helper.from_array((np.asarray(load_offset, float) / 100).astype(np.float32), "load_offset")]
    graph = helper.make_graph(
        nodes, "affine", inputs, [helper.make_tensor_value_info("error", TensorProto.FLOAT, ["N", 3])], inits
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    meta = contract_metadata(
        name=name,
        robot=robot,
        tool=tool or {"name": "tool1", "frame": [0, 0, 200, 0, 0, 0]},
        envelope=envelope,
        reach=reach,
        method=method,
        **extra_meta,
    )
    return _save(model, meta, path, defaults)


def joint_model(path: Path, gain: np.ndarray, tool_gain: np.ndarray | None = None, rotation_gain: np.ndarray | None = None,
                robot: str = "KR500-sim", tool: dict | None = None, name: str = "joint-test", defaults: bool = True,
                **extra_meta) -> Path:
    """A model of the arm's joints: E = gain · sin(joints) [+ tool_gain · tool[:3]] (input
    ``joints`` [N, 6] deg, optional input ``tool``), optional output ``rotation_error`` =
    rotation_gain · sin(joints) deg; E does not depend on ``pose`` at all, so a test sees which
    joint angles compensate passed."""
    gain = np.asarray(gain, float)
    nodes = [
        helper.make_node("Mul", ["joints", "rad"], ["q"]),
        helper.make_node("Sin", ["q"], ["sq"]),
        helper.make_node("MatMul", ["sq", "gainT"], ["e_q"]),
        # pose enters with weight 0 (every contract input must be used by the graph)
        helper.make_node("ReduceSum", ["pose", "ax1"], ["psum"], keepdims=1),
        helper.make_node("Mul", ["psum", "zero"], ["p0"]),
        helper.make_node("Add", ["e_q", "p0"], ["e_qp"]),
    ]
    inits = [
        numpy_helper.from_array(np.array(np.pi / 180, np.float32), "rad"),
        numpy_helper.from_array(gain.T.astype(np.float32), "gainT"),
        numpy_helper.from_array(np.array([1], np.int64), "ax1"),
        numpy_helper.from_array(np.array(0.0, np.float32), "zero"),
    ]
    inputs = [helper.make_tensor_value_info("pose", TensorProto.FLOAT, ["N", 6]),
              helper.make_tensor_value_info("joints", TensorProto.FLOAT, ["N", 6])]
    outputs = [helper.make_tensor_value_info("error", TensorProto.FLOAT, ["N", 3])]
    if tool_gain is not None:
        inputs.append(helper.make_tensor_value_info("tool", TensorProto.FLOAT, ["N", 6]))
        nodes += [helper.make_node("MatMul", ["tool", "toolT"], ["e_t"]),
                  helper.make_node("Add", ["e_qp", "e_t"], ["error"])]
        inits.append(numpy_helper.from_array(np.asarray(tool_gain, float).T.astype(np.float32), "toolT"))
    else:
        nodes.append(helper.make_node("Identity", ["e_qp"], ["error"]))
    if rotation_gain is not None:
        nodes.append(helper.make_node("MatMul", ["sq", "rotT"], ["rotation_error"]))
        inits.append(numpy_helper.from_array(np.asarray(rotation_gain, float).T.astype(np.float32), "rotT"))
        outputs.append(helper.make_tensor_value_info("rotation_error", TensorProto.FLOAT, ["N", 3]))
    graph = helper.make_graph(nodes, "joints", inputs, outputs, inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    meta = contract_metadata(name=name, robot=robot, tool=tool or {"name": "spindle", "frame": [300, 0, 75, 0, 0, 0]},
                             envelope=extra_meta.pop("envelope", None), reach=DEFAULT_REACH,
                             method="joint-test", **extra_meta)
    return _save(model, meta, path, defaults)


def as_contract_2(path: Path, out: Path | None = None) -> Path:
    """The contract-3 model file ``path`` rewritten (to ``out``, default in place) as contract 2
    wrote it: each optional input a plain tensor input with an initializer of its name (its
    default), read by the same broadcast nodes; the same numbers for any feed."""
    from ..model.contract import _DEFAULT, _VALUE, _rename_reads, _set_meta

    model = onnx.load(path)
    graph = model.graph
    optional = [i for i in graph.input if i.type.HasField("optional_type")]
    drop = {f"postproc_has_{i.name}" for i in optional} | {f"postproc_default_or_{i.name}" for i in optional}
    nodes = [n for n in graph.node if n.name not in drop]
    del graph.node[:]
    graph.node.extend(nodes)
    for value in optional:
        name = value.name
        _rename_reads(graph, name + _VALUE, name)
        default = next(i for i in graph.initializer if i.name == name + _DEFAULT)
        default.name = name
        tensor = onnx.TypeProto()
        tensor.CopyFrom(value.type.optional_type.elem_type)
        value.type.CopyFrom(tensor)
    _set_meta(model, "postproc_contract", "2")
    onnx.checker.check_model(model)
    out = Path(path if out is None else out)
    onnx.save(model, out)
    return out

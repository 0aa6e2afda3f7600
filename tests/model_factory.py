"""Small ONNX compensators built with onnx.helper, for tests (no torch needed).

``affine_model(offset, gain)`` predicts E = offset + gain · (xyz − centre): zero, constant
and position-dependent models with the full contract metadata.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

from postproc.compensator import contract_metadata

DEFAULT_ENVELOPE = {"box": [1700, 2300, -600, 600, 500, 1300], "attitude": [0, 90, 0], "range": 10}
DEFAULT_REACH = {"center": [500, 0, 1045], "radius_min": 300, "radius_max": 2700}


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
    **extra_meta,
) -> Path:
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
    for k, v in meta.items():
        model.metadata_props.add(key=k, value=v)
    onnx.checker.check_model(model)
    path = Path(path)
    onnx.save(model, path)
    return path

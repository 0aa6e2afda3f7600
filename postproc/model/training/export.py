"""Export a fitted network as a contract ONNX file (see postproc/model/compensator.py).

torch.onnx.export (the TorchScript exporter: the dynamo one needs onnxscript, which the
``train`` extra does not pull in), opset 17, input ``pose`` float32 [N, 6] with a dynamic
batch axis, output ``error`` float32 [N, 3]; pose features and standardisation are inside
the graph. Metadata go into ``metadata_props`` through ``contract_metadata``; each optional
input gets its default (``contract.with_defaults``: a caller may feed ``pose`` alone). The file is
written to a temporary name in the target folder and moved into place, so a failed export
never leaves a half-written model.
"""
from __future__ import annotations

import io
import warnings
from pathlib import Path

import onnx
import torch

from ...core import outputs
from ..contract import (
    INPUT_APPROACH,
    INPUT_JOINTS,
    INPUT_LOAD,
    INPUT_POSE,
    INPUT_PREVIOUS,
    INPUT_PREVIOUS_JOINTS,
    INPUT_TOOL,
    OUTPUT_ERROR,
    OUTPUT_JOINTS,
    OUTPUT_ROTATION,
    OUTPUT_STD,
    contract_metadata,
    with_defaults,
)

__all__ = ["export_onnx", "onnx_bytes", "write_atomic", "OPSET"]

OPSET = 17


def onnx_bytes(module: torch.nn.Module, metadata: dict, previous: bool = False, joints: bool = False,
               joints_input: bool = False, approach_input: bool = False, tool_input: bool = False,
               previous_joints_input: bool = False, rotation: bool = False, std: bool = False,
               load_input: bool = False) -> bytes:
    """The serialised ONNX model of ``module`` (pose [N, 6] [, previous_pose [N, 6]] [, joints
    [N, 6] deg] [, approach [N, 6]] [, tool [N, 6]] [, previous_joints [N, 6] deg] [, load [N, 4]] → error
    [N, 3] [, ik_joints [N, 6] deg] [, rotation_error [N, 3] deg] [, error_std [N, 1] mm]) with
    metadata; inputs and outputs in that order."""
    inputs = [INPUT_POSE, INPUT_PREVIOUS] if previous else [INPUT_POSE]
    if joints_input:
        inputs.append(INPUT_JOINTS)
    if approach_input:
        inputs.append(INPUT_APPROACH)
    if tool_input:
        inputs.append(INPUT_TOOL)
    if previous_joints_input:
        inputs.append(INPUT_PREVIOUS_JOINTS)
    if load_input:
        inputs.append(INPUT_LOAD)
    outputs = [OUTPUT_ERROR, OUTPUT_JOINTS] if joints else [OUTPUT_ERROR]
    if rotation:
        outputs.append(OUTPUT_ROTATION)
    if std:
        outputs.append(OUTPUT_STD)
    example = tuple(torch.tensor([[100.0, 0.0, 0.0, 200.0]] * 2, dtype=torch.float32) if name == INPUT_LOAD
                    else torch.tensor([[2000.0, 0.0, 900.0, 0.0, 90.0, 0.0]] * 2, dtype=torch.float32) for name in inputs)
    buffer = io.BytesIO()
    with warnings.catch_warnings():
        # the TorchScript exporter announces its deprecation on every call
        warnings.simplefilter("ignore")
        torch.onnx.export(
            module.eval(),
            example,
            buffer,
            dynamo=False,
            input_names=inputs,
            output_names=outputs,
            dynamic_axes={name: {0: "N"} for name in inputs + outputs},
            opset_version=OPSET,
            do_constant_folding=True,
        )
    model = onnx.load_from_string(buffer.getvalue())
    model.graph.name = "postproc_error_model"
    model.producer_name = "postproc.model.training"
    del model.metadata_props[:]
    for key, value in contract_metadata(**metadata).items():
        model.metadata_props.add(key=key, value=value)
    with_defaults(model)  # the optional inputs optional for any onnxruntime caller (contract.py)
    onnx.checker.check_model(model)
    return model.SerializeToString()


def write_atomic(path: str | Path, data: bytes) -> Path:
    """Write bytes to ``path`` atomically; missing folders are created (postproc.core.outputs: one rule)."""
    path = Path(path)
    outputs.write([(path, data)])
    return path


def export_onnx(module: torch.nn.Module, path: str | Path, metadata: dict) -> Path:
    """Export ``module`` with ``metadata`` to ``path`` (atomically)."""
    return write_atomic(path, onnx_bytes(module, metadata))

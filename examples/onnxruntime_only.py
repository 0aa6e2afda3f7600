"""Compensate a few targets with a postproc model, using onnxruntime and numpy only.

This is what a cell's own software (a robot-side PC, a CAM post-processor, a test rig) does
with a model file that `postproc train` wrote, without installing postproc:

    pip install onnxruntime numpy
    python onnxruntime_only.py models/default.onnx

The model maps commanded TCP poses (X, Y, Z mm, A, B, C deg, KUKA R = Rz(A)·Ry(B)·Rx(C), robot
base frame) to the positioning error E = P_target − P_actual (mm). The command that lands on P
is the fixed point c = P + Ê(c), started at c = P, iterated as often as the model card says.
Every input but `pose` is optional (contract 3: ONNX optional inputs, which `get_inputs()` lists
beside `pose` with the type optional(tensor(float)), fed a plain float32 array or left out): an
omitted `previous_pose` is the pose itself, an omitted `joints` / `tool` / `approach` /
`previous_joints` is unknown. A model that takes `joints` evaluates each target in the arm
configuration of the joint angles fed there, and without them in the one it identified: a
caller that knows the controller's joint angles at each target (deg) feeds them. (A file of
contract 2 lists its optional inputs in `get_overridable_initializers()` instead, and onnxruntime
warns about them: `postproc model upgrade OLD.onnx -o NEW.onnx` makes it contract 3.) The
contract's full text: postproc/model/compensator.py, docs/model-contract.md.
"""
import json
import sys

import numpy as np
import onnxruntime as ort

model_file = sys.argv[1] if len(sys.argv) > 1 else "models/default.onnx"

session = ort.InferenceSession(model_file, providers=["CPUExecutionProvider"])


def decoded(value: str):
    """A model card value: JSON where it is JSON, else the text itself."""
    try:
        return json.loads(value)
    except ValueError:
        return value


card = {k: decoded(v) for k, v in session.get_modelmeta().custom_metadata_map.items()}
iterations = int(card.get("iterations", 2))
# every input the model takes: `pose` (required), the others optional (left out: their default)
takes = {i.name: i.type for i in session.get_inputs()}

# three targets in the robot base frame, in program order (float32 [N, 6])
targets = np.array([[1800.0, -200.0, 900.0, 0.0, 90.0, 0.0],
                    [2000.0, 0.0, 1000.0, 5.0, 88.0, -3.0],
                    [2200.0, 300.0, 800.0, -4.0, 92.0, 2.0]], dtype=np.float32)
# the controller's joint angles at each target (deg, float32 [N, 6]) where your program knows
# them (its S/T, axis values): None here, so a model with `joints` takes the configuration it
# identified from its data
joints = None

commands = targets.copy()
for _ in range(iterations):
    feed = {"pose": commands}
    if "previous_pose" in takes:
        # the pose commanded before each target: the previous target's command (program order);
        # the first target's is itself (leave it out and the model takes the pose itself)
        feed["previous_pose"] = np.vstack([commands[:1], commands[:-1]])
    if "joints" in takes and joints is not None:
        feed["joints"] = joints  # the targets' configuration, the same at every iteration
    error = session.run(["error"], feed)[0]  # [N, 3] mm
    commands = targets.copy()
    commands[:, :3] += error  # c = P + Ê(c)

print(f"model {card.get('name', model_file)} (contract {card.get('postproc_contract', '?')}), "
      f"{iterations} iterations")
print("optional inputs: " + ", ".join(name for name, kind in takes.items() if kind.startswith("optional")))
if "joints" in takes:
    print("joints decides the arm configuration: " + ("fed" if joints is not None else
          "not fed, so each target is compensated in the configuration the model identified"))
for p, c in zip(targets, commands):
    print(f"target {p[0]:8.2f} {p[1]:8.2f} {p[2]:8.2f} -> command {c[0]:9.3f} {c[1]:9.3f} {c[2]:9.3f} mm "
          f"(correction {np.linalg.norm(c[:3] - p[:3]):.3f} mm)")

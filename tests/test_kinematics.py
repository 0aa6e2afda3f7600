"""One robot description, one reference FK: Pinocchio's model (postproc.robot.kinematics.reference.pin_model). The
derived kinematics — the numpy Chain (IK checks, simulator), the torch Arm (identification) and
the batch-last FK the exported ONNX graph runs (training/batch_last.py) — and the vectorised gravity torques are checked against
it on random joint angles over the joint ranges of both shipped descriptions and of a skewed
one (joint frames turned, axes off the coordinate axes: code paths the shipped robots skip)."""
from __future__ import annotations

import dataclasses
import io
import warnings

import numpy as np
import pytest

from postproc.robot.kinematics.chain import Chain
from postproc.robot.arm import Robot
from postproc.robot.kinematics.gravity import gravity_torques
from postproc.robot.description import load_description
from postproc.robot.kinematics.reference import pin_model
from postproc.core.resources import model_path

pin = pytest.importorskip("pinocchio")
torch = pytest.importorskip("torch")

POSES = 150
POSITION_MM, ROTATION, TORQUE = 1e-9, 1e-12, 1e-12  # torques: relative to the largest


def skewed(description):
    """The description with each joint frame turned and shifted a little, each axis tilted, another tool."""
    rng = np.random.default_rng(4)
    joints = []
    for j in description.joints:
        axis = j.axis + rng.normal(0, 0.05, 3)
        joints.append(dataclasses.replace(j, origin=j.origin + np.r_[rng.normal(0, 5, 3), rng.normal(0, 3, 3)],
                                          axis=axis / np.linalg.norm(axis)))
    return description.replace(joints=tuple(joints), tool=description.tool + [5, -3, 8, 10, -5, 3])


DESCRIPTIONS = {"kr500": load_description(), "ur10": load_description(model_path("ur10.toml"))}
DESCRIPTIONS["kr500 skewed"] = skewed(DESCRIPTIONS["kr500"])


@pytest.fixture(scope="module", params=list(DESCRIPTIONS))
def case(request):
    """(description, random joint angles [POSES, 6] deg within its limits)."""
    d = DESCRIPTIONS[request.param]
    limits = np.array([j.limits for j in d.joints])
    return d, np.random.default_rng(len(request.param)).uniform(limits[:, 0], limits[:, 1], (POSES, 6))


def reference_frames(description, q_deg):
    """Pinocchio's joint rotations [N, 6, 3, 3], origins [N, 6, 3] (mm) and TCPs [N, 4, 4]."""
    model = pin_model(description)
    data, tcp = model.createData(), model.getFrameId("tcp")
    n = len(q_deg)
    rot, org, end = np.zeros((n, 6, 3, 3)), np.zeros((n, 6, 3)), np.zeros((n, 4, 4))
    for i, qi in enumerate(np.radians(q_deg)):
        pin.framesForwardKinematics(model, data, qi)
        for j in range(6):
            rot[i, j], org[i, j] = data.oMi[j + 1].rotation, data.oMi[j + 1].translation * 1e3
        end[i, :3, :3], end[i, :3, 3], end[i, 3, 3] = data.oMf[tcp].rotation, data.oMf[tcp].translation * 1e3, 1.0
    return rot, org, end


def reference_gravity(description, q_deg, payload=True):
    """pin.computeGeneralizedGravity [N, 6] (Nm), one pose per call."""
    model = pin_model(description if payload else description.replace(payload_mass=0.0))
    data = model.createData()
    return np.array([pin.computeGeneralizedGravity(model, data, qi) for qi in np.radians(q_deg)])


def assert_frames(rot, org, tcp, reference):
    ref_rot, ref_org, ref_tcp = reference
    assert np.abs(org - ref_org).max() < POSITION_MM and np.abs(rot - ref_rot).max() < ROTATION
    assert np.abs(tcp[:, :3, 3] - ref_tcp[:, :3, 3]).max() < POSITION_MM
    assert np.abs(tcp[:, :3, :3] - ref_tcp[:, :3, :3]).max() < ROTATION


def assert_torques(got, expected):
    assert np.abs(expected).max() > 1.0  # the links' weight turns the joints at these angles
    assert np.abs(got - expected).max() < TORQUE * np.abs(expected).max()


def test_the_numpy_chain_is_pinocchios_fk(case):
    d, q = case
    chain = Chain.of(d)
    rot, org = chain.joints(np.radians(q))
    assert_frames(rot, org, chain.transforms(np.radians(q)), reference_frames(d, q))


def test_the_robots_fk_is_pinocchios():
    for d in (DESCRIPTIONS["kr500"], DESCRIPTIONS["ur10"]):
        robot = Robot(d)
        q = np.random.default_rng(5).uniform(robot.limits[:, 0], robot.limits[:, 1], (20, 6))
        np.testing.assert_allclose(robot.fk_matrix(q), robot.pin_fk(q), rtol=0, atol=POSITION_MM)
        np.testing.assert_allclose(robot.pin_fk(q, "flange") @ robot.tool_matrix, robot.fk_matrix(q), atol=POSITION_MM)


def test_the_torch_arm_is_pinocchios_fk(case):
    from postproc.robot.kinematics.twin import Arm, mc

    d, q = case
    arm = Arm(d)
    rot, org, tcp = arm.frames(torch.as_tensor(np.radians(q)))
    end = np.zeros((len(q), 4, 4))
    end[:, :3, :3], end[:, :3, 3] = mc(rot[:, -1], arm.end[:3, :3]).numpy(), tcp.numpy()
    assert_frames(rot.numpy(), org.numpy(), end, reference_frames(d, q))


class _Exported(torch.nn.Module):
    """The FK and gravity torques as they run inside an exported graph (training/batch_last.py:
    [3, N] vectors, [3, 3, N] rotations), brought back to [N, …]."""

    def __init__(self, arm):
        super().__init__()
        self.arm = arm

    def forward(self, q):
        from postproc.robot.kinematics import batch_last as bl

        arm = self.arm
        f = bl.frames(bl.joint_turns(arm.placements, arm.axes), arm.placements[:, :3, 3], q.t(), arm.end[:3, 3])
        rotations = torch.stack(f.rotations).permute(3, 0, 1, 2)
        tcp_rotation = bl.mat(f.rotations[-1], arm.end[:3, :3][:, :, None]).permute(2, 0, 1)
        return (rotations, f.origins_stacked().permute(2, 0, 1), f.tcp.t(), tcp_rotation,
                bl.torque_terms(arm, f)[:6].t())


def test_the_onnx_graph_is_pinocchios_fk_and_gravity(case):
    import onnxruntime

    from postproc.robot.kinematics.twin import Arm
    from postproc.model.training.export import OPSET

    d, q = case
    buffer = io.BytesIO()
    names = ("rotations", "origins", "tcp", "rotation", "tau")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the TorchScript exporter's deprecation notice
        torch.onnx.export(_Exported(Arm(d)).eval(), (torch.zeros(2, 6, dtype=torch.float64),), buffer, dynamo=False,
                          input_names=["q"], output_names=list(names),
                          dynamic_axes={name: {0: "N"} for name in ("q",) + names}, opset_version=OPSET)
    session = onnxruntime.InferenceSession(buffer.getvalue(), providers=["CPUExecutionProvider"])
    rotations, origins, tcp, rotation, tau = session.run(None, {"q": np.radians(q)})
    end = np.zeros((len(q), 4, 4))
    end[:, :3, :3], end[:, :3, 3] = rotation, tcp
    assert_frames(rotations, origins, end, reference_frames(d, q))
    assert_torques(tau, reference_gravity(d, q))


@pytest.mark.parametrize("payload", [True, False], ids=["payload", "unloaded"])
def test_gravity_torques_are_pinocchios(case, payload):
    from postproc.robot.kinematics.twin import Arm

    d, q = case
    expected = reference_gravity(d, q, payload)
    assert_torques(gravity_torques(d, q, payload), expected)
    arm = Arm(d if payload else d.replace(payload_mass=0.0))
    rot, org, _ = arm.frames(torch.as_tensor(np.radians(q)))
    assert_torques(arm.gravity_torques(rot, org).numpy(), expected)


@pytest.mark.parametrize("name", ["kr500", "ur10"])
def test_the_robots_gravity_torques_are_pinocchios(name, monkeypatch):
    import postproc.robot.kinematics.gravity

    d = DESCRIPTIONS[name]
    robot = Robot(d)
    q = np.random.default_rng(6).uniform(robot.limits[:, 0], robot.limits[:, 1], (25, 6))
    for payload in (True, False):
        assert_torques(robot.gravity_torques(q, payload=payload), reference_gravity(d, q, payload))
    whole = robot.gravity_torques(q)
    monkeypatch.setattr(postproc.robot.kinematics.gravity, "GRAVITY_ROWS", 7)  # many poses: a block at a time, same figures
    np.testing.assert_array_equal(robot.gravity_torques(q), whole)
    assert not np.allclose(whole, robot.gravity_torques(q, payload=False))  # the payload's weight counts

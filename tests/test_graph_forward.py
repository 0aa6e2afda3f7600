"""The exported graph's forward (KinematicErrorModule.parts, batch-last: training/batch_last.py)
computes what the fit's [N, …] functions compute — error_at, the rotation error, the error_std of
kinematic.jacobian's columns — on the shipped model's identification, and it solves the IK of
``previous_pose`` only for the rows where the row before does not already hold it."""
import math

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from postproc.core.resources import model_path  # noqa: E402
from postproc.robot.description import load_description  # noqa: E402
from postproc.robot.kinematics.twin import Arm, make_ik  # noqa: E402
from postproc.model.training.features import previous_poses  # noqa: E402
from postproc.model.training.kinematic import GROUPS, KinematicErrorModule, Layout, approach_signs, jacobian  # noqa: E402
from postproc.robot.kinematics.twin import rotation_matrices  # noqa: E402
from postproc.model.training.kinematic import residual_variance  # noqa: E402
from postproc.model.training.update import read_old_model  # noqa: E402

ROWS = 400


@pytest.fixture(scope="module")
def shipped():
    """models/default.onnx's identification as a torch module (as train --update reads it back),
    its covariance, and program-order poses over its envelope ±10° with other tools on some rows."""
    d = load_description()
    old = read_old_model(model_path("default.onnx"), d)
    module = KinematicErrorModule(Arm(d), old.ik, old.layout, old.theta, old.use_previous, old.tau_mean)
    assert len(old.layout.ripple) and old.covariance is not None and old.use_previous
    rng = np.random.default_rng(3)
    box = np.array(old.envelope["box"]).reshape(3, 2)
    poses = np.c_[rng.uniform(box[:, 0], box[:, 1], (ROWS, 3)), rng.uniform(-10, 10, ROWS),
                  90 + rng.uniform(-10, 10, ROWS), rng.uniform(-10, 10, ROWS)]
    tool = np.full((ROWS, 6), np.nan)
    tool[ROWS // 2:] = [250.0, 20.0, 120.0, 0.0, 5.0, 0.0]
    return module, torch.as_tensor(old.covariance), torch.as_tensor(poses), torch.as_tensor(tool)


def _reference(module, pose, q, signs, learned, tool, covariance, sigma2):
    """error_at's error and rotation error, and the std of jacobian's columns (the fit's [N, …] functions)."""
    error, turned = module.error_at(q, signs, pose[:, :3], learned, tool, rotation_matrices(pose[:, 3:6]))
    tools = None
    if tool is not None:
        tools = torch.where(torch.isnan(tool[:, :3]), module.tool0[:3].expand(len(tool), 3), tool[:, :3])
    _, jac, _ = jacobian(module.arm, module.layout, module.theta, q, signs, module.torques(q), tools,
                         ripple_rows=learned)
    return error, turned, residual_variance(jac, covariance, sigma2).mean(dim=-1, keepdim=True).sqrt()


RANGES = np.radians([[-15.0, 15.0], [-85.0, -30.0], [55.0, 130.0], [-10.0, 10.0], [5.0, 95.0], [-40.0, 40.0]])


def test_the_batch_last_forward_is_the_fits_error_rotation_and_std(shipped):
    module, covariance, pose, tool = shipped
    sigma2 = torch.tensor(0.02**2, dtype=torch.float64)
    previous = torch.as_tensor(previous_poses(pose.numpy()))
    with torch.no_grad():
        error, q, signs, learned, turned, std = module.parts(pose, previous, ranges=torch.as_tensor(RANGES), tool=tool,
                                                             rotation=True, uncertainty=(covariance, sigma2))
        assert 0 < learned.sum() < len(learned) and (signs != 0).any()  # both sides of the ripple mask, backlash
        ref_error, ref_turned, ref_std = _reference(module, pose, q, signs, learned, tool, covariance, sigma2)
    assert error.abs().max() > 0.3 and np.ptp(std.numpy()) > 0.1 * std.mean().item()  # (it varies over space)
    assert (error - ref_error).abs().max() < 1e-9  # mm
    assert (turned - ref_turned).abs().max() < 1e-12  # rad
    assert (std - ref_std).abs().max() < 1e-12  # mm


def test_every_parameter_group_and_no_tool_input(shipped):
    """An identification with every group (the tool mount's rotation and the tool's too, which the
    shipped model has not) at random parameters, without a tool input."""
    _, _, pose, _ = shipped
    d = load_description()
    layout = Layout(GROUPS, [(0, 36), (2, 3), (2, 7)])
    rng = np.random.default_rng(5)
    theta = rng.normal(0.0, 1e-3, layout.n)
    theta[layout.slices()["compliance"]] *= 1e-4  # (rad/Nm: τ ~ 1e3–1e4 Nm)
    theta[layout.slices()["coupling"]] *= 1e-4
    module = KinematicErrorModule(Arm(d), make_ik(d), layout, theta, True, rng.normal(0.0, 100.0, 27))
    half = rng.normal(size=(layout.n, layout.n)) * 1e-3
    covariance, sigma2 = torch.as_tensor(half @ half.T), torch.tensor(1e-4, dtype=torch.float64)
    previous = torch.as_tensor(previous_poses(pose.numpy()))
    with torch.no_grad():
        error, q, signs, learned, turned, std = module.parts(pose, previous, ranges=torch.as_tensor(RANGES),
                                                             rotation=True, uncertainty=(covariance, sigma2))
        ref_error, ref_turned, ref_std = _reference(module, pose, q, signs, learned, None, covariance, sigma2)
    assert error.abs().max() > 0.3 and turned.abs().max() > 1e-4 and np.ptp(std.numpy()) > 0.1 * std.mean().item()
    assert (error - ref_error).abs().max() < 1e-9 and (turned - ref_turned).abs().max() < 1e-12
    assert (std - ref_std).abs().max() < 1e-9 * ref_std.abs().max()


class _Counting(torch.nn.Module):
    """An IK that records how many rows each call solves."""

    def __init__(self, ik):
        super().__init__()
        self.inner, self.rows = ik, []

    def forward(self, pose, q_in=None):
        self.rows.append(len(pose[1]) if isinstance(pose, tuple) else len(pose))
        return self.inner(pose) if q_in is None else self.inner(pose, q_in)


def test_the_previous_poses_ik_is_the_row_befores_where_it_is_that_rows_pose(shipped):
    module, _, pose, tool = shipped
    with torch.no_grad():
        q_in = module.ik(pose)  # the controller's angles: the model's branch
        q_in[ROWS // 4] = float("nan")  # one row without (its own and the next row's branch: the default)
        q_previous = torch.cat([torch.full((1, 6), math.nan, dtype=torch.float64), q_in[:-1]])
        previous = torch.as_tensor(previous_poses(pose.numpy()))
        previous[ROWS // 3] += 0.5  # a row whose previous pose is not the row before's
        module.ik = counting = _Counting(module.ik)
        try:
            q = module.joints_of(pose, q_in)  # (without a tool: the model's own on every row)
            own = tool[:1].expand_as(tool).clone()
            own[:] = float("nan")
            solved = module.previous_joints(q, pose, previous, q_in, own, q_previous)
            counting.rows.clear()
            full = approach_signs(module.ik, module.arm.home_q, q, pose, previous, q_in, None, q_previous)
            shared = approach_signs(module.ik, module.arm.home_q, q, pose, previous, q_in, None, q_previous, solved)
            assert counting.rows == [ROWS]
            counting.rows.clear()
            # the first row (no row before), the row whose previous pose moved and the row after the one
            # without joints (solved on its own branch where the row before took the default one)
            module.previous_joints(q, pose, previous, q_in, own, q_previous)
            assert counting.rows == [3]
            # another tool from row ROWS // 2 on: that row's previous pose is solved at its own tool
            module.previous_joints(q, pose, previous, q_in, tool, q_previous)
            assert counting.rows[-1] == 4
        finally:
            module.ik = counting.inner
    torch.testing.assert_close(shared, full, rtol=0, atol=0)

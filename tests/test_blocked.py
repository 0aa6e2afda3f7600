"""Blocked cross-validation (training/blocked.py): the linearised per-region fits are the fits a
solver makes without each region; the regions; what train reports of them; the compliance
priors' scale from the whole joint range (a compliance fitted where a joint's torque stays small
does not carry to a pose where it is large)."""
import json

import numpy as np
import pytest

pytest.importorskip("torch")

from postproc.model.training.blocked import BlockedCV, folds  # noqa: E402


def test_each_region_is_predicted_by_the_fit_without_it():
    """Random linear problem, two parameter sets (the second fitted on top of the first, as the
    ripple orders on the physical groups), a prior: the Gram algebra gives exactly the residuals
    of least-squares fits made without each region, and rows outside the others' joint arcs get
    no second-set terms."""
    rng = np.random.default_rng(0)
    n, per_row, p = 90, 3, 7
    jac = rng.normal(size=(n * per_row, p))
    theta_true = rng.normal(size=p)
    r0 = -jac @ theta_true + 0.05 * rng.normal(size=n * per_row)  # residual at θ = 0
    theta_hat = rng.normal(size=p) * 0.1  # any linearisation point: r = r0 + J θ̂
    fold = np.r_[np.tile([0, 1], 30), np.full(30, 2)]
    # regions 0 and 1 interleaved over A1 0…60°, region 2 at 65…90°: beyond the others' arc
    q = np.radians(np.c_[np.r_[np.linspace(0, 60, 60), np.linspace(65, 90, 30)], np.zeros((n, 5))])
    cv = BlockedCV(jac, r0 + jac @ theta_hat, theta_hat, fold, q)
    weights = np.full(p, 0.3)
    first, second = np.arange(4), np.arange(4, 7)
    got = cv.evaluate(first, second, weights, variance=True)
    for k in range(3):
        rows = np.repeat(fold != k, per_row)
        a, b = jac[rows], r0[rows]
        t1 = np.linalg.solve(a[:, first].T @ a[:, first] + 0.3 * np.eye(4), -a[:, first].T @ b)
        rest = b + a[:, first] @ t1
        t2 = np.linalg.solve(a[:, second].T @ a[:, second] + 0.3 * np.eye(3), -a[:, second].T @ rest)
        held = np.repeat(fold == k, per_row)
        cols = jac[held].copy()
        if k == 2:
            cols[:, second] = 0.0  # outside the arc of the rows fitted: the second set left out
        e = r0[held] + cols[:, first] @ t1 + cols[:, second] @ t2
        np.testing.assert_allclose(got.residual[fold == k].reshape(-1), e, atol=1e-9)
    assert got.outside.tolist() == (fold == 2).tolist()
    assert got.sse == pytest.approx(float((got.residual ** 2).sum()))
    assert (got.variance > 0).all()


def test_regions_are_octants_and_whole_arm_configurations():
    rng = np.random.default_rng(1)
    q = np.radians(rng.uniform(-60, 60, size=(400, 6)))
    one = np.ones((400, 3))
    ways = folds(q, one)
    assert [name for name, _ in ways] == ["octants"] and ways[0][1].max() == 7
    branches = one.copy()
    branches[:100, 2] = -1  # a quarter of the rows in the flipped wrist
    ways = dict(folds(q, branches))
    assert set(ways) == {"octants", "configurations"} and np.bincount(ways["configurations"]).tolist() == [100, 300]
    branches[:10, 2] = 1
    branches[:10, 1] = -1  # 2.5 % in a third configuration: no way of its own, held out with the others
    assert len(np.bincount(dict(folds(q, branches))["configurations"])) == 3


@pytest.mark.slow
def test_train_reports_the_blocked_figures_and_what_it_chose(tmp_path, capsys):
    """The IPA Series C excerpt (150 rows, one arm configuration): the card carries the blocked
    held-out figures beside the random ones and the selection; train prints both."""
    from postproc.cli import main
    from postproc.model.compensator import load_model
    from postproc.core.resources import sample_path

    data = tmp_path / "c.csv"
    assert main(["import", "ipa", str(sample_path("ipa/series_c_excerpt.csv")), "-o", str(data), "--register",
                 "--val-fraction", "0", "-q"]) == 0
    capsys.readouterr()
    assert main(["train", str(data), "-o", str(tmp_path / "m.onnx"), "--robot", "models/ur10.toml",
                 "--val-fraction", "0.2"]) == 0
    out = capsys.readouterr().out
    assert "select    blocked CV over joint-space regions (8 octants, each held out)" in out
    assert "residual (blocked, arm)" in out
    card = load_model(tmp_path / "m.onnx").metadata
    blocked, selection = card["accuracy"]["blocked"], card["identified"]["selection"]
    assert blocked["regions"] == {"octants": 8} and blocked["rows"] == card["accuracy"]["n_train"]
    # regions held out whole are predicted worse than rows between training rows
    assert blocked["mean_mm"] > 0.5 * card["accuracy"]["val_mean_mm"] and blocked["max_mm"] >= blocked["mean_mm"]
    assert set(selection["groups"]) == {"all", "without coupling", "without compliance",
                                        "without coupling and compliance"}
    assert json.dumps(card["uncertainty"]["calibration"])  # the error_std's calibration on those rows
    assert card["uncertainty"]["calibration"]["kappa"] >= 1.0


def test_compliance_prior_is_scaled_by_the_torque_anywhere_in_the_joint_limits():
    """The prior's unit of a compliance is a deflection of 1 mrad at the largest torque the joint
    can see in its limits, not at the largest the rows saw: rows where A5 carries little torque
    (the tool hanging down) leave A5's compliance near 0 instead of free."""
    import torch

    from postproc.calibration.planning import latin_hypercube
    from postproc.robot.description import load_description
    from postproc.calibration.simulator import SimulatedRobot
    from postproc.model.training.features import previous_poses
    from postproc.model.training.kinematic import PRIOR_RAD, KinematicModel, Layout

    d = load_description()
    sim = SimulatedRobot(d)
    poses = latin_hypercube(150, attitude=(0.0, 90.0, 0.0), range_deg=2.0, seed=4)  # A5 turned little
    km = KinematicModel(d, ripple=[], select="none").fit(poses, poses[:, :3] - sim.measure(poses, rng_seed=0),
                                                         previous_poses(poses))
    with torch.no_grad():
        tau = km.module_.torques(torch.as_tensor(km.train_q_))
    rows = torch.abs(tau).amax(dim=0).numpy()
    assert km.torque_span_[4] > 3 * rows[4]  # A5's torque over its limits far beyond these rows'
    layout = Layout(("compliance",))
    np.testing.assert_allclose(km._prior_scales(layout, tau), PRIOR_RAD / np.maximum(km.torque_span_[:6], rows[:6]))
    # A5's fitted deflection at the largest torque it can see stays within the prior's few mrad
    assert abs(km.parameters()["compliance"][4]) * km.torque_span_[4] < 3e-3

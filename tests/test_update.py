"""Re-calibration (``train --update``, postproc.model.training.update) on simulated campaigns.

A simulated robot is measured (300 rows) and identified; then the same robot is re-mastered
(A2, A3, A5 zero offsets) and the tracker set up again (the base moves by a small rigid
motion), and 30 rows of it are measured. The update must recover it: held-out error close to
a full re-train on 300 rows and far below the old model's, and report as moved the
parameters that changed, not the others.
"""
from __future__ import annotations

import json

import numpy as np
import torch
import pytest

from postproc.cli import main
from postproc.model.compensator import load_model
from postproc.calibration.planning import latin_hypercube
from postproc.robot.kinematics.chain import Chain
from postproc.robot.description import load_description
from postproc.calibration.simulator import SimulatedRobot
from postproc.core.frames import small_transform
from postproc.model.training.features import previous_poses
from postproc.model.training.hybrid import HybridModel
from postproc.model.training.update import read_old_model, update_model

from helpers import REPO

HEADER = "x,y,z,a,b,c,x_meas,y_meas,z_meas"
ZERO_CHANGE_DEG = np.array([0.0, 0.04, -0.03, 0.0, 0.05, 0.0])  # re-mastered A2, A3, A5
BASE_TURN_RAD = np.array([0.0002, -0.0003, 0.0])
BASE_SHIFT_MM = np.array([0.8, -0.5, 0.3])
SETTINGS = {"residual": "none", "kinematic": {"max_ripple": 6}}


def _campaign(sim: SimulatedRobot, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    poses = latin_hypercube(n, seed=seed)
    return poses, poses[:, :3] - sim.measure(poses, rng_seed=seed)


def _changed(sim: SimulatedRobot) -> SimulatedRobot:
    """The same robot after re-mastering and a new tracker set-up."""
    sim.zero_offsets_deg = sim.zero_offsets_deg + ZERO_CHANGE_DEG / sim.scale
    c = sim.chain
    sim.chain = Chain(c.placements, c.axes, c.end, small_transform(BASE_TURN_RAD, BASE_SHIFT_MM) @ c.base)
    return sim


def _csv(path, poses, errors):
    rows = [",".join(f"{v:.5f}" for v in (*p, *(p[:3] - e))) for p, e in zip(poses, errors)]
    path.write_text("\n".join([HEADER, *rows]) + "\n", encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def kr500():
    return load_description()


@pytest.fixture(scope="module")
def old(kr500, tmp_path_factory):
    """(path, fitted model) of the first campaign: 300 rows, with a residual network."""
    from postproc.model.training.card import arm_metadata

    poses, errors = _campaign(SimulatedRobot(kr500, seed=3), 300, 1)
    model = HybridModel(kr500, residual="always", ensemble=1, epochs=40, kinematic={"max_ripple": 6}).fit(
        poses, errors, previous_poses(poses))
    path = tmp_path_factory.mktemp("update") / "old.onnx"
    model.export_onnx(path, identified=model.describe(), **arm_metadata(kr500))
    return path, model


@pytest.fixture(scope="module")
def remastered(kr500, old):
    """(robot, poses, errors, update): the robot re-mastered with a new tracker set-up, 30 rows of
    it and OLD updated from them (the update two tests look at)."""
    sim = _changed(SimulatedRobot(kr500, seed=3))
    poses, errors = _campaign(sim, 30, 7)
    return sim, poses, errors, update_model(read_old_model(old[0], kr500), kr500, poses, errors, previous_poses(poses))


def _mean(errors, predicted):
    return float(np.linalg.norm(errors - predicted, axis=1).mean())


@pytest.mark.slow
def test_update_recovers_remastering_and_a_new_tracker_from_30_rows(kr500, old, remastered):
    _, model = old
    sim, _, _, update = remastered
    held, held_errors = _campaign(sim, 300, 8)
    prev = previous_poses(held)
    full_poses, full_errors = _campaign(sim, 300, 9)
    full = HybridModel(kr500, **SETTINGS).fit(full_poses, full_errors, previous_poses(full_poses))
    before, after = _mean(held_errors, model.predict(held, prev)), _mean(held_errors, update.model.predict(held, prev))
    retrained = _mean(held_errors, full.predict(held, prev))
    assert after < 0.15 * before  # the old model is far off the changed robot
    assert after < 1.5 * retrained  # 30 rows do about what 300 do
    # what moved is what changed: A2, A3, A5 and the base's position and tilt
    moved = {p["name"]: p for p in update.moved}
    assert update.region["chosen"] == 0.0  # (the geometry did not change: the placements are kept)
    assert {"zero.A2", "zero.A3", "zero.A5", "base.x", "base.y", "base.z"} <= set(moved)
    assert not {"zero.A4", "zero.A6", "tool.x", "tool.y", "tool.z"} & set(moved)
    for j in (1, 2, 4):
        p = moved[f"zero.A{j + 1}"]
        assert p["unit"] == "deg" and abs(p["change"] - ZERO_CHANGE_DEG[j]) < max(3 * p["std"], 0.003)
    assert abs(moved["base.x"]["change"] - BASE_SHIFT_MM[0]) < 0.15
    # everything but the re-fitted groups is the old model's, the networks included
    km_old, km_new = model.kinematic_, update.model.kinematic_
    fixed = np.ones(km_old.layout_.n, bool)
    for group, where in km_old.layout_.slices().items():
        fixed[where] = group not in ("base", "zero", "tool")
    assert km_new.layout_.ripple == km_old.layout_.ripple
    assert np.array_equal(km_new.theta_[fixed], km_old.theta_[fixed])
    assert len(update.model.nets_) == 1
    for name, value in model.nets_[0].state_dict().items():
        assert np.allclose(update.model.nets_[0].state_dict()[name].numpy(), value.numpy(), rtol=1e-6, atol=1e-7)


def test_update_on_an_unchanged_robot_moves_nothing(kr500, old):
    path, model = old
    sim = SimulatedRobot(kr500, seed=3)
    poses, errors = _campaign(sim, 30, 11)
    update = update_model(read_old_model(path, kr500), kr500, poses, errors, previous_poses(poses))
    assert update.moved == []
    held, held_errors = _campaign(sim, 200, 12)
    prev = previous_poses(held)
    assert _mean(held_errors, update.model.predict(held, prev)) < 1.2 * _mean(held_errors, model.predict(held, prev))


@pytest.mark.slow
def test_train_update_cli_writes_the_moved_parameters(old, remastered, tmp_path, capsys):
    path, _ = old
    _, poses, errors, _ = remastered
    data = _csv(tmp_path / "new.csv", poses, errors)
    out = tmp_path / "new.onnx"
    assert main(["train", str(data), "-o", str(out), "--update", str(path), "--val-fraction", "0"]) == 0
    printed = capsys.readouterr().out
    card = load_model(out).metadata
    update = card["update"]
    # re-mastered and a new tracker set-up, the tool as it was: the rows ask for the frame and
    # the zero offsets, not the tool (its step's GCV score does not beat theirs)
    assert update["rows"] == 30 and update["from_sha256"] and update["groups"] == ["base", "zero"]
    assert [c["groups"] for c in update["choice"]["candidates"]] == [["base"], ["base", "zero"], ["base", "zero", "tool"]]
    assert "choice    the groups the new rows ask for" in printed
    moved = [p["name"] for p in update["parameters"] if p["moved"]]
    assert "zero.A2" in moved and "zero.A4" not in moved
    for name in moved:
        assert f"moved     {name}" in printed
    assert "zero.A4" not in printed.split("update    ")[1]
    assert "region    joint placements kept (GCV score" in printed and update["region"]["chosen"] == 0.0
    # the new card can be updated again (the chain of campaigns); without --val-fraction every one
    # of the 30 rows is fitted (below 100 rows none is held out), and train says so
    again = tmp_path / "again.onnx"
    assert main(["train", str(data), "-o", str(again), "--update", str(out)]) == 0
    assert "every one of the 30 rows fitted, none held out" in capsys.readouterr().err
    card = load_model(again).metadata
    assert json.loads(json.dumps(card["update"]))["from"] == "new" and card["update"]["rows"] == 30
    assert card["accuracy"]["n_val"] == 0


def test_update_refuses_a_model_without_identification(affine, kr500, tmp_path, capsys):
    poses, errors = _campaign(SimulatedRobot(kr500, seed=3), 30, 7)
    data = _csv(tmp_path / "new.csv", poses, errors)
    dnn = affine(gain=np.eye(3) * 1e-3)
    out = tmp_path / "new.onnx"
    assert main(["train", str(data), "-o", str(out), "--update", str(dnn)]) == 2
    err = capsys.readouterr().err
    assert f"{dnn}:" in err and "P317" in err and "no identified parameters" in err and not out.exists()
    assert main(["train", str(data), "-o", str(out), "--update", str(dnn), "--method", "gpso"]) == 2
    assert "P317" in capsys.readouterr().err and not out.exists()


def test_update_refuses_another_robot(old, tmp_path, capsys):
    path, _ = old
    ur10 = REPO / "models" / "ur10.toml"
    data = _csv(tmp_path / "new.csv", *_campaign(SimulatedRobot(load_description(), seed=3), 30, 7))
    out = tmp_path / "new.onnx"
    assert main(["train", str(data), "-o", str(out), "--update", str(path), "--robot", str(ur10)]) == 2
    err = capsys.readouterr().err
    assert f"{path}:" in err and "P318" in err and not out.exists()


def test_update_refuses_an_older_card(kr500, old, tmp_path):
    import onnx

    path, _ = old
    model = onnx.load(path)
    for prop in model.metadata_props:
        if prop.key == "identified":
            card = json.loads(prop.value)
            del card["ripple_amplitudes"]
            prop.value = json.dumps(card)
    older = tmp_path / "older.onnx"
    onnx.save(model, older)
    from postproc.core.diagnostics import PostprocError

    with pytest.raises(PostprocError) as info:
        read_old_model(older, kr500)
    assert info.value.code == "P317" and "older than --update" in str(info.value)


def test_update_refuses_too_few_rows_at_the_data(old, kr500, tmp_path, capsys):
    path, _ = old
    data = _csv(tmp_path / "four.csv", *_campaign(SimulatedRobot(kr500, seed=3), 4, 7))
    out = tmp_path / "new.onnx"
    assert main(["train", str(data), "-o", str(out), "--update", str(path), "--val-fraction", "0"]) == 2
    err = capsys.readouterr().err
    assert f"{data}:" in err and "P505" in err and "at least 5" in err and not out.exists()


def test_update_refuses_the_same_name_with_another_geometry(old, kr500):
    from postproc.core.diagnostics import PostprocError

    path, _ = old
    other = kr500.replace(tool=kr500.tool + np.array([0.0, 0.0, 50.0, 0.0, 0.0, 0.0]))
    with pytest.raises(PostprocError) as info:
        read_old_model(path, other)
    assert info.value.code == "P318" and "not the one the model was identified on" in str(info.value)
    assert read_old_model(path, kr500.replace(text="# another comment\n" + kr500.text)).layout.n  # text alone: same


def test_update_reads_back_every_residual_network(kr500, tmp_path):
    """An ensemble of residual networks fitted on the same rows shares its standardisation: the
    exporter keeps those equal tensors once, under the first network's name; every network is
    read back whole (was: P317 "network 1 cannot be read back")."""
    from postproc.model.training.card import arm_metadata

    poses, errors = _campaign(SimulatedRobot(kr500, seed=4), 200, 2)
    model = HybridModel(kr500, residual="always", ensemble=2, epochs=20, kinematic={"max_ripple": 4}).fit(
        poses, errors, previous_poses(poses))
    path = model.export_onnx(tmp_path / "two_nets.onnx", identified=model.describe(), **arm_metadata(kr500))
    back = read_old_model(path, kr500)
    assert len(back.nets) == 2
    x = torch.as_tensor(np.random.default_rng(0).normal(size=(50, back.nets[0].x_mean.shape[0])))
    with torch.no_grad():
        for mine, read in zip(model.nets_, back.nets):
            assert torch.allclose(mine(x), read(x), atol=1e-6)


def test_an_updated_model_keeps_stating_its_uncertainty(old, remastered, tmp_path):
    """OLD with ``error_std``: the update exports it too, from OLD's covariance of what it kept
    and the re-fit's of what it moved, at the new rows' residual level — so compensate's P336
    bound goes on holding after a re-calibration (was: the output was dropped)."""
    path, _ = old
    before = load_model(path)
    assert before.has_std
    sim, _, _, update = remastered
    new = load_model(update.model.export_onnx(tmp_path / "new.onnx", name="new"))
    assert new.has_std and new.max_std_mm is not None
    held = latin_hypercube(200, seed=9)
    truth = sim.true_error(held)
    predicted, std = new.predict(held, previous_poses(held), std=True)
    residual = np.abs(truth - predicted)  # per coordinate
    # the stated std is of the residual this campaign leaves: most coordinates within 2 std
    assert 0.8 < float((residual <= 2 * std[:, None]).mean()) <= 1.0
    assert np.all(std > 0) and np.all(np.isfinite(std))


TOOL_TURN_RAD = np.array([0.004, -0.003, 0.006])  # the probe mounted again, turned by ~0.45°


def _oriented_campaign(sim: SimulatedRobot, n: int, seed: int):
    """(poses, position errors, orientation errors deg) measured by a 6-DOF probe."""
    from postproc.core.frames import rotation_error_deg

    poses = latin_hypercube(n, seed=seed)
    measured = sim.measure(poses, rng_seed=seed, orientation=True)
    return poses, poses[:, :3] - measured[:, :3], rotation_error_deg(poses[:, 3:], measured[:, 3:])


@pytest.mark.slow
def test_update_refits_the_orientation_where_the_new_rows_measure_it(kr500, tmp_path):
    """OLD fitted position and orientation; the robot is re-mastered and its probe mounted
    again, turned: 30 rows with orientations give a model that keeps ``rotation_error`` and
    predicts the new orientation error (OLD's is off by the probe's turn), with the probe's turn
    among what moved; the same rows without orientations give a model without that output."""
    from postproc.model.training.card import arm_metadata

    sim = SimulatedRobot(kr500, seed=4)
    poses, errors, turns = _oriented_campaign(sim, 300, 1)
    model = HybridModel(kr500, **SETTINGS).fit(poses, errors, previous_poses(poses), rotation_errors=turns)
    assert model.orientation
    path = tmp_path / "old.onnx"
    model.export_onnx(path, identified=model.describe(), **arm_metadata(kr500))
    old = read_old_model(path, kr500)
    assert old.lever == pytest.approx(model.kinematic_.lever_, rel=1e-3)

    sim = _changed(sim)
    c = sim.chain
    sim.chain = Chain(c.placements, c.axes, c.end @ small_transform(TOOL_TURN_RAD, np.zeros(3)), c.base)
    new_poses, new_errors, new_turns = _oriented_campaign(sim, 30, 7)
    held, held_errors, held_turns = _oriented_campaign(sim, 200, 8)
    update = update_model(old, kr500, new_poses, new_errors, previous_poses(new_poses), rotation_errors=new_turns)
    assert update.model.orientation
    prev = previous_poses(held)
    before = _mean(held_turns, model.predict_rotation(held, prev))
    after = _mean(held_turns, update.model.predict_rotation(held, prev))
    probe_turn = float(np.degrees(np.linalg.norm(TOOL_TURN_RAD)))
    assert before > 0.6 * probe_turn and after < 0.15 * before  # deg
    assert _mean(held_errors, update.model.predict(held, prev)) < 0.15 * _mean(held_errors, model.predict(held, prev))
    moved = {p["name"] for p in update.moved}
    assert {"tool_rotation.rx", "tool_rotation.ry", "tool_rotation.rz"} & moved
    assert "tool_rotation" in update.card()["groups"]
    # the exported graph keeps the output and gives the same numbers
    out = update.model.export_onnx(tmp_path / "new.onnx", name="new")
    graph = load_model(out)
    assert graph.has_rotation
    got = graph.predict(held, prev, rotation=True)[-1]
    assert np.allclose(got, update.model.predict_rotation(held, prev), atol=2e-4)
    # without orientations in the new rows: position only, no rotation output
    plain = update_model(old, kr500, new_poses, new_errors, previous_poses(new_poses))
    assert not plain.model.orientation and "tool_rotation" not in plain.card()["groups"]


def test_update_refits_the_placements_where_the_new_rows_ask_for_it(kr500, old, monkeypatch):
    """A robot whose geometry moved (A3's frame shifted 0.4 mm and turned 0.4 mrad, as another
    joint region's effective geometry does): the GCV on the 30 new rows chooses to re-fit the
    joint placements, and the held-out error is well below the 15-parameter update's."""
    from postproc.model.training import update as module

    path, _ = old
    sim = _changed(SimulatedRobot(kr500, seed=3))
    c = sim.chain
    placements = c.placements.copy()
    placements[2] = placements[2] @ small_transform(np.array([0.0004, 0.0, -0.0003]), np.array([0.4, 0.0, -0.3]))
    sim.chain = Chain(placements, c.axes, c.end, c.base)
    poses, errors = _campaign(sim, 30, 7)
    held, held_errors = _campaign(sim, 300, 8)
    prev = previous_poses(held)
    auto = update_model(read_old_model(path, kr500), kr500, poses, errors, previous_poses(poses))
    monkeypatch.setattr(module, "REGION_FACTORS", (0.0,))
    plain = update_model(read_old_model(path, kr500), kr500, poses, errors, previous_poses(poses))
    assert plain.region is None and auto.region["chosen"] > 0
    assert min(g for g in auto.region["gcv"][1:]) < module.REGION_GAIN * auto.region["gcv"][0]
    assert "placement" in auto.card()["groups"]
    after, before = _mean(held_errors, auto.model.predict(held, prev)), _mean(held_errors, plain.model.predict(held, prev))
    assert after < 0.7 * before

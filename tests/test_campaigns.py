"""Several measurement campaigns in one fit (``postproc train a.csv c.csv``, a ``campaign`` column).

One simulated KR 500 is measured twice: campaign A (80 rows, Y < 0) in the robot base frame,
campaign C (80 rows, Y > 0) by a tracker set up elsewhere (its points turned by ~1 rad and
shifted by metres). Each campaign gets its own tracker → base frame inside the identification,
the robot's parameters shared: the model of both must be as good, at fresh targets over both
regions, as a model of the same 160 rows measured in one frame; one file holding both set-ups
without naming them is refused with what to do (P518), not "register them".
"""
from __future__ import annotations

import numpy as np
import pytest

from postproc.calibration.planning import latin_hypercube
from postproc.calibration.simulator import SimulatedRobot
from postproc.cli import main
from postproc.core.frames import small_transform
from postproc.core.registration import register_measurements
from postproc.measurements.csv import measurement_csv, read_measurements
from postproc.model.compensator import load_model
from postproc.model.training.features import previous_poses
from postproc.model.training.hybrid import HybridModel
from postproc.robot.description import load_description

TRACKER = small_transform(np.array([0.3, -0.2, 1.0]), np.array([2500.0, -800.0, 300.0]))  # base → tracker
TRAIN = ["--method", "kinematic", "--val-fraction", "0", "--seed", "0"]
N = 80  # rows per campaign


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    kr500 = load_description()
    sim = SimulatedRobot(kr500, seed=3)
    pa = latin_hypercube(N, box=(1600, 2300, -600, 0, 600, 1400), seed=1)
    pc = latin_hypercube(N, box=(1600, 2300, 0, 600, 600, 1400), seed=2)
    ma, mc = sim.measure(pa, rng_seed=1), sim.measure(pc, rng_seed=2)
    mc_tracker = mc @ TRACKER[:3, :3].T + TRACKER[:3, 3]
    folder = tmp_path_factory.mktemp("campaigns")
    a, c = folder / "a.csv", folder / "c.csv"
    a.write_text(measurement_csv(pa, ma, metadata={"frame": "base"}))
    c.write_text(measurement_csv(pc, mc_tracker, metadata={"frame": "tracker"}))
    both = np.r_[pa, pc], np.r_[ma, mc_tracker]
    unnamed, named = folder / "both.csv", folder / "named.csv"
    unnamed.write_text(measurement_csv(*both, metadata={"frame": "tracker"}))
    named.write_text(measurement_csv(*both, metadata={"frame": "tracker"})
                     .replace("z_meas\n", "z_meas,campaign\n", 1))
    lines = named.read_text().splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith("x,"))
    lines[head + 1:] = [f"{line},{'day1' if i < len(pa) else 'day2'}" for i, line in enumerate(lines[head + 1:])]
    named.write_text("\n".join(lines) + "\n")
    targets = latin_hypercube(150, box=(1650, 2250, -550, 550, 650, 1350), seed=9)
    # the reference: the same rows measured in one frame (the base), one campaign
    reference = HybridModel(kr500, residual="none", seed=0).fit(both[0], both[0][:, :3] - np.r_[ma, mc],
                                                                 previous_poses(both[0]))
    return {"sim": sim, "a": a, "c": c, "unnamed": unnamed, "named": named, "targets": targets,
            "true": sim.true_error(targets), "reference": reference, "folder": folder}


def _held_out(scene, predicted: np.ndarray, rigid: bool = False) -> float:
    """Mean |E − Ê| mm at the fresh targets (``rigid``: after the rigid fit of the model's
    positions to the true ones, for a model in a registered frame)."""
    targets, true = scene["targets"], scene["true"]
    if not rigid:
        return float(np.linalg.norm(true - predicted, axis=1).mean())
    positions, actual = targets[:, :3] - predicted, targets[:, :3] - true
    moved = register_measurements(actual, positions, np.ones(len(targets), bool))[0]  # (the model's onto the true)
    return float(np.linalg.norm(actual - moved, axis=1).mean())


def test_one_file_with_two_set_ups_is_refused_with_what_to_do(scene, capsys):
    out = scene["folder"] / "refused.onnx"
    assert main(["train", str(scene["unnamed"]), "--register", "-o", str(out), *TRAIN]) == 2
    err = capsys.readouterr().err
    assert "P518" in err and "do not fit one tracker frame" in err and "campaign" in err
    assert "register them" not in err  # (--register was given)
    # where the set-ups meet: A's N rows are lines 3…N + 2 (after '# frame:' and the header)
    assert f"lines up to {N + 2} and from {N + 3}" in err
    assert not out.exists()


def test_a_file_whose_rows_fit_two_frames_far_better_says_so(scene, capsys):
    """Two set-ups 20 mm and 2 mrad apart in one file: errors a robot could make (not refused),
    but two frames fit them far better than one: train says where, and how to name them."""
    lines = scene["unnamed"].read_text().splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith("x,"))
    data = read_measurements(scene["unnamed"])
    measured = data.measured.copy()
    measured[N:] = (data.measured[N:] - TRACKER[:3, 3]) @ TRACKER[:3, :3]  # C back in the base frame
    near = small_transform(np.array([0.002, 0.0, -0.001]), np.array([20.0, -5.0, 3.0]))
    measured[N:] = measured[N:] @ near[:3, :3].T + near[:3, 3]
    mild = scene["folder"] / "mild.csv"
    mild.write_text(measurement_csv(data.poses, measured, metadata={"frame": "tracker"}))
    out = scene["folder"] / "mild.onnx"  # (a small network: the finding is the data's, before any fit)
    assert main(["train", str(mild), "--register", "-o", str(out), "--method", "plain", "--hidden", "4",
                 "--epochs", "3", "--val-fraction", "0"]) == 0
    err = capsys.readouterr().err
    assert f"fit two tracker frames far better than one (lines up to {N + 2} and from {N + 3}" in err
    assert head == 1


def test_two_files_are_two_campaigns_in_one_fit(scene, capsys):
    out = scene["folder"] / "two.onnx"
    assert main(["train", str(scene["a"]), str(scene["c"]), "--register", "-o", str(out), *TRAIN]) == 0
    printed = capsys.readouterr().out
    assert "campaign  a:" in printed and "campaign  c:" in printed
    model = load_model(out)
    targets = scene["targets"]
    reference = _held_out(scene, scene["reference"].predict(targets, previous_poses(targets)))
    mine = _held_out(scene, model.predict(targets, previous_poses(targets)))
    # in the base frame (campaign a's: it is in the base), as good as one campaign of the same rows
    assert reference < 0.05
    assert mine < 1.5 * reference + 0.01, (mine, reference)
    card = model.metadata["campaigns"]
    assert [c["name"] for c in card] == ["a", "c"] and [c["rows"] for c in card] == [N, N]
    assert "registration" not in card[0] and card[0]["frame"]["reference"]
    c = card[1]
    # the registration found the tracker's frame (its inverse: tracker → base), the fit refined it, with a std
    turn = np.radians(c["registration"]["rotation_deg"])
    assert np.allclose(turn, -np.array([0.3, -0.2, 1.0]) @ small_transform(np.array([0.3, -0.2, 1.0]),
                                                                               np.zeros(3))[:3, :3], atol=2e-3)
    assert not c["frame"]["reference"] and all(s > 0 for s in c["frame"]["offset_std_mm"])
    assert max(abs(v) for v in c["frame"]["offset_mm"]) < 5.0
    capsys.readouterr()
    assert main(["model", "info", str(out)]) == 0
    assert f"campaigns: 2 in one fit, each its own frame, tool and zero offsets: a ({N} rows; the model's frame), c" \
        in capsys.readouterr().out


def test_a_campaign_column_names_the_set_ups(scene):
    data = read_measurements(scene["named"])
    assert list(dict.fromkeys(data.campaigns)) == ["day1", "day2"]
    out = scene["folder"] / "named.onnx"
    assert main(["train", str(scene["named"]), "--register", "-o", str(out), *TRAIN]) == 0
    model = load_model(out)
    assert [c["name"] for c in model.metadata["campaigns"]] == ["day1", "day2"]
    targets = scene["targets"]
    # both campaigns registered (the model's frame is day1's registration): scored after a rigid fit
    reference = _held_out(scene, scene["reference"].predict(targets, previous_poses(targets)), rigid=True)
    mine = _held_out(scene, model.predict(targets, previous_poses(targets)), rigid=True)
    assert mine < 1.5 * reference + 0.01, (mine, reference)


def test_without_campaigns_the_same_rows_fit_badly(scene):
    """The wall the campaigns remove: each set-up registered alone, then fitted as one frame."""
    kr500 = load_description()
    data = read_measurements(scene["named"])
    day = data.campaigns == "day2"
    measured = data.measured.copy()
    for mask in (day, ~day):
        measured[mask] = register_measurements(data.poses[mask, :3], data.measured[mask], np.ones(mask.sum(), bool))[0]
    poses = data.poses
    model = HybridModel(kr500, residual="none", seed=0).fit(poses, poses[:, :3] - measured, previous_poses(poses))
    targets = scene["targets"]
    one_frame = _held_out(scene, model.predict(targets, previous_poses(targets)), rigid=True)
    campaigns = HybridModel(kr500, residual="none", seed=0).fit(poses, poses[:, :3] - measured, previous_poses(poses),
                                                                campaigns=day.astype(int))
    assert _held_out(scene, campaigns.predict(targets, previous_poses(targets)), rigid=True) < one_frame / 4


@pytest.mark.parametrize("option", [["--method", "gpso"], ["--method", "dnn-joints"], ["--update", "old.onnx"]])
def test_what_cannot_take_several_campaigns_says_so(scene, capsys, option):
    """A pose-only network, dnn-joints (no identification: no frames to fit) and --update (one new
    campaign) refuse several campaigns (P519) instead of mixing their frames."""
    out = scene["folder"] / "several.onnx"
    option = [str(scene["folder"] / v) if v.endswith(".onnx") else v for v in option]
    assert main(["train", str(scene["a"]), str(scene["c"]), "--register", "-o", str(out), *option]) == 2
    err = capsys.readouterr().err
    assert "P519" in err and "2 campaigns (a, c)" in err
    assert not out.exists()


def _drift(points: np.ndarray, amplitude: float, phase: float) -> np.ndarray:
    """A day's error no frame, tool or zero offset explains (the robot warmed, a link settled):
    a smooth field of ``amplitude`` mm over the workspace."""
    u = points / 300.0
    return amplitude * np.c_[np.sin(u[:, 0] + phase), np.cos(u[:, 1] - phase), np.sin(u[:, 2] + 2 * phase)]


def test_error_std_takes_another_day_s_spread_from_the_campaigns(scene, capsys):
    """Two days that differ by more than a frame: train measures what another day adds (each
    campaign predicted by the model of the other, after its own rigid fit), error_std takes it,
    and its 2σ band covers a third day's residuals; with one day train says it cannot tell."""
    sim, folder = scene["sim"], scene["folder"]
    pa = latin_hypercube(N, box=(1600, 2300, -600, 600, 600, 1400), seed=21)
    pc = latin_hypercube(N, box=(1600, 2300, -600, 600, 600, 1400), seed=22)
    ma = sim.measure(pa, rng_seed=21) + _drift(pa[:, :3], 0.15, 0.0)
    mc = sim.measure(pc, rng_seed=22) + _drift(pc[:, :3], 0.15, 1.3)
    day1, day2 = folder / "day1.csv", folder / "day2.csv"
    day1.write_text(measurement_csv(pa, ma, metadata={"frame": "base"}))
    day2.write_text(measurement_csv(pc, mc, metadata={"frame": "base"}))
    out = folder / "days.onnx"
    assert main(["train", str(day1), str(day2), "-o", str(out), *TRAIN]) == 0
    assert "another day's spread" in capsys.readouterr().out
    model = load_model(out)
    spread = model.metadata["uncertainty"]
    assert spread["other_days_std_mm"] == pytest.approx(spread["residual_std_mm"])  # (the larger one)
    # a third day, scored after its own rigid fit: its residuals inside the 2σ band
    targets = latin_hypercube(150, box=(1650, 2250, -550, 550, 650, 1350), seed=23)
    actual = sim.actual_positions(targets) - _drift(targets[:, :3], 0.15, 2.6)
    predicted, std = model.predict(targets, previous_poses(targets), std=True)
    positions = targets[:, :3] - predicted
    moved = register_measurements(actual, positions, np.ones(len(targets), bool))[0]
    residual = np.abs(actual - moved)
    cover = float((residual <= 2 * std.reshape(-1, 1)).mean())
    assert cover >= 0.9, cover
    # the training rows' residual alone is too narrow a band (its std per coordinate: mean |E − Ê| / 1.6,
    # as for a 3-D Gaussian)
    own = model.metadata["accuracy"]["train_mean_mm"] / 1.6
    assert spread["other_days_std_mm"] > 1.5 * own
    assert float((residual <= 2 * own).mean()) < 0.9
    # one day: train says its error_std is of that set-up only
    assert main(["train", str(day1), "-o", str(folder / "day1.onnx"), *TRAIN]) == 0
    assert "one campaign cannot tell what another day adds" in capsys.readouterr().out


def test_campaigns_each_at_one_load_are_said_one_at_two_loads_is_not(scene, capsys):
    """A campaign's own frame and zero offsets take up part of what its load does: with each
    campaign at one load train says so; one campaign at two loads fixes what loads do."""
    sim, folder = scene["sim"], scene["folder"]
    pa = latin_hypercube(N, box=(1600, 2300, -600, 600, 600, 1400), seed=31)
    pc = latin_hypercube(N, box=(1600, 2300, -600, 600, 600, 1400), seed=32)
    heavy = np.tile([300.0, 220.0, 0.0, 40.0], (N, 1))
    empty = np.zeros((N, 4))

    def write(path, poses, loads, seed):
        measured = sim.measure(poses, rng_seed=seed, loads=loads)
        columns = dict(zip(("load_mass", "load_cx", "load_cy", "load_cz"), loads.T))
        path.write_text(measurement_csv(poses, measured, extra=columns, metadata={"frame": "base"}))

    write(folder / "empty.csv", pa, empty, 31)
    write(folder / "heavy.csv", pc, heavy, 32)
    out = folder / "one_load_each.onnx"
    assert main(["train", str(folder / "empty.csv"), str(folder / "heavy.csv"), "-o", str(out), *TRAIN]) == 0
    said = "each campaign was measured at one load (empty 0 kg, heavy 300 kg)"
    assert said in capsys.readouterr().err and load_model(out).takes_load
    both = np.where(np.arange(N)[:, None] % 2 == 0, empty, heavy)
    write(folder / "both.csv", pa, both, 33)
    assert main(["train", str(folder / "both.csv"), str(folder / "heavy.csv"), "-o", str(out), *TRAIN]) == 0
    assert "each campaign was measured at one load" not in capsys.readouterr().err

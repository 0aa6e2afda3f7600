"""Per-target positional std of an identified kinematic model (training/uncertainty.py):
calibrated on held-out simulated measurements, larger where the data did not reach."""
import numpy as np
import pytest

pytest.importorskip("torch")

from postproc.calibration.planning import latin_hypercube  # noqa: E402
from postproc.robot.description import load_description  # noqa: E402
from postproc.calibration.simulator import SimulatedRobot  # noqa: E402
import torch  # noqa: E402

from postproc.model.training.features import inside_ranges, previous_poses  # noqa: E402
from postproc.model.training.kinematic import KinematicModel  # noqa: E402
from postproc.model.training.uncertainty import MAX_STD_FACTOR, parameter_covariance, position_std  # noqa: E402


@pytest.fixture(scope="module")
def fitted():
    d = load_description()
    sim = SimulatedRobot(d)
    train = latin_hypercube(200, seed=1)
    errors = train[:, :3] - sim.measure(train, rng_seed=0)
    return sim, KinematicModel(d, ripple=[]).fit(train, errors, previous_poses(train))


def test_two_sigma_covers_90_to_98_percent_of_held_out_residuals(fitted):
    sim, km = fitted
    held = latin_hypercube(300, seed=5)
    residual = held[:, :3] - sim.measure(held, rng_seed=1) - km.predict(held, previous_poses(held))
    std = position_std(km, held, previous_poses(held))
    inside = np.abs(residual) <= 2.0 * std.per_axis
    assert 0.90 <= inside.mean() <= 0.98
    # the unexplained part alone (σ) or the model part alone would not be calibrated the same way
    cov = parameter_covariance(km)
    assert 0 < std.model.mean() < np.sqrt(cov.sigma2)
    assert (np.abs(residual) <= 2.0 * std.model[:, None]).mean() < 0.6
    assert 20 < cov.p_eff < len(km.theta_)


def test_model_std_grows_outside_the_training_box(fitted):
    _, km = fitted
    inside = latin_hypercube(100, box=(1800, 2200, -400, 400, 600, 1200), seed=3)
    outside = latin_hypercube(100, box=(1100, 1400, -1500, -1200, 1500, 1800), seed=3)
    s_in, s_out = position_std(km, inside).model, position_std(km, outside).model
    assert np.median(s_out) > 3 * np.median(s_in)


# --------------------------------------------------------------------------- the exported error_std


@pytest.fixture(scope="module")
def exported(fitted, tmp_path_factory):
    """The identified arm as a contract graph with error_std (a hybrid model without networks,
    one gear-ripple order, so the ripple terms' uncertainty is in the graph too)."""
    from postproc.model.training.hybrid import HybridModel

    sim, _ = fitted
    train = latin_hypercube(200, seed=1)
    hm = HybridModel(load_description(), residual="none", kinematic={"ripple": [(0, 36)]}).fit(
        train, train[:, :3] - sim.measure(train, rng_seed=0), previous_poses(train))
    from postproc.model.training.card import arm_metadata

    card = {"identified": {**hm.describe(), "identifiability": hm.kinematic_.identifiability()}}  # (as train's)
    path = hm.export_onnx(tmp_path_factory.mktemp("std") / "std.onnx", name="std", **arm_metadata(load_description()),
                          **card)
    return sim, hm, load_model(path)


from postproc.model.compensator import load_model  # noqa: E402
from postproc.settings import Settings


def test_exported_error_std_is_position_std_and_calibrated(exported):
    sim, hm, model = exported
    assert model.has_std and model.max_std_mm == pytest.approx(MAX_STD_FACTOR * np.sqrt(parameter_covariance(hm.kinematic_).sigma2),
                                                              rel=1e-5)
    held = latin_hypercube(300, seed=5)
    prev = previous_poses(held)
    error, std = model.predict(held, prev, std=True)
    ref = position_std(hm.kinematic_, held, prev)
    # outside the trained joint ranges the graph leaves the ripple terms out, and their uncertainty,
    # and adds what they explain at the training rows (the card's learned_std_mm): it does not know
    # that part there
    inside = inside_ranges(hm.kinematic_.ik_(torch.as_tensor(held)), hm.module_.joint_range).numpy() > 0
    assert 0 < (~inside).sum() < 0.1 * len(held)
    np.testing.assert_allclose(std[inside], ref.total[inside], rtol=1e-5)  # float32 of the same figure
    learned = model.metadata["uncertainty"]["learned_std_mm"] ** 2
    assert learned == pytest.approx(hm.learned_var_, rel=1e-4) and learned > 0
    sigma2 = parameter_covariance(hm.kinematic_).sigma2
    assert (std[~inside] ** 2 <= (ref.total[~inside] ** 2 + learned) * (1 + 1e-3)).all()  # (float32, the card rounds)
    assert (std[~inside] ** 2 >= (sigma2 + learned) * (1 - 1e-3)).all()
    assert np.ptp(std) > 0.05 * std.mean()  # it varies over space
    np.testing.assert_array_equal(error, model.predict(held, prev))  # asked for or not, the same error
    np.testing.assert_allclose(error, hm.predict(held, prev), atol=1e-3)  # (float32 poses in the graph)
    residual = held[:, :3] - sim.measure(held, rng_seed=1) - error
    assert 0.90 <= (np.abs(residual) <= 2.0 * std[:, None]).mean() <= 0.98
    # another TCP on the flange: its own lever arm (the identified tool offset is more uncertain)
    other = np.tile([[0.0, 0.0, 400.0, 0.0, 0.0, 0.0]], (len(held), 1))
    _, std_tool = model.predict(held, prev, tool=other, std=True)
    assert np.isfinite(std_tool).all() and not np.allclose(std_tool, std, rtol=1e-3)


def test_compensate_and_check_warn_where_the_std_exceeds_the_bound(exported):
    from postproc.compensation.check import check_program
    from postproc.compensation.api import compensate_text
    from postproc.core.diagnostics import PostprocError
    from postproc.programs.io import parse_program_text

    _, _, model = exported
    inside = latin_hypercube(4, box=(1800, 2200, -300, 300, 700, 1100), seed=2)
    far = np.array([[2400.0, -1500.0, 100.0, 0.0, 90.0, 0.0]])  # low and aside: where the data did not reach
    poses = np.r_[inside[:2], far, inside[2:]]
    text = "x,y,z,a,b,c\n" + "".join(",".join(f"{v:.3f}" for v in p) + "\n" for p in poses)
    program = parse_program_text(text, "p.csv")
    # each target's std as the rule sees it (message), all listed under a bound below every one
    listed = [d for d in check_program(program, model, Settings().override(max_std_mm=1e-6)) if d.code == "P336"]
    std = np.array([float(d.message.split(" is ")[1].split(" mm")[0]) for d in sorted(listed, key=lambda d: d.line)])
    assert len(std) == len(poses) and std[2] > model.max_std_mm > std[[0, 1, 3, 4]].max()
    out, report = compensate_text(text, model, name="p.csv")
    found = [d for d in report.warnings if d.code == "P336"]
    assert [(d.path, d.line) for d in found] == [("p.csv", 4)] and "std" in found[0].message
    assert out != text  # a warning: every target compensated
    # under --strict a refusal (the targets inside the data: no P301 first)
    plain = "x,y,z,a,b,c\n" + "".join(",".join(f"{v:.3f}" for v in p) + "\n" for p in inside)
    assert compensate_text(plain, model, name="p.csv", strict=True)[1].compensated == len(inside)
    with pytest.raises(PostprocError) as exc:
        compensate_text(plain, model, name="p.csv", strict=True, max_std_mm=float(std.min()) / 2)
    assert exc.value.diagnostic().code == "P336"
    # --max-std: the caller's bound wins; check finds the same
    codes = [d.code for d in check_program(program, model, Settings().override(max_std_mm=float(std.min()) / 2))]
    assert codes.count("P336") == len(poses)
    assert "P336" not in [d.code for d in check_program(program, model, Settings().override(max_std_mm=float(std.max()) * 2))]
    with pytest.raises(PostprocError):
        compensate_text(text, model, name="p.csv", max_std_mm=float("nan"))


def test_models_without_error_std_are_not_checked(tmp_path):
    from postproc.testing.models import affine_model

    from postproc.compensation.api import compensate_text

    model = load_model(affine_model(tmp_path / "m.onnx", gain=np.eye(3) * 1e-3))
    assert not model.has_std and model.max_std_mm is None
    _, report = compensate_text("x,y,z,a,b,c\n2000,0,900,0,90,0\n", model, name="p.csv", max_std_mm=1e-9)
    assert not [d for d in report.warnings if d.code == "P336"]


def test_report_and_certificate_show_the_uncertainty_and_what_the_data_could_not_separate(exported, tmp_path):
    import json

    from postproc.cli import main

    sim, hm, model = exported
    d = tmp_path
    assert main(["plan", "--iso9283", "--cycles", "3", "-o", str(d / "iso.csv")]) == 0
    assert main(["measure", str(d / "iso.csv"), "-o", str(d / "before.csv")]) == 0
    assert main(["report", "--iso9283", str(d / "before.csv"), "--model", str(model.path), "-o", str(d / "cert")]) == 0
    md = (d / "cert" / "certificate.md").read_text()
    ident = hm.kinematic_.identifiability()
    assert f"Numerical rank {ident['rank']} of {ident['parameters']} parameters; condition number" in md
    assert " + ".join(ident["unseparated"][0]) in md  # e.g. a zero offset and a placement about its axis
    # the moved parameters with their std, in the card's units (the simulated gears' lost motion:
    # backlash.A1 ... in deg), every listed one by more than 3σ; those the data cannot determine
    # alone (a base shift and A1's placement shift: one effect) counted, not listed
    rows = [line.split(" | ") for line in md.splitlines() if line.startswith("| backlash.")]
    assert len(rows) >= 3 and all(r[1].endswith(" deg") and abs(float(r[1].split()[0])) > 3 * float(r[2].split()[0])
                                  for r in rows)
    alone = sum(len(v) for v in ident["undetermined"].values())
    assert 0 < alone < ident["parameters"] and f"{alone} of them the data does not determine alone" in md
    assert "| base.x |" not in md and "error_std" in md
    # the accuracy report states the std at its poses and how many of their residuals it covers
    from postproc.measurements.csv import write_measurements

    held = latin_hypercube(150, seed=9)
    write_measurements(d / "held.csv", held, sim.measure(held, rng_seed=3))
    assert main(["report", str(d / "held.csv"), "--model", str(model.path), "-o", str(d / "rep")]) == 0
    sure = json.loads((d / "rep" / "summary.json").read_text())["uncertainty"]
    _, std = model.predict(held, previous_poses(held), std=True)
    assert sure["error_std_mm"]["mean"] == pytest.approx(std.mean(), rel=1e-5)
    assert 0.85 < sure["two_sigma_coverage"] <= 1.0 and sure["max_std_mm"] == model.max_std_mm
    report = (d / "rep" / "report.md").read_text()
    assert "How sure the model is" in report and "Numerical rank" in report


# --------------------------------------------------------------------------- data with joint angles


def _exported_std(hm, path):
    from postproc.model.training.card import arm_metadata

    return load_model(hm.export_onnx(path, name="std", **arm_metadata(hm.description)))


def test_a_planners_joint_angles_do_not_inflate_the_exported_std(fitted, tmp_path):
    """Rows with the controller's joint angles as a planner's numerical IK logs them (0.005° off
    the pose's exact IK, ~0.1 mm at the TCP, as IPA's): the fit evaluates the arm at those, the
    graph at the pose's IK, so that miss is no error a compensation leaves. The std is of what
    the graph leaves: calibrated, and the same as without the angles."""
    from postproc.model.training.hybrid import HybridModel

    sim, km = fitted
    train = latin_hypercube(200, seed=1)
    errors = train[:, :3] - sim.measure(train, rng_seed=0)
    q = sim.joint_angles(train) + np.random.default_rng(0).normal(0.0, 0.005, (len(train), 6))
    hm = HybridModel(load_description(), residual="none", kinematic={"ripple": []}).fit(
        train, errors, previous_poses(train), q_deg=q)
    sigma = np.sqrt(parameter_covariance(km).sigma2)  # (fitted without the angles)
    # the fit's own residual carries the planner's miss (what the std rested on before)
    assert np.sqrt(parameter_covariance(hm.kinematic_).sigma2) > 3 * sigma
    model = _exported_std(hm, tmp_path / "q.onnx")
    assert model.max_std_mm == pytest.approx(MAX_STD_FACTOR * sigma, rel=0.05)
    held = latin_hypercube(300, seed=5)
    error, std = model.predict(held, previous_poses(held), std=True)
    residual = held[:, :3] - sim.measure(held, rng_seed=1) - error
    assert 0.90 <= (np.abs(residual) <= 2.0 * std[:, None]).mean() <= 0.98


def test_two_sigma_covers_90_to_98_percent_of_held_out_ipa_rows(tmp_path):
    """The real UR10 + tracker excerpt (IPA Series C, its planner's joint angles): registered and
    identified on 80 % of the rows (as `train`), the exported std scored on the other 20 %."""
    from helpers import REPO

    from postproc.measurements.datasets import read_ipa
    from postproc.core.registration import register_measurements
    from postproc.core.resources import model_path
    from postproc.model.training.data import split_indices
    from postproc.model.training.hybrid import HybridModel

    s = read_ipa(REPO / "samples" / "ipa" / "series_c_excerpt.csv")
    train, held = split_indices(len(s), 0.2, 0)
    rows = np.isin(np.arange(len(s)), train)
    measured, _, _ = register_measurements(s.commanded[:, :3], s.measured, rows)
    errors = s.commanded[:, :3] - measured
    hm = HybridModel(load_description(model_path("ur10.toml")), residual="none", kinematic={"ripple": []}).fit(
        s.commanded[train], errors[train], q_deg=s.joints[train])
    model = _exported_std(hm, tmp_path / "ipa.onnx")
    error, std = model.predict(s.commanded[held], joints=s.joints[held], std=True)
    inside = np.abs(errors[held] - error) <= 2.0 * std[:, None]
    assert len(held) == 30 and 0.90 <= inside.mean() <= 0.98


def test_one_wrist_configurations_data_keeps_its_compliance_and_the_flipped_wrists_band_holds(tmp_path):
    """Data of one wrist configuration cannot tell the compliance from none: the blocked
    selection keeps it (blocked.HARM_SE), and in the flipped wrist the model lands nearer and
    its error_std covers what it leaves (benchmarks/transfer.py --parts flipped)."""
    from postproc.calibration.planning import plan_configurations
    from postproc.model.training.card import arm_metadata
    from postproc.model.training.hybrid import HybridModel
    from postproc.robot import configuration

    sim = SimulatedRobot()
    poses = latin_hypercube(300, box=(1800, 2200, -400, 400, 700, 1100), seed=5)
    config, ok = plan_configurations(sim.robot, poses, "home")
    poses, config = poses[ok], config[ok]
    q = sim.joint_angles(poses, config)
    hm = HybridModel(load_description(), seed=0).fit(poses, poses[:, :3] - sim.measure(poses, rng_seed=0, q_deg=q),
                                                     previous_poses(poses), q)
    assert "compliance" not in hm.kinematic_.selection_["dropped"]
    model = load_model(hm.export_onnx(tmp_path / "one_wrist.onnx", name="one-wrist", **arm_metadata(load_description())))
    targets = latin_hypercube(150, box=(1850, 2150, -300, 300, 750, 1050), seed=11)
    home, ok = plan_configurations(sim.robot, targets, "home")
    targets, home = targets[ok], home[ok]
    q_t, found = configuration.stated_joints(sim.robot, targets, home[:, 0] ^ 4, np.full(len(targets), -1))
    p, q_t = targets[found][:60], q_t[found][:60]
    true = p[:, :3] - sim.actual_positions(p, q_deg=q_t)
    predicted, std = model.predict(p, previous_poses(p), joints=q_t, std=True)
    residual = true - predicted
    assert np.linalg.norm(residual, axis=1).mean() < 0.4 * np.linalg.norm(true, axis=1).mean()
    assert (np.abs(residual) <= 2.0 * std.reshape(-1, 1)).mean() >= 0.9

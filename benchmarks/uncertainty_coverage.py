"""Is the per-target std calibrated? 2σ coverage of held-out residuals, simulated and real.

    python benchmarks/uncertainty_coverage.py [--data DIR] [--part sim|ipa|onnx|all]

sim: the default simulated KR500 (measurement noise seed 0 / 1), kinematic identification
     (pose + visiting order, no ripple search and with it) on n Latin-hypercube poses (seed 1),
     300 held-out poses (seed 5).
ipa: IPA Series C (UR10 + laser tracker, $POSTPROC_IPA_DATA, default
     /work/shared/datasets/ipa-robot-accuracy): tracker → base registered on the training
     rows (split_indices(n, 0.2, 0), as `postproc train`), identified on models/ur10.toml
     (pose only: the order of a random-pose series is not a motion the data documents) with
     the data's joint angles. σ from the residual the model leaves at its training rows at
     the IK of their poses (as the graph runs; ``parameter_covariance(km, residual)``); beside
     it, for comparison, σ from ``train_residual_`` (at the data's q1..q6, which carries the
     planner's IK miss: what the std was before).

onnx: the exported graph's output ``error_std`` (HybridModel without residual networks, ripple
     search, exported and run in onnxruntime): its 2σ coverage on the held-out simulated rows
     (n = 300) and IPA Series C validation rows, and what asking for it costs: one
     onnxruntime run over 8192 poses with the outputs compensate asks for (error, ik_joints)
     and with error_std too (ratio), and compensate on a 20000-target pose list with the
     card's --max-std (one more run at the commands) against --max-std inf (no P336 check).

Coverage = the fraction of held-out residual coordinates (X, Y, Z of E − Ê) within
2·std (training/uncertainty.position_std); 95.4 % for Gaussian residuals. Only σ and the
parameter covariance come from the training rows; the held-out rows are only scored.
--part all writes the figures to benchmarks/results/uncertainty_coverage.json (the README's).
"""
from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

from postproc.model.training.uncertainty import parameter_covariance, position_std  # noqa: E402

from _common import record  # noqa: E402  (benchmarks/ is on sys.path when a benchmark runs as a script)

DEFAULT_DATA = "/work/shared/datasets/ipa-robot-accuracy"
FIGURES: dict = {}


def coverage(residual: np.ndarray, std) -> float:
    """% of the residual coordinates [N, k] within 2·std (``PositionStd``'s per axis, [N, k] or [N])."""
    bound = std.per_axis if hasattr(std, "per_axis") else np.asarray(std).reshape(len(residual), -1)
    return round(100.0 * float((np.abs(residual) <= 2.0 * bound).mean()), 1)


def line(label: str, km, cov, residual: np.ndarray, std, seconds: float) -> str:
    return (f"{label:28s} P {len(km.theta_):3d} p_eff {cov.p_eff:5.1f}  σ {np.sqrt(cov.sigma2):.4f} mm  "
            f"model std mean {std.model.mean():.4f}  residual rms {np.sqrt((residual ** 2).mean()):.4f} mm  "
            f"2σ coverage {coverage(residual, std):.1f} %  (fit {seconds:.1f} s)")


def sim_part() -> None:
    from postproc.calibration.planning import latin_hypercube
    from postproc.robot.description import load_description
    from postproc.calibration.simulator import SimulatedRobot
    from postproc.model.training.features import previous_poses
    from postproc.model.training.kinematic import KinematicModel

    d = load_description()
    sim = SimulatedRobot(d)
    held = latin_hypercube(300, seed=5)
    e_held = held[:, :3] - sim.measure(held, rng_seed=1)
    for n in (60, 100, 300, 1000):
        for ripple in ([], "search"):
            train = latin_hypercube(n, seed=1)
            t0 = time.perf_counter()
            km = KinematicModel(d, ripple=ripple).fit(train, train[:, :3] - sim.measure(train, rng_seed=0),
                                                     previous_poses(train))
            seconds = time.perf_counter() - t0
            residual = e_held - km.predict(held, previous_poses(held))
            cov = parameter_covariance(km)  # (no joint angles in the data: the fit's residual is at the IK)
            std = position_std(km, held, previous_poses(held), cov)
            label = f"sim n={n} ripple={'search' if ripple else 'none'}"
            FIGURES.setdefault("sim", {})[f"n{n}_{'search' if ripple else 'none'}"] = coverage(residual, std)
            print(line(label, km, cov, residual, std, seconds))


def _ipa_c(data: str):
    """IPA Series C registered on its training rows (80/20 split, seed 0): (series, train rows,
    validation rows, errors E [N, 3] mm), or None where the data set is not here."""
    from postproc.measurements.datasets import read_ipa
    from postproc.core.registration import register_measurements
    from postproc.model.training.data import split_indices

    source = Path(data) / "Series_C/measurements_random_poses.csv"
    if not source.exists():
        return None
    s = read_ipa(source)
    train_idx, val_idx = split_indices(len(s), 0.2, 0)
    fit_rows = np.zeros(len(s), bool)
    fit_rows[train_idx] = True
    measured, _, _ = register_measurements(s.commanded[:, :3], s.measured, fit_rows)
    return s, train_idx, val_idx, s.commanded[:, :3] - measured


def ipa_part(data: str) -> None:
    from postproc.robot.description import load_description
    from postproc.core.resources import model_path
    from postproc.model.training.kinematic import KinematicModel

    loaded = _ipa_c(data)
    if loaded is None:
        print(f"ipa: skip, {Path(data) / 'Series_C'} not found")
        return
    s, train_idx, val_idx, errors = loaded
    d = load_description(model_path("ur10.toml"))
    import torch

    from postproc.robot.kinematics.twin import Arm

    with torch.no_grad():  # how far the nominal arm at the data's joint angles is from the pose (planner's IK)
        miss = Arm(d).frames(torch.as_tensor(np.radians(s.joints)))[2].numpy() - s.commanded[:, :3]
    FIGURES.setdefault("ipa_C", {})["joint_angle_miss"] = {"rms_mm": round(float(np.sqrt((miss**2).mean())), 3),
                                                          "max_mm": round(float(np.abs(miss).max()), 2)}
    print(f"ipa C: the nominal arm at the data's q1..q6 misses the pose by {np.sqrt((miss**2).mean()):.3f} mm rms "
          f"per coordinate (max {np.abs(miss).max():.2f} mm)")
    for ripple in ([], "search"):
        t0 = time.perf_counter()
        km = KinematicModel(d, ripple=ripple).fit(s.commanded[train_idx], errors[train_idx],
                                                 q_deg=s.joints[train_idx])
        seconds = time.perf_counter() - t0
        kept = np.delete(train_idx, km.dropped_)  # (the rows the fit kept)
        cov = parameter_covariance(km, errors[kept] - km.predict(s.commanded[kept]))  # (training rows only)
        residual = errors[val_idx] - km.predict(s.commanded[val_idx])
        std = position_std(km, s.commanded[val_idx], covariance=cov)
        label = f"ipa C n={len(train_idx)} ripple={'search' if ripple else 'none'}"
        print(line(label, km, cov, residual, std, seconds))
        before_cov = parameter_covariance(km)  # σ from the residual at the data's q1..q6
        before = position_std(km, s.commanded[val_idx], covariance=before_cov)
        FIGURES.setdefault("ipa_C", {})["search" if ripple else "none"] = {
            "coverage": coverage(residual, std), "coverage_before": coverage(residual, before),
            "sigma_mm": round(float(np.sqrt(cov.sigma2)), 4), "sigma_before_mm": round(float(np.sqrt(before_cov.sigma2)), 4),
            "residual_rms_mm": round(float(np.sqrt((residual**2).mean())), 4), "validation_rows": len(val_idx),
            # one σ for X, Y and Z: the axes' own coverage spreads around it where their residuals differ
            **{f"coverage_{axis}": coverage(residual[:, [k]], std.per_axis[:, [k]]) for k, axis in enumerate("xyz")}}
        print(f"{'':28s} (σ from the residual at the data's q1..q6: {np.sqrt(before_cov.sigma2):.4f} mm, "
              f"2σ coverage {coverage(residual, before):.1f} %)")


def _coverage(model, poses, previous, errors, joints=None) -> tuple[float, np.ndarray]:
    error, std = model.predict(poses, previous, joints=joints, std=True)
    return coverage(errors - error, std), std


def onnx_part(data: str) -> None:
    import tempfile

    from postproc.model.training.card import arm_metadata
    from postproc.compensation.api import compensate_text
    from postproc.model.contract import OUTPUT_ERROR, OUTPUT_JOINTS, OUTPUT_STD
    from postproc.model.compensator import load_model
    from postproc.calibration.planning import latin_hypercube
    from postproc.robot.description import load_description
    from postproc.calibration.simulator import SimulatedRobot
    from postproc.model.training.features import previous_poses
    from postproc.model.training.hybrid import HybridModel

    tmp = Path(tempfile.mkdtemp(prefix="uncertainty_"))
    d = load_description()
    sim = SimulatedRobot(d)
    train = latin_hypercube(300, seed=1)
    hm = HybridModel(d, residual="none").fit(train, train[:, :3] - sim.measure(train, rng_seed=0), previous_poses(train))
    model = load_model(hm.export_onnx(tmp / "sim.onnx", name="sim", **arm_metadata(d)))
    held = latin_hypercube(300, seed=5)
    cover, std = _coverage(model, held, previous_poses(held), held[:, :3] - sim.measure(held, rng_seed=1))
    FIGURES.setdefault("onnx", {})["sim"] = cover
    print(f"onnx sim n=300 P {len(hm.kinematic_.theta_)}: error_std mean {std.mean():.4f} mm (card bound "
          f"{model.max_std_mm:.4f}), 2σ coverage {cover:.1f} %")

    poses = latin_hypercube(8192, seed=7).astype(np.float32)
    nan = np.full(poses.shape, np.nan, np.float32)
    given = {"pose": poses, "previous_pose": np.r_[poses[:1], poses[:-1]]}
    feeds = {i.name: given.get(i.name, nan) for i in (*model.session.get_inputs(), *model.session.get_overridable_initializers())}  # (the others unknown: NaN)
    timings = {}
    for label, names in (("error+ik_joints", [OUTPUT_ERROR, OUTPUT_JOINTS]),
                         ("+error_std", [OUTPUT_ERROR, OUTPUT_JOINTS, OUTPUT_STD])):
        model.session.run(names, feeds)
        t0 = time.perf_counter()
        for _ in range(5):
            model.session.run(names, feeds)
        timings[label] = (time.perf_counter() - t0) / 5
    base = timings["error+ik_joints"]
    print(f"onnx run 8192 poses: error+ik_joints {1e3 * base:.1f} ms, +error_std {1e3 * timings['+error_std']:.1f} ms "
          f"(x{timings['+error_std'] / base:.2f})")
    program = latin_hypercube(20000, seed=8)
    text = "x,y,z,a,b,c\n" + "".join(",".join(f"{v:.3f}" for v in p) + "\n" for p in program)
    runs = {}
    for label, bound in (("--max-std inf", float("inf")), ("card --max-std", None)):
        compensate_text(text, model, name="p.csv", max_std_mm=bound)
        t0 = time.perf_counter()
        _, report = compensate_text(text, model, name="p.csv", max_std_mm=bound)
        runs[label] = time.perf_counter() - t0
    print(f"compensate 20000 targets: --max-std inf {runs['--max-std inf']:.2f} s, card bound "
          f"{runs['card --max-std']:.2f} s (x{runs['card --max-std'] / runs['--max-std inf']:.2f}); "
          f"P336 {sum(w.code == 'P336' for w in report.warnings)} listed")

    loaded = _ipa_c(data)
    if loaded is None:
        print(f"onnx ipa: skip, {Path(data) / 'Series_C'} not found")
        return
    from postproc.core.resources import model_path

    s, train_idx, val_idx, errors = loaded
    ur = load_description(model_path("ur10.toml"))
    hm = HybridModel(ur, residual="none").fit(s.commanded[train_idx], errors[train_idx], q_deg=s.joints[train_idx])
    model = load_model(hm.export_onnx(tmp / "ipa.onnx", name="ipa", **arm_metadata(ur)))
    cover, std = _coverage(model, s.commanded[val_idx], None, errors[val_idx], s.joints[val_idx])
    FIGURES.setdefault("onnx", {})["ipa_C"] = cover
    print(f"onnx ipa C n={len(train_idx)} P {len(hm.kinematic_.theta_)}: error_std mean {std.mean():.4f} mm, "
          f"2σ coverage {cover:.1f} % on {len(val_idx)} validation rows")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=os.environ.get("POSTPROC_IPA_DATA", DEFAULT_DATA))
    parser.add_argument("--part", choices=["sim", "ipa", "onnx", "all"], default="all")
    args = parser.parse_args()
    if args.part in ("sim", "all"):
        sim_part()
    if args.part in ("ipa", "all"):
        ipa_part(args.data)
    if args.part in ("onnx", "all"):
        onnx_part(args.data)
    if args.part == "all":
        print(f"figures: {record('uncertainty_coverage', FIGURES)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Is the per-target std calibrated? 2σ coverage of held-out residuals, simulated and real.

    python benchmarks/uncertainty_coverage.py [--data DIR] [--part sim|ipa|all]

sim: the default simulated KR500 (measurement noise seed 0 / 1), kinematic identification
     (pose + visiting order, no ripple search and with it) on n Latin-hypercube poses (seed 1),
     300 held-out poses (seed 5).
ipa: IPA Series C (UR10 + laser tracker, $POSTPROC_IPA_DATA, default
     /work/shared/datasets/ipa-robot-accuracy): tracker → base registered on the training
     rows (split_indices(n, 0.2, 0), as `postproc train`), identified on models/ur10.toml
     (pose only: the order of a random-pose series is not a motion the data documents).

Coverage = the fraction of held-out residual coordinates (X, Y, Z of E − Ê) within
2·std (training/uncertainty.position_std); 95.4 % for Gaussian residuals.
"""
from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

from postproc.training.uncertainty import parameter_covariance, position_std  # noqa: E402

DEFAULT_DATA = "/work/shared/datasets/ipa-robot-accuracy"


def line(label: str, km, residual: np.ndarray, std, seconds: float) -> str:
    cov = parameter_covariance(km)
    cover = float((np.abs(residual) <= 2.0 * std.per_axis).mean())
    return (f"{label:28s} P {len(km.theta_):3d} p_eff {cov.p_eff:5.1f}  σ {np.sqrt(cov.sigma2):.4f} mm  "
            f"model std mean {std.model.mean():.4f}  residual rms {np.sqrt((residual ** 2).mean()):.4f} mm  "
            f"2σ coverage {100 * cover:.1f} %  (fit {seconds:.1f} s)")


def sim_part() -> None:
    from postproc.planning import latin_hypercube
    from postproc.robot import load_description
    from postproc.simulator import SimulatedRobot
    from postproc.training.features import previous_poses
    from postproc.training.kinematic import KinematicModel

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
            std = position_std(km, held, previous_poses(held))
            print(line(f"sim n={n} ripple={'search' if ripple else 'none'}", km, residual, std, seconds))


def ipa_part(data: str) -> None:
    from postproc.datasets import read_ipa
    from postproc.registration import register_measurements
    from postproc.robot import load_description
    from postproc.resources import model_path
    from postproc.training.data import split_indices
    from postproc.training.kinematic import KinematicModel

    source = Path(data) / "Series_C/measurements_random_poses.csv"
    if not source.exists():
        print(f"ipa: skip, {source} not found")
        return
    s = read_ipa(source)
    train_idx, val_idx = split_indices(len(s), 0.2, 0)
    fit_rows = np.zeros(len(s), bool)
    fit_rows[train_idx] = True
    measured, _, _ = register_measurements(s.commanded[:, :3], s.measured, fit_rows)
    errors = s.commanded[:, :3] - measured
    d = load_description(model_path("ur10.toml"))
    for ripple in ([], "search"):
        t0 = time.perf_counter()
        km = KinematicModel(d, ripple=ripple).fit(s.commanded[train_idx], errors[train_idx],
                                                 q_deg=s.joints[train_idx])
        seconds = time.perf_counter() - t0
        residual = errors[val_idx] - km.predict(s.commanded[val_idx])
        std = position_std(km, s.commanded[val_idx])
        print(line(f"ipa C n={len(train_idx)} ripple={'search' if ripple else 'none'}", km, residual, std, seconds))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=os.environ.get("POSTPROC_IPA_DATA", DEFAULT_DATA))
    parser.add_argument("--part", choices=["sim", "ipa", "all"], default="all")
    args = parser.parse_args()
    if args.part in ("sim", "all"):
        sim_part()
    if args.part in ("ipa", "all"):
        ipa_part(args.data)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

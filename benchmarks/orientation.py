"""Orientation: the hybrid identification fitted on positions and orientations, on real and simulated data.

    python benchmarks/orientation.py [--part real|sim|all] [--data DIR] [--seed 101] [--out DIR]

Everything goes through the CLI (one process per command, 1 thread), as a user runs it.

* real: IPA Series C (UR10 + laser tracker with a 6-DOF probe; $POSTPROC_IPA_DATA, default
  /work/shared/datasets/ipa-robot-accuracy): `postproc import ipa --register --val-fraction 0.2
  --split-seed 0` (tracker → base and the probe's rotation on the flange fitted on the 80 %
  only; writes a_meas,b_meas,c_meas), then `postproc train --robot models/ur10.toml
  --val-fraction 0.2 --split-seed 0` (the same 20 % held out) twice: on that file ("position +
  orientation") and on it without the a_meas..c_meas columns ("position only"). On the held-out
  rows, the ONNX model run by `Compensator.predict` (pose, previous row's pose, the row's
  q1..q6): |E| and |E − Ê| (mm), the angle of the orientation error before |r| and after
  |r − r̂| (deg): mean, p95, max. Then the orientation model on Series B, D, A (transfer; each
  imported with `--register --val-fraction 0`: its own tracker registration and probe
  rotation, nothing else fitted on it): |r| before, and after its probe rotation is fitted
  again to the predicted orientations exp(r̂)·R_goal instead of R_goal (as the positions'
  rigid fit in cross_series.py), the angle of what is left.
* sim: robot seed S (default 101, an evaluation robot), `plan -n 1900 --seed 0`, `measure`
  (a 6-DOF probe: a_meas..c_meas), `train --val-fraction 0` with and without the orientation
  columns; 100 held-out targets (`plan -n 100 --seed 1000`) compensated with `--orientation`
  (the orientation model) and without (both models) and run through the simulated robot
  (`SimulatedRobot.verify`, from HOME in plan order, tracker noise): position (mm) and
  orientation (deg) error, mean / p95 / max.
"""
from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent

from _common import cli  # noqa: E402
from postproc.model.compensator import load_model  # noqa: E402
from postproc.calibration.planning import read_pose_csv  # noqa: E402
from postproc.measurements.csv import read_measurements  # noqa: E402
from postproc.model.training.features import previous_poses  # noqa: E402

DEFAULT_DATA = "/work/shared/datasets/ipa-robot-accuracy"
SERIES_C = "Series_C/measurements_random_poses.csv"
OTHERS = {"B": "Series_B/measurements_joint_configurations.csv", "D": "Series_D/measurements_iso_cubes.csv",
          "A": "Series_A/measurements_grid.csv"}
ORIENTATION = {"a_meas", "b_meas", "c_meas"}


def without_columns(src: Path, dst: Path, names: set[str]) -> Path:
    lines = src.read_text().splitlines()
    at = next(i for i, line in enumerate(lines) if line.strip() and not line.startswith("#"))
    keep = [i for i, h in enumerate(lines[at].split(",")) if h.strip() not in names]
    out = lines[:at] + [",".join(f for i, f in enumerate(line.split(",")) if i in keep) for line in lines[at:]]
    dst.write_text("\n".join(out) + "\n")
    return dst


def figures(v: np.ndarray) -> dict:
    n = np.linalg.norm(np.atleast_2d(v), axis=1) if np.ndim(v) == 2 else np.asarray(v)
    return {"mean": float(n.mean()), "p95": float(np.quantile(n, 0.95)), "max": float(n.max())}


def line(label: str, f: dict, unit: str) -> str:
    return f"{label:<52} {f['mean']:8.4f} {f['p95']:8.4f} {f['max']:8.4f}  {unit}"


def real_part(data_dir: str, work: Path) -> dict:
    csv = work / "c.csv"
    cli("import", "ipa", str(Path(data_dir) / SERIES_C), "-o", str(csv), "--register", "--val-fraction", "0.2",
        "--split-seed", "0", "-q")
    data = read_measurements(csv)
    held = data.holdout
    previous = previous_poses(data.poses)
    rotation = data.rotation_errors
    out = {"n_held_out": int(held.sum())}
    print(f"\n== real: IPA {SERIES_C}, {int((~held).sum())} training rows, {int(held.sum())} held out "
          "(import --register and train on the same split)")
    print(f"{'':<52} {'mean':>8} {'p95':>8} {'max':>8}")
    print(line("uncompensated |E|", figures(data.errors[held]), "mm"))
    print(line("uncompensated orientation |r|", figures(rotation[held]), "deg"))
    out["uncompensated"] = {"position_mm": figures(data.errors[held]), "orientation_deg": figures(rotation[held])}
    for label, src in (("position + orientation", csv),
                       ("position only", without_columns(csv, work / "c_pos.csv", ORIENTATION))):
        model_file = work / f"c_{len(out)}.onnx"
        _, seconds = cli("train", str(src), "-o", str(model_file), "--robot", str(ROOT / "models/ur10.toml"),
                         "--val-fraction", "0.2", "--split-seed", "0", "-q")
        model = load_model(model_file)
        out_ = model.predict(data.poses[held], previous[held], joints=data.joints[held], rotation=model.has_rotation)
        error, *turned = out_ if model.has_rotation else (out_,)
        row = {"position_mm": figures(data.errors[held] - error), "train_s": seconds}
        print(line(f"{label}: |E − Ê|", row["position_mm"], f"mm  (train {seconds:.0f} s)"))
        if turned:
            row["orientation_deg"] = figures(rotation[held] - turned[0])
            print(line(f"{label}: |r − r̂|", row["orientation_deg"], "deg"))
        out[label] = row
        if turned:
            out["transfer"] = transfer(model, data_dir, work)
    return out


def transfer(model, data_dir: str, work: Path) -> dict:
    """The orientation model on the other series, each with its own registration and probe rotation."""
    from scipy.spatial.transform import Rotation

    from postproc.core.frames import rotation_from_abc, rotation_vector

    out = {}
    for name, path in OTHERS.items():
        csv = work / f"{name}.csv"
        cli("import", "ipa", str(Path(data_dir) / path), "-o", str(csv), "--register", "--val-fraction", "0", "-q")
        m = read_measurements(csv)
        _, turned = model.predict(m.poses, previous_poses(m.poses), joints=m.joints, rotation=True)
        goal, measured = rotation_from_abc(m.poses[:, 3:]), rotation_from_abc(m.orientation)
        predicted = Rotation.from_rotvec(np.radians(turned)).as_matrix() @ goal
        u, _, vt = np.linalg.svd((np.swapaxes(predicted, 1, 2) @ measured).mean(axis=0))
        probe = u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt  # measured ≈ predicted · probe
        left = np.degrees(rotation_vector(measured @ probe.T @ np.swapaxes(predicted, 1, 2)))
        out[name] = {"rows": len(m), "before_deg": figures(m.rotation_errors), "after_deg": figures(left)}
        print(line(f"Series {name} ({len(m)} rows): |r| own probe fit", out[name]["before_deg"], "deg"))
        print(line(f"Series {name}: |r − r̂| probe refitted to r̂", out[name]["after_deg"], "deg"))
    return out


def sim_part(seed: int, work: Path) -> dict:
    from postproc.calibration.simulator import SimulatedRobot

    plan, test = work / "plan.csv", work / "test.csv"
    cli("plan", "-n", "1900", "--seed", "0", "-o", str(plan), "-q")
    cli("plan", "-n", "100", "--seed", "1000", "-o", str(test), "-q")
    measured = work / "measured.csv"
    cli("measure", str(plan), "-o", str(measured), "--robot-seed", str(seed), "--seed", "0", "-q")
    position_only = without_columns(measured, work / "measured_pos.csv", ORIENTATION)
    targets, _ = read_pose_csv(test)
    sim = SimulatedRobot(seed=seed)
    out = {"seed": seed}
    print(f"\n== sim: robot seed {seed}, 1900 training poses, 100 held-out targets (plan -n 100 --seed 1000), "
          "verify from HOME with tracker noise")
    print(f"{'':<52} {'mean':>8} {'p95':>8} {'max':>8}")
    for label, src, options in (("position + orientation, --orientation", measured, ["--orientation"]),
                                ("position + orientation, position only", measured, []),
                                ("position-only model", position_only, [])):
        model_file = work / f"m_{Path(src).stem}.onnx"
        seconds = 0.0
        if not model_file.exists():
            _, seconds = cli("train", str(src), "-o", str(model_file), "--val-fraction", "0", "--seed", "0", "-q")
        compensated = work / f"c_{len(out)}.csv"
        cli("compensate", str(test), "-o", str(compensated), "--model", str(model_file), "-q", *options)
        commands, _ = read_pose_csv(compensated)
        result = sim.verify(targets, commands, rng_seed=1)
        if len(out) == 1:
            before = {"position_mm": figures(result["errors_before"]),
                      "orientation_deg": figures(_angles(sim, targets, targets))}
            out["uncompensated"] = before
            print(line("uncompensated position", before["position_mm"], "mm"))
            print(line("uncompensated orientation", before["orientation_deg"], "deg"))
        row = {"position_mm": figures(result["errors_after"]), "orientation_deg": figures(_angles(sim, targets, commands)),
               "train_s": seconds}
        print(line(f"{label}: position", row["position_mm"], "mm" + (f"  (train {seconds:.0f} s)" if seconds else "")))
        print(line(f"{label}: orientation", row["orientation_deg"], "deg"))
        out[label] = row
    return out


def _angles(sim, targets: np.ndarray, commands: np.ndarray) -> np.ndarray:
    """Angle (deg) between each target's orientation and the one the robot reaches when
    commanded ``commands`` (no noise: the probe's noise is the description's)."""
    from postproc.core.frames import rotation_angle_deg

    reached = sim.measure(commands, rng_seed=2, orientation=True)
    return rotation_angle_deg(targets[:, 3:6], reached[:, 3:6])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--part", choices=["real", "sim", "all"], default="all")
    parser.add_argument("--data", default=os.environ.get("POSTPROC_IPA_DATA", DEFAULT_DATA))
    parser.add_argument("--seed", type=int, default=101)
    parser.add_argument("--out", default=None, help="folder for orientation.json (default: none written)")
    args = parser.parse_args()
    t0 = time.perf_counter()
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        if args.part in ("sim", "all"):
            results["sim"] = sim_part(args.seed, Path(tmp))
        if args.part in ("real", "all"):
            results["real"] = real_part(args.data, Path(tmp))
    print(f"\ntotal {time.perf_counter() - t0:.0f} s")
    if args.out:
        Path(args.out).mkdir(parents=True, exist_ok=True)
        (Path(args.out) / "orientation.json").write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()

"""Calibration that transfers and knows its limits (issue 28): the IPA UR10 figures and the
uncertainty's coverage, as an independent user would measure them.

    python benchmarks/transfer.py [--parts cross,campaigns,random,octant,singular,update,flipped] [--data DIR]
                                  [--seed 0] [--update-rows 30] [--update-seeds 0,1,2,3,4]

DIR is $POSTPROC_IPA_DATA, default /work/shared/datasets/ipa-robot-accuracy (not shipped). The
protocol is benchmarks/cross_series.py's (README "Transfer and re-calibration"): every series
registered to the robot base by its own rigid fit on all its rows (``postproc import ipa
--register``: here ``registration.register_measurements`` on the same rows, which the import
does); a model is the hybrid default of ``postproc train`` (seed 0, ``--robot models/ur10.toml``)
fitted on 80 % of each training series (``split_indices(n, 0.2, 0)``, the split ``train`` makes)
with the rows' joint angles and visiting order, exported to ONNX and run through
``Compensator.predict`` with each row's pose, previous pose and joint angles (what
``compensate`` does). |E − Ê| mm: mean / p95 / max.

* ``cross``: trained on A, on A+C, on C; scored on the other series, each after the rigid fit of
  its measured points to the model's predicted positions (its own tracker set-up), and — B, which
  shares C's campaign — also in the training frame (C's registration, no re-fit); the training
  series' 20 % held out ("random"). Beside each the share of residual coordinates within 2σ of
  the model's ``error_std`` there. Goals (issue 28): A → C ≤ 0.45, D ≤ 0.39, B ≤ 0.37; A+C → B,
  D ≤ 0.25; C → B / D / A ≤ 0.47 / 0.50 / 0.53, B in C's frame ≤ 0.65.
* ``campaigns``: A and C in one fit through ``train``'s own path (``training.fit`` with both
  series' raw tracker points as two measurement files — two campaigns, ``# frame: tracker``,
  ``--register``, q1..q6 — ``--val-fraction 0.2 --split-seed`` SEED, the hybrid default, seed 0):
  each campaign registered on its own training rows and given its own frame in the
  identification. Scored as ``cross``: B and D after their own rigid fit, B also in C's frame (C's
  registration, its fitted frame, tool and zero offsets, no re-fit), A and C on their held-out
  rows as their campaigns (the same). Goals (issue 32): B ≤ 0.25, D ≤ 0.28 (the classical 27-parameter
  calibration with one frame per series: 0.226 / 0.276).
* ``random``: B and D on their own 80 % (A and C: ``cross``), the 20 % held out: ≤ 0.10, max ≤ 0.6.
* ``octant``: each series' rows split into the octants of A1/A2/A3 (each at its median along its
  arc, as ``training.blocked.folds``); each octant predicted by the model fitted on the other
  seven: pooled mean ≤ 0.15, max ≤ 0.8 (``--octant-series``, default B,C,D,A).
* ``singular``: the model of D at D's stretched pose q = (0, −90, 0, 0, 0, 0) (elbow and wrist
  singular; D's last row): the prediction and what it leaves, and its ``error_std``.
* ``update``: ``train --update`` (``update_model``) with ``--update-rows`` random rows of each
  other series (5 draws, the frame registered on those rows alone), scored on the series' other
  rows: from the C model (B, D, A; goal ≤ 0.40), from the A model (B, C, D; goal ≤ 0.30) and from
  the A+C model of ``campaigns`` (B, D; goal ≤ 0.30; trained first where the part did not run).
* ``flipped``: the simulated KR 500, trained on 300 poses in the configuration nearest HOME; the
  2σ coverage of ``error_std`` at 100 targets in the flipped wrist (S bit 2; first order: E − Ê at
  the targets) and at 100 in the trained one.

Single thread. Figures to benchmarks/results/transfer.json (each part merged into it).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

from _common import RESULTS, record  # noqa: E402  (benchmarks/ is on sys.path when run as a script)
from postproc.model.compensator import load_model  # noqa: E402
from postproc.measurements.datasets import read_ipa  # noqa: E402
from postproc.core.registration import register_measurements  # noqa: E402
from postproc.robot.description import load_description  # noqa: E402
from postproc.model.training.card import arm_metadata  # noqa: E402
from postproc.model.training.data import split_indices  # noqa: E402
from postproc.model.training.features import previous_poses  # noqa: E402
from postproc.model.training.hybrid import HybridModel  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_DATA = "/work/shared/datasets/ipa-robot-accuracy"
SERIES = {"A": "Series_A/measurements_grid.csv", "B": "Series_B/measurements_joint_configurations.csv",
          "C": "Series_C/measurements_random_poses.csv", "D": "Series_D/measurements_iso_cubes.csv"}
CAMPAIGN = {"B": "C", "C": "B"}  # series measured in one tracker set-up
GOALS = {"A": {"C": 0.45, "D": 0.39, "B": 0.37}, "AC": {"B": 0.25, "D": 0.25},
         "C": {"B": 0.47, "D": 0.50, "A": 0.53, "B in C's frame": 0.65}}
UPDATE_GOALS = {"C": 0.40, "A": 0.30, "AC": 0.30}
CAMPAIGN_GOALS = {"B": 0.25, "D": 0.28}
STRETCHED = np.array([0.0, -90.0, 0.0, 0.0, 0.0, 0.0])


class Series:
    """One IPA series: poses, joint angles, the tracker's points, its own registration."""

    def __init__(self, data: str, name: str):
        s = read_ipa(Path(data) / SERIES[name])
        self.name, self.poses, self.joints, self.raw = name, s.commanded, s.joints, s.measured
        self.measured, self.transform, _ = register_measurements(self.poses[:, :3], self.raw,
                                                                 np.ones(len(self.poses), bool))
        self.errors = self.poses[:, :3] - self.measured
        self.previous = previous_poses(self.poses)

    def __len__(self) -> int:
        return len(self.poses)


def stats(v: np.ndarray) -> list[float]:
    n = np.linalg.norm(v, axis=1)
    return [round(float(n.mean()), 4), round(float(np.quantile(n, 0.95)), 4), round(float(n.max()), 4)]


def coverage(residual: np.ndarray, std: np.ndarray) -> float:
    """Share of residual coordinates within 2 error_std."""
    return round(float((np.abs(residual) <= 2.0 * std.reshape(-1, 1)).mean()), 4)


def train(description, parts: list[tuple[Series, np.ndarray]], path: Path, name: str):
    """The hybrid default on the rows ``parts`` [(series, rows)], exported to ``path``: (model, compensator)."""
    cat = lambda attr: np.concatenate([getattr(s, attr)[rows] for s, rows in parts])  # noqa: E731
    model = HybridModel(description, seed=0).fit(cat("poses"), cat("errors"), cat("previous"), cat("joints"))
    card = {"name": name, "identified": {**model.describe(), "identifiability": None}, **arm_metadata(description)}
    model.export_onnx(path, **card)
    return model, load_model(path)


def scored(compensator, s: Series, rows: np.ndarray, frame: np.ndarray | None = None,
           measured: np.ndarray | None = None) -> dict:
    """|E − Ê| at ``rows`` through the ONNX file: in ``frame`` (a tracker → base transform, no
    re-fit) or, None, after the rigid fit of the measured points to the predicted positions; or the
    ``measured`` points [len(rows), 3] given in the model's frame."""
    predicted, std = compensator.predict(s.poses[rows], s.previous[rows], joints=s.joints[rows], std=True)
    positions = s.poses[rows, :3] - predicted
    if measured is None and frame is None:
        measured = register_measurements(positions, s.raw[rows], np.ones(len(rows), bool))[0]
    elif measured is None:
        measured = s.raw[rows] @ frame[:3, :3].T + frame[:3, 3]
    residual = positions - measured
    return {"rows": int(len(rows)), "mm": stats(residual), "uncompensated_mm": stats(s.errors[rows]),
            "error_std_median_mm": round(float(np.median(std)), 4), "two_sigma_coverage": coverage(residual, std)}


def selection(model: HybridModel) -> dict:
    km = model.kinematic_
    return {"structure": model.structure, "selection": km.selection_, "blocked": km.blocked_figures(),
            "residual_nets": len(model.nets_)}


def part_cross(data: dict, description, out: Path, seed: int) -> dict:
    result = {}
    for trained in ("A", "AC", "C"):
        t0 = time.perf_counter()
        parts = [(data[n], split_indices(len(data[n]), 0.2, seed)) for n in trained]
        model, comp = train(description, [(s, fit) for s, (fit, _) in parts], out / f"{trained}.onnx", f"ipa-{trained}")
        entry = {"train_rows": int(sum(len(fit) for _, (fit, _) in parts)), "seconds": round(time.perf_counter() - t0, 1),
                 **selection(model), "series": {}}
        for s, (_, held) in parts:
            entry["series"][f"{s.name} held out (random)"] = scored(comp, s, held, s.transform)
        for name in "ABCD":
            if name in trained:
                continue
            s = data[name]
            entry["series"][name] = scored(comp, s, np.arange(len(s)))
            if CAMPAIGN.get(name, "-") in trained:
                entry["series"][f"{name} in {CAMPAIGN[name]}'s frame"] = scored(comp, s, np.arange(len(s)),
                                                                              data[CAMPAIGN[name]].transform)
        _print(f"trained on {trained} ({entry['train_rows']} rows, {entry['seconds']} s): {model.structure}",
               entry["series"], GOALS.get(trained, {}))
        result[trained] = entry
    return result


def _print(title: str, series: dict, goals: dict) -> None:
    print(f"\n{title}\n  {'scored on':<22}{'rows':>6}  {'uncompensated':>13}  {'|E − Ê| mean / p95 / max':>26}"
          f"  {'2σ cover':>8}  goal")
    for name, e in series.items():
        goal = goals.get(name)
        verdict = "" if goal is None else f"≤ {goal:.2f}: {'met' if e['mm'][0] <= goal else 'NOT met'}"
        print(f"  {name:<22}{e['rows']:>6}  {e['uncompensated_mm'][0]:13.3f}  {e['mm'][0]:8.3f} / {e['mm'][1]:6.3f} / "
              f"{e['mm'][2]:6.3f}  {100 * e['two_sigma_coverage']:7.1f}%  {verdict}", flush=True)


def _campaign_file(s: Series):
    """A series as ``postproc import`` would write it without --register: the tracker's points,
    q1..q6, '# frame: tracker' (a Measurements, as read_measurements returns it)."""
    import hashlib

    from postproc.measurements.csv import Measurements

    return Measurements(s.poses.copy(), s.raw.copy(), np.arange(len(s)) + 3,
                        hashlib.sha256(s.raw.tobytes()).hexdigest(), f"{s.name}.csv", {"frame": "tracker"},
                        joints=s.joints.copy())


def in_campaign(trained, s: Series, rows: np.ndarray, campaign: str) -> np.ndarray:
    """[len(rows), 3] the tracker points of ``rows`` as campaign ``campaign`` of the fit saw them,
    in the model's frame at its tool and zeros: the campaign's registration (the card's), then its
    fitted frame, tool and zero offsets undone (``KinematicModel.to_base``)."""
    names = [c["name"] for c in trained.card["campaigns"]]
    entry = trained.card["campaigns"][names.index(campaign)]
    registration = np.asarray(entry["registration"]["tracker_to_base"], dtype=float)
    measured = s.raw[rows] @ registration[:3, :3].T + registration[:3, 3]
    code = np.full(len(rows), names.index(campaign))
    errors = trained.model.kinematic_.to_base(s.poses[rows], s.poses[rows, :3] - measured, code, s.joints[rows])
    return s.poses[rows, :3] - errors


def campaigns_model(data: dict, description, out: Path, seed: int):
    """The A+C model of two campaigns through ``training.fit`` (train's path): (trained, compensator, path)."""
    from postproc.model.training.fitting import fit
    from postproc.settings import Settings

    settings = Settings().override(method="hybrid", robot=str(ROOT / "models/ur10.toml"), seed=0, register=True,
                                   val_fraction=0.2, split_seed=seed, name="ipa-A+C-campaigns")
    trained = fit([_campaign_file(data["A"]), _campaign_file(data["C"])], settings)
    path = trained.export(out / "AC_campaigns.onnx")
    return trained, load_model(path), path


def part_campaigns(data: dict, description, out: Path, seed: int) -> dict:
    t0 = time.perf_counter()
    trained, comp, _ = campaigns_model(data, description, out, seed)
    seconds = round(time.perf_counter() - t0, 1)
    card = trained.card
    entry = {"protocol": "training.fit([A.csv, C.csv], --register --val-fraction 0.2 --split-seed SEED, hybrid, seed 0): "
                         "two campaigns, each its own frame in the identification; B, D after their own rigid fit",
             "seed": seed, "train_rows": int(len(trained.train_rows)), "seconds": seconds,
             "campaigns": card["campaigns"], **selection(trained.model), "series": {}}
    offset = 0
    for name in "AC":  # each training series' held-out rows in its own frame (the card's)
        s = data[name]
        held = trained.val_rows[(trained.val_rows >= offset) & (trained.val_rows < offset + len(s))] - offset
        entry["series"][f"{name} held out (random)"] = scored(comp, s, held, measured=in_campaign(trained, s, held, name))
        offset += len(s)
    for name in "BD":
        s = data[name]
        entry["series"][name] = scored(comp, s, np.arange(len(s)))
    b = np.arange(len(data["B"]))
    entry["series"]["B in C's frame"] = scored(comp, data["B"], b, measured=in_campaign(trained, data["B"], b, "C"))
    _print(f"trained on A+C as two campaigns in one fit ({entry['train_rows']} rows, {seconds} s, seed {seed}): "
           f"{trained.model.structure}", entry["series"], CAMPAIGN_GOALS)
    for c in card["campaigns"]:
        f = c["frame"]
        print(f"  campaign {c['name']}: registration rms {c['registration']['rms_mm']:.3f} mm; fitted frame "
              f"{f['rotation_deg']} deg ± {f['rotation_std_deg']}, {f['offset_mm']} mm ± {f['offset_std_mm']}; tool "
              f"{f.get('tool_mm')} mm ± {f.get('tool_std_mm')}")
    return entry


def part_random(data: dict, description, out: Path, seed: int, series: str = "BD") -> dict:
    result = {}
    for name in series:
        s = data[name]
        fit, held = split_indices(len(s), 0.2, seed)
        model, comp = train(description, [(s, fit)], out / f"{name}.onnx", f"ipa-{name}")
        result[name] = {**scored(comp, s, held, s.transform), **selection(model)}
        _print(f"trained on {name} ({len(fit)} rows): {model.structure}", {f"{name} held out (random)": result[name]},
               {})
    return result


def octants(q_deg: np.ndarray) -> np.ndarray:
    """Each row's octant of A1/A2/A3 (medians along each joint's arc), as training.blocked.folds."""
    from postproc.model.envelope import joint_arcs

    arcs = joint_arcs(q_deg[:, :3])
    out = np.zeros(len(q_deg), int)
    for j in range(3):
        u = np.mod(q_deg[:, j] - arcs[j, 0], 360.0)
        out += (u > np.median(u)).astype(int) << j
    return out


def part_octant(data: dict, description, out: Path, series: str) -> dict:
    result = {}
    for name in series:
        s = data[name]
        octant = octants(s.joints)
        residuals, per = [], {}
        for k in range(8):
            held, fit = np.flatnonzero(octant == k), np.flatnonzero(octant != k)
            if not len(held):
                continue
            _, comp = train(description, [(s, fit)], out / f"{name}_oct{k}.onnx", f"ipa-{name}-octant{k}")
            predicted = comp.predict(s.poses[held], s.previous[held], joints=s.joints[held])
            residuals.append(s.errors[held] - predicted)
            per[str(k)] = stats(residuals[-1])
            print(f"  {name} octant {k} ({len(held)} rows held out): {per[str(k)]}", flush=True)
        pooled = stats(np.concatenate(residuals))
        result[name] = {"pooled_mm": pooled, "octants_mm": per}
        print(f"{name}: held-out octants pooled mean {pooled[0]:.3f} max {pooled[2]:.3f} (goal ≤ 0.15, max ≤ 0.8)")
    return result


def part_singular(data: dict, description, out: Path, seed: int) -> dict:
    s = data["D"]
    q = np.mod(s.joints + 180.0, 360.0) - 180.0
    stretched = np.flatnonzero((np.abs(q[:, 1:5] - STRETCHED[1:5]) < 2.0).all(axis=1))
    fit, _ = split_indices(len(s), 0.2, seed)
    fit = np.setdiff1d(fit, stretched)  # (held out: a prediction there, not a fit)
    model, comp = train(description, [(s, fit)], out / "D_singular.onnx", "ipa-D")
    predicted, std = comp.predict(s.poses[stretched], s.previous[stretched], joints=s.joints[stretched], std=True)
    residual = s.errors[stretched] - predicted
    result = {"rows": stretched.tolist(), "q_deg": s.joints[stretched].round(3).tolist(),
              "measured_error_mm": s.errors[stretched].round(4).tolist(), "predicted_mm": predicted.round(4).tolist(),
              "residual_mm": stats(residual), "error_std_mm": std.round(4).reshape(-1).tolist(),
              "two_sigma_coverage": coverage(residual, std), **selection(model)}
    print(f"\nD's stretched pose (rows {stretched.tolist()}): measured E {result['measured_error_mm']}, predicted "
          f"{result['predicted_mm']}, |E − Ê| {result['residual_mm'][0]:.3f}, error_std {result['error_std_mm']}, "
          f"2σ coverage {100 * result['two_sigma_coverage']:.0f}%")
    return result


def part_update(data: dict, description, out: Path, seed: int, rows: int, seeds: list[int]) -> dict:
    from cross_series import updates

    result = {}
    for trained, others in (("C", "BDA"), ("A", "BCD"), ("AC", "BD")):
        path = out / f"{trained}.onnx"
        if trained == "AC":  # (the two-campaign model of part 'campaigns')
            path = out / "AC_campaigns.onnx"
            if not path.is_file():
                campaigns_model(data, description, out, seed)
        elif not path.is_file():
            s = data[trained]
            train(description, [(s, split_indices(len(s), 0.2, seed)[0])], path, f"ipa-{trained}")
        # (cross_series.updates reads series with .poses, .errors via registration on the drawn rows, .joints, .measured)
        shown = {n: _AsMeasurements(data[n]) for n in others}
        result[trained] = updates(shown, trained, path, description, rows, seeds, out, others)
        worst = max(max(r["updated_mm"][0] for r in e["seeds"]) for e in result[trained].values())
        print(f"update from the {trained} model: worst draw's mean {worst:.3f} (goal ≤ {UPDATE_GOALS[trained]:.2f})")
    return result


class _AsMeasurements:
    """A Series as cross_series.updates reads a measurement file (poses, joints, measured: the
    tracker's points, which it registers on the drawn rows alone)."""

    def __init__(self, s: Series):
        self.poses, self.joints, self.measured = s.poses, s.joints, s.raw

    def __len__(self) -> int:
        return len(self.poses)


def part_flipped(out: Path) -> dict:
    from postproc.robot import configuration
    from postproc.calibration.planning import latin_hypercube, plan_configurations
    from postproc.calibration.simulator import SimulatedRobot

    sim = SimulatedRobot()
    robot = sim.robot
    poses = latin_hypercube(300, box=(1800, 2200, -400, 400, 700, 1100), seed=5)
    config, ok = plan_configurations(robot, poses, "home")
    poses, config = poses[ok], config[ok]
    q = sim.joint_angles(poses, config)
    measured = sim.measure(poses, rng_seed=0, q_deg=q)
    model = HybridModel(load_description(), seed=0).fit(poses, poses[:, :3] - measured, previous_poses(poses), q)
    comp = load_model(model.export_onnx(out / "sim_home.onnx", name="sim-home",
                                        **arm_metadata(load_description())))
    targets = latin_hypercube(300, box=(1850, 2150, -300, 300, 750, 1050), seed=11)
    home, ok = plan_configurations(robot, targets, "home")
    targets, home = targets[ok], home[ok]
    result = {}
    for name, status in (("trained wrist", home[:, 0]), ("flipped wrist", home[:, 0] ^ 4)):
        q_t, found = configuration.stated_joints(robot, targets, status, np.full(len(targets), -1))
        p, q_t = targets[found][:100], q_t[found][:100]
        true = p[:, :3] - sim.actual_positions(p, q_deg=q_t)
        predicted, std = comp.predict(p, previous_poses(p), joints=q_t, std=True)
        residual = true - predicted
        result[name] = {"targets": int(len(p)), "uncompensated_mm": stats(true), "mm": stats(residual),
                        "error_std_median_mm": round(float(np.median(std)), 4),
                        "two_sigma_coverage": coverage(residual, std)}
        print(f"simulated KR 500, data in the trained wrist only, {name}: |E| {result[name]['uncompensated_mm'][0]:.3f} → "
              f"|E − Ê| {result[name]['mm'][0]:.3f} mm (first order), error_std median "
              f"{result[name]['error_std_median_mm']:.3f}, 2σ coverage {100 * result[name]['two_sigma_coverage']:.1f}%")
    return result


def _key(name: str) -> str:
    """A README figure marker's key for a scored set's name ("B in C's frame" → "B_in_C_frame")."""
    return "_".join("".join(c if c.isalnum() else " " for c in name.replace("'s", "")).split())


def scalars(figures: dict) -> dict:
    """The README's figures (benchmarks/figures.py reads dotted keys of \\w names, no lists):
    per part the means, maxima and 2σ coverages under plain keys."""
    out = {}
    for trained, entry in (figures.get("cross") or {}).items():
        if isinstance(entry, dict) and "series" in entry:
            out[f"cross_{trained}"] = {f"{_key(n)}_{what}": v for n, e in entry["series"].items()
                                       for what, v in (("mean", e["mm"][0]), ("max", e["mm"][2]),
                                                       ("cover", round(100 * e["two_sigma_coverage"], 1)))}
    entry = figures.get("campaigns") or {}
    if "series" in entry:
        out["campaigns_AC"] = {f"{_key(n)}_{what}": v for n, e in entry["series"].items()
                               for what, v in (("mean", e["mm"][0]), ("max", e["mm"][2]),
                                               ("cover", round(100 * e["two_sigma_coverage"], 1)))}
    for name, e in (figures.get("random") or {}).items():
        if isinstance(e, dict) and "mm" in e:
            out.setdefault("random", {}).update({f"{name}_mean": e["mm"][0], f"{name}_max": e["mm"][2]})
    for name, e in (figures.get("octant") or {}).items():
        if isinstance(e, dict) and "pooled_mm" in e:
            out.setdefault("octant", {}).update({f"{name}_mean": e["pooled_mm"][0], f"{name}_max": e["pooled_mm"][2]})
    single = figures.get("singular") or {}
    if "residual_mm" in single:
        out["singular"] = {"residual": single["residual_mm"][0], "predicted_norm": round(float(np.linalg.norm(
            single["predicted_mm"][0])), 4), "measured_norm": round(float(np.linalg.norm(single["measured_error_mm"][0])), 4),
            "std": single["error_std_mm"][0], "cover": round(100 * single["two_sigma_coverage"], 1)}
    for trained, series in (figures.get("update") or {}).items():
        if isinstance(series, dict):
            out[f"update_{trained}"] = {f"{n}_{what}": v for n, e in series.items() if isinstance(e, dict)
                                        for what, v in (("mean", e["updated_mean_of_draws_mm"][0]),
                                                        ("worst", max(r["updated_mm"][0] for r in e["seeds"])),
                                                        ("rigid", e["rigid_mean_of_draws_mm"]))}
    for name, e in (figures.get("flipped") or {}).items():
        if isinstance(e, dict) and "mm" in e:
            out.setdefault("flipped", {}).update({f"{_key(name)}_mean": e["mm"][0], f"{_key(name)}_std": e["error_std_median_mm"],
                                                  f"{_key(name)}_cover": round(100 * e["two_sigma_coverage"], 1)})
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", default=os.environ.get("POSTPROC_IPA_DATA", DEFAULT_DATA))
    ap.add_argument("--parts", default="cross,campaigns,random,octant,singular,update,flipped",
                    help="the parts to run (each merged into the result file); 'summary': only the README's figures again")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--octant-series", default="BCDA")
    ap.add_argument("--update-rows", type=int, default=30)
    ap.add_argument("--update-seeds", default="0,1,2,3,4")
    ap.add_argument("--out", default=None, help="keep the models in this folder")
    args = ap.parse_args()
    import torch

    torch.set_num_threads(1)
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="transfer_"))
    out.mkdir(parents=True, exist_ok=True)
    parts = [p for p in args.parts.split(",") if p]
    if parts == ["summary"]:  # (the result file's README figures again, from its parts)
        path = RESULTS / "transfer.json"
        entry = json.loads(path.read_text())
        entry["figures"]["summary"] = scalars(entry["figures"])
        path.write_text(json.dumps(entry, indent=1) + "\n")
        return
    data = {n: Series(args.data, n) for n in SERIES} if set(parts) - {"flipped"} else {}
    description = load_description(ROOT / "models/ur10.toml")
    figures = {}
    for part in parts:
        t0 = time.perf_counter()
        if part == "cross":
            figures[part] = part_cross(data, description, out, args.seed)
        elif part == "campaigns":
            figures[part] = part_campaigns(data, description, out, args.seed)
        elif part == "random":
            figures[part] = part_random(data, description, out, args.seed)
        elif part == "octant":
            figures[part] = part_octant(data, description, out, args.octant_series)
        elif part == "singular":
            figures[part] = part_singular(data, description, out, args.seed)
        elif part == "update":
            figures[part] = part_update(data, description, out, args.seed, args.update_rows,
                                        [int(v) for v in args.update_seeds.split(",") if v])
        elif part == "flipped":
            figures[part] = part_flipped(out)
        else:
            raise SystemExit(f"unknown part {part!r}")
        figures[part]["seconds"] = round(time.perf_counter() - t0, 1)
        # each part merged into the result file (the parts run in separate processes on a busy machine)
        path = RESULTS / "transfer.json"
        merged = json.loads(path.read_text())["figures"] if path.is_file() else {}
        merged.update({part: figures[part]})
        merged["summary"] = scalars(merged)
        print(f"[{part}] wrote {record('transfer', merged, sys.argv[1:])}", flush=True)


if __name__ == "__main__":
    main()

"""ISO 9283 pose figures of the real IPA Series D (UR10 + laser tracker, ISO-style cubes).

    python benchmarks/iso9283_ipa.py [--data DIR] [--model UR10.onnx] [--out DIR]

DIR is $POSTPROC_IPA_DATA, default /work/shared/datasets/ipa-robot-accuracy (MIT licence;
not shipped: samples/ipa/series_d_excerpt.csv holds its first 27 rows for the tests).

Protocol, as a user would run it: `postproc import ipa Series_D/measurements_iso_cubes.csv
--register` (rigid tracker → base fit on 80 % of the rows, split seed 0), then `postproc report
--iso9283` (rows clustered to their nominal poses: commands within 1 mm and 0.5°). Series D
holds cubes of 400, 250 and 100 mm side (centre + 8 corners) at several places, most visited
once; the centre of the first cube 8 times. RP needs n ≥ 2, so the table splits by n.

AP here is measured against the best-fit rigid tracker → base transform of the same rows: the
registration absorbs the mean error, so these AP figures are lower than against an
independently surveyed base frame. RP does not depend on the registration.

With --model (a compensator of this UR10, e.g. `postproc train` on Series C with --register
--robot models/ur10.toml) the 'after' figures are first order: the compensated command
c = P + Ê(P) reaches ≈ attained + Ê, no re-measurement exists for this data (see
first_order_after: the model run with D's joint angles and visiting order, D's measured
points registered to the model's predicted positions).
"""
from __future__ import annotations

import argparse
import json
import os
import tempfile
from pathlib import Path

import numpy as np

from _common import cli, record  # noqa: E402

DEFAULT_DATA = "/work/shared/datasets/ipa-robot-accuracy"
SERIES_D = "Series_D/measurements_iso_cubes.csv"


def first_order_after(base_csv: Path, model_path: str, out: Path) -> str:
    """Write the first-order 'after' file; returns a note on the poses outside the model's
    training envelope ('' if none: compensate warns P301 there and applies the physical part).
    As ``compensate`` would: the model run with the visiting order and the data's joint angles
    (q1..q6: the arm configuration of each row). Series D's tracker set-up is its own: its
    measured points are registered (rigid fit) to the positions the model predicts, P − Ê, as
    benchmarks/cross_series.py does — registered to the Goal instead, the model's constant part
    (the probe offset it identified on C) would come back as error."""
    from postproc.model.compensator import load_model
    from postproc.measurements.csv import parse_measurements, write_measurements
    from postproc.core.registration import apply_rigid, fit_rigid
    from postproc.model.training.features import previous_poses

    m = parse_measurements(base_csv.read_bytes(), str(base_csv), repeats=True)
    model = load_model(model_path)
    outside = int(model.envelope.outside(m.poses).sum()) if model.envelope is not None else 0
    q = getattr(m, "joints", None)
    joints_out = int(model.envelope.outside_joints(q).sum()) if model.envelope is not None and q is not None else 0
    predicted = model.predict(m.poses, previous_poses(m.poses), joints=q)
    # the model's positions P − Ê in D's frame (rigid fit to D's measured points): the model of
    # this set-up, whose correction is P minus those (the C frame's constant part gone)
    rotation, translation = fit_rigid(m.poses[:, :3] - predicted, m.measured)
    correction = m.poses[:, :3] - apply_rigid(m.poses[:, :3] - predicted, rotation, translation)
    commands = m.poses.copy()
    commands[:, :3] += correction
    write_measurements(out, commands, m.measured + correction, metadata={"frame": "base", "after": "first order"})
    if outside or joints_out:
        return (f"{outside} of {len(m)} poses outside the model's training box, {joints_out} outside its trained "
                "joint arcs (compensate warns P301 there; the model's physical part applies)")
    return ""


def summary(figures: list[dict], n_min: int) -> dict:
    rows = [p for p in figures if p["n"] >= n_min]
    ap = np.array([p["AP"] for p in rows])
    rp = np.array([p["RP"] for p in rows if p["RP"] is not None])
    out = {"poses": len(rows), "AP_mean": round(float(ap.mean()), 4), "AP_max": round(float(ap.max()), 4)}
    if rp.size:
        out.update({"RP_mean": round(float(rp.mean()), 4), "RP_max": round(float(rp.max()), 4)})
    return out


def table(figures: list[dict], n_min: int) -> str:
    rows = [p for p in figures if p["n"] >= n_min]
    if not rows:
        return f"  no pose with n >= {n_min}"
    ap = np.array([p["AP"] for p in rows])
    rp = np.array([p["RP"] for p in rows if p["RP"] is not None])
    return (f"  n >= {n_min}: {len(rows)} poses; AP mean {ap.mean():.3f} max {ap.max():.3f} mm"
            + (f"; RP mean {rp.mean():.3f} max {rp.max():.3f} mm" if rp.size else ""))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=os.environ.get("POSTPROC_IPA_DATA", DEFAULT_DATA))
    parser.add_argument("--model", help="UR10 compensator for first-order 'after' figures")
    parser.add_argument("--out", help="keep the certificate here (default: a temporary folder)")
    args = parser.parse_args()
    source = Path(args.data) / SERIES_D
    if not source.exists():
        print(f"skip: {source} not found (set POSTPROC_IPA_DATA)")
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        out = Path(args.out) if args.out else tmp / "cert"
        base = tmp / "series_d.csv"
        _, t_import = cli("import", "ipa", str(source), "-o", str(base), "--register")
        report = ["report", "--iso9283", str(base), "-o", str(out)]
        note = ""
        if args.model:
            after = tmp / "series_d_after.csv"
            note = first_order_after(base, args.model, after)
            report += ["--model", args.model, "--after", str(after)]
        _, t_report = cli(*report)
        s = json.loads((out / "iso9283.json").read_text())
    before = s["before"]["poses"]
    counts = np.bincount([p["n"] for p in before])
    print(f"IPA Series D: {sum(p['n'] for p in before)} rows -> {len(before)} poses "
          f"(n: {', '.join(f'{n}x{c}' for n, c in enumerate(counts) if c)}); import {t_import:.1f} s, "
          f"report {t_report:.1f} s")
    print("before (measured):")
    for n_min in (1, 2, 3, 8):
        print(table(before, n_min))
    centre = max(before, key=lambda p: p["n"])
    print(f"  most repeated pose P{centre['pose']} (n {centre['n']}) at {centre['command'][:3]}: "
          f"AP {centre['AP']:.3f} (APx {centre['APx']:.3f} APy {centre['APy']:.3f} APz {centre['APz']:.3f}) "
          f"RP {centre['RP']:.3f} mm")
    figures = {"before": {f"n{n}": summary(before, n) for n in (1, 2)}}
    if "after" in s:
        print("after (first order, no re-measurement; Series D registered to the model's predicted positions)"
              + (f":\n  {note}" if note else ":"))
        for n_min in (1, 2, 3, 8):
            print(table(s["after"]["poses"], n_min))
        figures["after"] = {f"n{n}": summary(s["after"]["poses"], n) for n in (1, 2)}
        figures["model"] = Path(args.model).name
    if args.data == DEFAULT_DATA or os.environ.get("POSTPROC_IPA_DATA"):
        print(f"figures: {record('iso9283_ipa', figures)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Compare backprop optimisers and weight-search methods on one measurement set.

    python benchmarks/train_compare.py [--data measured.csv] [--seeds 0,1,2,3,4]
        [--optimizers gd,momentum,adam,lbfgs,lm] [--methods gpso] [--inertia constant]

Each (method, optimiser) is trained once per seed on the same 95 % / 5 % split (split seed
0, as `postproc train`'s default) and scored on the held-out 5 %: mean / max of |E − Ê| mm,
averaged over seeds, with the worst seed's mean and the time per fit. Without --data it uses
the synthetic error field (postproc.model.training.synthetic, 2000 poses). Single thread.
"""
from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from postproc.model.training import ErrorModel  # noqa: E402
from postproc.measurements.csv import read_measurements  # noqa: E402
from postproc.model.training.data import split_indices  # noqa: E402
from postproc.model.training.synthetic import synthetic_measurements  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", help="measurement CSV (default: synthetic field, 2000 poses)")
    ap.add_argument("--seeds", default="0,1,2,3,4")
    ap.add_argument("--optimizers", default="gd,momentum,adam,lbfgs,lm")
    ap.add_argument("--methods", default="gpso")
    ap.add_argument("--inertia", default="constant")
    ap.add_argument("--hidden", default="20,10,5")
    ap.add_argument("--epochs", type=int, default=500)
    ap.add_argument("--val-fraction", type=float, default=0.05)
    args = ap.parse_args()
    torch.set_num_threads(1)
    if args.data:
        data = read_measurements(args.data)
        poses, errors, source = data.poses, data.errors, f"{args.data} (sha256 {data.sha256[:12]}…)"
    else:
        poses, measured = synthetic_measurements(2000)
        errors, source = poses[:, :3] - measured, "synthetic field, 2000 poses"
    tr, va = split_indices(len(poses), args.val_fraction, 0)
    unc = np.linalg.norm(errors[va], axis=1)
    print(f"data: {source}; train {len(tr)}, validation {len(va)}; hidden {args.hidden}; epochs {args.epochs}")
    print(f"uncompensated |E| on validation: mean {unc.mean():.4f} max {unc.max():.4f} mm")
    seeds = [int(s) for s in args.seeds.split(",")]
    print(f"{'method':<6} {'optimiser':<9} {'val mean':>9} {'± sd':>7} {'worst':>7} {'val max':>8} {'train':>7} {'epochs':>6} {'s/fit':>6}   (mm, mean over seeds {args.seeds})")
    for method in args.methods.split(","):
        for opt in args.optimizers.split(","):
            means, maxes, trains, times, epochs = [], [], [], [], []
            for seed in seeds:
                t = time.perf_counter()
                model = ErrorModel(hidden=args.hidden, method=method, optimizer=opt, epochs=args.epochs,
                                   inertia=args.inertia, seed=seed).fit(poses[tr], errors[tr])
                times.append(time.perf_counter() - t)
                r = np.linalg.norm(errors[va] - model.predict(poses[va]), axis=1)
                means.append(r.mean())
                maxes.append(r.max())
                trains.append(model.train_stats_["mean"])
                epochs.append(len(model.losses_))
            print(f"{method:<6} {opt:<9} {np.mean(means):9.4f} {np.std(means):7.4f} {np.max(means):7.4f} {np.mean(maxes):8.4f} "
                  f"{np.mean(trains):7.4f} {np.mean(epochs):6.0f} {np.mean(times):6.1f}", flush=True)


if __name__ == "__main__":
    main()

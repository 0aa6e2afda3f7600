"""The method's Table 2 on the default simulated robot: GPSO-DNN vs GA-DNN vs PSO-DNN vs DNN.

    python benchmarks/table2.py [--seeds 0] [--out benchmarks/out]

1. `postproc plan -n 2000 --seed 0` (Latin hypercube) and `postproc measure` (default
   simulated KR500, noise seed 0);
2. the same split as `postproc train` (5 % held out, split seed 0): 1900 training rows, 100
   held-out targets;
3. per method, ErrorModel(method=…, seed=…) on the 1900 rows (the Python API, to keep each
   search's fitness history), exported as ONNX;
4. the 100 held-out targets, in visiting order, as a KRL program (held_out.src: LIN lines in
   DEF/END), compensated through the CLI (`postproc compensate held_out.src -o … --model M`)
   and run on the simulated robot (`postproc verify held_out.src comp.src --json`);
5. also trains `postproc train`'s own default method through the CLI (same split) for a
   row beside the paper's methods (skipped with --no-default);
6. prints max / min / mean / std (and p95) of the error norms (mm) before and after, per method, beside
   the paper's figures, and writes benchmarks/out/convergence.png (best training MSE per
   generation and per fitness evaluation: GPSO vs GA vs PSO) and table2.json.

With several --seeds every method is trained once per seed and the table gives the mean of
each figure over the seeds (plus the spread of the mean).
"""
from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
from _common import cli, krl_program  # noqa: E402
from postproc.model.training import ErrorModel  # noqa: E402
from postproc.measurements.csv import read_measurements  # noqa: E402
from postproc.model.training.data import split_indices  # noqa: E402

PAPER = {  # Hu, Hua & Tian, Table 2 (mm): max, min, mean, std
    "uncompensated": (1.529, 0.124, 0.754, 0.340),
    "GA-DNN": (0.965, 0.017, 0.284, 0.114),
    "PSO-DNN": (0.519, 0.172, 0.333, 0.062),
    "GPSO-DNN": (0.364, 0.097, 0.249, 0.064),
}
METHODS = {"gpso": "GPSO-DNN", "ga": "GA-DNN", "pso": "PSO-DNN", "plain": "DNN (plain)"}
KEYS = ("max", "min", "mean", "std", "p95")  # (the paper has no p95: its column stays empty)


def _model_method(path: Path) -> str:
    from postproc.model.compensator import load_model

    return str(load_model(path).metadata.get("method", "?"))


def convergence_plot(histories: dict[str, list[dict]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    colours = {"gpso": "C0", "ga": "C1", "pso": "C2"}
    for method, runs in histories.items():
        for i, run in enumerate(runs):
            h = np.asarray(run["history"])
            label = METHODS[method] if i == 0 else None
            axes[0].plot(np.arange(1, len(h) + 1), h, color=colours[method], alpha=0.9 if i == 0 else 0.35, label=label)
            axes[1].plot(run["evaluations"], h, color=colours[method], alpha=0.9 if i == 0 else 0.35, label=label)
    for ax, xlabel in zip(axes, ("generation", "networks evaluated")):
        ax.set_xlabel(xlabel)
        ax.set_ylabel("best training MSE (standardised)")
        ax.set_yscale("log")
        ax.grid(True, alpha=0.3)
        ax.legend()
    axes[0].set_title("initial-weight search: convergence")
    axes[1].set_title("… per fitness evaluation")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def evaluations_per_generation(method: str, model: ErrorModel) -> list[int]:
    """Cumulative networks evaluated after each generation (populations differ per method)."""
    pop = model.population or {"gpso": 20, "ga": 50, "pso": 40}[method]
    per_gen = {"gpso": pop + pop // 2, "ga": pop - 2, "pso": pop}[method]
    return [pop + per_gen * (g + 1) for g in range(len(model.history_))]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", default="0", help="training seeds (comma-separated)")
    ap.add_argument("--methods", default="gpso,ga,pso,plain")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "out"))
    ap.add_argument("--no-default", action="store_true", help="skip the row of `postproc train`'s default method")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    seeds = [int(s) for s in args.seeds.split(",")]
    methods = args.methods.split(",")
    t_start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        plan, measured = work / "plan.csv", work / "measured.csv"
        cli("plan", "-n", "2000", "--seed", "0", "-o", str(plan), "-q")
        cli("measure", str(plan), "-o", str(measured), "-q")
        data = read_measurements(measured)
        train, held = split_indices(len(data), 0.05, 0)
        poses, errors = data.poses, data.errors
        src = work / "held_out.src"
        src.write_text(krl_program("held_out", poses[held]))
        print(f"data: plan -n 2000 --seed 0 + measure (default robot), sha256 {data.sha256[:16]}…; "
              f"train {len(train)}, held out {len(held)} (KRL, visiting order)")
        results: dict[str, list[dict]] = {}
        histories: dict[str, list[dict]] = {}
        before = None
        iteration_check: dict[int, dict] = {}
        for method in methods:
            for seed in seeds:
                t = time.perf_counter()
                model = ErrorModel(method=method, seed=seed).fit(poses[train], errors[train])
                fit_s = time.perf_counter() - t
                onnx_path = work / f"{method}_{seed}.onnx"
                model.export_onnx(onnx_path, name=f"table2-{method}-{seed}", robot="KR500-sim",
                                  data_sha256=data.sha256)
                comp = work / f"comp_{method}_{seed}.src"
                cli("compensate", str(src), "-o", str(comp), "--model", str(onnx_path), "-q")
                report = json.loads(cli("verify", str(src), str(comp), "--json", "-q")[0])
                before = report["before"]
                results.setdefault(method, []).append({"seed": seed, "after": report["after"], "fit_s": fit_s,
                                                      "init_fitness": model.init_.fitness,
                                                      "train_mse": model.losses_[-1] if model.losses_ else None})
                if method == methods[0] and seed == seeds[0]:
                    # how many fixed-point iterations c ← P + Ê(c) pay off (the model card says 2)
                    for k in (1, 2, 3):
                        ck = work / f"comp_iter{k}.src"
                        cli("compensate", str(src), "-o", str(ck), "--model", str(onnx_path), "--iterations", str(k), "-q")
                        iteration_check[k] = json.loads(cli("verify", str(src), str(ck), "--json", "-q")[0])["after"]
                if method != "plain":
                    histories.setdefault(method, []).append(
                        {"seed": seed, "history": model.history_, "evaluations": evaluations_per_generation(method, model)})
                print(f"  {METHODS[method]:<12} seed {seed}: fit {fit_s:5.1f} s, mean after {report['after']['mean']:.3f} mm",
                      flush=True)
        default_row = None
        if not args.no_default:
            model_path = work / "default_method.onnx"
            t = time.perf_counter()
            cli("train", str(measured), "-o", str(model_path), "--val-fraction", "0.05", "--split-seed", "0", "-q")
            fit_s = time.perf_counter() - t
            comp = work / "comp_default.src"
            cli("compensate", str(src), "-o", str(comp), "--model", str(model_path), "-q")
            default_row = json.loads(cli("verify", str(src), str(comp), "--json", "-q")[0])["after"]
            method_name = _model_method(model_path)
            print(f"  postproc train default ({method_name}): {fit_s:5.1f} s (whole command), "
                  f"mean after {default_row['mean']:.3f} mm", flush=True)
    print()
    print(f"Table 2 — positioning error on {len(held)} held-out targets (mm); "
          f"ours: mean over seeds {args.seeds}" + (" (± spread of the mean)" if len(seeds) > 1 else ""))
    print(f"{'':<14} {'max':>13} {'min':>13} {'mean':>13} {'std':>13} {'p95':>13}   {'paper: max':>10} {'min':>6} "
          f"{'mean':>6} {'std':>6}")

    def row(label: str, figures: list[dict], paper_key: str | None) -> None:
        cells = []
        for k in KEYS:
            vals = np.array([f[k] for f in figures])
            cells.append(f"{vals.mean():6.3f} ± {vals.std():4.3f}" if len(vals) > 1 else f"{vals.mean():13.3f}")
        paper = PAPER.get(paper_key) if paper_key else None
        ptxt = "   " + " ".join(f"{v:{w}.3f}" for v, w in zip(paper, (10, 6, 6, 6))) if paper else ""
        print(f"{label:<14} " + " ".join(f"{c:>13}" for c in cells) + ptxt)

    row("uncompensated", [before], "uncompensated")
    for method in methods:
        label = METHODS[method]
        row(label, [r["after"] for r in results[method]], label if label in PAPER else None)
    if default_row is not None:
        row("train default", [default_row], None)
    print("\nfit times (s, 1 thread, shared machine): " + ", ".join(
        f"{METHODS[m]} {np.mean([r['fit_s'] for r in results[m]]):.1f}" for m in methods))
    if iteration_check:
        print(f"fixed-point iterations ({METHODS[methods[0]]}, seed {seeds[0]}): " + ", ".join(
            f"{k}: mean {v['mean']:.4f} max {v['max']:.4f}" for k, v in iteration_check.items()) + " mm")
    if histories:
        png = out / "convergence.png"
        convergence_plot(histories, png)
        print(f"convergence plot: {png}")
    (out / "table2.json").write_text(json.dumps(
        {"before": before, "methods": results, "train_default": default_row, "paper": PAPER, "seeds": seeds, "histories": histories,
         "iterations": iteration_check}, indent=1))
    print(f"figures: {out / 'table2.json'}; total {time.perf_counter() - t_start:.0f} s; "
          f"load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()

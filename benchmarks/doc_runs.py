"""The runs the README and the docs show, as a fresh clone runs them (shipped files only).

    python benchmarks/doc_runs.py

Each part runs `python -m postproc` as the page says and records what it printed or wrote
into benchmarks/results/doc_runs.json, so that the pages' figures carry markers
(``0.035<!-- fig doc_runs.report.after.mean -->``, checked by benchmarks/figures.py) instead of
numbers copied by hand:

* ``first_command``: the README's first command (compensate samples/krl/cam_pocket.src with
  the shipped model): its summary line's counts and corrections;
* ``verify``: `postproc verify` of that output, with and without tracker noise;
* ``orientation``: the same with `compensate --orientation`;
* ``report``: docs/acceptance.md's three lines (plan 300 poses, compensate, measure both,
  `postproc report before.csv --after after.csv`): Table 2 from report/summary.json;
* ``iso9283``: docs/acceptance.md's ISO 9283 commands: AP/RP per pose from iso9283.json;
* ``first_hour``: docs/getting-started.md's training runs (the simulator: plan, measure,
  train, compensate the sample, verify; the shipped IPA excerpt: import, train): the figures
  `train` prints, from the model card.

Everything is seeded: a second run gives the same figures (a few seconds in all).
"""
from __future__ import annotations

import json
import re
import tempfile
from pathlib import Path

from _common import ROOT, cli, record

SAMPLE = "samples/krl/cam_pocket.src"


def _summary(stderr_line: str) -> dict:
    m = re.search(r"(\d+) of (\d+) compensated; model \S+, max correction ([\d.]+) mm, mean ([\d.]+) mm, "
                  r"(\d+) iterations(?:, (\d+) in a joint's backlash dead band)?", stderr_line)
    if m is None:
        raise SystemExit(f"no summary line in: {stderr_line!r}")
    done, total, max_c, mean_c, iterations, dead = m.groups()
    return {"compensated": int(done), "targets": int(total), "max_correction": float(max_c),
            "mean_correction": float(mean_c), "iterations": int(iterations), "dead_band": int(dead or 0)}


def _stats(d: dict) -> dict:
    return {k: d[k] for k in ("max", "min", "mean", "std", "p95") if k in d}


def _verify(original: str, compensated: Path, *extra: str) -> dict:
    out, _ = cli("verify", original, str(compensated), "--json", "-q", *extra)
    v = json.loads(out)
    figures = {"before": _stats(v["before"]), "after": _stats(v["after"])}
    if "orientation_before_deg" in v:
        figures["orientation_before"] = _stats(v["orientation_before_deg"])
        figures["orientation_after"] = _stats(v["orientation_after_deg"])
    return figures


def _compensate(*args: str) -> dict:
    import subprocess
    import sys

    run = subprocess.run([sys.executable, "-m", "postproc", "compensate", *args], cwd=ROOT, capture_output=True,
                         text=True)
    if run.returncode not in (0, 1):
        raise SystemExit(f"postproc compensate {' '.join(args)} failed ({run.returncode}):\n{run.stderr}")
    return _summary(run.stderr.strip().splitlines()[-1]) | {"exit": run.returncode}


def _card(model: Path) -> dict:
    out, _ = cli("model", "info", "--json", str(model))
    accuracy = json.loads(out)["accuracy"]
    return {"val_mean": accuracy["val_mean_mm"], "val_max": accuracy["val_max_mm"],
            "val_uncompensated_mean": accuracy["val_uncompensated_mean_mm"], "n_train": accuracy["n_train"],
            "n_val": accuracy["n_val"]}


def main() -> None:
    figures: dict = {}
    with tempfile.TemporaryDirectory() as tmp:
        t = Path(tmp)
        out = t / "cam_pocket.src"
        figures["first_command"] = _compensate(SAMPLE, "-o", str(out))
        figures["verify"] = {"noise": _verify(SAMPLE, out), "no_noise": _verify(SAMPLE, out, "--no-noise")}
        oriented = t / "cam_pocket_o.src"
        _compensate(SAMPLE, "-o", str(oriented), "--orientation")
        figures["orientation"] = _verify(SAMPLE, oriented)

        # docs/acceptance.md, Reports: 300 fresh poses, the shipped model, measured before and after
        cli("plan", "-n", "300", "--seed", "7", "-o", str(t / "test.csv"), "-q")
        cli("compensate", str(t / "test.csv"), "-o", str(t / "test_comp.csv"), "-q")
        cli("measure", str(t / "test.csv"), "-o", str(t / "before.csv"), "-q")
        cli("measure", str(t / "test_comp.csv"), "-o", str(t / "after.csv"), "-q")
        cli("report", str(t / "before.csv"), "--after", str(t / "after.csv"), "-o", str(t / "report"), "-q")
        table2 = json.loads((t / "report" / "summary.json").read_text())["table2_mm"]
        figures["report"] = {"before": _stats(table2["before"]), "after": _stats(table2["after"])}

        # docs/acceptance.md, ISO 9283: the pose test before and after, the certificate
        cli("plan", "--iso9283", "-o", str(t / "iso.csv"), "--krl", str(t / "iso_test.src"), "-q")
        cli("measure", str(t / "iso.csv"), "-o", str(t / "ibefore.csv"), "-q")
        cli("compensate", str(t / "iso.csv"), "-o", str(t / "iso_comp.csv"), "-q")
        cli("measure", str(t / "iso_comp.csv"), "-o", str(t / "iafter.csv"), "--seed", "1", "-q")
        cli("report", "--iso9283", str(t / "ibefore.csv"), "--after", str(t / "iafter.csv"), "--model",
            "models/default.onnx", "-o", str(t / "cert"), "-q")
        iso = json.loads((t / "cert" / "iso9283.json").read_text())
        figures["iso9283"] = {f"P{p['pose']}": {"AP_before": p["AP"], "RP_before": p["RP"],
                                                "AP_after": a["AP"], "RP_after": a["RP"], "n": p["n"]}
                              for p, a in zip(iso["before"]["poses"], iso["after"]["poses"], strict=True)}

        # docs/getting-started.md: a model of your own, on the simulator and on the shipped real excerpt
        sim: dict = {}
        cli("plan", "-n", "300", "--seed", "0", "-o", str(t / "plan.csv"), "-q")
        cli("measure", str(t / "plan.csv"), "-o", str(t / "measured.csv"), "-q")
        cli("train", str(t / "measured.csv"), "-o", str(t / "my_kr500.onnx"), "-q")
        sim["card"] = _card(t / "my_kr500.onnx")
        mine = t / "cam_pocket_mine.src"
        sim["compensate"] = _compensate(SAMPLE, "--model", str(t / "my_kr500.onnx"), "-o", str(mine))
        sim["verify"] = _verify(SAMPLE, mine)
        cli("import", "ipa", "samples/ipa/series_c_excerpt.csv", "-o", str(t / "ipa.csv"), "-q")
        cli("train", str(t / "ipa.csv"), "-o", str(t / "my_ur10.onnx"), "--register", "--val-fraction", "0.2",
            "--robot", "models/ur10.toml", "-q")
        figures["first_hour"] = {"sim": sim, "ipa": {"card": _card(t / "my_ur10.onnx")}}
    print(json.dumps(figures, indent=1))
    record("doc_runs", figures)


if __name__ == "__main__":
    main()

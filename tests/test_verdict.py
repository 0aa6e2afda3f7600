"""The pass/fail verdict a cell's CI gates on (issue 27): `verify --verdict FILE` and `report`'s
verdict.json hold the limits stated, each check, the figures, the model's sha256 and the inputs'
sha256, validate against postproc/schemas/verdict.schema.json, and the exit code follows them."""
from __future__ import annotations

import hashlib
import json

import pytest
from helpers import REPO

from postproc.cli import main
from postproc.acceptance.verdict import verdict_problems

MODEL = REPO / "models" / "default.onnx"


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    folder = tmp_path_factory.mktemp("verdict")
    plan, comp = folder / "plan.csv", folder / "plan_comp.csv"
    assert main(["plan", "-n", "30", "--seed", "6", "-o", str(plan), "-q"]) == 0
    assert main(["compensate", str(plan), "-o", str(comp), "-q"]) == 0
    assert main(["measure", str(plan), "-o", str(folder / "before.csv"), "-q"]) == 0
    assert main(["measure", str(comp), "-o", str(folder / "after.csv"), "-q"]) == 0
    return folder


def _read(path):
    document = json.loads(path.read_text())
    assert verdict_problems(document) == []
    return document


def test_verify_verdict_passes_and_fails_with_its_limits(campaign, tmp_path):
    args = ["verify", str(campaign / "plan.csv"), str(campaign / "plan_comp.csv"), "--model", str(MODEL), "-q"]
    ok = tmp_path / "ok.json"
    assert main([*args, "--max-mean", "0.2", "--max-max", "0.5", "--verdict", str(ok)]) == 0
    document = _read(ok)
    assert document["passed"] and [c["figure"] for c in document["checks"]] == ["after.mean", "after.max"]
    assert document["model"]["sha256"] == hashlib.sha256(MODEL.read_bytes()).hexdigest()
    assert document["inputs"]["original"]["sha256"] == hashlib.sha256((campaign / "plan.csv").read_bytes()).hexdigest()
    mean = document["figures"]["after"]["mean"]
    assert document["checks"][0]["value"] == mean < 0.2 < document["figures"]["before"]["mean"]
    bad = tmp_path / "bad.json"
    assert main([*args, "--max-mean", f"{mean / 2:.6f}", "--verdict", str(bad)]) == 1
    failed = _read(bad)
    assert not failed["passed"] and not failed["checks"][0]["passed"]
    # no limits: the figures recorded, passed
    assert main([*args, "--verdict", str(tmp_path / "none.json")]) == 0
    assert _read(tmp_path / "none.json")["limits_stated"] is False


def test_report_writes_its_verdict(campaign, tmp_path):
    out = tmp_path / "report"
    args = ["report", str(campaign / "before.csv"), "--after", str(campaign / "after.csv"), "--model", str(MODEL),
            "-o", str(out), "-q"]
    assert main([*args, "--max-p95", "0.3"]) == 0
    document = _read(out / "verdict.json")
    assert document["kind"] == "report" and document["passed"]
    assert main([*args, "--max-p95", "0.001"]) == 1
    assert not _read(out / "verdict.json")["passed"]
    assert main([*args, "--max-orientation-mean", "-1"]) == 2  # a limit that is no positive number


def test_the_schema_refuses_a_malformed_verdict(campaign, tmp_path):
    path = tmp_path / "v.json"
    assert main(["verify", str(campaign / "plan.csv"), str(campaign / "plan_comp.csv"), "--max-mean", "1",
                 "--verdict", str(path), "-q"]) == 0
    document = _read(path)
    assert document["model"] is None  # (no --model: the programs alone)
    del document["passed"]
    document["checks"][0]["figure"] = "after.median"
    assert len(verdict_problems(document)) == 2

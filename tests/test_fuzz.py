"""Mutation fuzzing in the suite: a few hundred mutants of the sample corpus (the full count is
``benchmarks/fuzz.py``; the engine is ``postproc.testing.fuzz``). Every mutant compensates to an output that round-trips, or is refused
with a located message and nothing written; never a crash, a wrong output or a hang."""
import numpy as np
import pytest

from helpers import REPO

from postproc.testing import fuzz  # the one fuzzer: the benchmark runs it at full size, the suite small


def test_corpus_holds_every_sample_program():
    names = {s.name for s in fuzz.corpus()}
    assert {"drill_plate.csv", "sweep.txt"} <= names
    krl = REPO / "samples" / "krl"
    if krl.is_dir():
        assert {p.name for p in krl.glob("*.src")} <= names


@pytest.mark.slow
def test_mutants_end_in_a_clean_output_or_a_clean_error():
    counts, codes, bad = fuzz.fuzz(300, seed=20240601, subprocesses=3, timeout=10.0)
    assert bad == []
    assert counts["crash"] == counts["wrong"] == counts["hang"] == 0
    assert counts["output"] + counts["error"] == 300
    # not a degenerate fuzz: many mutants still compensate, many are refused, for several reasons
    assert counts["output"] >= 30 and counts["error"] >= 30
    assert len(codes) >= 3


def test_the_checker_catches_a_wrong_output(tmp_path):
    """The round-trip check is what the fuzz relies on: it must reject outputs that are off."""
    from postproc.testing.models import affine_model
    from postproc.compensation.api import compensate_text
    from postproc.model.compensator import load_model

    model = load_model(affine_model(tmp_path / "m.onnx", offset=fuzz.OFFSET))
    text = "x,y,z,a,b,c\n2000.000,0.000,900.000,0,90,0\n2100.5,-5,950,0,90,0\n"
    out, _ = compensate_text(text, model, name="p.csv")
    assert fuzz.check_output(["p.csv"], [text], [out], model) is None
    for wrong, why in [
        (out.replace("2000.300", "2000.301"), "expected a change of"),  # one µm off
        (out.replace("-0.200,900.100", "-0.200 ,900.100"), "bytes outside the number tokens"),
        (out.replace(",0,90,0\n", ",0,91,0\n", 1), "bytes outside the number tokens"),  # orientation changed
        (out.split("\n", 1)[1], "no stamp line"),
        (out.replace("2100.800,-5.200,950.100,0,90,0\n", ""), "targets before"),
    ]:
        assert wrong != out
        assert why in (fuzz.check_output(["p.csv"], [text], [wrong], model) or ""), why


def test_mutations_are_varied_and_reproducible():
    sample = fuzz.Sample("p.csv", {"p.csv": b"x,y,z\n1.5,2.5,3.5\n"})
    first = [fuzz.mutate(sample, np.random.default_rng(s)).files["p.csv"] for s in range(200)]
    again = [fuzz.mutate(sample, np.random.default_rng(s)).files["p.csv"] for s in range(200)]
    assert first == again
    assert len(set(first)) > 150
    assert any(len(m) < 10 for m in first) and any(len(m) > 25 for m in first)  # truncations, insertions

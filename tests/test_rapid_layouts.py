"""The RAPID analysis does not depend on the layout (issue 36's property): every RAPID program the
samples hold and random programs of the interpreter property's generator, laid out again as a
controller or an editor writes them (postproc.testing.reflow: CRLF; statements joined onto the line
of THEN/ELSE/DO/a label; argument lists, aggregates and routine headers broken over lines; the
required arguments of the motions given by name; the whole module on one line; all of these at once), give the same targets in the
same frames with the same tools, the same findings, the same commands, and a lossless rewrite of
the reflowed text (only number tokens change); the random programs, in every layout at once, also
pass the interpreter's property (the program and its compensated output run on every path)."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings

from postproc.compensation.api import compensate_text
from postproc.model.compensator import load_model
from postproc.programs.io import parse_program_text
from postproc.testing.generate import rapid_programs
from postproc.testing.oracle import check
from postproc.testing.reflow import LAYOUTS

SAMPLES = sorted(p for p in (Path(__file__).resolve().parent.parent / "samples").rglob("*")
                 if p.suffix.lower() in (".mod", ".prg", ".sys", ".modx"))
NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    from postproc.testing.models import affine_model

    path = affine_model(tmp_path_factory.mktemp("layouts") / "m.onnx", offset=(0.3, -0.2, 0.1),
                        gain=np.diag([2e-3, -1e-3, 3e-3]), reach=None, envelope=None, tool={"name": "any"})
    return load_model(path)


def _analysis(program):
    t = program.targets
    frames = [(program.frames[f].base.round(9).tolist(),
               None if program.frames[f].tool is None else np.round(program.frames[f].tool, 9).tolist())
              if f >= 0 else None for f in t.frame.tolist()]
    # (the codes, not how often: a finding is one per cause, and a cause that names its line — "called at
    # line 6" — is one cause where a layout puts two on one line)
    return np.nan_to_num(t.poses, nan=1e300).round(6).tolist(), frames, sorted({d.code for d in program.diagnostics})


def _same(text: str, name: str, model, layout: str):
    other = LAYOUTS[layout](text)
    assert other != text or layout in ("by_name", "join_heads", "flat")
    a, b = parse_program_text(text, name), parse_program_text(other, name)
    assert _analysis(a) == _analysis(b), layout
    out_a, rep_a = compensate_text(text, model, name=name)
    out_b, rep_b = compensate_text(other, model, name=name)
    assert (rep_a.compensated, sorted(rep_a.left_codes), sorted({w.code for w in rep_a.warnings})) == \
        (rep_b.compensated, sorted(rep_b.left_codes), sorted({w.code for w in rep_b.warnings})), layout
    # the same commands, and the reflowed text rewritten losslessly: only its number tokens changed
    assert _analysis(parse_program_text(out_a, name))[0] == _analysis(parse_program_text(out_b, name))[0], layout
    stamp_free = "\n".join(line for line in out_b.split("\n") if "postproc: compensated" not in line)
    assert NUMBER.sub("#", stamp_free) == NUMBER.sub("#", other), layout


@pytest.mark.parametrize("layout", list(LAYOUTS))
@pytest.mark.parametrize("sample", SAMPLES, ids=[p.name for p in SAMPLES])
def test_every_sample_reads_the_same_in_every_layout(sample, layout, model):
    _same(sample.read_text("latin-1"), sample.name, model, layout)


@settings(max_examples=25, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(program=rapid_programs())
def test_random_programs_read_the_same_in_every_layout(program, model):
    files, texts, _ = program
    for layout in LAYOUTS:
        _same(texts[0], files[0], model, layout)
    # and the interpreter's property on every path of the program laid out in every way at once (motion
    # arguments by name, heads and statements on one line, lists over lines): never silently wrong
    checked = check(files, [LAYOUTS["all"](texts[0])], "rapid", model, seeds=range(2))
    assert checked.violations == [], "\n".join(checked.violations)

"""A repository of compensated programs passes its own pre-commit check (issue 38, item 1): `postproc
check` on a compensated output says what it says of its source — never "already compensated"
(P401), which is compensate's refusal, not a finding of check: a stamp is checked by P402-P404.
Every family's sample (getting-started's commands), loops and calls included, and the README's
weld cell with its $config.dat (points run more than once)."""
from __future__ import annotations

import re
import shlex

import pytest

from postproc.cli import main

from helpers import REPO

PAGE = (REPO / "docs" / "getting-started.md").read_text()
SECTION = PAGE.split("\n## A robot of each family", 1)[1].split("\n## ", 1)[0]
COMMANDS = [shlex.split(line.split("#", 1)[0]) for line in SECTION.split("```sh\n", 1)[1].split("```", 1)[0].splitlines()
            if line.strip()]
CONFIG = str(REPO / "samples" / "krl" / "config" / "$config.dat")
COMMANDS.append(["postproc", "compensate", "samples/krl/weld_cell.src", "--config", CONFIG, "-o", "out/weld_cell.src"])
CODE = re.compile(r": (P\d{3}) ")


def _check(argv, capsys) -> tuple[int, list[str]]:
    code = main(argv)
    printed = capsys.readouterr()
    return code, sorted(CODE.findall(printed.out + printed.err))


@pytest.mark.parametrize("argv", COMMANDS, ids=lambda a: a[2])
def test_a_compensated_output_checks_as_its_source(tmp_path, capsys, monkeypatch, argv):
    monkeypatch.chdir(REPO)
    source = argv[2]
    options = argv[3:argv.index("-o")]
    out = tmp_path / "out" / source.split("/")[-1]
    assert main(["compensate", source, *options, "-o", str(out)]) in (0, 1)
    capsys.readouterr()
    written = [str(out)] + ([str(out.with_suffix(".dat"))] if out.with_suffix(".dat").is_file() else [])
    before = _check(["check", source, *options], capsys)
    after = _check(["check", *written, *options], capsys)
    assert "P401" not in after[1]
    assert after == before, (before, after)  # the same exit code and findings

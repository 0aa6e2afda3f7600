"""The benchmark figures of the README and the docs are the benchmarks' recorded results
(benchmarks/results/*.json), not numbers copied by hand: benchmarks/figures.py checks every marked
figure of every Markdown file that holds one."""
import subprocess
import sys

import pytest

from helpers import REPO

FIGURES = [sys.executable, str(REPO / "benchmarks" / "figures.py")]


def _tracked_markdown_with_markers() -> list[str]:
    """What git tracks (README.md, docs/, models/, samples/): the pages a reader gets."""
    listed = subprocess.run(["git", "ls-files", "*.md"], cwd=REPO, capture_output=True, text=True, check=True)
    return sorted(name for name in listed.stdout.split() if "<!-- fig " in (REPO / name).read_text())


def test_every_figure_matches_the_recorded_results():
    run = subprocess.run(FIGURES, capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr


def test_every_page_with_markers_is_checked():
    pages = _tracked_markdown_with_markers()
    assert {"README.md", "docs/acceptance.md", "models/README.md"} <= set(pages)
    listed = subprocess.run(FIGURES + ["--list"], capture_output=True, text=True, check=True).stdout.split()
    assert sorted(listed) == pages


@pytest.mark.parametrize("page", _tracked_markdown_with_markers())
def test_a_figure_that_differs_is_reported(tmp_path, page):
    text = (REPO / page).read_text()
    marked = text.index("<!-- fig ")
    start = marked - 1
    while text[start - 1].isdigit() or text[start - 1] in ",.":
        start -= 1
    wrong = tmp_path / "page.md"
    wrong.write_text(text[:start] + "9" + text[start:])  # one more digit in front
    run = subprocess.run(FIGURES + [str(wrong)], capture_output=True, text=True)
    assert run.returncode == 1 and "the result" in run.stdout
    subprocess.run(FIGURES + ["--update", str(wrong)], check=True, capture_output=True)
    assert wrong.read_text() == text

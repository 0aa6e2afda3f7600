"""The README's benchmark figures are the benchmarks' recorded results (benchmarks/results/*.json),
not numbers copied by hand: benchmarks/figures.py checks every marked figure."""
import subprocess
import sys

from helpers import REPO


def test_readme_figures_match_the_recorded_results():
    run = subprocess.run([sys.executable, str(REPO / "benchmarks" / "figures.py")], capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr


def test_a_figure_that_differs_is_reported(tmp_path):
    readme = (REPO / "README.md").read_text()
    marked = readme.index("<!-- fig ")
    start = marked - 1
    while readme[start - 1].isdigit() or readme[start - 1] in ",.":
        start -= 1
    wrong = tmp_path / "README.md"
    wrong.write_text(readme[:start] + "9" + readme[start:])  # one more digit in front
    run = subprocess.run([sys.executable, str(REPO / "benchmarks" / "figures.py"), str(wrong)],
                         capture_output=True, text=True)
    assert run.returncode == 1 and "the result" in run.stdout
    subprocess.run([sys.executable, str(REPO / "benchmarks" / "figures.py"), "--update", str(wrong)], check=True,
                   capture_output=True)
    assert wrong.read_text() == readme

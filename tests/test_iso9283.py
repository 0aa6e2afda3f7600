"""ISO 9283 pose test: the cube and its points, clustering, AP/RP against hand computations,
the plan and report routes, the simulated cell end to end, the IPA Series D excerpt, and the
certificate in a real headless browser."""
import json
import math
import os
import shutil
import subprocess

import numpy as np
import pytest

from postproc.cli import main
from postproc.measurements.datasets import read_ipa
from postproc.measurements.csv import write_measurements
from postproc.core.diagnostics import PostprocError
from postproc.acceptance.iso9283 import (
    CYCLE_ORDER, IsoCube, cluster_poses, largest_cube, orientation_deviation, pose_figures, read_iso_result,
    pose_test_plan,
)
from postproc.core.resources import model_path, sample_path

IPA_EXCERPT = sample_path("ipa/series_d_excerpt.csv")


def test_cube_points_lie_in_the_diagonal_plane_at_ten_percent_of_its_diagonal():
    cube = IsoCube((100.0, -20.0, 700.0), 200.0)
    p = cube.points()
    assert p[0].tolist() == [100.0, -20.0, 700.0]
    corners = cube.plane_corners
    diagonal = np.linalg.norm(corners[2] - corners[0])  # √(200² + (200√2)²)
    assert diagonal == pytest.approx(200.0 * math.sqrt(3))
    # P2 by hand: C1 = (0, −120, 600), 10 % of the way to C3 = (200, 80, 800)
    assert p[1].tolist() == pytest.approx([20.0, -100.0, 620.0])
    assert np.linalg.norm(p[1:] - corners, axis=1) == pytest.approx([0.1 * diagonal] * 4)
    # the plane through the lower edge at Y0 and the upper edge at Y1: y − z is constant on it
    assert np.ptp(p[:, 1] - p[:, 2]) == pytest.approx(0.0)
    poses, numbers = pose_test_plan(cube, (0.0, 90.0, 0.0), cycles=4)
    assert numbers.tolist() == list(CYCLE_ORDER) * 4 and CYCLE_ORDER == (1, 5, 4, 3, 2)
    assert np.array_equal(poses[:, :3], p[numbers - 1]) and (poses[:, 4] == 90.0).all()


def test_largest_cube_fills_the_shortest_side_and_shrinks_until_reachable():
    box = (0.0, 1000.0, -300.0, 300.0, 0.0, 800.0)
    assert largest_cube(box) == IsoCube((500.0, 0.0, 400.0), 600.0)

    def within(poses):  # a reach sphere of 250 mm around the box centre
        return np.linalg.norm(poses[:, :3] - [500.0, 0.0, 400.0], axis=1) <= 250.0

    cube = largest_cube(box, within)
    assert within(np.hstack([cube.points(), np.zeros((5, 3))])).all()
    assert cube.side < 600.0 and not within(np.hstack([IsoCube(cube.centre, cube.side / 0.95).points(),
                                                       np.zeros((5, 3))])).all()
    with pytest.raises(PostprocError) as err:
        largest_cube(box, lambda poses: np.zeros(len(poses), bool))
    assert err.value.code == "P335"


def test_ap_rp_match_a_hand_computation():
    # pose 1: four attained positions around (0.3, 0, −0.4) from the command (0, 0, 0):
    # barycentre offset (0.3, 0, −0.4) → AP = 0.5; l = 1, 1, 2, 2 → l̄ = 1.5, S_l = √(1/3), RP = 1.5 + √3
    # pose 2: three cycles at (100, 0, 0) attained (100, 0, 1), (100, 0, 1), (100, 0, 1) → AP 1, RP 0
    cmd = np.array([[0, 0, 0, 0, 0, 0]] * 4 + [[100, 0, 0, 0, 0, 0]] * 3, float)
    ring = np.array([[1, 0, 0], [-1, 0, 0], [0, 2, 0], [0, -2, 0]], float) + [0.3, 0.0, -0.4]
    att = np.vstack([ring, [[100, 0, 1]] * 3])
    # orientation of pose 1: C (about X, as A = B = 0) attained 0.1, −0.1, 0.3, −0.3 → APa 0,
    # S_a = √(0.2 / 3), RPa = 3·S_a; B attained 0.2 each → APb = 0.2 (about Y), RPb 0
    abc = np.array([[0, 0.2, 0.1], [0, 0.2, -0.1], [0, 0.2, 0.3], [0, 0.2, -0.3]] + [[0, 0, 0]] * 3)
    labels = cluster_poses(cmd)
    assert labels.tolist() == [0, 0, 0, 0, 1, 1, 1]
    f = pose_figures(cmd, att, labels, abc)
    assert f.n.tolist() == [4, 3]
    assert f.ap_xyz[0] == pytest.approx([0.3, 0.0, -0.4]) and f.ap[0] == pytest.approx(0.5)
    assert f.l_mean[0] == pytest.approx(1.5) and f.s_l[0] == pytest.approx(math.sqrt(1 / 3))
    assert f.rp[0] == pytest.approx(1.5 + math.sqrt(3))
    assert f.ap[1] == pytest.approx(1.0) and f.rp[1] == pytest.approx(0.0, abs=1e-12)
    assert f.ap_abc[0] == pytest.approx([0.0, 0.2, 0.0], abs=2e-5)  # small-angle: B about Y
    assert f.rp_abc[0, 0] == pytest.approx(3 * math.sqrt(0.2 / 3), rel=1e-4)
    assert f.rp_abc[0, 1] == pytest.approx(0.0, abs=1e-4)


def test_orientation_is_compared_as_rotations_not_as_abc_numbers():
    # at B = 90° only A − C matters: (10, 90, 10) is the same rotation as (0, 90, 0)
    cmd = np.array([[0, 0, 0, 0, 90, 0], [0.2, 0, 0, 10, 90, 10], [0, 0, 0, 0, 90, 1]], float)
    assert cluster_poses(cmd).tolist() == [0, 0, 1]
    dev = orientation_deviation(cmd[:1, 3:], np.array([[10.0, 90.0, 10.0]]))
    assert dev == pytest.approx(np.zeros((1, 3)), abs=1e-9)
    dev = orientation_deviation(np.array([[0.0, 90.0, 0.0]]), np.array([[0.3, 90.0, 0.0]]))
    assert dev[0] == pytest.approx([0.0, 0.0, 0.3])  # A turns about the base Z axis


def test_jittered_commands_cluster_to_their_poses_in_order_of_first_visit():
    rng = np.random.default_rng(1)
    nominal = np.array([[2000, 0, 900, 0, 90, 0], [1900, 100, 800, 0, 90, 0], [1900, 100, 805, 0, 90, 0]], float)
    order = np.array([2, 0, 1] * 5)
    cmd = nominal[order] + np.hstack([rng.uniform(-0.1, 0.1, (15, 3)), np.zeros((15, 3))])
    labels = cluster_poses(cmd)
    assert labels.tolist() == [0, 1, 2] * 5  # 5 mm apart: separate poses
    assert len(np.unique(cluster_poses(cmd, position_mm=10.0))) == 2


def _write(path, cmd, measured, **extra):
    write_measurements(path, cmd, measured, {k: v for k, v in extra.items() if k != "meta"}, extra.get("meta"))


def test_report_iso_reads_files_refuses_tracker_frame_and_checks_after_rows(tmp_path, capsys):
    cube = IsoCube((2000.0, 0.0, 900.0), 300.0)
    cmd, numbers = pose_test_plan(cube, (0.0, 90.0, 0.0), cycles=3)
    offset = np.array([[0.1, 0, 0], [0, 0.2, 0], [0, 0, 0.3], [0.4, 0, 0], [0, 0.5, 0]])[numbers - 1]
    _write(tmp_path / "before.csv", cmd, cmd[:, :3] + offset)
    comp = cmd.copy()
    comp[:, :3] -= offset  # the compensated program: the robot then reaches the nominal pose
    _write(tmp_path / "after.csv", comp, cmd[:, :3] + 0.01)
    result = read_iso_result(tmp_path / "before.csv", tmp_path / "after.csv")
    assert result.before.n.tolist() == [3] * 5
    assert result.before.ap == pytest.approx([0.1, 0.5, 0.4, 0.3, 0.2])  # P1, then P5, P4, P3, P2 by first visit
    assert result.after.ap == pytest.approx([0.01 * math.sqrt(3)] * 5)
    assert main(["report", "--iso9283", str(tmp_path / "before.csv"), "--after", str(tmp_path / "after.csv"),
                 "-o", str(tmp_path / "cert")]) == 0
    summary = json.loads((tmp_path / "cert" / "iso9283.json").read_text())
    assert summary["before"]["overall"]["AP_max"] == pytest.approx(0.5)
    md = (tmp_path / "cert" / "certificate.md").read_text()
    assert "not recorded" in md and "Fewer than the standard's 30 cycles" in md
    _write(tmp_path / "tracker.csv", cmd, cmd[:, :3], meta={"frame": "tracker"})
    assert main(["report", "--iso9283", str(tmp_path / "tracker.csv"), "-o", str(tmp_path / "x")]) == 2
    assert "P513" in capsys.readouterr().err
    _write(tmp_path / "short.csv", comp[:-1], cmd[:-1, :3])
    with pytest.raises(PostprocError) as err:
        read_iso_result(tmp_path / "before.csv", tmp_path / "short.csv")
    assert err.value.code == "P503"


def test_plan_iso9283_writes_the_plan_and_a_krl_program(tmp_path, capsys):
    plan, src = tmp_path / "iso.csv", tmp_path / "iso_test.src"
    assert main(["plan", "--iso9283", "--cycles", "30", "-o", str(plan), "--krl", str(src)]) == 0
    rows = np.loadtxt(plan, delimiter=",", skiprows=1)
    assert rows.shape == (150, 8)
    assert rows[:, 6].astype(int).tolist() == list(CYCLE_ORDER) * 30
    assert rows[:, 7].astype(int).tolist() == [c for c in range(1, 31) for _ in range(5)]
    # the default workspace box X 1700..2300, Y -600..600, Z 500..1300: cube side 600 at its centre
    assert rows[0, :3].tolist() == [2000.0, 0.0, 900.0]
    assert rows[4, :3].tolist() == pytest.approx([1760.0, -240.0, 660.0])  # P2
    text = src.read_text()
    assert text.count("MEASURE_HERE( )\n") == 150 + 1  # 150 calls and the subroutine's DEF
    assert "ISO 9283 pose test" in text
    assert main(["plan", "--iso9283", "--cube", "0", "0", "0", "400", "-o", str(tmp_path / "far.csv")]) == 2
    assert "P335" in capsys.readouterr().err and not (tmp_path / "far.csv").exists()


def test_simulated_cell_end_to_end(tmp_path):
    """plan → measure → compensate → measure → report on the simulated KR500."""
    d = tmp_path
    assert main(["plan", "--iso9283", "--cycles", "4", "-o", str(d / "iso.csv")]) == 0
    assert main(["measure", str(d / "iso.csv"), "-o", str(d / "before.csv")]) == 0
    assert main(["compensate", str(d / "iso.csv"), "-o", str(d / "comp.csv")]) == 0
    assert main(["measure", str(d / "comp.csv"), "-o", str(d / "after.csv"), "--seed", "1"]) == 0
    assert main(["report", "--iso9283", str(d / "before.csv"), "--after", str(d / "after.csv"),
                 "--model", str(model_path()), "-o", str(d / "cert")]) == 0
    s = json.loads((d / "cert" / "iso9283.json").read_text())
    before = [p["AP"] for p in s["before"]["poses"]]
    after = [p["AP"] for p in s["after"]["poses"]]
    assert len(before) == 5 and all(p["n"] == 4 for p in s["before"]["poses"])
    assert max(after) < 0.5 * max(before)
    md = (d / "cert" / "certificate.md").read_text()
    # the shipped model's card holds its identification: the parameters that moved, with units
    assert "KR500-sim" in md and "Identified parameters that moved" in md and "backlash.A5" in md
    # measure carried the plan's pose column: the report names each pose as the plan does (the
    # cycles visit P1 P5 P4 P3 P2: numbered by first appearance P5 would be "P2")
    plan = np.loadtxt(d / "iso.csv", delimiter=",", skiprows=1)
    for entry in s["before"]["poses"]:
        assert entry["command"][:3] == pytest.approx(plan[plan[:, 6] == entry["pose"]][0, :3], abs=1e-6)
    assert [p["pose"] for p in s["before"]["poses"]] == [1, 2, 3, 4, 5]
    p5 = plan[plan[:, 6] == 5][0, :3]
    assert f"| P5 | 4 | {p5[0]:.1f}, {p5[1]:.1f}, {p5[2]:.1f} |" in md and "numbered by first appearance" not in md
    # the parameter counts of the moved-parameter note and of the identifiability come from one list
    import re

    moved = re.search(r"(\d+) of (\d+) identified parameters moved.*?(\d+) of them the data does not determine", md)
    alone = re.search(r"(\d+) of (\d+) parameters are not determined alone", md)
    assert moved and alone and moved.group(2) == alone.group(2) and moved.group(3) == alone.group(1)


def test_a_pose_column_is_the_plans_and_must_name_one_pose_each(tmp_path):
    """A measurement CSV with the plan's pose column (``postproc measure`` keeps it): the poses
    are named by it; a number on two different commands, or two numbers on one, is refused
    (P503) rather than mixed into one pose's figures; without it the poses are numbered by first
    appearance, and the table says so."""
    cube = IsoCube((2000.0, 0.0, 900.0), 300.0)
    cmd, numbers = pose_test_plan(cube, (0.0, 90.0, 0.0), cycles=2)
    offset = np.array([[0.1, 0, 0], [0, 0.2, 0], [0, 0, 0.3], [0.4, 0, 0], [0, 0.5, 0]])[numbers - 1]
    _write(tmp_path / "labelled.csv", cmd, cmd[:, :3] + offset, pose=numbers)
    result = read_iso_result(tmp_path / "labelled.csv")
    assert result.before.ap == pytest.approx([0.1, 0.2, 0.3, 0.4, 0.5])  # P1…P5, the plan's numbers
    assert [result.before.name(k) for k in range(5)] == ["P1", "P2", "P3", "P4", "P5"]
    wrong = numbers.copy()
    wrong[6] = wrong[5]  # the second cycle's P5 and P4 both called P5
    _write(tmp_path / "wrong.csv", cmd, cmd[:, :3] + offset, pose=wrong)
    with pytest.raises(PostprocError) as err:
        read_iso_result(tmp_path / "wrong.csv")
    assert err.value.code == "P503" and err.value.line == 8
    _write(tmp_path / "bare.csv", cmd, cmd[:, :3] + offset)
    from postproc.acceptance.iso9283 import iso_markdown

    assert any("numbered by first appearance" in line for line in iso_markdown(read_iso_result(tmp_path / "bare.csv")))


def test_ipa_series_d_excerpt(tmp_path):
    """27 real rows (3 cycles of a 400 mm cube's centre and its 8 corners, commands jittered by
    ~0.1 mm between cycles): 9 poses of n = 3, row k with rows k + 9 and k + 18; AP and RP
    checked against a row-by-row computation here on the imported (base frame) file."""
    from postproc.measurements.csv import parse_measurements

    out = tmp_path / "d.csv"
    assert main(["import", "ipa", str(IPA_EXCERPT), "-o", str(out), "--register", "--val-fraction", "0"]) == 0
    result = read_iso_result(out)
    assert result.before.n.tolist() == [3] * 9
    assert result.labels.tolist() == list(range(9)) * 3
    m = parse_measurements(out.read_bytes(), str(out), repeats=True)
    for k in range(9):
        d = [m.measured[r] - m.poses[r, :3] for r in (k, k + 9, k + 18)]
        centre = sum(d) / 3
        l = [math.dist(v, centre) for v in d]
        mean = sum(l) / 3
        s_l = math.sqrt(sum((x - mean) ** 2 for x in l) / 2)
        assert result.before.ap[k] == pytest.approx(math.hypot(*centre), abs=1e-9)
        assert result.before.rp[k] == pytest.approx(mean + 3 * s_l, abs=1e-9)
    assert 0.1 < result.before.ap.max() < 2.0 and result.before.rp.max() < 0.5
    raw = read_ipa(IPA_EXCERPT)  # the repeatability of the attained positions alone is frame-free
    spread = [np.linalg.norm(raw.measured[[k, k + 9, k + 18]] - raw.measured[[k, k + 9, k + 18]].mean(0), axis=1)
              for k in range(9)]
    base = [np.linalg.norm(m.measured[[k, k + 9, k + 18]] - m.measured[[k, k + 9, k + 18]].mean(0), axis=1)
            for k in range(9)]
    assert np.allclose(spread, base, atol=1e-6)


CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
NO_BROWSER = ("chromium not installed: scripts/install-browser installs Debian's chromium with apt-get "
              "where it may (root, or sudo without a password); else: sudo apt-get install chromium")


def _readme_test_command() -> str:
    from helpers import REPO

    text = (REPO / "README.md").read_text()
    block = text.split("Install everything (simulator, training, reports, docs, tests) and run the tests:")[1]
    return block.split("```sh\n")[1].split("\n```")[0]


def test_the_ci_provides_the_browser_then_runs_the_readme_test_command():
    """A person types the README's command (no apt-get, no sudo in it); CI runs the browser
    script first, with CI set (the browser test then fails instead of skipping), then exactly
    that command."""
    from helpers import REPO

    command = _readme_test_command()
    assert "\n" not in command and command.endswith("python -m pytest -q")
    assert "apt-get" not in command and "sudo" not in command and len(command) < 150
    ci = (REPO / ".ci" / "run").read_text().splitlines()
    assert ci[-1] == command and 'export CI="${CI:-true}"' in ci
    assert "scripts/install-browser" in ci[:-1] and ci.index('export CI="${CI:-true}"') < ci.index("scripts/install-browser")
    script = REPO / "scripts" / "install-browser"
    assert os.access(script, os.X_OK) and "apt-get install -y -qq chromium" in script.read_text()


@pytest.mark.parametrize("apt_works", [True, False])
def test_the_browser_script_installs_chromium_with_apt_or_says_why_not(tmp_path, apt_works):
    """scripts/install-browser under bash, with a PATH of stubs (no chromium, an apt-get that
    records its arguments and succeeds as root would, or fails without root and no sudo): it
    installs Debian's package, or says why not and exits 0, so that the tests still run."""
    from helpers import REPO

    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    log = tmp_path / "apt.log"
    (bin_dir / "apt-get").write_text(f'#!/bin/sh\necho "$@" >> {log}\nexit {0 if apt_works else 100}\n')
    (bin_dir / "apt-get").chmod(0o755)
    (bin_dir / "env").symlink_to(shutil.which("env"))
    bash = shutil.which("bash")
    run = subprocess.run([bash, "-euo", "pipefail", "-c", f"{bash} {REPO / 'scripts' / 'install-browser'}; echo step-done"],
                         capture_output=True, text=True, env={"PATH": str(bin_dir)}, timeout=30)
    assert run.returncode == 0 and run.stdout.endswith("step-done\n"), run.stdout + run.stderr
    calls = log.read_text().splitlines()
    if apt_works:
        assert calls == ["update -qq", "install -y -qq chromium"] and "no chromium" not in run.stdout
    else:  # one try as is (sudo is not there): a note, and the tests still run
        assert calls == ["update -qq"] and "no chromium (apt-get needs root or sudo)" in run.stdout


def test_certificate_html_renders_offline_in_a_headless_browser(tmp_path):
    from matplotlib.image import imread

    if CHROMIUM is None:
        if os.environ.get("CI", "").lower() not in ("", "0", "false"):
            pytest.fail(NO_BROWSER + " (CI is set: this test must run)")
        pytest.skip(NO_BROWSER)

    cube = IsoCube((2000.0, 0.0, 900.0), 300.0)
    cmd, numbers = pose_test_plan(cube, (0.0, 90.0, 0.0), cycles=3)
    rng = np.random.default_rng(0)
    _write(tmp_path / "b.csv", cmd, cmd[:, :3] + 0.5 + rng.normal(scale=0.02, size=(15, 3)))
    _write(tmp_path / "a.csv", cmd, cmd[:, :3] + 0.05 + rng.normal(scale=0.02, size=(15, 3)))
    assert main(["report", "--iso9283", str(tmp_path / "b.csv"), "--after", str(tmp_path / "a.csv"),
                 "-o", str(tmp_path / "cert")]) == 0
    page = tmp_path / "cert" / "certificate.html"
    text = page.read_text()
    assert "http" not in text.replace("http-equiv", "") and 'src="data:image/png;base64,' in text
    (tmp_path / "cert" / "certificate.png").unlink()  # the page must not need the file beside it
    shot = tmp_path / "shot.png"
    subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", f"--screenshot={shot}",
                    "--window-size=1200,1600", page.as_uri()], check=True, capture_output=True, timeout=120)
    image = imread(shot)[..., :3]
    assert image.shape[:2] == (1600, 1200)
    assert image.std() > 0.1  # not a blank page
    red = (image[..., 0] > 0.75) & (image[..., 1] < 0.25) & (image[..., 2] < 0.25)  # the 'before' bars
    blue = (image[..., 2] > 0.6) & (image[..., 0] < 0.25)  # the 'after' bars
    assert red.sum() > 2000 and blue.sum() > 500
    # the AP plot (left half) as the data: before ~0.87 mm, after ~0.1 mm: the red bars ~8x the blue
    left = slice(0, image.shape[1] // 2)
    assert red[:, left].sum() > 4 * blue[:, left].sum()
    # text above the plots: the title at the top and many separate lines (the tables' rows)
    dark = image.max(axis=-1) < 0.35
    plots = np.flatnonzero(red.any(axis=1))[0]
    assert dark[:60].sum() > 1000  # "Calibration certificate — ISO 9283 pose test"
    lines = dark[:plots - 40].any(axis=1).astype(int)
    assert (np.diff(lines) == 1).sum() >= 20


def test_a_certificate_of_simulated_data_or_a_demonstration_model_says_so_on_its_face(tmp_path, affine):
    """(issue 38, item 7) The ISO 9283 certificate built from the simulator's measurements or with a
    demonstration model says so in its title, a notice before everything else and the first row of
    its table (Markdown and HTML); from real-looking data and a model of no simulated robot, none."""
    d = tmp_path
    assert main(["plan", "--iso9283", "--cycles", "3", "-o", str(d / "plan.csv"), "-q"]) == 0
    assert main(["measure", str(d / "plan.csv"), "-o", str(d / "sim.csv"), "-q"]) == 0
    assert main(["report", "--iso9283", str(d / "sim.csv"), "--model", str(model_path()),
                 "-o", str(d / "demo"), "-q"]) == 0
    md, page = (d / "demo" / "certificate.md").read_text(), (d / "demo" / "certificate.html").read_text()
    title = md.splitlines()[0]
    assert title.endswith("— SIMULATED DATA") and md.splitlines()[2].startswith("> **Not a certificate of a real robot")
    assert "measurements are simulated" in md and "demonstration model of a simulated robot (KR500-sim)" in md
    assert "| status |" in md and 'class="notice"' in page and "SIMULATED DATA</h1>" in page
    # the same rows without the simulator's lines, and a model of no simulated robot: a certificate as before
    real = "".join(line for line in (d / "sim.csv").read_text().splitlines(True)
                   if not line.startswith(("# simulated", "# robot_seed")))
    (d / "real.csv").write_text(real)
    assert main(["report", "--iso9283", str(d / "real.csv"), "--model", str(affine(offset=(0.1, 0, 0))),
                 "-o", str(d / "real"), "-q"]) == 0
    md = (d / "real" / "certificate.md").read_text()
    assert md.splitlines()[0] == "# Calibration certificate — ISO 9283 pose test"
    assert "Not a certificate of a real robot" not in md and "| status |" not in md

"""Orientation shown honestly (issue 38, item 6): near B = ±90° the A,B,C triple nearest the
one written may move A and C far for a small rotation — said once per file (P323, printed
without -v), the triple still the nearest exact one; verify and report say when the
orientation was not corrected (position only)."""
import re

import numpy as np
import pytest

from postproc.cli import main
from postproc.core import frames


def program(path, b_deg, n=12, seed=1):
    rng = np.random.default_rng(seed)
    lines = ["DEF g()", "  $BASE = {X 0, Y 0, Z 0, A 0, B 0, C 0}", "  $TOOL = {X 0, Y 0, Z 200, A 0, B 0, C 0}"]
    for _ in range(n):
        x, y, z = 1800 + rng.uniform(0, 400), rng.uniform(-300, 300), 900 + rng.uniform(0, 300)
        lines.append(f"  LIN {{X {x:.1f}, Y {y:.1f}, Z {z:.1f}, A 0.0, B {b_deg}, C 0.0}}")
    path.write_text("\n".join(lines + ["END", ""]))
    return path


def triples(text):
    return np.array([[float(v) for v in m] for m in re.findall(r"A (-?[\d.]+), B (-?[\d.]+), C (-?[\d.]+)", text)])


def test_near_b_90_the_nearest_triple_is_written_and_the_move_of_a_and_c_is_said(tmp_path, capsys):
    src = program(tmp_path / "g.src", 90.0)
    out = tmp_path / "out.src"
    assert main(["compensate", str(src), "-o", str(out), "--orientation", "--max-std", "inf"]) == 0
    err = capsys.readouterr().err
    said = [line for line in err.splitlines() if " P323 " in line]
    assert len(said) == 1 and said[0].startswith(f"{src}:4:7: P323 ")  # once, at the file's first such target
    old, new = triples(src.read_text())[1:], triples(out.read_text())[1:]  # (row 0: the $BASE)
    old, new = old[1:], new[1:]  # (and the $TOOL)
    angle = frames.rotation_angle_deg(old, new)
    assert angle.max() < 1.0 and np.abs(new[:, [0, 2]] - old[:, [0, 2]]).max() > 1.0
    m = re.search(r"A and C change by up to ([\d.]+)° for a rotation of at most ([\d.]+)°", said[0])
    assert float(m.group(1)) == pytest.approx(np.abs(new - old).max(), abs=6e-3)  # (the message says 2 decimals)
    assert float(m.group(2)) == pytest.approx(angle.max(), abs=6e-3)  # (the message says 2 decimals)
    # the triple written is the nearest of the two that state the new rotation
    alt = np.c_[new[:, 0] + 180, 180 - new[:, 1], new[:, 2] + 180]
    np.testing.assert_allclose(frames.nearest_triple(alt, old), new, atol=1e-9)
    # away from B = 90°: nothing to say
    away = program(tmp_path / "h.src", 45.0)
    assert main(["compensate", str(away), "-o", str(tmp_path / "h_out.src"), "--orientation", "--max-std", "inf"]) == 0
    assert " P323 " not in capsys.readouterr().err


def test_verify_says_when_the_orientation_was_not_corrected(tmp_path, capsys):
    src = program(tmp_path / "g.src", 60.0, n=8)
    position, both = tmp_path / "p.src", tmp_path / "o.src"
    assert main(["compensate", str(src), "-o", str(position), "-q", "--max-std", "inf"]) == 0
    assert main(["compensate", str(src), "-o", str(both), "-q", "--orientation", "--max-std", "inf"]) == 0
    capsys.readouterr()
    assert main(["verify", str(src), str(position), "-q"]) == 0
    out = capsys.readouterr().out
    assert "Orientation error (deg): not corrected" in out
    assert main(["verify", str(src), str(both), "-q"]) == 0
    out = capsys.readouterr().out
    assert "Orientation error (deg)\n" in out and "not corrected" not in out

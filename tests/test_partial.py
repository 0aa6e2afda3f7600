"""Partial aggregates: `LIN {Z 1250}` takes X, Y from the previous *commanded* position
on the controller, so postproc writes into it the X/Y/Z its own correction needs."""
import re

import numpy as np
import pytest

from postproc.cli import main
from postproc.compensation.api import compensate_text
from postproc.programs.io import load_program, parse_program_text
from postproc.model.compensator import load_model
from postproc.programs.base_poses import robot_base_poses

from helpers import REPO
from postproc.programs import ActiveFrames
from postproc.core.diagnostics import PostprocError

# made-up programs that set no $BASE/$TOOL: stated, as a user would (--base 0 --tool model)
STATED = ActiveFrames(base=0, tool="model")

GAIN = np.array([[2e-3, 0, 0], [0, -1e-3, 5e-4], [0, 0, 3e-3]])
SRC = """DEF p()
  LIN {X 2000.0,Y 0.0,Z 900.0,A 0.0,B 90.0,C 0.0}
  LIN {z 950.5}
  LIN { Y 100.25 , A 1.0 }
  LIN {X 2100.00, Z 920.00}
END
"""


def test_missing_components_are_written_in_the_aggregates_style(affine):
    model = load_model(affine(offset=(0.3, -0.2, 0.1), gain=GAIN))
    out, report = compensate_text(SRC, model, name="p.src", active=STATED)
    assert report.complete and report.compensated == 4
    lines = out.splitlines()[3:6]  # (after the stamp, DEF and the full target)
    assert re.fullmatch(r"  LIN \{x [\d.]+,y -?[\d.]+,z [\d.]+\}", lines[0])  # names in lower case, ',' as written
    assert re.fullmatch(r"  LIN \{ X [\d.]+ , Y [\d.]+ , Z [\d.]+ , A 1\.0 \}", lines[1])  # ' , ' and the A kept
    assert re.fullmatch(r"  LIN \{X [\d.]+\d{2}, Y [\d.-]+, Z [\d.]+\}", lines[2])  # ', ', 3 decimals
    # each target is commanded at P + Ê: the numbers read back are the model's commands for
    # the targets as the controller takes them (missing components from the previous target)
    written = parse_program_text(SRC, "p.src", active=STATED)
    poses, _ = robot_base_poses(written)
    again, _ = robot_base_poses(parse_program_text(out, "p.src", active=STATED))
    assert np.allclose(again[:, :3], model.command(poses), atol=6e-4)
    assert np.array_equal(np.isnan(again[:, 3:]), np.isnan(poses[:, 3:]))  # orientation not filled in


def test_no_fill_partial_refuses_with_the_target_located(tmp_path, affine, capsys):
    src = tmp_path / "p.src"
    src.write_text(SRC)
    out = tmp_path / "o.src"
    assert main(["compensate", str(src), "-o", str(out), "--model", str(affine(gain=GAIN)), "--no-fill-partial",
                 "--base", "0", "--tool", "model"]) == 2
    assert capsys.readouterr().err.startswith(f"{src}:3:7: P216 partial aggregate")
    assert not out.exists()


def test_weld_cell_partial_target_lands_as_if_written_in_full(tmp_path):
    """Through the simulator (`postproc verify`'s robot, no noise): the partial target of
    weld_cell.src (line 114) lands as close as the same target written in full."""
    from postproc.acceptance.verify import _fill
    from postproc.calibration.simulator import SimulatedRobot

    krl = REPO / "samples/krl"
    config = str(krl / "config" / "$config.dat")
    dat = (krl / "weld_cell.dat").read_text("latin-1")
    partial = (krl / "weld_cell.src").read_text("latin-1")
    assert partial.splitlines()[113].strip() == "LIN {Z 280.0}"
    full = partial.replace("LIN {Z 280.0}", "LIN {X 300.0,Y 420.0,Z 280.0,A 0.0,B 90.0,C 0.0}")
    sim, model = SimulatedRobot(), load_model()
    attitude = np.array([0.0, 90.0, 0.0])
    errors = {}
    for name, text in (("partial", partial), ("full", full)):
        new, report = compensate_text(text, model, name="w.src", dat_text=dat, config=config, active=STATED)
        # (XP11 runs after seam_clean's last target and, where PART_TYPE is neither 1 nor 2, after the last tack:
        # DEFAULT's HALT pauses, Start resumes — two approaches the default model corrects 0.19 mm apart: P230)
        assert report.left_codes == {"P230": 1} and report.compensated == report.targets - 1
        for label, src in (("original", text), ("compensated", new)):
            (tmp_path / f"{label}.src").write_text(src, "latin-1")
            (tmp_path / f"{label}.dat").write_text(dat if label == "original" else report.outputs["w.dat"], "latin-1")
        poses = [_fill(robot_base_poses(p)[0], p, attitude, "")[0]
                 for p in (load_program(tmp_path / f"{label}.src", config) for label in ("original", "compensated"))]
        errors[name] = sim.verify(*poses, noise=False)["errors_after"][17]  # the 18th target: line 114
    assert errors["partial"] == pytest.approx(errors["full"], abs=1e-3)
    assert errors["partial"] < 0.1  # (0.195 mm when X, Y were inherited from the previous command)


def test_the_last_checks_accept_the_inserted_components_and_catch_a_wrong_one(affine, monkeypatch):
    # a module with position variables: the new texts are read again (P191) with the filled-in
    # components counted as written; a formatter that writes a wrong number is refused (P190)
    dat = "DEFDAT m\n  DECL E6POS XP1={X 2000.0,Y 0.0,Z 900.0,A 0.0,B 90.0,C 0.0}\nENDDAT\n"
    src = "DEF m()\n  LIN XP1\n  LIN {Z 950.0}\nEND\n"
    model = load_model(affine(offset=(0.3, -0.2, 0.1), gain=GAIN))
    out, report = compensate_text(src, model, name="m.src", dat_text=dat, active=STATED)
    assert report.complete and parse_program_text(out, "m.src", dat_text=report.outputs["m.dat"], active=STATED).named_targets
    assert re.search(r"LIN \{X 2000\.\d{3},Y -?0\.\d{3},Z 950\.\d{3}\}", out)
    import postproc.programs.rewrite as rewrite

    monkeypatch.setattr(rewrite, "format_like", lambda token, value: format(value + 0.01, ".3f"))
    with pytest.raises(PostprocError) as info:
        compensate_text(src, model, name="m.src", dat_text=dat, active=STATED)
    assert (info.value.code, info.value.line) == ("P190", 3)

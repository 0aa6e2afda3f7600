"""The payload at every target (issue 33, item 3): each dialect's load statements give each row
its load (``Targets.load``), the model takes it (its correction varies over space and with the
mass), a load not known statically is left as written (P235, located at its cause naming the
motions), ``--load`` states it where the program sets none, and a load-blind model compensates as
before."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings

from postproc.cli import main
from postproc.compensation.pipeline import compensate_program
from postproc.model.compensator import load_model
from postproc.programs import ActiveFrames
from postproc.programs.io import read_program
from postproc.settings import Settings
from postproc.testing.generate import krl_programs
from postproc.testing.models import affine_model
from postproc.testing.oracle import check

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "samples" / "krl" / "pick_place_load.src"
GAIN = np.diag([0.001, 0.002, -0.001])


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    d = tmp_path_factory.mktemp("loads")
    aware = affine_model(d / "aware.onnx", gain=GAIN, offset=(0.2, 0.1, -0.1), load_gain=np.diag([0.0005, 0.001, 0.0]),
                         load_offset=(0.1, 0.05, -0.2), tool={"name": "any"})
    blind = affine_model(d / "blind.onnx", gain=GAIN, offset=(0.2, 0.1, -0.1), tool={"name": "any"})
    return load_model(aware), load_model(blind), aware, blind


def _read(path: Path, text: str, dialect: str):
    return read_program([str(path)], [text], dialect)


def _krl_numbers(text: str) -> np.ndarray:
    """X, Y, Z of every LIN {…} line, in order."""
    rows = re.findall(r"LIN \{X ([-\d.]+),Y ([-\d.]+),Z ([-\d.]+)", text)
    return np.array(rows, float)


def test_pick_and_place_krl_commands_differ_by_the_load_as_the_model_says(models):
    aware, blind, _, _ = models
    text = SAMPLE.read_text(encoding="latin-1")
    program = _read(SAMPLE, text, "krl")
    t = program.targets
    # the pick moves carry 0 kg, the place moves 300 kg (centre of mass 220 mm out), the last one 0 again
    assert t.load[:, 0].tolist() == [0.0, 0.0, 300.0, 300.0, 300.0, 0.0]
    assert t.load[2].tolist() == [300.0, 220.0, 0.0, 40.0]
    report = compensate_program(program, aware, Settings())
    assert report.complete and report.left == 0
    new = _krl_numbers(report.outputs[str(SAMPLE)])
    poses = t.poses  # ($BASE = $NULLFRAME, robot base = world: the rows are in the robot base)
    expected = aware.command(poses, load=t.load)
    assert np.abs(new - expected).max() < 2e-3
    # the same point (X 1900 Y -400 Z 1000) commanded apart with 0 and 300 kg: the load's term of the model
    reference = aware.command(poses)  # (NaN: the model's reference load, 300 kg)
    assert np.abs(new[0] - new[2]).max() > 0.3
    assert np.abs(new[2] - reference[2]).max() < 2e-3 and np.abs(new[0] - reference[0]).max() > 0.3
    # a load-blind model: every target for its one load, as before (a note says the program changes its payload)
    report_blind = compensate_program(_read(SAMPLE, text, "krl"), blind, Settings())
    assert report_blind.complete
    assert np.abs(_krl_numbers(report_blind.outputs[str(SAMPLE)]) - blind.command(poses)).max() < 2e-3
    assert [n.code for n in report_blind.notes if n.code == "P236"] == ["P236"]
    assert not [w for w in report_blind.warnings if w.code in ("P235", "P338")]


KRL_UNKNOWN = """DEF unk( )
  $BASE = {X 0,Y 0,Z 0,A 0,B 0,C 0}
  $TOOL = {X 0,Y 0,Z 200,A 0,B 0,C 0}
  $LOAD = {M 0,CM {X 0,Y 0,Z 0,A 0,B 0,C 0},J {X 0,Y 0,Z 0}}
  LIN {X 1900,Y -300,Z 900,A 0,B 90,C 0}
  IF $IN[3] THEN
    $LOAD = {M 300,CM {X 0,Y 0,Z 250,A 0,B 0,C 0},J {X 0,Y 0,Z 0}}
  ENDIF
  LIN {X 1900,Y 300,Z 900,A 0,B 90,C 0}
  LIN {X 2000,Y 300,Z 900,A 0,B 90,C 0}
  BAS(#TOOL, 0)
  $TOOL = {X 0,Y 0,Z 200,A 0,B 0,C 0}
  LIN {X 2000,Y 200,Z 900,A 0,B 90,C 0}
END
"""


def test_a_load_not_known_is_left_located_at_its_cause_and_exits_1(models, tmp_path, capsys):
    _, _, aware_path, blind_path = models
    src = tmp_path / "unk.src"
    src.write_text(KRL_UNKNOWN, encoding="latin-1")
    out = tmp_path / "out.src"
    assert main(["compensate", str(src), "-o", str(out), "--model", str(aware_path)]) == 1
    err = capsys.readouterr().err
    # the IF's branches leave it different: said at the IF (line 6), naming the motions at lines 9 and 10
    said = [line for line in err.splitlines() if " P235 " in line]
    assert any(line.startswith(f"{src}:6:") and f"{src}:9" in line and f"{src}:10" in line for line in said), err
    # BAS(#TOOL, 0): $LOAD = the machine data's default, not read: said at line 11, naming line 13
    assert any(line.startswith(f"{src}:11:") and "$DEF_L_M" in line for line in said), err
    assert "3 left as written" in err or "left as written: P235 ×3" in err
    written = out.read_text(encoding="latin-1")
    assert "LIN {X 1900,Y 300,Z 900," in written and "LIN {X 2000,Y 200,Z 900," in written  # (as written)
    assert "LIN {X 1900,Y -300,Z 900," not in written  # (its load is known: compensated)
    # the user states it: --load taken where the payload is not known, said at each cause (P339), exit 0
    out3 = tmp_path / "out3.src"
    assert main(["compensate", str(src), "-o", str(out3), "--model", str(aware_path), "--load", "150,0,0,100"]) == 0
    err = capsys.readouterr().err
    notes = [line for line in err.splitlines() if " P339 " in line]
    assert any(line.startswith(f"{src}:6:") and "150 kg" in line for line in notes), err
    assert "LIN {X 1900,Y 300,Z 900," not in out3.read_text(encoding="latin-1")
    # a load-blind model: no P235, every target compensated (exit 0), as before this issue
    out2 = tmp_path / "out2.src"
    assert main(["compensate", str(src), "-o", str(out2), "--model", str(blind_path)]) == 0
    assert "P235" not in capsys.readouterr().err


KRL_UNSET = """DEF unset( )
  $BASE = {X 0,Y 0,Z 0,A 0,B 0,C 0}
  $TOOL = {X 0,Y 0,Z 200,A 0,B 0,C 0}
  LIN {X 1900,Y -300,Z 900,A 0,B 90,C 0}
  LIN {X 2100,Y 300,Z 700,A 0,B 90,C 0}
END
"""


def test_load_states_the_payload_where_the_program_sets_none(models, tmp_path):
    aware, _, _, _ = models
    src = tmp_path / "unset.src"
    program = _read(src, KRL_UNSET, "krl")
    assert program.targets.load is None  # (a program that sets no payload)
    poses = program.targets.poses
    plain = compensate_program(program, aware, Settings())
    assert [n.code for n in plain.notes if n.code == "P339"] == ["P339"]  # (the model's reference load, said)
    assert np.abs(_krl_numbers(plain.outputs[str(src)]) - aware.command(poses)).max() < 2e-3
    stated = compensate_program(_read(src, KRL_UNSET, "krl"), aware, Settings().override(load="0"))
    assert not [n for n in stated.notes if n.code == "P339"]
    got = _krl_numbers(stated.outputs[str(src)])
    assert np.abs(got - aware.command(poses, load=np.array([0.0, 0, 0, 0]))).max() < 2e-3
    assert np.abs(got - aware.command(poses)).max() > 0.3
    # a payload beyond what the model extrapolates to (its card: measured 0 and 300 kg, × 2): left (P338)
    far = compensate_program(_read(src, KRL_UNSET, "krl"), aware, Settings().override(load="900,0,0,250"))
    assert {w.code for w in far.warnings} >= {"P338"} and far.left == 2


RAPID = """MODULE pp
  PERS tooldata tGrip := [TRUE, [[0, 0, 200], [1, 0, 0, 0]], [15, [0, 0, 80], [1, 0, 0, 0], 0, 0, 0]];
  PERS loaddata piece := [300, [0, 0, 50], [1, 0, 0, 0], 0, 0, 0];
  CONST robtarget pA := [[1900, -300, 800], [0, 0, 1, 0], [0, 0, 0, 0], [9E9, 9E9, 9E9, 9E9, 9E9, 9E9]];
  CONST robtarget pB := [[1900, 300, 800], [0, 0, 1, 0], [0, 0, 0, 0], [9E9, 9E9, 9E9, 9E9, 9E9, 9E9]];
  CONST robtarget pC := [[2000, 300, 800], [0, 0, 1, 0], [0, 0, 0, 0], [9E9, 9E9, 9E9, 9E9, 9E9, 9E9]];
  PROC main()
    MoveL pA, v100, fine, tGrip;
    GripLoad piece;
    MoveL pB, v100, fine, tGrip;
    GripLoad load0;
    MoveL pC, v100, fine, tGrip;
  ENDPROC
ENDMODULE
"""

URSCRIPT = """def prog():
  set_tcp(p[0, 0, 0.2, 0, 0, 0])
  set_payload(0.0, [0, 0, 0])
  movel(p[0.5, -0.3, 0.6, 0, 3.14159, 0], a=1.2, v=0.25)
  set_payload(12.5, [0, 0.01, 0.08])
  movel(p[0.5, 0.3, 0.6, 0, 3.14159, 0], a=1.2, v=0.25)
  set_target_payload(3, [0, 0, 0.05], [0, 0, 0, 0, 0, 0])
  movel(p[0.5, 0.3, 0.5, 0, 3.14159, 0], a=1.2, v=0.25)
  set_payload_mass(4)
  movel(p[0.4, 0.3, 0.5, 0, 3.14159, 0], a=1.2, v=0.25)
end
prog()
"""

FANUC = """/PROG PP
/ATTR
/MN
   1:  UFRAME_NUM=0 ;
   2:  UTOOL_NUM=0 ;
   3:  PAYLOAD[1] ;
   4:L P[1] 100mm/sec FINE ;
   5:  PAYLOAD[2] ;
   6:L P[2] 100mm/sec FINE ;
/POS
P[1]{
   GP1:
\tUF : 0, UT : 0,\t\tCONFIG : 'N U T, 0, 0, 0',
\tX =  1900.000  mm,\tY =  -300.000  mm,\tZ =   800.000  mm,
\tW =   180.000 deg,\tP =     0.000 deg,\tR =     0.000 deg
};
P[2]{
   GP1:
\tUF : 0, UT : 0,\t\tCONFIG : 'N U T, 0, 0, 0',
\tX =  1900.000  mm,\tY =   300.000  mm,\tZ =   800.000  mm,
\tW =   180.000 deg,\tP =     0.000 deg,\tR =     0.000 deg
};
/END
"""

POSES = """x,y,z,a,b,c,load_mass,load_cx,load_cy,load_cz
1900,-300,800,0,90,0,0,,,
1900,300,800,0,90,0,300,0,0,250
2000,300,800,0,90,0,,,,
"""


KRL_WITH = """DEF w( )
  EXT Other( )
  $BASE = $NULLFRAME
  $TOOL = {X 0,Y 0,Z 200,A 0,B 0,C 0}
  $LOAD = {M 0,CM {X 0,Y 0,Z 0,A 0,B 0,C 0},J {X 0,Y 0,Z 0}}
  LIN {X 2000,Y 0,Z 900,A 0,B 90,C 0}
  SLIN {X 2000,Y 100,Z 900,A 0,B 90,C 0} WITH $LOAD = {M 300,CM {X 0,Y 0,Z 250,A 0,B 0,C 0},J {X 0,Y 0,Z 0}}
  LIN {X 2000,Y 200,Z 900,A 0,B 90,C 0}
  BAS(#TOOL, 2)
  LIN {X 2000,Y 300,Z 900,A 0,B 90,C 0}
  $LOAD.M = 40
  LIN {X 2000,Y 400,Z 900,A 0,B 90,C 0}
  Other( )
  LIN {X 2010,Y 0,Z 900,A 0,B 90,C 0}
END
"""


def test_each_dialect_gives_each_target_the_load_in_force(tmp_path):
    # KRL: a motion's WITH $LOAD for that motion only; BAS(#TOOL, n) from $config.dat's LOAD_DATA[n]; a
    # component set; code not read leaves it unknown
    config = [(ROOT / "samples" / "krl" / "config" / "$config.dat").read_text(encoding="latin-1")]
    krl = read_program([str(tmp_path / "w.src")], [KRL_WITH], "krl", config=config).targets
    assert np.allclose(krl.load[:5], [[0, 0, 0, 0], [300, 0, 0, 250], [0, 0, 0, 0], [8, 0, 0, 90], [40, 0, 0, 90]])
    assert np.isnan(krl.load[5]).all() and "Other()" in krl.load_causes[krl.load_cause[5]][3]
    unknown = read_program([str(tmp_path / "w.src")], [KRL_WITH], "krl").targets  # (no $config.dat)
    assert "LOAD_DATA[2] needs $config.dat" in unknown.load_causes[unknown.load_cause[3]][3]
    # inline forms: BAS(#PTP_PARAMS) / SPLINE … WITH $LOAD = SLOAD(FS1.TOOL_NO): LOAD_DATA[1] of the $config.dat
    from postproc.programs.io import load_program

    weld = load_program(str(ROOT / "samples" / "krl" / "weld_cell.src"), [str(ROOT / "samples/krl/config/$config.dat")])
    assert len(weld.targets) == 20 and (weld.targets.load == [12.5, 0, 0, 120]).all()
    rapid = _read(tmp_path / "pp.mod", RAPID, "rapid").targets
    # the tool's tload (15 kg, cog 80 mm), + the gripped 300 kg (cog 50 mm in the tool frame: 250 on the flange)
    assert np.allclose(rapid.load, [[15, 0, 0, 80], [315, 0, 0, (15 * 80 + 300 * 250) / 315], [15, 0, 0, 80]])
    # a TRAP that sets the GripLoad, connected and switched on: the payload is not known while it may run
    trap = RAPID.replace("    GripLoad load0;\n", "").replace("  PROC main()\n", "  VAR intnum iGrip;\n  PROC main()\n")
    trap = trap.replace("    GripLoad piece;\n", "    CONNECT iGrip WITH tDrop;\n    ISignalDI diGrip, 1, iGrip;\n")
    trap = trap.replace("ENDMODULE", "  TRAP tDrop\n    GripLoad load0;\n  ENDTRAP\nENDMODULE")
    trapped = _read(tmp_path / "trap.mod", trap, "rapid").targets
    assert trapped.load_cause.tolist() == [-1, 0, 0] and "TRAP" in trapped.load_causes[0][3]
    ur = _read(tmp_path / "pp.script", URSCRIPT, "urscript").targets
    assert np.allclose(ur.load[:3], [[0, 0, 0, 0], [12.5, 0, 10, 80], [3, 0, 0, 50]])  # (cog in metres → mm)
    assert np.isnan(ur.load[3]).all() and ur.load_cause[3] >= 0  # (set_payload_mass: the cog in force not known)
    assert "line 9" in ur.load_causes[ur.load_cause[3]][3]
    fanuc = _read(tmp_path / "pp.ls", FANUC, "fanuc").targets
    assert np.isnan(fanuc.load).all() and (fanuc.load_cause >= 0).all()  # (the schedule is the controller's)
    assert [c[4] for c in fanuc.load_causes] == [1, 2] and [c[1] for c in fanuc.load_causes] == [6, 8]
    called = _read(tmp_path / "pp.ls", FANUC.replace("PAYLOAD[2]", "CALL GRIP"), "fanuc").targets
    assert "GRIP() called at line 8" in called.load_causes[called.load_cause[1]][3]  # (a program not read may select one)
    poses = _read(tmp_path / "pp.csv", POSES, "poses").targets
    assert np.array_equal(poses.load[:2], [[0, 0, 0, 0], [300, 0, 0, 250]]) and np.isnan(poses.load[2]).all()


def test_fanuc_payload_schedules_as_stated_and_pose_list_loads_reach_the_model(models, tmp_path):
    aware, _, _, _ = models
    path = tmp_path / "pp.ls"
    program = _read(path, FANUC, "fanuc")
    forced = Settings().override(force=True)  # (UT 0, the flange: not the test model's tool)
    unstated = compensate_program(program, aware, forced)
    assert {w.code for w in unstated.warnings} >= {"P235"} and unstated.left == 2
    located = [w for w in unstated.warnings if w.code == "P235"]
    assert sorted(w.line for w in located) == [6, 8]
    stated = compensate_program(_read(path, FANUC, "fanuc"), aware,
                                forced.override(payloads={"1": "0", "2": "300,0,0,250"}))
    assert stated.left == 0, [w.format() for w in stated.warnings]
    csv = tmp_path / "pp.csv"
    program = _read(csv, POSES, "poses")
    report = compensate_program(program, aware, Settings())
    got = np.array(re.findall(r"^([-\d.]+),([-\d.]+),([-\d.]+),", report.outputs[str(csv)], re.M), float)
    load = program.targets.load
    assert np.abs(got - aware.command(program.targets.poses, load=load)).max() < 2e-3


@pytest.fixture(scope="module")
def loaded(tmp_path_factory):
    """A load-aware model (its correction varies over space, with the approach and with the mass)."""
    path = tmp_path_factory.mktemp("l") / "l.onnx"
    return load_model(affine_model(path, offset=(0.2, -0.1, 0.15), gain=np.diag([2e-3, 1.5e-3, 2.5e-3]),
                                   previous_gain=5e-5, tool={"name": "any"}, load_gain=np.diag([2e-4, 5e-4, 0.0]),
                                   load_offset=(0.1, 0.05, -0.2)))


@settings(max_examples=25, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(krl_programs(loads=True))
def test_every_target_runs_with_the_load_the_analysis_gave_it(loaded, program):
    """Random KRL programs whose payload changes ($LOAD, $LOAD.M, BAS(#TOOL, n) from LOAD_DATA, code not
    read; in branches and loops): on every oracle's path each compensated target is at P + Ê(P, the load
    the run carries there) — the world's where the analysis did not know it — or was left as written."""
    files, texts, config = program
    checked = check(files, texts, "krl", loaded, config=config, active=ActiveFrames(base=0, tool="model"),
                    seeds=range(3))
    assert checked.violations == [], "\n".join(checked.violations) + "\n" + texts[0]


def test_the_property_sees_a_load_the_analysis_got_wrong(loaded, tmp_path):
    """The oracle is not blind to loads: the same program, checked as if the load were not tracked
    (every row's load dropped: the model's reference), is found wrong on the rows that carry 0 kg."""
    from postproc.programs.analysis import targets as built

    files, texts = ["t.src"], [SAMPLE.read_text(encoding="latin-1").replace("pick_place_load", "t")]
    assert check(files, texts, "krl", loaded, seeds=range(1)).violations == []
    columns = built._columns

    def blind(*args, **kwargs):
        out = columns(*args, **kwargs)
        out.load, out.load_cause = None, None
        return out

    built._columns = blind
    try:
        violations = check(files, texts, "krl", loaded, seeds=range(1)).violations
    finally:
        built._columns = columns
    assert len(violations) == 3  # (the rows at 0 kg, commanded for the reference 300 kg)


KRL_POINT = """DEF pt( )
  $BASE = {X 0,Y 0,Z 0,A 0,B 0,C 0}
  $TOOL = {X 0,Y 0,Z 200,A 0,B 0,C 0}
  $LOAD = {M 0,CM {X 0,Y 0,Z 0,A 0,B 0,C 0},J {X 0,Y 0,Z 0}}
  LIN XP1
  LIN XP2
  $LOAD = {M 300,CM {X 0,Y 0,Z 250,A 0,B 0,C 0},J {X 0,Y 0,Z 0}}
  LIN XP1
END
"""
KRL_POINT_DAT = """DEFDAT pt
  DECL E6POS XP1={X 1900.0,Y -300.0,Z 900.0,A 0.0,B 90.0,C 0.0}
  DECL E6POS XP2={X 2000.0,Y 300.0,Z 900.0,A 0.0,B 90.0,C 0.0}
ENDDAT
"""


def test_a_point_run_with_two_payloads_is_left_at_both_runs(models, tmp_path):
    """One point, two payloads: two corrections, one set of numbers — left (P230, naming the cause);
    a load-blind model compensates it once, as before."""
    aware, blind, _, _ = models
    files = [str(tmp_path / "pt.src"), str(tmp_path / "pt.dat")]
    report = compensate_program(read_program(files, [KRL_POINT, KRL_POINT_DAT], "krl"), aware, Settings())
    (w,) = [w for w in report.warnings if w.code == "P230"]
    assert "other payloads" in w.message and "give each payload its own point" in w.message
    assert "X 1900.0,Y -300.0" in report.outputs[files[1]] and "X 2000.0,Y 300.0" not in report.outputs[files[1]]
    plain = compensate_program(read_program(files, [KRL_POINT, KRL_POINT_DAT], "krl"), blind, Settings())
    assert plain.complete and "X 1900.0,Y -300.0" not in plain.outputs[files[1]]


def test_a_load_blind_model_says_a_payload_it_was_not_measured_with(tmp_path):
    # a model that does not take the load, measured at 300 kg (its card says so): a program that
    # carries 0 kg throughout is compensated for 300 kg — said at the first such target (P341)
    blind = load_model(affine_model(tmp_path / "blind.onnx", gain=GAIN, offset=(0.2, 0.1, -0.1),
                                    loads={"measured": [[300, 0, 0, 250]], "reference": [300, 0, 0, 250]}))
    text = ("DEF p()\n  $BASE = {X 1800, Y 0, Z 0, A 0, B 0, C 0}\n  $TOOL = {X 0, Y 0, Z 200, A 0, B 0, C 0}\n"
            "  $LOAD = {M 0,CM {X 0,Y 0,Z 0,A 0,B 0,C 0},J {X 0,Y 0,Z 0}}\n"
            "  LIN {X 100, Y 0, Z 900, A 0, B 90, C 0}\n  LIN {X 200, Y 50, Z 950, A 0, B 90, C 0}\nEND\n")
    program = read_program(["p.src"], [text], "krl")
    report = compensate_program(program, blind)
    said = [w for w in report.warnings if w.code == "P341"]
    assert len(said) == 1 and said[0].line == 5 and "2 target(s)" in said[0].message
    assert report.compensated == 2
    # at the load it was measured with: nothing to say
    same = text.replace("{M 0,CM {X 0,Y 0,Z 0,", "{M 300,CM {X 0,Y 0,Z 250,")
    report = compensate_program(read_program(["p.src"], [same], "krl"), blind)
    assert not [w for w in report.warnings if w.code == "P341"] and report.compensated == 2


def test_verify_simulates_the_payload_compensate_took():
    # --load where the payload is not statically known: compensate takes it (P339), so must verify
    from dataclasses import replace

    from postproc.acceptance.verify import _stated_loads
    from postproc.compensation.findings import payloads

    program = read_program(["unk.src"], [KRL_UNKNOWN], "krl")
    reading = replace(Settings().reading, load=np.array([150.0, 0.0, 0.0, 100.0]))
    unknown = np.flatnonzero(program.targets.load_cause >= 0)
    assert len(unknown)
    rows = np.arange(len(program.targets))
    assert np.allclose(_stated_loads(program, rows, reading)[unknown], [150.0, 0.0, 0.0, 100.0])
    assert np.allclose(_stated_loads(program, rows, reading), payloads(program, reading)[0], equal_nan=True)

"""KRL reader: targets, spans, frames, warnings and errors on the sample corpus and on
small programs written here for one construct each."""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from postproc.core.diagnostics import PostprocError
from postproc.programs import ActiveFrames, MOTIONS, STAMP_PREFIX, krl

# These programs are about other semantics than the active frames: they state them as the
# user would (--base 0 --tool model), the assumption the reader made silently before P220/P221.
STATED = ActiveFrames(base=0, tool="model")


SAMPLES = Path(__file__).resolve().parent.parent / "samples" / "krl"


def text_of(path: Path) -> str:
    return path.read_bytes().decode("latin-1")


def read(src: str, dat: str | None = None, config: list[str] | None = None, accelerate: bool = True,
         active=STATED):
    files, texts = ["t.src"], [src]
    if dat is not None:
        files.append("t.dat")
        texts.append(dat)
    return krl.read(files, texts, config=config, accelerate=accelerate, active=active)


def module(*lines: str) -> str:
    return "DEF t( )\n" + "\n".join(lines) + "\nEND\n"


def codes(program) -> list[str]:
    return [d.code for d in program.diagnostics]


def assert_spans_exact(program) -> None:
    """Every written X/Y/Z span holds the number token of the pose component."""
    t = program.targets
    for i in range(len(t)):
        text = program.texts[t.file[i]]
        for c in range(3):
            a, b = t.spans[i, c]
            if a < 0:
                assert b < 0
                continue
            token = text[a:b]
            assert re.fullmatch(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?", token), token
            assert float(token) == t.poses[i, c]


def rz(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def transform(r: np.ndarray, t) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = r
    m[:3, 3] = t
    return m


# ------------------------------------------------------------------ sample corpus


def cam():
    return krl.read(["cam_pocket.src"], [text_of(SAMPLES / "cam_pocket.src")])


def weld(config: bool = True):
    files = [SAMPLES / "weld_cell.src", SAMPLES / "weld_cell.dat"]
    cfg = [text_of(SAMPLES / "config" / "$config.dat")] if config else None
    return krl.read([str(f) for f in files], [text_of(f) for f in files], config=cfg)


def test_cam_pocket_counts_every_lin_and_both_circ_points():
    text = text_of(SAMPLES / "cam_pocket.src")
    p = cam()
    # independent count: Cartesian LIN lines + aux and end of every CIRC
    expected = len(re.findall(r"^LIN \{X", text, re.M)) + 2 * len(re.findall(r"^CIRC ", text, re.M))
    assert len(p.targets) == expected > 2000
    assert p.newlines == ["\r\n"] and p.dialect == "krl" and p.comment == ";"
    assert p.diagnostics == []
    assert_spans_exact(p)
    # one frame: $BASE translation (1850, -300, 650), $TOOL = the KR500-sim spindle X 300 Z 75
    assert len(p.frames) == 1 and (p.targets.frame == 0).all()
    np.testing.assert_allclose(p.frames[0].base, transform(np.eye(3), [1850, -300, 650]), atol=1e-12)
    np.testing.assert_allclose(p.frames[0].tool, [300, 0, 75, 0, 0, 0])
    # in the shipped model's envelope once in the robot base
    xyz = p.targets.poses[:, :3] + [1850, -300, 650]
    assert (xyz.min(0) >= [1750, -550, 550]).all() and (xyz.max(0) <= [2250, 550, 1250]).all()
    abc = p.targets.poses[:, 3:]
    assert np.abs(abc - [0, 90, 0]).max() <= 5.0


def test_cam_pocket_generator_is_deterministic(tmp_path, monkeypatch):
    import importlib.util

    spec = importlib.util.spec_from_file_location("make_cam_pocket", SAMPLES / "make_cam_pocket.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert ("\r\n".join(mod.program()) + "\r\n") == text_of(SAMPLES / "cam_pocket.src")


def test_weld_cell_targets_frames_and_spans():
    p = weld()
    t = p.targets
    # XP1..XP11 (CIRC XP4,XP5 and SCIRC XP9,XP10 both points), XTACK[1..4], XPARK,
    # the inline SPL and the two inline LINs of seam_clean; XP11 twice (after seam_clean, or after
    # the DEFAULT's HALT, which pauses: Start resumes it)
    assert len(t) == 20 and t.twin.tolist()[-2:] == [-1, 18]
    assert_spans_exact(p)
    assert p.newlines == ["\r\n", "\r\n"]
    dat = p.texts[1]
    # .dat declarations are the targets of named motions, once each, in the order they run
    # (seam_clean, called before SLIN XP11, moves to XPARK)
    names = [re.match(r"(?:DECL (?:GLOBAL )?\w+ )?(\w+(?:\[\d\])?)=", dat.splitlines()[ln - 1]).group(1)
             for ln, f in zip(t.line, t.file) if f == 1]
    assert names == ["XP1", "XP2", "XP3", "XP4", "XP5", "XP6", "XP7", "XP8", "XP9", "XP10",
                     "XTACK[1]", "XTACK[2]", "XTACK[3]", "XTACK[4]", "XPARK", "XP11", "XP11"]
    kinds = [MOTIONS[m] for m in t.motion]
    assert kinds[:10] == ["PTP", "LIN", "LIN", "CIRC-aux", "CIRC-end", "SPL", "SPL", "SLIN", "SCIRC-aux",
                          "SCIRC-end"]
    # BASE_DATA[1] / TOOL_DATA[1] of $config.dat, everywhere (FDAT path, SBASE/STOOL2, subroutine)
    assert len(p.frames) == 1 and (t.frame == 0).all()
    np.testing.assert_allclose(p.frames[0].base, transform(np.eye(3), [1850, -300, 650]), atol=1e-12)
    np.testing.assert_allclose(p.frames[0].tool, [300, 0, 75, 0, 0, 0])
    # the partial SPL {X 250,Y 180,Z 40} takes A,B,C of the point before it (XP10)
    spl = int(np.flatnonzero((t.file == 0) & (t.motion == MOTIONS.index("SPL")))[0])
    np.testing.assert_allclose(t.poses[spl], [250, 180, 40, -3, 92, 0])
    # LIN {Z 280.0} in seam_clean: X, Y from the LIN before it
    (z,) = np.flatnonzero((t.file == 0) & (t.line == 114))
    np.testing.assert_allclose(t.poses[z], [300, 420, 280, 0, 90, 0])
    assert tuple(t.spans[z, 0]) == (-1, -1) and tuple(t.spans[z, 1]) == (-1, -1)
    assert p.diagnostics == []


def test_weld_cell_without_config_leaves_frames_unresolved():
    p = weld(config=False)
    assert (p.targets.frame == -1).all() and p.frames == []
    (d,) = p.diagnostics
    assert d.code == "P201" and "BASE_DATA[1]" in d.message and "19 target" in d.message
    assert d.path.endswith("weld_cell.src") and d.line == 33  # the first BAS(#PTP_PARAMS) with FP1


def test_edge_mixed_endings_tabs_odd_numbers():
    path = SAMPLES / "edge" / "mixed_endings.src"
    p = krl.read([str(path)], [text_of(path)])
    t = p.targets
    assert len(t) == 6  # 3 LIN, CIRC aux + end, lin {x …}; the ptp {A1 …} is an axis target
    assert_spans_exact(p)
    assert p.newlines == ["\r\n"]  # 7 CRLF against 3 LF
    np.testing.assert_allclose(t.poses[1], [1950, 0, 880, 0.5, 90, 0])
    assert np.isnan(t.poses[0, 3:]).all()  # nothing before it to take A, B, C from
    assert np.isnan(t.poses[3, 3:]).all()  # after a PTP to axis values the pose is unknown
    np.testing.assert_allclose(t.poses[5, :3], [2030.25, 10, 900])  # Y, Z from the CIRC end point
    assert t.line.tolist() == [5, 6, 7, 9, 9, 10]
    assert t.col.tolist() == [6, 8, 6, 7, 26, 6]


def test_edge_relative_moves_from_a_known_start_are_targets_the_others_warn():
    path = SAMPLES / "edge" / "rel_moves.src"  # (sets $BASE, not $TOOL: stated)
    p = krl.read([str(path)], [text_of(path)], active=STATED)
    t = p.targets
    # LIN, LIN_REL {Z -20} and LIN_REL {X 5,Y 5} #TOOL from known starts, then LIN {X 210.0}
    assert t.line.tolist() == [4, 5, 6, 10]
    assert t.relative.tolist() == [-1, 0, 1, -1]
    # a relative target's numbers are the move's, in the frame start × move: #BASE keeps the base's
    # axes at the start's position, #TOOL turns with the tool (B 90: tool X is the base's -Z)
    assert np.allclose(t.poses[1, :3], [0, 0, -20]) and np.allclose(t.poses[2, :3], [5, 5, 0])
    base = np.array([1800.0, -400.0, 600.0])
    in_robot = [p.frames[t.frame[r]].base @ np.r_[t.poses[r, :3], 1.0] for r in (1, 2)]
    assert np.allclose(in_robot[0][:3], base + [200, 300, 380])
    assert np.allclose(in_robot[1][:3], base + [200, 300 + 5, 380 - 5], atol=1e-9)
    # PTP_REL {A3 5} turns an axis: after it nothing is known; LIN {X 210.0} takes Y/Z from where
    # the relative moves left the robot at run time: the LIN_REL #TOOL's command is read there (P217)
    assert codes(p) == ["P217"] + ["P210"] * 4
    assert [d.line for d in p.diagnostics] == [6, 7, 8, 8, 9]
    assert np.isnan(t.poses[3, 1:]).all()


def test_edge_frames_against_hand_computed_transforms():
    files = [SAMPLES / "edge" / "frames.src", SAMPLES / "edge" / "frames.dat"]
    p = krl.read([str(f) for f in files], [text_of(f) for f in files])
    t = p.targets
    assert_spans_exact(p)
    assert len(t) == 7  # (XP after XP.X = 2000.0: X that token, Y/Z the aggregate's, shared with the LIN XP before)
    assert t.group[4] == t.group[5] >= 0 and t.poses[5, 0] == 2000
    bases = [p.frames[f].base for f in t.frame]
    tool = [0, 0, 200, 0, 0, 0]
    # 1: $BASE aggregate
    np.testing.assert_allclose(bases[0], transform(np.eye(3), [1800, -400, 600]), atol=1e-9)
    # 2: XTABLE:XOFS = Rz(90) at (2000,0,700), then (10,20,0) in it → origin (1980, 10, 700)
    np.testing.assert_allclose(bases[1], transform(rz(90), [2000 - 20, 10, 700]), atol=1e-9)
    # 3: LIN XTABLE:XP1 after BAS(#BASE,0): XP1 (in the .dat) in XTABLE
    assert t.file[2] == 1 and t.poses[2, 1] == -150
    np.testing.assert_allclose(bases[2], transform(rz(90), [2000, 0, 700]), atol=1e-9)
    world = bases[2][:3, :3] @ t.poses[2, :3] + bases[2][:3, 3]
    np.testing.assert_allclose(world, [2150, 100, 950], atol=1e-9)
    # 4: a FRAME-typed name as target, 5: XP = {…} in the .src, both in $NULLFRAME
    assert t.file[3] == 1 and t.poses[3, 0] == 1900
    assert t.file[4] == 0 and t.poses[4, 0] == 1950
    np.testing.assert_allclose(bases[3], np.eye(4), atol=1e-12)
    # 7: INV_POS($ROBROOT):$BASE with $ROBROOT Z 100
    np.testing.assert_allclose(bases[6], transform(np.eye(3), [1700, 0, 400]), atol=1e-9)
    for f in t.frame:
        np.testing.assert_allclose(p.frames[f].tool, tool)
    # $POS_ACT, XPS[I] with nothing initialised: warnings, no targets
    assert codes(p) == ["P211", "P211"]
    assert [d.line for d in p.diagnostics] == [25, 26]


# ------------------------------------------------------------------ constructs

NUMBERS = [
    ("1950.1", 1950.1), ("-0.000", 0.0), ("1.5E+03", 1500.0), (".5", 0.5), ("1900.", 1900.0),
    ("+12", 12.0), ("-12.5e-1", -1.25), ("0", 0.0), ("2e2", 200.0),
]


@pytest.mark.parametrize("token,value", NUMBERS)
def test_number_forms(token, value):
    p = read(module(f"LIN {{X {token},Y 1,Z 2,A 0,B 90,C 0}} C_VEL"))
    assert p.targets.poses[0, 0] == value
    a, b = p.targets.spans[0, 0]
    assert p.texts[0][a:b] == token


AGGREGATES = [
    ("{X 1950.1,Y 12.5,Z 880}", [1950.1, 12.5, 880]),
    ("{  X   1 ,Y\t2,  Z 3  }", [1, 2, 3]),
    ("{E6POS: X 1, Y 2, Z 3, A 0, B 90, C 0, S 6, T 'B010', E1 0.0}", [1, 2, 3, 0, 90, 0]),
    ("{POS: X 1, Y 2, Z 3, S 'B110', T 'H2'}", [1, 2, 3]),
    ("{x 1,y 2,z 3,a 4,b 5,c 6}", [1, 2, 3, 4, 5, 6]),
    ("{X 1,Y 2,Z 3,A 0,B 90,C 0,S 2,T 35,E1 100.0,E2 -5}", [1, 2, 3, 0, 90, 0]),
    ("{Z 3}", [np.nan, np.nan, 3]),
    ("{FRAME: X 1,Y 2,Z 3,A 0,B 0,C 0}", [1, 2, 3, 0, 0, 0]),
]


@pytest.mark.parametrize("agg,pose", AGGREGATES)
@pytest.mark.parametrize("motion,kind", [("LIN", "LIN"), ("PTP", "PTP"), ("SLIN", "SLIN"), ("SPTP", "SPTP")])
def test_inline_aggregates(agg, pose, motion, kind):
    p = read(module(f"{motion} {agg} C_DIS"))
    assert len(p.targets) == 1
    assert MOTIONS[p.targets.motion[0]] == kind
    np.testing.assert_allclose(p.targets.poses[0, : len(pose)], pose)
    assert_spans_exact(p)
    assert p.targets.col[0] == len(motion) + 2 and p.targets.line[0] == 2


@pytest.mark.parametrize("line", [
    "CIRC {X 1,Y 2,Z 3},{X 4,Y 5,Z 6}",
    "CIRC {X 1,Y 2,Z 3},{X 4,Y 5,Z 6}, CA -45.5 C_VEL",
    "CIRC {X 1,Y 2,Z 3}, {X 4,Y 5,Z 6}, CA 720 C_DIS",
    "SCIRC {X 1,Y 2,Z 3}, {X 4,Y 5,Z 6}, CA 400 WITH $VEL = SVEL_CP(0.2, , LCPDAT1), $APO = SAPO(LCPDAT1) C_SPL",
])
def test_circ_aux_and_end_are_both_targets(line):
    p = read(module("LIN {X 0,Y 0,Z 0,A 10,B 80,C 5}", line))
    t = p.targets
    assert len(t) == 3
    s = "SCIRC" if line.startswith("S") else "CIRC"
    assert [MOTIONS[m] for m in t.motion[1:]] == [f"{s}-aux", f"{s}-end"]
    np.testing.assert_allclose(t.poses[1:, :3], [[1, 2, 3], [4, 5, 6]])
    # both take A, B, C from the start point (the aux point is no current position)
    np.testing.assert_allclose(t.poses[1:, 3:], [[10, 80, 5], [10, 80, 5]])
    assert_spans_exact(p)


@pytest.mark.parametrize("approx", ["", " C_PTP", " C_DIS", " C_VEL", " C_ORI", " C_PTP C_DIS", " c_vel"])
def test_approximation_keywords(approx):
    p = read(module(f"PTP {{X 1,Y 2,Z 3}}{approx}"))
    assert len(p.targets) == 1


def test_spline_block_segments():
    p = read(module(
        "SPLINE WITH $ACC = SACC_CP(LCPDAT1)",
        "  SPL {X 1,Y 2,Z 3,A 0,B 90,C 0}",
        "  SLIN {X 4,Y 5,Z 6}",
        "  SCIRC {X 7,Y 8,Z 9}, {X 10,Y 11,Z 12}",
        "  SPL {X 13,Y 14,Z 15} WITH $VEL = SVEL_CP(0.2, , LCPDAT1)",
        "ENDSPLINE",
    ))
    assert [MOTIONS[m] for m in p.targets.motion] == ["SPL", "SLIN", "SCIRC-aux", "SCIRC-end", "SPL"]
    np.testing.assert_allclose(p.targets.poses[:, 3:], [[0, 90, 0]] * 5)


def test_named_targets_and_declaration_forms():
    dat = "\n".join([
        "DEFDAT t PUBLIC",
        "DECL E6POS XP1={X 1,Y 2,Z 3,A 0,B 90,C 0}",
        "E6POS XP2={X 4,Y 5,Z 6}",
        "DECL GLOBAL POS XP3={X 7,Y 8,Z 9}",
        "DECL POS PA={X 10,Y 11,Z 12},PB={X 13,Y 14,Z 15}",
        "DECL E6POS P[5]",
        "P[3]={X 16,Y 17,Z 18}",
        "P[1]={X 19,Y 20,Z 21}",
        "DECL E6AXIS XAX={A1 0,A2 -90,A3 90,A4 0,A5 0,A6 0}",
        "DECL FRAME XF={X 22,Y 23,Z 24,A 0,B 0,C 0}",
        "DECL INT COUNT=3",
        "DECL REAL R=1.5",
        "DECL BOOL OK=TRUE",
        'DECL CHAR NAME[10]',
        "DECL MYTYPE M={A1 1, B 2}",
        "DECL E_TYPE E=#BASE",
        "DECL FDAT FP1={TOOL_NO 1,BASE_NO 0,IPO_FRAME #BASE,POINT2[] \" \",TQ_STATE FALSE}",
        "ENDDAT",
    ])
    src = module("PTP XP1", "LIN XP2", "LIN XP3", "LIN PA", "LIN PB", "LIN P[3]", "PTP XAX", "LIN XF",
                 "FOR I=1 TO 5", "  LIN P[I]", "ENDFOR", "LIN XP1", "PTP XHOME", "PTP XHOME1", "PTP $AXIS_ACT")
    p = read(src, dat)
    t = p.targets
    assert (t.file == 1).all()
    # the FOR runs P[1] … P[5]: P[1] and P[3] are targets (P[3] a second time, twin of the first),
    # P[2], P[4], P[5] have no value (P211, once for the statement); XP1 a second time, twin too
    np.testing.assert_allclose(t.poses[:, 0], [1, 4, 7, 10, 13, 16, 22, 19, 16, 1])
    assert t.twin.tolist() == [-1] * 8 + [5, 0]
    assert_spans_exact(p)
    assert codes(p) == ["P211"] and p.diagnostics[0].line == 11


def test_names_differing_in_digits_share_a_shape_but_keep_their_meaning():
    dat = "DEFDAT t\n" + "".join(f"DECL E6POS XP{i}={{X {i},Y 2,Z 3}}\n" for i in (1, 12, 305)) + \
        "DECL E6AXIS XA1={A1 1,A2 2}\nDECL E6POS XA12={X 7,Y 8,Z 9}\nENDDAT\n"
    p = read(module("LIN XP1", "LIN XP12", "LIN XP305", "PTP XA1", "PTP XA12", "PTP {A1 5}", "PTP {A 5,X 1,Y 2,Z 3}",
                    "LIN {X 1,Y 2,Z 3,E1 4}"), dat)
    np.testing.assert_allclose(p.targets.poses[:, 0], [1, 12, 305, 7, 1, 1])
    assert p.targets.file.tolist() == [1, 1, 1, 1, 0, 0]
    p = read(module("LIN XP1", "LIN XP13"), dat)  # XP13 is not XP12: not declared
    assert len(p.targets) == 1 and [(d.code, d.line, d.col) for d in p.diagnostics] == [("P215", 3, 5)]


def test_variable_given_an_aggregate_in_the_src():
    p = read(module("DECL E6POS XP", "XP = {X 1,Y 2,Z 3,A 0,B 90,C 0}", "LIN XP", "XP = {X 5}", "LIN XP"))
    t = p.targets
    assert len(t) == 2 and (t.file == 0).all()
    np.testing.assert_allclose(t.poses, [[1, 2, 3, 0, 90, 0], [5, 2, 3, 0, 90, 0]])
    # XP = {X 5} keeps Y, Z: their tokens are the first assignment's, shared by both targets
    assert (t.spans[1, 1:] == t.spans[0, 1:]).all() and t.spans[1, 0, 0] != t.spans[0, 0, 0]
    assert t.group.tolist() == [0, 0]


@pytest.mark.parametrize("lines,why", [
    (["DECL E6POS XP", "XP = $POS_ACT", "LIN XP"], "run-time"),
    (["DECL E6POS XP", "XP = shift(XP)", "LIN XP"], "shift() is not in the files read"),
    (["DECL E6POS XP", "LIN XP"], "not initialised"),
    (["LIN $POS_ACT"], "run-time position"),
    (["LIN shift(XP)"], "run time"),
    (["DECL E6POS PP[4]", "LIN PP[I]"], "run-time index"),
])
def test_not_statically_known_targets_warn(lines, why):
    p = read(module(*lines))
    assert len(p.targets) == 0
    left = [d for d in p.diagnostics if d.code != "P232"]  # (a call of shift(), not read: P232 at it)
    assert [d.code for d in left] == ["P211"] and why in left[0].message
    assert left[0].line == len(lines) + 1


def test_a_component_assigned_a_number_is_that_numbers_target():
    """``XP.X = 5`` then ``LIN XP``: X is the token 5 (rewritten there), Y/Z the aggregate's."""
    p = read(module("DECL E6POS XP", "XP = {X 1,Y 2,Z 3}", "XP.X = 5", "LIN XP"))
    t = p.targets
    assert len(t) == 1 and p.diagnostics == []
    np.testing.assert_allclose(t.poses[0, :3], [5, 2, 3])
    assert p.texts[0][slice(*t.spans[0, 0])] == "5" and p.texts[0][slice(*t.spans[0, 1])] == "2"


def test_undeclared_target_name_is_left_alone_with_a_warning():
    # it may be a global of a data list or $config.dat not given: not an error for the file
    p = read(module("LIN {X 1,Y 2,Z 3}", "  LIN XP9 C_DIS", "LIN {X 4,Y 5,Z 6}"))
    assert p.targets.poses[:, 0].tolist() == [1, 4]
    assert [(d.code, d.line, d.col) for d in p.diagnostics] == [("P215", 3, 7)]
    assert "XP9 is not declared in the files read" in p.diagnostics[0].message


def test_nothing_else_is_a_target():
    src = module(
        "; LIN {X 1,Y 2,Z 3} in a comment",
        'MSG[] = "LIN {X 1, Y 2, Z 3}; not a target"',
        "$BASE = {X 1800,Y -400,Z 600,A 0,B 0,C 0}",
        "$TOOL = {X 0,Y 0,Z 200,A 0,B 0,C 0}",
        "PTP {A1 0,A2 -90,A3 90,A4 0,A5 0,A6 0}",
        "PTP {E6AXIS: A1 0, A2 -90}",
        "PTP {E1 100}",
        "XF = {X 5,Y 6,Z 7,A 0,B 0,C 0}",
        "LIN {X 11,Y 12,Z 13} ; {X 14, Y 15, Z 16}",
    )
    p = read(src, "DEFDAT t\nDECL FRAME XF\nDECL CHAR MSG[40]\nENDDAT\n")
    assert len(p.targets) == 1
    np.testing.assert_allclose(p.targets.poses[0, :3], [11, 12, 13])


SURROUNDING = [
    "$VEL.CP=0.2", "$APO.CDIS=1.0", "$OUT[3]=TRUE", "$BWDSTART=FALSE", "BAS(#PTP_PARAMS,100)",
    "BAS (#INITMOV,0 )", "PDAT_ACT=PPDAT1", "FDAT_ACT=FP1", "LDAT_ACT=LCPDAT1", "INI", "my_sub(1, 2.5)",
    "IF $IN[1]==TRUE AND NOT $IN[2] THEN\nHALT\nELSE\nRETURN\nENDIF",
    "FOR I=1 TO 10 STEP 2\nCONTINUE\nENDFOR", "WHILE a < 5 OR b B_AND 3\nENDWHILE", "LOOP\nEXIT\nENDLOOP",
    "REPEAT\nUNTIL x EXOR y", "SWITCH n\nCASE 1,2\nDEFAULT\nENDSWITCH", "WAIT FOR $IN[1]", "WAIT SEC 0.5",
    "GOTO m1\nm1:", "GLOBAL INTERRUPT DECL 3 WHEN $STOPMESS==TRUE DO IR_STOPM ( )", "INTERRUPT ON 3",
    "INTERRUPT OFF 3", "TRIGGER WHEN DISTANCE=0 DELAY=0 DO $OUT[1]=TRUE",
    "TRIGGER WHEN PATH=-20.5 ONSTART DELAY=10 DO my_sub() PRIO=-1", "ANIN ON x = 1.0 * $ANIN[1]",
    "ANOUT ON $ANOUT[1] = 0.1*$VEL_ACT DELAY=-0.2", "ANOUT OFF $ANOUT[1]", "BRAKE F", "BRAKE",
    "x = -(a + 2) * f(b[1, 2].c) / 3", "x = a <> b", "msg[] = \"a ; {b} 'c'\"", "y = 'B1010' B_OR 'H0F'",
    "DECL INT I, J, K", "DECL E6POS XLOCAL", "RETURN f(x)", "TIME_BLOCK START", "PTP_REL {A3 5} C_PTP",
]


@pytest.mark.parametrize("stmt", SURROUNDING)
def test_surrounding_statements_parse(stmt):
    p = read(module(stmt))
    assert len(p.targets) == 0
    assert set(codes(p)) <= {"P210", "P232"}  # (P232: a call of a routine not read, my_sub, f, INI)


def test_headers_folds_def_variants():
    src = "\n".join([
        "&ACCESS RVP", "&REL 12", "&PARAM TEMPLATE = C:\\KRC\\Roboter\\Template\\vorgabe", "&PARAM EDITMASK = *",
        "&COMMENT uses {X 1} ; odd", "GLOBAL DEF t(P:IN, Q[]:OUT)",
        ";FOLD LIN P1 CONT Vel=2 m/s CPDAT1 Tool[1] Base[0];%{PE}%R 8.3.40,%MKUKATPBASIS,%CMOVE,%VLIN,%P 1:LIN",
        "  ;FOLD nested", "  LIN {X 1,Y 2,Z 3}", "  ;ENDFOLD", ";ENDFOLD",
        "END", "", "DEFFCT E6POS shift(p:IN)", "  DECL E6POS p", "  RETURN p", "ENDFCT",
    ])
    p = read(src)
    assert len(p.targets) == 1 and p.diagnostics == []


def test_subroutine_inherits_the_callers_frame():
    src = "\n".join([
        "DEF t( )", "BAS(#BASE, 1)", "sub( )", "END",
        "DEF sub( )", "LIN {X 1,Y 2,Z 3}", "END",
    ])
    cfg = ["DEFDAT $CONFIG\nDECL GLOBAL FRAME BASE_DATA[32]\nBASE_DATA[1]={X 1800,Y 0,Z 600,A 0,B 0,C 0}\nENDDAT\n"]
    p = read(src, config=cfg)
    np.testing.assert_allclose(p.frames[p.targets.frame[0]].base[:3, 3], [1800, 0, 600])
    # called in two different bases: the target runs twice, once in each (a twin row: the
    # rewrite writes its numbers only where both agree, ``compensate``)
    src2 = src.replace("sub( )\nEND", "sub( )\nBAS(#BASE, 0)\nsub( )\nEND")
    p = read(src2, config=cfg)
    t = p.targets
    assert len(t) == 2 and t.twin.tolist() == [-1, 0] and codes(p) == []
    assert [p.frames[f].base[:3, 3].tolist() for f in t.frame] == [[1800, 0, 600], [0, 0, 0]]


@pytest.mark.parametrize("setting,origin,rot", [
    ("BAS(#BASE, 2)", [1780, 150, 700], 90),
    ("$BASE = BASE_DATA[2]", [1780, 150, 700], 90),
    ("$BASE = BASE_DATA[1]:{X 10,Y 0,Z 0,A 90,B 0,C 0}", [1860, -300, 650], 90),
    ("$BASE = BASE_DATA[2]:BASE_DATA[1]", [1780 + 300, 150 + 1850, 1350], 90),
    ("BAS(#BASE, 0)", [0, 0, 0], 0),
    ("$BASE = $NULLFRAME", [0, 0, 0], 0),
    ("FDAT_ACT = {TOOL_NO 2,BASE_NO 2,IPO_FRAME #BASE}\nBAS(#CP_PARAMS, 0.2)", [1780, 150, 700], 90),
])
def test_base_settings_from_config(setting, origin, rot):
    cfg = [text_of(SAMPLES / "config" / "$config.dat")]
    p = read(module(setting, "LIN {X 1,Y 2,Z 3}"), config=cfg)
    np.testing.assert_allclose(p.frames[p.targets.frame[0]].base, transform(rz(rot), origin), atol=1e-9)


def test_tool_settings_and_with_lists():
    cfg = [text_of(SAMPLES / "config" / "$config.dat")]
    dat = ("DEFDAT t\nDECL FDAT FT={TOOL_NO 1,BASE_NO 2,IPO_FRAME #TCP}\n"
           "DECL FDAT FB={TOOL_NO 2,BASE_NO 1,IPO_FRAME #BASE}\nENDDAT\n")
    p = read(module(
        "BAS(#TOOL, 2)", "BAS(#BASE, 1)",
        "LIN {X 1,Y 2,Z 3}",
        "SLIN {X 4,Y 5,Z 6} WITH $TOOL = STOOL2(FB), $BASE = SBASE(2)",
        "LIN {X 7,Y 8,Z 9}",
        "SLIN {X 1,Y 2,Z 3} WITH $BASE = SBASE(FT.BASE_NO), $IPO_MODE = SIPO_MODE(FT.IPO_FRAME)",
    ), dat, config=cfg)
    t = p.targets
    origin = [p.frames[f].base[:3, 3].tolist() if f >= 0 else None for f in t.frame]
    # the WITH list holds for its motion only; external TCP (#TCP) is not resolved
    assert origin == [[1850, -300, 650], [1780, 150, 700], [1850, -300, 650], None]
    np.testing.assert_allclose(p.frames[t.frame[0]].tool, [0, 0, 185, 0, 0, 0])
    np.testing.assert_allclose(p.frames[t.frame[1]].tool, [0, 0, 185, 0, 0, 0])
    assert codes(p) == ["P201"] and "#TCP" in p.diagnostics[0].message


@pytest.mark.parametrize("setting,message", [
    ("BAS(#BASE, 3)", "BASE_DATA[3]"),
    ("$BASE = BASE_DATA[N]", "run-time index"),
    ("$BASE = EK(MACHINE_DEF[2].ROOT, MACHINE_DEF[2].MECH_TYPE, BASE_DATA[1])", "external kinematic"),
    ("$BASE.X = XOFF", "XOFF is not declared"),
])
def test_unresolvable_bases_warn(setting, message):
    cfg = ["DEFDAT $CONFIG\nDECL GLOBAL FRAME BASE_DATA[32]\nBASE_DATA[1]={X 1800,Y 0,Z 600,A 0,B 0,C 0}\nENDDAT\n"]
    p = read(module(setting, "LIN {X 1,Y 2,Z 3}", "LIN {X 4,Y 5,Z 6}"), config=cfg)
    assert (p.targets.frame == -1).all()
    (d,) = p.diagnostics
    assert d.code in ("P201", "P225") and message in d.message and "2 target" in d.message and d.line == 2


def test_name_used_in_two_frames_is_two_rows_of_one_target():
    p = read(module("LIN XP1", "$BASE = {X 100,Y 0,Z 0,A 0,B 0,C 0}", "LIN XP1"),
             "DEFDAT t\nDECL E6POS XP1={X 1,Y 2,Z 3}\nENDDAT\n")
    t = p.targets
    assert len(t) == 2 and codes(p) == [] and t.twin.tolist() == [-1, 0] and t.prev.tolist() == [-1, 0]
    np.testing.assert_allclose(p.frames[t.frame[0]].base, np.eye(4))
    np.testing.assert_allclose(p.frames[t.frame[1]].base[:3, 3], [100, 0, 0])


def test_partial_aggregates_fill_within_a_def_and_frame():
    p = read("\n".join([
        "DEF t( )", "LIN {X 1,Y 2,Z 3,A 10,B 80,C 5}", "LIN {X 4}", "LIN {Y 7,A 11}", "END",
        "DEF u( )", "LIN {X 8}", "END",
    ]))
    t = p.targets
    np.testing.assert_allclose(t.poses[:3], [[1, 2, 3, 10, 80, 5], [4, 2, 3, 10, 80, 5], [4, 7, 3, 11, 80, 5]])
    assert np.isnan(t.poses[3, 1:]).all()  # a new DEF knows no current position


def test_stamps_and_newlines():
    src = f"DEF t( )\r\n; {STAMP_PREFIX} demo.onnx 2024\r\nLIN {{X 1,Y 2,Z 3}}\r\nEND"
    p = read(src, "DEFDAT t\nENDDAT\n")
    assert p.stamps == {0: f"; {STAMP_PREFIX} demo.onnx 2024"}
    assert p.newlines == ["\r\n", "\n"]
    p = read('DEF t( )\nMSG[] = "' + STAMP_PREFIX + '"\nEND\n')
    assert p.stamps == {}


# ------------------------------------------------------------------ errors

ERRORS = [
    (module("LIN {X 1,Y 2 Z 3}"), "P101", 2, 14, "expected ',' or '}' in aggregate, found 'Z'"),
    (module("LIN {X 1.5.5,Y 2,Z 3}"), "P101", 2, 8, "malformed number '1.5.5'"),
    (module("LIN {X 1,Y 2,Z 3} ?"), "P101", 2, 19, "unexpected '?'"),
    (module("LIN {X 1,Y 2,Z"), "P101", 2, 15, "found end of line"),
    (module("LIN {X 1,Y 2,Z 1E999}"), "P103", 2, 16, "not a finite number"),
    (module("IF x THEN", "LIN {X 1,Y 2,Z 3}"), "P101", 4, 1, "END does not close IF (line 2)"),
    (module("ENDIF"), "P101", 2, 1, "ENDIF does not close DEF"),
    ("DEF t( )\nLIN {X 1,Y 2,Z 3}\n", "P101", 1, 1, "DEF t has no matching END"),
    (module("SPL {X 1,Y 2,Z 3}"), "P101", 2, 1, "SPL must stand inside SPLINE"),
    (module("SPLINE", "SPL {X 1,Y 2,Z 3}"), "P101", 4, 1, "END does not close SPLINE"),
    (module("ENDSPLINE"), "P101", 2, 1, "ENDSPLINE does not close DEF"),
    ("LIN {X 1,Y 2,Z 3}\n", "P101", 1, 1, "inside DEF"),
    ("; only a comment\n", "P104", 1, 1, "no DEF"),
    ("", "P104", 1, 1, "empty"),
    ("  \r\n\t\n", "P104", 1, 1, "empty"),
    ("DEFDAT t\nENDDAT\n", "P104", 1, 1, "DEFDAT"),
    (module("LIN {X 1,Y 2,Z 3}") + "DEF u( )\nDEF v( )\nEND\n", "P101", 5, 1, "missing END"),
]


@pytest.mark.parametrize("line,name", [("  LIN {X xoff,Y 2,Z 3}", "xoff"), ("LIN {X 1,Y NAN,Z 3}", "NAN")])
def test_a_component_that_is_an_undeclared_name_is_not_known(line, name):
    p = read(module(line))
    assert len(p.targets) == 0 and codes(p) == ["P212"] and p.diagnostics[0].line == 2
    assert f"{name.upper()} is not declared" in p.diagnostics[0].message


@pytest.mark.parametrize("src,code,line,col,message", ERRORS)
def test_errors_name_the_place(src, code, line, col, message):
    with pytest.raises(PostprocError) as e:
        read(src)
    assert (e.value.code, e.value.line, e.value.col) == (code, line, col), str(e.value)
    assert message in e.value.message
    assert str(e.value).startswith(f"t.src:{line}:{col}: {code} ")


def test_error_in_dat_names_the_dat():
    with pytest.raises(PostprocError) as e:
        read(module("LIN XP1"), "DEFDAT t\nDECL E6POS XP1={X 1,Y 2,,Z 3}\nENDDAT\n")
    assert e.value.path == "t.dat" and (e.value.line, e.value.col) == (2, 25)  # the second ','
    assert "expected" in e.value.message and "found ','" in e.value.message


def test_unbalanced_fold_is_a_warning():
    p = read(module(";FOLD open", "LIN {X 1,Y 2,Z 3}"))
    assert codes(p) == ["P105"] and p.diagnostics[0].line == 2


# ------------------------------------------------------------------ the fast path


def big_program(n: int) -> str:
    """Lines of many shapes: signs, partial aggregates, CIRC, comments and strings with
    numbers, a base change halfway, a spline block, CRLF and LF."""
    rng = np.random.default_rng(1)
    out = ["&ACCESS RVP", "DEF big( )", "$BASE = {X 1800,Y -400,Z 600,A 0,B 0,C 0}"]
    for i in range(n):
        x, y, z, a, b, c = rng.uniform(-300, 300, 6).round(3)
        k = i % 97
        if k == 5:
            out.append(f"LIN {{X {x},Y {y},Z {z}}} C_DIS")
        elif k == 9:
            out.append(f"CIRC {{X {x},Y {y},Z {z}}},{{X {y},Y {x},Z {z}}}, CA {a} C_VEL")
        elif k == 13:
            out.append(f"; point {i}: {{X {x}, Y {y}}}")
        elif k == 17:
            out.append(f'MSG[] = "{x} {{Z {z}}}; ok"')
        elif k == 21:
            out.append(f"$VEL.CP = {abs(a) / 100}")
        elif k == 25:
            out.append(f"LIN {{Y {y}}}")
        elif k == 40:
            out.append(f"LIN {{X {x},Y {y},Z {z},A {a},B {b},C {c}}} C_VEL ; seg{i} P{i}.")
        elif k == 30:
            out.append(f"SPLINE\nSPL {{X {x},Y {y},Z {z},A {a},B {b},C {c}}}\nENDSPLINE")
        else:
            out.append(f"LIN {{X {x},Y {y},Z {z},A {a},B {b},C {c}}} C_VEL")
        if i == n // 2:
            out.append("$BASE = {X 1900,Y 0,Z 700,A 90,B 0,C 0}")
    out.append("END")
    return "\r\n".join(out[: len(out) // 2]) + "\r\n" + "\n".join(out[len(out) // 2:])


def test_accelerated_read_equals_line_by_line_read():
    src = big_program(12000)
    dat = "DEFDAT big\nDECL CHAR MSG[40]\nENDDAT\n"
    fast, slow = read(src, dat), read(src, dat, accelerate=False)
    assert len(fast.targets) == len(slow.targets) > 10000
    for name in ("poses", "spans", "file", "line", "col", "frame", "motion"):
        np.testing.assert_array_equal(getattr(fast.targets, name), getattr(slow.targets, name), err_msg=name)
    assert len(fast.frames) == len(slow.frames) == 2
    assert codes(fast) == codes(slow) == []
    assert_spans_exact(fast)


def test_accelerated_read_reports_errors_at_the_token():
    src = big_program(6000)
    end = src.rindex("\nEND")
    src = src[:end] + "\nLIN {X 1,Y 2,Z 1E999,A 0,B 90,C 0} C_VEL" + src[end:]
    with pytest.raises(PostprocError) as e:
        read(src)
    line = src[: src.index("1E999")].count("\n") + 1
    assert (e.value.code, e.value.line, e.value.col) == ("P103", line, 16)


@pytest.mark.parametrize("tail,line_of,message", [
    ("END\nLIN {X 1,Y 2,Z 3,A 0,B 90,C 0} C_VEL\n", "LIN {X 1,Y 2,Z 3,", "inside DEF"),
    ("SPL {X 1,Y 2,Z 3,A 0,B 90,C 0}\nEND\n", "SPL", "inside SPLINE"),
])
def test_accelerated_read_checks_the_block_structure(tail, line_of, message):
    src = big_program(6000)
    src = src[: src.rindex("END")] + tail
    with pytest.raises(PostprocError) as e:
        read(src)
    line = src[: src.rindex(line_of)].count("\n") + 1
    assert (e.value.code, e.value.line, e.value.col) == ("P101", line, 1) and message in e.value.message


def test_planning_measurement_program_reads_back():
    """The measurement programs postproc writes (planning.py) read back: the N poses plus
    the approach/retreat points, all in $NULLFRAME with the robot's tool."""
    from postproc.calibration.planning import krl_measurement_program

    class StubRobot:  # what krl_measurement_program asks of a robot, without Pinocchio
        name, tool_name, tool = "stub", "probe", np.array([0.0, 0.0, 150.0, 0.0, 0.0, 0.0])
        home_q = [0.0, -90.0, 90.0, 0.0, 0.0, 0.0]

        def ik(self, poses):
            return np.zeros((len(poses), 6)), np.ones(len(poses), bool)

        def status_turn(self, q):
            return np.full(len(q), 2), np.zeros(len(q), int)

    poses = np.array([[2000, 0, 900, 0, 90, 0], [2100, -100, 1000, 2, 88, -1]], float)
    text = krl_measurement_program(poses, "meas", StubRobot())
    p = krl.read(["meas.src"], [text])
    assert len(p.targets) == 4 and p.diagnostics == []
    np.testing.assert_allclose(p.targets.poses[1:3], poses)
    assert len(p.frames) == 1
    np.testing.assert_allclose(p.frames[0].base, np.eye(4))
    np.testing.assert_allclose(p.frames[0].tool, StubRobot.tool)


@pytest.mark.parametrize("lhs", ["#BASE", "5", "ABS(X)"])
def test_an_assignment_to_what_is_not_a_variable_is_refused_located(lhs):
    # (found by the fuzzer: '#BASE = {…}' for '$BASE = {…}' crashed the analysis)
    text = f"DEF p()\n  {lhs} = {{X 1800.0,Y -400.0,Z 600.0,A 0.0,B 0.0,C 0.0}}\n  LIN {{X 1,Y 2,Z 3}}\nEND\n"
    with pytest.raises(PostprocError) as e:
        krl.read(["p.src"], [text], active=ActiveFrames(base=0, tool="model"))
    assert (e.value.line, e.value.col, e.value.code) == (2, 3, "P101") and "not a variable" in str(e.value)


@pytest.mark.parametrize("old, new", [("INTERRUPT ON 5", "INTERRUPT ON 1E999"), ("INTERRUPT OFF 5", "INTERRUPT OFF 1E999"),
                                      ("INTERRUPT DECL 5 WHEN", "INTERRUPT DECL 1E999 WHEN")])
def test_numbers_of_infinity_where_a_whole_number_stands_are_not_known(old, new):
    # (found by the fuzzer: an interrupt's number or an index of 1E999 crashed the analysis: int(inf))
    path = SAMPLES / "syntax" / "handlers.src"
    text = text_of(path).replace(old, new)
    assert new in text
    p = krl.read([str(path)], [text], active=ActiveFrames(base=0, tool="model"))
    assert len(p.targets)
    index = "DEF q()\n  DECL E6POS XP[2]\n  LIN XP[1E999]\nEND\n"
    assert [d.code for d in krl.read(["q.src"], [index], active=ActiveFrames(base=0, tool="model")).diagnostics]

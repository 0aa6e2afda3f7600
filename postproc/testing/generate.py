"""Small random robot programs for the property tests (hypothesis strategies): branches, loops,
jumps, calls with OUT parameters, copies with offsets, frame changes, code that is not read —
the constructs issue 24 found the product wrong on, combined at random.

``krl_programs()`` draws (files, texts, config texts) of a KRL module: a .src with a main DEF
and its subroutines, a .dat with the points, a $config.dat with two bases. Targets stay inside
the test models' envelope and the robot's reach (points near (2000, 0, 900), small frames).
"""
from __future__ import annotations

from hypothesis import strategies as st

__all__ = ["krl_programs", "rapid_programs", "urscript_programs", "ls_programs", "CONFIG", "LS_FRAMES"]

CONFIG = ("DEFDAT $CONFIG\nDECL GLOBAL FRAME BASE_DATA[32]\n"
          "BASE_DATA[1]={X 40.0,Y -30.0,Z 20.0,A 5.0,B 0.0,C 0.0}\n"
          "BASE_DATA[2]={X -50.0,Y 60.0,Z -10.0,A -8.0,B 2.0,C 0.0}\nENDDAT\n")
SUBS = ("DEF lift(P:OUT)\n  DECL E6POS P\n  P.Z = P.Z + 120\nEND\n"
        "DEF visit( )\n  LIN XP2\n  LIN {Z 980.0}\nEND\n"
        "DEF setbase(n:IN)\n  DECL INT n\n  BAS(#BASE, n)\nEND\n"
        "DEF shift(n:OUT)\n  DECL INT n\n  n = 2\nEND\n")

_coord = st.integers(-300, 300)


def _point(draw, name: str, configurations: bool = False) -> str:
    x, y, z = draw(_coord), draw(_coord), draw(st.integers(-200, 250))
    return f"DECL E6POS {name}={{X {2000 + x}.0,Y {y}.5,Z {900 + z}.0,A 0.0,B 90.0,C 0.0{_st(draw, configurations)}}}"


def _st(draw, configurations: bool) -> str:
    """``,S s,T t`` (or S alone, or nothing) where ``configurations``: the arm branches every
    generated pose has on the KR500 (S 2, S 6: the wrist either way; with bit 4, which says
    nothing of the arm), turns of the wrist joints."""
    if not configurations or not draw(st.booleans()):
        return ""
    s = draw(st.sampled_from([2, 6, 18, 22]))
    t = draw(st.sampled_from([None, 0, 8, 32, 40, 58]))
    return f",S {s}" + (f",T {t}" if t is not None else "")


_LOAD_MASSES = (0, 150, 300)


def _load_statement(draw) -> str:
    """A payload change (issue 33): ``$LOAD`` set whole, its mass alone, or from LOAD_DATA by the tool's
    number (BAS #TOOL: $config.dat's LOAD_DATA[1], 2 not in it), or by code not read."""
    choice = draw(st.integers(0, 4))
    if choice <= 1:
        m, z = draw(st.sampled_from(_LOAD_MASSES)), draw(st.integers(0, 300))
        return f"$LOAD = {{M {m}.0,CM {{X 0.0,Y 0.0,Z {z}.0,A 0.0,B 0.0,C 0.0}},J {{X 0.0,Y 0.0,Z 0.0}}}}"
    if choice == 2:
        return f"$LOAD.M = {draw(st.sampled_from(_LOAD_MASSES))}.0"
    if choice == 3:
        return f"BAS(#TOOL, {draw(st.integers(1, 2))})\n$TOOL = $NULLFRAME"
    return "gripper()"


@st.composite
def _statements(draw, depth: int, labels: list, configurations: bool = False, loads: bool = False):
    out = []
    cf = configurations
    for _ in range(draw(st.integers(1, 4))):
        if loads and draw(st.integers(0, 2)) == 0:
            out += _load_statement(draw).split("\n")
        k = draw(st.integers(1, 4))
        choice = draw(st.integers(0, 15 if depth > 0 else 10))
        if choice == 0:
            out.append(f"LIN XP{k}")
        elif choice == 1:
            out.append(f"PTP XP{k}")
        elif choice == 2:
            x, y, z = draw(_coord), draw(_coord), draw(st.integers(-150, 200))
            motion = "PTP" if cf and draw(st.booleans()) else "LIN"
            out.append(f"{motion} {{X {2000 + x}.25,Y {y}.75,Z {900 + z}.5,A 0.0,B 90.0,C 0.0{_st(draw, cf)}}}")
        elif choice == 3 and draw(st.booleans()):
            out.append(f"LIN {{Z {900 + draw(st.integers(-100, 150))}.0}}")
        elif choice == 3:  # a relative motion: from the start known on every path, a target of its own
            d = draw(st.integers(-30, 30))
            out.append(draw(st.sampled_from([f"LIN_REL {{X {d}.5,Z 10.0}}", f"LIN_REL {{Y {d}.0}} #TOOL",
                                             f"SLIN_REL {{Z {d}.25,A 0}}", "CIRC_REL {X 20.0,Y 20.0},{X 40.0,Y 0.0}",
                                             "PTP_REL {A3 5.0}"])))
        elif choice == 4:
            out.append(f"BAS(#BASE, {draw(st.integers(0, 2))})")
        elif choice == 5:
            out.append(f"nB = {draw(st.integers(0, 2))}")
            out.append("BAS(#BASE, nB)")
        elif choice == 6:
            out.append(f"lift(XP{k})")
        elif choice == 7:
            out.append(f"XP{k} = XP{draw(st.integers(1, 4))}")
        elif choice == 8:
            out.append(f"XP{k}.X = XP{draw(st.integers(1, 4))}.X + {draw(st.integers(-40, 40))}")
        elif choice == 9:
            out.append(draw(st.sampled_from(["visit()", f"setbase({draw(st.integers(0, 2))})", "shift(nB)",
                                             "gripper()", "$BASE = XF"])))
        elif choice == 10:
            label = f"L{len(labels)}"
            labels.append(label)
            out.append(f"GOTO {label}")
            out.append(f"LIN XP{k}")
            out.append(f"{label}:")
        elif choice in (11, 12):
            then = draw(_statements(depth - 1, labels, cf, loads))
            other = draw(_statements(depth - 1, labels, cf, loads)) if draw(st.booleans()) else []
            out.append(f"IF $IN[{k}] THEN")
            out += ["  " + s for s in then]
            if other:
                out.append("ELSE")
                out += ["  " + s for s in other]
            out.append("ENDIF")
        elif choice == 13:
            out.append("FOR I = 1 TO 2")
            out += ["  " + s for s in draw(_statements(depth - 1, labels, cf, loads))]
            out.append("ENDFOR")
        elif choice == 14:
            out.append(f"WHILE $IN[{k + 4}]")
            out += ["  " + s for s in draw(_statements(depth - 1, labels, cf, loads))]
            out.append("ENDWHILE")
        else:
            out.append(f"SWITCH nB\nCASE 1\n  LIN XP{k}\nCASE 2\n  BAS(#BASE, 1)\nDEFAULT\n  LIN XP{draw(st.integers(1, 4))}"
                       "\nENDSWITCH")
    return out


@st.composite
def krl_programs(draw, depth: int = 2, configurations: bool = False, loads: bool = False):
    """(files, texts, config texts) of a random KRL module (see the module text); with
    ``configurations`` its points and literal targets write S/T (``_st``) and some literal
    targets are PTPs: a LIN's S/T the controller does not read, a PTP's it does; with ``loads``
    the payload changes between the motions (``_load_statement``: $LOAD, $LOAD.M, BAS(#TOOL, n)
    with LOAD_DATA[1] in the $config.dat, code not read), in branches and loops too."""
    labels: list = []
    body = ["BAS(#BASE, 0)", "nB = 1"] + draw(_statements(depth, labels, configurations, loads))
    src = ("DEF t( )\n  DECL INT nB, I\n  EXT gripper()\n" + "".join(f"  {s}\n" for s in body) + "END\n" + SUBS)
    dat = ("DEFDAT t\n" + "".join(f"  {_point(draw, f'XP{i}', configurations)}\n" for i in range(1, 5)) +
           "  DECL FRAME XF={X 20.0,Y 10.0,Z -5.0,A 3.0,B 0.0,C 0.0}\nENDDAT\n")
    return ["t.src", "t.dat"], [src, dat], [LOAD_CONFIG if loads else CONFIG]


# the $config.dat with LOAD_DATA (BAS(#TOOL, 1) sets $LOAD from it; LOAD_DATA[2] is not set: not known)
LOAD_CONFIG = CONFIG.replace("ENDDAT\n", "DECL GLOBAL LOAD LOAD_DATA[16]\n"
                             "LOAD_DATA[1]={M 150.0,CM {X 0.0,Y 20.0,Z 180.0,A 0.0,B 0.0,C 0.0},J {X 0.0,Y 0.0,Z 0.0}}\n"
                             "ENDDAT\n")


# ---------------------------------------------------------------------------------------- RAPID
RAPID_EAX = "[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]"
RAPID_Q = "[0,0,1,0]"  # (the tool pointing down)
RAPID_ROUTINES = ("PROC lift(INOUT robtarget p, num dz)\n  p.trans.z := p.trans.z + dz;\nENDPROC\n"
                  "PROC visit(robtarget p)\n  MoveL p, v100, fine, tool0;\n  MoveL Offs(p, 0, 0, 40), v100, z10, tool0;\n"
                  "ENDPROC\n"
                  "PROC touch(VAR robtarget p)\n  p := Offs(p, 5, 0, 0);\n  MoveL p, v100, fine, tool0\\WObj:=wPart;\n"
                  "ENDPROC\n")


def _robtarget(draw, around=(2000, 0, 900)) -> str:
    x, y, z = around[0] + draw(_coord), around[1] + draw(_coord), around[2] + draw(st.integers(-200, 250))
    return f"[[{x}.5,{y}.25,{z}],{RAPID_Q},[0,0,0,0],{RAPID_EAX}]"


@st.composite
def _rapid_statements(draw, depth: int, labels: list):
    out = []
    point = st.sampled_from(["p1", "p2", "p3", "p4"])
    for _ in range(draw(st.integers(1, 4))):
        choice = draw(st.integers(0, 19 if depth > 0 else 14))
        p, q = draw(point), draw(point)
        if choice == 0:
            out.append(f"MoveL {p}, v100, fine, tool0;")
        elif choice == 1:
            out.append(f"MoveJ {p}, v500, z20, tool0;")
        elif choice == 2:
            out.append(f"MoveL {_robtarget(draw)}, v100, fine, tool0;")
        elif choice == 3:
            out.append(f"MoveL Offs({p}, {draw(st.integers(-40, 40))}, 0, {draw(st.integers(0, 60))}), v100, fine, "
                       "tool0;")
        elif choice == 4:
            out.append(f"MoveL RelTool({p}, 0, {draw(st.integers(-30, 30))}, {draw(st.integers(-50, 0))}), v100, "
                       "fine, tool0;")
        elif choice == 5:
            out.append(f"MoveL {p}, v100, fine, tool0\\WObj:=wPart;")
        elif choice == 6:
            out.append(draw(st.sampled_from([f"PDispOn \\ExeP:={p}, {q}, tool0;", "PDispSet dispF;", "PDispOff;"])))
        elif choice == 7:
            out.append(draw(st.sampled_from([f"wPart.oframe.trans := {p}.trans;",
                                             f"wPart.uframe.trans.x := {draw(st.integers(-100, 100))};"])))
        elif choice == 8:
            out.append(draw(st.sampled_from([f"pw := {p};", f"pw := Offs({p}, 0, {draw(st.integers(-30, 30))}, 20);",
                                             f"{draw(st.sampled_from(['p3', 'p4']))} := {p};"])))
        elif choice == 9:
            out.append(f"lift {draw(st.sampled_from(['pw', 'p3', 'p4']))}, {draw(st.integers(10, 80))};")
        elif choice == 10:
            out.append("MoveL pw, v100, fine, tool0;")
        elif choice == 11:
            out.append(draw(st.sampled_from([f"visit {p};", f"touch {draw(st.sampled_from(['pw', 'p3', 'p4']))};",
                                             "gripper;", f"n := {draw(st.integers(0, 2))};"])))
        elif choice == 12:
            label = f"lbl{len(labels)}"
            labels.append(label)
            out += [f"GOTO {label};", f"MoveL {p}, v100, fine, tool0;", f"{label}:"]
        elif choice == 13:
            out.append(f"MoveL {p}, v100, fine, tool0\\WObj:=wFix;")
        elif choice == 14:
            out.append(f"MoveC {p}, {q}, v100, fine, tool0;")
        elif choice in (15, 16):
            then = draw(_rapid_statements(depth - 1, labels))
            other = draw(_rapid_statements(depth - 1, labels)) if draw(st.booleans()) else []
            out.append(f"IF DInput(di{draw(st.integers(1, 4))}) = 1 THEN")
            out += ["  " + s for s in then]
            if other:
                out.append("ELSE")
                out += ["  " + s for s in other]
            out.append("ENDIF")
        elif choice == 17:
            out.append("FOR i FROM 1 TO 2 DO")
            out += ["  " + s for s in draw(_rapid_statements(depth - 1, labels))]
            out.append("ENDFOR")
        elif choice == 18:
            out.append(f"WHILE DInput(di{draw(st.integers(5, 8))}) = 1 DO")
            out += ["  " + s for s in draw(_rapid_statements(depth - 1, labels))]
            out.append("ENDWHILE")
        else:
            out.append("TEST n")
            out.append("CASE 1:")
            out += ["  " + s for s in draw(_rapid_statements(depth - 1, labels))]
            out.append("CASE 2:")
            out.append("  PDispSet dispF;")
            out.append("DEFAULT:")
            out.append(f"  MoveL {q}, v100, fine, tool0;")
            out.append("ENDTEST")
    return out


@st.composite
def rapid_programs(draw, depth: int = 2):
    """(files, texts, config texts) of a random RAPID module: robtargets declared at the top
    (CONST and VAR) and moved to in another order, a work object set from a robtarget, program
    displacement (PDispOn \\ExeP, PDispSet), Offs/RelTool, INOUT/VAR parameters, routines called
    twice, IF/WHILE/FOR/TEST/GOTO, a routine not read."""
    labels: list = []
    body = ["n := 1;"] + draw(_rapid_statements(depth, labels))
    data = [f"CONST robtarget p1:={_robtarget(draw)};", f"CONST robtarget p2:={_robtarget(draw)};",
            f"VAR robtarget p3:={_robtarget(draw)};", f"PERS robtarget p4:={_robtarget(draw)};",
            "VAR robtarget pw;", "VAR num n:=0;",
            'PERS wobjdata wPart:=[FALSE,TRUE,"",[[0,0,0],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];',
            'PERS wobjdata wFix:=[FALSE,TRUE,"",[[30,-20,10],[0.9961947,0,0,0.0871557]],[[5,5,0],[1,0,0,0]]];',
            "CONST pose dispF:=[[12,-8,4],[0.9990482,0,0,0.0436194]];"]
    text = ("MODULE m\n" + "".join(f"  {d}\n" for d in data) + "PROC main()\n" + "".join(f"  {s}\n" for s in body) +
            "ENDPROC\n" + RAPID_ROUTINES + "ENDMODULE\n")
    return ["m.mod"], [text], None


def dialect_cases(dialect: str, depth: int = 2):
    """(the strategy of ``dialect``'s random programs, the ActiveFrames its check states)."""
    from ..programs import ActiveFrames

    if dialect == "krl":
        return krl_programs(depth=depth), ActiveFrames(base=0, tool="model")
    if dialect == "rapid":
        return rapid_programs(depth=depth), None
    if dialect == "urscript":
        return urscript_programs(depth=depth), ActiveFrames(tool="model")
    if dialect == "fanuc":
        return ls_programs(depth=depth), None
    raise ValueError(dialect)


# ---------------------------------------------------------------------------------------- URScript
UR_FUNCTIONS = ("  def lift(q, dz=0.05):\n    return pose_add(q, p[0, 0, dz, 0, 0, 0])\n  end\n"
                "  def visit(q, up=0.04, v=0.25):\n    movel(q, a=1.2, v=v)\n"
                "    movel(pose_trans(q, p[0, 0, -up, 0, 0, 0]), a=1.2, v=v)\n  end\n")


def _ur_pose(draw) -> str:
    x, y, z = 2000 + draw(_coord), draw(_coord), 900 + draw(st.integers(-200, 250))
    return f"p[{x / 1000:.4f}, {y / 1000:.4f}, {z / 1000:.4f}, 0, 3.1416, 0]"


@st.composite
def _ur_statements(draw, depth: int, loop: bool):
    out = []
    pose = st.sampled_from(["wp1", "wp2", "wp3", "wp4"])
    for _ in range(draw(st.integers(1, 4))):
        choice = draw(st.integers(0, 17 if depth > 0 else 13))
        p, q = draw(pose), draw(pose)
        if choice == 0:
            out.append(f"movel({p}, a=1.2, v=0.25)")
        elif choice == 1:
            out.append(f"{draw(st.sampled_from(['movej', 'movep']))}({p}, a=1.4, v=1.05)")
        elif choice == 2:
            out.append(f"movel({_ur_pose(draw)}, a=1.2, v=0.25)")
        elif choice == 3:
            out.append(f"movel(pose_trans(feat, {p}), a=1.2, v=0.25)")
        elif choice == 4:
            out.append(f"movel(pose_trans({p}, p[0, {draw(st.integers(-30, 30)) / 1000}, -0.02, 0, 0, 0]))")
        elif choice == 5:
            out.append(draw(st.sampled_from([f"{p} = {q}", f"{p} = lift({q})", f"{p} = lift({q}, dz=0.03)",
                                             f"{p} = pose_add({q}, p[0.01, 0, 0, 0, 0, 0])"])))
        elif choice == 6:
            out.append(draw(st.sampled_from([f"visit({p})", f"visit({p}, v=0.1)", f"visit({p}, 0.02)"])))
        elif choice == 7:
            out.append(draw(st.sampled_from(["set_tcp(p[0, 0, 0.15, 0, 0, 0])", "set_tcp(p[0.01, 0, 0.2, 0, 0, 0.1])"])))
        elif choice == 8:
            out.append(f"movej(get_inverse_kin({p}), a=1.4, v=1.05)")
        elif choice == 9:
            out.append(draw(st.sampled_from(["gripper_open()", "n = n + 1", "feat = pose_trans(feat, p[0.01, 0, 0, 0, 0, 0])",
                                             f"feat = {p}"])))
        elif choice == 10:
            out.append(f"movel(pose_trans(feat, p[0.0, 0.0, {draw(st.integers(-50, 0)) / 1000}, 0, 0, 0]))")
        elif choice == 11:
            out.append("movej([0.1, -1.2, 1.4, -1.8, -1.5708, 0.0], a=1.4, v=1.05)")
        elif choice == 12:
            out.append(draw(st.sampled_from(["break", "continue"])) if loop else f"movel({q})")
        elif choice == 13:
            out.append(f"movec({p}, {q}, a=1.2, v=0.1, r=0)")
        elif choice in (14, 15):
            then = draw(_ur_statements(depth - 1, loop))
            other = draw(_ur_statements(depth - 1, loop)) if draw(st.booleans()) else []
            out.append(f"if get_standard_digital_in({draw(st.integers(0, 3))}):")
            out += ["  " + s for s in then]
            if other:
                out.append("else:")
                out += ["  " + s for s in other]
            out.append("end")
        elif choice == 16:
            out.append(f"while get_standard_digital_in({draw(st.integers(4, 7))}):")
            out += ["  " + s for s in draw(_ur_statements(depth - 1, True))]
            out.append("end")
        else:
            out.append("if n == 1:")
            out += ["  " + s for s in draw(_ur_statements(depth - 1, loop))]
            out.append("elif n == 2:")
            out.append("  halt")
            out.append("end")
    return out


@st.composite
def urscript_programs(draw, depth: int = 2):
    """(files, texts, None) of a random URScript program: pose variables declared at the top and
    moved to in another order, functions with default and keyword arguments, if/elif/while/break/
    continue, pose_trans frames (a feature), set_tcp in branches, get_inverse_kin, a function not
    read."""
    body = ["set_tcp(p[0, 0, 0.1, 0, 0, 0])"] + [f"global wp{k} = {_ur_pose(draw)}" for k in range(1, 5)]
    body += ["global feat = p[0.02, -0.01, 0.005, 0, 0, 0.05]", "global n = 1"]
    body += draw(_ur_statements(depth, False))
    text = "def prog():\n" + UR_FUNCTIONS + "".join(f"  {s}\n" for s in body) + "end\n"
    return ["u.script"], [text], None


# ---------------------------------------------------------------------------------------- Fanuc LS
LS_FRAMES = ("[uframe.1]\nxyzwpr = [1800.0, -100.0, 700.0, 0.0, 0.0, 30.0]\n"
             "[uframe.2]\nxyzwpr = [1700.0, 150.0, 650.0, 5.0, -3.0, -20.0]\n"
             "[utool.1]\nxyzwpr = [0.0, 0.0, 200.0, 0.0, 0.0, 0.0]\n"
             "[utool.2]\nxyzwpr = [10.0, 0.0, 250.0, 0.0, 0.0, 0.0]\n")


def _ls_position(draw, n: int) -> str:
    x, y, z = 200 + draw(_coord), 100 + draw(_coord), 200 + draw(st.integers(-150, 200))
    uf = draw(st.sampled_from([1, 1, 1, 2]))
    return (f"P[{n}]{{\n   GP1:\n\tUF : {uf}, UT : 1,\t\tCONFIG : 'N U T, 0, 0, 0',\n"
            f"\tX = {x:9.3f}  mm,\tY = {y + 0.5:9.3f}  mm,\tZ = {z:9.3f}  mm,\n"
            f"\tW =   180.000 deg,\tP =     0.000 deg,\tR =     0.000 deg\n}};")


@st.composite
def _ls_statements(draw, depth: int, labels: list):
    out = []
    for _ in range(draw(st.integers(1, 4))):
        choice = draw(st.integers(0, 16 if depth > 0 else 12))
        k, j = draw(st.integers(1, 4)), draw(st.integers(1, 4))
        if choice == 0:
            out.append(f"L P[{k}] 100mm/sec FINE")
        elif choice == 1:
            out.append(f"J P[{k}] 50% CNT50")
        elif choice == 2:
            out.append(f"L P[{k}] 100mm/sec FINE Offset,PR[3]")
        elif choice == 3:
            out.append(f"PR[1]=P[{k}]")
            if draw(st.booleans()):
                out.append(f"PR[1,3]=PR[1,3]+{draw(st.integers(10, 80))}")
        elif choice == 4:
            out.append("L PR[1] 100mm/sec FINE")
        elif choice == 5:
            out += ["PR[3]=PR[3]-PR[3]", f"PR[3,1]={draw(st.integers(-20, 20))}", f"PR[3,3]={draw(st.integers(0, 40))}"]
        elif choice == 6:
            out.append(f"UFRAME_NUM={draw(st.sampled_from([1, 2]))}")
        elif choice == 7:
            out.append(f"UTOOL_NUM={draw(st.sampled_from([1, 2]))}")
        elif choice == 8:
            out.append(draw(st.sampled_from(["CALL GRIPPER", f"R[1]={draw(st.integers(0, 2))}", "PR[2]=PR[1]+PR[3]",
                                             "L PR[2] 100mm/sec FINE"])))
        elif choice == 9:
            n = len(labels) + 1
            labels.append(n)
            out += [f"JMP LBL[{n}]", f"L P[{k}] 100mm/sec FINE", f"LBL[{n}]"]
        elif choice == 10:
            n = len(labels) + 1
            labels.append(n)
            out += [f"IF R[1]={draw(st.integers(0, 2))},JMP LBL[{n}]", f"L P[{k}] 100mm/sec FINE", f"LBL[{n}]"]
        elif choice == 11:
            out.append(f"L P[{k}] 100mm/sec FINE Offset")
        elif choice == 12:
            out.append(f"OFFSET CONDITION PR[{draw(st.sampled_from([1, 3]))}]")
        elif choice in (13, 14):
            then = draw(_ls_statements(depth - 1, labels))
            other = draw(_ls_statements(depth - 1, labels)) if draw(st.booleans()) else []
            out.append(f"IF (DI[{draw(st.integers(1, 4))}]=ON) THEN")
            out += then
            if other:
                out.append("ELSE")
                out += other
            out.append("ENDIF")
        elif choice == 15:
            out.append("FOR R[5]=1 TO 2")
            out += draw(_ls_statements(depth - 1, labels))
            out.append("ENDFOR")
        else:
            a, b = len(labels) + 1, len(labels) + 2
            labels += [a, b]
            out += [f"SELECT R[1]=1,JMP LBL[{a}]", f"       =2,JMP LBL[{b}]", f"       ELSE,JMP LBL[{b}]",
                    f"LBL[{a}]", f"L P[{j}] 100mm/sec FINE", f"LBL[{b}]"]
    return out


@st.composite
def ls_programs(draw, depth: int = 2):
    """(files, texts, [the frame file]) of a random LS program: P[n] and PR[n] copies with
    offsets, Offset,PR[n], OFFSET CONDITION, UFRAME_NUM/UTOOL_NUM, LBL/JMP, IF/SELECT/FOR, CALL of
    a program not given."""
    labels: list = []
    mn = ["UFRAME_NUM=1", "UTOOL_NUM=1", "R[1]=1"] + draw(_ls_statements(depth, labels))
    lines = ["/PROG  T", "/ATTR", "OWNER\t\t= MNEDITOR;", f"LINE_COUNT\t= {len(mn)};", "/MN"]
    lines += [f"{k:4d}:  {line} ;" for k, line in enumerate(mn, start=1)]
    lines += ["/POS"] + [_ls_position(draw, n) for n in range(1, 5)] + ["/END", ""]
    return ["t.ls"], ["\n".join(lines)], [LS_FRAMES]

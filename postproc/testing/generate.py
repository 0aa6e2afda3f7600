"""Small random robot programs for the property tests (hypothesis strategies): branches, loops,
jumps, calls with OUT parameters, copies with offsets, frame changes, code that is not read —
the constructs issue 24 found the product wrong on, combined at random.

``krl_programs()`` draws (files, texts, config texts) of a KRL module: a .src with a main DEF
and its subroutines, a .dat with the points, a $config.dat with two bases. Targets stay inside
the test models' envelope and the robot's reach (points near (2000, 0, 900), small frames).
"""
from __future__ import annotations

from hypothesis import strategies as st

__all__ = ["krl_programs", "CONFIG"]

CONFIG = ("DEFDAT $CONFIG\nDECL GLOBAL FRAME BASE_DATA[32]\n"
          "BASE_DATA[1]={X 40.0,Y -30.0,Z 20.0,A 5.0,B 0.0,C 0.0}\n"
          "BASE_DATA[2]={X -50.0,Y 60.0,Z -10.0,A -8.0,B 2.0,C 0.0}\nENDDAT\n")
SUBS = ("DEF lift(P:OUT)\n  DECL E6POS P\n  P.Z = P.Z + 120\nEND\n"
        "DEF visit( )\n  LIN XP2\n  LIN {Z 980.0}\nEND\n"
        "DEF setbase(n:IN)\n  DECL INT n\n  BAS(#BASE, n)\nEND\n"
        "DEF shift(n:OUT)\n  DECL INT n\n  n = 2\nEND\n")

_coord = st.integers(-300, 300)


def _point(draw, name: str) -> str:
    x, y, z = draw(_coord), draw(_coord), draw(st.integers(-200, 250))
    return f"DECL E6POS {name}={{X {2000 + x}.0,Y {y}.5,Z {900 + z}.0,A 0.0,B 90.0,C 0.0}}"


@st.composite
def _statements(draw, depth: int, labels: list):
    out = []
    for _ in range(draw(st.integers(1, 4))):
        k = draw(st.integers(1, 4))
        choice = draw(st.integers(0, 15 if depth > 0 else 10))
        if choice == 0:
            out.append(f"LIN XP{k}")
        elif choice == 1:
            out.append(f"PTP XP{k}")
        elif choice == 2:
            x, y, z = draw(_coord), draw(_coord), draw(st.integers(-150, 200))
            out.append(f"LIN {{X {2000 + x}.25,Y {y}.75,Z {900 + z}.5,A 0.0,B 90.0,C 0.0}}")
        elif choice == 3:
            out.append(f"LIN {{Z {900 + draw(st.integers(-100, 150))}.0}}")
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
            then = draw(_statements(depth - 1, labels))
            other = draw(_statements(depth - 1, labels)) if draw(st.booleans()) else []
            out.append(f"IF $IN[{k}] THEN")
            out += ["  " + s for s in then]
            if other:
                out.append("ELSE")
                out += ["  " + s for s in other]
            out.append("ENDIF")
        elif choice == 13:
            out.append("FOR I = 1 TO 2")
            out += ["  " + s for s in draw(_statements(depth - 1, labels))]
            out.append("ENDFOR")
        elif choice == 14:
            out.append(f"WHILE $IN[{k + 4}]")
            out += ["  " + s for s in draw(_statements(depth - 1, labels))]
            out.append("ENDWHILE")
        else:
            out.append(f"SWITCH nB\nCASE 1\n  LIN XP{k}\nCASE 2\n  BAS(#BASE, 1)\nDEFAULT\n  LIN XP{draw(st.integers(1, 4))}"
                       "\nENDSWITCH")
    return out


@st.composite
def krl_programs(draw, depth: int = 2):
    """(files, texts, config texts) of a random KRL module (see the module text)."""
    labels: list = []
    body = ["BAS(#BASE, 0)", "nB = 1"] + draw(_statements(depth, labels))
    src = ("DEF t( )\n  DECL INT nB, I\n  EXT gripper()\n" + "".join(f"  {s}\n" for s in body) + "END\n" + SUBS)
    dat = ("DEFDAT t\n" + "".join(f"  {_point(draw, f'XP{i}')}\n" for i in range(1, 5)) +
           "  DECL FRAME XF={X 20.0,Y 10.0,Z -5.0,A 3.0,B 0.0,C 0.0}\nENDDAT\n")
    return ["t.src", "t.dat"], [src, dat], [CONFIG]

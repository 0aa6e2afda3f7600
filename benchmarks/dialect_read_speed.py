"""Read speed of the ABB RAPID, URScript, Fanuc LS (and other non-KRL) readers on generated 100k-target programs.

    python benchmarks/dialect_read_speed.py [--targets 100000] [--dialect rapid|urscript|fanuc]

Per program style: the time of ``postproc.programs.io.read_program`` (best of --repeat), the
targets per second, and the number of targets read (which must be --targets).
"""
from __future__ import annotations

import argparse
import time

import numpy as np

EAX = "[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]"
WOBJ = 'TASK PERS wobjdata wCam:=[FALSE,TRUE,"",[[1900,-100,600],[0.9961947,0,0,0.0871557]],[[0,0,0],[1,0,0,0]]];'
TOOL = "TASK PERS tooldata tCut:=[TRUE,[[0,0,150],[1,0,0,0]],[5,[0,0,50],[1,0,0,0],0,0,0]];"


def _points(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.uniform([-200, -300, 0], [200, 300, 400], size=(n, 3))


def rapid_inline(n: int) -> str:
    """CAM / offline-programming style: one inline robtarget per MoveL."""
    out = ["MODULE cam_big", "  " + TOOL, "  " + WOBJ, "  PROC main()"]
    out += [f"    MoveL [[{x:.3f},{y:.3f},{z:.3f}],[0,0,1,0],[0,0,0,0],{EAX}],v100,z1,tCut\\WObj:=wCam;"
            for x, y, z in _points(n)]
    return "\n".join(out + ["  ENDPROC", "ENDMODULE", ""])


def rapid_declared(n: int) -> str:
    """RobotStudio style: CONST robtarget declarations, then MoveL to each name."""
    pts = _points(n)
    out = ["MODULE big", "  " + TOOL, "  " + WOBJ]
    out += [f"  CONST robtarget p{i}:=[[{x:.3f},{y:.3f},{z:.3f}],[0,0.7071068,0.7071068,0],[0,-1,0,0],{EAX}];"
            for i, (x, y, z) in enumerate(pts)]
    out += ["  PROC main()"] + [f"    MoveL p{i},v100,z1,tCut\\WObj:=wCam;" for i in range(n)]
    return "\n".join(out + ["  ENDPROC", "ENDMODULE", ""])


def ur_inline(n: int) -> str:
    """URScript as a CAM post writes it: one inline pose per movel (metres, rotation vector)."""
    out = ["def cam_big():", "  set_tcp(p[0.0, 0.0, 0.150, 0.0, 0.0, 0.0])"]
    out += [f"  movel(p[{x / 1000:.6f}, {y / 1000:.6f}, {z / 1000:.6f}, 3.141593, 0.0, 0.0], a=1.2, v=0.25, r=0.001)"
            for x, y, z in _points(n)]
    return "\n".join(out + ["end", ""])


def ur_declared(n: int) -> str:
    """Polyscope style: global pose variables, then a movel to each name."""
    pts = _points(n)
    out = ["def big():", "  set_tcp(p[0.0, 0.0, 0.150, 0.0, 0.0, 0.0])"]
    out += [f"  global wp{i} = p[{x / 1000:.9f}, {y / 1000:.9f}, {z / 1000:.9f}, 2.221441469, -2.221441469, 0.0]"
            for i, (x, y, z) in enumerate(pts)]
    out += [f"  movel(wp{i}, a=1.2, v=0.25)" for i in range(n)]
    return "\n".join(out + ["end", ""])


def ls_positions(n: int) -> str:
    """Fanuc LS as ROBOGUIDE / a CAM post writes it: one L P[i] per line, the /POS records after."""
    pts = _points(n)
    out = ["/PROG  BIG", "/ATTR", "OWNER\t\t= MNEDITOR;", f"LINE_COUNT\t= {n};", "/MN"]
    out += [f"{i:4d}:L P[{i}] 100mm/sec CNT100    ;" for i in range(1, n + 1)]
    out.append("/POS")
    for i, (x, y, z) in enumerate(pts, start=1):
        out += [f"P[{i}]{{", "   GP1:", "\tUF : 1, UT : 1,\t\tCONFIG : 'N U T, 0, 0, 0',",
                f"\tX = {x:9.3f}  mm,\tY = {y:9.3f}  mm,\tZ = {z:9.3f}  mm,",
                "\tW =  180.000 deg,\tP =    0.000 deg,\tR =    0.000 deg", "};"]
    return "\n".join(out + ["/END", ""])


LS_FRAMES = "[uframe.1]\nxyzwpr = [1900, -100, 600, 0, 0, 10]\n[utool.1]\nxyzwpr = [0, 0, 150, 0, 0, 0]\n"
CONFIG = {"fanuc": [LS_FRAMES]}  # the frame file (--frames)
STYLES = {"fanuc": [("P[n] records", ls_positions, "big.ls")],
          "rapid": [("inline MoveL", rapid_inline, "cam.mod"), ("declared robtargets", rapid_declared, "big.mod")],
          "urscript": [("inline movel", ur_inline, "cam.script"), ("global pose variables", ur_declared, "big.script")]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--targets", type=int, default=100_000)
    parser.add_argument("--dialect", choices=sorted(STYLES), action="append")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    from postproc.programs.io import read_program

    for dialect in args.dialect or sorted(STYLES):
        for style, make, name in STYLES[dialect]:
            text = make(args.targets)
            best, count = float("inf"), 0
            for _ in range(args.repeat):
                start = time.perf_counter()
                program = read_program([name], [text], dialect, config=CONFIG.get(dialect))
                best = min(best, time.perf_counter() - start)
                count = len(program.targets)
            print(f"{dialect:6s} {style:22s} {count:>8,} targets  {len(text) / 1e6:6.1f} MB  {best:6.2f} s  "
                  f"{count / best:>9,.0f} targets/s")


if __name__ == "__main__":
    main()

"""KRL reader on a set of modules (a cell): $config.dat among the files, a PUBLIC data list
with DECL GLOBAL points, .src/.dat paired by stem, globals missing from the set."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from postproc.core.diagnostics import PostprocError
from postproc.core.frames import frame_to_matrix
from postproc.programs import ActiveFrames, krl

# These programs are about other semantics than the active frames: they state them as the
# user would (--base 0 --tool model), the assumption the reader made silently before P220/P221.
STATED = ActiveFrames(base=0, tool="model")


SAMPLES = Path(__file__).resolve().parent.parent / "samples" / "krl"
CONFIG = (SAMPLES / "config" / "$config.dat").read_bytes().decode("latin-1")
CONFIG_WITH_POINT = CONFIG.replace("ENDDAT", "DECL GLOBAL E6POS XCFG={X 50,Y 60,Z 70,A 0,B 90,C 0,S 2,T 10}\nENDDAT")
POINTS = ("DEFDAT xPoints PUBLIC\n"
          "  DECL GLOBAL E6POS XPICK={X 100,Y 200,Z 300,A 0,B 90,C 0}\n"
          "  DECL GLOBAL E6POS XPLACE={X 400,Y 500,Z 600,A 0,B 90,C 0}\n"
          "  DECL E6POS XLOCAL={X 1,Y 1,Z 1,A 0,B 90,C 0}\n"      # not GLOBAL: only xPoints sees it
          "ENDDAT\n")
MAIN = ("DEF main( )\n"                  # 1
        "  BAS(#BASE, 2)\n"              # 2
        "  LIN XPICK\n"                  # 3
        "  LIN XHOMEPOS\n"               # 4: its .dat
        "  BAS(#BASE, 1)\n"              # 5
        "  LIN XPLACE\n"                 # 6
        "  LIN XCFG\n"                   # 7: $config.dat
        "  LIN XLOCAL\n"                 # 8: not visible
        "  place()\n"                    # 9: place.src, in the set
        "  LIN XPICK\n"                  # 10: BASE_DATA[2] again, set by place(): a second frame
        "END\n")
MAIN_DAT = "DEFDAT main\n  DECL E6POS XHOMEPOS={X 10,Y 20,Z 30,A 0,B 90,C 0}\nENDDAT\n"
PLACE = "DEF place( )\n  BAS(#BASE, 2)\n  LIN XPLACE\nEND\n"


def cell(*names):
    texts = {"main.src": MAIN, "main.dat": MAIN_DAT, "xPoints.dat": POINTS, "$config.dat": CONFIG_WITH_POINT,
             "place.src": PLACE}
    files = [f"R1/Program/{n}" if n != "$config.dat" else "R1/System/$config.dat" for n in names]
    return krl.read(files, [texts[n] for n in names], active=STATED)


def test_a_cell_resolves_globals_across_data_lists_and_config():
    p = cell("main.src", "xPoints.dat", "main.dat", "$config.dat", "place.src")
    t = p.targets
    # each motion in the order it runs, its point in the file it is declared in
    where = [(p.files[f].rsplit("/", 1)[1], int(line)) for f, line in zip(t.file, t.line)]
    assert where == [("xPoints.dat", 2), ("main.dat", 2), ("xPoints.dat", 3), ("$config.dat", 30),
                     ("xPoints.dat", 3), ("xPoints.dat", 2)]
    base1 = frame_to_matrix(np.array([1850.0, -300.0, 650.0, 0, 0, 0]))
    base2 = frame_to_matrix(np.array([1780.0, 150.0, 700.0, 90.0, 0, 0]))
    # XPLACE runs under BASE_DATA[1] (main) and BASE_DATA[2] (place.src): two rows of one target
    # (compensate writes it only if both agree); XPICK at line 10 is under BASE_DATA[2] again, set
    # inside place()
    assert t.frame.tolist() == [0, 0, 1, 1, 0, 0] and t.twin.tolist() == [-1, -1, -1, -1, 2, 0]
    np.testing.assert_allclose(p.frames[0].base, base2)
    np.testing.assert_allclose(p.frames[1].base, base1)
    assert t.config[3].tolist() == [2, 10]
    # XLOCAL is not GLOBAL: not visible from main
    assert [(d.path.rsplit("/", 1)[1], d.code, d.line) for d in p.diagnostics] == [("main.src", "P215", 8)]


def test_a_global_not_in_the_set_is_left_alone_not_an_error_for_the_file():
    p = cell("main.src", "main.dat", "$config.dat", "place.src")  # no xPoints.dat
    assert [(d.path.rsplit("/", 1)[1], d.code, d.line) for d in p.diagnostics] == [
        ("main.src", "P215", 3), ("main.src", "P215", 6), ("main.src", "P215", 8), ("main.src", "P215", 10),
        ("place.src", "P215", 3)]
    assert p.targets.poses[:, 0].tolist() == [10, 50]  # XHOMEPOS, XCFG


def test_a_data_list_alone_says_what_is_missing():
    with pytest.raises(PostprocError) as e:
        cell("xPoints.dat")
    assert e.value.code == "P104" and "give the modules (.src) that use it" in e.value.message
    p = cell("xPoints.dat", "main.src", "main.dat", "$config.dat", "place.src")  # a data list first: fine
    assert p.targets.poses[:, 0].tolist() == [100, 10, 400, 50, 400, 100]

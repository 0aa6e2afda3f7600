"""KRL reader: $BASE/$TOOL through calls (local DEFs, other modules, code not available),
tools that cannot be resolved."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from postproc.core.frames import frame_to_matrix
from postproc.programs import ActiveFrames, krl

# These programs are about other semantics than the active frames: they state them as the
# user would (--base 0 --tool model), the assumption the reader made silently before P220/P221.
STATED = ActiveFrames(base=0, tool="model")


SAMPLES = Path(__file__).resolve().parent.parent / "samples" / "krl"
CONFIG = (SAMPLES / "config" / "$config.dat").read_bytes().decode("latin-1")
BASE2 = frame_to_matrix(np.array([1780.0, 150.0, 700.0, 90.0, 0.0, 0.0]))
TOOL1 = [300.0, 0.0, 75.0, 0.0, 0.0, 0.0]
MOVE_SETTINGS = """DEF MoveSettings(nBase:IN, nTool:IN, nVel:IN)
  DECL INT nBase, nTool
  DECL REAL nVel
  BAS(#BASE, nBase)
  BAS(#TOOL, nTool)
  $VEL.CP = nVel
END
"""


def read(*modules: tuple[str, str], config=True, accelerate=True, active=STATED):
    files, texts = zip(*modules)
    return krl.read(list(files), list(texts), config=[CONFIG] if config else None, accelerate=accelerate,
                    active=active)


def diags(p):
    return [(d.code, d.line) for d in p.diagnostics]


def test_frames_set_in_a_local_callee_hold_after_the_call():
    src = ("DEF t( )\n"                                   # 1
           "  LIN {X 1,Y 2,Z 3,A 0,B 0,C 0}\n"            # 2: $NULLFRAME
           "  MoveSettings(2, 1, 0.2)\n"                  # 3
           "  LIN {X 10,Y 20,Z 30,A 0,B 0,C 0}\n"         # 4: BASE_DATA[2] / TOOL_DATA[1]
           "  MoveSettings(0, 0, 0.2)\n"                  # 5
           "  LIN {X 11,Y 21,Z 31,A 0,B 0,C 0}\n"         # 6: $NULLFRAME / no tool
           "END\n" + MOVE_SETTINGS)
    for accelerate in (True, False):
        p = read(("t.src", src), accelerate=accelerate)
        f = p.targets.frame
        assert diags(p) == []
        assert f.tolist() == [0, 1, 2]  # $NULLFRAME with no tool set, BASE_DATA[2] / TOOL_DATA[1], $NULLFRAME / tool 0
        np.testing.assert_allclose(p.frames[f[1]].base, BASE2)
        np.testing.assert_allclose(p.frames[f[1]].tool, TOOL1)
        np.testing.assert_allclose(p.frames[f[0]].base, np.eye(4))
        assert p.frames[f[0]].tool is None
        np.testing.assert_allclose(p.frames[f[2]].base, np.eye(4))
        np.testing.assert_allclose(p.frames[f[2]].tool, np.zeros(6))


def test_frames_set_in_another_module_hold_after_the_call():
    src = "DEF t( )\n  MoveSettings(2, 1, 0.2)\n  LIN {X 10,Y 20,Z 30,A 0,B 0,C 0}\nEND\n"
    p = read(("t.src", src), ("movesettings.src", MOVE_SETTINGS))
    assert diags(p) == [] and p.targets.frame.tolist() == [0]
    np.testing.assert_allclose(p.frames[0].base, BASE2)
    np.testing.assert_allclose(p.frames[0].tool, TOOL1)


def test_a_local_def_of_another_module_is_not_visible():
    lib = "DEF lib( )\nEND\n" + MOVE_SETTINGS  # MoveSettings is local to lib.src (no GLOBAL)
    src = "DEF t( )\n  MoveSettings(2, 1, 0.2)\n  LIN {X 10,Y 20,Z 30,A 0,B 0,C 0}\nEND\n"
    p = read(("t.src", src), ("lib.src", lib))
    assert p.targets.frame.tolist() == [-1] and diags(p) == [("P201", 2), ("P232", 2)]
    p = read(("t.src", src), ("lib.src", lib.replace("DEF MoveSettings", "GLOBAL DEF MoveSettings")))
    assert p.targets.frame.tolist() == [0] and diags(p) == []


def test_a_call_to_code_not_read_makes_the_frames_unknown_at_the_call():
    src = ("DEF t( )\n"
           "  BAS(#BASE, 2)\n"
           "  LIN {X 1,Y 2,Z 3,A 0,B 0,C 0}\n"
           "  gripper_open()\n"                           # 4: not in the files read
           "  LIN {X 10,Y 20,Z 30,A 0,B 0,C 0}\n"
           "  LIN {X 11,Y 21,Z 31,A 0,B 0,C 0}\n"
           "  BAS(#BASE, 2)\n"                            # the base known again, the tool not
           "  LIN {X 12,Y 22,Z 32,A 0,B 0,C 0}\n"
           "END\n")
    p = read(("t.src", src))
    assert p.targets.frame.tolist() == [0, -1, -1, -1]
    assert diags(p) == [("P201", 4), ("P203", 4), ("P232", 4)]
    assert "gripper_open" in p.diagnostics[0].message and "2 target" in p.diagnostics[0].message
    assert "1 target" in p.diagnostics[1].message


def test_a_callee_that_sets_no_frame_keeps_it():
    src = ("DEF t( )\n  BAS(#BASE, 2)\n  SET_CD_PARAMS(0)\n  wait_part(3)\n  LIN {X 1,Y 2,Z 3,A 0,B 0,C 0}\nEND\n"
           "DEF wait_part(n:IN)\n  DECL INT n\n  WAIT FOR $IN[n]\n  $OUT[2] = TRUE\nEND\n")
    p = read(("t.src", src))
    assert diags(p) == [] and p.targets.frame.tolist() == [0]
    np.testing.assert_allclose(p.frames[0].base, BASE2)


def test_a_frame_from_a_run_time_argument_is_unknown_after_the_call():
    src = ("DEF t( )\n  DECL INT n\n  n = $IN_VALUE\n  MoveSettings(n, 1, 0.2)\n"
           "  LIN {X 10,Y 20,Z 30,A 0,B 0,C 0}\nEND\n" + MOVE_SETTINGS)
    p = read(("t.src", src))
    assert p.targets.frame.tolist() == [-1] and diags(p) == [("P201", 4)]
    assert "MoveSettings() called at line 4" in p.diagnostics[0].message


def test_a_constant_variable_argument_is_bound():
    dat = "DEFDAT t\n  DECL INT nFixture = 2\nENDDAT\n"
    src = "DEF t( )\n  MoveSettings(nFixture, 1, 0.2)\n  LIN {X 10,Y 20,Z 30,A 0,B 0,C 0}\nEND\n" + MOVE_SETTINGS
    p = read(("t.src", src), ("t.dat", dat))
    assert diags(p) == [] and p.targets.frame.tolist() == [0]
    np.testing.assert_allclose(p.frames[0].base, BASE2)


def test_nested_calls_and_a_recursion_stay_bounded():
    src = ("DEF t( )\n  setup()\n  LIN {X 1,Y 2,Z 3,A 0,B 0,C 0}\n  spin()\n  LIN {X 4,Y 5,Z 6,A 0,B 0,C 0}\nEND\n"
           "DEF setup( )\n  MoveSettings(2, 1, 0.1)\nEND\n"
           "DEF spin( )\n  spin()\nEND\n" + MOVE_SETTINGS)
    p = read(("t.src", src))
    assert p.targets.frame.tolist() == [0, -1]
    np.testing.assert_allclose(p.frames[0].base, BASE2)
    assert diags(p) == [("P201", 4), ("P203", 4)] or diags(p) == [("P201", 4)]
    assert "recurses" in p.diagnostics[0].message


def test_a_tool_that_cannot_be_resolved_leaves_its_targets_alone():
    src = ("DEF t( )\n  BAS(#BASE, 2)\n  BAS(#TOOL, 1)\n  LIN {X 1,Y 2,Z 3,A 0,B 0,C 0}\n"
           "  BAS(#TOOL, 6)\n  LIN {X 4,Y 5,Z 6,A 0,B 0,C 0}\n  LIN {X 7,Y 8,Z 9,A 0,B 0,C 0}\nEND\n")
    p = read(("t.src", src))
    assert p.targets.frame.tolist() == [0, -1, -1]
    assert diags(p) == [("P203", 5)] and "TOOL_DATA[6]" in p.diagnostics[0].message
    assert "2 target" in p.diagnostics[0].message
    p = read(("t.src", src.replace("  BAS(#BASE, 2)\n", "")), config=False)  # no $config.dat at all
    assert p.targets.frame.tolist() == [-1, -1, -1] and [c for c, _ in diags(p)] == ["P203", "P203"]


def test_calls_on_the_fast_path_equal_the_line_by_line_read():
    lines = []
    for i in range(6000):
        if i == 2000:
            lines.append("  MoveSettings(2, 1, 0.2)")
        if i == 4000:
            lines.append("  gripper_open()")
        lines.append(f"  LIN {{X {i}.5,Y -{i},Z 3,A 0,B 90,C 0}}" if i % 7 else f"  LIN {{X {i},Y 2,Z 3}}")
    src = "DEF t( )\n" + "\n".join(lines) + "\nEND\n" + MOVE_SETTINGS
    fast, slow = read(("t.src", src)), read(("t.src", src), accelerate=False)
    for k in ("poses", "spans", "line", "col", "frame", "config"):
        assert np.array_equal(getattr(fast.targets, k), getattr(slow.targets, k), equal_nan=k == "poses"), k
    assert diags(fast) == diags(slow) == [("P201", 4003), ("P232", 4003)]  # (one reason per target: the base first)
    f = fast.targets.frame
    assert (f[:2000] == 0).all() and (f[2000:4000] == 1).all() and (f[4000:] == -1).all()


def test_after_a_callee_that_moves_the_robot_stands_at_its_target():
    src = ("DEF t( )\n  LIN {X 1,Y 2,Z 3,A 0,B 90,C 0}\n  settle()\n  LIN {Z 40}\n  park()\n  LIN {Z 50}\nEND\n"
           "DEF settle( )\n  $VEL.CP = 0.1\nEND\n"
           "DEF park( )\n  go()\nEND\n"
           "DEF go( )\n  LIN {X 100,Y 200,Z 300,A 0,B 90,C 0}\nEND\n")
    for accelerate in (True, False):
        p = read(("t.src", src), accelerate=accelerate)
        poses = p.targets.poses
        # settle() does not move: {Z 40} takes X, Y from line 2; park() moves in go(), which
        # runs before {Z 50}: that takes X, Y from go()'s target, not from line 4
        np.testing.assert_allclose(poses[1, :3], [1, 2, 40])
        np.testing.assert_allclose(poses[2, :3], [100, 200, 300])
        np.testing.assert_allclose(poses[3, :3], [100, 200, 50])
        assert p.targets.prev.tolist() == [-1, 0, 1, 2]

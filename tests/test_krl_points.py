"""KRL reader: the (S, T) configuration each target states (-1 where it does not); derived points."""
from __future__ import annotations

import numpy as np
import pytest

from postproc.programs import ActiveFrames, krl

# These programs are about other semantics than the active frames: they state them as the
# user would (--base 0 --tool model), the assumption the reader made silently before P220/P221.
STATED = ActiveFrames(base=0, tool="model")


def read(src, dat=None, accelerate=True):
    files, texts = ["t.src"], [src]
    if dat is not None:
        files.append("t.dat")
        texts.append(dat)
    return krl.read(files, texts, accelerate=accelerate, active=STATED)


SRC = ("DEF t( )\n"
       "  PTP {X 1,Y 2,Z 3,A 0,B 90,C 0,S 2,T 35}\n"             # integers
       "  PTP {X 1,Y 2,Z 3,A 0,B 90,C 0,S 'B110',T 'B100011'}\n"  # bit literals
       "  PTP {X 1,Y 2,Z 3,A 0,B 90,C 0,S 'H2',T 'H0A'}\n"        # hex literals
       "  LIN {X 1,Y 2,Z 3}\n"                                   # not stated
       "  PTP {X 1,Y 2,Z 3,A 0,B 90,C 0,T 10}\n"                 # T only
       "  PTP {X 1,Y 2,Z 3,A 0,B 90,C 0,S 2.5,T 1E9}\n"          # not a configuration
       "  PTP XP1\n"                                             # a .dat E6POS
       "  PTP XP2\n"                                             # a POS without S/T
       "END\n")
DAT = ("DEFDAT t\n  DECL E6POS XP1={X 4,Y 5,Z 6,A 0,B 0,C 0,S 6,T 'B011',E1 0}\n"
       "  DECL POS XP2={X 4,Y 5,Z 7,A 0,B 0,C 0}\nENDDAT\n")


@pytest.mark.parametrize("accelerate", [True, False])
def test_configuration_of_each_target_form(accelerate):
    p = read(SRC, DAT, accelerate)
    assert p.targets.config.dtype == np.int16
    assert p.targets.config.tolist() == [[2, 35], [6, 35], [2, 10], [-1, -1], [-1, 10], [-1, -1], [6, 3], [-1, -1]]


def test_configuration_on_the_fast_path_equals_the_line_by_line_read():
    lines = [f"PTP {{X {i}.5,Y -{i},Z 3,A 0,B 90,C 0,S {i % 8},T {i % 64}}}" if i % 3 else
             f"LIN {{X {i},Y 2,Z 3}}" for i in range(6000)]
    src = "DEF t( )\n" + "\n".join(lines) + "\nEND\n"
    fast, slow = read(src), read(src, accelerate=False)
    assert np.array_equal(fast.targets.config, slow.targets.config)
    assert fast.targets.config[1].tolist() == [1, 1] and fast.targets.config[0].tolist() == [-1, -1]
    assert fast.targets.config[5999].tolist() == [5999 % 8, 5999 % 64]


def test_a_derived_point_shares_the_tokens_it_is_derived_from():
    """``XP2 = XP1; XP2.Z = XP1.Z + 150`` and ``XP3.X = XP1.X - 20``: at run time XP2 and XP3
    move with XP1's numbers. Each is a row whose tokens are XP1's (+ an offset); the rows that
    share a token are one group: compensate writes the tokens only where every row of the group
    agrees (test_compensate's groups), so none moves by another's correction without a word."""
    src = ("DEF t( )\n"
           "  LIN XP1\n"                     # 2
           "  XP2 = XP1\n"                   # 3
           "  XP2.Z = XP1.Z + 150\n"         # 4
           "  LIN XP2\n"                     # 5: XP1's tokens, Z + 150
           "  XP3.X = XP1.X - 20\n"          # 6: XP3's own Y, Z; X is XP1's − 20
           "  LIN XP3\n"                     # 7
           "  LIN XP4\n"                     # 8: its own point
           "END\n")
    dat = ("DEFDAT t\n  DECL E6POS XP1={X 4,Y 5,Z 6,A 0,B 0,C 0}\n  DECL E6POS XP2={X 9,Y 9,Z 9,A 0,B 0,C 0}\n"
           "  DECL E6POS XP3={X 7,Y 7,Z 7,A 0,B 0,C 0}\n  DECL E6POS XP4={X 8,Y 8,Z 8,A 0,B 0,C 0}\nENDDAT\n")
    for accelerate in (True, False):
        p = read(src, dat, accelerate)
        t = p.targets
        assert p.diagnostics == []
        np.testing.assert_allclose(t.poses[:, :3], [[4, 5, 6], [4, 5, 156], [-16, 7, 7], [8, 8, 8]])
        xp1 = t.spans[0]
        assert (t.spans[1] == xp1).all() and t.offset[1].tolist() == [0, 0, 150]
        assert (t.spans[2, 0] == xp1[0]).all() and t.offset[2].tolist() == [-20, 0, 0]
        assert t.group.tolist() == [0, 0, 0, -1]

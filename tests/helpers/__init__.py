"""What the tests share besides fixtures (those are in conftest.py): the repository's root and
hand-built programs. Tests import it as ``helpers`` (pytest puts tests/ on sys.path); the ONNX
models the tests build are in :mod:`postproc.testing.models`."""
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent.parent
DOCS = REPO / "docs"

# A backup's SYSPAR/SYS.cfg of a two-robot cell: motion tasks T_ROB1 and T_ROB2 on groups rob1, rob2.
SYS_CFG = """SYS:CFG_1.0:6:0::
#
CAB_TASKS:

      -Name "T_ROB1" -Type "NORMAL" -UseMechanicalUnitGroup "rob1" -MotionTask

      -Name "T_ROB2" -Type "NORMAL" -UseMechanicalUnitGroup "rob2" -MotionTask
"""


def pages() -> dict[str, str]:
    """The pages a reader gets: README.md and every Markdown file of docs/ (the docs site), by
    their path relative to the repository."""
    found = [REPO / "README.md", *sorted(DOCS.rglob("*.md"))]
    return {str(path.relative_to(REPO)): path.read_text() for path in found}


def program_in_base(base, pose, label: str = ""):
    """A one-target pose program built by hand: ``pose`` [6] written as its X,Y,Z in a frame
    ``base`` (X,Y,Z,A,B,C or a 4x4 matrix, which may hold what no reader would accept)."""
    import numpy as np

    from postproc.core import frames
    from postproc.programs import Frame, Program, TargetsBuilder

    text = "x,y,z\n" + ",".join(f"{v:.3f}" for v in pose[:3]) + "\n"
    spans, pos = [], text.index("\n") + 1
    for tok in text[pos:].rstrip("\n").split(","):
        spans += [pos, pos + len(tok)]
        pos += len(tok) + 1
    builder = TargetsBuilder()
    builder.add(list(pose), spans, 0, 2, 1, 0, 0)
    matrix = np.asarray(base, float) if np.shape(base) == (4, 4) else frames.frame_to_matrix(base)
    return Program(["p.csv"], [text], builder.build(), [Frame(matrix, None, label)], dialect="poses",
                   newlines=["\n"], comment="#")

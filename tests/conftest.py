import sys
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parent
sys.path.insert(0, str(TESTS))  # model_factory

REPO = TESTS.parent


@pytest.fixture
def affine(tmp_path):
    """Build an ONNX compensator E = offset + gain·(xyz − centre) in tmp_path."""
    from model_factory import affine_model

    counter = iter(range(1000))

    def make(**kwargs):
        return affine_model(tmp_path / f"model{next(counter)}.onnx", **kwargs)

    return make


def program_in_base(base, pose, label: str = ""):
    """A one-target pose program built by hand: ``pose`` [6] written as its X,Y,Z in a frame
    ``base`` (X,Y,Z,A,B,C or a 4x4 matrix, which may hold what no reader would accept)."""
    import numpy as np

    from postproc import frames
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

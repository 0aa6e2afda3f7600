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

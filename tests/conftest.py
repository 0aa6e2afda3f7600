"""Fixtures the tests share; other shared helpers are in tests/helpers/ and postproc.testing."""
import pytest


@pytest.fixture
def affine(tmp_path):
    """Build an ONNX compensator E = offset + gain·(xyz − centre) in tmp_path."""
    from postproc.testing.models import affine_model

    counter = iter(range(1000))

    def make(**kwargs):
        return affine_model(tmp_path / f"model{next(counter)}.onnx", **kwargs)

    return make

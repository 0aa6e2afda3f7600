"""Fixtures the tests share; other shared helpers are in tests/helpers/ and postproc.testing.

Run in parallel (pyproject.toml: ``-n auto --dist loadfile``): one worker process per core, at
most ``MAX_WORKERS``; each worker's numerical libraries run one thread (two workers each running
torch's and OpenMP's two threads on two cores spend the time switching), and the test files
holding a ``slow`` test go first, so that no long file is left running alone at the end.
"""
import os

import pytest

MAX_WORKERS = 4  # each worker imports torch, onnxruntime, Pinocchio: ~0.5 GB

if os.environ.get("PYTEST_XDIST_WORKER"):  # (set before this file is imported; read at torch's import)
    for _name in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ.setdefault(_name, "1")


def pytest_xdist_auto_num_workers(config):
    return max(1, min(os.cpu_count() or 1, MAX_WORKERS))


def pytest_collection_modifyitems(session, config, items):
    """Files with a ``slow`` test first (stable: the collection order otherwise)."""
    slow = {item.path for item in items if item.get_closest_marker("slow")}
    items.sort(key=lambda item: item.path not in slow)


@pytest.fixture
def affine(tmp_path):
    """Build an ONNX compensator E = offset + gain·(xyz − centre) in tmp_path."""
    from postproc.testing.models import affine_model

    counter = iter(range(1000))

    def make(**kwargs):
        return affine_model(tmp_path / f"model{next(counter)}.onnx", **kwargs)

    return make

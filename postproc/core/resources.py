"""Where the grammars, the shipped model and the robot description live.

In a clone (or an editable install) they sit at the top of the repository; a wheel
installs them under ``<prefix>/share/postproc`` (see setup.cfg's data_files).
"""
from __future__ import annotations

import sys
from pathlib import Path

_PACKAGE = Path(__file__).resolve().parents[1]  # postproc/
_REPO = _PACKAGE.parent


def _find(folder: str, name: str) -> Path:
    for root in (_REPO / folder, Path(sys.prefix) / "share" / "postproc" / folder):
        candidate = root / name
        if candidate.exists():
            return candidate
    return _REPO / folder / name  # the error message then names the expected place


def grammar_path(name: str) -> Path:
    return _find("grammars", name)


def model_path(name: str = "default.onnx") -> Path:
    return _find("models", name)


def sample_path(name: str) -> Path:
    return _REPO / "samples" / name


def schema_path(name: str) -> Path:
    """A JSON Schema of the package (``postproc/schemas/``: the model card's, the verdict's)."""
    return _PACKAGE / "schemas" / name

"""Pass/fail for a cell's CI: the verdict of ``postproc verify`` and ``postproc report``.

One JSON document (``schemas/verdict.schema.json``, version ``VERDICT_VERSION``): the limits the
caller stated (``--max-mean``, ``--max-p95``, ``--max-max`` on the positioning error after
compensation, mm; ``--max-orientation-mean`` on the orientation error after, deg), each check
(figure, value, limit, passed), ``passed`` (every check; true where no limit was stated: the
figures are then only recorded), the figures themselves (Table 2 before/after), the model (name,
sha256, contract) and the inputs (path, sha256). ``verify --verdict FILE`` writes it; ``report``
writes ``verdict.json`` beside ``summary.json``. Both exit 1 when a limit fails (the exit code a
CI job gates on; the file says which figure and by how much).
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

from ..core.diagnostics import P308, PostprocError
from ..core.resources import schema_path
from ..settings import LIMITS, Acceptance

__all__ = ["VERDICT_VERSION", "SCHEMA_PATH", "verdict", "verdict_problems", "model_entry", "failed_lines"]

VERDICT_VERSION = 1
SCHEMA_PATH = schema_path("verdict.schema.json")
def _figure(figures: dict, path: str):
    value = figures
    for key in path.split("."):
        value = value.get(key) if isinstance(value, dict) else None
    return value


def file_sha256(path) -> str | None:
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError:
        return None


def verdict(kind: str, limits: Acceptance, figures: dict, model: dict | None, inputs: dict) -> dict:
    """The verdict document (module text). ``figures``: at least ``before`` / ``after`` Table 2
    (mm) and, where known, ``orientation_before`` / ``orientation_after`` (deg); ``model``: name,
    sha256, contract (None: no model, e.g. verify's programs alone); ``inputs``: role → path."""
    from ..core.version import __version__

    checks = []
    for name, limit in limits.stated.items():
        figure, unit = LIMITS[name]
        value = _figure(figures, figure)
        if value is None:
            raise PostprocError(f"--{name.replace('_', '-')}: this {kind} has no {figure} to hold to it", code=P308)
        checks.append({"figure": figure, "unit": unit, "value": float(value), "limit": float(limit),
                       "passed": bool(float(value) <= float(limit))})
    return {
        "verdict_version": VERDICT_VERSION,
        "kind": kind,
        "passed": all(c["passed"] for c in checks),
        "limits_stated": bool(checks),
        "checks": checks,
        "figures": figures,
        "model": model,
        "inputs": {role: {"path": str(p), "sha256": file_sha256(p)} for role, p in inputs.items() if p is not None},
        "postproc_version": __version__,
    }


def model_entry(model) -> dict | None:
    from ..model.contract import contract_version

    if model is None:
        return None
    return {"name": model.name, "sha256": model.sha256, "path": str(model.path), "contract": contract_version(model.metadata)}


def verdict_problems(document: dict) -> list[str]:
    """What in a verdict the schema does not allow ([] valid; needs jsonschema)."""
    import jsonschema

    validator = jsonschema.Draft202012Validator(json.loads(SCHEMA_PATH.read_text(encoding="utf-8")))
    return [f"{'.'.join(map(str, e.absolute_path)) or '(verdict)'}: {e.message}" for e in validator.iter_errors(document)]


def failed_lines(document: dict) -> list[str]:
    return [f"{c['figure']} {c['value']:.4g} {c['unit']} > {c['limit']:g} {c['unit']}" for c in document["checks"]
            if not c["passed"]]

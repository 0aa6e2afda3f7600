"""Training: the learned error model (torch lives only in this package).

``ErrorModel`` (estimator.py) runs the method: GPSO (gpso.py) or the GA / PSO / plain
baselines (baselines.py) search the initial weights of a ReLU MLP (network.py), backprop
(optimise.py) refines them, export.py writes the contract ONNX file. data.py reads and
checks measurement CSVs (numpy only), search.py picks a structure.

Attributes are resolved lazily so that ``postproc.training.data`` can check a CSV without
loading torch.
"""
from __future__ import annotations

__all__ = ["ErrorModel", "METHODS", "DEFAULT_OPTIMIZER", "OPTIMIZERS", "residual_stats", "accuracy_card"]


def __getattr__(name: str):
    if name in ("ErrorModel", "METHODS", "DEFAULT_OPTIMIZER", "residual_stats", "accuracy_card"):
        from . import estimator

        return getattr(estimator, name)
    if name == "OPTIMIZERS":
        from .optimise import OPTIMIZERS

        return OPTIMIZERS
    raise AttributeError(name)

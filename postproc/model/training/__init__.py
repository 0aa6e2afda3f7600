"""Training: the learned error model (torch lives only in this package).

``fit`` (fitting.py) is the use case — measurements → a fitted model + its model card →
``TrainedModel.export`` (the contract ONNX file); ``postproc train`` calls it. The estimators
(scikit-learn conventions, ``estimator.Estimator``): ``HybridModel`` (hybrid.py: the
identified arm of kinematic.py + residual networks) and ``ErrorModel`` (estimator.py: GPSO
(gpso.py) or the GA / PSO / plain baselines (baselines.py) search the initial weights of a
ReLU MLP (network.py), backprop (optimise.py) refines them). export.py writes the contract
ONNX file, card.py the card's robot, reach, tool and iterations, data.py reads and checks
measurement CSVs (numpy only), search.py picks a structure, methods.py names the methods.

Attributes are resolved lazily so that ``postproc.model.training.data`` can check a CSV (and the CLI
read the method names) without loading torch.
"""
from __future__ import annotations

__all__ = ["fit", "TrainedModel", "arm_metadata", "ErrorModel", "METHODS", "DEFAULT_OPTIMIZER", "OPTIMIZERS",
           "residual_stats", "accuracy_card"]

_HOMES = {
    "fit": "fitting", "TrainedModel": "fitting",
    "arm_metadata": "card",
    "ErrorModel": "estimator", "DEFAULT_OPTIMIZER": "estimator", "residual_stats": "estimator",
    "accuracy_card": "estimator",
    "METHODS": "estimator",  # (the networks' methods; methods.METHODS: every method train knows)
    "OPTIMIZERS": "methods",
}


def __getattr__(name: str):
    if name not in _HOMES:
        raise AttributeError(name)
    from importlib import import_module

    return getattr(import_module(f".{_HOMES[name]}", __name__), name)

"""The names of the training methods and backprop optimisers (no numpy, no torch: the CLI's
choices are read from here without loading either).

``IDENTIFIED``: the robot's kinematics identified on its nominal description
(``HybridModel``, training/hybrid.py); ``NETWORKS``: pose-only MLPs whose initial weights a
search finds (``ErrorModel``, training/estimator.py), refined by backprop with one of
``OPTIMIZERS`` (training/optimise.py).
"""
from __future__ import annotations

__all__ = ["IDENTIFIED", "NETWORKS", "METHODS", "OPTIMIZERS"]

IDENTIFIED = ("hybrid", "kinematic", "dnn-joints")
NETWORKS = ("gpso", "ga", "pso", "plain")
METHODS = IDENTIFIED + NETWORKS  # train's --method choices, in the order its help lists them
OPTIMIZERS = ("lm", "lbfgs", "adam", "momentum", "gd")

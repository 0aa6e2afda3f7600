"""The backprop stage: refine the searched initial weights on the training MSE.

The method: learning rate 0.01, up to 500 epochs, stop at MSE goal 1e-5. It ran in MATLAB,
whose default network training is Levenberg–Marquardt (``trainlm``), so the optimiser is a
choice here; all of them work on the full training batch, one update per epoch:

* ``gd``: plain gradient descent, lr 0.01;
* ``momentum``: gradient descent with momentum 0.9, lr 0.01;
* ``adam``: Adam, lr 0.01;
* ``lbfgs``: L-BFGS with a strong-Wolfe line search, one iteration per epoch;
* ``lm``: Levenberg–Marquardt as MATLAB's trainlm (μ from 1e-3, ×0.1 on success, ×10 on
  failure, stop at μ > 1e10); the Jacobian of the residuals [N·3, D] is the MLP's backprop
  written out (``network.jacobian``; a few hundred weights: JᵀJ is cheap).

The MSE is in standardised output units (each of Ex, Ey, Ez scaled to unit variance), so the
goal 1e-5 means a residual ~0.3 % of the spread of the errors.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import torch

from .methods import OPTIMIZERS
from .network import Structure, forward, jacobian

__all__ = ["OPTIMIZERS", "RefineResult", "refine"]

MU_START, MU_DEC, MU_INC, MU_MAX = 1e-3, 0.1, 10.0, 1e10  # trainlm's defaults


@dataclass
class RefineResult:
    theta: torch.Tensor
    losses: list[float] = field(default_factory=list)  # training MSE after each epoch
    stopped: str = ""  # why it stopped: "epochs", "goal", "mu"


def refine(
    structure: Structure,
    theta: torch.Tensor,
    x: torch.Tensor,
    y: torch.Tensor,
    optimizer: str = "lm",
    epochs: int = 500,
    lr: float = 0.01,
    goal: float = 1e-5,
    callback: Callable[[int, float], None] | None = None,
) -> RefineResult:
    """Refine θ [D] on standardised inputs x [N, 6] and targets y [N, 3]."""
    if optimizer == "lm":
        return _levenberg_marquardt(structure, theta, x, y, epochs, goal, callback)
    theta = theta.detach().clone().requires_grad_(True)
    if optimizer == "gd":
        opt = torch.optim.SGD([theta], lr=lr)
    elif optimizer == "momentum":
        opt = torch.optim.SGD([theta], lr=lr, momentum=0.9)
    elif optimizer == "adam":
        opt = torch.optim.Adam([theta], lr=lr)
    elif optimizer == "lbfgs":
        # lr 1 with a line search: the step length is found, not set
        # max_eval must be set: its default (1.25·max_iter) would leave the line search no evaluations
        opt = torch.optim.LBFGS(
            [theta], lr=1.0, max_iter=1, max_eval=25, history_size=20, line_search_fn="strong_wolfe"
        )
    else:
        raise ValueError(f"unknown optimizer {optimizer!r} ({'|'.join(OPTIMIZERS)})")

    def closure() -> torch.Tensor:
        opt.zero_grad()
        loss = torch.mean((forward(structure, theta, x) - y) ** 2)
        loss.backward()
        return loss

    losses: list[float] = []
    stopped = "epochs"
    for epoch in range(epochs):
        opt.step(closure)
        with torch.no_grad():
            loss = float(torch.mean((forward(structure, theta, x) - y) ** 2))
        losses.append(loss)
        if callback is not None:
            callback(epoch, loss)
        if loss <= goal:
            stopped = "goal"
            break
    return RefineResult(theta.detach(), losses, stopped)


def _levenberg_marquardt(
    structure: Structure,
    theta: torch.Tensor,
    x: torch.Tensor,
    y: torch.Tensor,
    epochs: int,
    goal: float,
    callback: Callable[[int, float], None] | None,
) -> RefineResult:
    theta = theta.detach().clone()
    n_res = y.numel()

    def residuals(t: torch.Tensor) -> torch.Tensor:
        return (forward(structure, t, x) - y).reshape(-1)

    eye = torch.eye(theta.numel(), dtype=theta.dtype)
    mu = MU_START
    r = residuals(theta)
    loss = float(r @ r) / n_res
    losses: list[float] = []
    stopped = "epochs"
    for epoch in range(epochs):
        if loss <= goal:
            stopped = "goal"
            break
        j = jacobian(structure, theta, x)
        jtj, jtr = j.T @ j, j.T @ r
        while True:
            step = torch.linalg.solve(jtj + mu * eye, jtr)
            trial = theta - step
            r_trial = residuals(trial)
            trial_loss = float(r_trial @ r_trial) / n_res
            if trial_loss < loss:
                theta, r, loss = trial, r_trial, trial_loss
                mu = max(mu * MU_DEC, 1e-20)
                break
            mu *= MU_INC
            if mu > MU_MAX:
                break
        losses.append(loss)
        if callback is not None:
            callback(epoch, loss)
        if mu > MU_MAX:
            stopped = "mu"
            break
    else:
        if loss <= goal:
            stopped = "goal"
    return RefineResult(theta, losses, stopped)

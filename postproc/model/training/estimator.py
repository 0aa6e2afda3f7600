"""``ErrorModel``: the scikit-learn-style estimator that runs the whole training method.

    model = ErrorModel(hidden=(20, 10, 5), method="gpso", seed=0).fit(poses, errors)
    model.predict(poses)            # [N, 3] mm
    model.export_onnx("m.onnx", name="cell-3", robot="KR500")

fit = standardise → search initial weights (GPSO / GA / PSO / plain) on the training MSE →
refine by backprop (``optimizer``) → keep the network. Fitted attributes end in ``_``.
Everything random draws from one ``torch.Generator`` seeded with ``seed``, and ``fit`` runs
torch on one thread (restored afterwards): the same seed and data give the same model, and
for networks this small a second thread costs more in synchronisation than it saves
(measured 6× slower on the shared 2-core machine).

``Estimator``, the conventions every model class here follows (``ErrorModel``,
``HybridModel``, ``KinematicModel``): the constructor stores its parameters and nothing else,
``get_params``/``set_params`` read the parameter names from its signature, ``fit`` returns
the estimator and what it fitted ends in ``_`` — scikit-learn's, without depending on it.
"""
from __future__ import annotations

import inspect
import math
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import torch

from ...core.stats import table2
from . import baselines
from .data import check_size, envelope_of
from .gpso import InitResult, gpso
from .methods import NETWORKS as METHODS
from .methods import OPTIMIZERS
from .network import ErrorNet, Scaling, Structure, forward, parse_hidden
from .optimise import refine

__all__ = ["Estimator", "ErrorModel", "METHODS", "DEFAULT_OPTIMIZER", "residual_stats"]

# The backprop optimiser used after the weight search unless told otherwise: the best of
# gd / momentum / adam / lbfgs / lm measured after GPSO (models/README.md, benchmarks/train_compare.py).
DEFAULT_OPTIMIZER = "lm"
METHOD_LABEL = {"gpso": "GPSO-DNN", "ga": "GA-DNN", "pso": "PSO-DNN", "plain": "DNN"}


@contextmanager
def _one_thread():
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(before)


def residual_stats(residual: np.ndarray) -> dict:
    """Table 2 figures (postproc.core.stats.table2) of the per-point distance |r| in mm; None for
    no points (a model card's JSON has no NaN)."""
    figures = table2(np.linalg.norm(np.asarray(residual, float).reshape(-1, 3), axis=1))
    return {k: None if math.isnan(v) else v for k, v in figures.items()}


def accuracy_card(val_errors: np.ndarray, val_predicted: np.ndarray, train_mean_mm: float, n_train: int) -> dict:
    """The model card's ``accuracy``: validation residual |E − Ê| and the uncompensated error
    on the same rows (mm, rounded to 1 nm), the training residual, the split sizes."""
    val = residual_stats(val_errors - val_predicted)
    unc = residual_stats(val_errors)
    card = {
        "val_mean_mm": val["mean"],
        "val_max_mm": val["max"],
        "val_std_mm": val["std"],
        "train_mean_mm": train_mean_mm,
        "n_train": n_train,
        "n_val": len(val_errors),
        "val_uncompensated_mean_mm": unc["mean"],
        "val_uncompensated_max_mm": unc["max"],
        "val_uncompensated_std_mm": unc["std"],
    }
    return {k: (round(v, 6) if isinstance(v, float) else v) for k, v in card.items()}


class Estimator:
    """scikit-learn's estimator conventions, without scikit-learn: the parameters are the
    constructor's (``inspect.signature``), stored under their own names; ``get_params`` /
    ``set_params`` read and write them, so ``type(m)(**m.get_params())`` is an unfitted copy
    that fits the same. (No parameter is itself an estimator: ``deep`` changes nothing.)"""

    @classmethod
    def _param_names(cls) -> list[str]:
        signature = inspect.signature(cls.__init__)
        return [name for name, p in signature.parameters.items()
                if name != "self" and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]

    def get_params(self, deep: bool = True) -> dict:
        return {name: getattr(self, name) for name in self._param_names()}

    def set_params(self, **params):
        names = self._param_names()
        for name, value in params.items():
            if name not in names:
                raise ValueError(f"unknown parameter {name!r} of {type(self).__name__} ({', '.join(names)})")
            setattr(self, name, value)
        return self


class ErrorModel(Estimator):
    """Learned positioning error E(pose) of one robot + tool.

    Parameters
    ----------
    hidden: hidden layer widths (the method's [20, 10, 5] by default).
    method: initial-weight search: "gpso" (the method), "ga", "pso", "plain" (random).
    optimizer: backprop optimiser after the search ("lm", "lbfgs", "adam", "momentum", "gd");
        None → DEFAULT_OPTIMIZER.
    epochs, lr, goal: backprop budget, learning rate (gd/momentum/adam), MSE goal
        (standardised units).
    population, generations: None → the method's (GPSO 20×50, GA 50×100, PSO 40×100).
    inertia: GPSO's inertia weight, "constant" (0.7298) or "linear" (0.9 → 0.4).
    seed: seeds every random draw.
    progress: show a tqdm bar on stderr.
    """

    def __init__(
        self,
        hidden=(20, 10, 5),
        method: str = "gpso",
        optimizer: str | None = None,
        epochs: int = 500,
        lr: float = 0.01,
        goal: float = 1e-5,
        population: int | None = None,
        generations: int | None = None,
        inertia: str = "constant",
        seed: int = 0,
        progress: bool = False,
    ):
        self.hidden = hidden
        self.method = method
        self.optimizer = optimizer
        self.epochs = epochs
        self.lr = lr
        self.goal = goal
        self.population = population
        self.generations = generations
        self.inertia = inertia
        self.seed = seed
        self.progress = progress

    def __repr__(self) -> str:
        return f"ErrorModel(hidden={tuple(parse_hidden(self.hidden))}, method={self.method!r}, optimizer={self.optimizer_name!r}, seed={self.seed})"

    @property
    def optimizer_name(self) -> str:
        return self.optimizer or DEFAULT_OPTIMIZER

    @property
    def label(self) -> str:
        """e.g. 'GPSO-DNN + lm'."""
        return f"{METHOD_LABEL.get(self.method, self.method)} + {self.optimizer_name}"

    # -- fitting ---------------------------------------------------------------------------
    def fit(self, poses: np.ndarray, errors: np.ndarray) -> "ErrorModel":
        """Fit to commanded poses [N, 6] and their errors E = P_target − P_measured [N, 3] mm."""
        poses = np.asarray(poses, dtype=np.float64).reshape(-1, 6)
        errors = np.asarray(errors, dtype=np.float64).reshape(-1, 3)
        if len(poses) != len(errors):
            raise ValueError(f"{len(poses)} poses but {len(errors)} errors")
        if self.method not in METHODS:
            raise ValueError(f"unknown method {self.method!r} ({'|'.join(METHODS)})")
        if self.optimizer_name not in OPTIMIZERS:
            raise ValueError(f"unknown optimizer {self.optimizer_name!r} ({'|'.join(OPTIMIZERS)})")
        structure = Structure(parse_hidden(self.hidden))
        check_size(len(poses), structure.n_params, str(structure))
        with _one_thread():
            self._fit(structure, poses, errors)
        return self

    def _fit(self, structure: Structure, poses: np.ndarray, errors: np.ndarray) -> None:
        t0 = time.perf_counter()
        scaling = Scaling.fit(poses, errors)
        x = torch.as_tensor(scaling.inputs(poses))
        y = torch.as_tensor(scaling.outputs(errors))
        gen = torch.Generator().manual_seed(int(self.seed))

        def fitness(theta: torch.Tensor) -> torch.Tensor:  # [P, D] → [P] training MSE
            with torch.no_grad():
                return torch.mean((forward(structure, theta, x) - y) ** 2, dim=(1, 2))

        generations = self._generations()
        bar = self._bar(generations + self.epochs)
        tick = (lambda i, f: bar.update(1)) if bar is not None else None
        dim = structure.n_params
        if self.method == "gpso":
            init = gpso(fitness, dim, self.population or 20, generations, self.inertia, gen, callback=tick)
        elif self.method == "ga":
            init = baselines.ga(fitness, dim, self.population or 50, generations, generator=gen, callback=tick)
        elif self.method == "pso":
            init = baselines.pso(fitness, dim, self.population or 40, generations, generator=gen, callback=tick)
        else:
            init = baselines.plain(fitness, dim, generator=gen)
        t1 = time.perf_counter()
        if bar is not None:
            bar.set_description(f"{self.method} → {self.optimizer_name}")
        result = refine(structure, init.theta, x, y, self.optimizer_name, self.epochs, self.lr, self.goal, callback=tick)
        if bar is not None:
            bar.close()
        t2 = time.perf_counter()

        self.structure_ = structure
        self.n_weights_ = structure.n_params
        self.scaling_ = scaling
        self.params_ = result.theta.detach().numpy().copy()
        self.init_: InitResult = init
        self.history_ = list(init.history)  # best fitness (training MSE, standardised) per generation
        self.losses_ = list(result.losses)  # training MSE per backprop epoch
        self.stopped_ = result.stopped
        self.envelope_ = envelope_of(poses)
        self.n_train_ = len(poses)
        self.fit_seconds_ = {"init": t1 - t0, "backprop": t2 - t1, "total": t2 - t0}
        self.net_ = ErrorNet(structure, self.params_, scaling, torch.float64).eval()
        self.train_stats_ = residual_stats(errors - self.predict(poses))

    def _generations(self) -> int:
        if self.method == "plain":
            return 0
        if self.generations is not None:
            return int(self.generations)
        return {"gpso": 50, "ga": 100, "pso": 100}[self.method]

    def _bar(self, total: int):
        if not self.progress:
            return None
        from tqdm import tqdm

        return tqdm(total=total, desc=self.method, unit="step", leave=False, dynamic_ncols=True)

    # -- using the fitted model ------------------------------------------------------------
    def _check_fitted(self) -> None:
        if not hasattr(self, "net_"):
            raise RuntimeError("ErrorModel is not fitted yet: call fit(poses, errors) first")

    def predict(self, poses: np.ndarray) -> np.ndarray:
        """Ê [N, 3] mm for poses [N, 6] (float64 throughout)."""
        self._check_fitted()
        with torch.no_grad():
            out = self.net_(torch.as_tensor(np.asarray(poses, dtype=np.float64).reshape(-1, 6)))
        return out.numpy()

    def module(self, dtype: torch.dtype = torch.float32) -> ErrorNet:
        """The fitted network as a torch module computing in ``dtype`` (for export)."""
        self._check_fitted()
        return ErrorNet(self.structure_, self.params_, self.scaling_, dtype).eval()

    def fixed_point_iterations(self, poses: np.ndarray, tol_mm: float = 1e-3, most: int = 10) -> int:
        """Iterations k of c = P + Ê(c) after which one more changes no command by > tol_mm."""
        self._check_fitted()
        poses = np.asarray(poses, dtype=np.float64).reshape(-1, 6)
        trial = poses.copy()
        trial[:, :3] = poses[:, :3] + self.predict(poses)
        for k in range(1, most):
            nxt = poses[:, :3] + self.predict(trial)
            change = float(np.max(np.abs(nxt - trial[:, :3]))) if len(poses) else 0.0
            trial[:, :3] = nxt
            if change <= tol_mm:
                return k
        return most

    def card(self, **metadata) -> dict:
        """The model card ``export_onnx`` writes: ``metadata`` as in the contract (name, robot,
        tool, envelope, reach, data_sha256, accuracy, iterations) over this model's method,
        structure and envelope, and iterations 2."""
        self._check_fitted()
        meta = {
            "method": self.label,
            "structure": str(self.structure_),
            "envelope": self.envelope_,
            "iterations": 2,
        }
        meta.update(metadata)
        return meta

    def export_onnx(self, path: str | Path, float64: bool = False, **metadata) -> Path:
        """Write the fitted model as a contract ONNX file (atomically) with ``card(**metadata)``."""
        from .export import export_onnx

        meta = self.card(**metadata)
        return export_onnx(self.module(torch.float64 if float64 else torch.float32), path, meta)


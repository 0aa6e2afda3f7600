"""The error network: a ReLU MLP pose (6) → E (3), its standardisation, batched evaluation.

Weights live in one flat vector θ (what GPSO/GA/PSO move around as particle positions).
:func:`forward` evaluates θ of shape [D] or a whole population [P, D] with one batched
matmul per layer — no loop over particles. :class:`ErrorNet` is the same function as a
torch module, with the standardisation inside, for ``predict`` and the ONNX export.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from .data import attitude_centre, wrap_deg

__all__ = ["Structure", "Scaling", "forward", "ErrorNet", "parse_hidden"]

N_IN, N_OUT = 6, 3


def parse_hidden(text: str | tuple | list) -> tuple[int, ...]:
    """'20,10,5' → (20, 10, 5)."""
    if isinstance(text, (tuple, list)):
        values = tuple(int(v) for v in text)
    else:
        try:
            values = tuple(int(v) for v in str(text).replace(" ", "").split(",") if v)
        except ValueError:
            values = ()
    if not values or any(v < 1 for v in values):
        raise ValueError(f"hidden layer sizes must be positive integers like 20,10,5, got {text!r}")
    return values


@dataclass(frozen=True)
class Structure:
    """Layer sizes and where each layer's weights sit in the flat parameter vector."""

    hidden: tuple[int, ...]

    @property
    def sizes(self) -> tuple[int, ...]:
        return (N_IN, *self.hidden, N_OUT)

    @property
    def n_params(self) -> int:
        s = self.sizes
        return sum((s[i] + 1) * s[i + 1] for i in range(len(s) - 1))

    def __str__(self) -> str:
        return "-".join(str(v) for v in self.sizes)

    def unflatten(self, theta: torch.Tensor) -> list[tuple[torch.Tensor, torch.Tensor]]:
        """θ [..., D] → per layer (W [..., in, out], b [..., 1, out]) as views."""
        lead = theta.shape[:-1]
        out, pos = [], 0
        s = self.sizes
        for i in range(len(s) - 1):
            n_in, n_out = s[i], s[i + 1]
            w = theta[..., pos : pos + n_in * n_out].reshape(*lead, n_in, n_out)
            pos += n_in * n_out
            b = theta[..., pos : pos + n_out].reshape(*lead, 1, n_out)
            pos += n_out
            out.append((w, b))
        return out

    def flatten(self, layers: list[tuple[torch.Tensor, torch.Tensor]]) -> torch.Tensor:
        """Inverse of :meth:`unflatten` for one network (W [in, out], b [out])."""
        return torch.cat([t for w, b in layers for t in (w.reshape(-1), b.reshape(-1))])


def forward(structure: Structure, theta: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
    """Standardised outputs for standardised inputs x [N, 6]: θ [D] → [N, 3], θ [P, D] → [P, N, 3].

    torch.matmul broadcasts [N, in] @ [P, in, out] → [P, N, out] and then batches
    [P, N, k] @ [P, k, m]: one bmm per layer over the whole population.
    """
    layers = structure.unflatten(theta)
    h = x
    for i, (w, b) in enumerate(layers):
        h = torch.matmul(h, w) + b
        if i < len(layers) - 1:
            h = torch.relu(h)
    if theta.dim() == 1:
        h = h.reshape(h.shape[-2], h.shape[-1])
    return h


@dataclass
class Scaling:
    """Input and output standardisation; A,B,C are first wrapped around the data's attitude centre."""

    attitude: np.ndarray  # [3] deg
    x_mean: np.ndarray  # [6]
    x_std: np.ndarray  # [6]
    y_mean: np.ndarray  # [3]
    y_std: np.ndarray  # [3]

    @classmethod
    def fit(cls, poses: np.ndarray, errors: np.ndarray) -> "Scaling":
        centre = attitude_centre(poses[:, 3:6])
        x = cls._unwrap(poses, centre)
        # a constant column (e.g. one fixed attitude) would divide by zero: leave it unscaled
        x_std = x.std(axis=0)
        y_std = errors.std(axis=0)
        return cls(
            centre,
            x.mean(axis=0),
            np.where(x_std > 1e-9, x_std, 1.0),
            errors.mean(axis=0),
            np.where(y_std > 1e-12, y_std, 1.0),
        )

    @staticmethod
    def _unwrap(poses: np.ndarray, centre: np.ndarray) -> np.ndarray:
        x = np.array(poses, dtype=np.float64).reshape(-1, 6)
        x[:, 3:6] = wrap_deg(x[:, 3:6] - centre)
        return x

    def inputs(self, poses: np.ndarray) -> np.ndarray:
        return (self._unwrap(poses, self.attitude) - self.x_mean) / self.x_std

    def outputs(self, errors: np.ndarray) -> np.ndarray:
        return (np.asarray(errors, dtype=np.float64) - self.y_mean) / self.y_std


class ErrorNet(torch.nn.Module):
    """pose [N, 6] (any float dtype) → E [N, 3] mm: unwrap angles, standardise, MLP, unscale.

    ``dtype`` is the internal precision; the output is cast back to the input's dtype so the
    exported graph takes and returns float32 while computing in float64 when asked.
    """

    def __init__(self, structure: Structure, theta: np.ndarray, scaling: Scaling, dtype: torch.dtype = torch.float32):
        super().__init__()
        self.structure = structure
        self.dtype = dtype

        def buf(name: str, value) -> None:
            self.register_buffer(name, torch.as_tensor(np.asarray(value, dtype=np.float64), dtype=dtype))

        buf("attitude", scaling.attitude)
        buf("x_mean", scaling.x_mean)
        buf("x_std", scaling.x_std)
        buf("y_mean", scaling.y_mean)
        buf("y_std", scaling.y_std)
        self.layers = torch.nn.ModuleList()
        for w, b in structure.unflatten(torch.as_tensor(np.asarray(theta, dtype=np.float64))):
            lin = torch.nn.Linear(w.shape[0], w.shape[1], dtype=dtype)
            with torch.no_grad():
                lin.weight.copy_(w.T)
                lin.bias.copy_(b.reshape(-1))
            self.layers.append(lin)

    def forward(self, pose: torch.Tensor) -> torch.Tensor:
        p = pose.to(self.dtype)
        abc = torch.remainder(p[:, 3:6] - self.attitude + 180.0, 360.0) - 180.0
        h = (torch.cat([p[:, 0:3], abc], dim=1) - self.x_mean) / self.x_std
        for i, layer in enumerate(self.layers):
            h = layer(h)
            if i < len(self.layers) - 1:
                h = torch.relu(h)
        return (h * self.y_std + self.y_mean).to(pose.dtype)

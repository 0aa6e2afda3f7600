"""GPSO's operators, the batched population evaluation, and the GA / PSO baselines."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from postproc.model.training import baselines
from postproc.model.training.gpso import (
    C1, C2, arithmetic_crossover, better_half, child_velocities, gpso, inertia_schedule, pso_velocity,
)
from postproc.model.training.network import Structure, forward


def _gen(seed: int = 0) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


def test_crossover_children_lie_between_their_parents():
    g = _gen()
    x1, x2 = torch.randn(50, 30, generator=g, dtype=torch.float64), torch.randn(50, 30, generator=g, dtype=torch.float64)
    p = torch.rand(50, generator=g, dtype=torch.float64)
    c1, c2 = arithmetic_crossover(x1, x2, p)
    lo, hi = torch.minimum(x1, x2), torch.maximum(x1, x2)
    for c in (c1, c2):
        assert torch.all(c >= lo - 1e-12) and torch.all(c <= hi + 1e-12)
        # on the segment x2 → x1: c − x2 is a multiple t ∈ [0, 1] of x1 − x2
        t = ((c - x2) * (x1 - x2)).sum(1) / ((x1 - x2) ** 2).sum(1)
        assert torch.allclose(c, x2 + t[:, None] * (x1 - x2), atol=1e-12)
        assert torch.all((t >= -1e-12) & (t <= 1 + 1e-12))
    assert torch.allclose(c1 + c2, x1 + x2)  # the pair's mean is kept
    assert torch.allclose(c1, p[:, None] * x1 + (1 - p[:, None]) * x2)


def test_children_velocities_keep_parent_speeds_along_the_summed_direction():
    g = _gen(1)
    v1, v2 = torch.randn(40, 25, generator=g, dtype=torch.float64), torch.randn(40, 25, generator=g, dtype=torch.float64)
    u1, u2 = child_velocities(v1, v2)
    assert torch.allclose(u1.norm(dim=1), v1.norm(dim=1)) and torch.allclose(u2.norm(dim=1), v2.norm(dim=1))
    direction = (v1 + v2) / (v1 + v2).norm(dim=1, keepdim=True)
    assert torch.allclose(u1 / u1.norm(dim=1, keepdim=True), direction)
    assert torch.allclose(u2 / u2.norm(dim=1, keepdim=True), direction)
    # opposite parents (no summed direction) still give finite velocities of the right speeds
    w1, w2 = child_velocities(v1[:1], -v1[:1])
    assert torch.isfinite(w1).all() and torch.allclose(w2.norm(), v1[0].norm())


def test_better_half_keeps_the_lowest_fitness():
    f = torch.tensor([5.0, 1.0, 3.0, 0.5, 9.0, 2.0, 7.0, 4.0])
    keep = better_half(f)
    assert sorted(keep.tolist()) == [1, 2, 3, 5] and keep[0] == 3  # best first
    assert torch.all(f[keep].max() < f[[i for i in range(8) if i not in keep.tolist()]].min())


def test_pso_velocity_is_the_textbook_update():
    g1, g2 = _gen(3), _gen(3)
    x, v, pb = (torch.rand(4, 6, generator=_gen(i), dtype=torch.float64) for i in range(3))
    gb = torch.rand(6, generator=_gen(9), dtype=torch.float64)
    out = pso_velocity(x, v, pb, gb, 0.7298, g1)
    r1, r2 = torch.rand(x.shape, generator=g2, dtype=x.dtype), torch.rand(x.shape, generator=g2, dtype=x.dtype)
    assert torch.allclose(out, 0.7298 * v + C1 * r1 * (pb - x) + C2 * r2 * (gb - x))
    assert inertia_schedule("linear", 0, 50) == pytest.approx(0.9) and inertia_schedule("linear", 49, 50) == pytest.approx(0.4)


def _numpy_mlp(theta: np.ndarray, sizes: tuple[int, ...], x: np.ndarray) -> np.ndarray:
    """An independent per-network forward pass: weights row-major [in, out] then bias."""
    h, pos = x, 0
    for i in range(len(sizes) - 1):
        n_in, n_out = sizes[i], sizes[i + 1]
        w = theta[pos : pos + n_in * n_out].reshape(n_in, n_out)
        pos += n_in * n_out
        b = theta[pos : pos + n_out]
        pos += n_out
        h = h @ w + b
        if i < len(sizes) - 2:
            h = np.maximum(h, 0.0)
    assert pos == len(theta)
    return h


def test_batched_population_fitness_equals_a_loop_over_particles():
    s = Structure((5, 4))
    g = _gen(4)
    theta = torch.rand(7, s.n_params, generator=g, dtype=torch.float64) * 2 - 1
    x = torch.randn(30, 6, generator=g, dtype=torch.float64)
    y = torch.randn(30, 3, generator=g, dtype=torch.float64)
    batched = torch.mean((forward(s, theta, x) - y) ** 2, dim=(1, 2))
    looped = [np.mean((_numpy_mlp(t.numpy(), s.sizes, x.numpy()) - y.numpy()) ** 2) for t in theta]
    assert np.allclose(batched.numpy(), looped, rtol=1e-12)
    assert torch.allclose(forward(s, theta[2], x), forward(s, theta, x)[2])


def _sphere(theta: torch.Tensor) -> torch.Tensor:
    return ((theta - 0.3) ** 2).sum(dim=1)


@pytest.mark.parametrize(
    "run",
    [
        lambda g: gpso(_sphere, 12, population=10, generations=40, generator=g),
        lambda g: gpso(_sphere, 12, population=10, generations=40, inertia="linear", generator=g),
        lambda g: baselines.ga(_sphere, 12, population=20, generations=40, generator=g),
        lambda g: baselines.pso(_sphere, 12, population=10, generations=40, generator=g),
    ],
    ids=["gpso", "gpso-linear", "ga", "pso"],
)
def test_searches_improve_monotonically_and_report_their_best(run):
    start = float(_sphere(torch.rand(200, 12, generator=_gen(5), dtype=torch.float64) * 2 - 1).mean())
    result = run(_gen(6))
    h = np.array(result.history)
    assert len(h) == 40 and np.all(np.diff(h) <= 0)  # best-so-far never gets worse
    assert h[-1] < 0.2 * start  # a real improvement on a convex bowl
    assert float(_sphere(result.theta[None])[0]) == pytest.approx(result.fitness)


def test_searches_are_reproducible_from_the_generator():
    a = gpso(_sphere, 8, population=6, generations=5, generator=_gen(7))
    b = gpso(_sphere, 8, population=6, generations=5, generator=_gen(7))
    c = gpso(_sphere, 8, population=6, generations=5, generator=_gen(8))
    assert torch.equal(a.theta, b.theta) and not torch.equal(a.theta, c.theta)


def test_written_out_jacobian_equals_torch_func():
    from postproc.model.training.network import jacobian

    s = Structure((7, 5, 4))
    g = _gen(10)
    theta = torch.rand(s.n_params, generator=g, dtype=torch.float64) * 2 - 1
    x = torch.randn(40, 6, generator=g, dtype=torch.float64)
    reference = torch.func.jacrev(lambda t: forward(s, t, x).reshape(-1))(theta)
    assert torch.allclose(jacobian(s, theta, x), reference, atol=1e-12)

"""The method's comparison initialisations: GA, PSO, and plain random weights.

* GA-DNN (population 50, 100 generations, crossover 0.3, mutation 0.1), real-coded:
  elitism (the 2 best pass unchanged), binary tournament selection, arithmetic crossover
  of each parent pair with probability 0.3 (otherwise the parents pass), gaussian mutation
  of each gene with probability 0.1 (σ = 0.1, a twentieth of the initial [−1, 1] span).
* PSO-DNN (population 40, 100 generations): global-best PSO with the same constants as
  GPSO (w = 0.7298, c1 = c2 = 1.4962), no genetic step.
* plain: one random draw from the same U[−1, 1] the populations start from — so the four
  methods differ only in how the starting weights were searched.

All return an :class:`~postproc.model.training.gpso.InitResult`; fitness is evaluated for the
whole population in one batched call.
"""
from __future__ import annotations

from typing import Callable

import torch

from .gpso import W_CONSTANT, InitResult, arithmetic_crossover, pso_velocity

__all__ = ["ga", "pso", "plain"]

Fitness = Callable[[torch.Tensor], torch.Tensor]
MUTATION_SIGMA = 0.1
ELITE = 2


def ga(
    fitness: Fitness,
    dim: int,
    population: int = 50,
    generations: int = 100,
    crossover: float = 0.3,
    mutation: float = 0.1,
    generator: torch.Generator | None = None,
    dtype: torch.dtype = torch.float64,
    callback: Callable[[int, float], None] | None = None,
) -> InitResult:
    """Real-coded GA over weight vectors; returns the best individual ever seen."""
    gen = generator if generator is not None else torch.Generator().manual_seed(0)
    x = torch.rand(population, dim, generator=gen, dtype=dtype) * 2 - 1
    f = fitness(x)
    evaluations = population
    history = []
    n_off = population - ELITE
    n_pairs = (n_off + 1) // 2
    best_i = int(torch.argmin(f))
    best, best_f = x[best_i].clone(), float(f[best_i])
    for generation in range(generations):
        elite = torch.argsort(f, stable=True)[:ELITE]
        # binary tournaments: the fitter of two random individuals becomes a parent
        a = torch.randint(population, (2 * n_pairs,), generator=gen)
        b = torch.randint(population, (2 * n_pairs,), generator=gen)
        parents = torch.where(f[a] <= f[b], a, b)
        x1, x2 = x[parents[:n_pairs]], x[parents[n_pairs:]]
        p = torch.rand(n_pairs, 1, generator=gen, dtype=dtype)
        cross = torch.rand(n_pairs, 1, generator=gen, dtype=dtype) < crossover
        m1, m2 = arithmetic_crossover(x1, x2, p)
        c1, c2 = torch.where(cross, m1, x1), torch.where(cross, m2, x2)
        off = torch.cat([c1, c2])[:n_off]
        mask = torch.rand(off.shape, generator=gen, dtype=dtype) < mutation
        off = off + mask * torch.randn(off.shape, generator=gen, dtype=dtype) * MUTATION_SIGMA
        x = torch.cat([x[elite], off])
        f = torch.cat([f[elite], fitness(off)])
        evaluations += n_off
        i = int(torch.argmin(f))
        if float(f[i]) < best_f:
            best, best_f = x[i].clone(), float(f[i])
        history.append(best_f)
        if callback is not None:
            callback(generation, best_f)
    return InitResult(best, best_f, history, evaluations)


def pso(
    fitness: Fitness,
    dim: int,
    population: int = 40,
    generations: int = 100,
    generator: torch.Generator | None = None,
    dtype: torch.dtype = torch.float64,
    callback: Callable[[int, float], None] | None = None,
) -> InitResult:
    """Global-best PSO over weight vectors (positions and velocities start in [−1, 1])."""
    gen = generator if generator is not None else torch.Generator().manual_seed(0)
    x = torch.rand(population, dim, generator=gen, dtype=dtype) * 2 - 1
    v = torch.rand(population, dim, generator=gen, dtype=dtype) * 2 - 1
    f = fitness(x)
    pbest, pbest_f = x.clone(), f.clone()
    evaluations = population
    history = []
    for generation in range(generations):
        g = int(torch.argmin(pbest_f))
        v = pso_velocity(x, v, pbest, pbest[g], W_CONSTANT, gen)
        x = x + v
        f = fitness(x)
        evaluations += population
        improved = f < pbest_f
        pbest = torch.where(improved[:, None], x, pbest)
        pbest_f = torch.where(improved, f, pbest_f)
        history.append(float(pbest_f.min()))
        if callback is not None:
            callback(generation, history[-1])
    g = int(torch.argmin(pbest_f))
    return InitResult(pbest[g].clone(), float(pbest_f[g]), history, evaluations)


def plain(
    fitness: Fitness, dim: int, generator: torch.Generator | None = None, dtype: torch.dtype = torch.float64
) -> InitResult:
    """One random weight vector from U[−1, 1] (no search)."""
    gen = generator if generator is not None else torch.Generator().manual_seed(0)
    x = torch.rand(1, dim, generator=gen, dtype=dtype) * 2 - 1
    return InitResult(x[0], float(fitness(x)[0]), [], 1)

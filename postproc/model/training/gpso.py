"""GPSO: particle swarm optimisation with a genetic step, for the network's initial weights.

Each generation (population P, flat weight vectors as particle positions):

1. PSO move: v ← w·v + c1·r1·(pbest − x) + c2·r2·(gbest − x), x ← x + v
   (c1 = c2 = 1.4962; w = 0.7298 constant by default — measured better than 0.9→0.4 on our
   data, see ``benchmarks/train_compare.py --inertia``);
2. fitness (training MSE, standardised units) of the whole population in one batched pass;
   update personal and global bests;
3. selection: keep the better half by fitness;
4. refill by arithmetic crossover of random pairs of kept particles,
   child1 = p·x1 + (1−p)·x2, child2 = (1−p)·x1 + p·x2 with p ~ U[0, 1] per pair; the
   children's velocities point along the parents' summed velocity with each parent's speed,
   v_child1 = (v1+v2)/|v1+v2|·|v1|, v_child2 = (v1+v2)/|v1+v2|·|v2|; children start with
   their own position as personal best (evaluated at once, batched).

Initial positions and velocities are uniform in [−1, 1]. The result is the global best,
which backprop (``optimise.py``) then refines.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import torch

__all__ = [
    "C1",
    "C2",
    "W_CONSTANT",
    "InitResult",
    "gpso",
    "pso_velocity",
    "inertia_schedule",
    "better_half",
    "arithmetic_crossover",
    "child_velocities",
]

C1 = C2 = 1.4962
W_CONSTANT = 0.7298  # Clerc's constriction expressed as inertia: convergent with c1 = c2 = 1.4962
W_START, W_END = 0.9, 0.4  # the linearly decreasing alternative

Fitness = Callable[[torch.Tensor], torch.Tensor]  # [P, D] → [P]


@dataclass
class InitResult:
    """What a weight-initialisation search hands to backprop."""

    theta: torch.Tensor  # [D] best weights found
    fitness: float  # its training MSE (standardised units)
    history: list[float] = field(default_factory=list)  # best fitness after each generation
    evaluations: int = 0  # networks evaluated


def inertia_schedule(kind: str, generation: int, generations: int) -> float:
    """'constant' → 0.7298; 'linear' → 0.9 falling to 0.4 over the run."""
    if kind == "constant":
        return W_CONSTANT
    if kind == "linear":
        return W_START - (W_START - W_END) * generation / max(1, generations - 1)
    raise ValueError(f"unknown inertia schedule {kind!r} (constant|linear)")


def pso_velocity(
    x: torch.Tensor, v: torch.Tensor, pbest: torch.Tensor, gbest: torch.Tensor, w: float, gen: torch.Generator
) -> torch.Tensor:
    """The PSO velocity update for a population [P, D] (r1, r2 ~ U[0, 1] per component)."""
    r1 = torch.rand(x.shape, generator=gen, dtype=x.dtype)
    r2 = torch.rand(x.shape, generator=gen, dtype=x.dtype)
    return w * v + C1 * r1 * (pbest - x) + C2 * r2 * (gbest - x)


def better_half(fitness: torch.Tensor) -> torch.Tensor:
    """Indices of the better (lower-MSE) half, best first; ties keep the earlier particle."""
    order = torch.argsort(fitness, stable=True)
    return order[: (len(fitness) + 1) // 2]


def arithmetic_crossover(
    x1: torch.Tensor, x2: torch.Tensor, p: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """Children of parent pairs x1, x2 [K, D] with weights p [K]: both lie on the segment x1–x2."""
    p = p.reshape(-1, 1)
    return p * x1 + (1 - p) * x2, (1 - p) * x1 + p * x2


def child_velocities(v1: torch.Tensor, v2: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Children's velocities: the direction of v1 + v2, with the speeds |v1| and |v2|."""
    s = v1 + v2
    norm = torch.linalg.vector_norm(s, dim=1, keepdim=True)
    # parents moving exactly against each other: no common direction, keep each parent's own
    degenerate = norm <= torch.finfo(s.dtype).tiny
    direction = torch.where(degenerate, v1, s) / torch.where(
        degenerate, torch.linalg.vector_norm(v1, dim=1, keepdim=True).clamp_min(torch.finfo(s.dtype).tiny), norm
    )
    speed1 = torch.linalg.vector_norm(v1, dim=1, keepdim=True)
    speed2 = torch.linalg.vector_norm(v2, dim=1, keepdim=True)
    return direction * speed1, direction * speed2


def gpso(
    fitness: Fitness,
    dim: int,
    population: int = 20,
    generations: int = 50,
    inertia: str = "constant",
    generator: torch.Generator | None = None,
    dtype: torch.dtype = torch.float64,
    callback: Callable[[int, float], None] | None = None,
) -> InitResult:
    """Run GPSO on ``fitness`` over weight vectors of length ``dim``; return the global best."""
    if population < 4:
        raise ValueError("GPSO needs a population of at least 4 (two pairs of parents)")
    gen = generator if generator is not None else torch.Generator().manual_seed(0)
    x = torch.rand(population, dim, generator=gen, dtype=dtype) * 2 - 1
    v = torch.rand(population, dim, generator=gen, dtype=dtype) * 2 - 1
    f = fitness(x)
    pbest, pbest_f = x.clone(), f.clone()
    g = int(torch.argmin(pbest_f))
    gbest, gbest_f = pbest[g].clone(), float(pbest_f[g])
    evaluations = population
    history = []
    n_keep = (population + 1) // 2
    n_children = population - n_keep
    n_pairs = (n_children + 1) // 2
    for generation in range(generations):
        # 1. move
        v = pso_velocity(x, v, pbest, gbest, inertia_schedule(inertia, generation, generations), gen)
        x = x + v
        # 2. evaluate, update bests
        f = fitness(x)
        evaluations += population
        improved = f < pbest_f
        pbest = torch.where(improved[:, None], x, pbest)
        pbest_f = torch.where(improved, f, pbest_f)
        # 3. keep the better half (with their velocities and memories)
        keep = better_half(f)
        x, v, pbest, pbest_f = x[keep], v[keep], pbest[keep], pbest_f[keep]
        # 4. refill by crossover of random pairs of survivors
        i1 = torch.randint(n_keep, (n_pairs,), generator=gen)
        i2 = (i1 + torch.randint(1, n_keep, (n_pairs,), generator=gen)) % n_keep  # a different partner
        p = torch.rand(n_pairs, generator=gen, dtype=dtype)
        c1, c2 = arithmetic_crossover(x[i1], x[i2], p)
        u1, u2 = child_velocities(v[i1], v[i2])
        cx = torch.cat([c1, c2])[:n_children]
        cv = torch.cat([u1, u2])[:n_children]
        cf = fitness(cx)
        evaluations += n_children
        x, v = torch.cat([x, cx]), torch.cat([v, cv])
        pbest, pbest_f = torch.cat([pbest, cx]), torch.cat([pbest_f, cf])
        g = int(torch.argmin(pbest_f))
        if float(pbest_f[g]) < gbest_f:
            gbest, gbest_f = pbest[g].clone(), float(pbest_f[g])
        history.append(gbest_f)
        if callback is not None:
            callback(generation, gbest_f)
    return InitResult(gbest, gbest_f, history, evaluations)

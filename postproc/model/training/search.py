"""Structure search: which hidden layers, scored on a validation split of the training data.

The method searched 1–6 hidden layers of 3–16 nodes each. All 14^6 combinations cannot be
trained, so this searches two families — **equal widths** (n,)*L and **halving widths**
(n, n/2, n/4, …, never below 3, like the method's 20-10-5) for L in 1..6 and n in 3..16,
149 distinct structures — plus the method's own (20, 10, 5) as a reference, by successive
halving:

1. screen: every candidate gets the chosen weight search (GPSO by default) and 300 L-BFGS
   epochs (cheap: its cost grows with the number of weights D, Levenberg–Marquardt's with D²);
2. final: the ``keep`` best of the screen are trained with the full method (the chosen
   optimiser, all epochs), once per seed of ``final_seeds`` (the same seeds for each, so a
   lucky start does not decide), and the lowest mean validation |E − Ê| wins.

The validation split is drawn from the *training* rows (``val_fraction`` of them, seeded), so
the held-out rows that ``postproc train`` reports on are never used to choose. Candidates
with more weights than the data support (see ``data.min_points``) are listed and skipped.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from functools import partial
from typing import Callable, Iterable

import numpy as np

from ...core.diagnostics import P505, PostprocError
from .data import min_points, split_indices
from .estimator import ErrorModel
from .network import Structure

__all__ = ["Candidate", "SearchResult", "candidates", "fit_and_score", "search_structure", "format_table"]

METHOD_STRUCTURE = (20, 10, 5)
SCREEN_OPTIMIZER, SCREEN_EPOCHS = "lbfgs", 300


@dataclass
class Candidate:
    hidden: tuple[int, ...]
    n_weights: int
    screen_mm: float | None = None  # validation mean |E − Ê| after the screen
    final_mm: float | None = None  # … after the full method (finalists only)
    final_max_mm: float | None = None
    seconds: float = 0.0
    note: str = ""

    @property
    def label(self) -> str:
        return ",".join(str(v) for v in self.hidden)


@dataclass
class SearchResult:
    best: tuple[int, ...]
    candidates: list[Candidate] = field(default_factory=list)
    n_fit: int = 0
    n_val: int = 0
    final_seeds: int = 1


def candidates(layers=range(1, 7), widths=range(3, 17)) -> list[tuple[int, ...]]:
    """Equal-width and halving-width structures (distinct) plus the method's (20, 10, 5)."""
    equal = [(n,) * n_layers for n_layers in layers for n in widths]
    halving = [tuple(max(3, round(n / 2**i)) for i in range(n_layers)) for n_layers in layers for n in widths]
    return list(dict.fromkeys(equal + halving + [METHOD_STRUCTURE]))


def _val_mean(model: ErrorModel, poses: np.ndarray, errors: np.ndarray) -> tuple[float, float]:
    d = np.linalg.norm(errors - model.predict(poses), axis=1)
    return float(d.mean()), float(d.max())


def fit_and_score(hidden: tuple[int, ...], optimizer: str | None, epochs: int, seed: int, *, method: str,
                  px: np.ndarray, ex: np.ndarray, pv: np.ndarray, ev: np.ndarray) -> tuple[float, float, float]:
    """One candidate's fit — one task of the search: (mean, max) validation |E − Ê| mm and its seconds."""
    t = time.perf_counter()
    model = ErrorModel(hidden, method, optimizer, epochs, seed=seed).fit(px, ex)
    return (*_val_mean(model, pv, ev), time.perf_counter() - t)


def search_structure(
    poses: np.ndarray,
    errors: np.ndarray,
    method: str = "gpso",
    optimizer: str | None = None,
    epochs: int = 500,
    seed: int = 0,
    val_fraction: float = 0.2,
    keep: int = 6,
    final_seeds: int = 2,
    structures: list[tuple[int, ...]] | None = None,
    screen_epochs: int = SCREEN_EPOCHS,
    progress: bool = False,
    log: Callable[[str], None] | None = None,
    map_fn: Callable[..., Iterable] | None = None,
) -> SearchResult:
    """Search structures on (poses, errors); returns the winner and every candidate's scores.

    ``map_fn(fn, *iterables)`` runs the fits, results in order (default: the built-in ``map``,
    one after another here; ``postproc.fleet.cluster.task_map`` gives one whose calls are tasks on a
    cluster). Every fit is seeded, so where it runs does not change the result."""
    map_fn = map_fn or map
    fit_rows, val_rows = split_indices(len(poses), val_fraction, seed)
    if len(val_rows) == 0:
        raise ValueError("structure search needs a validation split (val_fraction > 0)")
    task = partial(fit_and_score, method=method, px=poses[fit_rows], ex=errors[fit_rows], pv=poses[val_rows],
                   ev=errors[val_rows])
    pool = [Candidate(h, Structure(h).n_params) for h in (structures or candidates())]
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(pool) + keep * final_seeds, desc="search", unit="net", leave=False, dynamic_ncols=True)
    for cand in pool:
        if len(fit_rows) < min_points(cand.n_weights):
            cand.note = f"skipped: needs ≥ {min_points(cand.n_weights)} points"
            if bar is not None:
                bar.update(1)
    fits = [c for c in pool if not c.note]
    runs = map_fn(task, [c.hidden for c in fits], [SCREEN_OPTIMIZER] * len(fits), [screen_epochs] * len(fits),
                  [seed] * len(fits))
    for cand, (mean, _, seconds) in zip(fits, runs):
        cand.screen_mm, cand.seconds = mean, cand.seconds + seconds
        if bar is not None:
            bar.update(1)
        if log is not None:
            log(f"screen {cand.label:<18} {cand.screen_mm:.4f} mm")
    screened = sorted((c for c in pool if c.screen_mm is not None), key=lambda c: c.screen_mm)
    if not screened:
        raise PostprocError(
            f"{len(fit_rows)} points are too few for any candidate structure (the smallest needs "
            f"{min(min_points(c.n_weights) for c in pool)} after the search's validation split)",
            code=P505,
        )
    finalists = [(cand, k) for cand in screened[:keep] for k in range(final_seeds)]
    runs = iter(map_fn(task, [c.hidden for c, _ in finalists], [optimizer] * len(finalists),
                       [epochs] * len(finalists), [seed + k for _, k in finalists]))
    for cand in screened[:keep]:
        scores = []
        for _ in range(final_seeds):
            mean, worst, seconds = next(runs)
            scores.append((mean, worst))
            cand.seconds += seconds
            if bar is not None:
                bar.update(1)
        cand.final_mm = float(np.mean([m for m, _ in scores]))
        cand.final_max_mm = float(np.mean([m for _, m in scores]))
        if log is not None:
            log(f"final  {cand.label:<18} {cand.final_mm:.4f} mm")
    if bar is not None:
        bar.close()
    best = min((c for c in pool if c.final_mm is not None), key=lambda c: c.final_mm)
    return SearchResult(best.hidden, pool, len(fit_rows), len(val_rows), final_seeds)


def format_table(result: SearchResult, screen_epochs: int = SCREEN_EPOCHS) -> str:
    """The search as a text table, best first (finalists, then the screened, then skipped)."""

    def key(c: Candidate):
        return (c.final_mm is None, c.final_mm or 0.0, c.screen_mm is None, c.screen_mm or 0.0)

    head = (
        f"structure search: {len(result.candidates)} candidates, fit on {result.n_fit} points, "
        f"scored on {result.n_val} (mean |E − Ê| mm on the search's validation split)\n"
        f"{'hidden':<18} {'weights':>7} {'screen':>8} {'final':>8} {'final max':>9} {'s':>6}\n"
    )
    lines = []
    for c in sorted(result.candidates, key=key):
        mark = "  ← chosen" if c.hidden == result.best else ""
        if c.hidden == METHOD_STRUCTURE:
            mark += "  (the method's)"
        screen = f"{c.screen_mm:8.4f}" if c.screen_mm is not None else f"{'-':>8}"
        final = f"{c.final_mm:8.4f}" if c.final_mm is not None else f"{'-':>8}"
        fmax = f"{c.final_max_mm:9.4f}" if c.final_max_mm is not None else f"{'-':>9}"
        lines.append(f"{c.label:<18} {c.n_weights:7d} {screen} {final} {fmax} {c.seconds:6.1f}{mark}{'  ' + c.note if c.note else ''}")
    foot = (f"\nscreen: {screen_epochs} L-BFGS epochs after the weight search; final: the full method, "
            f"mean over {result.final_seeds} seed(s)")
    return head + "\n".join(lines) + foot

"""Blocked cross-validation: what an identification carries to joint-space regions it did not see.

Random held-out rows of one campaign sit between training rows: every term that fits the
campaign's own rows scores well there, whether it carries to other regions or not. So the
identification chooses what it adds to the physical model — optional physical groups
(``OPTIONAL_GROUPS``: the 21 torque couplings, the joint compliances), how many of the gear-
ripple orders it found — by holding out whole regions of joint space instead (``folds``): the
rows' octants of A1/A2/A3 (each joint's arc split at its median) and, where the data has more
than one, their arm configurations (the IK branch: shoulder, elbow, wrist; a configuration held
out whole, as a program in another one). Each region is predicted by the model fitted on the others, as
the exported graph would predict it: the ripple orders left out where a row lies outside the
joint arcs of the rows fitted.

It is cheap because the identification is nearly linear in its small parameters: with the
Jacobian J [M, P] and residual r at the full fit θ̂ (M = 3N coordinates, or 6N with orientation),
r(θ) ≈ r0 + J·θ with r0 = r − J·θ̂, and every candidate is a regularised least squares in it.
Per region k the Gram matrix of [J, r0] over its rows is formed once; the fit without k is then
a solve with the total minus k's Gram. The groups are fitted first and the ripple orders on top
(the identification's staging), with the fit's own prior (weights W). On the IPA UR10 data
(2,200–9,500 rows) a candidate costs a few hundredths of a second; a nonlinear refit per region
and candidate would cost minutes.

``BlockedCV.evaluate`` gives each held-out row's residual and, from each region's posterior
(σ²·A₋ₖ⁻¹ with A₋ₖ the Gram without it plus W), the model part of its variance there: what the
uncertainty's calibration (training/uncertainty.py) holds against the residuals.

numpy only.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["folds", "BlockedCV", "BlockedSets", "Evaluation", "OPTIONAL_GROUPS", "PARSIMONY", "HARM_SE", "MIN_ROWS"]

# physical groups the blocked CV may leave out (terms whose fit on one region need not carry:
# the couplings are 21 free functions of the arm's posture)
OPTIONAL_GROUPS = ("coupling", "compliance")
# the candidates within this share of the best blocked score count as equal: of the physical
# groups the most are kept (left out only where held-out regions show harm), of the ripple orders
# the fewest (``KinematicModel._select_groups`` / ``_select_ripple``)
PARSIMONY = 0.01
# the joint compliance is left out only where leaving it out scores better by more than this
# many standard errors of the difference (``BlockedSets.difference_se``: the regions' paired
# sums): a difference the regions do not agree on is the data not telling, and the physical
# effect stays. (A simulated KR 500 measured in one wrist configuration scored without its
# compliance and couplings 1.2 % better, just beyond PARSIMONY; both left out, its flipped wrist
# was compensated to 1.24 mm with a 2σ band covering 67 %, the compliance kept 0.80 mm and
# 100 %. The same rule for the couplings — 21 free terms — cost IPA Series A's model its
# transfer: D 0.38 → 0.64 mm)
HARM_SE = 2.0
# fewer rows than this (or fewer than two regions): no selection, every group and order kept
MIN_ROWS = 60
# the arm configurations are a way to split the rows when two of them hold this share of them each
MIN_SHARE = 0.05


def folds(q_rad: np.ndarray, branches: np.ndarray) -> list[tuple[str, np.ndarray]]:
    """The ways the rows are split into regions, each a (name, region of each row [N] 0…K−1):
    "octants" of A1, A2, A3 (each joint split at the median of its angle along the smallest arc
    that holds the rows: ``compensator.joint_arcs``), and "configurations", the IK branch
    ``branches`` [N, 3] (±1: shoulder, elbow, wrist), where at least two of them hold
    ``MIN_SHARE`` of the rows each. Each row is held out once per way."""
    from ..envelope import joint_arcs

    q_deg = np.degrees(np.asarray(q_rad, float))
    arcs = joint_arcs(q_deg[:, :3])
    octant = np.zeros(len(q_deg), int)
    for j in range(3):
        u = np.mod(q_deg[:, j] - arcs[j, 0], 360.0)
        octant += (u > np.median(u)).astype(int) << j
    out = [("octants", np.unique(octant, return_inverse=True)[1].reshape(-1))]
    branch = ((np.asarray(branches) > 0).astype(int) * np.array([1, 2, 4])).sum(axis=1)
    configuration = np.unique(branch, return_inverse=True)[1].reshape(-1)
    if (np.bincount(configuration) >= MIN_SHARE * len(branch)).sum() >= 2:
        out.append(("configurations", configuration))
    return [(name, fold) for name, fold in out if fold.max() >= 1]


@dataclass
class Evaluation:
    """A candidate's blocked held-out figures: per row the residual [N, per_row] (what the model
    fitted without the row's region leaves there) and the model part of its variance per
    coordinate [N] (σ²-free: multiply by σ²), and the sum of squares."""

    residual: np.ndarray
    variance: np.ndarray
    sse: float
    outside: np.ndarray | None = None  # [N] bool: the row lies outside the joint arcs of the rows fitted without it

    @property
    def rms(self) -> float:
        return float(np.sqrt(self.sse / self.residual.size))

    def norms(self, coordinates: int = 3) -> np.ndarray:
        """|residual| of each row's position (its first three coordinates), mm."""
        return np.linalg.norm(self.residual[:, :coordinates], axis=1)


class BlockedCV:
    """The Grams of [J, r0] per region (module text) and each region's rows outside the joint
    arcs of the others (where the graph leaves the ripple orders out)."""

    def __init__(self, jac: np.ndarray, r: np.ndarray, theta: np.ndarray, fold: np.ndarray, q_rad: np.ndarray,
                 ripple_joint: np.ndarray | None = None, ripple_order: np.ndarray | None = None):
        from ..envelope import joint_arcs, widened_arcs

        n = len(fold)
        self.per_row = len(r) // n
        self.fold = np.asarray(fold)
        self.k = int(self.fold.max()) + 1
        r0 = r - jac @ theta
        self.z = np.c_[jac, r0]  # [M, P + 1]
        rows = np.repeat(self.fold, self.per_row)
        self.grams = np.stack([self.z[rows == k].T @ self.z[rows == k] for k in range(self.k)])
        self.total = self.grams.sum(axis=0)
        self.row_of = [np.flatnonzero(self.fold == k) for k in range(self.k)]
        # each region's coordinates of [J, r0], taken out once
        self.z_of = [self.z[np.repeat(mine, self.per_row) * self.per_row + np.tile(np.arange(self.per_row), len(mine))]
                     for mine in self.row_of]
        # ripple columns (2 per order: sin, cos) of each held-out row outside the others' arcs: 0
        q_deg = np.degrees(np.asarray(q_rad, float))
        self.outside = []
        for k, mine in enumerate(self.row_of):
            arcs = widened_arcs(joint_arcs(q_deg[self.fold != k])) if (self.fold != k).any() else None
            if arcs is None:
                self.outside.append(np.ones(len(mine), bool))
                continue
            u = np.mod(q_deg[mine] - arcs[:, 0], 360.0)
            self.outside.append((u > (arcs[:, 1] - arcs[:, 0])).any(axis=1))
        self.n_par = jac.shape[1]

    @property
    def regions(self) -> int:
        return self.k

    def evaluate(self, physical: np.ndarray, ripple: np.ndarray, weights: np.ndarray,
                 variance: bool = False) -> Evaluation:
        """The candidate with the parameter columns ``physical`` fitted first and ``ripple`` on top
        (the others 0: the nominal value), each under the prior ``weights`` [P] (mm² per unit²):
        every region predicted by the fit without it; with ``variance`` also the model part of
        each held-out row's variance (else zeros)."""
        p = self.n_par
        residual = np.zeros((len(self.fold), self.per_row))
        model_var = np.zeros(len(self.fold))
        outside = np.zeros(len(self.fold), bool)
        sse = 0.0
        both = np.r_[physical, ripple].astype(int)
        for k, mine in enumerate(self.row_of):
            if not len(mine):
                continue
            a = self.total - self.grams[k]
            a_pp = a[np.ix_(physical, physical)] + np.diag(weights[physical])
            theta = np.zeros(p)
            theta[physical] = -np.linalg.solve(a_pp, a[physical, p])
            if len(ripple):
                a_rr = a[np.ix_(ripple, ripple)] + np.diag(weights[ripple])
                theta[ripple] = -np.linalg.solve(a_rr, a[ripple, p] + a[np.ix_(ripple, physical)] @ theta[physical])
            z = self.z_of[k]
            e = z[:, p] + z[:, :p] @ theta
            out = np.repeat(self.outside[k], self.per_row) if len(ripple) else None
            if out is not None and out.any():  # (the ripple terms left out there)
                e[out] -= z[np.ix_(out, ripple)] @ theta[ripple]
            residual[mine] = e.reshape(-1, self.per_row)
            outside[mine] = self.outside[k]
            sse += float(e @ e)
            if not variance:
                continue
            # the model part of each row's variance (σ² = 1): the staged posterior taken as one
            # regularised fit of both sets, J A⁻¹ Jᵀ over the row's position coordinates
            a_all = a[np.ix_(both, both)] + np.diag(weights[both])
            jc = z[:, both].copy()
            if out is not None and out.any():
                jc[np.ix_(out, np.arange(len(physical), len(both)))] = 0.0
            var = np.einsum("ij,ij->i", jc @ np.linalg.inv(a_all), jc).reshape(-1, self.per_row)[:, :3]
            model_var[mine] = var.mean(axis=1)
        return Evaluation(residual, model_var, sse, outside)


class BlockedSets:
    """Several ways of splitting the rows (``folds``), each a ``BlockedCV``: a candidate's score
    is the sum over them (each row held out once per way), its rows one after the other."""

    def __init__(self, jac: np.ndarray, r: np.ndarray, theta: np.ndarray, ways: list[tuple[str, np.ndarray]],
                 q_rad: np.ndarray):
        self.names = [name for name, _ in ways]
        self.sets = [BlockedCV(jac, r, theta, fold, q_rad) for _, fold in ways]

    @property
    def regions(self) -> dict[str, int]:
        return {name: cv.regions for name, cv in zip(self.names, self.sets)}

    def difference_se(self, a: Evaluation, b: Evaluation) -> float:
        """The standard error of ``a.sse − b.sse`` (two candidates' evaluations): from the
        paired difference of their sums of squares per held-out region (every way's regions
        one after the other), √(K·var) over the K regions."""
        labels = np.concatenate([cv.fold + sum(c.k for c in self.sets[:i]) for i, cv in enumerate(self.sets)])
        k = sum(cv.k for cv in self.sets)
        d = (np.bincount(labels, (a.residual ** 2).sum(axis=1), minlength=k)
             - np.bincount(labels, (b.residual ** 2).sum(axis=1), minlength=k))
        return float(np.sqrt(k * d.var(ddof=1))) if k > 1 else 0.0

    def evaluate(self, physical: np.ndarray, ripple: np.ndarray, weights: np.ndarray,
                 variance: bool = False) -> Evaluation:
        parts = [cv.evaluate(physical, ripple, weights, variance) for cv in self.sets]
        return Evaluation(np.concatenate([e.residual for e in parts]), np.concatenate([e.variance for e in parts]),
                          sum(e.sse for e in parts), np.concatenate([e.outside for e in parts]))

"""How sure an identified kinematic model is at each target: a positional standard deviation.

The identification (training/kinematic.py) minimises ‖r(θ)‖² + Σ w_i θ_i² over the 3N position
residuals of the training rows. At its solution θ̂, with J = ∂r/∂θ [3N, P] (the same geometric
Jacobian the fit uses) and A = JᵀJ + W (W = diag w, the weak prior):

* residual variance per coordinate σ² = ‖r(θ̂)‖² / (3N − p_eff), p_eff = tr(A⁻¹JᵀJ) the
  effective number of parameters (the prior takes some of their freedom); r the residual the
  model leaves at its training rows evaluated as the graph evaluates it, at the IK of each
  row's pose (see below);
* parameter covariance C = σ²·A⁻¹JᵀJ·A⁻¹ (the sandwich of the regularised least-squares
  estimate: the spread of θ̂ over repeated measurements of the same poses; what the
  predictions inherit). What is known of a parameter's own value is the posterior σ²·A⁻¹
  (``posterior_std``: the certificate's uncertainty), which differs where the data fixes only
  sums of parameters;
* at a target with Jacobian J_t [3, P] the residual a compensation leaves, E − Ê, has per
  coordinate the variance σ² + diag(J_t C_p J_tᵀ): what the model does not explain plus what it
  does not know. C_p is the *predictive* covariance κ·σ²·A⁻¹, the posterior, not the sandwich:
  along the directions the data cannot separate (a zero offset and a placement turned about
  its axis; the wrist's zero offsets and the tool with one arm configuration) the sandwich has
  no spread — the split does not vary with the noise — while the posterior keeps the prior's,
  which is what a target that does separate them (the flipped wrist) inherits. κ ≥ 1 is
  calibrated on the blocked held-out rows (training/blocked.py: each row predicted by the fit
  without its joint-space region, with that fit's posterior): the least κ whose band covers
  ``COVERAGE`` of their residual coordinates within 2σ (``calibrate``; the card's
  ``uncertainty.calibration``);
* where the graph leaves its learned parts out (outside the trained joint arcs: the ripple
  orders, the residual networks) it adds what they explain at the training rows, per coordinate
  (``HybridModule.learned_var``, the card's ``uncertainty.learned_std_mm``): there the model
  does not know that part of the error.

:func:`position_std` returns, per target, that residual std (the root mean over X, Y, Z) and
its model part alone (of the identified arm: without the learned parts' term, which the graph adds). Under Gaussian residuals 95.4 % of the held-out residual coordinates
lie within 2σ; the tests check 90–98 % on simulated data (also with a planner's joint angles)
and on IPA rows. numpy + torch (as training/).

Which residual: where the data has joint angles q1..q6 the fit evaluates the arm at them and
fits the identified arm *relative to the nominal one at the same q* (FK_id(q) against
FK_nom(q) − E), so the pose a planner's numerical IK misses by (FK_nom(q) ≠ P: IPA 0.057 mm
rms per coordinate, up to 0.26 mm) cancels in the least squares; ``train_residual_``
(E − (P − FK_id(q))) still carries that miss, which no compensation leaves (the graph runs at
the pose's exact IK). σ from it overstated IPA's held-out residual std by 40 % (2σ covered
98.8 %); callers that have the training rows pass the residual at the IK
(:func:`parameter_covariance`'s ``residual``: HybridModel, the benchmark). Without joint angles
in the data both are the same.

The exported graph computes the same figure (the contract's optional output ``error_std``):
``KinematicErrorModule`` builds J_t with the columns of the same geometric Jacobian
(``kinematic.jacobian``, batch-last: ``kinematic.KinematicErrorModule._error_std``) from the
graph's own q, approach signs and tool, and takes ``kinematic.residual_variance`` with C_p and
σ² stored in the graph (``HybridModule``'s buffers ``covariance`` [P, P], ``sigma2`` and
``learned_var``). It is of
the identified arm only: where residual networks were kept, σ is the identification's residual
(larger than what the networks leave,
so the figure errs on the safe side).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from .kinematic import KinematicModel, approach_signs, jacobian, residual_variance

# compensate / check warn (P336) where error_std exceeds this multiple of the identification's
# residual std σ per coordinate (the card's uncertainty.max_std_mm; --max-std overrides). Inside
# the data error_std ≈ σ (the model's own part ~0.1-0.3 σ); at 2σ that part has grown to √3·σ:
# the residual to expect there is twice what the card's accuracy was validated at
MAX_STD_FACTOR = 2.0
# the predictive covariance's calibration on blocked held-out rows (``calibrate``): the 2σ share
# it asks for (a Gaussian's), and the largest factor on the posterior it takes
COVERAGE = 0.954
KAPPA_MAX = 100.0

__all__ = ["MAX_STD_FACTOR", "ParameterCovariance", "parameter_covariance", "PositionStd", "position_std",
           "residual_variance", "calibrate", "COVERAGE", "KAPPA_MAX"]


@dataclass
class ParameterCovariance:
    covariance: np.ndarray  # [P, P] of θ̂ (rad, mm, rad/Nm as the layout)
    sigma2: float  # residual variance per coordinate, mm²
    dof: float  # 3N − p_eff
    p_eff: float  # effective number of parameters
    posterior: np.ndarray | None = None  # [P, P] σ²·A⁻¹: what is known of each parameter's value
    kappa: float = 1.0  # the posterior's factor from the blocked calibration (``calibrate``)
    calibration: dict | None = None  # what ``calibrate`` found (the card's uncertainty.calibration)

    @property
    def predictive(self) -> np.ndarray:
        """[P, P] the covariance error_std propagates: κ·σ²·A⁻¹ (module text)."""
        return self.kappa * (self.posterior if self.posterior is not None else self.covariance)

    @property
    def std(self) -> np.ndarray:
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))

    @property
    def posterior_std(self) -> np.ndarray:
        """How well the data (with the weak prior) knows each parameter's own value: √diag(σ²A⁻¹).
        ≈ ``std`` where the data determines the parameter; where it fixes only a sum with others
        (the prior splits it) ``std`` is ~0 — the split does not vary with the noise — while this
        stays near the prior's scale: the value itself is not known."""
        return np.sqrt(np.clip(np.diag(self.posterior), 0.0, None))


@dataclass
class PositionStd:
    total: np.ndarray  # [N] mm: std of a coordinate of E − Ê (unexplained + model)
    model: np.ndarray  # [N] mm: the model's part, √(tr(J C Jᵀ)/3)
    per_axis: np.ndarray  # [N, 3] mm: std of X, Y, Z of E − Ê


def _jac(model: KinematicModel, q: torch.Tensor, signs: torch.Tensor) -> np.ndarray:
    with torch.no_grad():
        tau = model.module_.torques(q, getattr(model, "train_load_", None))  # (the rows' loads)
        _, jac, _ = jacobian(model.arm_, model.layout_, torch.as_tensor(model.theta_), q, signs, tau)
    return jac.numpy()  # [N, 3, P]


def parameter_covariance(model: KinematicModel, residual: np.ndarray | None = None) -> ParameterCovariance:
    """The covariance of the identified parameters from the Jacobian at the solution and the
    training residuals (see the module docstring). ``model`` is a fitted KinematicModel;
    ``residual`` [N, 3] mm: what it leaves at its training rows (those the fit kept) evaluated
    at the IK of their poses, as the graph does (None: ``train_residual_``, the same unless the
    fit had the data's joint angles)."""
    q = torch.as_tensor(model.train_q_)
    s = torch.as_tensor(model.train_signs_)
    jac = _jac(model, q, s).reshape(-1, len(model.theta_))
    with torch.no_grad():
        tau = model.module_.torques(q, getattr(model, "train_load_", None))  # (the rows' loads)
    scale = model._prior_scales(model.layout_, tau)  # each parameter's typical size
    w = model.prior_ / scale**2  # the fit's prior curvature
    jtj = jac.T @ jac
    # A⁻¹ in the parameters' own scales: A's raw entries span ~30 decades (mm vs rad/Nm), where a
    # pseudo-inverse would drop the directions only the prior holds, as if they had no variance
    a_scaled = scale[:, None] * (jtj + np.diag(w)) * scale[None, :]
    a_inv = scale[:, None] * np.linalg.inv(a_scaled) * scale[None, :]
    p_eff = float(np.trace(a_inv @ jtj))
    r = np.asarray(model.train_residual_ if residual is None else residual, float).reshape(-1)
    if len(r) != jac.shape[0]:
        raise ValueError(f"residual has {len(r)} coordinates, the fit's rows {jac.shape[0]}")
    dof = max(len(r) - p_eff, 1.0)
    sigma2 = float(r @ r) / dof
    cov = ParameterCovariance(sigma2 * a_inv @ jtj @ a_inv, sigma2, dof, p_eff, sigma2 * a_inv)
    blocked = getattr(model, "blocked_", None)
    if blocked is not None:
        cov.kappa, cov.calibration = calibrate(blocked, sigma2)
    return cov


def _coverage(e: np.ndarray, var: np.ndarray) -> float:
    """Share of the coordinates ``e`` [N, 3] within 2σ, σ² = ``var`` [N]."""
    return float((np.abs(e) <= 2.0 * np.sqrt(var)[:, None]).mean())


def calibrate(blocked, sigma2: float) -> tuple[float, dict]:
    """κ ≥ 1 of the predictive covariance κ·σ²·A⁻¹ from the blocked held-out rows
    (``blocked.Evaluation``: each row's residual where the model fitted without its joint-space
    region predicted it, and the model part of its variance then, per σ²): the least κ with which
    σ² + κ·σ²·v covers COVERAGE of those residual coordinates within 2σ, at most KAPPA_MAX (1
    where σ² alone covers them). The rows another region's fit extrapolates to are what error_std
    must hold at targets away from the data; random held-out rows would only ask for σ."""
    e, v = blocked.residual[:, :3], blocked.variance
    before = _coverage(e, sigma2 * (1.0 + v))
    kappa = 1.0
    if before < COVERAGE and _coverage(e, sigma2 * (1.0 + KAPPA_MAX * v)) >= COVERAGE:
        lo, hi = 1.0, KAPPA_MAX
        for _ in range(40):  # (the coverage grows with κ)
            mid = math.sqrt(lo * hi)
            lo, hi = (mid, hi) if _coverage(e, sigma2 * (1.0 + mid * v)) < COVERAGE else (lo, mid)
        kappa = hi
    elif before < COVERAGE:
        kappa = KAPPA_MAX
    after = _coverage(e, sigma2 * (1.0 + kappa * v))
    return kappa, {"kappa": round(kappa, 4), "blocked_rows": int(len(e)),
                   "blocked_2sigma_coverage_before": round(before, 4), "blocked_2sigma_coverage": round(after, 4)}


def position_std(model: KinematicModel, poses: np.ndarray, previous: np.ndarray | None = None,
                 covariance: ParameterCovariance | None = None) -> PositionStd:
    """Per target [N, 6] (and the pose visited before each, as ``model.predict`` takes it), the
    std of the residual a compensation leaves (mm; see the module docstring)."""
    cov = covariance or parameter_covariance(model)
    pose = torch.as_tensor(np.asarray(poses, dtype=np.float64).reshape(-1, 6))
    with torch.no_grad():
        q = model.ik_(pose)
        signs = torch.zeros_like(q)
        if model.use_previous_ and previous is not None:
            prev = torch.as_tensor(np.asarray(previous, dtype=np.float64).reshape(-1, 6))
            signs = approach_signs(model.ik_, model.arm_.home_q, q, pose, prev)
    jac = _jac(model, q, signs)  # [N, 3, P]
    var_model = residual_variance(torch.as_tensor(jac), torch.as_tensor(cov.predictive), 0.0).numpy()
    per_axis = np.sqrt(cov.sigma2 + var_model)
    return PositionStd(np.sqrt((per_axis**2).mean(axis=1)), np.sqrt(var_model.mean(axis=1)), per_axis)

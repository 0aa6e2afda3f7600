"""Real laser-tracker data: registration and simple error predictors on IPA Series C.

    python benchmarks/real_data.py [--data DIR] [--file Series_C/measurements_random_poses.csv]
        [--seed 0] [--val-fraction 0.2] [--only gp-pose,kin+gp,...]

DIR is $POSTPROC_IPA_DATA, default /work/shared/datasets/ipa-robot-accuracy (the IPA
robot-accuracy data: a UR10 measured with a laser tracker, Landgraf et al., IEEE CASE 2021,
MIT licence; not shipped: samples/ipa/ holds a 150-row excerpt).

Protocol: the file is read with postproc.measurements.datasets.read_ipa (the converter behind `postproc
import ipa`); the rows are split 80 / 20 by postproc.model.training.data.split_indices(n, 0.2, seed=0)
(numpy default_rng(0).permutation; the first 20 % held out), the split `postproc train
--val-fraction 0.2` makes. The tracker → base rigid transform is fitted on the training rows
only (postproc.core.registration.register_measurements), E = P_goal − P_measured. Every predictor
is fitted on the training rows and scored on the held-out rows: mean / max of |E − Ê| mm.

Predictors:
  gp-pose     Gaussian process (ARD RBF kernel shared by Ex, Ey, Ez; hyper-parameters by
              maximum marginal likelihood on 3 subsets of 800 training rows, the best on all
              training rows kept; posterior on all) on X,Y,Z,A,B,C
  gp-joints   the same on sin, cos of the six joint angles
  mlp-pose    torch MLP 6-64-64-3 (tanh, Adam, 3000 full-batch epochs) on X,Y,Z,A,B,C
  mlp-joints  the same on sin, cos of the joint angles
  kin         kinematic identification: UR10 DH deviations (24), probe offset (3), base
              pose (6) and gravity compliance of joints 2-4 (6) by scipy least_squares
  kin+gp      kin, then gp-joints on its residual (its time excludes kin's fit)
  kin+mlp     kin, then mlp-joints on its residual (likewise)
Single thread (torch.set_num_threads(1); OMP/OpenBLAS/MKL_NUM_THREADS default to 1).
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core for numpy's BLAS too; must precede the numpy import

import numpy as np  # noqa: E402
from scipy.linalg import cho_factor, cho_solve  # noqa: E402
from scipy.optimize import least_squares, minimize  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402

from postproc.measurements.datasets import read_ipa  # noqa: E402
from postproc.core.frames import rotation_from_abc  # noqa: E402
from postproc.core.registration import register_measurements  # noqa: E402
from postproc.model.training.data import split_indices  # noqa: E402

DEFAULT_DATA = "/work/shared/datasets/ipa-robot-accuracy"
SERIES_C = "Series_C/measurements_random_poses.csv"

# UR10 (CB3) nominal standard DH parameters, public datasheet: mm, rad
UR10_D = np.array([127.3, 0.0, 0.0, 163.941, 115.7, 92.2])
UR10_A = np.array([0.0, -612.0, -572.3, 0.0, 0.0, 0.0])
UR10_ALPHA = np.array([np.pi / 2, 0.0, 0.0, np.pi / 2, -np.pi / 2, 0.0])
# The T-Mac probe's TCP on the flange: Trafo_TM_F_init.txt is the flange in the probe's frame,
# its inverse puts the TCP at (0.0004, 0, 109.0) mm: 109 mm along the flange's z axis.
PROBE_TCP = np.array([0.0, 0.0, 109.0])
# ROS's base_link (the frame of the Goal poses) is the DH base turned 180° about z
BASE_LINK = np.diag([-1.0, -1.0, 1.0])


# --------------------------------------------------------------------------- kinematics
N_KIN = 39  # dθ 6, dd 6, da 6, dα 6, probe 3, base rotation vector 3, base translation 3, compliance 6
# typical size of each parameter: rad for angles, mm for lengths, rad per unit cos for compliance
KIN_SCALE = np.r_[np.full(6, 1e-3), np.ones(12), np.full(6, 1e-3), np.ones(3), np.full(3, 1e-3), np.ones(3), np.full(6, 1e-3)]


def ur10_tcp(q: np.ndarray, p: np.ndarray | None = None) -> np.ndarray:
    """[N, 6] joint angles (rad) → [N, 3] probe TCP (mm) in base_link, with deviations ``p``.

    p = 0 is the nominal robot. The compliance terms turn joints 2-4 in proportion to the
    cosines of the link angles, i.e. to the gravity torques on them.
    """
    p = np.zeros(N_KIN) if p is None else p
    d_theta, d_d, d_a, d_alpha = p[0:6], p[6:12], p[12:18], p[18:24]
    probe, base_w, base_t, k = PROBE_TCP + p[24:27], p[27:30], p[30:33], p[33:39]
    c2, c23, c234 = np.cos(q[:, 1]), np.cos(q[:, 1] + q[:, 2]), np.cos(q[:, 1] + q[:, 2] + q[:, 3])
    theta = q + d_theta
    theta[:, 1] += k[0] * c2 + k[1] * c23 + k[2] * c234
    theta[:, 2] += k[3] * c23 + k[4] * c234
    theta[:, 3] += k[5] * c234
    d, a, alpha = UR10_D + d_d, UR10_A + d_a, UR10_ALPHA + d_alpha
    n = len(q)
    rot = np.broadcast_to(Rotation.from_rotvec(base_w).as_matrix() @ BASE_LINK, (n, 3, 3))
    pos = np.broadcast_to(base_t, (n, 3))
    for i in range(6):  # six joints; every pose at once
        ct, st = np.cos(theta[:, i]), np.sin(theta[:, i])
        ca, sa = np.cos(alpha[i]), np.sin(alpha[i])
        link = np.empty((n, 3, 3))
        link[:, 0] = np.stack([ct, -st * ca, st * sa], axis=1)
        link[:, 1] = np.stack([st, ct * ca, -ct * sa], axis=1)
        link[:, 2] = np.stack([np.zeros(n), np.full(n, sa), np.full(n, ca)], axis=1)
        offset = np.stack([a[i] * ct, a[i] * st, np.full(n, d[i])], axis=1)
        pos = pos + (rot @ offset[:, :, None])[:, :, 0]
        rot = rot @ link
    return pos + rot @ probe


def fit_kinematics(q: np.ndarray, measured: np.ndarray, damping: float = 1e-3) -> np.ndarray:
    """Deviations p minimising |ur10_tcp(q, p) − measured|² (+ a small ridge for redundant ones)."""

    def residual(p: np.ndarray) -> np.ndarray:
        return np.r_[(ur10_tcp(q, p) - measured).ravel(), damping * p / KIN_SCALE]

    return least_squares(residual, np.zeros(N_KIN), x_scale=KIN_SCALE, method="trf").x


# --------------------------------------------------------------------------- GP
class GaussianProcess:
    """Exact GP regression, ARD RBF kernel + white noise, one kernel for all outputs.

    Hyper-parameters: maximum marginal likelihood (L-BFGS-B, analytic gradient) on
    ``restarts`` random subsets of ``n_opt`` training rows (an O(n³) step per iteration that
    the full set would make ~30× slower); the candidate with the best marginal likelihood on
    *all* training rows wins (the subsets land in different local optima).
    """

    def __init__(self, n_opt: int = 800, restarts: int = 3, seed: int = 0):
        self.n_opt, self.restarts, self.seed = n_opt, restarts, seed

    def fit(self, x: np.ndarray, y: np.ndarray) -> GaussianProcess:
        self.x_mu_, self.x_sd_ = x.mean(0), x.std(0) + 1e-12
        self.y_mu_, self.y_sd_ = y.mean(0), y.std()
        x, y = (x - self.x_mu_) / self.x_sd_, (y - self.y_mu_) / self.y_sd_
        dim, best = x.shape[1], None
        for r in range(self.restarts):
            rows = np.random.default_rng(self.seed + r).permutation(len(x))[: self.n_opt]
            res = minimize(
                self._nll,
                np.r_[np.zeros(dim), 0.0, np.log(0.05)],
                args=(x[rows], y[rows]),
                jac=True,
                method="L-BFGS-B",
                bounds=[(-4.0, 5.0)] * dim + [(-5.0, 5.0), (-12.0, 1.0)],
            )
            self.log_params_ = res.x
            chol = cho_factor(self._kernel(x, x) + (np.exp(res.x[-1]) + 1e-8) * np.eye(len(x)), lower=True)
            alpha = cho_solve(chol, y)
            nll = 0.5 * (y * alpha).sum() + y.shape[1] * np.log(np.diag(chol[0])).sum()
            if best is None or nll < best[0]:
                best = (nll, res.x, alpha)
        _, self.log_params_, self.alpha_ = best
        self.x_ = x
        return self

    def _kernel(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        ell, sf2 = np.exp(self.log_params_[:-2]), np.exp(self.log_params_[-2])
        a, b = a / ell, b / ell
        sq = (a**2).sum(1)[:, None] + (b**2).sum(1)[None, :] - 2.0 * a @ b.T
        return sf2 * np.exp(-0.5 * np.maximum(sq, 0.0))

    @staticmethod
    def _nll(p: np.ndarray, x: np.ndarray, y: np.ndarray) -> tuple[float, np.ndarray]:
        """Negative log marginal likelihood summed over outputs and its gradient in log params."""
        dim, m = x.shape[1], y.shape[1]
        ell, sf2, sn2 = np.exp(p[:dim]), np.exp(p[dim]), np.exp(p[dim + 1])
        sq = (x[:, None, :] - x[None, :, :]) ** 2  # [n, n, dim]
        kf = sf2 * np.exp(-0.5 * (sq / ell**2).sum(-1))
        chol = cho_factor(kf + (sn2 + 1e-8) * np.eye(len(x)), lower=True)
        alpha = cho_solve(chol, y)
        w = m * cho_solve(chol, np.eye(len(x))) - alpha @ alpha.T  # d nll = ½ tr(w dK)
        wk = w * kf
        grad = np.r_[0.5 * np.einsum("ij,ijk->k", wk, sq) / ell**2, 0.5 * wk.sum(), 0.5 * np.trace(w) * sn2]
        value = 0.5 * (y * alpha).sum() + m * np.log(np.diag(chol[0])).sum()
        return value, grad

    def predict(self, x: np.ndarray) -> np.ndarray:
        return self._kernel((x - self.x_mu_) / self.x_sd_, self.x_) @ self.alpha_ * self.y_sd_ + self.y_mu_


# --------------------------------------------------------------------------- MLP
def fit_mlp(x: np.ndarray, y: np.ndarray, hidden: int = 64, epochs: int = 3000, lr: float = 3e-3, seed: int = 0):
    """A 2-hidden-layer tanh MLP, full-batch Adam with cosine decay; returns a predict function."""
    import torch

    torch.manual_seed(seed)
    x_mu, x_sd, y_mu, y_sd = x.mean(0), x.std(0) + 1e-12, y.mean(0), y.std(0)
    xt = torch.tensor((x - x_mu) / x_sd, dtype=torch.float32)
    yt = torch.tensor((y - y_mu) / y_sd, dtype=torch.float32)
    net = torch.nn.Sequential(
        torch.nn.Linear(x.shape[1], hidden),
        torch.nn.Tanh(),
        torch.nn.Linear(hidden, hidden),
        torch.nn.Tanh(),
        torch.nn.Linear(hidden, y.shape[1]),
    )
    opt = torch.optim.Adam(net.parameters(), lr=lr)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, epochs)
    for _ in range(epochs):
        opt.zero_grad()
        loss = torch.mean((net(xt) - yt) ** 2)
        loss.backward()
        opt.step()
        sched.step()

    def predict(xs: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            out = net(torch.tensor((xs - x_mu) / x_sd, dtype=torch.float32)).numpy()
        return out * y_sd + y_mu

    return predict


# --------------------------------------------------------------------------- main
def _stats(v: np.ndarray) -> str:
    n = np.linalg.norm(v, axis=1)
    return f"mean {n.mean():6.3f}  median {np.median(n):6.3f}  max {n.max():6.3f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", default=os.environ.get("POSTPROC_IPA_DATA", DEFAULT_DATA))
    ap.add_argument("--file", default=SERIES_C, help="measurement file inside --data")
    ap.add_argument("--seed", type=int, default=0, help="split seed (default 0)")
    ap.add_argument("--val-fraction", type=float, default=0.2)
    ap.add_argument("--only", default="", help="comma-separated predictor names (default all)")
    args = ap.parse_args()
    data_file = Path(args.data) / args.file
    if not data_file.is_file():  # the data set is not shipped: say where to get it, no traceback
        sys.exit(f"real_data.py: {data_file} not found. This benchmark needs the IPA robot-accuracy data set "
                 "(Landgraf et al. 2021, MIT; not shipped, samples/ipa/ holds a 150-row excerpt): download it and "
                 "give its folder with --data DIR or $POSTPROC_IPA_DATA.")
    import torch

    torch.set_num_threads(1)
    start = time.perf_counter()

    series = read_ipa(Path(args.data) / args.file)
    n = len(series)
    train_idx, val_idx = split_indices(n, args.val_fraction, args.seed)
    train = np.zeros(n, dtype=bool)
    train[train_idx] = True
    goal = series.commanded[:, :3]
    q = np.radians(series.joints)
    print(f"{args.file}: {n} poses, {train.sum()} training / {len(val_idx)} held out (split seed {args.seed})")

    # conventions: the Goal is the probe TCP in base_link; the measured angles are intrinsic XYZ
    nominal = np.linalg.norm(ur10_tcp(q) - goal, axis=1)
    print(f"nominal UR10 FK(joints) + probe 109 mm vs Goal: mean {nominal.mean():.3f} max {nominal.max():.3f} mm")
    measured, transform, rms = register_measurements(goal, series.measured, train)
    if series.measured_rotation is not None:
        goal_rot = rotation_from_abc(series.commanded[:, 3:])
        rel = Rotation.from_matrix(np.swapaxes(goal_rot, 1, 2) @ transform[:3, :3] @ series.measured_rotation)
        spread = np.degrees(np.linalg.norm((rel * rel.mean().inv()).as_rotvec(), axis=1))
        print(f"probe orientation vs Goal after registration: spread mean {spread.mean():.3f} max {spread.max():.3f} deg")
    print(f"registration (training rows): rms {rms:.3f} mm, tracker → base rotation "
          f"{np.degrees(Rotation.from_matrix(transform[:3, :3]).magnitude()):.2f} deg, "
          f"translation {np.round(transform[:3, 3], 1).tolist()} mm")
    error = goal - measured
    print(f"uncompensated |E| training: {_stats(error[train])}")
    print(f"uncompensated |E| held out: {_stats(error[val_idx])}")
    print(f"registration + setup: {time.perf_counter() - start:.1f} s")

    pose = series.commanded
    joints_sc = np.c_[np.sin(q), np.cos(q)]
    kin: dict[str, np.ndarray] = {}

    def kinematic() -> np.ndarray:
        if "fit" not in kin:
            kin["fit"] = goal - ur10_tcp(q, fit_kinematics(q[train], measured[train]))
        return kin["fit"]

    def residual_then(model):
        base = kinematic()
        return base[val_idx] + model(joints_sc[train], (error - base)[train], joints_sc[val_idx])

    def gp(x, y, xs):
        return GaussianProcess().fit(x, y).predict(xs)

    def mlp(x, y, xs):
        return fit_mlp(x, y)(xs)

    predictors = {
        "gp-pose": lambda: gp(pose[train], error[train], pose[val_idx]),
        "gp-joints": lambda: gp(joints_sc[train], error[train], joints_sc[val_idx]),
        "mlp-pose": lambda: mlp(pose[train], error[train], pose[val_idx]),
        "mlp-joints": lambda: mlp(joints_sc[train], error[train], joints_sc[val_idx]),
        "kin": lambda: kinematic()[val_idx],
        "kin+gp": lambda: residual_then(gp),
        "kin+mlp": lambda: residual_then(mlp),
    }
    chosen = [s for s in args.only.split(",") if s] or list(predictors)
    print(f"\nheld-out |E − Ê| (mm), fitted on the training rows    {'':>4}time")
    for name in chosen:
        t0 = time.perf_counter()
        predicted = predictors[name]()
        print(f"  {name:<11} {_stats(error[val_idx] - predicted)}  {time.perf_counter() - t0:6.1f} s")
    print(f"total {time.perf_counter() - start:.1f} s (one thread)")


if __name__ == "__main__":
    main()

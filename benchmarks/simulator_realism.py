"""Is the simulated robot realistic? Pose-only [20,10,5] network residual vs the paper's.

Hu, Hua & Tian train a [20, 10, 5] ReLU network on 1900 measured poses (pose input only) and
leave ~0.2–0.25 mm mean error on 100 held-out targets. A simulator on which a pose-only
network reaches ~0.01 mm teaches nothing; one where it cannot get below ~0.5 mm is not
the paper's robot. Per simulated robot this prints:

* before: Table 2 of the 100 held-out targets, uncompensated (measured);
* pose-only: |E_measured − Ê| on the 100 held-out targets, and Table 2 after commanding
  them compensated (c = P + Ê(P)) through the simulator;
* floors: the mean error that would remain if the smooth static error were known exactly
  (backlash + gear mesh ripple + noise), if backlash were known too (ripple + noise), and
  noise alone: what better models (approach-direction / joint-space features) can reach;
* identification: a model that knows the error's structure but not its values (linearised
  least squares on the nominal model: joint placements, tool, base, zero offsets, backlash ×
  approach sign, compliance × gravity torque, ripple sin/cos of the known gear orders) fitted
  on the same 1900 rows: the proof that ≤ 0.10 mm is reachable on these robots.

The network is postproc.model.training.ErrorModel (GPSO initial weights + backprop, the method)
when that package is importable, else a plain torch MLP [20,10,5] trained with Adam on
standardised inputs/outputs, full batch. torch.set_num_threads(1). Several training seeds
per robot, because one training run can land in a poor local minimum.

    python benchmarks/simulator_realism.py                      # default robot, 3 training seeds
    python benchmarks/simulator_realism.py --robot-seeds default 1 2 3 --train-seeds 0
    python benchmarks/simulator_realism.py --adam               # the plain torch MLP
"""
from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from postproc.calibration.planning import latin_hypercube
from postproc.robot.description import load_description
from postproc.robot.kinematics.chain import Chain
from postproc.calibration.simulator import SimulatedRobot
from postproc.robot.approach import approach_signs
from postproc.core.frames import small_transform
from postproc.core.stats import table2


def adam_mlp(poses: np.ndarray, errors: np.ndarray, seed: int, epochs: int = 3000):
    """Plain [20,10,5] ReLU MLP, Adam (cosine-annealed lr), standardised data, full batch."""
    torch.manual_seed(seed)
    xm, xs, ym, ys = poses.mean(0), poses.std(0), errors.mean(0), errors.std(0)
    x = torch.tensor((poses - xm) / xs, dtype=torch.float32)
    y = torch.tensor((errors - ym) / ys, dtype=torch.float32)
    sizes = [6, 20, 10, 5]
    layers: list[torch.nn.Module] = []
    for a, b in zip(sizes[:-1], sizes[1:]):
        layers += [torch.nn.Linear(a, b), torch.nn.ReLU()]
    net = torch.nn.Sequential(*layers, torch.nn.Linear(5, 3))
    opt = torch.optim.Adam(net.parameters(), lr=1e-2)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, epochs)
    for _ in range(epochs):
        opt.zero_grad()
        loss = ((net(x) - y) ** 2).mean()
        loss.backward()
        opt.step()
        sched.step()

    def predict(p: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            return net(torch.tensor((p - xm) / xs, dtype=torch.float32)).numpy() * ys + ym

    return predict


def method_mlp(poses: np.ndarray, errors: np.ndarray, seed: int):
    from postproc.model.training import ErrorModel

    return ErrorModel(hidden=(20, 10, 5), method="gpso", seed=seed).fit(poses, errors).predict


def floors(sim: SimulatedRobot, poses: np.ndarray, rng_seed: int) -> dict:
    """Mean error left when parts of the error are known exactly (see the module docstring)."""
    q = sim.joint_angles(poses)
    signs = approach_signs(q, sim.robot.home_q)
    phase = np.radians(q)[:, :, None] * sim.ripple_orders + sim.ripple_phase
    terms = sim.ripple_amp_deg * np.sin(phase)
    smooth_orders = sim.ripple_orders <= 2  # once/twice per turn: smooth over the box
    low, high = terms[..., smooth_orders].sum(-1), terms[..., ~smooth_orders].sum(-1)
    tcp = lambda dq: sim._tcp(q, dq)  # noqa: E731
    smooth = tcp(low + sim.deflection(q))
    with_ripple = tcp(low + high + sim.deflection(q))
    full = tcp(sim._joint_errors(q, signs))
    noise = np.random.default_rng(rng_seed).normal(0.0, sim.noise_mm, full.shape)
    n = lambda v: float(np.linalg.norm(v, axis=1).mean())  # noqa: E731
    return {"backlash+ripple+noise": n(full - smooth + noise), "ripple+noise": n(with_ripple - smooth + noise),
            "noise": n(noise)}


def identification_design(sim: SimulatedRobot, poses: np.ndarray) -> np.ndarray:
    """[3N, P] first-order effect of every error parameter on the TCP position (numerical)."""
    r = sim.robot
    q = sim.joint_angles(poses)
    signs = approach_signs(q, r.home_q)
    qr = np.radians(q)
    nominal = r.chain.transforms(qr)[:, :3, 3]
    eps = 1e-6
    cols = []

    def bump(k: int) -> np.ndarray:
        v = np.zeros(6)
        v[k] = eps
        return small_transform(v[:3], v[3:])

    for j in range(6):  # joint placements
        for k in range(6):
            placements = r.chain.placements.copy()
            placements[j] = placements[j] @ bump(k)
            cols.append((Chain(placements, r.chain.axes, r.chain.end).transforms(qr)[:, :3, 3] - nominal) / eps)
    for k in range(6):  # tool, base
        for chain in (Chain(r.chain.placements, r.chain.axes, r.chain.end @ bump(k)),
                      Chain(r.chain.placements, r.chain.axes, r.chain.end, bump(k))):
            cols.append((chain.transforms(qr)[:, :3, 3] - nominal) / eps)
    tau = r.gravity_torques(q)
    for j in range(6):  # joint-angle errors: zero offset, backlash, compliance, ripple
        dq = np.zeros(6)
        dq[j] = eps
        column = (r.chain.transforms(qr + dq)[:, :3, 3] - nominal) / eps
        features = [np.ones(len(q)), signs[:, j], tau[:, j]]
        for n in sim.ripple_orders:
            features += [np.sin(n * qr[:, j]), np.cos(n * qr[:, j])]
        cols += [column * f[:, None] for f in features]
    return np.stack(cols, axis=-1).reshape(-1, len(cols))


def identification_residual(sim: SimulatedRobot, poses: np.ndarray, errors: np.ndarray, train: slice,
                            test: slice) -> float:
    a = identification_design(sim, poses).reshape(len(poses), 3, -1)
    a_train = a[train].reshape(-1, a.shape[-1])
    scale = np.linalg.norm(a_train, axis=0)
    scale[scale == 0] = 1.0
    theta, *_ = np.linalg.lstsq(a_train / scale, -errors[train].reshape(-1), rcond=1e-10)
    predicted = -(a[test] / scale) @ theta
    return float(np.linalg.norm(errors[test] - predicted, axis=1).mean())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--robot-seeds", nargs="+", default=["default"], help="'default' and/or integers")
    parser.add_argument("--train-seeds", nargs="+", type=int, default=[0, 1, 2])
    parser.add_argument("--plan-seed", type=int, default=11)
    parser.add_argument("--adam", action="store_true", help="plain torch MLP + Adam instead of the method's training")
    args = parser.parse_args()
    torch.set_num_threads(1)
    fit = adam_mlp if args.adam else method_mlp
    if not args.adam:
        try:
            import postproc.model.training.estimator  # noqa: F401
        except ImportError:
            print("postproc.model.training not available: using the plain torch MLP")
            fit = adam_mlp
    description = load_description()
    ws = description.workspace
    poses = latin_hypercube(2000, ws["box"], ws["attitude"], ws["range"], seed=args.plan_seed)
    train, test = slice(0, 1900), slice(1900, 2000)
    print(f"{'adam MLP' if fit is adam_mlp else 'ErrorModel (GPSO + backprop)'} [20,10,5], pose input only; "
          f"plan: LHS seed {args.plan_seed}, 1900 train / 100 held out (visiting order)")
    fmt = lambda s: f"max {s['max']:.3f} min {s['min']:.3f} mean {s['mean']:.3f} std {s['std']:.3f}"  # noqa: E731
    for robot_seed in args.robot_seeds:
        sim = SimulatedRobot(description, None if robot_seed == "default" else int(robot_seed))
        errors = poses[:, :3] - sim.measure(poses, rng_seed=3)
        print(f"\nrobot seed {sim.seed}{' (default)' if sim.is_default else ''}, geometric scale {sim.scale:.2f}")
        print(f"  before (100 held out):  {fmt(table2(np.linalg.norm(errors[test], axis=1)))}")
        print(f"  before (all 2000):      {fmt(table2(np.linalg.norm(errors, axis=1)))}")
        means = []
        for train_seed in args.train_seeds:
            t0 = time.perf_counter()
            predict = fit(poses[train], errors[train], train_seed)
            held = np.linalg.norm(errors[test] - predict(poses[test]), axis=1)
            target = poses[test]
            command = target.copy()
            command[:, :3] += predict(target)
            after = np.linalg.norm(target[:, :3] - sim.measure(command, rng_seed=5), axis=1)
            means.append(held.mean())
            print(f"  pose-only, training seed {train_seed}: held-out |E − Ê| mean {held.mean():.3f} mm; "
                  f"compensated: {fmt(table2(after))} ({time.perf_counter() - t0:.0f} s)")
        print(f"  pose-only residual over training seeds: median {np.median(means):.3f}, best {min(means):.3f} mm")
        f = floors(sim, poses[test], 7)
        print("  floors (mean mm): " + ", ".join(f"{k} {v:.3f}" for k, v in f.items()))
        ident = identification_residual(sim, poses, errors, train, test)
        print(f"  structure-aware identification (linear least squares): held-out |E − Ê| mean {ident:.3f} mm")


if __name__ == "__main__":
    main()

"""``HybridModel``: kinematic identification first, a small network on what it leaves.

    model = HybridModel(load_description("models/kr500.toml"), seed=0).fit(poses, errors, previous)
    model.predict(poses, previous)          # Ê [N, 3] mm
    model.export_onnx("m.onnx", name="cell-3")

fit = :class:`~postproc.model.training.kinematic.KinematicModel` (geometry, compliance, backlash
with the approach direction, gear ripple orders found in the data) on every training row,
then — only if it pays on rows it did not see — an ensemble of small MLPs on the
identified model's residual, with the nominal joint angles (sin, cos) as inputs. The
exported graph is one ONNX model with the contract's inputs: ``pose`` and, when backlash
was identified, ``previous_pose``; the IK of the nominal arm, the identified arm and the
networks are all inside it, so ``compensate`` needs only onnxruntime.
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import torch

from ...core.progress import stages
from ...robot.description import RobotDescription
from ..envelope import joint_arcs, widened_arcs
from .data import envelope_of
from .estimator import Estimator, _one_thread, residual_stats
from .export import onnx_bytes, write_atomic
from .features import inside_ranges, joint_features, previous_poses, wrap_angles
from .kinematic import (
    KinematicErrorModule,
    KinematicModel,
    nominal_digest,
    unseparated_mount,
)

__all__ = ["HybridModel", "HybridModule", "ResidualNet"]

# the residual network is kept only if it lowers the mean residual on rows it did not see by
# at least this fraction (else it would mostly learn the measurement noise)
KEEP_GAIN = 0.03


def learned_ranges(joint_range) -> np.ndarray:
    """[6, 2] rad: the trained joint arcs [6][2] deg (``compensator.joint_arcs``) widened as
    compensate's P301 rule widens them; the graph's learned parts (ripple orders, residual
    nets) hold inside them only."""
    return np.radians(widened_arcs(joint_range))


class ResidualNet(torch.nn.Module):
    """Joint features (sin, cos of q [+ approach signs]) → residual error [N, 3] mm:
    standardise, tanh MLP, unscale."""

    def __init__(self, n_in: int, hidden: tuple[int, ...], x_mean, x_std, y_std):
        super().__init__()
        layers: list[torch.nn.Module] = []
        width = n_in
        for h in hidden:
            layers += [torch.nn.Linear(width, h, dtype=torch.float64), torch.nn.Tanh()]
            width = h
        layers.append(torch.nn.Linear(width, 3, dtype=torch.float64))
        self.net = torch.nn.Sequential(*layers)
        for name, value in (("x_mean", x_mean), ("x_std", x_std), ("y_std", y_std)):
            self.register_buffer(name, torch.as_tensor(np.asarray(value, dtype=np.float64)))

    def forward(self, features: torch.Tensor) -> torch.Tensor:
        return self.net((features - self.x_mean) / self.x_std) * self.y_std


class HybridModule(torch.nn.Module):
    """pose [N, 6] (+ previous_pose [N, 6]) (+ the controller's joints [N, 6] rad) → Ê [N, 3]:
    identified arm + mean of the residual nets.

    ``joint_range`` [6, 2] rad (wrapped, already widened by the envelope's margin): outside it
    the learned parts that do not extrapolate — gear-ripple orders and residual networks —
    are left out, the physical groups (geometry, compliance, backlash) stay."""

    def __init__(self, kinematic: KinematicErrorModule, nets: list[ResidualNet], joint_range: np.ndarray | None = None):
        super().__init__()
        self.kinematic = kinematic
        self.nets = torch.nn.ModuleList(nets)
        rng = np.array([[-4.0, 4.0]] * 6) if joint_range is None else np.asarray(joint_range, dtype=np.float64)
        self.register_buffer("joint_range", torch.as_tensor(rng))
        # the identification's parameter covariance [P, P] and residual variance (mm²): the
        # graph's error_std (training/uncertainty.py); None: the model states no uncertainty
        self.register_buffer("covariance", None)
        self.register_buffer("sigma2", None)
        # what the learned parts explain at the training rows (mm² per coordinate): added to the
        # variance where the graph leaves them out (outside the trained joint arcs)
        self.register_buffer("learned_var", None)

    def set_uncertainty(self, covariance: np.ndarray, sigma2: float, learned_var: float = 0.0) -> "HybridModule":
        """Store the parameter covariance (``uncertainty.parameter_covariance``), the residual
        variance and the learned parts' variance for ``error_std``."""
        self.covariance = torch.as_tensor(np.asarray(covariance, dtype=np.float64))
        self.sigma2 = torch.tensor(float(sigma2), dtype=torch.float64)
        self.learned_var = torch.tensor(float(learned_var), dtype=torch.float64)
        return self

    @property
    def has_uncertainty(self) -> bool:
        return self.covariance is not None

    @property
    def uses_previous(self) -> bool:
        return self.kinematic.use_previous

    @property
    def orientation(self) -> bool:
        """The identified arm's orientation part was fitted on measured orientations."""
        return self.kinematic.orientation

    def error_and_joints(self, pose: torch.Tensor, previous_pose: torch.Tensor | None = None,
                         q_in: torch.Tensor | None = None, tool: torch.Tensor | None = None,
                         rotation: bool = False, approach: torch.Tensor | None = None,
                         q_previous: torch.Tensor | None = None,
                         uncertainty: bool = False, load: torch.Tensor | None = None) -> tuple[torch.Tensor, ...]:
        """(Ê [N, 3], the controller's joint angles q [N, 6] rad) in the dtype of ``pose``;
        ``q_in`` [N, 6] rad picks each row's IK branch (NaN rows: the identified branch);
        ``tool`` [N, 6] each row's TCP on the flange (NaN rows: the model's own). With
        ``rotation``: + r̂ [N, 3] rad, the identified arm's orientation error (the residual nets
        are of the position only). ``approach`` [N, 6] fixes the approach signs (NaN: from
        ``previous_pose``); ``q_previous`` [N, 6] rad the controller's angles at the target
        before (NaN rows: unknown). With ``uncertainty`` (and ``covariance`` set): + the std of
        E − Ê [N, 1] mm last (``uncertainty.error_std``). ``load`` [N, 4]: each row's load (mass
        kg, centre of mass mm on the flange; NaN rows: the reference) for a load-aware model."""
        dtype = pose.dtype
        pose = pose.to(torch.float64)
        prev = previous_pose.to(torch.float64) if previous_pose is not None else None
        q_in = q_in.to(torch.float64) if q_in is not None else None
        tool = tool.to(torch.float64) if tool is not None else None
        approach = approach.to(torch.float64) if approach is not None else None
        q_previous = q_previous.to(torch.float64) if q_previous is not None else None
        error, q, signs, learned, *turned = self.kinematic.parts(
            pose, prev, q_in, self.joint_range, tool, rotation, approach, q_previous,
            (self.covariance, self.sigma2) if uncertainty else None, load=load)
        if len(self.nets):
            features = joint_features(q, signs if self.uses_previous else None)
            error = error + learned[:, None] * torch.stack([net(features) for net in self.nets]).mean(dim=0)
        if uncertainty and self.learned_var is not None:  # where the learned parts are left out, what they explain
            std = turned[-1]
            turned[-1] = torch.sqrt(std * std + (1.0 - learned[:, None]) * self.learned_var)
        return (error.to(dtype), q.to(dtype), *(t.to(dtype) for t in turned))

    def forward(self, pose: torch.Tensor, previous_pose: torch.Tensor | None = None,
                q_in: torch.Tensor | None = None, tool: torch.Tensor | None = None,
                q_previous: torch.Tensor | None = None, load: torch.Tensor | None = None) -> torch.Tensor:
        return self.error_and_joints(pose, previous_pose, q_in, tool, q_previous=q_previous, load=load)[0]

    @property
    def load_aware(self) -> bool:
        """The identified arm's torques take each target's load (the graph's ``load`` input)."""
        return self.kinematic.load_aware


class _WithJoints(torch.nn.Module):
    """The exported graph: inputs ``pose`` [, ``previous_pose``], ``joints`` (deg, NaN rows:
    unknown) [, ``approach`` (with ``previous_pose``: the approach signs compensate settles,
    NaN = from ``previous_pose``)] [, ``tool`` (NaN rows: the model's own)] [,
    ``previous_joints`` (deg, NaN rows: unknown; with ``previous_pose``)] [, ``load`` ([N, 4], NaN
    rows: the reference load; a load-aware model)]; outputs ``error`` and
    ``joints`` (deg, wrapped to [−180, 180)), so that compensate can check the joint ranges of
    the envelope with onnxruntime alone, and, when the orientation was identified from measured
    orientations, ``rotation_error`` (deg), and, with ``uncertainty``, ``error_std`` (mm, last)."""

    def __init__(self, module: HybridModule, tool: bool = False, previous_joints: bool = False,
                 uncertainty: bool = False):
        super().__init__()
        self.module = module
        self.tool = tool
        self.previous_joints = previous_joints and module.uses_previous
        self.uncertainty = uncertainty
        self.load = module.load_aware

    def forward(self, pose: torch.Tensor, *rest: torch.Tensor):
        rest = list(rest)  # (previous_pose,) joints, (approach,) (tool,) (previous_joints,): onnx_bytes' order
        previous_pose = rest.pop(0) if self.module.uses_previous else None
        to_rad = math.pi / 180.0  # (torch.deg2rad has no ONNX export)
        joints = rest.pop(0) * to_rad
        approach = rest.pop(0) if self.module.uses_previous else None
        tool = rest.pop(0) if self.tool else None
        q_previous = rest.pop(0) * to_rad if self.previous_joints else None
        load = rest.pop(0) if self.load else None
        error, q, *turned = self.module.error_and_joints(pose, previous_pose, joints, tool, self.module.orientation,
                                                         approach, q_previous, self.uncertainty, load)
        std = [turned.pop()] if self.uncertainty else []
        return (error, wrap_angles(q) * (180.0 / math.pi), *(t * (180.0 / math.pi) for t in turned), *std)


def _train_net(x: np.ndarray, y: np.ndarray, hidden: tuple[int, ...], epochs: int, seed: int) -> ResidualNet:
    """Full-batch Adam with a cosine-annealed rate on standardised inputs and outputs."""
    gen = torch.Generator().manual_seed(seed)
    x_std = np.where(x.std(0) > 1e-9, x.std(0), 1.0)
    y_std = np.where(y.std(0) > 1e-12, y.std(0), 1.0)
    net = ResidualNet(x.shape[1], hidden, x.mean(0), x_std, y_std)
    with torch.no_grad():  # seeded initialisation (torch's default init draws from the global RNG)
        for layer in net.net:
            if isinstance(layer, torch.nn.Linear):
                bound = 1.0 / math.sqrt(layer.in_features)
                layer.weight.copy_((torch.rand(layer.weight.shape, generator=gen, dtype=torch.float64) * 2 - 1) * bound)
                layer.bias.zero_()
    xt, yt = torch.as_tensor(x), torch.as_tensor(y)
    opt = torch.optim.Adam(net.parameters(), lr=3e-3)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, epochs)
    for _ in range(epochs):
        opt.zero_grad()
        loss = torch.mean(((net(xt) - yt) / net.y_std) ** 2)
        loss.backward()
        opt.step()
        sched.step()
    return net.eval()


class HybridModel(Estimator):
    """Learned positioning error of one robot + tool: identified arm + residual networks.

    Parameters
    ----------
    description: the robot's nominal description (``models/*.toml``); its IK family (KUKA-type
        or UR-type) and the controller's branch are found from the data.
    residual: "auto" (keep the networks only if they help on held-back rows), "always", "none".
    hidden, epochs, ensemble: the residual networks (tanh MLPs, Adam, full batch).
    seed: seeds every random draw.
    kinematic: keyword arguments of :class:`KinematicModel` (groups, max_order, max_ripple, ...).
    """

    def __init__(self, description: RobotDescription, residual: str = "auto", hidden=(32, 32), epochs: int = 1500,
                 ensemble: int = 3, seed: int = 0, kinematic: dict | None = None, progress: bool = False):
        self.description = description
        self.residual = residual
        self.hidden = hidden
        self.epochs = epochs
        self.ensemble = ensemble
        self.seed = seed
        self.kinematic = kinematic
        self.progress = progress

    @property
    def label(self) -> str:
        kin = "kinematic identification"
        nets = f"MLP x{len(getattr(self, 'nets_', []))} ({'-'.join(map(str, self.hidden))}, joint features)"
        if hasattr(self, "kinematic_") and not self.kinematic_.layout_.n:
            return nets
        if getattr(self, "nets_", None):
            return f"{kin} + residual {nets}"
        return f"{kin} (hybrid: residual MLPs tried, not kept)" if self.residual == "auto" else kin

    def fit(self, poses: np.ndarray, errors: np.ndarray, previous: np.ndarray | None = None,
            q_deg: np.ndarray | None = None, tools: np.ndarray | None = None,
            rotation_errors: np.ndarray | None = None, previous_q_deg: np.ndarray | None = None,
            campaigns: np.ndarray | None = None, loads: np.ndarray | None = None) -> "HybridModel":
        """Fit to commanded poses [N, 6], errors E = P − P_measured [N, 3], the pose visited before
        each row [N, 6] (None: visiting order unknown, no backlash), the controller's joint
        angles [N, 6] if the data has them, the TCP on the flange each row was measured with
        [N, 6] (None: the description's tool) and the measured orientation errors [N, 3] deg if
        it has those (``KinematicModel.fit``: then the graph outputs ``rotation_error``; one tool
        only); ``previous_q_deg``: the joint angles of the row visited before (see
        ``KinematicModel.fit``). The first row's tool becomes the model's own (``description_``:
        the description with that tool; the card's ``tool``). ``campaigns`` [N] int: each row's
        measurement campaign, each with its own frame in the identification (``KinematicModel.fit``);
        the model predicts in the first campaign's frame, its rows' errors moved there. ``loads``
        [N, 4]: the load each row was measured with (mass kg, centre of mass mm on the flange): a
        load-aware model (``KinematicModel.fit``; the graph's ``load`` input, the card's ``loads``)."""
        if self.residual not in ("auto", "always", "none"):
            raise ValueError(f"residual must be auto, always or none, not {self.residual!r}")
        poses = np.asarray(poses, dtype=np.float64).reshape(-1, 6)
        errors = np.asarray(errors, dtype=np.float64).reshape(-1, 3)
        names = ["kinematic identification", "residual networks"]
        tools = None if tools is None else np.asarray(tools, dtype=np.float64).reshape(-1, 6)
        self.description_ = self.description if tools is None else self.description.replace(tool=tools[0])
        with _one_thread(), stages(names, "hybrid", self.progress) as stage:
            t0 = time.perf_counter()
            stage(names[0])
            self.kinematic_ = KinematicModel(self.description_, **(self.kinematic or {})).fit(
                poses, errors, previous, q_deg, tools, rotation_errors, previous_q_deg, campaigns=campaigns,
                loads=loads)
            errors = self.kinematic_.to_base(poses, errors, campaigns, q_deg)
            if self.kinematic_.campaign_frames_ is not None:
                rotation_errors = None  # (position only with several campaigns)
            t1 = time.perf_counter()
            stage(names[1])
            self.nets_ = self._fit_residual(self.kinematic_.train_residual_)
            t2 = time.perf_counter()
        arcs = joint_arcs(np.degrees(self.kinematic_.train_q_))  # the trained joints' arcs
        joint_range = [[math.floor(a * 1e3) / 1e3, math.ceil(b * 1e3) / 1e3] for a, b in arcs]
        self._finish(poses, errors, previous, q_deg, joint_range, tools=tools, rotation_errors=rotation_errors,
                     previous_q_deg=previous_q_deg, loads=loads)
        self.fit_seconds_ = {"kinematic": t1 - t0, "residual": t2 - t1, "total": t2 - t0}
        return self

    def _finish(self, poses: np.ndarray, errors: np.ndarray, previous: np.ndarray | None, q_deg: np.ndarray | None,
                joint_range: list, envelope: dict | None = None, tools: np.ndarray | None = None,
                rotation_errors: np.ndarray | None = None, previous_q_deg: np.ndarray | None = None,
                loads: np.ndarray | None = None) -> None:
        """The graph from ``kinematic_`` and ``nets_``, with the trained ``joint_range`` [6][2]
        deg (the learned parts' validity) and the position ``envelope`` (default: of the rows);
        the training figures on the rows the identification kept (each row's ``tools``, and
        the orientation's where it was fitted)."""
        # rows the identification left out (unreachable / singular, ≤ 1 %): the caller names them
        self.dropped_ = self.kinematic_.dropped_
        keep = ~np.isin(np.arange(len(poses)), self.dropped_)
        poses, errors = poses[keep], errors[keep]
        previous = None if previous is None else np.asarray(previous, dtype=np.float64).reshape(-1, 6)[keep]
        q_deg = None if q_deg is None else np.asarray(q_deg, dtype=np.float64).reshape(-1, 6)[keep]
        tools = None if tools is None else tools[keep]
        if previous_q_deg is not None:
            previous_q_deg = np.asarray(previous_q_deg, dtype=np.float64).reshape(-1, 6)[keep]
        loads = None if loads is None else np.asarray(loads, dtype=np.float64).reshape(-1, 4)[keep]
        self.joint_range_ = joint_range
        self.module_ = HybridModule(self.kinematic_.module_, self.nets_, learned_ranges(joint_range)).eval()
        self.envelope_ = envelope_of(poses) if envelope is None else envelope
        self.n_train_ = len(poses)
        fitted = self.predict(poses, previous, q_deg, tools, previous_q_deg, loads=loads)
        self.train_stats_ = residual_stats(errors - fitted)
        # what the identified arm leaves at the rows evaluated as the graph does (at the IK of the
        # poses): the σ of error_std (uncertainty.parameter_covariance's residual)
        arm = (self.predict(poses, previous, q_deg, tools, previous_q_deg, arm_only=True, loads=loads) if self.nets_
               else fitted)
        self.identified_residual_ = errors - arm
        # what the learned parts (ripple orders, residual networks) explain at the training rows,
        # per coordinate: the variance error_std adds where the graph leaves them out
        physical = self.predict(poses, previous, q_deg, tools, previous_q_deg, physical_only=True, loads=loads)
        self.learned_var_ = float(np.mean((fitted - physical) ** 2))
        self.train_rotation_stats_ = None
        if self.orientation:
            rotation_errors = np.asarray(rotation_errors, dtype=np.float64).reshape(-1, 3)[keep]
            self.train_rotation_stats_ = residual_stats(rotation_errors - self.predict_rotation(poses, previous, q_deg))

    @classmethod
    def refitted(cls, description: RobotDescription, kinematic: KinematicModel, nets: list[ResidualNet],
                 hidden: tuple[int, ...], joint_range: list, envelope: dict, poses: np.ndarray, errors: np.ndarray,
                 previous: np.ndarray | None = None, q_deg: np.ndarray | None = None,
                 rotation_errors: np.ndarray | None = None) -> "HybridModel":
        """A model made of a re-fitted identification (:meth:`KinematicModel.refit`) and an older
        model's residual networks, joint ranges and envelope (training/update.py); the training
        figures on the re-fit's rows (the orientation's too where it was re-fitted)."""
        model = cls(description, residual="always" if nets else "none", hidden=hidden)
        model.kinematic_, model.nets_ = kinematic, list(nets)
        model.description_ = kinematic.description  # (the old model's, its tool included)
        poses = np.asarray(poses, dtype=np.float64).reshape(-1, 6)
        errors = np.asarray(errors, dtype=np.float64).reshape(-1, 3)
        model._finish(poses, errors, previous, q_deg, joint_range, envelope, rotation_errors=rotation_errors)
        return model

    def _fit_residual(self, residual: np.ndarray) -> list[ResidualNet]:
        if self.residual == "none" or self.ensemble < 1:
            return []
        km = self.kinematic_
        x = joint_features(torch.as_tensor(km.train_q_),
                           torch.as_tensor(km.train_signs_) if km.use_previous_ else None).numpy()
        self.residual_check_ = None
        if self.residual == "auto":
            # train on 85 % of the rows, compare on the other 15 %: keep only if it pays. The 15 %
            # are whole joint-space regions where the identification has them (its blocked
            # selection's): random rows sit between training rows, where a network that learned
            # this campaign's own rows scores well whether it carries or not. As in the graph,
            # the networks add nothing at held-out rows outside the joint arcs of those fitted
            held, fit_rows = self._held_regions(len(x))
            if len(held) < 10:
                return []
            net = _train_net(x[fit_rows], residual[fit_rows], self.hidden, self.epochs, self.seed)
            q = torch.as_tensor(km.train_q_[held])
            inside = inside_ranges(q, torch.as_tensor(learned_ranges(joint_arcs(np.degrees(km.train_q_[fit_rows])))))
            with torch.no_grad():
                learned = inside[:, None] * net(torch.as_tensor(x[held]))
            after = np.linalg.norm(residual[held] - learned.numpy(), axis=1).mean()
            before = np.linalg.norm(residual[held], axis=1).mean()
            self.residual_check_ = {"before_mm": float(before), "after_mm": float(after),
                                    "held_out": "regions" if km.regions_ is not None else "random rows"}
            if after > (1.0 - KEEP_GAIN) * before:
                return []
        return [_train_net(x, residual, self.hidden, self.epochs, self.seed + 1 + k) for k in range(self.ensemble)]

    def _held_regions(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """(held-out rows, fitted rows) of the residual networks' check: about 15 % of the rows,
        whole regions of the identification's blocked selection (``KinematicModel.regions_``),
        drawn in a seeded order; random rows where it has none."""
        rng = np.random.default_rng(self.seed)
        regions = self.kinematic_.regions_
        if regions is None:
            order = rng.permutation(n)
            return order[: n * 15 // 100], order[n * 15 // 100:]
        held = np.zeros(n, bool)
        for k in rng.permutation(int(regions.max()) + 1):
            if held.sum() >= n * 15 // 100:
                break
            if held.sum() + (regions == k).sum() <= n // 2:  # (never half of the rows)
                held |= regions == k
        return np.flatnonzero(held), np.flatnonzero(~held)

    # ------------------------------------------------------------------ using it
    def _check_fitted(self) -> None:
        if not hasattr(self, "module_"):
            raise RuntimeError("HybridModel is not fitted yet: call fit(poses, errors) first")

    @property
    def uses_previous(self) -> bool:
        self._check_fitted()
        return self.module_.uses_previous

    def predict(self, poses: np.ndarray, previous: np.ndarray | None = None,
                joints: np.ndarray | None = None, tools: np.ndarray | None = None,
                previous_joints: np.ndarray | None = None, arm_only: bool = False,
                physical_only: bool = False, loads: np.ndarray | None = None) -> np.ndarray:
        """Ê [N, 3] mm for poses [N, 6], the poses visited before them (None: unknown), the
        controller's joint angles [N, 6] deg (None / NaN rows: unknown), which pick each row's
        IK branch (as the exported graph's ``joints`` input), and each row's TCP on the flange
        [N, 6] (None / NaN rows: the model's own; the graph's ``tool`` input), the joint angles
        [N, 6] deg at the poses visited before (None / NaN rows: unknown; ``previous_joints``).
        ``arm_only``: the identified arm's part alone (without the residual networks);
        ``physical_only``: its physical groups alone (as outside the trained joint arcs: no ripple
        orders, no networks). ``loads`` [N, 4] (or [4]): each row's load, mass kg and centre of
        mass mm on the flange (None / NaN rows: the reference load; the graph's ``load`` input);
        ignored by a model that is not load-aware."""
        self._check_fitted()
        pose = torch.as_tensor(np.asarray(poses, dtype=np.float64).reshape(-1, 6))
        prev = None if previous is None else torch.as_tensor(np.asarray(previous, dtype=np.float64).reshape(-1, 6))
        q_in = None if joints is None else torch.as_tensor(np.radians(np.asarray(joints, dtype=np.float64).reshape(-1, 6)))
        tool = None if tools is None else torch.as_tensor(np.asarray(tools, dtype=np.float64).reshape(-1, 6))
        q_prev = (None if previous_joints is None
                  else torch.as_tensor(np.radians(np.asarray(previous_joints, dtype=np.float64).reshape(-1, 6))))
        load = (None if loads is None
                else torch.as_tensor(np.broadcast_to(np.asarray(loads, dtype=np.float64), (len(pose), 4)).copy()))
        with torch.no_grad():
            if arm_only or physical_only:
                m = self.module_
                ranges = m.joint_range
                if physical_only:  # (arcs that hold no angle: every row outside)
                    ranges = torch.stack([ranges[:, 0], ranges[:, 0] - 1.0], dim=1)
                return m.kinematic.parts(pose, prev, q_in, ranges, tool, q_previous=q_prev, load=load)[0].numpy()
            return self.module_(pose, prev, q_in, tool, q_prev, load).numpy()

    @property
    def orientation(self) -> bool:
        """The orientation error was identified from measured orientations (the graph outputs
        ``rotation_error``); without them the model claims nothing about orientation."""
        self._check_fitted()
        return self.module_.orientation

    def predict_rotation(self, poses: np.ndarray, previous: np.ndarray | None = None,
                         joints: np.ndarray | None = None) -> np.ndarray:
        """r̂ [N, 3] deg, the orientation error (rotation vector commanded → actual, base frame),
        as the exported ``rotation_error``; arguments as :meth:`predict`."""
        self._check_fitted()
        if not self.orientation:
            raise ValueError("the model was fitted without measured orientations: no rotation error")
        pose = torch.as_tensor(np.asarray(poses, dtype=np.float64).reshape(-1, 6))
        prev = None if previous is None else torch.as_tensor(np.asarray(previous, dtype=np.float64).reshape(-1, 6))
        q_in = None if joints is None else torch.as_tensor(np.radians(np.asarray(joints, dtype=np.float64).reshape(-1, 6)))
        with torch.no_grad():
            return np.degrees(self.module_.error_and_joints(pose, prev, q_in, rotation=True)[2].numpy())

    def predict_at_joints(self, poses: np.ndarray, joints: np.ndarray) -> np.ndarray:
        """Ê [N, 3] with the identified arm evaluated at exactly these joint angles [N, 6] deg
        (no IK, no visiting order): P − FK_identified(q), the classical calibration's figure
        when the data's poses and angles disagree slightly (a planner's numerical IK)."""
        self._check_fitted()
        pose = torch.as_tensor(np.asarray(poses, dtype=np.float64).reshape(-1, 6))
        q = torch.as_tensor(np.radians(np.asarray(joints, dtype=np.float64).reshape(-1, 6)))
        m = self.module_
        with torch.no_grad():
            learned = inside_ranges(q, m.joint_range)
            error = m.kinematic.error_at(q, torch.zeros_like(q), pose[:, :3], learned)
            if len(m.nets):
                features = joint_features(q, torch.zeros_like(q) if m.uses_previous else None)
                error = error + learned[:, None] * torch.stack([net(features) for net in m.nets]).mean(dim=0)
            return error.numpy()

    def fixed_point_iterations(self, poses: np.ndarray, tol_mm: float = 2e-3, most: int = 8) -> int:
        """The fewest iterations k of c = P + Ê(c) (each target coming from its predecessor's
        command, as ``compensate`` runs them) that put 99 % of the commands within ``tol_mm`` of
        the converged ones (``most`` iterations). Each iteration is a model run over the program:
        the model card's ``iterations`` is this, not a safe-looking larger number. (A joint whose
        step to a target is smaller than the correction's change can flip its approach sign from
        one iteration to the next: such rare targets never settle, whatever k; compensate settles
        them on their approach after the k iterations: compensator's module text.)"""
        poses = np.asarray(poses, dtype=np.float64).reshape(-1, 6)
        trial = poses.copy()
        history = []
        for _ in range(most):
            prev = previous_poses(trial) if self.uses_previous else None
            trial[:, :3] = poses[:, :3] + self.predict(trial, prev)
            history.append(trial[:, :3].copy())
        final = history[-1]
        return next(k + 1 for k, c in enumerate(history) if np.quantile(np.abs(c - final).max(axis=1), 0.99) <= tol_mm)

    def describe(self) -> dict:
        """What the fit found: ripple orders, backlash, compliance, residual networks."""
        self._check_fitted()
        km = self.kinematic_
        p = km.parameters()
        return {
            "ripple": [[int(j) + 1, int(n)] for j, n in km.layout_.ripple],
            "backlash_deg": [round(float(v), 5) for v in np.degrees(p["backlash"])] if km.use_previous_ else None,
            "ik_branch": list(km.ik_.branch),
            "ik_family": km.ik_.family,
            "residual_nets": len(self.nets_),
            "residual_check": getattr(self, "residual_check_", None),
            # what the blocked cross-validation chose (physical groups left out, ripple orders kept)
            "selection": getattr(km, "selection_", None),
            # what the orientation part rests on: measured orientations (and the lever, mm/rad, that
            # weighed them against the positions) or nothing (then no rotation_error output)
            "orientation": ({"fitted": True, "lever_mm_per_rad": round(km.lever_, 3),
                             "train_residual_deg": self.train_rotation_stats_} if km.orientation_
                            else {"fitted": False}),
            # the identified parameters (rad, mm, rad/Nm; each group flattened as Layout.unpack
            # reads it, the ripple amplitudes [R][sin, cos] in the order of "ripple"), the
            # torques' mean the graph linearises about and each parameter's std with the fit's
            # residual std per coordinate: what a re-calibration (train --update) starts from
            **self.identified_parameters(),
        }

    def identified_parameters(self) -> dict:
        """The identification as the model card stores it for ``train --update``
        (training/update.py reads it back): parameters, ripple amplitudes, tau_mean,
        parameter_std and residual_std_mm (from the parameter covariance at the solution)."""
        km = self.kinematic_
        if not km.layout_.n:
            return {}
        p, sizes = km.parameters(), km.layout_.sizes
        # (a re-calibration sets its own: OLD's std, the posterior std of what it re-fitted)
        std, residual_std = getattr(self, "identification_std_", (None, None))
        posterior = None
        if std is None:
            cov = self._covariance()
            std, residual_std, posterior = cov.std, math.sqrt(cov.sigma2), cov.posterior_std
        cuts = np.cumsum(list(sizes.values()))[:-1]
        std = dict(zip(sizes, np.split(np.asarray(std, dtype=np.float64), cuts)))
        posterior = None if posterior is None else dict(zip(sizes, np.split(posterior, cuts)))
        groups = [name for name in sizes if name != "ripple" and sizes[name]]
        # (the stds also of the ripple amplitudes, key "ripple", in the order of ripple_amplitudes flattened)
        with_ripple = [name for name in sizes if sizes[name]]
        return {
            "parameters": {name: [float(v) for v in np.ravel(p[name])] for name in groups},
            "ripple_amplitudes": [[float(a), float(b)] for a, b in p["ripple"]],
            "tau_mean": [float(v) for v in km.module_.tau_mean],
            "parameter_std": {name: [float(v) if v == v else None for v in std[name]] for name in with_ripple},  # None: unknown
            # what is known of each value (the certificate's uncertainty; not for a re-calibration)
            **({"parameter_posterior_std": {name: [float(v) for v in posterior[name]] for name in with_ripple}}
               if posterior is not None else {}),
            "residual_std_mm": float(residual_std),
            "nominal_sha256": nominal_digest(self.description),
        }

    def tool_card(self, name: str) -> dict:
        """The model card's ``tool``: the model's own TCP (``frame``, the one NaN rows of the
        ``tool`` input take), the TCPs of the data (``measured``) and what they identify of the
        tool mount: ``unseparated`` = the directions (flange frame) of its rotation the data
        cannot tell from a shift (compensate warns, P319, where another TCP's lever arm makes
        them matter); ``valid`` says it in words."""
        self._check_fitted()
        own = [round(float(v), 6) for v in self.description_.tool]
        card = {"name": name, "frame": own}
        km = self.kinematic_
        measured = km.tools_ if km.tools_ is not None else np.asarray([own])
        card["measured"] = [[round(float(v), 6) for v in t] for t in measured]
        if not km.layout_.n:
            card["valid"] = "the measured tool only (networks on the joint angles: no physical model to carry a tool)"
            return card
        apart = unseparated_mount(measured[:, :3])
        card["unseparated"] = [[round(float(v), 6) for v in u] for u in apart]
        if len(apart) == 3:
            card["valid"] = ("any tool; measured with one tool: its offset is carried to other tools as a shift fixed "
                             "to the flange, the mount's rotation is not separated (calibrate with two or three "
                             "tools for tool independence)")
        elif len(apart):
            card["valid"] = ("any tool; the mount's rotation is identified except about the line through the "
                             "measured TCPs (a third tool off that line separates it)")
        else:
            card["valid"] = "any tool; the tool mount's rotation is identified (three or more TCPs not on a line)"
        return card

    def card(self, **metadata) -> dict:
        """The model card ``export_onnx`` writes: ``metadata`` over this model's method,
        structure, envelope (+ joint ranges), iterations 2 and (an identification fitted here)
        uncertainty."""
        self._check_fitted()
        envelope = dict(self.envelope_)
        envelope["joints"] = self.joint_range_
        meta = {"method": self.label, "structure": self.structure, "envelope": envelope, "iterations": 2}
        loads = self.loads_card()
        if loads is not None:
            meta["loads"] = loads
        if self._uncertainty():
            from .uncertainty import MAX_STD_FACTOR

            sigma = math.sqrt(float(self.module_.sigma2))
            meta["uncertainty"] = {"max_std_mm": round(MAX_STD_FACTOR * sigma, 6), "residual_std_mm": round(sigma, 6),
                                   "max_std_rule": f"{MAX_STD_FACTOR:g} x residual_std_mm"}
            learned = self.module_.learned_var
            if learned is not None:  # (models whose error_std adds what the learned parts explain outside their arcs)
                meta["uncertainty"]["learned_std_mm"] = round(math.sqrt(float(learned)), 6)
            if getattr(self, "days_var_", 0.0) > 0:
                meta["uncertainty"]["other_days_std_mm"] = round(math.sqrt(self.days_var_), 6)
                meta["uncertainty"]["other_days_rule"] = (
                    "residual_std_mm is the larger of the training rows' and other_days_std_mm: each campaign "
                    "predicted by the model of the others, after its own rigid fit")
            if getattr(self, "uncertainty_calibration_", None):
                meta["uncertainty"]["calibration"] = self.uncertainty_calibration_
        meta.update(metadata)
        return meta

    def export_onnx(self, path: str | Path, **metadata) -> Path:
        """Write the fitted model as one contract ONNX file (atomically) with ``card(**metadata)``."""
        meta = self.card(**metadata)
        std = self._uncertainty()
        # the tool input where the error is the identified arm's (a physical model); the residual
        # networks alone (dnn-joints) learned one TCP's error and keep P304 for the others
        tool = bool(self.kinematic_.layout_.n)
        # with backlash: the controller's angles at the target before (a turn or configuration
        # change between targets is a motion their poses alone do not show)
        graph = _WithJoints(self.module_, tool, previous_joints=True, uncertainty=std)
        return write_atomic(path, onnx_bytes(graph, meta, self.uses_previous, joints=True, joints_input=True,
                                             approach_input=self.uses_previous, tool_input=tool,
                                             previous_joints_input=graph.previous_joints, rotation=self.orientation,
                                             std=std, load_input=graph.load))

    def loads_card(self) -> dict | None:
        """The card's ``loads`` of a load-aware model (the data's loads: ``measured``, ``rows``,
        ``reference``, ``extrapolate``), None for one fitted without loads."""
        km = self.kinematic_
        if getattr(km, "load_reference_", None) is None or not km.layout_.n:
            return None
        from .features import LOAD_EXTRAPOLATE

        # (one mass measured: the compliance is seen under that load only, the arm's own share not
        # told from the load's; benchmarks/loads.py: 6-9x the error at other loads; held to it)
        several = len(np.unique(km.measured_loads_[:, 0])) > 1
        return {**km.measured_card_,
                "reference": [round(float(v), 6) for v in km.load_reference_],
                "extrapolate": LOAD_EXTRAPOLATE if several else 1.0, "aware": True}

    def _uncertainty(self) -> bool:
        """Put the identification's parameter covariance into the graph (output ``error_std``):
        for an identified arm fitted here; a re-calibration (``train --update``, whose
        ``identification_std_`` comes from the older model) and the networks alone state none."""
        if self.module_.has_uncertainty:
            return True
        if not self.kinematic_.layout_.n or hasattr(self, "identification_std_"):
            return False
        cov = self._covariance()
        self.uncertainty_calibration_ = cov.calibration
        # (data of several campaigns: what a campaign left out of the fit leaves, where larger — ``days_var_``)
        sigma2 = max(cov.sigma2, getattr(self, "days_var_", 0.0))
        self.module_.set_uncertainty(cov.predictive, sigma2, getattr(self, "learned_var_", 0.0))
        return True

    def _covariance(self):
        """The identification's ``uncertainty.ParameterCovariance``, its σ from the residual the
        identified arm leaves at the training rows as the graph evaluates it."""
        from .uncertainty import parameter_covariance

        return parameter_covariance(self.kinematic_, getattr(self, "identified_residual_", None))

    @property
    def structure(self) -> str:
        km = self.kinematic_
        parts = [f"{km.layout_.n} kinematic parameters ({', '.join(km.layout_.groups)}, "
                 f"{len(km.layout_.ripple)} ripple orders)", f"IK {km.ik_.family} branch {list(km.ik_.branch)}"]
        if km.orientation_:
            parts.append(f"orientation fitted with the position (lever {km.lever_:.0f} mm/rad; output rotation_error)")
        if self.nets_:
            n_in = 18 if self.uses_previous else 12
            inputs = "sin/cos q, approach signs" if self.uses_previous else "sin/cos q"
            parts.append(f"{len(self.nets_)} x MLP {n_in}-{'-'.join(map(str, self.hidden))}-3 on {inputs}")
        return "; ".join(parts)


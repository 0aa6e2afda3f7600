"""The "physical" robot and the laser tracker: the nominal robot + seeded, documented errors.

A command (TCP pose, robot base frame) goes through the controller's IK on the *nominal*
model (:meth:`postproc.robot.arm.Robot.ik`, branch nearest HOME) to commanded joint angles q.
The real robot then turns its joints to

    q_true = q + zero offsets                                 (mastering)
               + Σ_k a_jk·sin(n_k·q_j + φ_jk)                  (gear transmission error)
               − d_j·b_j/2                                     (backlash: d = sign of the last motion)
               − K⁻¹·(τ_g(q, load) − τ_g(mastering, no load))  (compliance under gravity)

and its TCP lands at the real robot's forward kinematics of q_true: joint placements off by
a small rigid motion each (position and direction of every axis, 6 numbers per joint), the
base ($ROBROOT as registered) and the tool (TCP) off by small frames. d_j is the sign of
joint j's last motion along the visiting order, starting from HOME: the robot is simulated
along the order of a plan or a program, never pose by pose. The tracker adds its noise and
the robot's repeatability (both Gaussian, per axis) to the true position.

All magnitudes and the ``seed`` live in the description's ``[errors]`` table; a seed draws
a fresh robot. ``target_mean_mm`` (if > 0) scales the geometric errors (placements, zero
offsets, base, tool) of every drawn robot so that its mean error norm over the workspace
(Latin hypercube, 2000 poses, fixed seed) is that figure; compliance, gear ripple, backlash
and noise keep their physical sizes. The default robot (``seed`` of the file) is the one
calibrated to Hu, Hua & Tian's uncompensated row (mean 0.754 mm).

The load is what the robot carries at each target: the description's ``[payload]``
(``default_load``) unless a call gives ``loads`` [N, 4] (mass kg, centre of mass cx,
cy, cz mm in the flange frame) per row: a pick-and-place program carries the part to the
place and nothing back, a calibration campaign is measured at two or three test loads
(``postproc plan --load``). A load row with a NaN is the description's payload; a load
heavier than the robot's rated payload (``[payload] rated``, ``rated_payload``) is refused.

Vectorised throughout: IK/FK and gravity torques (from the joint frames) in numpy over all
poses, backlash signs from ``np.diff`` with a forward fill; Pinocchio is not needed.

Arm configuration and tools: a command may carry its Status/Turn (``config`` [N, 2], -1 = not
stated, or a ``configuration.Stated``: what a program states in its controller's form; the
controller's rules of :mod:`postproc.robot.configuration` for the rest, from HOME) or its joint angles, and its own TCP on the flange (``tools`` [N, 6], default the description's
tool). The drawn tool error is a mount error on the flange: for the description's tool T₀ the
real TCP is flange·T₀·E, for another tool T it is flange·(T₀·E·T₀⁻¹)·T, the same physical
error carried by the flange. ``actual_poses`` / ``measure(..., orientation=True)`` give the
TCP's orientation too (a 6-DOF tracker probe), with ``orientation_noise_deg`` per angle.
"""
from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field

import numpy as np

from ..core import frames
from ..core.diagnostics import P331, P335, P512, PostprocError
from ..core.frames import nearest_triple, rotation_angle_deg, small_transform
from ..core.stats import table2
from ..core.toml import check_value
from ..robot import configuration, conventions
from ..robot.approach import approach_signs, ordered_approach_signs
from ..robot.arm import Robot
from ..robot.description import RobotDescription, load_description
from ..robot.kinematics.chain import Chain

__all__ = ["ErrorSpec", "SimulatedRobot", "table2"]

CALIBRATION_POSES = 2000
CALIBRATION_SEED = 0

# [errors] key → kind (as postproc.robot.description.check_value; "orders": positive integers, "amplitudes": 6 rows)
_ERROR_KEYS: dict[str, str] = {
    "seed": "int",
    "target_mean_mm": "num",
    "joint_position_mm": "num",
    "joint_direction_deg": "num",
    "zero_offset_deg": "num",
    "base_position_mm": "num",
    "base_rotation_deg": "num",
    "tool_position_mm": "num",
    "tool_rotation_deg": "num",
    "stiffness": "vec:6",
    "stiffness_spread": "num",
    "mastering_q": "vec:6",
    "ripple_orders": "orders",
    "ripple_deg": "amplitudes",
    "backlash_deg": "vec:6",
    "backlash_spread": "num",
    "tracker_noise_mm": "num",
    "repeatability_mm": "num",
    "orientation_noise_deg": "num",
}


@dataclass(frozen=True)
class ErrorSpec:
    """The ``[errors]`` table, checked: magnitudes (standard deviations unless noted)."""

    seed: int = 0
    target_mean_mm: float = 0.0
    joint_position_mm: float = 0.0
    joint_direction_deg: float = 0.0
    zero_offset_deg: float = 0.0
    base_position_mm: float = 0.0
    base_rotation_deg: float = 0.0
    tool_position_mm: float = 0.0
    tool_rotation_deg: float = 0.0
    stiffness: np.ndarray | None = None  # [6] Nm/rad; None = rigid
    stiffness_spread: float = 0.0  # relative σ of each robot's stiffness
    mastering_q: np.ndarray | None = None  # [6] deg; None = HOME
    ripple_orders: tuple[int, ...] = ()
    ripple_deg: np.ndarray = field(default_factory=lambda: np.zeros((6, 0)))  # [6, K] amplitudes
    backlash_deg: np.ndarray = field(default_factory=lambda: np.zeros(6))  # [6] full lost motion
    backlash_spread: float = 0.0  # relative half-width of the uniform draw around backlash_deg
    tracker_noise_mm: float = 0.0
    repeatability_mm: float = 0.0
    orientation_noise_deg: float = 0.0  # per-angle noise of a 6-DOF probe's A, B, C

    @classmethod
    def from_description(cls, d: RobotDescription) -> "ErrorSpec":
        """Check the description's ``[errors]`` table; PostprocError (P331/P332) at the key's line."""
        values: dict[str, object] = {}
        for key, value in d.errors.items():
            if key not in _ERROR_KEYS:
                known = ", ".join(_ERROR_KEYS)
                raise d.error(f"unknown key '{key}' in [errors] (known: {known})", "errors", key, P331)
            values[key] = _checked(d, key, _ERROR_KEYS[key], value)
        orders = values.get("ripple_orders", ())
        amps = values.setdefault("ripple_deg", np.zeros((6, len(orders))))
        if amps.shape != (6, len(orders)):
            where = "ripple_deg" if "ripple_deg" in d.errors else "ripple_orders"
            raise d.error(f"[errors] ripple_deg must be 6 rows of {len(orders)} amplitudes, one per ripple_orders",
                          "errors", where)
        return cls(**values)


def _checked(d: RobotDescription, key: str, kind: str, value) -> object:
    def fail(message: str) -> PostprocError:
        return d.error(message, "errors", key)

    where = f"[errors] {key}"
    if kind == "orders":
        if not isinstance(value, list) or not all(type(v) is int and v > 0 for v in value):
            raise fail(f"{where} must be a list of positive integers (cycles per joint turn), got {value!r}")
        return tuple(value)
    if kind == "amplitudes":
        if not isinstance(value, list) or len(value) != 6 or not all(isinstance(r, list) for r in value):
            raise fail(f"{where} must be 6 rows (one per joint) of amplitudes, got {value!r}")
        return np.array([check_value(f"vec:{len(r)}", r, where, fail) for r in value]).reshape(6, -1)
    checked = check_value(kind, value, where, fail)
    if key != "mastering_q" and np.any(np.asarray(checked) < 0):
        raise fail(f"{where} must not be negative")
    if key == "stiffness" and np.any(checked <= 0):
        raise fail(f"{where} must be positive (Nm/rad)")
    return checked


def _workspace_poses(workspace: dict, n: int, seed: int) -> np.ndarray | None:
    """Latin hypercube poses over the description's workspace (box, attitude ± range).

    A plain numpy LHS (a stratum per pose and dimension, shuffled): the same design as
    ``postproc plan`` draws, without importing scipy.stats (0.7 s) into every measurement."""
    if not {"box", "attitude", "range"} <= set(workspace):
        return None
    box, att, rng_deg = np.asarray(workspace["box"]), np.asarray(workspace["attitude"]), float(workspace["range"])
    lo = np.concatenate([box[0::2], att - rng_deg])
    hi = np.concatenate([box[1::2], att + rng_deg])
    rng = np.random.default_rng(seed)
    strata = np.argsort(rng.random((n, 6)), axis=0)
    unit = (strata + rng.random((n, 6))) / n
    return lo + unit * (hi - lo)


class SimulatedRobot:
    """The real robot: nominal model + errors drawn with ``seed`` (None = the file's default,
    calibrated robot), and the simulated laser tracker.

    >>> sim = SimulatedRobot()                 # models/kr500.toml, default robot
    >>> measured = sim.measure(plan_poses, rng_seed=0)
    """

    def __init__(self, description: RobotDescription | None = None, seed: int | None = None):
        self.description = description if description is not None else load_description()
        self.robot = Robot(self.description)
        self.spec = ErrorSpec.from_description(self.description)
        self.seed = self.spec.seed if seed is None else int(seed)
        self.is_default = seed is None or int(seed) == self.spec.seed
        self._last_ik: tuple | None = None
        self._draw()
        self.scale = 1.0
        self._reference = self._reference_set()
        self._build_chain()
        if self.spec.target_mean_mm > 0:
            self._calibrate(self.spec.target_mean_mm)

    @classmethod
    def from_file(cls, path=None, seed: int | None = None) -> "SimulatedRobot":
        """The simulated robot of a description file (default models/kr500.toml)."""
        return cls(load_description(path), seed)

    # ---------------------------------------------------------------- drawing a robot
    def _draw(self) -> None:
        s, robot = self.spec, self.robot

        def rng(part: int) -> np.random.Generator:  # one stream per error kind: adding one keeps the others
            return np.random.default_rng([self.seed, part])

        self.joint_offsets_mm = rng(1).normal(0.0, s.joint_position_mm, (6, 3))
        self.joint_tilts_rad = np.radians(rng(2).normal(0.0, s.joint_direction_deg, (6, 3)))
        self.zero_offsets_deg = rng(3).normal(0.0, s.zero_offset_deg, 6)
        base = rng(4)
        self.base_error = (np.radians(base.normal(0.0, s.base_rotation_deg, 3)),
                           base.normal(0.0, s.base_position_mm, 3))
        tool = rng(5)
        self.tool_error = (np.radians(tool.normal(0.0, s.tool_rotation_deg, 3)),
                           tool.normal(0.0, s.tool_position_mm, 3))
        if s.stiffness is not None:
            factor = np.clip(rng(6).normal(1.0, s.stiffness_spread, 6), 0.5, 1.5)
            self.stiffness = s.stiffness * factor  # Nm/rad
        else:
            self.stiffness = None
        k = len(s.ripple_orders)
        ripple = rng(7)
        self.ripple_orders = np.asarray(s.ripple_orders, float)
        self.ripple_amp_deg = s.ripple_deg * ripple.uniform(0.5, 1.5, (6, k))
        self.ripple_phase = ripple.uniform(0.0, 2 * np.pi, (6, k))
        self.backlash_deg = s.backlash_deg * rng(8).uniform(1 - s.backlash_spread, 1 + s.backlash_spread, 6)
        mastering = robot.home_q if s.mastering_q is None else s.mastering_q
        self._tau_mastering = robot.gravity_torques(mastering, payload=False)[0]

    def _build_chain(self) -> None:
        """The real robot's kinematics with the geometric errors scaled by ``self.scale``, in
        the base frame the tracker registration gives: the rigid motion that best fits the
        real robot's positions to the commanded ones over the workspace (as a measurement
        campaign sets its frame up), then the drawn registration error on top of it."""
        from ..core.registration import fit_rigid, transform_matrix

        r, k = self.robot, self.scale
        nominal = r.chain
        placements = nominal.placements @ small_transform(k * self.joint_tilts_rad, k * self.joint_offsets_mm)
        tool = small_transform(k * self.tool_error[0], k * self.tool_error[1])
        end = r.flange_chain.end @ r.tool_matrix @ tool
        base = small_transform(self.base_error[0], self.base_error[1])
        if self._reference is not None:
            poses, q, joint_errors = self._reference
            q_true = q + joint_errors + k * self.zero_offsets_deg
            raw = Chain(placements, nominal.axes, end).transforms(np.radians(q_true))[:, :3, 3]
            target = poses[:, :3]
            base = base @ transform_matrix(*fit_rigid(raw, target))  # R·raw + t ≈ target (Kabsch)
        self.chain = Chain(placements, nominal.axes, end, base)

    def _calibrate(self, target: float) -> None:
        """Solve mean error norm (scale) = target for the geometric scale; the mean is monotone
        and nearly linear in the scale, so a bracketed secant (Illinois) converges in a few
        steps. (scipy.optimize would do the same but costs 0.3–0.6 s to import per command.)"""
        if self._reference is None:
            raise self.description.error("[errors] target_mean_mm needs a [workspace] table with box, attitude, range",
                                         "errors", "target_mean_mm")
        poses, q, joint_errors = self._reference

        def excess(scale: float) -> float:
            self.scale = scale
            self._build_chain()
            actual = self._tcp(q, joint_errors)
            return float(np.linalg.norm(poses[:, :3] - actual, axis=1).mean()) - target

        a, fa = 0.0, excess(0.0)
        if fa >= 0:  # compliance, ripple and backlash alone already exceed the target
            raise self.description.error(
                f"[errors] the non-geometric errors alone give {fa + target:.3f} mm > target_mean_mm {target}: "
                "stiffen the joints or lower ripple/backlash", "errors", "target_mean_mm")
        b, fb = 1.0, excess(1.0)
        while fb < 0:
            a, fa = b, fb
            b *= 4.0
            if b > 1e6:
                raise self.description.error(
                    "[errors] no geometric error magnitudes given: cannot reach target_mean_mm", "errors", "target_mean_mm")
            fb = excess(b)
        side = 0
        for _ in range(60):
            c = b - fb * (b - a) / (fb - fa)
            fc = excess(c)
            if abs(fc) < 1e-7 * target:
                break
            if (fc < 0) == (fa < 0):
                a, fa = c, fc
                if side == -1:
                    fb /= 2
                side = -1
            else:
                b, fb = c, fc
                if side == 1:
                    fa /= 2
                side = 1
        self.scale = c
        self._build_chain()

    def _reference_set(self) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """Workspace poses (LHS, fixed seed) visited from HOME: for registration and calibration."""
        poses = _workspace_poses(self.description.workspace, CALIBRATION_POSES, CALIBRATION_SEED)
        if poses is None:
            return None
        q, ok = self.robot.ik(poses)
        if not ok.all():
            raise self.description.error("the [workspace] box is not reachable everywhere", "workspace", "box",
                                         P335)
        return poses, q, self._joint_errors(q, approach_signs(q, self.robot.home_q))

    # ---------------------------------------------------------------- the physics
    def deflection(self, q_deg: np.ndarray, payload: bool = True, loads: np.ndarray | None = None) -> np.ndarray:
        """Joint deflection under gravity [N, 6] (deg): −K⁻¹·(τ_g(q, load) − τ_g at mastering),
        with the description's payload (``payload`` False: none) or each row's ``loads`` [N, 4]
        (mass kg, centre of mass mm in the flange frame; a row with a NaN: the description's)."""
        q = np.atleast_2d(np.asarray(q_deg, float))
        if self.stiffness is None:
            return np.zeros_like(q)
        from ..robot.kinematics.gravity import gravity_torques

        # (Robot.gravity_torques' call, each row's load in place of the description's payload where given)
        tau = gravity_torques(self.robot.description, q, payload, self.robot.flange_chain, self.loads(loads, len(q)))
        return -np.degrees((tau - self._tau_mastering) / self.stiffness)

    @property
    def default_load(self) -> np.ndarray:
        """[4] the description's payload (``[payload]`` mass and com): the load of a row that
        states none; mass kg, centre of mass mm (flange)."""
        d = self.description
        return np.r_[d.payload_mass, d.payload_com].astype(float)

    @property
    def rated_payload(self) -> float | None:
        """The robot's rated payload (kg, the description's ``[payload] rated``), None where the
        description does not state it."""
        return self.description.payload_rated

    def loads(self, loads: np.ndarray | None, n: int) -> np.ndarray | None:
        """Each of ``n`` rows' load [n, 4] (a row with a NaN: the description's payload), None
        for ``loads`` None (the description's payload everywhere). Raises PostprocError for a
        negative mass."""
        if loads is None:
            return None
        loads = np.array(np.broadcast_to(np.asarray(loads, float), (n, 4)))
        unknown = np.isnan(loads).any(axis=1)
        loads[unknown] = self.default_load
        if not np.isfinite(loads).all() or (loads[:, 0] < 0).any():
            raise PostprocError("a load must be a mass >= 0 kg and a centre of mass in mm (finite numbers)", code=P512)
        rated = self.rated_payload
        if rated is not None and (loads[:, 0] > rated).any():
            raise PostprocError(f"a load of {loads[:, 0].max():g} kg is more than {self.robot.name}'s rated payload "
                                f"{rated:g} kg ([payload] rated of its description)", code=P512)
        return loads

    def ripple(self, q_deg: np.ndarray) -> np.ndarray:
        """Gear transmission error [N, 6] (deg) at commanded joint angles."""
        q = np.radians(np.atleast_2d(np.asarray(q_deg, float)))
        if not len(self.ripple_orders):
            return np.zeros_like(q)
        phase = q[:, :, None] * self.ripple_orders + self.ripple_phase
        return (self.ripple_amp_deg * np.sin(phase)).sum(axis=-1)

    def _joint_errors(self, q_deg: np.ndarray, signs: np.ndarray, loads: np.ndarray | None = None) -> np.ndarray:
        """Everything the joints add to the command except the (scaled) zero offsets."""
        return self.ripple(q_deg) - signs * self.backlash_deg / 2 + self.deflection(q_deg, loads=loads)

    def _tcp(self, q_deg: np.ndarray, joint_errors: np.ndarray, tools: np.ndarray | None = None) -> np.ndarray:
        return self._tcp_matrix(q_deg, joint_errors, tools)[:, :3, 3]

    def _tcp_matrix(self, q_deg: np.ndarray, joint_errors: np.ndarray, tools: np.ndarray | None = None) -> np.ndarray:
        """The real TCP transforms [N, 4, 4]; ``tools`` [N, 6] each row's TCP on the flange."""
        q_true = np.radians(q_deg + joint_errors + self.scale * self.zero_offsets_deg)
        if tools is None:
            return self.chain.transforms(q_true)
        tools = np.asarray(tools, float).reshape(len(q_true), 6)
        out = np.empty((len(q_true), 4, 4))
        distinct, which = np.unique(tools, axis=0, return_inverse=True)
        r, k = self.robot, self.scale
        mount = r.tool_matrix @ small_transform(k * self.tool_error[0], k * self.tool_error[1]) @ frames.inverse(r.tool_matrix)
        for i, tool in enumerate(distinct):  # over the few tools of a program
            rows = which.ravel() == i
            end = r.flange_chain.end @ mount @ frames.frame_to_matrix(tool)
            out[rows] = Chain(self.chain.placements, self.chain.axes, end, self.chain.base).transforms(q_true[rows])
        return out

    # ---------------------------------------------------------------- public
    def _ik(self, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Nominal IK (branch nearest HOME), remembered for the last pose array: a command
        typically asks reachable() and then measures the same 10^5 poses."""
        poses = np.ascontiguousarray(np.atleast_2d(np.asarray(poses, float)))
        key = (poses.shape, hashlib.blake2b(poses.tobytes(), digest_size=16).digest())
        if self._last_ik is None or self._last_ik[0] != key:
            self._last_ik = (key, *self.robot.ik(poses))
        return self._last_ik[1].copy(), self._last_ik[2].copy()

    def reachable(self, poses: np.ndarray) -> np.ndarray:
        """Mask of commanded poses [N, 6] the controller can reach (nominal IK within limits)."""
        return self._ik(poses)[1]

    def joint_angles(self, poses: np.ndarray, config: np.ndarray | None = None, tools: np.ndarray | None = None,
                     motions: np.ndarray | None = None, prev: np.ndarray | None = None,
                     axes: np.ndarray | None = None) -> np.ndarray:
        """The controller's commanded joint angles [N, 6] (deg) for TCP poses [N, 6]: nominal
        IK, branch nearest HOME; with ``config`` [N, 2] (S, T; -1 = not stated) the stated
        branches and the controller's rules from HOME (``motions`` [N] kinds, programs.MOTIONS indices;
        default: every row on its own, as a plan's), with ``tools`` [N, 6] each row's TCP;
        ``prev`` [N] each row's predecessor (-1 none: a program's execution order, default the row
        before) and ``axes`` [N, 6] the axis values a joint motion before a row left the robot at
        (``Targets.start``). Raises PostprocError (P335) if any pose is out of reach (in its
        configuration)."""
        poses = np.atleast_2d(np.asarray(poses, float))
        q, ok = self._configured_ik(poses, config, tools, motions, prev, axes)
        if not ok.all():
            bad = np.flatnonzero(~ok)
            raise PostprocError(
                f"{len(bad)} of {len(poses)} poses are out of reach of {self.robot.name} "
                f"(first: row {bad[0] + 1}, {np.round(poses[bad[0]], 3).tolist()})", code=P335)
        return q

    def reachable_in(self, poses: np.ndarray, config: np.ndarray | None = None, tools: np.ndarray | None = None,
                     motions: np.ndarray | None = None, prev: np.ndarray | None = None,
                     axes: np.ndarray | None = None) -> np.ndarray:
        """Mask of poses reachable in their configuration (see :meth:`joint_angles`)."""
        return self._configured_ik(np.atleast_2d(np.asarray(poses, float)), config, tools, motions, prev, axes)[1]

    def _configured_ik(self, poses, config, tools, motions, prev=None, axes=None) -> tuple[np.ndarray, np.ndarray]:
        """``motions``: None = every row on its own (nearest HOME), else [N] motion kinds
        (programs.MOTIONS indices: PTP-like, keep-configuration and independent rows)."""
        if config is None and motions is None and prev is None and axes is None \
                and (tools is None or np.allclose(tools, self.robot.tool)):
            return self._ik(poses)  # (the plain case, cached)
        n = len(poses)
        if isinstance(config, configuration.Stated):  # (a program's stated forms: S/T, confdata, CONFIG)
            stated = config
        else:
            config = np.full((n, 2), conventions.UNSTATED) if config is None else np.asarray(config, int)
            stated = configuration.Stated(config[:, 0], config[:, 1])
        if motions is None:
            ptp, alone = np.zeros(n, bool), np.ones(n, bool)
        else:
            ptp, alone = conventions.execution_kinds(motions)
        if prev is not None or axes is not None:
            prev = np.arange(-1, n - 1) if prev is None else np.asarray(prev)
            return configuration.ordered_joints(self.robot, poses, stated, ptp, self.robot.home_q, tools, alone, prev,
                                                axes)
        return configuration.controller_joints(self.robot, poses, stated.status, stated.turn, ptp,
                                               self.robot.home_q, tools, alone, windows=stated.windows)

    def approach_directions(self, poses: np.ndarray, start_q: np.ndarray | None = None) -> np.ndarray:
        """Sign (+1/−1) [N, 6] of each joint's last motion when the poses are visited in order
        from ``start_q`` (default HOME): the side each joint's backlash is taken up on."""
        start = self.robot.home_q if start_q is None else np.asarray(start_q, float)
        return approach_signs(self.joint_angles(poses), start)

    def true_joint_angles(self, poses: np.ndarray, start_q: np.ndarray | None = None,
                          loads: np.ndarray | None = None) -> np.ndarray:
        """Joint angles [N, 6] (deg) the real joints take when the poses are visited in order
        (carrying ``loads`` [N, 4], default the description's payload)."""
        q = self.joint_angles(poses)
        start = self.robot.home_q if start_q is None else np.asarray(start_q, float)
        return q + self._joint_errors(q, approach_signs(q, start), loads) + self.scale * self.zero_offsets_deg

    def actual_poses(self, commanded_poses: np.ndarray, start_q: np.ndarray | None = None, *,
                     q_deg: np.ndarray | None = None, config: np.ndarray | None = None,
                     tools: np.ndarray | None = None, motions: np.ndarray | None = None,
                     prev: np.ndarray | None = None, axes: np.ndarray | None = None,
                     loads: np.ndarray | None = None) -> np.ndarray:
        """Where the TCP really goes as transforms [N, 4, 4] (mm, robot base frame) when the
        commanded poses [N, 6] are visited in order from ``start_q`` (default HOME), at the
        joint angles ``q_deg`` if given, else in their configuration ``config`` (see
        :meth:`joint_angles`), with each row's ``tools``, carrying each row's ``loads`` [N, 4]
        (mass kg, centre of mass mm in the flange frame; None or a NaN row: the description's
        payload). Deterministic: no noise."""
        q = (self.joint_angles(commanded_poses, config, tools, motions, prev, axes) if q_deg is None
             else np.asarray(q_deg, float))
        start = self.robot.home_q if start_q is None else np.asarray(start_q, float)
        signs = approach_signs(q, start) if prev is None else ordered_approach_signs(q, prev, start, axes)
        return self._tcp_matrix(q, self._joint_errors(q, signs, loads), tools)

    def actual_positions(self, commanded_poses: np.ndarray, start_q: np.ndarray | None = None, **options) -> np.ndarray:
        """Where the TCP really goes [N, 3] (mm, robot base frame): :meth:`actual_poses`' positions."""
        return self.actual_poses(commanded_poses, start_q, **options)[:, :3, 3]

    def measure(self, commanded_poses: np.ndarray, rng_seed: int | None = 0,
                start_q: np.ndarray | None = None, orientation: bool = False, **options) -> np.ndarray:
        """Tracker readings [N, 3] (mm, robot base frame): the actual positions + the robot's
        repeatability + tracker noise (Gaussian, per axis), visited in order. With
        ``orientation``: [N, 6], the probe's A, B, C too (+ ``orientation_noise_deg``).
        ``options``: q_deg, config, tools, motions, loads (see :meth:`actual_poses`)."""
        actual = self.actual_poses(commanded_poses, start_q, **options)
        rng = np.random.default_rng(rng_seed)
        sigma = math.hypot(self.spec.tracker_noise_mm, self.spec.repeatability_mm)
        xyz = actual[:, :3, 3] + rng.normal(0.0, 1.0, (len(actual), 3)) * sigma
        if not orientation:
            return xyz
        abc = nearest_triple(frames.matrix_to_frame(actual)[:, 3:], np.atleast_2d(commanded_poses)[:, 3:6])
        if self.spec.orientation_noise_deg > 0:
            abc = abc + rng.normal(0.0, self.spec.orientation_noise_deg, abc.shape)
        return np.hstack([xyz, abc])

    @property
    def noise_mm(self) -> float:
        """Per-axis standard deviation of a measurement about the true mean position (mm)."""
        return math.hypot(self.spec.tracker_noise_mm, self.spec.repeatability_mm)

    def true_error(self, poses: np.ndarray, start_q: np.ndarray | None = None, **options) -> np.ndarray:
        """E = P_target − P_actual [N, 3] (mm) for poses visited in order (no noise); ``options``
        as :meth:`actual_poses` (``loads`` among them)."""
        poses = np.atleast_2d(np.asarray(poses, float))
        return poses[:, :3] - self.actual_positions(poses, start_q, **options)

    def verify(self, targets: np.ndarray, commands: np.ndarray, rng_seed: int | None = 0,
               noise: bool = True, **options) -> dict:
        """The method's Table 2 before and after compensation: error = |target − where the robot
        goes| when commanded the target itself (before) and the compensated command (after),
        each run in order from HOME; measured with tracker noise + repeatability unless
        ``noise`` is False. Returns {"before": table2, "after": table2, "errors_before",
        "errors_after"} (the last two [N] arrays of norms, mm), and "orientation_before" /
        "orientation_after": Table 2 of the angle (deg) between the target's and the actual
        orientation (a 6-DOF probe, ``orientation_noise_deg``). ``options`` (config, tools,
        motions, loads; see :meth:`actual_poses`): the program's configurations, tools and the
        load carried at each target, for both runs."""
        targets = np.atleast_2d(np.asarray(targets, float))
        commands = np.atleast_2d(np.asarray(commands, float))
        if targets.shape != commands.shape:
            raise PostprocError(f"targets {targets.shape} but commands {commands.shape}: they must be poses [N, 6] "
                                "that correspond row by row")
        if noise:
            seeds = np.random.SeedSequence(rng_seed).spawn(2)
            before = self.measure(targets, seeds[0], orientation=True, **options)
            after = self.measure(commands, seeds[1], orientation=True, **options)
        else:
            before = frames.matrix_to_frame(self.actual_poses(targets, **options))
            after = frames.matrix_to_frame(self.actual_poses(commands, **options))
        e_before = np.linalg.norm(targets[:, :3] - before[:, :3], axis=1)
        e_after = np.linalg.norm(targets[:, :3] - after[:, :3], axis=1)
        r_before, r_after = (rotation_angle_deg(targets[:, 3:6], m[:, 3:6]) for m in (before, after))
        return {"before": table2(e_before), "after": table2(e_after),
                "errors_before": e_before, "errors_after": e_after,
                "orientation_before": table2(r_before), "orientation_after": table2(r_after)}

    def describe(self) -> dict:
        """The drawn robot's parameters (for reports and tests)."""
        k = self.scale
        return {
            "robot": self.robot.name,
            "seed": self.seed,
            "default": self.is_default,
            "geometric_scale": k,
            "joint_offsets_mm": (k * self.joint_offsets_mm).tolist(),
            "joint_tilts_deg": np.degrees(k * self.joint_tilts_rad).tolist(),
            "zero_offsets_deg": (k * self.zero_offsets_deg).tolist(),
            "base_error": {"rotation_deg": np.degrees(k * self.base_error[0]).tolist(),
                           "offset_mm": (k * self.base_error[1]).tolist()},
            "tool_error": {"rotation_deg": np.degrees(k * self.tool_error[0]).tolist(),
                           "offset_mm": (k * self.tool_error[1]).tolist()},
            "stiffness_nm_per_rad": None if self.stiffness is None else self.stiffness.tolist(),
            "ripple_orders": self.ripple_orders.tolist(),
            "ripple_amplitude_deg": self.ripple_amp_deg.tolist(),
            "backlash_deg": self.backlash_deg.tolist(),
            "tracker_noise_mm": self.spec.tracker_noise_mm,
            "repeatability_mm": self.spec.repeatability_mm,
        }

    def __repr__(self) -> str:
        return f"SimulatedRobot({self.robot.name!r}, seed={self.seed}{' (default)' if self.is_default else ''})"

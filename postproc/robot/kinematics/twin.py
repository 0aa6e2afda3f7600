"""The torch twin of the nominal arm: forward kinematics, gravity torques and the closed-form
inverse kinematics — the pieces of the kinematic error model (``model.training.kinematic``)
that are fitted in torch (autograd) and run inside the exported ONNX graph; and the torch
rotation helpers (``rotation_matrices``, ``small_rotation``, ``small_transform``,
``rotation_log``, ``axis_rotations``, ``turn_columns`` / ``turn_rows``: the numpy ones are
postproc.core.frames').

Everything is float64 and vectorised over poses; the only loop is over the six joints.
:class:`Arm` is the torch FK ([N, …] layout, the fit's); the exported graph's own layout is
``batch_last`` (the same quantities, tests/test_kinematics.py). The IK is not written here:
``KukaIK`` and ``UrIK`` run postproc.robot.kinematics.ik's formulas (the numpy Robot's too) on
the array namespace ``TORCH``. ONNX Runtime has no float64 Atan / Acos / Asin kernel, so that
namespace evaluates them in float32 (``_atan2`` / ``_acos`` / ``_asin``): a joint angle off by
1e-7 rad moves the *error* the model predicts by ~1e-7 mm, because the error is the
difference of two chains evaluated at the same angles (nominal minus identified), not a position.

Two IK families, one branch each (the branch the controller uses over the data, see
``choose_branch``): ``KukaIK`` (A1 about ±Z, A2/A3/A5 about ±Y, A4/A6 about ±X with a
spherical wrist) and ``UrIK`` (Universal-Robots type: three parallel shoulder/elbow/wrist-1
axes and an offset wrist); ``make_ik`` picks the description's.
"""
from __future__ import annotations

import math

import numpy as np
import torch

from ...core.frames import MM, abc_entries
from ..description import RobotDescription
from .gravity import GRAVITY, gravity_from_points, holding_torques, load_torques
from .ik import (
    UR_SINGULAR_TORCH,
    KukaGeometry,
    Ops,
    UrGeometry,
    geometry_of,
    kuka_elbow,
    kuka_shoulder,
    kuka_wrist,
    kuka_wrist_centre,
    ur_elbow,
    ur_elbow_plane,
    ur_shoulder,
    ur_wrist,
    ur_wrist_frame,
)

__all__ = [
    "coupling_pairs", "Arm", "axis_rotations", "mc", "mv", "turn_columns", "turn_rows", "small_rotation",
    "pose_matrices", "at_tool", "KukaIK", "UrIK", "make_ik", "GRAVITY", "wrapped_step", "rotation_matrices", "TORCH",
    "small_transform", "axial", "rotation_log",
]



def _t(value) -> torch.Tensor:
    return torch.as_tensor(np.asarray(value, dtype=np.float64))


def axis_rotations(axes: torch.Tensor, q: torch.Tensor) -> torch.Tensor:
    """Rotations about unit ``axes`` [J, 3] by ``q`` [N, J] rad → [N, J, 3, 3] (Rodrigues)."""
    zero = torch.zeros_like(axes[:, 0])
    k = torch.stack([zero, -axes[:, 2], axes[:, 1], axes[:, 2], zero, -axes[:, 0], -axes[:, 1], axes[:, 0], zero],
                    dim=-1).reshape(-1, 3, 3)
    aat = axes[:, :, None] * axes[:, None, :]
    s, c = torch.sin(q)[..., None, None], torch.cos(q)[..., None, None]
    eye = torch.eye(3, dtype=q.dtype)
    return c * eye + s * k + (1.0 - c) * aat


# Batched 3x3 products are written out so that the exported graph avoids onnxruntime's
# MatMul over millions of tiny matrices (13 ms per product for 1e5 poses): a product with a
# constant is one GEMM over all rows (2 ms), a turn about a coordinate axis mixes two columns.


def mc(a: torch.Tensor, c: torch.Tensor) -> torch.Tensor:
    """[..., 3, 3] @ constant [3, 3]: one GEMM over all rows."""
    return (a.reshape(-1, 3) @ c).reshape(a.shape)


def mv(a: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """[..., 3, 3] @ [..., 3] (v batched or constant)."""
    if v.dim() == 1:  # (Mul + ReduceSum: faster in onnxruntime than a MatMul with a vector)
        return (a * v).sum(-1)
    return (a @ v[..., None])[..., 0]


def _axis_index(axis: torch.Tensor) -> tuple[int, float] | None:
    """(k, sign) if ``axis`` is ±e_k, else None."""
    a = axis.detach().numpy() if isinstance(axis, torch.Tensor) else np.asarray(axis)
    k = int(np.argmax(np.abs(a)))
    return (k, float(np.sign(a[k]))) if abs(abs(a[k]) - 1.0) < 1e-12 else None


def turn_columns(x: torch.Tensor, axis: torch.Tensor, q: torch.Tensor) -> torch.Tensor:
    """x @ R(axis, q) for x [N, 3, 3], q [N]: about a coordinate axis two columns mix; else
    Rodrigues, c·x + s·x[a]× + (1 − c)·(x a) aᵀ, with products by constants only."""
    c, s = torch.cos(q)[:, None], torch.sin(q)[:, None]
    aligned = _axis_index(axis)
    if aligned is None:
        k = torch.stack([torch.zeros_like(axis[0]), -axis[2], axis[1], axis[2], torch.zeros_like(axis[0]), -axis[0],
                         -axis[1], axis[0], torch.zeros_like(axis[0])]).reshape(3, 3)
        return c[..., None] * x + s[..., None] * mc(x, k) + (1 - c)[..., None] * mv(x, axis)[..., None] * axis
    k, sign = aligned
    s = sign * s
    i, j = [(1, 2), (2, 0), (0, 1)][k]  # R_k mixes columns i, j: (x_i c + x_j s, −x_i s + x_j c)
    cols = list(x.unbind(-1))
    cols[i], cols[j] = cols[i] * c + cols[j] * s, cols[j] * c - cols[i] * s
    return torch.stack(cols, dim=-1)


def turn_rows(x: torch.Tensor, k: int, q: torch.Tensor) -> torch.Tensor:
    """R_k(q)ᵀ @ x for x [N, 3, 3], q [N]: undo a turn about coordinate axis k from the left."""
    c, s = torch.cos(q)[:, None], torch.sin(q)[:, None]
    i, j = [(1, 2), (2, 0), (0, 1)][k]
    rows = list(x.unbind(-2))
    rows[i], rows[j] = rows[i] * c + rows[j] * s, rows[j] * c - rows[i] * s
    return torch.stack(rows, dim=-2)


def small_rotation(rotvec: torch.Tensor) -> torch.Tensor:
    """[..., 3] rotation vectors → [..., 3, 3]; exact Rodrigues, smooth (and differentiable) at 0."""
    theta2 = (rotvec * rotvec).sum(-1, keepdim=True)[..., None]
    theta = torch.sqrt(theta2 + 1e-300)
    # sin θ/θ and (1 − cos θ)/θ² by their series below 1e-4 rad (exact to 1e-17 there)
    small = theta < 1e-4
    a = torch.where(small, 1.0 - theta2 / 6.0, torch.sin(theta) / theta)
    b = torch.where(small, 0.5 - theta2 / 24.0, (1.0 - torch.cos(theta)) / torch.where(small, 1.0, theta2))
    x, y, z = rotvec.unbind(-1)
    zero = torch.zeros_like(x)
    k = torch.stack([zero, -z, y, z, zero, -x, -y, x, zero], dim=-1).reshape(*rotvec.shape[:-1], 3, 3)
    return torch.eye(3, dtype=rotvec.dtype) + a * k + b * (k @ k)


def small_transform(rotvec: torch.Tensor, offset: torch.Tensor) -> torch.Tensor:
    """[..., 4, 4] rigid transforms from rotation vectors [..., 3] and offsets [..., 3]
    (postproc.core.frames.small_transform in torch, differentiable)."""
    r = small_rotation(rotvec)
    top = torch.cat([r, offset[..., :, None]], dim=-1)
    bottom = torch.zeros(*top.shape[:-2], 1, 4, dtype=top.dtype)
    bottom[..., 0, 3] = 1.0
    return torch.cat([top, bottom], dim=-2)


def axial(m: torch.Tensor, batch_last: bool = False) -> torch.Tensor:
    """The axial vector of m − mᵀ, (m21 − m12, m02 − m20, m10 − m01) = 2·sin θ·axis of rotations
    [N, 3, 3] → [N, 3] (``batch_last``: [3, 3, N] → [3, N], the exported graph's layout)."""
    if batch_last:
        return torch.stack([m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]])
    return torch.stack([m[:, 2, 1] - m[:, 1, 2], m[:, 0, 2] - m[:, 2, 0], m[:, 1, 0] - m[:, 0, 1]], dim=1)


def rotation_log(m: torch.Tensor, batch_last: bool = False) -> torch.Tensor:
    """Rotations within a few degrees of I [N, 3, 3] → rotation vectors [N, 3] rad (``batch_last``:
    [3, 3, N] → [3, N]): the axial vector v = sin θ·axis scaled by asin|v|/|v| ≈ 1 + |v|²/6 (exact
    to 1e-8 relative at 1°; no acos: ONNX-friendly, smooth at 0)."""
    v = 0.5 * axial(m, batch_last)
    return v * (1.0 + (v * v).sum(0 if batch_last else 1, keepdim=True) / 6.0)


def pose_matrices(pose) -> tuple[torch.Tensor, torch.Tensor]:
    """Poses [N, 6] (mm, KUKA A,B,C deg) → rotations [N, 3, 3] and positions [N, 3]; a pair
    (rotations, positions) passes through (``at_tool``'s result: the IK takes either)."""
    if isinstance(pose, tuple):
        return pose
    return rotation_matrices(pose[:, 3:6]), pose[:, 0:3]


_AXES = torch.eye(3, dtype=torch.float64)


def at_tool(pose: torch.Tensor, tool: torch.Tensor, tool0: torch.Tensor):
    """The pose of TCP ``tool0`` [6] on the flange that puts the TCP ``tool`` [N, 6] at ``pose``
    [N, 6]: the same flange pose, P·T⁻¹·T₀, as (rotations [N, 3, 3], positions [N, 3]) for the
    IK of a description whose tool is T₀. Rows of ``tool`` with a NaN are T₀ (pose unchanged)."""
    tool = torch.where(torch.isnan(tool), tool0.expand_as(tool), tool)
    r_p, p_p = pose_matrices(pose)
    r_0 = rotation_matrices(tool0[None, 3:6])[0]
    # R_P·R_Tᵀ = R_P·Rx(−C)·Ry(−B)·Rz(−A): three turns about coordinate axes (column mixes)
    back = r_p
    for k, angle in ((0, tool[:, 5]), (1, tool[:, 4]), (2, tool[:, 3])):
        back = turn_columns(back, _AXES[k], angle * (-math.pi / 180.0))
    return mc(back, r_0), p_p + mv(back, tool0[:3] - tool[:, :3])


def _unturn(x: torch.Tensor, a: torch.Tensor, b: torch.Tensor | None = None) -> torch.Tensor:
    """(Rz(a)·Ry(b))ᵀ·x = Ry(b)ᵀ·Rz(a)ᵀ·x for x [N, 3, 3] (b None: Rz(a)ᵀ·x): two row mixes."""
    x = turn_rows(x, 2, a)
    return x if b is None else turn_rows(x, 1, b)


def _atan2(y: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
    return torch.atan2(y.float(), x.float()).to(y.dtype)


def _acos(x: torch.Tensor) -> torch.Tensor:
    return torch.acos(x.float()).to(x.dtype)


def _asin(x: torch.Tensor) -> torch.Tensor:
    return torch.asin(x.float()).to(x.dtype)


class Arm:
    """The nominal arm of a robot description as float64 tensors (mm, rad, kg).

    Joint j's frame at q is ``placements[j]`` (in its parent) turned by q_j about ``axes[j]``;
    the TCP is ``end`` (flange · tool) in the last joint's frame. Link masses and centres of
    mass are the description's; the payload rides on the last joint at the flange.
    """

    def __init__(self, description: RobotDescription):
        d = self.description = description
        self.placements = _t(d.placements)
        self.axes = _t(d.axes)
        self.flange = _t(d.flange_matrix)
        self.tool = _t(d.tool_matrix)
        self.end = self.flange @ self.tool
        self.tool0 = _t(d.tool)  # the description's TCP on the flange, X,Y,Z,A,B,C
        self.masses = _t(d.masses)
        self.coms = _t(d.coms)
        self.payload_mass = float(d.payload_mass)
        self.payload_com = _t(d.payload_com_in_last)  # in the last joint's frame
        self.home_q = _t(np.radians(d.home_q))

    def frames(self, q: torch.Tensor, placements: torch.Tensor | None = None, end: torch.Tensor | None = None,
               base: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Joint rotations [N, J, 3, 3], joint origins [N, J, 3] and TCP positions [N, 3] (mm)
        at q [N, J] rad, for the nominal chain or one with other ``placements`` / ``end`` (a
        [4, 4] transform, or per-row TCP positions [N, 3] in the last joint's frame) / ``base``."""
        placements = self.placements if placements is None else placements
        end = self.end if end is None else end
        n = q.shape[0]
        if base is None:
            r = torch.eye(3, dtype=q.dtype).expand(n, 3, 3)
            p = torch.zeros(n, 3, dtype=q.dtype)
        else:
            r = base[:3, :3].expand(n, 3, 3)
            p = base[:3, 3].expand(n, 3)
        rs, ps = [], []
        eye = torch.eye(3, dtype=q.dtype)
        for j in range(self.axes.shape[0]):  # six joints, every pose at once
            m = placements[j]
            p = p + mv(r, m[:3, 3])
            if m.requires_grad or not torch.equal(m[:3, :3], eye):  # (the nominal placements are pure offsets)
                r = mc(r, m[:3, :3])
            r = turn_columns(r, self.axes[j], q[:, j])
            rs.append(r)
            ps.append(p)
        # ``end`` [4, 4], or each row's TCP position in the last joint's frame [N, 3] (tools)
        tcp = p + mv(r, end if end.shape[-1] == 3 else end[:3, 3])
        return torch.stack(rs, dim=1), torch.stack(ps, dim=1), tcp

    def tcp(self, q: torch.Tensor, **chain) -> torch.Tensor:
        """TCP positions [N, 3] mm at q [N, J] rad."""
        return self.frames(q, **chain)[2]

    def _points(self, rotations: torch.Tensor, origins: torch.Tensor) -> tuple[list, list]:
        """Each link's centre of mass [N, 3] (mm) and each joint's axis [N, 3] in the base frame."""
        count = range(len(self.axes))
        return ([origins[:, j] + mv(rotations[:, j], self.coms[j]) for j in count],
                [mv(rotations[:, j], self.axes[j]) for j in count])

    def gravity_torques(self, rotations: torch.Tensor, origins: torch.Tensor) -> torch.Tensor:
        """Joint torques [N, J] (Nm) that hold the arm against gravity, from the joint frames of
        :meth:`frames`: postproc.robot.kinematics.gravity.gravity_from_points, the simulator's formula."""
        payload = origins[:, -1] + mv(rotations[:, -1], self.payload_com)
        return torch.stack(gravity_from_points(origins.unbind(1), *self._points(rotations, origins), self.masses,
                                               self.payload_mass, payload), dim=1)

    def load_centre(self, rotations: torch.Tensor, origins: torch.Tensor, load: torch.Tensor) -> torch.Tensor:
        """[N, 3] mm: each row's load's centre of mass (``load`` [N, 4], mass kg and centre mm in
        the flange frame) in the base frame."""
        in_last = load[:, 1:] @ self.flange[:3, :3].T + self.flange[:3, 3]
        return origins[:, -1] + mv(rotations[:, -1], in_last)

    def torque_terms(self, rotations: torch.Tensor, origins: torch.Tensor,
                     load: torch.Tensor | None = None) -> torch.Tensor:
        """[N, J + J(J+1)/2]: the gravity torques of :meth:`gravity_torques`, then each link's
        own share of them, τ_ji for i ≥ j (pairs in ``coupling_pairs`` order): the regressors
        of a compliance whose link masses and lever arms are not known (only their directions).
        With ``load`` [N, 4] (each row's load: mass kg, centre of mass mm in the flange frame; no
        NaN) in place of the description's payload: the arm's links' torques and shares, the
        load's own torque (``gravity.load_torques``, exact for a known mass and centre) added to
        the gravity torques only — a load-aware compliance, whose shares stay the arm's."""
        j_idx, i_idx = coupling_pairs(len(self.axes))
        centres, omega = (torch.stack(points, 1) for points in self._points(rotations, origins))
        weights = self.masses.clone()
        if load is not None:
            points = self._points(rotations, origins)
            arm = gravity_from_points(origins.unbind(1), *points, self.masses)
            held = load_torques(origins.unbind(1), points[1], load[:, 0], self.load_centre(rotations, origins, load))
            total = torch.stack([a + b for a, b in zip(arm, held)], dim=1)
            lever = (centres[:, i_idx] - origins[:, j_idx]) * MM * weights[i_idx][:, None]
            return torch.cat([total, holding_torques(omega[:, j_idx], lever)], dim=1)
        total = self.gravity_torques(rotations, origins)
        weights[-1] = weights[-1] + self.payload_mass
        lever = (centres[:, i_idx] - origins[:, j_idx]) * MM * weights[i_idx][:, None]  # [N, P, 3]
        return torch.cat([total, holding_torques(omega[:, j_idx], lever)], dim=1)


def coupling_pairs(n: int = 6) -> tuple[list[int], list[int]]:
    """(joint j, link i) pairs with i ≥ j: which link's weight turns which joint."""
    pairs = [(j, i) for j in range(n) for i in range(j, n)]
    return [j for j, _ in pairs], [i for _, i in pairs]


# --------------------------------------------------------------------------- IK

# the IK formulas' array namespace in torch (postproc.robot.kinematics.ik: one implementation per
# arm family for numpy and torch); atan2, acos, asin in float32 for ONNX Runtime
TORCH = Ops(atan2=_atan2, acos=_acos, asin=_asin, sqrt=torch.sqrt, hypot=lambda x, y: torch.sqrt(x**2 + y**2),
            cos=torch.cos, sin=torch.sin, abs=torch.abs, clip=torch.clamp, where=torch.where, isnan=torch.isnan,
            zeros_like=torch.zeros_like, ones_like=torch.ones_like,
            stack=lambda tensors, axis: torch.stack(tensors, dim=axis), mc=mc, mv=mv, unturn=_unturn)


class _ClosedForm(torch.nn.Module):
    """A closed-form IK for one branch: the geometry's constants (``ARRAYS`` as float64 buffers,
    ``NUMBERS`` as floats) under the names the formulas of postproc.robot.kinematics.ik read."""

    def __init__(self, geometry, branch: tuple[float, float, float]):
        super().__init__()
        self.branch = tuple(float(b) for b in branch)
        for name, value in geometry.constants().items():
            if name in geometry.ARRAYS:
                self.register_buffer(name, _t(value))
            else:
                setattr(self, name, float(value))

    @staticmethod
    def branches() -> list[tuple[float, float, float]]:
        return [(a, b, c) for a in (1.0, -1.0) for b in (1.0, -1.0) for c in (1.0, -1.0)]


class KukaIK(_ClosedForm):
    """Closed-form IK of a KUKA-type arm for one branch (shoulder, elbow, wrist flip ∈ ±1):
    postproc.robot.kinematics.ik's formulas in torch. pose [N, 6] → q [N, 6] rad (turns not
    unwrapped: everything downstream is periodic in q); at a wrist singularity A4 = 0 (HOME)."""

    family = "kuka"

    def __init__(self, description: RobotDescription, branch: tuple[float, float, float] = (1.0, 1.0, 1.0)):
        super().__init__(KukaGeometry(description), branch)  # (checks the geometry: P333 for other arms)

    def branch_of(self, pose: torch.Tensor, q_in: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Per-row branch signs (shoulder, elbow, flip) [N] of joint angles ``q_in`` [N, 6] rad
        at ``pose``; rows with a NaN take this module's branch. Read from the angles the
        closed form gives on each branch: A1 = φ (shoulder +) or φ + π, A3 = α3 − α2 ∓ γ0
        (elbow), sin A5 of the flip's sign."""
        s = self.s
        c = kuka_wrist_centre(TORCH, self, *pose_matrices(pose))[1]
        phi = _atan2(c[:, 1], c[:, 0])
        return _branch_signs(self.branch, q_in, [
            torch.cos(phi - s[0] * q_in[:, 0]),
            torch.sin(self.al3 - self.al2 - s[2] * q_in[:, 2]),
            torch.sin(s[4] * q_in[:, 4])])

    def forward(self, pose: torch.Tensor, q_in: torch.Tensor | None = None) -> torch.Tensor:
        """q [N, 6] rad on this module's branch, or per row on the branch of ``q_in`` [N, 6] rad
        (NaN rows: this module's branch)."""
        shoulder, elbow, flip = self.branch if q_in is None else self.branch_of(pose, q_in)
        r_all, c = kuka_wrist_centre(TORCH, self, *pose_matrices(pose))
        th1, u, w, _, gamma0 = kuka_shoulder(TORCH, self, c, shoulder)
        th2, th3 = kuka_elbow(TORCH, self, u, w, gamma0, elbow)
        return kuka_wrist(TORCH, self, th1, th2, th3, r_all, flip)


class UrIK(_ClosedForm):
    """Closed-form IK of a Universal-Robots-type arm for one branch (shoulder, wrist, elbow ∈ ±1):
    postproc.robot.kinematics.ik's formulas in torch (the description's joint frames parallel to
    the base at q = 0, as models/ur10.toml). At the wrist singularity A6 keeps the given angle."""

    family = "ur"

    def __init__(self, description: RobotDescription, branch: tuple[float, float, float] = (1.0, 1.0, 1.0)):
        super().__init__(UrGeometry(description), branch)

    def branch_of(self, pose: torch.Tensor, q_in: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Per-row branch signs (shoulder, wrist, elbow) [N] of joint angles ``q_in`` [N, 6] rad
        at ``pose``; rows with a NaN take this module's branch. From the closed form: ψ − t1 =
        lateral (shoulder +, cos ≥ 0) or π − lateral; sin t5 and sin t3 carry the wrist and
        elbow signs."""
        _, p6 = ur_wrist_frame(TORCH, self, *pose_matrices(pose))
        psi = _atan2(p6[:, 1], p6[:, 0])
        t = q_in * self.s
        return _branch_signs(self.branch, q_in, [torch.cos(psi - t[:, 0]), torch.sin(t[:, 4]), torch.sin(t[:, 2])])

    def forward(self, pose: torch.Tensor, q_in: torch.Tensor | None = None) -> torch.Tensor:
        """q [N, 6] rad on this module's branch, or per row on the branch of ``q_in`` [N, 6] rad
        (NaN rows: this module's branch)."""
        shoulder, wrist, elbow = self.branch if q_in is None else self.branch_of(pose, q_in)
        r6, p6 = ur_wrist_frame(TORCH, self, *pose_matrices(pose))
        t1, _ = ur_shoulder(TORCH, self, p6, shoulder)
        keep6 = None if q_in is None else q_in[:, 5] * self.s[5]
        t5, t6, t234, c1, s1 = ur_wrist(TORCH, self, r6, t1, wrist, UR_SINGULAR_TORCH, keep6)
        t2, t3 = ur_elbow(TORCH, self, *ur_elbow_plane(TORCH, self, p6, t234, c1, s1), elbow)
        return torch.stack([t1, t2, t3, t234 - t2 - t3, t5, t6], dim=1) * self.s


def _branch_signs(default, q_in: torch.Tensor, indicators: list[torch.Tensor]) -> tuple[torch.Tensor, ...]:
    """±1 [N] per indicator (its sign; 0 counts as +), ``default`` where ``q_in`` has a NaN."""
    known = ~torch.isnan(q_in).any(dim=1)
    return tuple(torch.where(known & ~torch.isnan(v), torch.where(v < 0, -torch.ones_like(v), torch.ones_like(v)),
                             torch.full_like(v, float(d))) for v, d in zip(indicators, default))


def make_ik(description: RobotDescription, family: str | None = None, branch=(1.0, 1.0, 1.0)) -> torch.nn.Module:
    """The IK module of a description: ``family`` "kuka" or "ur", or None = the first that fits."""
    kind = geometry_of(description, family).family
    return (KukaIK if kind == "kuka" else UrIK)(description, branch)


def wrapped_step(q: torch.Tensor, q_previous: torch.Tensor) -> torch.Tensor:
    """q − q_previous wrapped to (−π, π]: the IK does not unwrap turns."""
    return torch.remainder(q - q_previous + math.pi, 2 * math.pi) - math.pi


def rotation_matrices(abc_deg: torch.Tensor) -> torch.Tensor:
    """[N, 3] KUKA A,B,C (deg) → [N, 3, 3] R = Rz(A)·Ry(B)·Rx(C) (as postproc.core.frames, in torch)."""
    a, b, c = (abc_deg * (math.pi / 180.0)).unbind(dim=1)
    rows = abc_entries(torch.cos(a), torch.sin(a), torch.cos(b), torch.sin(b), torch.cos(c), torch.sin(c))
    return torch.stack(rows, dim=1).reshape(-1, 3, 3)

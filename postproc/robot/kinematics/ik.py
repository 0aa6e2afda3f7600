"""The controller's inverse kinematics, closed form, one per arm family (KUKA-type, UR-type).

Each family's formulas are written once, over an array namespace (:class:`Ops`: numpy here,
torch in ``twin.TorchOps``): ``kuka_shoulder`` / ``kuka_elbow`` / ``kuka_wrist`` and
``ur_shoulder`` / ``ur_wrist`` / ``ur_elbow`` solve one branch (shoulder, elbow, wrist flip
given as ±1, a number or a row of them). The numpy geometry classes (:class:`_IkGeometry`,
:class:`_UrIkGeometry`: the controller's IK of ``robot.arm.Robot``, every branch with its
reach) and the torch modules (``twin.KukaIK``, ``twin.UrIK``: one branch inside the exported
graph) run the same functions; what differs is only the backend's arithmetic — the torch
namespace evaluates atan2 / acos / asin in float32 (onnxruntime has no float64 kernel for them)
— and the wrist singularity's tolerance (1e-10 in float64, 1e-3 where an angle comes from
float32).
"""
from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np

from ...core import frames
from ...core.diagnostics import P333, PostprocError
from ..description import RobotDescription
from .chain import Chain


class Ops:
    """The numpy namespace of the IK formulas (``twin.TorchOps`` is torch's)."""

    atan2 = staticmethod(np.arctan2)
    acos = staticmethod(np.arccos)
    asin = staticmethod(np.arcsin)
    sqrt = staticmethod(np.sqrt)
    cos = staticmethod(np.cos)
    sin = staticmethod(np.sin)
    abs = staticmethod(np.abs)
    clip = staticmethod(np.clip)
    where = staticmethod(np.where)
    ones_like = staticmethod(np.ones_like)
    isnan = staticmethod(np.isnan)

    @staticmethod
    def stack(parts) -> np.ndarray:
        return np.stack(parts, axis=-1)

    @staticmethod
    def turn_rows(x: np.ndarray, k: int, q: np.ndarray) -> np.ndarray:
        """R_k(q)ᵀ @ x for x [N, 3, 3], q [N]: undo a turn about coordinate axis k from the left."""
        c, s = np.cos(q)[:, None], np.sin(q)[:, None]
        i, j = [(1, 2), (2, 0), (0, 1)][k]
        out = x.copy()
        out[:, i], out[:, j] = x[:, i] * c + x[:, j] * s, x[:, j] * c - x[:, i] * s
        return out


NUMPY = Ops()


# --------------------------------------------------------------------------- KUKA-type


def kuka_shoulder(ops, g, c, shoulder):
    """A1 of wrist centres ``c`` [N, 3] (relative to A1's origin) on the ``shoulder`` branch
    (+1 in front of the A1 axis, −1 over the top), and the arm plane's coordinates of the wrist
    centre from A2: (θ1, u, w, reach [N] bool, γ0: the elbow's opening)."""
    phi = ops.atan2(c[:, 1], c[:, 0])
    r_xy = ops.sqrt(c[:, 0] * c[:, 0] + c[:, 1] * c[:, 1])
    th1 = phi + (1.0 - shoulder) * (math.pi / 2)
    u = shoulder * r_xy - g.a1
    w = c[:, 2] - g.d1
    kappa = (u * u + w * w - g.l2**2 - g.l3**2) / (2 * g.l2 * g.l3)
    return th1, u, w, ops.abs(kappa) <= 1.0 + 1e-12, ops.acos(ops.clip(kappa, -1.0, 1.0))


def kuka_elbow(ops, g, u, w, gamma0, elbow):
    """A2, A3 (θ2, θ3, rad, before the axis signs) of the ``elbow`` branch (±1)."""
    th3 = g.al3 - g.al2 - elbow * gamma0
    ang = g.al3 - th3  # the forearm's direction before A2's turn
    th2 = ops.atan2(g.L2[1] + g.l3 * ops.sin(ang), g.L2[0] + g.l3 * ops.cos(ang)) - ops.atan2(w, u)
    return th2, th3


def kuka_wrist(ops, g, th1, th2, th3, r_all, flip, a4):
    """The six joint angles [N, 6] (rad, not wrapped) of an arm branch (θ1, θ2, θ3) and wrist
    ``flip`` (±1), ``r_all`` [N, 3, 3] the product of the six axis rotations; at a wrist
    singularity (A5 = 0: only A4 + A6 is defined) A4 is ``a4`` [N] (rad)."""
    s = g.s
    rw = ops.turn_rows(ops.turn_rows(r_all, 2, th1), 1, th2 + th3)  # (Rz(θ1)·Ry(θ2+θ3))ᵀ·R = Rx(α) Ry(β) Rx(γ)
    sbeta = flip * ops.sqrt(rw[:, 0, 1] * rw[:, 0, 1] + rw[:, 0, 2] * rw[:, 0, 2])
    beta = ops.atan2(sbeta, rw[:, 0, 0])
    alpha = ops.atan2(flip * rw[:, 1, 0], -flip * rw[:, 2, 0])
    gam = ops.atan2(flip * rw[:, 0, 1], flip * rw[:, 0, 2])
    singular = ops.abs(sbeta) < 1e-10
    alpha = ops.where(singular, s[3] * a4, alpha)
    gam = ops.where(singular, ops.atan2(rw[:, 2, 1], rw[:, 1, 1]) - alpha, gam)
    return ops.stack([s[0] * th1, s[1] * th2, s[2] * th3, s[3] * alpha, s[4] * beta, s[5] * gam])


# --------------------------------------------------------------------------- UR-type


def ur_shoulder(ops, g, p6, shoulder):
    """A1 of A6 origins ``p6`` [N, 3] on the ``shoulder`` branch: every joint origin from A2 to
    A6 lies y4 off the A1 axis along the shoulder axis Rz(t1)·e_y, so ρ·sin(ψ − t1) = y4.
    (t1, cos t1, sin t1, reach [N] bool)."""
    rho = ops.sqrt(p6[:, 0] * p6[:, 0] + p6[:, 1] * p6[:, 1])
    psi = ops.atan2(p6[:, 1], p6[:, 0])
    ratio = g.y4 / rho
    lateral = ops.asin(ops.clip(ratio, -1.0, 1.0))
    t1 = psi - shoulder * lateral - (1.0 - shoulder) * (math.pi / 2)
    return t1, ops.cos(t1), ops.sin(t1), ops.abs(ratio) <= 1.0


def ur_wrist(ops, g, r6, t1, c1, s1, wrist, keep6, tolerance):
    """A5, A6 and the sum A2 + A3 + A4 (t5, t6, t234) of the ``wrist`` branch (±1); R6 [N, 3, 3]
    the A6 frame's rotation = Rz(t1)·Ry(t234)·Rz(t5)·Ry(t6). Within ``tolerance`` of the wrist
    singularity (sin t5 = 0: only t234 ± t6 is defined) A6 is ``keep6`` [N] (rad, before its
    axis sign; None or NaN rows: the ratio's value) and t234 the rest."""
    a6 = r6[:, :, 1]  # the A6 axis: the shoulder axis turned by t5 about A5
    cos5 = -s1 * a6[:, 0] + c1 * a6[:, 1]
    abs_sin5 = ops.sqrt(a6[:, 2] * a6[:, 2] + (c1 * a6[:, 0] + s1 * a6[:, 1]) ** 2)
    t5 = wrist * ops.atan2(abs_sin5, cos5)
    rp = ops.turn_rows(r6, 2, t1)  # Rz(−t1)·R6 = Ry(t234)·Rz(t5)·Ry(t6)
    singular = abs_sin5 < tolerance
    safe5 = ops.where(singular, ops.ones_like(abs_sin5), wrist * abs_sin5)
    t6 = ops.atan2(rp[:, 1, 2] / safe5, rp[:, 1, 0] / safe5)
    t234 = ops.atan2(rp[:, 2, 1] / safe5, -rp[:, 0, 1] / safe5)
    up = cos5 > 0  # R' = Ry(t234 + t6) (t5 = 0) or Ry(t234 − t6)·Rz(π) (t5 = π)
    total = ops.where(up, ops.atan2(rp[:, 0, 2], rp[:, 0, 0]), ops.atan2(rp[:, 0, 2], -rp[:, 0, 0]))
    keep6 = t6 if keep6 is None else ops.where(ops.isnan(keep6), t6, keep6)
    t6 = ops.where(singular, keep6, t6)
    t234 = ops.where(singular, ops.where(up, total - keep6, total + keep6), t234)
    return t5, t6, t234


def ur_elbow(ops, g, p6, c1, s1, t234, elbow):
    """A2, A3, A4 (t2, t3, t4) of the ``elbow`` branch (±1) and its reach [N] bool: A5's origin
    p5 = p6 − z5·Rz(t1)·Ry(t234)·e_z; in the arm plane the links A2 → A3 → A4 are the planar
    arm u = a2·c2 + a3·c23, w = a2·s2 + a3·s23."""
    c234, s234 = ops.cos(t234), ops.sin(t234)
    u = c1 * (p6[:, 0] - g.z5 * c1 * s234) + s1 * (p6[:, 1] - g.z5 * s1 * s234)
    w = g.z0 - (p6[:, 2] - g.z5 * c234)
    kappa = (u * u + w * w - g.a2**2 - g.a3**2) / (2 * g.a2 * g.a3)
    t3 = elbow * ops.acos(ops.clip(kappa, -1.0, 1.0))
    t2 = ops.atan2(w, u) - ops.atan2(g.a3 * ops.sin(t3), g.a2 + g.a3 * ops.cos(t3))
    return t2, t3, t234 - t2 - t3, ops.abs(kappa) <= 1.0 + 1e-12


# the wrist centre this far (mm) off the A1 axis or more: S bit 0 is the IK's shoulder branch
SHOULDER_MM = 1e-3


class _IkGeometry:
    """Closed-form IK of a KUKA-type arm: A1 about ±Z, A2/A3 about ±Y, spherical wrist
    A4 (±X) · A5 (±Y) · A6 (±X); joint frames parallel to the base at q = 0."""

    def __init__(self, d: RobotDescription):
        flange_chain, tool_matrix = Chain.of(d, tool=False), d.tool_matrix
        o, axes = d.origins, d.axes
        want = [2, 1, 1, 0, 1, 0]  # which base axis each joint turns about
        ok = np.allclose(o[:, 3:], 0.0) and all(abs(abs(axes[j, want[j]]) - 1.0) < 1e-12 for j in range(6))
        ok = ok and np.allclose(o[1:, 1], 0.0) and np.allclose(o[4:6, 2], 0.0)
        if not ok:
            raise PostprocError(
                "the analytic IK needs a KUKA-type arm: joint origins without rotation, axes A1 ±Z, A2/A3/A5 ±Y, "
                "A4/A6 ±X, all origins after A1 in the XZ plane and A4, A5, A6 on one line (spherical wrist)",
                d.path, d.locate("joint", None, 0), 1, P333)
        self.s = np.array([axes[j, want[j]] for j in range(6)])  # axis signs
        self.p1 = o[0, :3]
        self.a1, self.d1 = o[1, 0], o[1, 2]
        self.L2 = np.array([o[2, 0], o[2, 2]])
        self.L3 = np.array([o[3, 0] + o[4, 0], o[3, 2] + o[4, 2]])
        self.l2, self.l3 = float(np.linalg.norm(self.L2)), float(np.linalg.norm(self.L3))
        self.al2, self.al3 = math.atan2(self.L2[1], self.L2[0]), math.atan2(self.L3[1], self.L3[0])
        self.c0 = flange_chain.joints(np.zeros((1, 6)))[1][0, 4]  # wrist centre = A5's origin, on the A4 and A6 axes
        self.flange0 = flange_chain.transforms(np.zeros((1, 6)))[0]
        self.tcp0 = (self.flange0 @ tool_matrix)[:3, 3]
        self.inv_tool = frames.inverse(tool_matrix)

    family = "kuka"
    wrist_index = 4  # the wrist point of S bit 0: A5's origin (the wrist centre)

    def wrist_radius(self, t_tcp: np.ndarray) -> np.ndarray:
        """[N] distance (mm) of the wrist centre of TCP transforms [N, 4, 4] from the A1 axis."""
        t_fl = t_tcp @ self.inv_tool
        c = t_fl[:, :3, 3] - t_fl[:, :3, :3] @ self.flange0[:3, :3].T @ (self.flange0[:3, 3] - self.c0) - self.p1
        return np.hypot(c[:, 0], c[:, 1])

    @property
    def stretched(self) -> float:
        """θ3 (rad) with the forearm in line with the upper arm."""
        return self.al3 - self.al2

    def _wrist_centre(self, t_tcp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(product of the six axis rotations [N, 3, 3], wrist centre relative to A1's origin [N, 3])."""
        t_fl = t_tcp @ self.inv_tool
        r_all = t_fl[:, :3, :3] @ self.flange0[:3, :3].T  # product of the six axis rotations
        c = t_fl[:, :3, 3] - r_all @ (self.flange0[:3, 3] - self.c0)
        return r_all, c - self.p1

    def _arms(self, c: np.ndarray) -> Iterator[tuple[float, float, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
        """The 4 arm branches (A1-A3) of wrist centres [N, 3], in ``branches``' order: (shoulder,
        elbow, reach mask, the elbow's opening γ0, θ1, θ2, θ3) [N] each (rad)."""
        for shoulder in (1.0, -1.0):
            th1, u, w, reach_ok, gamma0 = kuka_shoulder(NUMPY, self, c, shoulder)
            for elbow in (1.0, -1.0):
                th2, th3 = kuka_elbow(NUMPY, self, u, w, gamma0, elbow)
                yield shoulder, elbow, reach_ok, gamma0, th1, th2, th3

    def _wrist(self, th1: np.ndarray, th2: np.ndarray, th3: np.ndarray, r_all: np.ndarray, flip,
               ref: np.ndarray) -> np.ndarray:
        """Principal joint angles [N, 6] (rad) of an arm branch and wrist ``flip`` (±1, or [N]);
        at a wrist singularity A4 stays at the reference ``ref`` [N, 6] (rad)."""
        q = kuka_wrist(NUMPY, self, th1, th2, th3, r_all, flip, ref[:, 3])
        return (q + np.pi) % (2 * np.pi) - np.pi

    def branches(self, t_tcp: np.ndarray, ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The 8 closed-form solutions [8, N, 6] (rad, principal angles) of TCP transforms
        [N, 4, 4] and their reachability [8, N]; ``ref`` [N, 6] (rad) keeps A4 at a wrist
        singularity (A5 = 0, where only A4 + A6 is defined)."""
        r_all, c = self._wrist_centre(t_tcp)
        branches, valid = [], []
        for _, _, reach_ok, _, th1, th2, th3 in self._arms(c):
            for flip in (1.0, -1.0):
                branches.append(self._wrist(th1, th2, th3, r_all, flip, ref))
                valid.append(reach_ok)
        return np.stack(branches), np.stack(valid)

    # clearance (rad) from the elbow's stretched/folded and the wrist's A5 = 0/180° boundaries
    # beyond which a branch's Status is that of its index (far above the float error, ~1e-15)
    _CLEAR = 1e-9

    def arm_table(self, t_tcp: np.ndarray) -> tuple[np.ndarray, list, np.ndarray]:
        """(product of the axis rotations [N, 3, 3], the 4 arm branches (reach, θ1, θ2, θ3) [N]
        each in ``branches``' order, sure [N]): every reaching arm branch clear of the elbow
        (γ0 = 0, π) and wrist (β = 0, π) boundaries and the wrist centre off the A1 axis, so
        that each of the 8 branches has the Status of its index: shoulder·4 + elbow·2 + flip, S
        bit 0 the shoulder (:meth:`Robot.shoulder_status`), bit 1 (A3 beyond stretched) the
        elbow −1, bit 2 (A5 ≤ 0) the flip whose A5 has the sign −1 (:meth:`status_of`)."""
        r_all, c = self._wrist_centre(t_tcp)
        sure = np.hypot(c[:, 0], c[:, 1]) > SHOULDER_MM  # (= wrist_radius: S bit 0 is the shoulder's)
        arms = []
        for _, _, reach_ok, gamma0, th1, th2, th3 in self._arms(c):
            th23 = th2 + th3  # the wrist's β from the first row of Rw = (Rz(θ1)·Ry(θ2+θ3))ᵀ·R
            c23 = np.cos(th23)
            col = np.stack([np.cos(th1) * c23, np.sin(th1) * c23, -np.sin(th23)], axis=-1)
            rw0 = np.einsum("nk,nkj->nj", col, r_all)
            clear = (gamma0 > self._CLEAR) & (gamma0 < np.pi - self._CLEAR) & (np.hypot(rw0[:, 1], rw0[:, 2]) > self._CLEAR)
            sure &= ~reach_ok | clear
            arms.append((reach_ok, th1, th2, th3))
        return r_all, arms, sure

    def status_of(self, arm: np.ndarray, flip: np.ndarray) -> np.ndarray:
        """The Status of arm branch ``arm`` (0..3) with wrist ``flip`` (±1) where sure (:meth:`arm_table`)."""
        return (arm >> 1) | ((arm & 1) << 1) | (((flip * self.s[4]) < 0).astype(int) << 2)

    def status_branch(self, t_tcp: np.ndarray, ref: np.ndarray, status: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The branch of Status ``status`` [N] of each transform, alone: (principal angles [N, 6]
        rad, reach [N], sure [N] as :meth:`arm_table`) as :meth:`branches` computes that branch."""
        r_all, arms, sure = self.arm_table(t_tcp)
        want = 2 * (status & 1) + ((status >> 1) & 1)  # the arm branch (shoulder, elbow)
        flip = np.where(((status >> 2) & 1) == (1 if self.s[4] > 0 else 0), -1.0, 1.0)
        th = np.zeros((3, len(status)))
        reach = np.zeros(len(status), bool)
        for k, (reach_ok, th1, th2, th3) in enumerate(arms):
            mine = want == k
            th[:, mine] = th1[mine], th2[mine], th3[mine]
            reach[mine] = reach_ok[mine]
        return self._wrist(th[0], th[1], th[2], r_all, flip, ref), reach, sure


def ur_geometry(description) -> tuple[np.ndarray, np.ndarray]:
    """The joint origins [6, 6] and axis signs [6] of a UR-type description (the one check of
    the geometry the closed-form UR IK needs, numpy and torch); P333
    for another geometry."""
    o, axes = description.origins, description.axes
    want = [2, 1, 1, 1, 2, 1]
    ok = np.allclose(o[:, 3:], 0.0) and all(abs(abs(axes[j, want[j]]) - 1.0) < 1e-12 for j in range(6))
    ok = ok and np.allclose(axes[1], axes[2]) and np.allclose(axes[1], axes[3])
    ok = ok and np.allclose(o[1, :2], 0.0) and np.allclose(o[2:4, 1:], 0.0) and np.allclose(o[4, [0, 2]], 0.0)
    ok = ok and np.allclose(o[5, :2], 0.0) and np.allclose(o[0, :2], 0.0)
    if not ok:
        raise PostprocError(
            "the UR-type IK needs joint origins without rotation, axes A1 ±Z, A2 = A3 = A4 ±Y, A5 ±Z, A6 ±Y, "
            "A2 above A1, A3 and A4 along X from it, A5 beside A4 (Y), A6 below/above A5 (Z)",
            description.path, description.locate("joint", None, 0), 1, P333)
    return o, np.array([axes[j, want[j]] for j in range(6)])


class _UrIkGeometry:
    """Closed-form IK of a Universal-Robots-type arm (as ``models/ur10.toml``; numpy, all 8 branches;
    ``twin.UrIK`` runs the same formulas in torch): A1 about ±Z; A2 = A3 = A4 about ±Y; A5 about ±Z; A6
    about ±Y; A2 above A1, A3 and A4 along X from it, A5 beside A4 (Y), A6 below A5 (Z)."""

    family = "ur"
    wrist_index = 5  # the wrist point of S bit 0: A6's origin (on the A6 axis)
    stretched = 0.0  # θ3 with the forearm in line with the upper arm

    def __init__(self, d: RobotDescription):
        flange_chain, tool_matrix = Chain.of(d, tool=False), d.tool_matrix
        o, self.s = ur_geometry(d)
        self.z0 = float(o[0, 2] + o[1, 2])
        self.a2, self.a3 = float(o[2, 0]), float(o[3, 0])
        self.y4 = float(o[4, 1])  # A4 → A5 along the shoulder axis
        self.z5 = float(o[5, 2])  # A5 → A6 along Z
        self.inv_end = frames.inverse(flange_chain.end @ tool_matrix)  # A6 frame from the TCP

    def branches(self, t_tcp: np.ndarray, ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """As :meth:`_IkGeometry.branches`; at the wrist singularity (A5 = 0) A6 keeps the reference."""
        t6 = t_tcp @ self.inv_end
        r6, p6 = t6[:, :3, :3], t6[:, :3, 3]
        keep6 = self.s[5] * ref[:, 5]
        branches, valid = [], []
        with np.errstate(divide="ignore", invalid="ignore"):
            for shoulder in (1.0, -1.0):
                t1, c1, s1, lateral_ok = ur_shoulder(NUMPY, self, p6, shoulder)
                for wrist in (1.0, -1.0):
                    t5, t6a, t234 = ur_wrist(NUMPY, self, r6, t1, c1, s1, wrist, keep6, 1e-10)
                    for elbow in (1.0, -1.0):
                        t2, t3, t4, reach_ok = ur_elbow(NUMPY, self, p6, c1, s1, t234, elbow)
                        branches.append(np.stack([t1, t2, t3, t4, t5, t6a], axis=1) * self.s)
                        valid.append(lateral_ok & reach_ok)
        q_all = (np.stack(branches) + np.pi) % (2 * np.pi) - np.pi
        return q_all, np.stack(valid)

"""The controller's inverse kinematics, closed form, one per arm family (KUKA-type, UR-type)."""
from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np

from ...core import frames
from ...core.diagnostics import P333, PostprocError
from ..description import RobotDescription
from .chain import Chain

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
        # A1: the wrist centre's azimuth, in front of the A1 axis or over the top (behind)
        phi = np.arctan2(c[:, 1], c[:, 0])
        r_xy = np.hypot(c[:, 0], c[:, 1])
        for shoulder in (1.0, -1.0):
            th1 = phi if shoulder > 0 else phi + np.pi
            u = shoulder * r_xy - self.a1
            w = c[:, 2] - self.d1
            dist2 = u * u + w * w
            kappa = (dist2 - self.l2**2 - self.l3**2) / (2 * self.l2 * self.l3)
            reach_ok = np.abs(kappa) <= 1.0 + 1e-12
            gamma0 = np.arccos(np.clip(kappa, -1.0, 1.0))
            for elbow in (1.0, -1.0):
                # angle between upper arm and forearm vectors in the arm plane
                th3 = self.al3 - self.al2 - elbow * gamma0
                ang = self.al3 - th3  # direction of the forearm vector before A2's rotation
                w2 = np.stack([self.L2[0] + self.l3 * np.cos(ang), self.L2[1] + self.l3 * np.sin(ang)], axis=-1)
                th2 = np.arctan2(w2[:, 1], w2[:, 0]) - np.arctan2(w, u)
                yield shoulder, elbow, reach_ok, gamma0, th1, th2, th3

    def _wrist(self, th1: np.ndarray, th2: np.ndarray, th3: np.ndarray, r_all: np.ndarray, flip,
               ref: np.ndarray) -> np.ndarray:
        """Principal joint angles [N, 6] (rad) of an arm branch and wrist ``flip`` (±1, or [N])."""
        s = self.s
        q123 = np.stack([s[0] * th1, s[1] * th2, s[2] * th3], axis=-1)
        rw = _rz_ry(th1, th2 + th3).swapaxes(-1, -2) @ r_all  # = Rx(α) Ry(β) Rx(γ)
        sb = flip * np.hypot(rw[:, 0, 1], rw[:, 0, 2])
        beta = np.arctan2(sb, rw[:, 0, 0])
        alpha = np.arctan2(flip * rw[:, 1, 0], -flip * rw[:, 2, 0])
        gam = np.arctan2(flip * rw[:, 0, 1], flip * rw[:, 0, 2])
        singular = np.abs(sb) < 1e-10  # A5 ≈ 0: only A4 + A6 is defined; keep A4 at the reference
        if singular.any():
            alpha = np.where(singular, s[3] * ref[:, 3], alpha)
            gam = np.where(singular, np.arctan2(rw[:, 2, 1], rw[:, 1, 1]) - alpha, gam)
        q = np.concatenate([q123, np.stack([s[3] * alpha, s[4] * beta, s[5] * gam], axis=-1)], axis=-1)
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
    the geometry the closed-form UR IK needs, numpy here and torch in training/arm.py); P333
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
    """Closed-form IK of a Universal-Robots-type arm (as ``models/ur10.toml``; the numpy twin of
    training.arm.UrIK, all 8 branches): A1 about ±Z; A2 = A3 = A4 about ±Y; A5 about ±Z; A6
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
        rho = np.hypot(p6[:, 0], p6[:, 1])
        psi = np.arctan2(p6[:, 1], p6[:, 0])
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = self.y4 / rho
        lateral_ok = np.abs(ratio) <= 1.0
        lateral = np.arcsin(np.clip(ratio, -1.0, 1.0))
        branches, valid = [], []
        for shoulder in (1.0, -1.0):
            t1 = psi - lateral if shoulder > 0 else psi - np.pi + lateral
            c1, s1 = np.cos(t1), np.sin(t1)
            # R' = Rz(−t1)·R6 = Ry(t2 + t3 + t4)·Rz(t5)·Ry(t6)
            rp = np.einsum("nij,njk->nik", _rz_ry(-t1, np.zeros_like(t1)), r6)
            cos5 = np.clip(rp[:, 1, 1], -1.0, 1.0)
            for wrist in (1.0, -1.0):
                t5 = wrist * np.arccos(cos5)
                sin5 = np.sin(t5)
                singular = np.abs(sin5) < 1e-10
                safe = np.where(singular, 1.0, sin5)
                t6a = np.arctan2(rp[:, 1, 2] / safe, rp[:, 1, 0] / safe)
                t234 = np.arctan2(rp[:, 2, 1] / safe, -rp[:, 0, 1] / safe)
                if singular.any():  # R' = Ry(t234 + t6) (t5 = 0) or Ry(t234 − t6)·Rz(π) (t5 = π)
                    t6a = np.where(singular, self.s[5] * ref[:, 5], t6a)
                    total = np.arctan2(rp[:, 0, 2], rp[:, 0, 0] * np.sign(cos5))
                    t234 = np.where(singular, total - np.sign(cos5) * t6a, t234)
                c234, s234 = np.cos(t234), np.sin(t234)
                p5 = p6 - self.z5 * np.stack([c1 * s234, s1 * s234, c234], axis=1)
                u = c1 * p5[:, 0] + s1 * p5[:, 1]
                w = self.z0 - p5[:, 2]
                kappa = (u * u + w * w - self.a2**2 - self.a3**2) / (2 * self.a2 * self.a3)
                reach_ok = lateral_ok & (np.abs(kappa) <= 1.0 + 1e-12)
                for elbow in (1.0, -1.0):
                    t3 = elbow * np.arccos(np.clip(kappa, -1.0, 1.0))
                    t2 = np.arctan2(w, u) - np.arctan2(self.a3 * np.sin(t3), self.a2 + self.a3 * np.cos(t3))
                    t4 = t234 - t2 - t3
                    branches.append(np.stack([t1, t2, t3, t4, t5, t6a], axis=1) * self.s)
                    valid.append(reach_ok)
        q_all = (np.stack(branches) + np.pi) % (2 * np.pi) - np.pi
        return q_all, np.stack(valid)


def _rz_ry(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rz(a)·Ry(b) for angle arrays [N] (radians) → [N, 3, 3]."""
    ca, sa, cb, sb = np.cos(a), np.sin(a), np.cos(b), np.sin(b)
    r = np.empty(a.shape + (3, 3))
    r[..., 0, 0], r[..., 0, 1], r[..., 0, 2] = ca * cb, -sa, ca * sb
    r[..., 1, 0], r[..., 1, 1], r[..., 1, 2] = sa * cb, ca, sa * sb
    r[..., 2, 0], r[..., 2, 1], r[..., 2, 2] = -sb, 0.0, cb
    return r

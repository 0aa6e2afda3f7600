"""The controller's inverse kinematics, closed form, one per arm family (KUKA-type, UR-type),
written once for numpy and torch alike.

Each family's formulas are functions of an *array namespace* ``xp`` (:class:`Ops`: the few
operations they use — trigonometry, ``where``, ``stack``, products of per-row rotations with
constants, a turn of rows) and of a *geometry* ``g`` (the arm's constants, by attribute):

* numpy: :data:`NUMPY` and the geometry classes themselves (:class:`KukaGeometry`,
  :class:`UrGeometry`, numpy constants): :class:`postproc.robot.arm.Robot` solves all 8
  branches of many poses at once (``branches``), FK-checked by its caller;
* torch: ``postproc.robot.kinematics.twin`` (``TORCH``, ``KukaIK``, ``UrIK``: torch modules
  holding the same constants as buffers, :meth:`KukaGeometry.constants`) solves one branch per
  row, differentiable and exported with ``torch.onnx`` inside the models' graphs.

This module never imports torch (the numpy path must not load it: tests/test_lazy_imports.py).
What the two namespaces do differently is numerics, not formulas: torch evaluates atan2 /
acos / asin in float32 (ONNX Runtime has no float64 kernel of them; twin.py's docstring says
why the model's error does not mind), and therefore calls the UR wrist singular within
``UR_SINGULAR_TORCH`` rad of it (1e-3: a float32 t1 leaves ~1e-7 of noise in sin t5, which the
A6 ratio divides by) where numpy, in float64, does within ``UR_SINGULAR`` (1e-10, the FK check's
scale). At a singular wrist numpy keeps A4 (KUKA) / A6 (UR) at a reference configuration's,
torch at 0 (KUKA) / the controller's given angle or the ratio's (UR): the callers pass it.
"""
from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np

from ...core import frames
from ...core.diagnostics import P333, PostprocError
from ..description import RobotDescription
from .chain import Chain

__all__ = ["Ops", "NUMPY", "KukaGeometry", "UrGeometry", "geometry_of", "kuka_wrist_centre", "kuka_shoulder",
           "kuka_elbow", "kuka_wrist", "ur_wrist_frame", "ur_shoulder", "ur_wrist", "ur_elbow_plane", "ur_elbow",
           "SHOULDER_MM", "UR_SINGULAR", "UR_SINGULAR_TORCH"]

# the wrist centre this far (mm) off the A1 axis or more: S bit 0 is the IK's shoulder branch
SHOULDER_MM = 1e-3
# |sin A5| below this: the UR wrist is singular (only A4 + A2 + A3 ± A6 is defined), float64 / float32 trigonometry
UR_SINGULAR, UR_SINGULAR_TORCH = 1e-10, 1e-3
# |sin A5| below this: the KUKA wrist is singular (only A4 + A6 is defined)
KUKA_SINGULAR = 1e-10
HALF_PI = math.pi / 2



def _along(origins: np.ndarray, axes: np.ndarray, want: list[int]) -> bool:
    """The joint origins carry no rotation and joint j turns about base axis ``want[j]`` (±1)."""
    return bool(np.allclose(origins[:, 3:], 0.0) and np.allclose(np.abs(axes[np.arange(6), want]), 1.0, rtol=0, atol=1e-12))

class Ops:
    """An array namespace for the IK formulas: elementwise ``atan2``, ``acos``, ``asin``,
    ``sqrt``, ``hypot``, ``cos``, ``sin``, ``abs``, ``clip``, ``where``, ``isnan``,
    ``zeros_like``, ``ones_like``; ``stack(arrays, axis)``; ``mc(r, c)`` per-row rotations [N, 3, 3]
    times a constant [3, 3], ``mv(r, v)`` times a constant vector [3] → [N, 3]; ``unturn(x, a, b)``
    = (Rz(a)·Ry(b))ᵀ·x for x [N, 3, 3] and angles [N] (b None: Rz(a)ᵀ·x), the turns of A1 and of
    the arm (A2 + A3 ...) undone from the left (numpy: one product of the two turns, torch: row
    mixes, no batched 3×3 product in the graph)."""

    def __init__(self, **functions):
        self.__dict__.update(functions)


NUMPY = Ops(atan2=np.arctan2, acos=np.arccos, asin=np.arcsin, sqrt=np.sqrt, hypot=np.hypot, cos=np.cos, sin=np.sin,
            abs=np.abs, clip=np.clip, where=np.where, isnan=np.isnan, zeros_like=np.zeros_like,
            ones_like=np.ones_like, stack=lambda arrays, axis: np.stack(arrays, axis=axis),
            mc=lambda r, c: r @ c, mv=lambda r, v: r @ v,
            unturn=lambda x, a, b=None: frames.rotation_zy(a, b).swapaxes(-1, -2) @ x)


def _wrap(q):
    """Angles (rad) to (−π, π]."""
    return (q + np.pi) % (2 * np.pi) - np.pi


# --------------------------------------------------------------------------- KUKA-type


def kuka_wrist_centre(xp: Ops, g, r_tcp, p_tcp):
    """(the product of the six axis rotations [N, 3, 3], the wrist centre relative to A1's
    origin [N, 3]) of TCP rotations [N, 3, 3] and positions [N, 3]: the flange from the TCP
    (``tool_offset``: the TCP → flange shift in the TCP frame), the wrist centre (A5's origin,
    on the A4 and A6 axes) ``wrist_offset`` behind it in the flange's turned frame at q = 0."""
    r_all = xp.mc(r_tcp, g.wrist_turn)
    p_flange = p_tcp + xp.mv(r_tcp, g.tool_offset)
    return r_all, p_flange - xp.mv(r_all, g.wrist_offset) - g.p1


def kuka_shoulder(xp: Ops, g, c, shoulder):
    """A1 of a shoulder branch (±1: the wrist centre in front of the A1 axis, or over the top)
    and the arm plane's triangle: (θ1, u, w — the wrist centre from A2 in the arm plane —,
    κ = cos of the elbow's opening (|κ| > 1: out of reach), γ0 the opening) [N] each."""
    phi = xp.atan2(c[:, 1], c[:, 0])
    r_xy = xp.hypot(c[:, 0], c[:, 1])
    th1 = phi + (1.0 - shoulder) * HALF_PI
    u = shoulder * r_xy - g.a1
    w = c[:, 2] - g.d1
    kappa = (u * u + w * w - g.l2**2 - g.l3**2) / (2 * g.l2 * g.l3)
    return th1, u, w, kappa, xp.acos(xp.clip(kappa, -1.0, 1.0))


def kuka_elbow(xp: Ops, g, u, w, gamma0, elbow):
    """(θ2, θ3) [N] of an elbow branch (±1) of the arm plane's triangle (:func:`kuka_shoulder`)."""
    th3 = g.al3 - g.al2 - elbow * gamma0
    ang = g.al3 - th3  # direction of the forearm vector before A2's rotation
    w2x = g.L2[0] + g.l3 * xp.cos(ang)
    w2y = g.L2[1] + g.l3 * xp.sin(ang)
    return xp.atan2(w2y, w2x) - xp.atan2(w, u), th3


def kuka_wrist(xp: Ops, g, th1, th2, th3, r_all, flip, a4=None):
    """Joint angles [N, 6] (rad, not wrapped) of an arm branch (θ1..θ3) and wrist ``flip`` (±1, or
    [N]): (Rz(θ1)·Ry(θ2 + θ3))ᵀ·R = Rx(α)·Ry(β)·Rx(γ). At a wrist singularity (A5 = 0, where only
    A4 + A6 is defined) A4 is ``a4`` [N] (rad, already in joint signs; None: 0) and A6 the rest."""
    s = g.s
    rw = xp.unturn(r_all, th1, th2 + th3)
    sb = flip * xp.hypot(rw[:, 0, 1], rw[:, 0, 2])
    beta = xp.atan2(sb, rw[:, 0, 0])
    alpha = xp.atan2(flip * rw[:, 1, 0], -flip * rw[:, 2, 0])
    gam = xp.atan2(flip * rw[:, 0, 1], flip * rw[:, 0, 2])
    singular = xp.abs(sb) < KUKA_SINGULAR
    alpha = xp.where(singular, xp.zeros_like(alpha) if a4 is None else a4, alpha)
    gam = xp.where(singular, xp.atan2(rw[:, 2, 1], rw[:, 1, 1]) - alpha, gam)
    return xp.stack([s[0] * th1, s[1] * th2, s[2] * th3, s[3] * alpha, s[4] * beta, s[5] * gam], 1)


class KukaGeometry:
    """Closed-form IK of a KUKA-type arm: A1 about ±Z, A2/A3 about ±Y, spherical wrist
    A4 (±X) · A5 (±Y) · A6 (±X); joint frames parallel to the base at q = 0. The constants of
    the formulas above (numpy), P333 for another geometry; all 8 branches of many poses."""

    family = "kuka"
    wrist_index = 4  # the wrist point of S bit 0: A5's origin (the wrist centre)
    # the constants the formulas read: arrays (torch: buffers), numbers
    ARRAYS = ("s", "p1", "L2", "wrist_turn", "wrist_offset", "tool_offset")
    NUMBERS = ("a1", "d1", "l2", "l3", "al2", "al3")

    def __init__(self, d: RobotDescription):
        flange_chain, tool_matrix = Chain.of(d, tool=False), d.tool_matrix
        o, axes = d.origins, d.axes
        want = [2, 1, 1, 0, 1, 0]  # which base axis each joint turns about
        ok = _along(o, axes, want) and np.allclose(o[1:, 1], 0.0) and np.allclose(o[4:6, 2], 0.0)
        if not ok:
            raise PostprocError(
                "the analytic IK needs a KUKA-type arm: joint origins without rotation, axes A1 ±Z, A2/A3/A5 ±Y, "
                "A4/A6 ±X, all origins after A1 in the XZ plane and A4, A5, A6 on one line (spherical wrist)",
                d.path, d.locate("joint", None, 0), 1, P333)
        self.s = axes[np.arange(6), want]  # axis signs
        self.p1 = o[0, :3]
        self.a1, self.d1 = float(o[1, 0]), float(o[1, 2])
        self.L2 = np.array([o[2, 0], o[2, 2]])
        self.L3 = np.array([o[3, 0] + o[4, 0], o[3, 2] + o[4, 2]])
        self.l2, self.l3 = float(np.linalg.norm(self.L2)), float(np.linalg.norm(self.L3))
        self.al2, self.al3 = math.atan2(self.L2[1], self.L2[0]), math.atan2(self.L3[1], self.L3[0])
        self.c0 = flange_chain.joints(np.zeros((1, 6)))[1][0, 4]  # wrist centre = A5's origin, on the A4 and A6 axes
        flange0 = flange_chain.transforms(np.zeros((1, 6)))[0]
        self.tcp0 = (flange0 @ tool_matrix)[:3, 3]
        inv_tool = frames.inverse(tool_matrix)
        self.wrist_turn = inv_tool[:3, :3] @ flange0[:3, :3].T  # TCP rotation → product of the axis rotations
        self.tool_offset = inv_tool[:3, 3]  # TCP → flange, in the TCP frame
        self.wrist_offset = flange0[:3, 3] - self.c0  # wrist centre → flange at q = 0

    def constants(self) -> dict:
        """{name: value} of the constants the formulas read (:data:`ARRAYS`, :data:`NUMBERS`)."""
        return {name: getattr(self, name) for name in self.ARRAYS + self.NUMBERS}

    def wrist_radius(self, t_tcp: np.ndarray) -> np.ndarray:
        """[N] distance (mm) of the wrist centre of TCP transforms [N, 4, 4] from the A1 axis."""
        c = self._wrist_centre(t_tcp)[1]
        return np.hypot(c[:, 0], c[:, 1])

    @property
    def stretched(self) -> float:
        """θ3 (rad) with the forearm in line with the upper arm."""
        return self.al3 - self.al2

    def _wrist_centre(self, t_tcp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:func:`kuka_wrist_centre` of TCP transforms [N, 4, 4]."""
        return kuka_wrist_centre(NUMPY, self, t_tcp[:, :3, :3], t_tcp[:, :3, 3])

    def _arms(self, c: np.ndarray) -> Iterator[tuple]:
        """The 4 arm branches (A1-A3) of wrist centres [N, 3], in ``branches``' order: (shoulder,
        elbow, reach mask, the elbow's opening γ0, θ1, θ2, θ3) [N] each (rad)."""
        for shoulder in (1.0, -1.0):
            th1, u, w, kappa, gamma0 = kuka_shoulder(NUMPY, self, c, shoulder)
            reach_ok = np.abs(kappa) <= 1.0 + 1e-12
            for elbow in (1.0, -1.0):
                th2, th3 = kuka_elbow(NUMPY, self, u, w, gamma0, elbow)
                yield shoulder, elbow, reach_ok, gamma0, th1, th2, th3

    def _wrist(self, th1: np.ndarray, th2: np.ndarray, th3: np.ndarray, r_all: np.ndarray, flip,
               ref: np.ndarray) -> np.ndarray:
        """Principal joint angles [N, 6] (rad) of an arm branch and wrist ``flip`` (±1, or [N]);
        A4 at the reference ``ref`` [N, 6] (rad) where the wrist is singular."""
        return _wrap(kuka_wrist(NUMPY, self, th1, th2, th3, r_all, flip, self.s[3] * ref[:, 3]))

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


# --------------------------------------------------------------------------- UR-type


def ur_wrist_frame(xp: Ops, g, r_tcp, p_tcp):
    """The A6 frame (rotation [N, 3, 3], origin [N, 3] on the A6 axis) of TCP rotations and
    positions: R6 = Rz(t1)·Ry(t2+t3+t4)·Rz(t5)·Ry(t6) with t_j = s_j·q_j (every joint frame
    parallel to the base at q = 0)."""
    return xp.mc(r_tcp, g.inv_end[:3, :3]), p_tcp + xp.mv(r_tcp, g.inv_end[:3, 3])


def ur_shoulder(xp: Ops, g, p6, shoulder):
    """(t1 [N] of a shoulder branch (±1), y4/ρ [N]: |y4/ρ| > 1 is out of reach). Every joint
    origin from A2 to A6 lies in the plane y4 off the A1 axis along the shoulder axis
    ŷ1 = Rz(t1)·e_y, so −sin t1·x6 + cos t1·y6 = y4, i.e. ρ·sin(ψ − t1) = y4."""
    rho = xp.hypot(p6[:, 0], p6[:, 1])
    psi = xp.atan2(p6[:, 1], p6[:, 0])
    ratio = g.y4 / rho
    lateral = xp.asin(xp.clip(ratio, -1.0, 1.0))
    return psi - shoulder * lateral - (1.0 - shoulder) * HALF_PI, ratio


def ur_wrist(xp: Ops, g, r6, t1, wrist, singular_below: float, keep6=None):
    """(t5, t6, a = t2 + t3 + t4, cos t1, sin t1) [N] of a wrist branch (±1) on shoulder angle
    ``t1``. The A6 axis a6 = R6·e_y is ŷ1 turned by t5 about the A5 axis: cos t5 = ŷ1·a6 and
    |sin t5| = |ŷ1 × a6|; R' = Rz(−t1)·R6 = Ry(a)·Rz(t5)·Ry(t6): row 1 = sin t5·(cos t6, ·,
    sin t6), column 1 = (−cos a·sin t5, ·, sin a·sin t5). Within ``singular_below`` of
    |sin t5| = 0 only a ± t6 is defined (R' = Ry(a + t6) or Ry(a − t6)·Rz(π)): A6 keeps
    ``keep6`` [N] (rad, in joint signs; its NaN rows and None: the ratio's) and a takes the rest."""
    c1, s1 = xp.cos(t1), xp.sin(t1)
    a6 = r6[:, :, 1]
    cos5 = -s1 * a6[:, 0] + c1 * a6[:, 1]
    abs_sin5 = xp.sqrt(a6[:, 2] ** 2 + (c1 * a6[:, 0] + s1 * a6[:, 1]) ** 2)
    t5 = wrist * xp.atan2(abs_sin5, cos5)
    rp = xp.unturn(r6, t1)
    sin5 = wrist * abs_sin5
    singular = abs_sin5 < singular_below
    safe5 = xp.where(singular, xp.ones_like(sin5), sin5)
    t6 = xp.atan2(rp[:, 1, 2] / safe5, rp[:, 1, 0] / safe5)
    t234 = xp.atan2(rp[:, 2, 1] / safe5, -rp[:, 0, 1] / safe5)
    keep = t6 if keep6 is None else xp.where(xp.isnan(keep6), t6, keep6)
    up = cos5 > 0
    total = xp.where(up, xp.atan2(rp[:, 0, 2], rp[:, 0, 0]), xp.atan2(rp[:, 0, 2], -rp[:, 0, 0]))
    t6 = xp.where(singular, keep, t6)
    t234 = xp.where(singular, xp.where(up, total - keep, total + keep), t234)
    return t5, t6, t234, c1, s1


def ur_elbow_plane(xp: Ops, g, p6, t234, c1, s1):
    """(u, w, κ) [N]: A5's origin p5 = p6 − z5·Rz(t1)·Ry(a)·e_z in the arm plane (along
    Rz(t1)·e_x and −Z, from A2), where the links A2 → A3 → A4 are the planar arm
    u = a2·c2 + a3·c23, w = a2·s2 + a3·s23; κ = cos t3 (|κ| > 1: out of reach)."""
    c234, s234 = xp.cos(t234), xp.sin(t234)
    p5x = p6[:, 0] - g.z5 * (c1 * s234)
    p5y = p6[:, 1] - g.z5 * (s1 * s234)
    p5z = p6[:, 2] - g.z5 * c234
    u = c1 * p5x + s1 * p5y
    w = g.z0 - p5z
    return u, w, (u * u + w * w - g.a2**2 - g.a3**2) / (2 * g.a2 * g.a3)


def ur_elbow(xp: Ops, g, u, w, kappa, elbow):
    """(t2, t3) [N] of an elbow branch (±1) of the planar arm (:func:`ur_elbow_plane`)."""
    t3 = elbow * xp.acos(xp.clip(kappa, -1.0, 1.0))
    return xp.atan2(w, u) - xp.atan2(g.a3 * xp.sin(t3), g.a2 + g.a3 * xp.cos(t3)), t3


class UrGeometry:
    """Closed-form IK of a Universal-Robots-type arm (as ``models/ur10.toml``): A1 about ±Z;
    A2 = A3 = A4 about ±Y; A5 about ±Z; A6 about ±Y; A2 above A1, A3 and A4 along X from it, A5
    beside A4 (Y), A6 below A5 (Z) — the standard DH form (d1, a2, a3, d4, d5, d6) of Hawkins'
    solution. The constants of the formulas above (numpy), P333 for another geometry; all 8
    branches of many poses."""

    family = "ur"
    wrist_index = 5  # the wrist point of S bit 0: A6's origin (on the A6 axis)
    stretched = 0.0  # θ3 with the forearm in line with the upper arm
    ARRAYS = ("s", "inv_end")
    NUMBERS = ("z0", "a2", "a3", "y4", "z5")

    def __init__(self, d: RobotDescription):
        o, axes = d.origins, d.axes
        want = [2, 1, 1, 1, 2, 1]
        ok = _along(o, axes, want) and np.allclose(axes[1], axes[2]) and np.allclose(axes[1], axes[3])
        ok = ok and np.allclose(o[1, :2], 0.0) and np.allclose(o[2:4, 1:], 0.0) and np.allclose(o[4, [0, 2]], 0.0)
        ok = ok and np.allclose(o[5, :2], 0.0) and np.allclose(o[0, :2], 0.0)
        if not ok:
            raise PostprocError(
                "the UR-type IK needs joint origins without rotation, axes A1 ±Z, A2 = A3 = A4 ±Y, A5 ±Z, A6 ±Y, "
                "A2 above A1, A3 and A4 along X from it, A5 beside A4 (Y), A6 below/above A5 (Z)",
                d.path, d.locate("joint", None, 0), 1, P333)
        self.s = axes[np.arange(6), want]  # axis signs
        # the chain at q = 0 in the base frame: A2 at height z0, upper arm and forearm along X,
        # the wrist offsets along Y (y4 = A4 → A5) and Z (z5 = A5 → A6), then the flange
        self.z0 = float(o[0, 2] + o[1, 2])
        self.a2, self.a3 = float(o[2, 0]), float(o[3, 0])
        self.y4 = float(o[4, 1])  # A4 → A5 along the shoulder axis
        self.z5 = float(o[5, 2])  # A5 → A6 along Z
        self.inv_end = frames.inverse(d.flange_matrix @ d.tool_matrix)  # A6 frame from the TCP

    constants = KukaGeometry.constants

    def branches(self, t_tcp: np.ndarray, ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """As :meth:`KukaGeometry.branches`; at the wrist singularity (A5 = 0) A6 keeps the reference."""
        r6, p6 = ur_wrist_frame(NUMPY, self, t_tcp[:, :3, :3], t_tcp[:, :3, 3])
        keep6 = self.s[5] * ref[:, 5]
        branches, valid = [], []
        for shoulder in (1.0, -1.0):
            with np.errstate(divide="ignore", invalid="ignore"):
                t1, ratio = ur_shoulder(NUMPY, self, p6, shoulder)
            lateral_ok = np.abs(ratio) <= 1.0
            for wrist in (1.0, -1.0):
                t5, t6, t234, c1, s1 = ur_wrist(NUMPY, self, r6, t1, wrist, UR_SINGULAR, keep6)
                u, w, kappa = ur_elbow_plane(NUMPY, self, p6, t234, c1, s1)
                reach_ok = lateral_ok & (np.abs(kappa) <= 1.0 + 1e-12)
                for elbow in (1.0, -1.0):
                    t2, t3 = ur_elbow(NUMPY, self, u, w, kappa, elbow)
                    branches.append(np.stack([t1, t2, t3, t234 - t2 - t3, t5, t6], axis=1) * self.s)
                    valid.append(reach_ok)
        return _wrap(np.stack(branches)), np.stack(valid)


def geometry_of(description: RobotDescription, family: str | None = None) -> KukaGeometry | UrGeometry:
    """The closed-form IK geometry of a description: ``family`` "kuka" or "ur", or None = the
    first that fits (P333 naming both where neither does)."""
    if family == "ur":
        return UrGeometry(description)
    try:
        return KukaGeometry(description)
    except PostprocError as kuka:
        if family == "kuka":
            raise
        try:
            return UrGeometry(description)
        except PostprocError as ur:
            raise PostprocError(f"no closed-form IK for this arm: {kuka.message}; or {ur.message}",
                                ur.path, ur.line, ur.col, ur.code) from None

"""Kinematic + compliance identification: the robot's error as the nominal arm with
identified parameters, fitted by least squares on the measured points.

The controller sends joint angles q = IK_nominal(P) for a commanded pose P. The real arm
turns its joints to q + δq and its TCP lands at FK_identified(q + δq), so

    Ê(P) = P − FK_identified(q + δq(q, s)),      q = IK_nominal(P)

with these parameter groups (all small; the fit is Levenberg–Marquardt with the geometric
Jacobian and a Gaussian prior toward the nominal arm that settles the directions the
measurements do not see — e.g. a zero offset and a placement turned about its own joint axis
are one parameter. Its weight is the residual variance per coordinate a first fit leaves
(``prior="auto"``): each parameter ~ N(0, its typical size²) against what the model does not
explain. Directions the poses hardly see stay near nominal instead of taking up what is
particular to those poses; on the IPA UR10, trained on Series C, that alone took Series B
from 0.55 to 0.52 mm mean):

* ``placement``: each joint frame off by a small rigid motion (rotation vector, offset; 6
  per joint) — link lengths, axis directions, mastering;
* ``base`` (6) and ``tool`` (TCP offset, 3): the measured frames; the tool offset is a shift
  fixed to the flange, carried to any other TCP as it is;
* ``mount`` (3, only with data of two or more tools, ``tools``): the tool mount's rotation on
  the flange, Rot(ω)·t for each row's TCP t — what moves tools with other lever arms
  differently. One tool cannot tell it from the shift (ω × t is a constant there); two tools
  leave the rotation about the line between their TCPs, three not on a line none;
* ``zero``: joint zero offsets (6);
* ``compliance``: δq_j = c_j·τ_j(q), τ the gravity torques of the arm (masses in the robot
  description) — joint stiffness; with data measured at known loads (``fit``'s ``loads``: mass,
  centre of mass on the flange per row) τ takes each row's load in place of the description's
  payload, its torque exact from the mass and centre (``Arm.torque_terms``): the model is then
  load-aware (``load_reference_``; the graph's ``load`` input), and being physical it carries the
  stiffness it identified to loads between and beyond those measured (the compliance group is
  then always kept: it is what carries the load);
* ``backlash``: δq_j = −b_j·s_j, s_j the sign of joint j's motion from the previous pose
  (the visiting order) — lost motion; only when the order is known (``previous``);
* ``ripple``: δq_j += a·sin(n·q_j) + b·cos(n·q_j) for (joint, order) pairs — gear
  transmission error. The orders are *searched*, not assumed: after the fit of the other
  groups, every joint and order 1…``max_order`` is a candidate; per joint the order that
  explains most of the residual (orthogonal to the parameters already in) is added while its
  χ² gain beats a Bonferroni-style threshold. The orders are fitted on top of the physical
  groups, which keep the values they have without them (``staged``): ripple terms fitted at
  the angles the data visited do not extrapolate, and outside the trained joint arcs the
  graph leaves them out — there the physical part must be the one fitted without them (on
  the IPA UR10 a joint fit let the geometry lean on 87 orders: Series B 0.92 mm against
  0.50 staged, C held out 0.067 against 0.10).

Everything stays in torch (float64), so the same functions are fitted here and exported to
ONNX with the IK of the nominal arm in front of them (``KinematicErrorModule``, which
evaluates the fitted model with one forward kinematics: see there).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import torch

from ...core import frames
from ...core.diagnostics import P505, P508, P519, PostprocError
from ...robot.description import RobotDescription
from ...robot.kinematics import batch_last as bl
from ...robot.kinematics.twin import (
    Arm,
    _t,
    at_tool,
    axis_rotations,
    coupling_pairs,
    make_ik,
    mc,
    mv,
    rotation_log,
    rotation_matrices,
    small_rotation,
    small_transform,
    wrapped_step,
)
from .estimator import Estimator
from .features import inside_ranges, measured_loads, motion_signs

__all__ = [
    "Layout", "KinematicModel", "KinematicErrorModule", "GROUPS", "DEFAULT_GROUPS", "unseparated_mount",
    "nominal_digest", "residual_variance", "prior_scales", "choose_branch",
]

GROUPS = ("placement", "base", "tool", "mount", "tool_rotation", "zero", "compliance", "coupling", "backlash")
DEFAULT_GROUPS = GROUPS
# compliance with unknown link masses / lever arms: joint j deflects by Σ_i k_ji·τ_ji over the
# links i ≥ j it carries (21 pairs), τ_ji the gravity torque of link i alone about joint j
COUPLING_J, COUPLING_I = coupling_pairs(6)
N_COUPLING = len(COUPLING_J)
COUPLING_ONEHOT = torch.nn.functional.one_hot(torch.tensor(COUPLING_J), 6).to(torch.float64)  # [21, 6]
# the prior's unit sizes: 1 mrad (0.057°) for angles, 1 mm for offsets
PRIOR_RAD, PRIOR_MM = 1e-3, 1.0
# the prior's weight (mm² per typical size²) of the first fit, and its floor: it decides only
# what the data do not see at all (prior="auto" then sets it to the residual variance)
WEAK_PRIOR = 1e-3
# a pose whose IK does not bring the nominal arm back onto it (mm) is out of reach
REACH_TOLERANCE_MM = 0.01
# rows whose joint angles put the nominal arm farther than this from the row's pose (mm) are
# not this robot's angles for that pose (a planner's numerical IK leaves < 1 mm on IPA)
JOINTS_TOLERANCE_MM = 5.0
# at most this share of the rows is dropped (named in a warning) as out of reach / off; more
# is refused (P508): the robot description or the data is wrong
DROP_AT_MOST = 0.01
# joint steps below this (rad) count as no motion: float32 IK noise is ~1e-7 rad
SIGN_DEADBAND = 2e-6
# orientation residuals (rad) enter the least squares times a lever (mm/rad): first this one
# (1 mrad weighs as 1 mm: a 1 m lever), then the ratio of the rms position residual to the rms
# orientation residual of that fit (each kind weighed by what it leaves unexplained: noise
# and unmodelled error), within LEVER_RANGE
LEVER_MM = 1000.0
LEVER_RANGE = (10.0, 10000.0)
# the prior's unit sizes of a campaign's frame (rows measured in another tracker set-up: ``fit``'s
# ``campaigns``), each after its own rigid registration: 10 mrad, 10 mm — a weak prior, the
# frames are the data's to fix; and of its own tool (reflector) offset, along the TCP's axes
# and joint zero offsets (re-mastered axes: 5 mrad, as update.DRIFT) — what ``--update`` re-fits
# between campaigns
CAMPAIGN_RAD, CAMPAIGN_MM, CAMPAIGN_ZERO_RAD = 1e-2, 10.0, 5e-3
CAMPAIGN_SIZE = 15  # per campaign beyond the first: rotation vector (3), offset (3), tool offset (3), zeros (6)


def nominal_digest(description: RobotDescription) -> str:
    """sha256 of what identified parameters are relative to: the nominal chain (joint frames,
    axes, link masses and centres of mass), flange, tool, payload and HOME (for the approach
    from HOME); not the name, limits or comments. A re-fit refuses another digest (P318)."""
    import hashlib

    numbers = [np.r_[j.origin, j.axis, j.mass, j.com] for j in description.joints]
    numbers += [description.flange, description.tool, np.r_[description.payload_mass, description.payload_com],
                description.home_q]
    text = ";".join(",".join(f"{float(v):.9g}" for v in np.ravel(a)) for a in numbers)
    return hashlib.sha256(text.encode()).hexdigest()


def prior_scales(layout: "Layout", tau: np.ndarray) -> np.ndarray:
    """A typical size of every parameter of ``layout`` (rad, mm, rad/Nm): the prior's unit. The
    compliance and coupling terms' from the largest torque terms ``tau`` [N, 27] of the rows
    (a deflection of PRIOR_RAD there)."""
    tau_max = np.abs(np.asarray(tau, float)).max(axis=0)
    scales = np.where(tau_max > 1e-9, PRIOR_RAD / np.maximum(tau_max, 1e-9), PRIOR_RAD)
    compliance, coupling = scales[:6], scales[6:]
    unit = {"placement": np.tile(np.r_[np.full(3, PRIOR_RAD), np.full(3, PRIOR_MM)], 6),
            "base": np.r_[np.full(3, PRIOR_RAD), np.full(3, PRIOR_MM)], "tool": np.full(3, PRIOR_MM),
            "mount": np.full(3, PRIOR_RAD), "tool_rotation": np.full(3, PRIOR_RAD),
            "zero": np.full(6, PRIOR_RAD), "compliance": compliance, "coupling": coupling,
            "backlash": np.full(6, PRIOR_RAD), "ripple": np.full(2 * len(layout.ripple), PRIOR_RAD)}
    return np.concatenate([unit[name] for name in layout.sizes])


@dataclass
class Layout:
    """Where each parameter group sits in the flat vector θ."""

    groups: tuple[str, ...]
    ripple: list[tuple[int, int]] = field(default_factory=list)  # (joint, order) pairs

    @property
    def sizes(self) -> dict[str, int]:
        size = {"placement": 36, "base": 6, "tool": 3, "mount": 3, "tool_rotation": 3, "zero": 6, "compliance": 6, "coupling": N_COUPLING, "backlash": 6}
        out = {g: size[g] for g in GROUPS if g in self.groups}
        out["ripple"] = 2 * len(self.ripple)
        return out

    @property
    def n(self) -> int:
        return sum(self.sizes.values())

    def slices(self) -> dict[str, slice]:
        out, pos = {}, 0
        for name, k in self.sizes.items():
            out[name] = slice(pos, pos + k)
            pos += k
        return out

    def unpack(self, theta: torch.Tensor) -> dict[str, torch.Tensor]:
        """θ → the group tensors (zeros for groups not identified)."""
        s = self.slices()
        zero = theta.new_zeros

        def get(name: str, shape: tuple[int, ...]) -> torch.Tensor:
            return theta[s[name]].reshape(shape) if name in s else zero(shape)

        return {
            "placement": get("placement", (6, 6)),
            "base": get("base", (6,)),
            "tool": get("tool", (3,)),
            "mount": get("mount", (3,)),
            "tool_rotation": get("tool_rotation", (3,)),
            "zero": get("zero", (6,)),
            "compliance": get("compliance", (6,)),
            "coupling": get("coupling", (N_COUPLING,)),
            "backlash": get("backlash", (6,)),
            "ripple": theta[s["ripple"]].reshape(-1, 2),
        }


def unseparated_mount(tcps: np.ndarray) -> np.ndarray:
    """The directions [k, 3] (unit, flange frame; k = 0…3) of the tool mount's rotation that data
    measured with TCP positions ``tcps`` [T, 3] on the flange cannot tell from a shift of the
    tool: a rotation ω moves TCP t by ω × t, so only ω × (t_i − t_0) is seen. One tool: all
    three; tools on a line: the rotation about that line; three not on a line: none. (The
    rotation about the A6 axis is the A6 zero offset's too: the same for every tool.)"""
    tcps = np.unique(np.round(np.asarray(tcps, dtype=np.float64).reshape(-1, 3), 6), axis=0)
    d = tcps[1:] - tcps[0]
    if not len(d):
        return np.eye(3)
    skew = np.concatenate([np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]]) for x, y, z in d])  # [3(T−1), 3]
    _, sv, vt = np.linalg.svd(skew)
    sv = np.r_[sv, np.zeros(3 - len(sv))]
    return vt[sv <= 1e-3 * max(float(np.abs(d).max()), 1.0)]


def identified_end(arm: Arm, p: dict[str, torch.Tensor], tcp: torch.Tensor) -> torch.Tensor:
    """The identified TCP positions in the last joint's frame for TCP positions ``tcp`` [..., 3]
    on the flange: flange · (Rot(mount)·t + the tool shift), the shift fixed to the flange
    (``tool`` is stored in the description tool's axes)."""
    shift = arm.tool[:3, :3] @ p["tool"]
    on_flange = mv(small_rotation(p["mount"]), tcp) + shift
    return arm.flange[:3, 3] + mv(arm.flange[:3, :3], on_flange)


def identified_chain(arm: Arm, p: dict[str, torch.Tensor], tools: torch.Tensor | None = None) -> dict[str, torch.Tensor]:
    """The identified arm's placements, end (TCP) and base as tensors (differentiable in p);
    with ``tools`` [N, 3] (each row's TCP position on the flange) the end is per row [N, 3]."""
    placements = arm.placements @ small_transform(p["placement"][:, :3], p["placement"][:, 3:])
    if tools is None:
        end = torch.cat([torch.cat([arm.end[:3, :3], identified_end(arm, p, arm.tool[:3, 3])[:, None]], 1),
                         arm.end[3:]], 0)
        if "tool_rotation" in p:  # the TCP frame turned about its own axes (moves no TCP: orientation data only)
            end = end @ small_transform(p["tool_rotation"], torch.zeros(3, dtype=end.dtype))
    else:  # (per-row TCP positions: position only, no orientation is fitted with several tools)
        end = identified_end(arm, p, tools)
    base = small_transform(p["base"][:3], p["base"][3:])
    return {"placements": placements, "end": end, "base": base}


def static_deflection(p: dict[str, torch.Tensor], tau: torch.Tensor) -> torch.Tensor:
    """δq [..., 6] rad of the compliance groups for torque terms ``tau`` [..., 6 + 21]."""
    dq = p["compliance"] * tau[..., :6]
    return dq + (p["coupling"] * tau[..., 6:]) @ COUPLING_ONEHOT.to(tau.dtype)


def joint_error(p: dict[str, torch.Tensor], q: torch.Tensor, signs: torch.Tensor, tau: torch.Tensor,
                ripple_joint: torch.Tensor, ripple_order: torch.Tensor,
                ripple_rows: torch.Tensor | None = None) -> torch.Tensor:
    """δq [N, 6] rad: zero offsets + compliance·τ + Σ_i coupling_ji·τ_ji − backlash·s + Σ ripple
    (``tau`` [N, 6 + 21]: ``Arm.torque_terms``; ``ripple_rows`` [N] 1/0: the rows that have the
    ripple terms, default all)."""
    dq = p["zero"] + static_deflection(p, tau) - p["backlash"] * signs
    if len(ripple_joint):
        phase = q[:, ripple_joint] * ripple_order  # [N, R]
        terms = torch.sin(phase) * p["ripple"][:, 0] + torch.cos(phase) * p["ripple"][:, 1]
        if ripple_rows is not None:
            terms = terms * ripple_rows[:, None]
        onehot = torch.nn.functional.one_hot(ripple_joint, 6).to(q.dtype)  # [R, 6]
        dq = dq + terms @ onehot
    return dq


def jacobian(arm: Arm, layout: Layout, theta: torch.Tensor, q: torch.Tensor, signs: torch.Tensor,
             tau: torch.Tensor, tools: torch.Tensor | None = None, rotation: bool = False,
             ripple_rows: torch.Tensor | None = None) -> tuple[torch.Tensor, ...]:
    """TCP positions [N, 3] of the identified arm, their Jacobian [N, 3, P] w.r.t. θ and the
    sensitivity to each joint angle [N, 3, 6], from one forward pass (geometric Jacobian).
    With ``rotation`` also the TCP's rotation [N, 3, 3] and the same two for its orientation
    (angular velocity in the base frame, rad per unit of θ / of q_j): [N, 3, P], [N, 3, 6].

    A joint angle turns everything after it about its axis ω_j through its origin p_j:
    ∂tcp/∂q_j = ω_j × (tcp − p_j) (and turns the TCP frame by ω_j); the joint-space groups are
    that column times their regressor (1, τ_j, −s_j, sin/cos n·q_j). A placement's small
    rotation turns the rest of the chain about the placement's own axes, its offset shifts it
    along them; the base turns and shifts everything; the tool offset moves along the TCP
    frame's axes, the mount's rotation turns each row's TCP (``tools`` [N, 3] on the flange;
    None: the description's; position only), the tool rotation turns the TCP frame about its
    axes. (For the rotation vectors this is the derivative at 0 applied at θ: |θ| ~ 1e-3 makes
    the difference ~1e-3 relative, which costs Levenberg–Marquardt an iteration, not accuracy.) ``ripple_rows`` [N]
    1/0: the rows with the ripple terms (a re-fit: the graph leaves them out of the trained
    joint ranges), default all."""
    p = layout.unpack(theta)
    chain = identified_chain(arm, p, tools)
    ripple_joint = torch.tensor([j for j, _ in layout.ripple], dtype=torch.long)
    ripple_order = torch.tensor([float(n) for _, n in layout.ripple], dtype=torch.float64)
    dq = joint_error(p, q, signs, tau, ripple_joint, ripple_order, ripple_rows)
    rot, org, tcp = arm.frames(q + dq, **chain)
    n = q.shape[0]
    omega = mv(rot, arm.axes)  # [N, 6, 3]
    lever = tcp[:, None, :] - org  # [N, 6, 3]
    sens = torch.linalg.cross(omega, lever).transpose(1, 2)  # [N, 3, 6]
    eye = torch.eye(3, dtype=q.dtype)
    tcp_rot = rot[:, -1] @ chain["end"][:3, :3] if tools is None else None  # [N, 3, 3] (per-row ends: positions)
    zero3 = torch.zeros(n, 3, 3, dtype=q.dtype)
    cols: dict[str, tuple[torch.Tensor, torch.Tensor]] = {}  # group → (position columns, rotation columns)
    if "placement" in layout.groups:
        before = torch.cat([chain["base"][:3, :3].expand(n, 1, 3, 3), rot[:, :-1]], dim=1)  # frame before joint j
        axes = before @ arm.placements[:, :3, :3]  # [N, 6, 3, 3]: the placement's own axes (columns)
        turn = torch.linalg.cross(axes.transpose(2, 3), lever[:, :, None, :].expand(n, 6, 3, 3))  # [N, 6, k, 3]
        shift = axes.transpose(2, 3)  # [N, 6, k, 3]
        cols["placement"] = (torch.cat([turn, shift], dim=2).permute(0, 3, 1, 2).reshape(n, 3, 36),
                             torch.cat([shift, torch.zeros_like(shift)], dim=2).permute(0, 3, 1, 2).reshape(n, 3, 36))
    if "base" in layout.groups:
        turn = torch.linalg.cross(eye[None].expand(n, 3, 3), (tcp - chain["base"][:3, 3])[:, None, :].expand(n, 3, 3))
        cols["base"] = (torch.cat([turn.transpose(1, 2), eye.expand(n, 3, 3)], dim=2),
                        torch.cat([eye.expand(n, 3, 3), zero3], dim=2))
    if "tool" in layout.groups:
        cols["tool"] = (rot[:, -1] @ arm.end[:3, :3], zero3)
    if "mount" in layout.groups:
        t = arm.tool[:3, 3].expand(n, 3) if tools is None else tools
        turn = torch.linalg.cross(eye[None].expand(n, 3, 3), t[:, None, :].expand(n, 3, 3))  # e_k × t, rows k
        cols["mount"] = (rot[:, -1] @ arm.flange[:3, :3] @ turn.transpose(1, 2), zero3)
    if "tool_rotation" in layout.groups:
        cols["tool_rotation"] = (zero3, tcp_rot)
    sens_rot = omega.transpose(1, 2)  # [N, 3, 6]
    for name, joint_cols in _joint_columns(layout, q, signs, tau, ripple_joint, ripple_order, ripple_rows).items():
        cols[name] = (joint_cols(sens), joint_cols(sens_rot) if rotation else None)  # (position only: not built)
    names = [name for name in layout.sizes if layout.sizes[name]]
    jac = torch.cat([cols[name][0] for name in names], dim=2)
    if not rotation:
        return tcp, jac, sens
    return tcp, jac, sens, tcp_rot, torch.cat([cols[name][1] for name in names], dim=2), sens_rot


def residual_variance(jac: torch.Tensor, covariance: torch.Tensor, sigma2: torch.Tensor | float,
                      batch_last: bool = False) -> torch.Tensor:
    """Per target and coordinate [N, 3] the variance of E − Ê: σ² + diag(J_t C J_tᵀ) (the
    model part clipped at 0) for target Jacobians ``jac`` [N, 3, P]; ``batch_last``: ``jac``
    [P, M] (the exported graph's layout, M = 3N) → [M]. One rule, used by
    ``uncertainty.position_std`` and by the exported graph (``KinematicErrorModule``)."""
    if batch_last:  # (one GEMM with the parameters first: no transpose of the [P, 3N] Jacobian)
        return sigma2 + ((covariance @ jac) * jac).sum(dim=0).clamp(min=0.0)
    return sigma2 + ((jac @ covariance) * jac).sum(dim=-1).clamp(min=0.0)


def campaign_frames(tcp: torch.Tensor, jac: torch.Tensor, sens: torch.Tensor, frames: torch.Tensor,
                    rows: torch.Tensor, tcp_axes: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The identified TCPs [N, 3] seen in each row's campaign: R(ω_k)·(tcp + R_tcp·d_k + S·z_k) + t_k
    for the rows of campaign k ≥ 1 (``rows`` [N, K − 1] one-hot; ``frames`` [15(K − 1)]: rotation
    vector rad, offset mm, tool offset d mm along the TCP's axes ``tcp_axes`` [N, 3, 3], joint zero
    offsets z rad to first order through the joint sensitivities S = ``sens`` [N, 3, 6]), with the
    Jacobian [N, 3, P] turned and the campaigns' columns [N, 3, 15(K − 1)] appended (e_i × the
    point, e_i, R·R_tcp, R·S; as the base, tool and zero groups', at θ), and S turned."""
    per_row = rows @ frames.reshape(-1, CAMPAIGN_SIZE)  # [N, 15] (the first campaign's rows: 0)
    turn = small_rotation(per_row[:, :3])  # [N, 3, 3]
    turned = mv(turn, tcp + mv(tcp_axes, per_row[:, 6:9]) + mv(sens, per_row[:, 9:]))
    n = tcp.shape[0]
    eye = torch.eye(3, dtype=tcp.dtype)
    cross = torch.linalg.cross(eye[None].expand(n, 3, 3), turned[:, None, :].expand(n, 3, 3)).transpose(1, 2)
    cols = torch.cat([cross, eye.expand(n, 3, 3), turn @ tcp_axes, turn @ sens], dim=2)  # [N, 3, 15]
    cols = (cols[:, :, None, :] * rows[:, None, :, None]).reshape(n, 3, -1)
    return turned + per_row[:, 3:6], torch.cat([turn @ jac, cols], dim=2), turn @ sens


def to_first_frame(measured: torch.Tensor, per_row: torch.Tensor, tcp_axes: torch.Tensor,
                   sens: torch.Tensor) -> torch.Tensor:
    """Measured points [N, 3] of rows of campaigns (``per_row`` [N, 15]: each row's campaign's
    frame, tool offset and zero offsets, as ``campaign_frames``; ``tcp_axes`` [N, 3, 3], ``sens``
    [N, 3, 6]) in the first campaign's frame, at its tool and zeros: R(ω)ᵀ(m − t) − R_tcp·d − S·z."""
    return (mv(small_rotation(per_row[:, :3]).transpose(1, 2), measured - per_row[:, 3:6])
            - mv(tcp_axes, per_row[:, 6:9]) - mv(sens, per_row[:, 9:]))


def tcp_axes_of(poses: np.ndarray) -> torch.Tensor:
    """[N, 3, 3] the TCP's axes at commanded poses [N, 6] (a campaign's tool offset moves along them)."""
    return torch.as_tensor(frames.rotation_from_abc(np.asarray(poses, dtype=np.float64).reshape(-1, 6)[:, 3:6]))


def _joint_columns(layout: Layout, q: torch.Tensor, signs: torch.Tensor, tau: torch.Tensor,
                   ripple_joint: torch.Tensor, ripple_order: torch.Tensor,
                   ripple_rows: torch.Tensor | None = None) -> dict:
    """The joint-space groups' columns as functions of a sensitivity to the joint angles
    [N, 3, 6] (of the position or of the orientation): that times each regressor."""
    out = {}
    if "zero" in layout.groups:
        out["zero"] = lambda s: s
    if "compliance" in layout.groups:
        out["compliance"] = lambda s: s * tau[:, None, :6]
    if "coupling" in layout.groups:
        out["coupling"] = lambda s: s[:, :, COUPLING_J] * tau[:, None, 6:]
    if "backlash" in layout.groups:
        out["backlash"] = lambda s: -s * signs[:, None, :]
    if len(layout.ripple):
        phase = q[:, ripple_joint] * ripple_order
        rows = 1.0 if ripple_rows is None else ripple_rows[:, None, None]
        out["ripple"] = lambda s: torch.stack([s[:, :, ripple_joint] * rows * torch.sin(phase)[:, None, :],
                                               s[:, :, ripple_joint] * rows * torch.cos(phase)[:, None, :]],
                                              dim=-1).reshape(q.shape[0], 3, -1)  # (traced: not len(q))
    return out


def previous_branch(q_in: torch.Tensor | None, q_previous: torch.Tensor | None) -> torch.Tensor | None:
    """The joint angles [N, 6] whose branch the previous pose is solved on (``approach_signs``):
    the previous target's own (``q_previous``) where known, else this target's (``q_in``)."""
    if q_previous is None or q_in is None:
        return q_in
    return torch.where(torch.isnan(q_previous).any(dim=1, keepdim=True), q_in, q_previous)


def approach_signs(ik: torch.nn.Module, home_q: torch.Tensor, q: torch.Tensor, pose: torch.Tensor,
                   previous: torch.Tensor, q_in: torch.Tensor | None = None, at=None,
                   q_previous: torch.Tensor | None = None, solved: torch.Tensor | None = None) -> torch.Tensor:
    """Approach signs [N, 6] for q = IK(pose) reached from ``previous`` [N, 6]. A row whose
    previous pose is the pose itself (compensate's first target: nothing known before it) is
    taken as reached from HOME, where robot programs start (a joint HOME leaves as it is: +1,
    the side the simulator starts every joint on). ``q_in`` (the controller's angles
    at ``pose``, NaN rows unknown): the previous pose is solved on the same branch. ``at``: the
    row's tool (``arm.at_tool`` bound to it), the previous pose taken onto the IK's tool with it.
    ``q_previous`` (rad: the angles the arm really stood at before each row, the data's
    previous row or the graph's ``previous_joints``, NaN rows unknown) replaces that IK where
    known, with ``q_in``: the previous row may be in another configuration (a flipped wrist) or
    turn (A4 from 179° to −179° turns 358°), which solving it on the row's branch would miss.

    Hard signs, as the simulator's backlash: a ramp over the lost motion (a joint turning back
    by less than it takes it up in part) is more physical, but measured worse on the simulator
    (0.23 vs 0.10 mm max on robot seed 3: a 0.003° step of A1 got a third of its sign).

    ``solved`` [N, 6]: that IK of the previous poses when the caller has it already
    (``KinematicErrorModule.previous_joints``: the row before's where it is that row's pose)."""
    same = (previous == pose).all(dim=1, keepdim=True)
    both = q_previous is not None and q_in is not None
    if solved is None:
        # the previous pose solved on its own target's branch where that is known, else on this one's
        branch = previous_branch(q_in, q_previous)
        previous = previous if at is None else at(previous)
        solved = ik(previous) if branch is None else ik(previous, branch)
    q_prev = torch.where(same, home_q.expand_as(q), solved)
    signs = motion_signs(q, q_prev, eps=SIGN_DEADBAND)
    # a joint that has not moved since HOME is on the side the robot starts it on (the
    # simulator's start sign, +1), not in the middle
    signs = torch.where(same & (signs == 0), torch.ones_like(signs), signs)
    if not both:
        return signs
    # the controller's angles are the joints' own (not wrapped: a wrist flip turns A4 and A6 by
    # about 180°, either way; a turn's change nearly 360°), so the step between them is the
    # motion itself; q and q_prev (the IK of this and the previous pose, wrapped) are q_in and
    # q_previous up to the corrections' few mm: the step is from command to command, which
    # decides a joint that barely moves (a correction of ~1 mm turns a joint by ~0.01°)
    step = wrapped_step(q, q_in) + (q_in - q_previous) - wrapped_step(q_prev, q_previous)
    known = ~(same | torch.isnan(q_previous).any(dim=1, keepdim=True) | torch.isnan(q_in).any(dim=1, keepdim=True))
    return torch.where(known, torch.where(torch.abs(step) > SIGN_DEADBAND, torch.sign(step), torch.zeros_like(step)),
                       signs)


class KinematicErrorModule(torch.nn.Module):
    """pose [N, 6] (+ previous_pose [N, 6]) → Ê [N, 3] mm for an identified arm (ONNX-exportable).

    For speed it runs one forward kinematics, not two: the identified chain (zero offsets and
    the mean compliance deflection folded into the placements, exactly) at the commanded q,
    then the small joint-angle terms (the deflection's variation, backlash, ripple; ≲ 2e-4
    rad) to first order through the geometric Jacobian, ω_j × (tcp − p_j)·δq_j. Gravity
    torques come from the same frames (the fit used the nominal ones: a 1e-3 relative change).
    Ê = P − that, with P the commanded position itself.
    """

    def __init__(self, arm: Arm, ik: torch.nn.Module, layout: Layout, theta: np.ndarray, use_previous: bool,
                 tau_mean: np.ndarray | None = None, load_reference: np.ndarray | None = None):
        super().__init__()
        self.arm, self.ik, self.layout, self.use_previous = arm, ik, layout, use_previous
        # a load-aware model: the torques take each row's load (mass kg, centre of mass mm on the
        # flange), a NaN row this one (None: the description's payload, not an input)
        self.load_aware = load_reference is not None
        self.register_buffer("load_reference", None if load_reference is None else torch.as_tensor(
            np.asarray(load_reference, dtype=np.float64).reshape(4)))
        self.orientation = False  # the orientation part was identified from measured orientations
        self.register_buffer("theta", torch.as_tensor(np.asarray(theta, dtype=np.float64)))
        self.register_buffer("ripple_joint", torch.tensor([j for j, _ in layout.ripple], dtype=torch.long))
        self.register_buffer("ripple_order", torch.tensor([float(n) for _, n in layout.ripple], dtype=torch.float64))
        # the compliance term's mean over the data goes into the zero offsets: what is left to
        # first order is its variation, ~10x smaller (and the neglected second order 100x)
        self.register_buffer("tau_mean", torch.as_tensor(np.zeros(6 + N_COUPLING) if tau_mean is None else tau_mean,
                                                         dtype=torch.float64))
        with torch.no_grad():
            p = layout.unpack(self.theta)
            chain = identified_chain(arm, p)
            turn = axis_rotations(arm.axes, (p["zero"] + static_deflection(p, self.tau_mean))[None, :])[0]  # [6, 3, 3]
            folded = chain["placements"].clone()
            folded[:, :3, :3] = folded[:, :3, :3] @ turn  # R(axis_j, z_j) commutes with the joint's turn
        self.register_buffer("placements", folded)
        self.register_buffer("end", chain["end"])
        self.register_buffer("tool0", torch.as_tensor(np.asarray(arm.description.tool, dtype=np.float64)))
        self.register_buffer("base", chain["base"])
        self._batch_last = self._constants()

    def _constants(self) -> dict[str, torch.Tensor]:
        """The constants of the batch-last evaluation (``_evaluate``), from θ."""
        arm, layout = self.arm, self.layout
        with torch.no_grad():
            p = layout.unpack(self.theta)
            chain = identified_chain(arm, p)
            mount = arm.flange[:3, :3] @ small_rotation(p["mount"])
            return {
                "turns": bl.joint_turns(self.placements, arm.axes), "offsets": self.placements[:, :3, 3],
                "id_turns": bl.joint_turns(chain["placements"], arm.axes), "id_offsets": chain["placements"][:, :3, 3],
                "id_base": chain["base"], "end": self.end[:3, 3],
                # per-row TCPs t on the flange: identified_end = mount-turned t + the tool shift, on the flange
                "end_turn": mount, "end_shift": arm.flange[:3, 3] + arm.flange[:3, :3] @ (arm.tool[:3, :3] @ p["tool"]),
                "tool_turn": self.end[:3, :3] @ arm.tool[:3, :3].T,
                "zero": p["zero"], "compliance": p["compliance"], "coupling": p["coupling"], "backlash": p["backlash"],
                "coupling_sum": COUPLING_ONEHOT.T.contiguous(), "coupling_joints": torch.tensor(COUPLING_J),
                "ripple": p["ripple"],
                "ripple_sum": torch.nn.functional.one_hot(self.ripple_joint, 6).to(torch.float64).T.contiguous(),
            }

    def loads_of(self, load: torch.Tensor | None, n: int) -> torch.Tensor | None:
        """Each row's load [n, 4] for the torques of a load-aware model (``load`` [n, 4]; None or
        a row with a NaN: ``load_reference``); None for a model that is not load-aware."""
        if not self.load_aware:
            return None
        reference = self.load_reference.to(torch.float64)[None, :].expand(n, 4)
        if load is None:
            return reference
        load = load.to(torch.float64)
        unknown = torch.isnan(load.sum(dim=1, keepdim=True))  # (a NaN anywhere in the row)
        return torch.where(unknown, reference, load)

    def joints_of(self, pose: torch.Tensor, q_in: torch.Tensor | None = None) -> torch.Tensor:
        """q [N, 6] rad the controller turns to for float64 ``pose``: the nominal IK on the
        identified branch, or per row on the branch of ``q_in`` [N, 6] rad (the controller's
        angles at or near that pose; NaN rows: the identified branch)."""
        return self.ik(pose) if q_in is None else self.ik(pose, q_in)

    def parts(self, pose: torch.Tensor, previous: torch.Tensor | None = None, q_in: torch.Tensor | None = None,
              ranges: torch.Tensor | None = None, tool: torch.Tensor | None = None, rotation: bool = False,
              approach: torch.Tensor | None = None, q_previous: torch.Tensor | None = None,
              uncertainty: tuple[torch.Tensor, torch.Tensor] | None = None,
              load: torch.Tensor | None = None) -> tuple[torch.Tensor, ...]:
        """(Ê [N, 3], q [N, 6], signs [N, 6], learned [N]) for float64 poses (``q_in``: see
        ``joints_of``); with joint ``ranges`` [6, 2] rad the ripple terms are left out where q
        is outside them (learned = 0 there, else 1). ``tool`` [N, 6]: each row's TCP on the
        flange (NaN rows: the model's own, ``tool0``): the IK solves the flange pose that puts
        that TCP at ``pose`` and the error is the identified arm's at that TCP. With
        ``rotation``: + r̂ [N, 3] rad (``error_at``). ``approach`` [N, 6]: the approach sign of
        each joint to assume (+1, −1, 0 = the middle of the lost motion) in place of the one
        from ``previous``; NaN = from ``previous`` (the contract's ``approach`` input).
        ``q_previous`` [N, 6] rad: the controller's angles at the target before (see
        ``approach_signs``). ``uncertainty`` (covariance [P, P], σ²): + the std of E − Ê [N, 1]
        mm last (the contract's ``error_std``: ``uncertainty``'s module text). ``load`` [N, 4]:
        each row's load (``loads_of``; a load-aware model's torques). Evaluated
        batch-last (``batch_last``): the same quantities as ``error_at`` and, for the std,
        ``jacobian`` with ``residual_variance``, to rounding."""
        at = None if tool is None else (lambda p: at_tool(p, tool, self.tool0))  # noqa: E731
        q = self.joints_of(pose if at is None else at(pose), q_in)
        signs = torch.zeros_like(q)
        if self.use_previous and previous is not None:
            solved = self.previous_joints(q, pose, previous, q_in, tool, q_previous)
            signs = approach_signs(self.ik, self.arm.home_q, q, pose, previous, q_in, at, q_previous, solved)
        if self.use_previous and approach is not None:
            signs = torch.where(torch.isnan(approach), signs, approach)
        learned = torch.ones_like(q[:, 0]) if ranges is None else inside_ranges(q, ranges)
        mask = None if ranges is None else learned
        out = self._evaluate(q, signs, pose, mask, tool, rotation, uncertainty, load)
        return (out[0], q, signs, learned, *out[1:])

    def previous_joints(self, q: torch.Tensor, pose: torch.Tensor, previous: torch.Tensor,
                        q_in: torch.Tensor | None, tool: torch.Tensor | None,
                        q_previous: torch.Tensor | None) -> torch.Tensor:
        """The IK of the previous poses [N, 6] as ``approach_signs`` solves it: where a row's
        previous pose is the row before's pose (program order: compensate passes each target's
        predecessor command), with the same tool and branch, that row's q, which is the same
        number; the other rows solved (only those: gathered, then scattered back)."""
        def before(x: torch.Tensor) -> torch.Tensor:
            return torch.cat([x[:1], x[:-1]])

        def same_rows(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:  # (any NaN: the default branch)
            return (a == b).all(dim=1) | (torch.isnan(a).any(dim=1) & torch.isnan(b).any(dim=1))

        branch = previous_branch(q_in, q_previous)
        shared = (previous == before(pose)).all(dim=1) & (torch.arange(pose.shape[0]) > 0)
        if branch is not None:
            shared = shared & same_rows(branch, before(q_in))
        if tool is not None:
            own = torch.where(torch.isnan(tool), self.tool0.expand_as(tool), tool)
            shared = shared & (own == before(own)).all(dim=1)
        rows = torch.nonzero(~shared).reshape(-1)
        ahead = previous.index_select(0, rows)
        if tool is not None:
            ahead = at_tool(ahead, tool.index_select(0, rows), self.tool0)
        solved = self.ik(ahead) if branch is None else self.ik(ahead, branch.index_select(0, rows))
        return before(q).scatter(0, rows[:, None].expand(-1, q.shape[1]), solved)

    def _evaluate(self, q: torch.Tensor, signs: torch.Tensor, pose: torch.Tensor, learned: torch.Tensor | None,
                  tool: torch.Tensor | None, rotation: bool, uncertainty,
                  load: torch.Tensor | None = None) -> tuple[torch.Tensor, ...]:
        """(Ê [N, 3] [, r̂ [N, 3] rad] [, error_std [N, 1] mm]) at q [N, 6] reached with ``signs``
        for the commanded ``pose`` [N, 6]: ``error_at``'s quantities (and ``_error_std``),
        batch-last (``batch_last``: vectors [3, N], rotations [3, 3, N])."""
        c = self._batch_last
        qt, st = q.t(), signs.t()
        tools = None if tool is None else torch.where(torch.isnan(tool[:, :3]), self.tool0[:3], tool[:, :3]).t()
        end = c["end"] if tools is None else c["end_turn"] @ tools + c["end_shift"][:, None]
        f = bl.frames(c["turns"], c["offsets"], qt, end)
        # [27, N] (the fit's ``torques``: of the identified chain at q, with each row's load)
        tau = bl.torque_terms(self.arm, f, self.loads_of(load, q.shape[0]))
        dq = self._joint_error(qt, st, tau - self.tau_mean[:, None], learned, zero=False)
        omega = f.axes(self.arm.axes)  # [6, 3, N]
        sens = bl.cross(omega, f.tcp[None] - f.origins_stacked(), 1)  # [6, 3, N]
        actual = f.tcp + (sens * dq[:, None, :]).sum(0)
        out = [(pose[:, :3].t() - self.base[:3, :3] @ actual - self.base[:3, 3:4]).t()]
        if rotation:
            last = f.rotations[-1]
            if tool is None:  # the TCP's rotation at q (identified chain, no base)
                reached = bl.mat(last, self.end[:3, :3][:, :, None])
            else:  # each row's TCP frame on the flange, turned as the model's own: R_end·R_tool0ᵀ·R_tool
                abc = torch.where(torch.isnan(tool[:, 3:6]), self.tool0[3:6], tool[:, 3:6])
                reached = bl.mat(bl.mat(last, c["tool_turn"][:, :, None]), bl.abc_rotations(abc))
            m = bl.mat_t(bl.const_mat(self.base[:3, :3], reached), bl.abc_rotations(pose[:, 3:6]))
            turned = rotation_log(m, batch_last=True)
            out.append((turned + self.base[:3, :3] @ (omega * dq[:, None, :]).sum(0)).t())
        if uncertainty is not None:
            rows = learned if learned is not None and len(self.layout.ripple) else None
            out.append(self._error_std(qt, st, tau, tools, rows, *uncertainty))
        return tuple(out)

    def _joint_error(self, qt: torch.Tensor, st: torch.Tensor, tau: torch.Tensor, rows: torch.Tensor | None,
                     zero: bool) -> torch.Tensor:
        """δq [6, N] (``joint_error`` batch-last): + the zero offsets with ``zero`` (else folded)."""
        c = self._batch_last
        dq = c["compliance"][:, None] * tau[:6] + c["coupling_sum"] @ (c["coupling"][:, None] * tau[6:])
        if zero:
            dq = c["zero"][:, None] + dq
        dq = dq - c["backlash"][:, None] * st
        if len(self.layout.ripple):
            phase = qt.index_select(0, self.ripple_joint) * self.ripple_order[:, None]  # [R, N]
            terms = torch.sin(phase) * c["ripple"][:, 0:1] + torch.cos(phase) * c["ripple"][:, 1:2]
            if rows is not None:
                terms = terms * rows[None, :]
            dq = dq + c["ripple_sum"] @ terms
        return dq

    def _error_std(self, qt: torch.Tensor, st: torch.Tensor, tau: torch.Tensor, tools: torch.Tensor | None,
                   rows: torch.Tensor | None, covariance: torch.Tensor, sigma2: torch.Tensor) -> torch.Tensor:
        """The graph's ``error_std`` [N, 1] (``uncertainty``): the position Jacobian of the identified
        chain at q + δq (``jacobian``'s columns, [P, 3, N]) and σ² + diag(J C Jᵀ) (``residual_variance``)."""
        c, arm = self._batch_last, self.arm
        end = c["end"] if tools is None else c["end_turn"] @ tools + c["end_shift"][:, None]
        dq = self._joint_error(qt, st, tau, rows, zero=True)
        g = bl.frames(c["id_turns"], c["id_offsets"], qt + dq, end, base=c["id_base"])
        omega = g.axes(arm.axes)
        lever = g.tcp[None] - g.origins_stacked()  # [6, 3, N]
        sens = bl.cross(omega, lever, 1)  # ∂tcp/∂q_j [6, 3, N]
        n = qt.shape[1]
        blocks = {}
        groups = self.layout.groups
        if "placement" in groups:
            first = (c["id_base"][:3, :3] @ arm.placements[0, :3, :3])[:, :, None].expand(3, 3, n)
            axes = torch.stack([first] + [bl.mat(r, m[:3, :3][:, :, None])
                                          for r, m in zip(g.rotations[:-1], arm.placements[1:])])  # [6, 3, 3(k), N]
            axes = axes.transpose(1, 2)  # [6, k, 3, N]: the placement's own axes
            turn = bl.cross(axes, lever[:, None], 2)
            blocks["placement"] = torch.cat([turn, axes], dim=1).reshape(36, 3, n)
        if "base" in groups:
            turn = bl.unit_crosses(g.tcp - c["id_base"][:3, 3:4])
            blocks["base"] = torch.cat([turn, torch.eye(3, dtype=turn.dtype)[:, :, None].expand(3, 3, n)])
        if "tool" in groups:
            blocks["tool"] = bl.mat(g.rotations[-1], arm.end[:3, :3][:, :, None]).transpose(0, 1)
        if "mount" in groups:
            turn = bl.unit_crosses(arm.tool[:3, 3:4].expand(3, n) if tools is None else tools)
            on_flange = (arm.flange[:3, :3] @ turn.transpose(0, 1).reshape(3, -1)).reshape(3, 3, n).transpose(0, 1)
            blocks["mount"] = (g.rotations[-1][None] * on_flange[:, None]).sum(2)
        if "zero" in groups:
            blocks["zero"] = sens
        if "compliance" in groups:
            blocks["compliance"] = sens * tau[:6, None]
        if "coupling" in groups:
            blocks["coupling"] = sens.index_select(0, c["coupling_joints"]) * tau[6:, None]
        if "backlash" in groups:
            blocks["backlash"] = -sens * st[:, None]
        if len(self.layout.ripple):
            phase = (qt.index_select(0, self.ripple_joint) * self.ripple_order[:, None])[:, None]  # [R, 1, N]
            at_joint = sens.index_select(0, self.ripple_joint)
            if rows is not None:
                at_joint = at_joint * rows
            blocks["ripple"] = torch.stack([at_joint * torch.sin(phase), at_joint * torch.cos(phase)], dim=1).reshape(
                -1, 3, n)
        if "tool_rotation" in groups:  # (turns the TCP frame only: zero in position)
            blocks["tool_rotation"] = torch.zeros_like(sens[:3])
        jac = torch.cat([blocks[name] for name in self.layout.sizes if name in blocks]).reshape(self.layout.n, -1)
        # (the covariance as stored: train --update reads it back from the graph, initializer module.covariance)
        return residual_variance(jac, covariance, sigma2, batch_last=True).reshape(3, n).mean(dim=0).sqrt()[:, None]

    def tool_end(self, tool: torch.Tensor) -> torch.Tensor:
        """The identified TCP positions [N, 3] in the last joint's frame for the TCPs ``tool``
        [N, 6] on the flange (NaN rows: ``tool0``)."""
        t = torch.where(torch.isnan(tool[:, :3]), self.tool0[:3].expand(tool.shape[0], 3), tool[:, :3])
        return identified_end(self.arm, self.layout.unpack(self.theta), t)

    def torques(self, q: torch.Tensor, load: torch.Tensor | None = None) -> torch.Tensor:
        """The gravity torques [N, 6] the model uses: of its own chain at q, without the base
        (gravity acts in the robot's frame, not in the registered one), with each row's ``load``
        (``loads_of``)."""
        rot, org, _ = self.arm.frames(q, placements=self.placements, end=self.end)
        return self.arm.torque_terms(rot, org, self.loads_of(load, q.shape[0]))

    def error_at(self, q: torch.Tensor, signs: torch.Tensor, position: torch.Tensor,
                 learned: torch.Tensor | None = None, tool: torch.Tensor | None = None,
                 attitude: torch.Tensor | None = None, load: torch.Tensor | None = None):
        """Ê [N, 3] for commanded positions [N, 3] whose IK is q [N, 6], reached with ``signs``;
        ``learned`` [N] (1 keep, 0 drop) scales the gear-ripple terms, which do not extrapolate
        outside the trained joint ranges (the physical groups do); ``tool`` [N, 6]: each row's TCP
        on the flange (None: ``tool0``). With the commanded ``attitude`` [N, 3, 3]: (Ê, r̂ [N, 3]
        rad), r̂ the orientation error as the rotation vector of commanded → actual in the base
        frame (the same first order: the identified chain's TCP rotation at q turned by
        Σ ω_j·δq_j; another tool's TCP frame carries the identified turn of the model's own)."""
        p = self.layout.unpack(self.theta)
        p["zero"] = torch.zeros_like(p["zero"])  # (folded into the placements)
        end = self.end if tool is None else self.tool_end(tool)
        rot, org, tcp = self.arm.frames(q, placements=self.placements, end=end)
        tau = self.arm.torque_terms(rot, org, self.loads_of(load, q.shape[0])) - self.tau_mean
        # outside the trained arcs (``learned`` 0) every ripple order goes: fitted on what the
        # physical part leaves at the angles the data visited (low orders included: on the IPA
        # UR10 the orders 1-2 fitted on Series C's arcs made the other series worse, not better)
        dq = joint_error(p, q, signs, tau, self.ripple_joint, self.ripple_order, learned)
        omega = torch.stack([mv(rot[:, j], self.arm.axes[j]) for j in range(6)], dim=1)
        sens = torch.linalg.cross(omega, tcp[:, None, :] - org)  # [N, 6, 3]
        actual = tcp + (sens * dq[..., None]).sum(dim=1)
        error = position - mv(self.base[:3, :3][None], actual) - self.base[:3, 3]
        if attitude is None:
            return error
        if tool is None:
            reached = mc(rot[:, -1], self.end[:3, :3])  # the TCP's rotation at q (identified chain, no base)
        else:  # each row's TCP frame on the flange, turned as the model's own: R_end·R_tool0ᵀ·R_tool
            abc = torch.where(torch.isnan(tool[:, 3:6]), self.tool0[3:6].expand(tool.shape[0], 3), tool[:, 3:6])
            reached = rot[:, -1] @ (self.end[:3, :3] @ self.arm.tool[:3, :3].T) @ rotation_matrices(abc)
        turned = rotation_log(self.base[:3, :3] @ reached @ attitude.transpose(1, 2))
        return error, turned + mv(self.base[:3, :3][None], (omega * dq[..., None]).sum(dim=1))

    def forward(self, pose: torch.Tensor, previous_pose: torch.Tensor | None = None) -> torch.Tensor:
        dtype = pose.dtype
        prev = previous_pose.to(torch.float64) if previous_pose is not None else None
        return self.parts(pose.to(torch.float64), prev)[0].to(dtype)


class KinematicModel(Estimator):
    """Identified kinematic + compliance (+ backlash, gear ripple) error model of one robot.

    >>> km = KinematicModel(load_description()).fit(poses, errors, previous_poses(poses))
    >>> km.predict(poses, previous)          # Ê [N, 3] mm

    ``ripple``: "search" (orders 1…``max_order`` of ``ripple_joints``, at most ``max_ripple``) or
    a fixed list of (joint, order); ``prior``: the prior's weight in mm² per typical size², or
    "auto" (the residual variance of a first fit: a Gaussian prior, module text); ``staged``:
    searched orders fitted on top of the physical groups, which keep their values (False: all
    refitted together, which lets the geometry lean on orders that hold only where the data
    was); ``iterations`` of Levenberg–Marquardt; ``family`` of the IK (None: the description's);
    ``select``: "blocked" (the optional physical groups and how many of the searched ripple orders
    are kept, chosen by blocked cross-validation over joint-space regions: training/blocked.py;
    ``selection_`` says what it found) or "none" (every group and order kept).
    """

    def __init__(self, description: RobotDescription, groups: tuple[str, ...] = DEFAULT_GROUPS,
                 ripple: str | list[tuple[int, int]] = "search", max_order: int = 100, ripple_joints=range(6),
                 max_ripple: int = 120, prior: float | str = "auto", iterations: int = 20, family: str | None = None,
                 staged: bool = True, select: str = "blocked"):
        self.description = description
        self.staged = staged
        self.select = select
        self.groups = tuple(groups)
        self.ripple = ripple
        self.max_order = max_order
        self.ripple_joints = tuple(ripple_joints)
        self.max_ripple = max_ripple
        self.prior = prior
        self.iterations = iterations
        self.family = family

    # ------------------------------------------------------------------ fitting
    def _choose_ik(self, poses: np.ndarray, q_deg: np.ndarray | None) -> None:
        if q_deg is None and (self.family in (None, "kuka")):
            try:
                from ...robot.arm import Robot

                q_deg, ok = Robot(self.description).ik(poses)
                if not ok.all():
                    q_deg = None
            except Exception:  # not a KUKA-type arm: the default branch of the other family
                q_deg = None
        if q_deg is None:
            self.ik_ = make_ik(self.description, self.family)
            self.branch_share_ = math.nan
        else:
            self.ik_, self.branch_share_ = choose_branch(self.description, poses, q_deg, self.family)

    def fit(self, poses: np.ndarray, errors: np.ndarray, previous: np.ndarray | None = None,
            q_deg: np.ndarray | None = None, tools: np.ndarray | None = None,
            rotation_errors: np.ndarray | None = None, previous_q_deg: np.ndarray | None = None,
            campaigns: np.ndarray | None = None, loads: np.ndarray | None = None) -> "KinematicModel":
        """Fit to commanded poses [N, 6], errors E = P − P_measured [N, 3] and (optionally) the
        pose visited before each row [N, 6] (``features.previous_poses`` of the rows in their
        visiting order; the row itself = came from HOME); ``q_deg`` [N, 6] are the controller's
        joint angles if the data has them (they pick the IK branch), ``previous_q_deg`` [N, 6]
        those of the row visited before (``features.previous_joints``; NaN rows: the previous
        pose solved on the row's branch); ``tools`` [N, 6] each row's
        TCP on the flange (None: the description's tool; the description's tool is the model's
        own, NaN in the ``tool`` input). The mount's rotation is identified only from two or more
        TCP positions. ``rotation_errors`` [N, 3] deg (a 6-DOF probe: the rotation vector of
        commanded → measured orientation, base frame, ``frames.rotation_error_deg``): the
        orientation is fitted too, in the same least squares (see ``lever_``), with the tool's
        rotation as three more parameters — with one tool only (data of several tools: position
        only, ``orientation_`` False). ``campaigns`` [N] int (0, 1, …): each row's measurement
        campaign (tracker set-up); campaigns beyond the first get their own rigid frame and tool
        (reflector) offset (9 parameters each) in the same least squares, the robot's parameters shared
        (``campaign_frames_``; ``to_base`` moves rows into the first campaign's frame, which the
        model predicts in); position only. ``loads`` [N, 4]: the load each row was measured with
        (mass kg, centre of mass cx, cy, cz mm in the flange frame): the compliance's torques take
        it, the model is load-aware (``load_reference_``: the load of most rows, what a NaN row
        of the graph's ``load`` input means; ``measured_loads_``, ``load_rows_``); None: every row
        at the description's payload, as before loads existed."""
        poses = np.asarray(poses, dtype=np.float64).reshape(-1, 6)
        errors = np.asarray(errors, dtype=np.float64).reshape(-1, 3)
        self.arm_ = Arm(self.description)
        self.torque_span_ = self._torque_span()
        if tools is not None and np.allclose(tools, self.description.tool):
            tools = None
        tools_t = None if tools is None else torch.as_tensor(np.asarray(tools, dtype=np.float64).reshape(-1, 6))
        at = None if tools_t is None else (lambda p: at_tool(p, tools_t, self.arm_.tool0))  # noqa: E731
        ik_poses = poses
        if at is not None:  # the IK's pose: the description's TCP on the row's flange pose
            with torch.no_grad():
                rot, pos = at(torch.as_tensor(poses))
            ik_poses = np.c_[pos.numpy(), frames.abc_from_rotation(rot.numpy())]
        self.tools_ = None if tools is None else np.unique(np.round(tools, 6), axis=0)
        self._choose_ik(ik_poses, q_deg)
        several = self.tools_ is not None and len(np.unique(np.round(self.tools_[:, :3]), axis=0)) > 1
        # (no physical groups, e.g. dnn-joints' networks alone: nothing that could carry an orientation;
        # per-row tools: the identified ends are positions only)
        campaigns = None if campaigns is None else np.asarray(campaigns, dtype=np.int64).reshape(-1)
        several_campaigns = campaigns is not None and len(np.unique(campaigns)) > 1
        self.orientation_ = (rotation_errors is not None and tools_t is None and not several_campaigns
                             and any(g != "tool_rotation" for g in self.groups))
        rotation_errors = rotation_errors if self.orientation_ else None
        groups = tuple(g for g in self.groups
                       if (g != "backlash" or previous is not None) and (g != "mount" or several)
                       and (g != "tool_rotation" or self.orientation_))
        n_par = Layout(groups, list(self.ripple) if isinstance(self.ripple, list) else []).n
        per_row = 6 if self.orientation_ else 3
        if per_row * len(poses) < n_par:
            raise PostprocError(
                f"{len(poses)} training rows give {per_row * len(poses)} measured coordinates, fewer than the {n_par} "
                f"parameters of {', '.join(groups)}: a model fitted on them would be worse than none; measure "
                f"at least {-(-n_par // per_row)} poses", code=P505)
        self.use_previous_ = previous is not None  # the approach signs: backlash, and the residual nets' inputs
        self._set_loads(loads, len(poses))
        q, s, tau, tcp, pose_t, poses, errors, nominal_rot, keep = self._prepare(poses, errors, previous, q_deg,
                                                                                tools_t, at, previous_q_deg)
        if not keep.all():  # (a few singular / unreachable rows: left out, named by the caller)
            tools_t = None if tools_t is None else tools_t[torch.as_tensor(keep)]
            if self.orientation_:
                rotation_errors = np.asarray(rotation_errors, dtype=np.float64).reshape(-1, 3)[keep]
        # each row's TCP position on the flange, for the fit's identified ends (None: the description's)
        self._tool_rows = None if tools_t is None else tools_t[:, :3]
        measured = tcp - torch.as_tensor(errors)
        self.lever_ = None
        if self.orientation_:
            # the measured orientation, as the measured position: the nominal TCP at q moved by the error
            turn = torch.as_tensor(np.radians(np.asarray(rotation_errors, dtype=np.float64).reshape(-1, 3)))
            measured = (measured, small_rotation(turn) @ nominal_rot)
            self.lever_ = LEVER_MM
        layout = Layout(groups, list(self.ripple) if isinstance(self.ripple, list) else [])
        self.campaign_frames_ = self.campaign_std_ = None
        if several_campaigns and not layout.n:
            raise PostprocError("several campaigns need an identification to give each its frame: these groups are "
                                "empty (no physical parameter to fit)", code=P519)
        if several_campaigns:
            theta, tau, measured = self._fit_campaigns(layout, q, s, tau, measured, campaigns[keep], poses)
            errors = (tcp - measured).numpy()  # (in the first campaign's frame)
        else:
            theta, tau = self._fit_physical(layout, q, s, tau, measured)
        self.ripple_search_, self.ripple_rounds_, self.selection_, self.blocked_ = [], [], None, None
        region = self._regions(ik_poses[keep], q) if self.select == "blocked" and layout.n else None
        # (each training row's octant: the residual networks' check holds some out)
        self.regions_ = None if region is None else region[0][1]
        if region is not None:
            layout, theta, tau = self._select_groups(layout, theta, q, s, tau, measured, region)
        if self.ripple == "search":
            layout, theta = self._search_ripple(layout, theta, q, s, tau, measured)
        if region is not None and self.ripple == "search":  # (a list given is kept as given)
            layout, theta = self._select_ripple(layout, theta, q, s, tau, measured, region)
        self.layout_ = layout
        self.theta_ = theta
        self.module_ = KinematicErrorModule(self.arm_, self.ik_, layout, theta, self.use_previous_,
                                            tau.mean(dim=0).numpy(), self.load_reference_)
        self.module_.orientation = self.orientation_
        with torch.no_grad():
            if self.orientation_:
                fitted, turned = self.module_.error_at(q, s, pose_t[:, :3], attitude=nominal_rot, load=self.train_load_)
            else:
                fitted = self.module_.error_at(q, s, pose_t[:, :3], tool=tools_t, load=self.train_load_)
        self.train_q_, self.train_signs_ = q.numpy(), s.numpy()
        self.train_residual_ = errors - fitted.numpy()
        self.train_rotation_residual_ = (np.asarray(rotation_errors).reshape(-1, 3) - np.degrees(turned.numpy())
                                         if self.orientation_ else None)
        self.n_train_ = len(poses)
        return self

    def refit(self, layout: Layout, theta: np.ndarray, tau_mean: np.ndarray, ik: torch.nn.Module,
              use_previous: bool, free: np.ndarray, weights: np.ndarray, poses: np.ndarray, errors: np.ndarray,
              previous: np.ndarray | None = None, q_deg: np.ndarray | None = None,
              ranges: np.ndarray | None = None, rotation_errors: np.ndarray | None = None,
              lever: float | None = None) -> "KinematicModel":
        """Re-calibration: an identified model (``layout``, ``theta``, ``tau_mean``, its IK branch
        ``ik``, whether it takes the visiting order) re-fitted on new rows, moving only the
        parameters ``free`` (bool [P]) under the prior Σ w_i(θ_i − θ_i,old)² (``weights`` [P],
        mm² per unit²); every other parameter, the ripple orders and the torques' mean keep
        their old values. The rows as :meth:`fit` takes them; without ``previous`` a model that
        takes the visiting order sees every row as reached from HOME. ``ranges`` [6, 2] rad: the
        model's trained joint ranges, outside which its graph leaves the ripple terms out: the
        re-fit does the same, so that it fits the model the graph evaluates. ``rotation_errors``
        [N, 3] deg with ``lever`` (mm/rad, the old fit's): the orientation is re-fitted with the
        position, as :meth:`fit` weighs them (the graph keeps ``rotation_error``); without them
        the re-fit is position only and the model has no orientation part."""
        poses = np.asarray(poses, dtype=np.float64).reshape(-1, 6)
        errors = np.asarray(errors, dtype=np.float64).reshape(-1, 3)
        self.arm_, self.ik_, self.branch_share_ = Arm(self.description), ik, math.nan
        self.torque_span_ = self._torque_span()
        self.use_previous_ = use_previous
        self.prior_ = self._first_prior()
        if use_previous and previous is None:
            previous = poses  # (the row itself: came from HOME)
        q, s, _, tcp, pose_t, poses, errors, nominal_rot, keep = self._prepare(
            poses, errors, previous if use_previous else None, q_deg)
        # (at the model's own tool; the orientation where the new rows measured it)
        self.orientation_ = rotation_errors is not None and lever is not None
        self._tool_rows, self.tools_, self.lever_ = None, None, (float(lever) if self.orientation_ else None)
        measured = tcp - torch.as_tensor(errors)
        if self.orientation_:
            rotation_errors = np.asarray(rotation_errors, dtype=np.float64).reshape(-1, 3)[keep]
            turn = torch.as_tensor(np.radians(rotation_errors))
            measured = (measured, small_rotation(turn) @ nominal_rot)
        rows = None if ranges is None else inside_ranges(q, torch.as_tensor(np.asarray(ranges, dtype=np.float64)))
        old = np.asarray(theta, dtype=np.float64)
        theta = old.copy()
        tau_mean = np.asarray(tau_mean, dtype=np.float64)
        self.ripple_search_, self.ripple_rounds_, self.selection_, self.blocked_ = [], [], None, None
        self.regions_ = None
        for _ in range(2):  # the torques of the identified chain depend on θ only weakly
            with torch.no_grad():
                tau = KinematicErrorModule(self.arm_, ik, layout, theta, use_previous, tau_mean).torques(q)
            theta = self._levenberg_marquardt(layout, theta, q, s, tau, measured, self.iterations, anchor=old,
                                              weights=weights, free=free, ripple_rows=rows)
        self.layout_, self.theta_ = layout, theta
        self.module_ = KinematicErrorModule(self.arm_, ik, layout, theta, use_previous, tau_mean)
        self.module_.orientation = self.orientation_
        with torch.no_grad():
            if self.orientation_:
                fitted, turned = self.module_.error_at(q, s, pose_t[:, :3], rows, attitude=nominal_rot)
            else:
                fitted = self.module_.error_at(q, s, pose_t[:, :3], rows)
        self.train_q_, self.train_signs_ = q.numpy(), s.numpy()
        self.train_residual_ = errors - fitted.numpy()
        self.train_rotation_residual_ = (rotation_errors - np.degrees(turned.numpy()) if self.orientation_ else None)
        self.n_train_ = len(poses)
        return self

    def _prepare(self, poses: np.ndarray, errors: np.ndarray, previous: np.ndarray | None,
                 q_deg: np.ndarray | None, tools_t: torch.Tensor | None = None, at=None,
                 previous_q_deg: np.ndarray | None = None):
        """The rows as the fit sees them: joint angles q (the data's, else the IK of ``self.ik_``
        of each row's pose, ``at`` taking it onto the IK's tool for rows of other tools
        ``tools_t``), approach signs, nominal gravity torque terms, nominal TCP (at each row's
        tool) and its rotation, poses and errors, with the few rows out of reach (or whose
        q1..q6 are not of their pose) left out (``dropped_``; more than ``DROP_AT_MOST`` of
        them: P508); ``keep`` bool [N] says which rows stay. ``previous_q_deg``: the joint angles
        of the row visited before (``approach_signs``' ``q_previous``)."""
        with torch.no_grad():
            pose_t = torch.as_tensor(poses)
            q_in = None if q_deg is None else torch.as_tensor(np.radians(np.asarray(q_deg, dtype=np.float64)))
            # the controller's own angles when the data has them (the arm went there), else the IK
            q = self.ik_(pose_t if at is None else at(pose_t)) if q_in is None else q_in
            ends = None if tools_t is None else self.arm_.flange[:3, 3] + mv(self.arm_.flange[:3, :3], tools_t[:, :3])
            rot, org, tcp = self.arm_.frames(q, end=ends)
            loads = getattr(self, "_loads_in", None)  # (fit's rows' loads: ``_set_loads``)
            tau = self.arm_.torque_terms(rot, org, loads)
            nominal_rot = mc(rot[:, -1], self.arm_.end[:3, :3])  # the nominal TCP's rotation at q
            miss = torch.linalg.norm(tcp - pose_t[:, :3], dim=1).numpy()
            # the nominal arm at q must land on the pose: else out of reach (IK) or the joint
            # angles are of another pose, robot or unit
            tolerance = REACH_TOLERANCE_MM if q_in is None else JOINTS_TOLERANCE_MM
            bad = np.flatnonzero(~(miss <= tolerance))
            self.dropped_ = bad
            if len(bad) > max(DROP_AT_MOST * len(poses), 0):
                what = "out of reach of" if q_in is None else "not where the joint angles q1..q6 put"
                raise PostprocError(
                    f"{len(bad)} of {len(poses)} poses are {what} the nominal {self.description.name} "
                    f"(IK {self.ik_.family} branch {list(self.ik_.branch)}; first: row {bad[0] + 1}, "
                    f"{np.round(poses[bad[0]], 3).tolist()}, {miss[bad[0]]:.3g} mm away): is this the robot "
                    f"of the data (--robot)?", self.description.path, code=P508)
            s = torch.zeros_like(q)
            if previous is not None:
                prev = torch.as_tensor(np.asarray(previous, dtype=np.float64).reshape(-1, 6))
                q_prev = (None if previous_q_deg is None
                          else torch.as_tensor(np.radians(np.asarray(previous_q_deg, dtype=np.float64).reshape(-1, 6))))
                s = approach_signs(self.ik_, self.arm_.home_q, q, pose_t, prev, q_in, at, q_prev)
            keep = ~np.isin(np.arange(len(poses)), bad)
            if len(bad):
                kt = torch.as_tensor(keep)
                q, s, tau, tcp, pose_t, nominal_rot = q[kt], s[kt], tau[kt], tcp[kt], pose_t[kt], nominal_rot[kt]
                loads = None if loads is None else loads[kt]
                poses, errors = poses[keep], errors[keep]
            self.train_load_ = loads  # [N, 4] the kept rows' loads (None: not load-aware)
        return q, s, tau, tcp, pose_t, poses, errors, nominal_rot, keep

    def _prior_scales(self, layout: Layout, tau: torch.Tensor) -> np.ndarray:
        """A typical size of every parameter (rad, mm, rad/Nm): the prior's unit (:func:`prior_scales`),
        the compliance and coupling terms' from the largest torques of the rows ``tau`` or of the
        arm anywhere in its joint limits (``torque_span_``), whichever is larger: a deflection of
        PRIOR_RAD at the largest torque the joint can see, not at the largest these rows saw (a
        compliance fitted where a joint's torque stays small would be free to grow, and a pose
        with more torque — the arm stretched — would carry it out: 4.6 mm at IPA Series D's
        stretched pose from A5's)."""
        span = getattr(self, "torque_span_", None)
        rows = np.abs(tau.numpy()).max(axis=0, initial=0.0)
        return prior_scales(layout, rows if span is None else np.maximum(rows, span)[None])

    def _torque_span(self, samples: int = 4096) -> np.ndarray:
        """[27] the largest |torque term| of the nominal arm over ``samples`` joint configurations
        drawn (seeded) uniformly within its joint limits (each within ±180°)."""
        limits = np.clip(np.array([j.limits for j in self.description.joints], float), -180.0, 180.0)
        q = np.random.default_rng(0).uniform(limits[:, 0], limits[:, 1], size=(samples, 6))
        with torch.no_grad():
            rot, org, _ = self.arm_.frames(torch.as_tensor(np.radians(q)))
            return torch.abs(self.arm_.torque_terms(rot, org)).amax(dim=0).numpy()

    def _levenberg_marquardt(self, layout: Layout, theta: np.ndarray, q, s, tau, measured,
                             iterations: int, anchor: np.ndarray | None = None, weights: np.ndarray | None = None,
                             free: np.ndarray | None = None, ripple_rows: torch.Tensor | None = None) -> np.ndarray:
        """min ‖FK_id − measured‖² (+ ‖lever·log(R_id·R_measuredᵀ)‖² with orientation: ``measured``
        a (positions, rotations) pair) + Σ w_i(θ_i − θ⁰_i)² by Levenberg–Marquardt with the
        geometric Jacobian (:func:`jacobian`). By default the fit's prior (``self.prior_``, mm² per
        σ², σ a typical size of each parameter, θ⁰ = 0) decides only what the data do not:
        directions no measurement sees (a zero offset and a placement turned about its own axis;
        A6's angle when the TCP sits on the A6 axis) stay near zero instead of wandering off. A
        re-fit (:meth:`refit`) passes its own ``anchor`` θ⁰ and ``weights`` w and moves only the
        parameters ``free`` (bool [P]); the others keep their values, and its ``ripple_rows``
        (see :func:`jacobian`)."""
        arm = self.arm_
        campaign = self._campaign_parameters()
        if weights is None:  # the fit's own prior: every parameter free, toward 0 (and the campaigns' frames)
            w2 = self.prior_ / np.r_[self._prior_scales(layout, tau), self._campaign_scales()] ** 2
            free, anchor = slice(None), None
        else:
            w2 = np.asarray(weights, float)
            free, anchor = np.asarray(free, bool), np.asarray(anchor, float)
        w2f = w2[free]

        def away(t: np.ndarray) -> np.ndarray:  # θ − θ⁰ of the free parameters
            return t if anchor is None else (t - anchor)[free]

        def evaluate(t: np.ndarray):
            if isinstance(measured, tuple):  # position and orientation: 6 rows per point, rad × lever
                tcp, jac, sens, rot, jac_r, sens_r = jacobian(arm, layout, torch.as_tensor(t), q, s, tau, rotation=True,
                                                              ripple_rows=ripple_rows)
                lever = self.lever_
                r = torch.cat([tcp - measured[0], lever * rotation_log(rot @ measured[1].transpose(1, 2))], dim=1)
                jac, sens = torch.cat([jac, lever * jac_r], dim=1), torch.cat([sens, lever * sens_r], dim=1)
                r = r.numpy().reshape(-1)
            else:
                tt = torch.as_tensor(t)
                tcp, jac, sens = jacobian(arm, layout, tt[:len(t) - campaign] if campaign else tt, q, s, tau,
                                          self._tool_rows, ripple_rows=ripple_rows)
                if campaign:  # (rows of other campaigns: their tool offset, their frame's turn and shift after the arm)
                    tcp, jac, sens = campaign_frames(tcp, jac, sens, tt[len(t) - campaign:], self._campaign_rows,
                                                     self._campaign_axes)
                r = (tcp - measured).numpy().reshape(-1)
            d = away(t)
            return r, jac.numpy().reshape(len(r), -1), sens.numpy(), float(r @ r + (w2f * d * d).sum())

        r, jac, sens, cost = evaluate(theta)
        mu = 1e-3
        for _ in range(iterations):
            jf = jac if anchor is None else jac[:, free]
            jtj = jf.T @ jf + np.diag(w2f)
            grad = jf.T @ r + w2f * away(theta)
            diag = np.maximum(np.diag(jtj), 1e-30)
            while True:
                step = np.linalg.solve(jtj + mu * np.diag(diag), grad)
                if anchor is None:
                    trial = theta - step
                else:
                    trial = theta.copy()
                    trial[free] -= step
                out = evaluate(trial)
                if out[3] <= cost or mu > 1e8:
                    break
                mu *= 10.0
            if out[3] > cost:
                break
            gain = cost - out[3]
            theta, (r, jac, sens, cost) = trial, out
            mu = max(mu / 10.0, 1e-9)
            if gain <= 1e-9 * cost:
                break
        self._state = (r, jac, sens)
        return theta

    def _campaign_parameters(self) -> int:
        """How many campaign parameters the fit carries now (CAMPAIGN_SIZE per campaign beyond the first)."""
        rows = getattr(self, "_campaign_rows", None)
        return 0 if rows is None else CAMPAIGN_SIZE * rows.shape[1]

    def _campaign_scales(self) -> np.ndarray:
        return np.tile(np.r_[np.full(3, CAMPAIGN_RAD), np.full(6, CAMPAIGN_MM), np.full(6, CAMPAIGN_ZERO_RAD)],
                       self._campaign_parameters() // CAMPAIGN_SIZE)

    def _fit_campaigns(self, layout: Layout, q, s, tau, measured: torch.Tensor, campaigns: np.ndarray,
                       poses: np.ndarray) -> tuple[np.ndarray, torch.Tensor, torch.Tensor]:
        """The physical fit with a rigid frame and a tool offset per campaign beyond the first
        (``campaigns`` [N] int; ``poses`` [N, 6] the rows' commanded poses), the robot's
        parameters shared: (θ of ``layout``, torques, the measured points moved into the first
        campaign's frame at its tool). Sets ``campaign_frames_`` [K, 9] (rotation vector rad,
        offset mm: the first campaign's frame ↦ each campaign's; the tool offset mm along the
        TCP's axes; the first zeros), ``campaign_std_`` [K, 9] (the posterior std, σ²(JᵀJ + W)⁻¹,
        the robot's parameters with them) and ``campaign_codes_`` (the campaigns in that order).
        A tool offset the rows cannot tell from the frame's shift (one orientation) stays where
        the prior splits it: the same points either way."""
        codes, index = np.unique(campaigns, return_inverse=True)
        onehot = torch.nn.functional.one_hot(torch.as_tensor(index), len(codes)).to(torch.float64)[:, 1:]
        axes = tcp_axes_of(poses)
        self._campaign_rows, self._campaign_axes = onehot, axes
        try:
            theta, tau = self._fit_physical(layout, q, s, tau, measured)
            r, jac, _ = self._state
            scale = np.r_[self._prior_scales(layout, tau), self._campaign_scales()]
            jtj = jac.T @ jac
            a_scaled = scale[:, None] * (jtj + np.diag(self.prior_ / scale**2)) * scale[None, :]
            a_inv = scale[:, None] * np.linalg.pinv(a_scaled, hermitian=True) * scale[None, :]
            sigma2 = float(r @ r) / max(len(r) - float(np.trace(a_inv @ jtj)), 1.0)
            std = np.sqrt(np.clip(np.diag(a_inv)[layout.n:], 0.0, None) * sigma2)
        finally:
            self._campaign_rows = None
        frames = np.vstack([np.zeros(CAMPAIGN_SIZE), theta[layout.n:].reshape(-1, CAMPAIGN_SIZE)])
        self.campaign_frames_ = frames
        self.campaign_std_ = np.vstack([np.zeros(CAMPAIGN_SIZE), std.reshape(-1, CAMPAIGN_SIZE)])
        self.campaign_codes_ = codes
        theta = theta[:layout.n].copy()
        with torch.no_grad():
            sens = jacobian(self.arm_, layout, torch.as_tensor(theta), q, s, tau, self._tool_rows)[2]
        measured = to_first_frame(measured, torch.as_tensor(frames[index]), axes, sens)
        self._levenberg_marquardt(layout, theta, q, s, tau, measured, 0)  # (the state of the fit without the frames)
        return theta, tau, measured

    def to_base(self, poses: np.ndarray, errors: np.ndarray, campaigns: np.ndarray | None,
                q_deg: np.ndarray | None = None) -> np.ndarray:
        """E [N, 3] of rows of the campaigns ``campaigns`` [N] int (``fit``'s codes) moved into the
        first campaign's frame and tool — which the model predicts for — by the fitted campaign
        frames, tool and zero offsets (``errors`` as they are without campaigns); ``q_deg`` [N, 6] the
        rows' joint angles if known (they pick the IK branch of the zero offsets' sensitivities)."""
        frames = getattr(self, "campaign_frames_", None)
        if frames is None or campaigns is None:
            return np.asarray(errors, dtype=np.float64)
        index = np.searchsorted(self.campaign_codes_, np.asarray(campaigns, dtype=np.int64))
        if not (index < len(self.campaign_codes_)).all() or not (self.campaign_codes_[np.minimum(
                index, len(self.campaign_codes_) - 1)] == campaigns).all():
            raise ValueError("rows of a campaign the fit did not see")
        poses = np.asarray(poses, dtype=np.float64).reshape(-1, 6)
        p = poses[:, :3]
        measured = torch.as_tensor(p - np.asarray(errors, dtype=np.float64).reshape(-1, 3))
        with torch.no_grad():
            pose = torch.as_tensor(poses)
            q_in = None if q_deg is None else torch.as_tensor(np.radians(np.asarray(q_deg, dtype=np.float64).reshape(-1, 6)))
            q = self.module_.joints_of(pose, q_in)
            sens = jacobian(self.arm_, self.layout_, torch.as_tensor(self.theta_), q, torch.zeros_like(q),
                            self.module_.torques(q))[2]
            return p - to_first_frame(measured, torch.as_tensor(frames[index]), tcp_axes_of(poses), sens).numpy()

    def _set_loads(self, loads: np.ndarray | None, n: int) -> None:
        """The rows' loads for the fit (``fit``'s ``loads``): ``_loads_in`` [n, 4] tensor, the
        distinct loads ``measured_loads_`` [K, 4] with their row counts ``load_rows_``, and the
        reference ``load_reference_`` [4] (the load of most rows, the heaviest of a tie); all None
        without loads."""
        self._loads_in = self.load_reference_ = self.measured_loads_ = self.load_rows_ = self.measured_card_ = None
        if loads is None:
            return
        loads = np.asarray(loads, dtype=np.float64).reshape(-1, 4)
        if len(loads) != n or not np.isfinite(loads).all() or (loads[:, 0] < 0).any():
            raise ValueError("loads must be [N, 4] finite numbers (mass kg >= 0, centre of mass mm), one row per pose")
        distinct, counts, self.measured_card_ = measured_loads(loads)
        self.measured_loads_, self.load_rows_ = distinct, counts
        best = np.lexsort((distinct[:, 0], counts))[-1]  # (most rows, then the heaviest)
        self.load_reference_ = distinct[best]
        self._loads_in = torch.as_tensor(loads)

    def _first_prior(self) -> float:
        """The prior's weight before any fit: ``prior`` as given, the weak floor for "auto"."""
        return WEAK_PRIOR if self.prior == "auto" else float(self.prior)

    def _fit_physical(self, layout: Layout, q, s, tau, measured) -> tuple[np.ndarray, torch.Tensor]:
        """(θ, the torques of the identified chain) of the groups in ``layout`` (with a fixed
        ripple list, those orders too): the first fit, the orientation's lever, the prior's
        weight (``prior_``) and the torques refitted."""
        theta = np.zeros(layout.n + self._campaign_parameters())
        self.prior_ = self._first_prior()
        if layout.n:
            theta = self._levenberg_marquardt(layout, theta, q, s, tau, measured, self.iterations)
            if self.orientation_:
                # weigh position and orientation by what each leaves unexplained (one step of
                # variance-component estimation): lever = rms position / rms orientation residual
                r = self._state[0].reshape(-1, 2, 3)
                rms_mm = float(np.sqrt(np.mean(r[:, 0] ** 2)))
                rms_rad = float(np.sqrt(np.mean(r[:, 1] ** 2))) / self.lever_
                self.lever_ = float(np.clip(rms_mm / max(rms_rad, 1e-12), LEVER_RANGE[0], LEVER_RANGE[1]))
                theta = self._levenberg_marquardt(layout, theta, q, s, tau, measured, self.iterations)
            if self.prior == "auto":
                # the prior as a Gaussian one: each parameter ~ N(0, its typical size²) against
                # residuals of the variance this fit leaves per coordinate (what the model does
                # not explain counts as noise): weight = σ̂². Directions the data hardly see
                # stay near nominal instead of taking up what is particular to these poses
                r = self._state[0]
                self.prior_ = max(float(r @ r) / max(len(r) - len(theta), 1), WEAK_PRIOR)
                theta = self._levenberg_marquardt(layout, theta, q, s, tau, measured, self.iterations)
        # the torques of the identified chain (what the exported module computes, one forward
        # kinematics for everything), refitted twice: they depend on θ only weakly
        for _ in range(2 if layout.n and ("compliance" in layout.groups or "coupling" in layout.groups) else 0):
            module = KinematicErrorModule(self.arm_, self.ik_, layout, theta[:layout.n], self.use_previous_,
                                          tau.mean(dim=0).numpy(), getattr(self, "load_reference_", None))
            with torch.no_grad():
                tau = module.torques(q, getattr(self, "train_load_", None))
            theta = self._levenberg_marquardt(layout, theta, q, s, tau, measured, self.iterations)
        return theta, tau

    def _regions(self, ik_poses: np.ndarray, q: torch.Tensor) -> list | None:
        """The ways the rows are split into joint-space regions for the blocked selection
        (``blocked.folds``: octants of A1–A3, the IK branches), None where there are too few rows
        or no way with two regions."""
        from .blocked import MIN_ROWS, folds

        if len(q) < MIN_ROWS:
            return None
        with torch.no_grad():
            branches = torch.stack(self.ik_.branch_of(torch.as_tensor(ik_poses), q), dim=1).numpy()
        return folds(q.numpy(), branches) or None

    def _blocked(self, layout: Layout, theta: np.ndarray, q: torch.Tensor, region: list):
        """The blocked CV (``blocked.BlockedSets``) linearised at the last fit (``_state``) of ``layout``."""
        from .blocked import BlockedSets

        r, jac, _ = self._state
        return BlockedSets(jac, r, theta, region, q.numpy())

    def _select_groups(self, layout: Layout, theta: np.ndarray, q, s, tau, measured,
                       region: list) -> tuple[Layout, np.ndarray, torch.Tensor]:
        """The physical groups kept: of the candidates without some of ``blocked.OPTIONAL_GROUPS``
        the one whose blocked held-out sum of squares is least — within ``blocked.PARSIMONY`` of
        it, the one with most parameters: a physical group is left out where holding regions out
        shows it does harm, not where the data cannot tell (IPA Series C, one arm configuration,
        cannot tell its 21 couplings from none; kept, they carry it to Series A and D at 0.53 /
        0.52 mm, left out at 0.60 / 0.68). The joint compliance (6 stiffnesses, which every arm
        has) is left out only where that harm exceeds ``blocked.HARM_SE`` standard errors of
        the difference (the regions' paired sums); refitted without the groups it leaves out."""
        from itertools import combinations

        from .blocked import HARM_SE, OPTIONAL_GROUPS, PARSIMONY

        cv = self._blocked(layout, theta, q, region)
        weights = self.prior_ / self._prior_scales(layout, tau) ** 2
        slices = layout.slices()
        optional = [g for g in OPTIONAL_GROUPS if g in layout.groups
                    and not (g == "compliance" and getattr(self, "load_reference_", None) is not None)]
        scores = []
        for k in range(len(optional) + 1):
            for drop in combinations(optional, k):
                cols = np.concatenate([np.arange(slices[g].start, slices[g].stop) for g in layout.groups
                                       if g not in drop and slices[g].stop > slices[g].start])
                scores.append((drop, cols, cv.evaluate(cols, np.zeros(0, int), weights)))
        best = min(e.sse for _, _, e in scores)
        drop, chosen_cols, chosen = max((c for c in scores if c[2].sse <= (1.0 + PARSIMONY) * best),
                                        key=lambda c: len(c[1]))
        if "compliance" in drop:  # (a physical effect of every arm: left out only where it does harm)
            kept = next(c for c in scores if set(c[0]) == set(drop) - {"compliance"})
            if kept[2].sse - chosen.sse <= HARM_SE * cv.difference_se(kept[2], chosen):
                drop, chosen_cols, chosen = kept
        self.selection_ = {"regions": cv.regions, "rows": int(len(q)),
                           "groups": {("without " + " and ".join(d)) if d else "all": round(e.rms, 6)
                                      for d, _, e in scores},
                           "dropped": list(drop)}
        if drop:
            layout = Layout(tuple(g for g in layout.groups if g not in drop), layout.ripple)
            theta, tau = self._fit_physical(layout, q, s, tau, measured)
        self.blocked_ = chosen  # (its variances with the ripple orders' selection, or here without them)
        if self.ripple != "search":
            self.blocked_ = cv.evaluate(chosen_cols, np.zeros(0, int), weights, variance=True)
        return layout, theta, tau

    def _select_ripple(self, layout: Layout, theta: np.ndarray, q, s, tau, measured,
                       region: list) -> tuple[Layout, np.ndarray]:
        """How many of the searched ripple orders are kept: the first m (the search's order, m at
        the end of one of its rounds, 0 included) whose blocked held-out sum of squares is least
        (within ``blocked.PARSIMONY``, the fewest); the amplitudes refitted for them."""
        from .blocked import PARSIMONY

        searched = len(layout.ripple)
        physical = layout.n - 2 * searched
        if not searched or not self.staged:
            if self.selection_ is not None:
                self.selection_["ripple"] = {"searched": searched, "kept": searched}
            return layout, theta
        cv = self._blocked(layout, theta, q, region)
        weights = self.prior_ / self._prior_scales(layout, tau) ** 2
        scores = {}
        for m in dict.fromkeys([0, *self.ripple_rounds_, searched]):
            scores[m] = cv.evaluate(np.arange(physical), physical + np.arange(2 * m), weights)
        best = min(e.sse for e in scores.values())
        kept = min(m for m, e in scores.items() if e.sse <= (1.0 + PARSIMONY) * best)
        self.selection_["ripple"] = {"searched": searched, "kept": kept,
                                     "rms": {str(m): round(e.rms, 6) for m, e in scores.items()}}
        self.blocked_ = cv.evaluate(np.arange(physical), physical + np.arange(2 * kept), weights, variance=True)
        if kept < searched:
            layout = Layout(layout.groups, layout.ripple[:kept])
            theta = theta[: physical + 2 * kept].copy()
            # (the amplitudes kept refitted; none kept: the state — residual, Jacobian — of the physical fit)
            theta = self._fit_ripple(layout, theta, physical, q, s, tau, measured, self.iterations if kept else 0)
        return layout, theta

    def blocked_figures(self) -> dict | None:
        """The identified arm's blocked held-out figures (mm: mean, p95, max of |E − Ê| at the
        rows, each predicted by the fit without its region; rms per coordinate), None without a
        blocked selection."""
        if self.blocked_ is None:
            return None
        norms = self.blocked_.norms()
        return {"regions": self.selection_["regions"], "rows": int(self.selection_["rows"]),
                "mean_mm": round(float(norms.mean()), 6),
                "p95_mm": round(float(np.quantile(norms, 0.95)), 6), "max_mm": round(float(norms.max()), 6),
                "rms_mm": round(self.blocked_.rms, 6)}

    def _search_ripple(self, layout: Layout, theta: np.ndarray, q, s, tau, measured) -> tuple[Layout, np.ndarray]:
        """Gear-ripple orders added on top of the fitted physical model, which stays as fitted
        (``staged``): the orders take up what it leaves at the angles the data visited, and the
        physical parameters do not lean on them — outside the trained joint ranges, where the
        graph leaves the gear-mesh orders out, the physical part alone is what it would be
        without them. Rounds of the best order per joint (``_best_ripple``) until none passes."""
        physical = layout.n
        while len(layout.ripple) < self.max_ripple:
            # the best order of each joint that passes (the joints' columns hardly overlap)
            picks = self._best_ripple(layout, q)[: self.max_ripple - len(layout.ripple)]
            if not picks:
                break
            self.ripple_search_ += picks
            layout = Layout(layout.groups, layout.ripple + [pick for pick, _ in picks])
            self.ripple_rounds_.append(len(layout.ripple))
            theta = np.r_[theta, np.zeros(2 * len(picks))]
            # a few iterations per round (warm start); the full fit at the end
            theta = self._fit_ripple(layout, theta, physical, q, s, tau, measured, 3)
        if self.ripple_search_:
            theta = self._fit_ripple(layout, theta, physical, q, s, tau, measured, self.iterations)
        return layout, theta

    def _fit_ripple(self, layout: Layout, theta: np.ndarray, physical: int, q, s, tau, measured,
                    iterations: int) -> np.ndarray:
        """Levenberg–Marquardt on the ripple parameters (after the first ``physical``) alone, or
        on all of them without ``staged``; the fit's own prior toward 0 either way."""
        if not self.staged:
            return self._levenberg_marquardt(layout, theta, q, s, tau, measured, iterations)
        free = np.arange(layout.n) >= physical
        anchor = np.where(free, 0.0, theta)
        weights = self.prior_ / self._prior_scales(layout, tau) ** 2
        return self._levenberg_marquardt(layout, theta, q, s, tau, measured, iterations, anchor=anchor,
                                         weights=weights, free=free)

    def _best_ripple(self, layout: Layout, q: torch.Tensor) -> list[tuple[tuple[int, int], float]]:
        """Per joint, the order whose sin/cos columns explain most of the current residual beyond
        the parameters already in (its χ² gain with the residual's variance), for the joints
        where that beats the threshold (χ²₂ tail 1 % over all candidates); best first."""
        r, jac, sens = self._state
        n_rows, n_par = jac.shape
        norms = np.linalg.norm(jac, axis=0)
        scaled = jac[:, norms > 1e-12] / norms[norms > 1e-12]
        # an orthonormal basis of what the parameters explain, basis = scaled·V·Λ^-½ from the
        # eigenvectors of scaledᵀ·scaled (directions the data do not see, λ ≤ 1e-12·λ_max,
        # left out), applied as basisᵀx = Λ^-½·Vᵀ·(scaledᵀx): never formed
        lam, vec = np.linalg.eigh(scaled.T @ scaled)
        seen = lam > 1e-12 * lam.max(initial=0.0)
        to_basis = (vec[:, seen] / np.sqrt(lam[seen])).T  # [k, p]
        sigma2 = float(r @ r) / max(n_rows - n_par, 1)
        orders = np.arange(1, self.max_order + 1)
        threshold = 2.0 * math.log(len(self.ripple_joints) * len(orders) / 0.01)
        taken = set(layout.ripple)
        picks = []
        qn = q.numpy()
        k_max = len(orders)
        # The candidate columns c = sens[:, :, j] ⊗ regress (rows i·3 + axis) are never formed:
        # their Gram entries and the part the parameters already in explain (basisᵀc) are sums
        # over the N rows, 3× (6×) smaller than the 3N × 2K columns (and one product, not two).
        per_row = sens.shape[1]  # 3 coordinates a point (6 with orientation: lever·rad rows)
        scaled3 = scaled.reshape(len(qn), per_row, -1)  # [N, 3|6, p]
        r3 = r.reshape(len(qn), per_row)
        basis_r = to_basis @ (scaled.T @ r)  # [k]
        for j in self.ripple_joints:  # six joints; all orders at once
            phase = qn[:, j, None] * orders  # [N, K]
            sin, cos = np.sin(phase), np.cos(phase)
            regress = np.concatenate([sin, cos], axis=1)  # [N, 2K]
            sj = sens[:, :, j]  # [N, 3]
            s2 = (sj * sj).sum(1)[:, None]
            explained = to_basis @ (np.einsum("iap,ia->ip", scaled3, sj).T @ regress)  # basisᵀc [k, 2K]
            es, ec = explained[:, :k_max], explained[:, k_max:]
            # the Gram entries of c − basis·basisᵀc: what the parameters already in cannot explain
            g11 = (s2 * sin * sin).sum(0) - (es * es).sum(0)
            g22 = (s2 * cos * cos).sum(0) - (ec * ec).sum(0)
            g12 = (s2 * sin * cos).sum(0) - (es * ec).sum(0)
            b = regress.T @ (sj * r3).sum(1) - explained.T @ basis_r  # (c − basis·basisᵀc)ᵀr
            b1, b2 = b[:k_max], b[k_max:]
            det = g11 * g22 - g12**2
            ok = det > 1e-9 * g11 * g22
            gain = np.where(ok, (g22 * b1**2 - 2 * g12 * b1 * b2 + g11 * b2**2) / np.where(ok, det, 1.0), 0.0) / sigma2
            gain[[k for k, n in enumerate(orders) if (j, int(n)) in taken]] = 0.0
            k = int(np.argmax(gain))
            if gain[k] > threshold:
                picks.append(((j, int(orders[k])), float(gain[k])))
        return sorted(picks, key=lambda pick: -pick[1])

    def identifiability(self, tolerance: float = 1e-6) -> dict:
        """What the data can tell apart: the numerical rank of the fit's Jacobian (columns scaled
        by each parameter's typical size, singular values below ``tolerance`` × the largest
        count as zero), the condition number of the part it can see (largest / smallest kept
        singular value: how much noise the worst-seen direction amplifies) and, for each
        direction it cannot see, the groups that share it (e.g. a
        zero offset and a placement turned about that joint's axis: one effect, two groups);
        the weak prior settles those, the data does not. ``undetermined`` {group: [index in the
        group]}: the parameters with more than 1 % of their (scaled) weight in those directions:
        the data fixes their sum with others, not their own value (the prior splits it; their
        spread from fit to fit is the optimiser's path, not a statistical one)."""
        _, jac, _ = self._state
        layout = self.layout_
        sigma = prior_scales(layout, np.ones((1, 6 + N_COUPLING)))
        scaled = jac * sigma
        _, sv, vt = np.linalg.svd(scaled, full_matrices=False)
        rank = int((sv > tolerance * sv[0]).sum()) if len(sv) else 0
        owner = np.concatenate([[name] * k for name, k in layout.sizes.items() if k])
        together = []
        for v in vt[rank:]:
            share = {}
            for name, w in zip(owner, v * v):
                share[name] = share.get(name, 0.0) + float(w)
            groups = tuple(sorted(g for g, w in share.items() if w > 0.05))
            if groups not in together:
                together.append(groups)
        # the condition number of what the data does separate (largest / smallest kept singular value)
        condition = float(sv[0] / sv[rank - 1]) if rank else math.inf
        null = (vt[rank:] ** 2).sum(axis=0)  # [P] each parameter's weight in the unseen directions
        undetermined = {name: [int(k) for k in np.flatnonzero(null[s] > 0.01)] for name, s in layout.slices().items()
                        if s.stop > s.start and (null[s] > 0.01).any()}
        return {"parameters": int(layout.n), "rank": rank, "condition": condition,
                "unseparated": [list(g) for g in together], "undetermined": undetermined}

    # ------------------------------------------------------------------ using it
    def predict(self, poses: np.ndarray, previous: np.ndarray | None = None) -> np.ndarray:
        """Ê [N, 3] mm for poses [N, 6] (and the poses visited before them, if known)."""
        pose = torch.as_tensor(np.asarray(poses, dtype=np.float64).reshape(-1, 6))
        prev = None if previous is None else torch.as_tensor(np.asarray(previous, dtype=np.float64).reshape(-1, 6))
        with torch.no_grad():
            return self.module_(pose, prev).numpy()

    def parameters(self) -> dict[str, np.ndarray]:
        """The identified groups (rad, mm, rad/Nm) as numpy arrays."""
        return {k: v.numpy() for k, v in self.layout_.unpack(torch.as_tensor(self.theta_)).items()}


def choose_branch(description: RobotDescription, poses: np.ndarray, q_deg: np.ndarray,
                  family: str | None = None) -> tuple[torch.nn.Module, float]:
    """The IK branch that reproduces the controller's joint angles ``q_deg`` [N, 6] for
    ``poses`` [N, 6] on most rows; returns (IK module, fraction of rows it matches to 1°: a
    planner's numerical IK leaves ~0.05°, another branch is tens of degrees away)."""
    pose = _t(poses)
    q = _t(np.radians(q_deg))
    best, best_share = None, -1.0
    family_ik = make_ik(description, family)
    for branch in family_ik.branches():
        ik = type(family_ik)(description, branch)
        with torch.no_grad():
            got = ik(pose)
        match = (torch.abs(wrapped_step(got, q)) < math.radians(1.0)).all(dim=1)
        share = float(match.double().mean())
        if share > best_share:
            best, best_share = ik, share
    return best, best_share

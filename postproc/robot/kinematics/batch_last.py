"""The identified arm as the exported graph evaluates it: batch-last tensors.

``KinematicErrorModule.parts`` (the ONNX graph, ``HybridModel.predict``) runs the forward
kinematics, gravity torques, the first-order joint-error terms, the rotation error and the
``error_std`` Jacobian here: vectors are [3, N] tensors, rotations [3, 3, N] (R[i, j, n]),
per-joint quantities stacked in front ([6, 3, N]). Each step is then a few onnxruntime kernels
over all rows, with N innermost: a product with a constant matrix is one GEMM (``const_mat``),
a product of two per-row rotations one broadcast Mul + ReduceSum (``mat``), a joint's turn the
constant placement times Rodrigues written as P0 + cos q·P1 + sin q·P2 with constant P's (no
Concat/Slice/Unsqueeze per column, no batched 3×3 MatMul, which onnxruntime runs as one tiny
GEMM per row). The same quantities as ``twin.Arm.frames`` / ``Arm.torque_terms`` /
``kinematic.error_at`` / ``kinematic.jacobian`` (tests/test_kinematics.py, tests/test_hybrid*.py:
to rounding), which the fit keeps in the [N, …] layout its least squares stacks.
"""
from __future__ import annotations

import torch

from ...core.frames import MM, abc_entries
from .gravity import gravity_from_points, holding_torques, load_torques

__all__ = ["const_mat", "mat", "mat_t", "mat_vec", "const_vec", "cross", "unit_crosses", "abc_rotations", "joint_turns",
           "Frames", "frames", "torque_terms"]

_NEXT, _PREV = [1, 2, 0], [2, 0, 1]


def const_mat(c: torch.Tensor, a: torch.Tensor) -> torch.Tensor:
    """constant [3, 3] @ [3, k, N] → [3, k, N]: one GEMM over all rows."""
    return (c @ a.reshape(3, -1)).reshape(a.shape)


def mat(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """[3, 3, N] @ [3, 3, N] (either may be a constant [3, 3, 1])."""
    return (a[:, :, None, :] * b[None, :, :, :]).sum(1)


def mat_t(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """[3, 3, N] @ [3, 3, N]ᵀ (per row)."""
    return (a[:, None, :, :] * b[None, :, :, :]).sum(2)


def mat_vec(a: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """[..., 3, 3, N] @ [3, N] or a constant [3, 1] → [..., 3, N]."""
    return (a * v[None, :, :] if v.dim() == 2 else a * v).sum(-2)


def const_vec(a: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """[..., 3, 3, N] @ constant [3] → [..., 3, N]."""
    return (a * v[:, None]).sum(-2)


def cross(a: torch.Tensor, b: torch.Tensor, dim: int) -> torch.Tensor:
    """a × b along ``dim`` (broadcast)."""
    nxt, prv = torch.tensor(_NEXT), torch.tensor(_PREV)
    return (a.index_select(dim, nxt) * b.index_select(dim, prv) - a.index_select(dim, prv) * b.index_select(dim, nxt))


def unit_crosses(v: torch.Tensor) -> torch.Tensor:
    """e_k × v for k = 0, 1, 2 [3(k), 3, N] of vectors ``v`` [3, N]."""
    zero = torch.zeros_like(v[0])
    return torch.stack([torch.stack([zero, -v[2], v[1]]), torch.stack([v[2], zero, -v[0]]),
                        torch.stack([-v[1], v[0], zero])])


def abc_rotations(abc_deg: torch.Tensor) -> torch.Tensor:
    """[N, 3] KUKA A,B,C (deg) → [3, 3, N] R = Rz(A)·Ry(B)·Rx(C) (``core.frames.abc_entries``)."""
    rad = abc_deg.t() * (torch.pi / 180.0)
    cos, sin = torch.cos(rad), torch.sin(rad)
    rows = abc_entries(cos[0], sin[0], cos[1], sin[1], cos[2], sin[2])
    return torch.stack(rows).reshape(3, 3, -1)


def joint_turns(placements: torch.Tensor, axes: torch.Tensor) -> torch.Tensor:
    """[6, 3, 3, 3]: per joint j the constants (P0, P1, P2) with placement_j's rotation ·
    R(axis_j, q) = P0 + cos q·P1 + sin q·P2 (Rodrigues: aaᵀ + cos q (I − aaᵀ) + sin q [a]×)."""
    out = []
    eye = torch.eye(3, dtype=torch.float64)
    for m, a in zip(placements, axes):
        aat = torch.outer(a, a)
        k = torch.tensor([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]], dtype=torch.float64)
        out.append(torch.stack([m[:3, :3] @ aat, m[:3, :3] @ (eye - aat), m[:3, :3] @ k]))
    return torch.stack(out)


class Frames:
    """The joint frames of a chain at q: ``rotations`` [6][3, 3, N], ``origins`` [6][3, N] and the
    TCP ``tcp`` [3, N]."""

    def __init__(self, rotations: list, origins: list, tcp: torch.Tensor):
        self.rotations, self.origins, self.tcp = rotations, origins, tcp

    def axes(self, axes: torch.Tensor) -> torch.Tensor:
        """The joint axes in the base frame [6, 3, N]."""
        return torch.stack([const_vec(r, a) for r, a in zip(self.rotations, axes)])

    def origins_stacked(self) -> torch.Tensor:
        return torch.stack(self.origins)


def frames(turns: torch.Tensor, offsets: torch.Tensor, q: torch.Tensor, end: torch.Tensor,
           base: torch.Tensor | None = None) -> Frames:
    """The chain's frames at q [6, N] rad: joint j at ``offsets`` [6, 3] (its placement's
    translation) in its parent, turned by its placement's rotation and q_j (``turns``:
    ``joint_turns``); ``end`` the TCP in the last joint's frame (a constant [3] or per row
    [3, N]); ``base`` [4, 4] or None (identity)."""
    cos, sin = torch.cos(q), torch.sin(q)
    rotations, origins = [], []
    r = None if base is None else base[:3, :3]
    p = torch.zeros_like(q[:3]) if base is None else base[:3, 3:4] + torch.zeros_like(q[:3])
    for j in range(len(turns)):
        local = turns[j, 0][:, :, None] + cos[j] * turns[j, 1][:, :, None] + sin[j] * turns[j, 2][:, :, None]
        if r is None:
            p = p + offsets[j][:, None]
            r = local
        elif r.dim() == 2:  # (the base: a constant)
            p = p + (r @ offsets[j])[:, None]
            r = const_mat(r, local)
        else:
            p = p + const_vec(r, offsets[j])
            r = mat(r, local)
        rotations.append(r)
        origins.append(p)
    tcp = p + (const_vec(r, end) if end.dim() == 1 else mat_vec(r, end))
    return Frames(rotations, origins, tcp)


def torque_terms(arm, f: Frames, load: torch.Tensor | None = None) -> torch.Tensor:
    """[6 + 21, N]: ``Arm.torque_terms`` (the gravity torques, then each link's share τ_ji, i ≥ j,
    in ``coupling_pairs`` order) of the frames ``f``: ``gravity.gravity_from_points`` /
    ``holding_torques``, the one gravity formula, on [N, …] views of the batch-last frames.
    ``load`` [N, 4] (no NaN): each row's load in place of the payload (``Arm.torque_terms``)."""
    from .twin import coupling_pairs

    omega = f.axes(arm.axes)[:, :2]  # [6, 2, N] (only x, y turn against gravity)
    origins = f.origins_stacked()[:, :2]
    centres = torch.stack([o[:2] + const_vec(r[:2], c) for r, o, c in zip(f.rotations, f.origins, arm.coms)])
    if load is not None:
        j_idx, i_idx = (torch.tensor(v) for v in coupling_pairs(len(arm.axes)))
        in_last = (load[:, 1:] @ arm.flange[:3, :3].T + arm.flange[:3, 3]).t()  # [3, N]
        centre = (f.origins[-1][:2] + mat_vec(f.rotations[-1][:2], in_last)).t()  # [N, 2]
        o, w = origins.transpose(1, 2), omega.transpose(1, 2)
        total = [a + b for a, b in zip(gravity_from_points(o, centres.transpose(1, 2), w, arm.masses),
                                       load_torques(o, w, load[:, 0], centre))]
        lever = (centres[i_idx] - origins[j_idx]) * (MM * arm.masses[i_idx])[:, None, None]
        return torch.cat([torch.stack(total), holding_torques(omega[j_idx].transpose(1, 2), lever.transpose(1, 2))])
    payload = (f.origins[-1][:2] + const_vec(f.rotations[-1][:2], arm.payload_com)).t()
    total = gravity_from_points(origins.transpose(1, 2), centres.transpose(1, 2), omega.transpose(1, 2), arm.masses,
                                arm.payload_mass, payload)
    j_idx, i_idx = (torch.tensor(v) for v in coupling_pairs(len(arm.axes)))
    weights = arm.masses.clone()
    weights[-1] = weights[-1] + arm.payload_mass
    lever = (centres[i_idx] - origins[j_idx]) * (MM * weights[i_idx])[:, None, None]  # [21, 2, N]
    return torch.cat([torch.stack(total), holding_torques(omega[j_idx].transpose(1, 2), lever.transpose(1, 2))])

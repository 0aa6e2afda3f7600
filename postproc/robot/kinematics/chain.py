"""THE forward kinematics (numpy): a serial chain's joint frames for many poses at once."""
from __future__ import annotations

import numpy as np

from ..description import RobotDescription

__all__ = ['Chain']


class Chain:
    """A serial chain of revolute joints, evaluated for many configurations at once (numpy).

    ``placements`` [J, 4, 4] (mm) are joint frames in their parents at q = 0, ``axes`` [J, 3]
    unit axes in the joint frames, ``end`` [4, 4] the end frame (flange, TCP) in the last joint
    frame and ``base`` [4, 4] the first joint's parent in the reference frame. A description's
    chain is :meth:`of`; the simulator perturbs its arrays. Tested against Pinocchio's FK
    (tests/test_kinematics.py).
    """

    def __init__(self, placements: np.ndarray, axes: np.ndarray, end: np.ndarray, base: np.ndarray | None = None):
        self.placements = np.asarray(placements, float)
        self.axes = np.asarray(axes, float)
        self.end = np.asarray(end, float)
        self.base = np.eye(4) if base is None else np.asarray(base, float)

    @classmethod
    def of(cls, description: RobotDescription, tool: bool = True) -> "Chain":
        """The nominal chain of a description, ending at the TCP (or at the flange)."""
        end = description.flange_matrix @ description.tool_matrix if tool else description.flange_matrix
        return cls(description.placements, description.axes, end)

    def _walk(self, q_rad: np.ndarray, count: int | None = None):
        """Each of the first ``count`` joints' rotation (after its turn) and origin, in order,
        stored component-major (rotations [3, 3, N], origins [3, N]: every step a few products
        over contiguous rows): the one FK walk, over the joints and vectorised over poses."""
        count = len(self.axes) if count is None else count
        angles = np.ascontiguousarray(q_rad[:, :count].T)  # [count, N]
        cos, sin = np.cos(angles), np.sin(angles)
        r = np.repeat(self.base[:3, :3, None], len(q_rad), axis=2)
        p = self.base[:3, 3, None]
        for j in range(count):
            m = self.placements[j]
            p = p + _times(r, m[:3, 3])
            if not np.array_equal(m[:3, :3], np.eye(3)):  # (a description's placements are pure offsets)
                r = _times(r, m[:3, :3])
            r = _turned(r, self.axes[j], cos[j], sin[j])
            yield r, p

    def joints(self, q_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Joint rotations [N, J, 3, 3] and origins [N, J, 3] (mm) for configurations [N, J] (radians)."""
        q_rad = np.atleast_2d(np.asarray(q_rad, float))
        rs, ps = zip(*self._walk(q_rad))
        return np.stack(rs).transpose(3, 0, 1, 2), np.stack(ps).transpose(2, 0, 1)

    def zero_frames(self) -> tuple[np.ndarray, np.ndarray]:
        """The joint frames [J, 4, 4] at q = 0 (each after its turn) and the end frame [4, 4]."""
        zero = np.zeros((1, len(self.axes)))
        rotations, origins = self.joints(zero)
        out = np.zeros((len(self.axes), 4, 4))
        out[:, :3, :3], out[:, :3, 3], out[:, 3, 3] = rotations[0], origins[0], 1.0
        return out, self.transforms(zero)[0]

    def transforms(self, q_rad: np.ndarray) -> np.ndarray:
        """[N, 4, 4] end frames for configurations [N, J] (radians)."""
        q_rad = np.atleast_2d(np.asarray(q_rad, float))
        *_, (r, p) = self._walk(q_rad)
        out = np.zeros((len(q_rad), 4, 4))
        out[:, :3, :3] = _times(r, self.end[:3, :3]).transpose(2, 0, 1)
        out[:, :3, 3] = (p + _times(r, self.end[:3, 3])).T
        out[:, 3, 3] = 1.0
        return out


def _times(r: np.ndarray, m: np.ndarray) -> np.ndarray:
    """Rotations stored component-major, r [3, 3, N], times a constant [3] → [3, N] or [3, 3] → [3, 3, N]."""
    if m.ndim == 1:
        return r[:, 0] * m[0] + r[:, 1] * m[1] + r[:, 2] * m[2]
    return np.matmul(m.T, r)


def _turned(r: np.ndarray, axis: np.ndarray, cos: np.ndarray, sin: np.ndarray) -> np.ndarray:
    """r [3, 3, N] (component-major) times the rotations about unit ``axis`` by the angles of
    ``cos``, ``sin`` [N]: about ±e_k two columns mix; any other axis by Rodrigues,
    c·r + s·r[a]× + (1 − c)·(r a) aᵀ."""
    k = int(np.argmax(np.abs(axis)))
    if abs(abs(axis[k]) - 1.0) < 1e-12:
        s = np.sign(axis[k]) * sin
        i, j = [(1, 2), (2, 0), (0, 1)][k]  # R_k mixes columns i, j: (x_i c + x_j s, x_j c − x_i s)
        out = np.empty_like(r)
        out[:, k] = r[:, k]
        out[:, i] = r[:, i] * cos + r[:, j] * s
        out[:, j] = r[:, j] * cos - r[:, i] * s
        return out
    skew = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return cos * r + sin * _times(r, skew) + (1.0 - cos) * _times(r, axis)[:, None, :] * axis[None, :, None]

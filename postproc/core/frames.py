"""KUKA frames: X,Y,Z (mm) and A,B,C (deg) with R = Rz(A)·Ry(B)·Rx(C).

All functions are vectorised over leading axes: a frame is ``[..., 6]``, a homogeneous
transform ``[..., 4, 4]``. ``F1:F2`` in KRL is ``compose(F1, F2)`` = T1·T2.

The dialects write an orientation in one of three *forms* (``ORIENTATION_NAMES``): ``abc``
(KUKA A,B,C degrees; pose lists, Fanuc W/P/R in A,B,C order), ``quaternion`` (RAPID's
q1..q4 = w,x,y,z) and ``rotvec`` (URScript's rotation vector, radians).
``orientation_rotation`` reads a form's numbers, ``orientation_numbers`` writes a rotation in
a form, as the numbers nearest those written before (``compensate --orientation``).
"""
from __future__ import annotations

import numpy as np

__all__ = [
    "rotation_from_abc", "abc_from_rotation", "frame_to_matrix", "matrix_to_frame", "compose", "inverse",
    "transform_points", "rotate_vectors", "rotation_vector", "rotation_error_deg", "frames_used", "frame_groups",
    "rotation_from_quaternion", "quaternion_from_rotation", "rotation_from_rotvec", "rotvec_from_rotation",
    "ORIENTATION_NAMES", "orientation_rotation", "orientation_numbers", "small_transform", "axis_rotations",
    "nearest_rotation", "rotation_zy", "rotation_angle_deg", "nearest_triple", "abc_entries", "MM",
]


def frames_used(frame: np.ndarray) -> np.ndarray:
    """The distinct frame indices ≥ 0 in ``frame`` (targets' ``Targets.frame``), ascending:
    ``np.unique`` without its import of numpy.ma (8 ms of a 100-target CLI run)."""
    frame = np.asarray(frame, dtype=np.int64)
    return np.flatnonzero(np.bincount(frame[frame >= 0]))


def frame_groups(frame: np.ndarray):
    """(f, rows) for each distinct frame index f ≥ 0 of ``frame`` (targets' ``Targets.frame``),
    ascending, ``rows`` the indices where it stands, ascending: one sort, not a pass over every
    row per frame (a program on a track has a frame per track position)."""
    frame = np.asarray(frame, dtype=np.int64)
    rows = np.flatnonzero(frame >= 0)
    if not len(rows):
        return []
    order = rows[np.argsort(frame[rows], kind="stable")]
    keys = frame[order]
    cut = np.flatnonzero(np.diff(keys)) + 1
    return [(int(g[0]), r) for g, r in zip(np.split(keys, cut), np.split(order, cut))]


def rotation_from_abc(abc: np.ndarray) -> np.ndarray:
    """[..., 3] A,B,C in degrees → [..., 3, 3] rotation Rz(A)·Ry(B)·Rx(C)."""
    a, b, c = np.moveaxis(np.radians(np.asarray(abc, dtype=float)), -1, 0)
    with np.errstate(invalid="ignore"):  # an infinite angle gives NaN (callers check), not a warning
        ca, sa, cb, sb, cc, sc = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    r = np.empty(a.shape + (3, 3))
    r[..., 0, 0] = ca * cb
    r[..., 0, 1] = ca * sb * sc - sa * cc
    r[..., 0, 2] = ca * sb * cc + sa * sc
    r[..., 1, 0] = sa * cb
    r[..., 1, 1] = sa * sb * sc + ca * cc
    r[..., 1, 2] = sa * sb * cc - ca * sc
    r[..., 2, 0] = -sb
    r[..., 2, 1] = cb * sc
    r[..., 2, 2] = cb * cc
    return r


def rotation_zy(a: np.ndarray, b: np.ndarray | None = None) -> np.ndarray:
    """Rz(a)·Ry(b) for angle arrays [N] (radians; b None: Rz(a) alone) → [N, 3, 3]: A1's and
    the arm's turn of the closed-form IKs (postproc.robot.kinematics.ik)."""
    ca, sa = np.cos(a), np.sin(a)
    cb, sb = (1.0, 0.0) if b is None else (np.cos(b), np.sin(b))
    r = np.empty(np.shape(a) + (3, 3))
    r[..., 0, 0], r[..., 0, 1], r[..., 0, 2] = ca * cb, -sa, ca * sb
    r[..., 1, 0], r[..., 1, 1], r[..., 1, 2] = sa * cb, ca, sa * sb
    r[..., 2, 0], r[..., 2, 1], r[..., 2, 2] = -sb, 0.0, cb
    return r


def abc_from_rotation(r: np.ndarray) -> np.ndarray:
    """[..., 3, 3] rotation → [..., 3] A,B,C in degrees, B in [-90, 90].

    At gimbal lock (|B| = 90°) only A−C (or A+C) is defined; C is set to 0 there.
    """
    r = np.asarray(r, dtype=float)
    cb = np.hypot(r[..., 0, 0], r[..., 1, 0])
    b = np.arctan2(-r[..., 2, 0], cb)
    locked = cb < 1e-9
    a = np.where(locked, np.arctan2(-r[..., 0, 1], r[..., 1, 1]), np.arctan2(r[..., 1, 0], r[..., 0, 0]))
    c = np.where(locked, 0.0, np.arctan2(r[..., 2, 1], r[..., 2, 2]))
    return np.degrees(np.stack([a, b, c], axis=-1))


def frame_to_matrix(frame: np.ndarray) -> np.ndarray:
    """[..., 6] X,Y,Z,A,B,C → [..., 4, 4] homogeneous transform."""
    frame = np.asarray(frame, dtype=float)
    t = np.zeros(frame.shape[:-1] + (4, 4))
    t[..., :3, :3] = rotation_from_abc(frame[..., 3:6])
    t[..., :3, 3] = frame[..., :3]
    t[..., 3, 3] = 1.0
    return t


def matrix_to_frame(t: np.ndarray) -> np.ndarray:
    """[..., 4, 4] homogeneous transform → [..., 6] X,Y,Z,A,B,C."""
    t = np.asarray(t, dtype=float)
    return np.concatenate([t[..., :3, 3], abc_from_rotation(t[..., :3, :3])], axis=-1)


def compose(*transforms: np.ndarray) -> np.ndarray:
    """T1·T2·…: KRL's ``F1:F2:…`` on 4×4 transforms (broadcasting)."""
    out = transforms[0]
    for t in transforms[1:]:
        out = out @ t
    return out


def inverse(t: np.ndarray) -> np.ndarray:
    """Inverse of rigid transforms (KRL's INV_POS)."""
    t = np.asarray(t, dtype=float)
    out = np.zeros_like(t)
    rt = np.swapaxes(t[..., :3, :3], -1, -2)
    out[..., :3, :3] = rt
    out[..., :3, 3] = -(rt @ t[..., :3, 3, None])[..., 0]
    out[..., 3, 3] = 1.0
    return out


def transform_points(t: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply [..., 4, 4] transforms to [..., 3] points."""
    t = np.asarray(t, dtype=float)
    return (t[..., :3, :3] @ np.asarray(points, dtype=float)[..., None])[..., 0] + t[..., :3, 3]


def rotate_vectors(t: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """Apply only the rotation of [..., 4, 4] transforms to [..., 3] vectors (e.g. corrections)."""
    t = np.asarray(t, dtype=float)
    return (t[..., :3, :3] @ np.asarray(vectors, dtype=float)[..., None])[..., 0]


def rotation_vector(r: np.ndarray) -> np.ndarray:
    """[..., 3, 3] rotations → [..., 3] rotation vectors (rad; the log map, angles < 180°)."""
    r = np.asarray(r, dtype=float)
    v = 0.5 * np.stack([r[..., 2, 1] - r[..., 1, 2], r[..., 0, 2] - r[..., 2, 0], r[..., 1, 0] - r[..., 0, 1]], axis=-1)
    s = np.linalg.norm(v, axis=-1)
    angle = np.arctan2(s, 0.5 * (np.trace(r, axis1=-2, axis2=-1) - 1.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.where(s > 1e-12, angle / np.where(s > 1e-12, s, 1.0), 1.0)
    return v * scale[..., None]


def rotation_angle_deg(abc_a: np.ndarray, abc_b: np.ndarray) -> np.ndarray:
    """The angle [N] (deg) of the rotation between two orientations given as A,B,C [N, 3]."""
    relative = rotation_from_abc(abc_a).swapaxes(-1, -2) @ rotation_from_abc(abc_b)
    cos = (np.trace(relative, axis1=-2, axis2=-1) - 1.0) / 2.0
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def rotation_error_deg(nominal_abc: np.ndarray, actual_abc: np.ndarray) -> np.ndarray:
    """[..., 3] the orientation error as the model contract has it: the rotation vector (deg, base
    frame) of nominal → actual, r with R_actual = exp(r)·R_nominal, from A,B,C [..., 3] each."""
    relative = rotation_from_abc(actual_abc) @ np.swapaxes(rotation_from_abc(nominal_abc), -1, -2)
    return np.degrees(rotation_vector(relative))


def rotation_from_quaternion(q: np.ndarray) -> np.ndarray:
    """[..., 4] quaternions w,x,y,z (any length > 0: scaled to 1) → [..., 3, 3] rotations."""
    q = np.asarray(q, float)
    w, x, y, z = np.moveaxis(q / np.linalg.norm(q, axis=-1, keepdims=True), -1, 0)
    r = np.empty(q.shape[:-1] + (3, 3))
    r[..., 0, 0] = 1 - 2 * (y * y + z * z)
    r[..., 0, 1] = 2 * (x * y - w * z)
    r[..., 0, 2] = 2 * (x * z + w * y)
    r[..., 1, 0] = 2 * (x * y + w * z)
    r[..., 1, 1] = 1 - 2 * (x * x + z * z)
    r[..., 1, 2] = 2 * (y * z - w * x)
    r[..., 2, 0] = 2 * (x * z - w * y)
    r[..., 2, 1] = 2 * (y * z + w * x)
    r[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return r


def quaternion_from_rotation(r: np.ndarray) -> np.ndarray:
    """[..., 3, 3] rotations → [..., 4] unit quaternions w,x,y,z (either sign: q and −q are one
    rotation). Each row of 4·q·qᵀ is built from R's entries and the one with the largest
    diagonal taken (Shepperd's choice: no division by a small number, exact at 180°)."""
    r = np.asarray(r, float)
    d0, d1, d2 = r[..., 0, 0], r[..., 1, 1], r[..., 2, 2]
    a, b, c = r[..., 2, 1] - r[..., 1, 2], r[..., 0, 2] - r[..., 2, 0], r[..., 1, 0] - r[..., 0, 1]
    e, f, g = r[..., 0, 1] + r[..., 1, 0], r[..., 0, 2] + r[..., 2, 0], r[..., 1, 2] + r[..., 2, 1]
    outer = np.stack([np.stack([1 + d0 + d1 + d2, a, b, c], -1),
                      np.stack([a, 1 + d0 - d1 - d2, e, f], -1),
                      np.stack([b, e, 1 - d0 + d1 - d2, g], -1),
                      np.stack([c, f, g, 1 - d0 - d1 + d2], -1)], -2)  # 4·q·qᵀ
    k = np.argmax(np.diagonal(outer, axis1=-2, axis2=-1), axis=-1)
    q = np.take_along_axis(outer, k[..., None, None], axis=-2)[..., 0, :]
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def rotation_from_rotvec(v: np.ndarray) -> np.ndarray:
    """[..., 3] rotation vectors (rad: axis × angle, any angle) → [..., 3, 3] rotations."""
    v = np.asarray(v, float)
    angle = np.linalg.norm(v, axis=-1, keepdims=True)
    # sin(θ/2)/θ as 0.5·sinc(θ/2π): no division by zero at θ = 0
    q = np.concatenate([np.cos(angle / 2), v * (0.5 * np.sinc(angle / (2 * np.pi)))], axis=-1)
    return rotation_from_quaternion(q)


def rotvec_from_rotation(r: np.ndarray) -> np.ndarray:
    """[..., 3, 3] rotations → [..., 3] rotation vectors (rad), angle in [0, π] (at π either
    axis sign). Through the quaternion: exact near 180°, where the log map of R's antisymmetric
    part (``rotation_vector``) loses the axis."""
    q = quaternion_from_rotation(r)
    q = np.where(q[..., :1] < 0, -q, q)
    s = np.linalg.norm(q[..., 1:], axis=-1, keepdims=True)
    angle = 2 * np.arctan2(s, q[..., :1])
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.where(s > 1e-12, angle / np.where(s > 1e-12, s, 1.0), 2.0 / q[..., :1])
    return q[..., 1:] * scale


# the numbers each orientation form writes, by name (for messages)
ORIENTATION_NAMES = {"abc": ("A", "B", "C"), "quaternion": ("q1", "q2", "q3", "q4"), "rotvec": ("rx", "ry", "rz")}


def orientation_rotation(numbers: np.ndarray, form: str) -> np.ndarray:
    """[..., k] the numbers of an orientation ``form`` (A,B,C deg; w,x,y,z; rotation vector
    rad) → [..., 3, 3] rotations."""
    if form == "abc":
        return rotation_from_abc(numbers)
    if form == "quaternion":
        return rotation_from_quaternion(numbers)
    if form == "rotvec":
        return rotation_from_rotvec(numbers)
    raise ValueError(f"unknown orientation form {form!r}")


def orientation_numbers(abc: np.ndarray, written: np.ndarray, form: str) -> np.ndarray:
    """[n, 3] attitudes A,B,C (deg) → [n, k] the numbers of ``form`` nearest ``written`` [n, k]
    (the numbers the program wrote, which every form can write in more than one way):

    * ``abc``: of the two triples of a rotation — (A, B, C) and (A+180, 180−B, C+180) — and
      their turns (±360° on each angle), the one nearest the written triple;
    * ``quaternion``: unit, in the written one's hemisphere (q or −q: one rotation);
    * ``rotvec``: of the vectors (θ + 2πk)·u of one rotation, the one nearest the written vector:
      the principal one (θ ≤ π) unless the written vector is within the correction of θ = π
      (then on its side: continuous with it, θ may pass π by as much) or on another branch.
    """
    abc = np.asarray(abc, float)
    written = np.asarray(written, float)
    if form == "abc":
        alt = np.stack([abc[:, 0] + 180.0, 180.0 - abc[:, 1], abc[:, 2] + 180.0], axis=1)
        near = [written + (t - written + 180.0) % 360.0 - 180.0 for t in (abc, alt)]
        return np.where((np.abs(near[1] - written).max(axis=1) < np.abs(near[0] - written).max(axis=1))[:, None],
                        near[1], near[0])
    r = rotation_from_abc(abc)
    if form == "quaternion":
        q = quaternion_from_rotation(r)
        return np.where(np.sum(q * written, axis=1, keepdims=True) < 0, -q, q)
    if form == "rotvec":
        v = rotvec_from_rotation(r)
        angle = np.linalg.norm(v, axis=1, keepdims=True)
        axis = np.where(angle > 0, v / np.where(angle > 0, angle, 1.0), 0.0)
        turns = np.round((np.sum(written * axis, axis=1, keepdims=True) - angle) / (2 * np.pi))
        return v + (2 * np.pi * turns) * axis
    raise ValueError(f"unknown orientation form {form!r}")


def small_transform(rotvec_rad: np.ndarray, offset_mm: np.ndarray) -> np.ndarray:
    """[..., 4, 4] rigid transforms from rotation vectors [..., 3] and offsets [..., 3]."""
    angle = np.linalg.norm(rotvec_rad, axis=-1)
    axis = np.where(angle[..., None] > 0, rotvec_rad / np.where(angle > 0, angle, 1.0)[..., None], [0.0, 0.0, 1.0])
    t = np.zeros(rotvec_rad.shape[:-1] + (4, 4))
    t[..., :3, :3] = axis_rotations(axis, angle)
    t[..., :3, 3] = offset_mm
    t[..., 3, 3] = 1.0
    return t


def nearest_triple(abc: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Of the two A,B,C triples of each rotation, (A, B, C) and (A+180, 180−B, C+180), the one
    nearest ``ref`` [N, 3], each angle on the turn nearest the reference's (the probe reads
    angles as the program writes them: B = 93° stays 93°, not 87° with A and C turned)."""
    alt = np.stack([abc[:, 0] + 180.0, 180.0 - abc[:, 1], abc[:, 2] + 180.0], axis=1)
    out = []
    for t in (abc, alt):
        out.append(ref + (t - ref + 180.0) % 360.0 - 180.0)
    far = [np.abs(t - ref).max(axis=1) for t in out]
    return np.where((far[1] < far[0])[:, None], out[1], out[0])


def nearest_rotation(m: np.ndarray) -> np.ndarray:
    """The rotation nearest a [3, 3] matrix (Frobenius): its SVD's U·diag(1, 1, ±1)·Vᵀ, the sign
    making it proper (Kabsch's fit of directions, a chordal mean of rotations)."""
    u, _, vt = np.linalg.svd(m)
    return u @ np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))]) @ vt


def abc_entries(ca, sa, cb, sb, cc, sc) -> list:
    """The nine entries (row by row) of R = Rz(A)·Ry(B)·Rx(C) from the cosines and sines of
    A, B, C (arrays or tensors): the one formula of the torch rotations (the twin's
    ``rotation_matrices`` and the exported graph's batch-last ``batch_last.abc_rotations``);
    :func:`rotation_from_abc` writes the same entries in place (numpy: no nine temporaries,
    ~15% faster on 300k rows)."""
    return [
        ca * cb, ca * sb * sc - sa * cc, ca * sb * cc + sa * sc,
        sa * cb, sa * sb * sc + ca * cc, sa * sb * cc - ca * sc,
        -sb, cb * sc, cb * cc,
    ]  # fmt: skip


MM = 1e-3  # mm → m: the one unit factor (its inverse, m → mm, is 1 / MM: x / MM)


def axis_rotations(axes: np.ndarray, q_rad: np.ndarray) -> np.ndarray:
    """Rotations about unit ``axes`` [J, 3] by angles ``q_rad`` [N, J] → [N, J, 3, 3].

    Rodrigues as c·I + s·[a]× + (1−c)·a·aᵀ: elementwise over all poses, no small matmuls."""
    axes = np.asarray(axes, float)
    k = np.zeros(axes.shape[:-1] + (3, 3))
    k[..., 0, 1], k[..., 0, 2], k[..., 1, 2] = -axes[..., 2], axes[..., 1], -axes[..., 0]
    k[..., 1, 0], k[..., 2, 0], k[..., 2, 1] = axes[..., 2], -axes[..., 1], axes[..., 0]
    aat = axes[..., :, None] * axes[..., None, :]
    s, c = np.sin(q_rad)[..., None, None], np.cos(q_rad)[..., None, None]
    return c * np.eye(3) + s * k + (1.0 - c) * aat

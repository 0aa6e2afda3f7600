"""The nominal robot (:class:`Robot`): a description's FK, gravity torques and the controller's
inverse kinematics, in mm and degrees at every public interface.

A description (``models/kr500.toml`` is the example; :mod:`postproc.robot.description`) lists
the joints of a serial 6R arm; everything here is built from its arrays, in
:mod:`postproc.robot.kinematics`: the forward kinematics of many poses at once is the numpy
:class:`~postproc.robot.kinematics.chain.Chain`, the gravity torques
:func:`~postproc.robot.kinematics.gravity.gravity_torques` of its joint frames, the inverse
kinematics the closed form of the arm's family (:mod:`postproc.robot.kinematics.ik`: KUKA-type
with a spherical wrist, or UR-type; 8 branches), each pose solved on the branch nearest a
reference configuration, each joint on its 360° turn nearest it within the limits.
Pinocchio's model (``model``, ``data``, :meth:`Robot.pin_fk`:
:mod:`postproc.robot.kinematics.reference`, built on first use) is the reference the checks
compare with; no product path computes with it.
"""
from __future__ import annotations

import math

import numpy as np

from ..core import frames
from .description import RobotDescription, load_description
from .kinematics.chain import Chain
from .kinematics.gravity import gravity_torques
from .kinematics.ik import SHOULDER_MM, KukaGeometry, UrGeometry, geometry_of
from .kinematics.reference import pin_fk, pin_model

__all__ = ["Robot"]


class Robot:
    """The nominal robot: FK (:class:`Chain`), gravity torques, the controller's IK; its
    ``pin.Model`` (``model``, ``data``: the reference, built on first use).

    >>> robot = Robot()                       # models/kr500.toml
    >>> poses = robot.fk([[0, -90, 90, 0, 45, 0]])
    >>> q, ok = robot.ik(poses)
    """

    def __init__(self, description: RobotDescription | None = None):
        self.description = description if description is not None else load_description()
        d = self.description
        self.name: str = d.name
        self.tool: np.ndarray = d.tool.copy()
        self.tool_name: str = d.tool_name
        self.home_q: np.ndarray = d.home_q.copy()
        self.joint_names: list[str] = [j.name for j in d.joints]
        self.limits: np.ndarray = np.array([j.limits for j in d.joints])  # [6, 2] deg
        self.flange_chain = Chain.of(d, tool=False)
        self.tool_matrix = d.tool_matrix
        self.chain = Chain.of(d)
        self._solver: KukaGeometry | UrGeometry = geometry_of(d)
        self._model = None

    @property
    def family(self) -> str:
        """'kuka' (KUKA-type arm, spherical wrist) or 'ur' (Universal-Robots-type wrist)."""
        return self._solver.family

    @property
    def _ik(self) -> KukaGeometry:
        """The KUKA-type geometry (:meth:`reach` reads its dimensions); P333 for other arms."""
        return self._solver if self._solver.family == "kuka" else KukaGeometry(self.description)

    def _build_model(self) -> None:
        """The pin.Model, built once on first use (only checks need it)."""
        self._model = pin_model(self.description)
        self._data = self._model.createData()

    @property
    def model(self):
        """The ``pin.Model`` of the nominal robot with its payload (built once)."""
        if self._model is None:
            self._build_model()
        return self._model

    @property
    def data(self):
        """The ``pin.Data`` reused by every Pinocchio call."""
        if self._model is None:
            self._build_model()
        return self._data

    # ---------------------------------------------------------------- FK
    def fk_matrix(self, q_deg: np.ndarray) -> np.ndarray:
        """TCP transforms [N, 4, 4] (mm) for joint angles [N, 6] (deg)."""
        return self.chain.transforms(np.radians(np.atleast_2d(np.asarray(q_deg, float))))

    def fk(self, q_deg: np.ndarray) -> np.ndarray:
        """TCP poses X,Y,Z,A,B,C [N, 6] (mm, deg; B in [-90, 90]) for joint angles [N, 6] (deg)."""
        return frames.matrix_to_frame(self.fk_matrix(q_deg))

    def pin_fk(self, q_deg: np.ndarray, frame: str = "tcp") -> np.ndarray:
        """The reference FK, Pinocchio's (:func:`~postproc.robot.kinematics.reference.pin_fk`; for checks)."""
        return pin_fk(self.model, self.data, q_deg, frame)

    # ---------------------------------------------------------------- gravity
    def gravity_torques(self, q_deg: np.ndarray, payload: bool = True) -> np.ndarray:
        """Joint torques [N, 6] (Nm) that hold the arm (with its payload, or without) against
        gravity at joint angles [N, 6] (deg): :func:`gravity_torques`."""
        return gravity_torques(self.description, q_deg, payload, self.flange_chain)

    # ---------------------------------------------------------------- IK
    def ik(self, poses: np.ndarray, reference_q: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The controller's inverse kinematics: joint angles [N, 6] (deg) for TCP poses [N, 6]
        (robot base frame, mm/deg) and a mask of poses reachable within the joint limits.

        Of the 8 closed-form branches (shoulder, elbow, wrist) and the 360° turns of each
        joint, the one nearest to ``reference_q`` ([6] or [N, 6], default HOME) is chosen;
        rows that cannot be reached are NaN."""
        q_all, ok_all = self.ik_branches(poses, reference_q)
        ref = self.home_q if reference_q is None else np.asarray(reference_q, float)
        ref = np.broadcast_to(ref, q_all.shape[1:])
        cost = np.where(ok_all, ((q_all - ref) ** 2).sum(axis=-1), np.inf)
        best = np.argmin(cost, axis=0)
        n = np.arange(q_all.shape[1])
        q = q_all[best, n]
        ok = ok_all[best, n]
        q[~ok] = np.nan
        return q, ok

    def ik_branches(self, poses: np.ndarray, reference_q: np.ndarray | None = None,
                    check: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Every closed-form branch: joint angles [8, N, 6] (deg; each joint on the 360° turn
        nearest ``reference_q`` within its limits, default HOME) and a mask [8, N] of the
        branches that reach the pose within the limits (FK checked: 1e-6 mm, 1e-9 rad; with
        ``check`` False the caller checks the branches it uses with :meth:`reaches`).
        Which branch is which: :meth:`status_turn` of the angles."""
        poses = np.atleast_2d(np.asarray(poses, float))
        ref = self.home_q if reference_q is None else np.asarray(reference_q, float)
        ref = np.broadcast_to(ref, (len(poses), 6))
        t_tcp = frames.frame_to_matrix(poses)
        q_all, ok_all = self._solver.branches(t_tcp, np.radians(ref))
        q_all = np.degrees(q_all)
        q_all, in_limits = self.nearest_turn(q_all, ref)
        ok_all &= in_limits
        q_all[~ok_all] = np.nan
        flat = ok_all.ravel()
        if check and flat.any():  # a closed form is exact; the check guards the reachability masks themselves
            bad = ~self.reaches(q_all.reshape(-1, 6)[flat], t_tcp[np.nonzero(ok_all)[1]])
            if bad.any():  # (the row of each reaching branch, in flat order)
                idx = np.flatnonzero(flat)[bad]
                ok_all.ravel()[idx] = False
                q_all.reshape(-1, 6)[idx] = np.nan
        return q_all, ok_all

    def status_branch(self, poses: np.ndarray, status: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """The branch of each pose [n, 6] whose Status is ``status`` [n], without the other seven:
        (joint angles [n, 6] deg, reach mask [n], sure [n]), the entry ``ik_branches(poses,
        zeros, check=False)`` gives that status (same numbers), where ``sure``: every reaching
        branch of the pose is clear of the shoulder, elbow and wrist boundaries, so each has the
        status of its index and no two share one (the rows not sure: solve all 8). None for an
        arm without this shortcut (UR-type)."""
        if self.family != "kuka":
            return None
        poses = np.atleast_2d(np.asarray(poses, float))
        ref = np.zeros((len(poses), 6))
        t_tcp = frames.frame_to_matrix(poses)
        status = np.asarray(status, int).reshape(len(poses))
        q, ok, sure = self._solver.status_branch(t_tcp, np.radians(ref), status)
        q = np.degrees(q)
        q, in_limits = self.nearest_turn(q, ref)
        ok &= in_limits
        q[~ok] = np.nan
        return q, ok, sure

    def nearest_pair(self, poses: np.ndarray, ref_deg: np.ndarray) -> tuple | None:
        """For a choice of the branch nearest ``ref_deg`` [n, 6]: the two branches (both wrists)
        of the arm branch (A1-A3) whose A1-A3 lie nearest ``ref_deg`` (on their nearest turns),
        as :meth:`ik_branches` (zeros, check=False) gives them: (joint angles [2, n, 6] deg,
        reach [2, n], their Status [2, n], the least squared A1-A3 distance of the other three
        arm branches [n] (inf where none reaches within the limits), sure [n] (:meth:`status_branch`)).
        A branch of another arm is at least that far from ``ref_deg``. None for a UR-type arm."""
        if self.family != "kuka":
            return None
        poses = np.atleast_2d(np.asarray(poses, float))
        n = len(poses)
        zeros = np.zeros((n, 6))
        ref_deg = np.broadcast_to(np.asarray(ref_deg, float), (n, 6))
        g = self._solver
        r_all, arms, sure = g.arm_table(frames.frame_to_matrix(poses))
        lo, hi = self.limits[:3, 0] - 1e-9, self.limits[:3, 1] + 1e-9
        far = np.empty((4, n))
        for k, (reach_ok, th1, th2, th3) in enumerate(arms):
            q = np.zeros((n, 6))  # A1-A3 as _wrist and ik_branches make them (each joint on its own)
            q[:, :3] = np.stack([g.s[0] * th1, g.s[1] * th2, g.s[2] * th3], axis=-1)
            q = np.degrees((q + np.pi) % (2 * np.pi) - np.pi)
            q, _ = self.nearest_turn(q, zeros)
            inside = ((q[:, :3] >= lo) & (q[:, :3] <= hi)).all(axis=1)
            cand, _ = self.nearest_turn(q, ref_deg)
            inside &= ((cand[:, :3] >= lo) & (cand[:, :3] <= hi)).all(axis=1)
            with np.errstate(invalid="ignore"):
                far[k] = np.where(reach_ok & inside, ((cand[:, :3] - ref_deg[:, :3]) ** 2).sum(axis=-1), np.inf)
        arm = np.argmin(far, axis=0)
        others = np.where(np.arange(4)[:, None] == arm, np.inf, far).min(axis=0)
        th = [np.choose(arm, [a[i] for a in arms]) for i in (1, 2, 3)]
        reach = np.choose(arm, [a[0] for a in arms])
        q_pair, ok_pair, status = np.empty((2, n, 6)), np.empty((2, n), bool), np.empty((2, n), int)
        for j, flip in enumerate((1.0, -1.0)):
            q = np.degrees(g._wrist(th[0], th[1], th[2], r_all, flip, np.radians(zeros)))
            q, in_limits = self.nearest_turn(q, zeros)
            ok = reach & in_limits
            q[~ok] = np.nan
            q_pair[j], ok_pair[j], status[j] = q, ok, g.status_of(arm, np.full(n, flip))
        return q_pair, ok_pair, status, others, sure

    def reaches(self, q_deg: np.ndarray, t_tcp: np.ndarray) -> np.ndarray:
        """The FK check of IK solutions: [M] bool, joint angles [M, 6] (deg) whose TCP is the
        transform [M, 4, 4] within 1e-6 mm and 1e-9 (rotation matrix entries)."""
        back = self.fk_matrix(q_deg)
        bad = np.linalg.norm(back[:, :3, 3] - t_tcp[:, :3, 3], axis=1) > 1e-6
        bad |= np.abs(back[:, :3, :3] - t_tcp[:, :3, :3]).max(axis=(1, 2)) > 1e-9
        return ~bad

    def nearest_turn(self, q_deg: np.ndarray, ref_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Add the multiple of 360° that brings each joint nearest to the reference within its
        limits (the nearest turn, or the next one towards the inside of the limits); and a
        mask of the rows whose joints are then all within the limits."""
        lo, hi = self.limits[:, 0], self.limits[:, 1]
        with np.errstate(invalid="ignore"):
            q = q_deg + 360.0 * np.rint((ref_deg - q_deg) / 360.0)
            q += 360.0 * (q < lo - 1e-9)
            q -= 360.0 * (q > hi + 1e-9)
            inside = (q >= lo - 1e-9) & (q <= hi + 1e-9)
        return q, inside.all(axis=-1)

    def shoulder_status(self, poses: np.ndarray) -> np.ndarray | None:
        """S bit 0 of each of :meth:`ik_branches`' branches [8, N] (int8) where the branch's
        shoulder decides it (a KUKA-type arm whose wrist centre is more than 1e-3 mm off the A1
        axis: the first 4 branches in front, the last 4 behind), −1 where :meth:`status_turn`
        must compute it; None for an arm without this shortcut (UR-type)."""
        if self.family != "kuka":
            return None
        poses = np.atleast_2d(np.asarray(poses, float))
        known = self._solver.wrist_radius(frames.frame_to_matrix(poses)) > SHOULDER_MM
        side = np.repeat(np.array([0, 1], np.int8), 4)[:, None]
        return np.where(known[None, :], side, np.int8(-1))

    def status_turn(self, q_deg: np.ndarray, behind: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """KUKA Status and Turn [N] ints of joint angles [N, 6]: S bit 0 = wrist point behind
        the A1 axis (overhead), bit 1 = A3 at or beyond the stretched-arm angle, bit 2 = A5 ≤ 0
        (A5 taken in (−180°, 180°]); T bit i = A(i+1) < 0. The wrist point is the wrist centre (A5's origin) of a KUKA-type
        arm and A6's origin of a UR-type arm (UR controllers have no S/T: this is postproc's
        mapping of their shoulder, elbow and wrist branches on KUKA's bits)."""
        q = np.atleast_2d(np.asarray(q_deg, float))
        shape = q.shape[:-1]
        q = q.reshape(-1, 6)
        g = self._solver
        if behind is None:
            back = self._wrist_in_a1(np.radians(q), g.wrist_index)[:, 0] < 0
        else:  # bit 0 given where known (shoulder_status), computed where −1
            behind = np.asarray(behind).reshape(-1)
            back = behind == 1
            todo = np.flatnonzero(behind < 0)
            if len(todo):
                back[todo] = self._wrist_in_a1(np.radians(q[todo]), g.wrist_index)[:, 0] < 0
        stretched = math.degrees(g.s[2] * g.stretched)  # A3 with the forearm in line with the upper arm
        from_stretched = (q[:, 2] - stretched + 180.0) % 360.0 - 180.0
        beyond = from_stretched >= 0 if g.s[2] > 0 else from_stretched <= 0
        flipped = (q[:, 4] + 180.0) % 360.0 - 180.0 <= 0  # (a UR wrist turns ±360°: the branch, not the turn)
        status = back.astype(int) | (beyond.astype(int) << 1) | (flipped.astype(int) << 2)
        turn = ((q < 0).astype(int) << np.arange(6)).sum(axis=1)
        return status.reshape(shape), turn.reshape(shape)

    def _wrist_in_a1(self, q_rad: np.ndarray, wrist: int) -> np.ndarray:
        """The origin of joint ``wrist`` [N, 3] in A1's turned frame (relative to A1's origin):
        the chain after A1 walked only as far as needed (status bit 0 of 10^6 branches)."""
        after_a1 = Chain(self.flange_chain.placements[1:], self.flange_chain.axes[1:], np.eye(4))
        *_, (_, origin) = after_a1._walk(q_rad[:, 1:], wrist)  # joints A2 .. the wrist point's
        return origin.T

    @property
    def reach(self) -> dict:
        """Sphere that holds every reachable TCP position: centre on the A1 axis at A2's height,
        radius_max = A1→A2 offset + upper arm + forearm + wrist centre→TCP (conservative:
        nothing reachable lies outside); radius_min 0."""
        g = self._ik
        radius = math.hypot(g.a1, 0.0) + g.l2 + g.l3 + float(np.linalg.norm(g.tcp0 - g.c0))
        centre = g.p1 + np.array([0.0, 0.0, g.d1])
        return {"center": [round(float(v), 3) for v in centre], "radius_min": 0.0, "radius_max": round(radius, 3)}

    def __repr__(self) -> str:
        return f"Robot({self.name!r}, tool={self.tool.tolist()})"



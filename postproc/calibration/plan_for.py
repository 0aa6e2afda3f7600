"""``postproc plan --for PROGRAMS``: measurement poses for the programs that will run.

A model holds where its data was: the joint arcs, arm configurations and tools the measurement
visited (compensate warns, P301, outside the arcs; the wrist zero offsets are not separable from
the tool with one configuration). So the plan starts from the programs:

1. **What they use** (:func:`program_targets`, the one place that reads programs: the public
   API ``compensate.load_program``, ``findings.robot_base_poses`` and the program's
   ``Targets``): each target's pose in the robot base, the controller's joint angles in its
   arm configuration (S/T, or the controller's rules: ``configuration.target_joints``) and its
   ``$TOOL``.
2. **Groups**: the targets' arm configurations (Status bits 0–2) × tools. Each group gets at
   least ``MIN_SHARE`` of the plan (all groups alike when there are more than 1/``MIN_SHARE``),
   the rest by its share of the targets.
3. **Candidates** per group: joint angles drawn by Latin hypercube in the group's joint arcs
   (those of its targets, widened as P301 widens a model's, within the joint limits), and the
   targets themselves; kept where the nominal arm reaches them in that configuration and
   clear of the wrist singularity (|A5| ≥ ``WRIST_CLEAR_DEG``).
4. **Selection**: ``COVER`` of each group's poses space-filling (the first candidates of its
   hypercube), the rest for observability: greedy D-optimal design over the identification's
   Jacobian (``training.kinematic.jacobian`` of the physical groups at the nominal arm, each
   parameter in its typical size, the fit's prior as information of its own, the rows of
   ``--data`` already measured counted in): the next pose is the candidate that adds most to
   log det of the information matrix (Fedorov's greedy exchange without the exchange; FIGAROH
   picks its calibration poses by the same criterion).
5. **Coverage** (:func:`coverage`): which targets the existing data does not cover — in an arm
   configuration or with a tool it has no rows of, or outside its joint arcs in that
   configuration (widened as P301's) — P337, located at the target.

torch is imported only for the Jacobian (the training extra).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core.diagnostics import P337, P512, Diagnostic, PostprocError

__all__ = ["ProgramTargets", "program_targets", "plan_for", "PlanFor", "coverage", "listed", "MIN_SHARE", "COVER"]

MIN_SHARE = 0.2  # each configuration × tool group gets at least this share of the plan
COVER = 0.5  # share of a group's poses drawn space-filling (the rest: D-optimal)
WRIST_CLEAR_DEG = 5.0  # candidates keep |A5| at least this far from the wrist singularity
CANDIDATES = 600  # joint-space candidates drawn per group (besides up to as many of its targets)
NOISE_MM = 0.05  # measurement noise per coordinate the design assumes (against the prior's sizes)
DESIGN_GROUPS = ("placement", "base", "tool", "zero", "compliance")  # the physical groups designed for
TOOL_DECIMALS = 3  # tools equal to this many decimals are one


@dataclass
class ProgramTargets:
    """The programs' targets as the controller runs them (rows in program order, file by file)."""

    poses: np.ndarray  # [N, 6] robot base (the description's frame), TCP
    joints: np.ndarray  # [N, 6] deg, the controller's joint angles in each target's configuration
    tools: np.ndarray  # [N, 6] each target's TCP on the flange
    where: list[tuple[str, int, int]]  # each target's (file, line, col)
    skipped: list[Diagnostic] = field(default_factory=list)  # targets without a known frame or joint angles

    def __len__(self) -> int:
        return len(self.poses)


def program_targets(programs, description) -> ProgramTargets:
    """The targets of ``programs`` (read as compensate reads them: ``programs.cell.load_programs``):
    each target's pose, joint angles and tool (see the module text). Targets whose frame is
    not known, that leave a coordinate out, or whose configuration the nominal arm cannot take
    are skipped, each said once (P337, note)."""
    from ..core import frames
    from ..programs.base_poses import robot_base_poses
    from ..programs.locate import where
    from ..robot import configuration
    from ..robot.arm import Robot

    robot = Robot(description)
    controller = frames.frame_to_matrix(np.asarray(description.controller_base, float))
    poses, joints, tools, places, skipped = [], [], [], [], []
    for program in programs:
        bases = [controller @ f.base for f in program.frames]
        base_poses, resolved = robot_base_poses(program, bases)
        t = program.targets
        ok = resolved & np.isfinite(base_poses).all(axis=1)
        rows = np.flatnonzero(ok)
        own = np.tile(np.asarray(description.tool, float), (len(t), 1))
        for f, frame in enumerate(program.frames):
            if frame.tool is not None:
                own[t.frame == f] = frame.tool
        q, found = configuration.target_joints(robot, t, rows, base_poses[rows], own[rows], robot.home_q)
        for r in np.flatnonzero(~ok)[:1]:
            skipped.append(Diagnostic(*where(program, int(r)), P337, f"{int((~ok).sum())} target(s) of this program "
                                      "with an unknown frame or a coordinate left out: not planned for", "note"))
        for r in rows[~found][:1]:
            skipped.append(Diagnostic(*where(program, int(r)), P337, f"{int((~found).sum())} target(s) of this "
                                      "program without joint angles on the nominal arm: not planned for", "note"))
        rows, q = rows[found], q[found]
        poses.append(base_poses[rows])
        joints.append(q)
        tools.append(own[rows])
        places += [where(program, int(r)) for r in rows]
    if not places:
        raise PostprocError("no target of the programs has a known frame and joint angles: nothing to plan for",
                            programs[0].files[0] if programs else "", code=P512)
    return ProgramTargets(np.concatenate(poses), np.concatenate(joints), np.round(np.concatenate(tools), TOOL_DECIMALS),
                          places, skipped)


def _groups(robot, joints: np.ndarray, tools: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each row's group (0…G−1: arm configuration = Status bits 0–2, × tool) and the groups' keys
    [G, 7] (status, tool)."""
    from ..robot import conventions

    status = np.empty(len(joints), int)
    for tool in np.unique(tools, axis=0):
        here = (tools == tool).all(axis=1)
        arm = type(robot)(robot.description.replace(tool=tool))
        status[here] = conventions.status_turn_of(arm, joints[here])[0] & 7
    keys, group = np.unique(np.c_[status, tools], axis=0, return_inverse=True)
    return group.ravel(), keys


def _quotas(n: int, counts: np.ndarray) -> np.ndarray:
    """Poses per group: at least MIN_SHARE of ``n`` each (or n / G when G·MIN_SHARE > 1), the rest
    by the groups' shares of the targets (largest remainders)."""
    g = len(counts)
    floor = min(MIN_SHARE, 1.0 / g) * n
    want = floor + (n - g * floor) * counts / counts.sum()
    out = np.floor(want).astype(int)
    out[np.argsort(want - out)[::-1][: n - out.sum()]] += 1
    return out


def _candidates(robot, joints: np.ndarray, tool: np.ndarray, status: int, rng, count: int) -> tuple[np.ndarray, np.ndarray]:
    """Candidate joint angles [M, 6] deg for one group (its targets' ``joints``, configuration
    ``status``, TCP ``tool``) and their poses [M, 6]: ``count`` drawn by Latin hypercube in the
    targets' widened joint arcs within the limits, space-filling order first, then the targets;
    kept where the nominal arm reaches the pose in that configuration (the IK gives the angles
    back) clear of the wrist singularity."""
    from scipy.stats import qmc

    from ..model.envelope import joint_arcs, widened_arcs
    from ..robot import configuration, conventions

    arm = type(robot)(robot.description.replace(tool=tool))
    arcs = widened_arcs(joint_arcs(joints))
    limits = np.array([j.limits for j in robot.description.joints], float)
    unit = qmc.LatinHypercube(d=6, seed=rng).random(count)
    drawn = arcs[:, 0] + unit * (arcs[:, 1] - arcs[:, 0])
    # each angle as the turn nearest the targets' own (a joint's limits may allow several)
    centre = np.median(joints, axis=0)
    drawn = drawn + 360.0 * np.round((centre - drawn) / 360.0)
    pick = rng.permutation(len(joints))[:count]
    q = np.vstack([drawn, joints[pick]])
    inside = ((q >= limits[:, 0]) & (q <= limits[:, 1])).all(axis=1)
    clear = np.abs(np.mod(q[:, 4] + 180.0, 360.0) - 180.0) >= WRIST_CLEAR_DEG
    q = q[inside & clear]
    poses = arm.fk(q)
    s, t = conventions.status_turn_of(arm, q)
    back, found = configuration.stated_joints(arm, poses, s, t)
    same = found & (np.abs(np.mod(back - q + 180.0, 360.0) - 180.0).max(axis=1) < 1e-3) & ((s & 7) == status)
    return q[same], poses[same]


def _design_jacobian(description, q_deg: np.ndarray, tools: np.ndarray, several_tools: bool) -> np.ndarray:
    """[N, 3, P]: the identification's position Jacobian (``training.kinematic.jacobian``) of its
    physical groups at the nominal arm, each column in its parameter's typical size (the fit's
    prior unit) and per NOISE_MM of measurement noise."""
    import torch

    from ..model.training.kinematic import Layout, jacobian, prior_scales
    from ..robot.kinematics.twin import Arm

    groups = DESIGN_GROUPS + (("mount",) if several_tools else ())
    layout = Layout(tuple(g for g in ("placement", "base", "tool", "mount", "zero", "compliance") if g in groups))
    arm = Arm(description)
    q = torch.as_tensor(np.radians(q_deg))
    with torch.no_grad():
        rot, org, _ = arm.frames(q)
        tau = arm.torque_terms(rot, org)
        _, jac, _ = jacobian(arm, layout, torch.zeros(layout.n, dtype=torch.float64), q, torch.zeros_like(q), tau,
                             torch.as_tensor(tools[:, :3]) if several_tools else None)
    return jac.numpy() * prior_scales(layout, tau.numpy())[None, None, :] / NOISE_MM


def _greedy(info: np.ndarray, blocks: np.ndarray, want: int) -> tuple[list[int], np.ndarray]:
    """Greedy D-optimal choice of ``want`` of the candidates' Jacobian ``blocks`` [M, 3, P] given
    the information ``info`` [P, P] so far: each step the candidate with the largest
    log det(I + J M⁻¹ Jᵀ), M⁻¹ updated by Woodbury. Returns the chosen indices and the new M."""
    m_inv = np.linalg.inv(info)
    chosen: list[int] = []
    free = np.ones(len(blocks), bool)
    for _ in range(min(want, len(blocks))):
        a = blocks @ m_inv  # [M, 3, P]
        s = np.einsum("mip,mjp->mij", a, blocks) + np.eye(3)
        gain = np.where(free, np.linalg.slogdet(s)[1], -np.inf)
        k = int(np.argmax(gain))
        chosen.append(k)
        free[k] = False
        j = blocks[k]
        mj = m_inv @ j.T
        m_inv = m_inv - mj @ np.linalg.solve(np.eye(3) + j @ mj, mj.T)
        info = info + j.T @ j
    return chosen, info


@dataclass
class PlanFor:
    """The plan: poses [n, 6] (robot base), S/T [n, 2], tools [n, 6] (each row's TCP), each row's
    group, the groups' keys (status, tool) and target counts, the design's log det gain."""

    poses: np.ndarray
    config: np.ndarray
    tools: np.ndarray
    group: np.ndarray
    keys: np.ndarray
    targets_per_group: np.ndarray
    log_det: tuple[float, float]  # of the information matrix before (prior + data) and after the plan


def plan_for(targets: ProgramTargets, description, n: int, seed: int = 0,
             data_joints: np.ndarray | None = None, data_tools: np.ndarray | None = None) -> PlanFor:
    """``n`` measurement poses for the programs' ``targets`` (see the module text); the rows of
    existing data (their joint angles [M, 6] deg and tools [M, 6]) count in the design."""
    from ..robot import conventions
    from ..robot.arm import Robot

    if n < 1:
        raise PostprocError(f"a plan needs at least 1 pose, got {n}", code=P512)
    robot = Robot(description)
    rng = np.random.default_rng(seed)
    group, keys = _groups(robot, targets.joints, targets.tools)
    counts = np.bincount(group, minlength=len(keys))
    quotas = _quotas(n, counts)
    several = len(np.unique(targets.tools[:, :3], axis=0)) > 1 or (
        data_tools is not None and len(np.unique(np.round(data_tools[:, :3], TOOL_DECIMALS), axis=0)) > 1)
    cand_q, cand_p, cand_g, cover = [], [], [], []
    for g, key in enumerate(keys):
        q, p = _candidates(robot, targets.joints[group == g], key[1:], int(key[0]), rng, CANDIDATES)
        if not len(q):
            raise PostprocError(f"no reachable pose in the joint region of the targets in configuration S {int(key[0])} "
                                f"with tool {key[1:].tolist()}", code=P512)
        k = min(len(q), int(round(COVER * quotas[g])))
        cover.append(len(np.concatenate(cand_g)) + np.arange(k) if cand_g else np.arange(k))
        cand_q.append(q)
        cand_p.append(p)
        cand_g.append(np.full(len(q), g))
    cand_q, cand_p, cand_g = np.concatenate(cand_q), np.concatenate(cand_p), np.concatenate(cand_g)
    cand_t = keys[cand_g, 1:]
    blocks = _design_jacobian(description, cand_q, cand_t, several)
    info = np.eye(blocks.shape[2])  # the prior: each parameter ~ its typical size
    if data_joints is not None and len(data_joints):
        tools = np.tile(description.tool, (len(data_joints), 1)) if data_tools is None else data_tools
        d = _design_jacobian(description, data_joints, tools, several).reshape(-1, blocks.shape[2])
        info = info + d.T @ d
    start = np.linalg.slogdet(info)[1]
    chosen = list(np.concatenate(cover).astype(int))
    for k in chosen:
        info = info + blocks[k].T @ blocks[k]
    # the rest of each group's quota for observability, the groups in turn
    for g in range(len(keys)):
        pool = np.flatnonzero((cand_g == g) & ~np.isin(np.arange(len(cand_g)), chosen))
        want = quotas[g] - int((cand_g[chosen] == g).sum())
        picked, info = _greedy(info, blocks[pool], want)
        chosen += [int(pool[i]) for i in picked]
    chosen = np.asarray(chosen)
    # visiting order: tool by tool (a tool change is a stop), the rows of each shuffled
    order = np.concatenate([rng.permutation(chosen[(cand_t[chosen] == tool).all(axis=1)])
                            for tool in np.unique(cand_t[chosen], axis=0)])
    q = cand_q[order]
    config = np.zeros((len(order), 2), np.int64)
    for tool in np.unique(cand_t[order], axis=0):
        here = (cand_t[order] == tool).all(axis=1)
        arm = Robot(description.replace(tool=tool))
        config[here] = np.stack(conventions.status_turn_of(arm, q[here]), axis=1)
    return PlanFor(cand_p[order], config, cand_t[order], cand_g[order], keys, counts,
                   (float(start), float(np.linalg.slogdet(info)[1])))


def coverage(targets: ProgramTargets, description, data_joints: np.ndarray, data_tools: np.ndarray | None) -> list[Diagnostic]:
    """The targets the existing data does not cover (P337, warning, one per target: ``listed``
    gives a file's first few and a count): an arm configuration or a tool the data has no rows of, or a
    joint outside the data's arcs in that configuration (widened as P301 widens a model's)."""
    from ..model.envelope import joint_arcs, widened_arcs
    from ..robot.arm import Robot

    robot = Robot(description)
    tools = np.tile(description.tool, (len(data_joints), 1)) if data_tools is None else data_tools
    tools = np.round(np.asarray(tools, float), TOOL_DECIMALS)
    g_data, k_data = _groups(robot, data_joints, tools)
    g_prog, k_prog = _groups(robot, targets.joints, targets.tools)
    found = []
    for g, key in enumerate(k_prog):
        rows = np.flatnonzero(g_prog == g)
        status, tool = int(key[0]), key[1:]
        same_tool = (np.abs(k_data[:, 1:] - tool).max(axis=1) < 10 ** -TOOL_DECIMALS) if len(k_data) else []
        match = np.flatnonzero(same_tool & (k_data[:, 0] == status)) if len(k_data) else []
        if not np.any(same_tool):
            why = [f"the data has no rows with the tool {tool.tolist()}"] * len(rows)
        elif not len(match):
            why = [f"the data has no rows in this arm configuration (S {status} with this tool)"] * len(rows)
        else:
            arcs = widened_arcs(joint_arcs(data_joints[np.isin(g_data, match)]))
            q = targets.joints[rows]
            off = np.mod(q - arcs[:, 0] + 360.0, 360.0) > (arcs[:, 1] - arcs[:, 0])  # outside each arc
            bad = off.any(axis=1)
            rows = rows[bad]
            why = [f"A{int(np.argmax(o)) + 1} {q_row[int(np.argmax(o))]:.1f}° is outside the data's "
                   f"{arcs[int(np.argmax(o)), 0]:.1f}…{arcs[int(np.argmax(o)), 1]:.1f}° in this configuration"
                   for o, q_row in zip(off[bad], q[bad])]
        found += [Diagnostic(*targets.where[r], P337, f"not covered by the measurement data: {w}", "warning")
                  for r, w in zip(rows, why)]
    return found


def listed(found: list[Diagnostic]) -> list[Diagnostic]:
    """Per file the first ``findings.MAX_LISTED`` in program order, then one that counts the rest."""
    from ..programs.locate import MAX_LISTED

    out = []
    for path in dict.fromkeys(d.path for d in found):
        mine = sorted((d for d in found if d.path == path), key=lambda d: (d.line, d.col))
        out += mine[:MAX_LISTED]
        if len(mine) > MAX_LISTED:
            rest = len(mine) - MAX_LISTED - 1
            d = mine[MAX_LISTED]
            more = f" (and {rest} more target{'s' * (rest != 1)} of this file)" if rest else ""
            out.append(Diagnostic(d.path, d.line, d.col, d.code, d.message + more, d.severity))
    return out


def read_data(path: str | Path, description) -> tuple[np.ndarray, np.ndarray | None]:
    """An existing measurement CSV's joint angles [M, 6] deg (its q1..q6, its s,t through the
    nominal IK, else the IK nearest HOME) and tools [M, 6] (None: the description's)."""
    from ..measurements.csv import read_measurements
    from ..model.training.data import measured_tools
    from ..robot import configuration
    from ..robot.arm import Robot

    data = read_measurements(path)
    tools = measured_tools(data)
    q, keep, _ = configuration.measurement_joints(description, data, tools)
    if q is None:
        q, ok = Robot(description).ik(data.poses, description.home_q)
        keep = ok
    return q[keep], None if tools is None else tools[keep]

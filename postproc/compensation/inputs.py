"""What the controller will use at each target besides its pose: the joint angles of its
arm configuration (S/T, the controller's rules for targets without them, or a pose list's
``q1..q6``) and its tool (the active ``$TOOL``). Only models with the contract inputs
``joints`` / ``tool`` need them (``Compensator.wants_joints`` / ``wants_tool``).

One stage between ``findings.select`` (which targets the model takes, in the robot base)
and the model: it narrows the selection by the targets whose configuration has no joint
angles on the nominal arm (P309, left as written) and attaches the inputs to it.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..core import frames
from ..core.diagnostics import P309, P311, P313, P314, P319, Diagnostic, PostprocError
from ..model.compensator import Compensator
from ..programs import Program
from ..programs.locate import where
from ..robot.conventions import _DIALECT_NAMES, DIALECT_CONTROLLERS, controller_of

__all__ = [
    "model_description", "controller_inputs", "family_mismatch", "configuration_mismatch", "unseparated_mount_mm",
    "JOINT_TOLERANCE_DEG", "MOUNT_ROTATION_DEG", "TOOL_WARNING_MM",
]

# A target's stated configuration (S/T) is the model's when the joint angles agree to this.
JOINT_TOLERANCE_DEG = 1.0
# P319: the tool mount's rotation (with the A6 mastering about its axis) assumed at most, where
# the model's data could not separate it (card ``tool.unseparated``), and the extra error at
# another TCP from it that is worth a warning
MOUNT_ROTATION_DEG = 0.1
TOOL_WARNING_MM = 0.1


def unseparated_mount_mm(model: Compensator, tools: np.ndarray) -> np.ndarray:
    """[n] mm: what the part of the tool mount's rotation the model's data could not separate
    (card ``tool.unseparated``, unit directions in the flange frame) may add at each TCP
    ``tools`` [n, 6], for a rotation of MOUNT_ROTATION_DEG: θ·max |u × (t − t₀)| over unit u
    in their span (t₀ the model's own TCP). Zero for models that do not say (no tool input)."""
    card = model.tool or {}
    apart = np.asarray(card.get("unseparated", []), float).reshape(-1, 3)
    if not len(apart) or card.get("frame") is None or not len(tools):
        return np.zeros(len(tools))
    tools = np.asarray(tools, float)
    if len(tools) > 1 and (tools == tools[0]).all():  # (one $TOOL for the whole program: one value)
        return np.repeat(unseparated_mount_mm(model, tools[:1]), len(tools))
    lever = tools[:, :3] - np.asarray(card["frame"], float)[:3]
    turned = np.cross(apart[None, :, :], lever[:, None, :])  # [n, k, 3]
    return np.radians(MOUNT_ROTATION_DEG) * np.linalg.norm(turned, ord=2, axis=(1, 2))  # largest singular value


def model_description(model: Compensator):
    """The robot description of the model's robot (the shipped ``models/*.toml`` whose
    [robot] name is the card's ``robot``), or None."""
    from ..robot.description import shipped_description

    return shipped_description(model.robot) if model.robot else None


def model_tool(model: Compensator, description) -> np.ndarray:
    """The TCP on the flange the model's poses are of where a program says none: the card's
    tool frame, else the description's."""
    card_tool = model.tool.get("frame") if model.tool else None
    return np.asarray(card_tool if card_tool is not None else description.tool, float)


def family_mismatch(program: Program, model: Compensator) -> str | None:
    """Why a model that takes joint angles does not fit the controller ``program`` is written
    for (its dialect: KRL a KUKA's, RAPID an ABB's, URScript a Universal Robots', LS a FANUC's),
    when the description of the model's robot names another (``[robot] configuration``, or a
    UR-type arm); None where they agree or either is not known (a pose list, a model without
    the ``joints`` input or without a description)."""
    if not model.wants_joints:
        return None
    description = model_description(model)
    own = controller_of(description)
    wanted = DIALECT_CONTROLLERS.get(program.dialect)
    if wanted is None or own is None or own == wanted:
        return None
    name = _DIALECT_NAMES[program.dialect]
    owner = f"{own}'" if own.endswith("s") else f"{own}'s"  # (Universal Robots', KUKA's)
    return (f"the program is {name}, written for {wanted} controllers, and the model was trained on {model.robot}, "
            f"an arm of {owner} (its description {Path(description.path).name}): compensate with a model of this "
            "program's robot")


def _reachable_instead(description, poses: np.ndarray, tools: np.ndarray) -> list[str]:
    """For P309's targets that no joint angles reach in the configuration they state: the way
    forward — the joint angles of the configuration nearest HOME that reaches the pose, and the
    numbers that state it in the controller's form (KUKA S/T, ABB confdata, FANUC CONFIG)."""
    from ..robot import conventions
    from ..robot.arm import Robot

    out = ["; no configuration reaches it on the nominal robot (out of reach or the joint limits)"] * len(poses)
    if not len(poses):
        return out
    _, first, which = np.unique(tools, axis=0, return_index=True, return_inverse=True)
    for k in range(len(first)):  # (one IK call per tool, one conversion of all its rows)
        idx = np.flatnonzero(which.reshape(-1) == k)
        arm = Robot(description.replace(tool=tools[first[k]]))
        q, ok = arm.ik(poses[idx])
        idx, q = idx[ok], q[ok]
        if not len(idx):
            continue
        if description.configuration == "abb":
            stated = [f"confdata [{','.join(str(int(v)) for v in c)}]" for c in conventions.abb_confdata(arm, q)]
        elif description.configuration == "fanuc":
            stated = [f"CONFIG '{c}'" for c in conventions.fanuc_configs(arm, q)]
        else:
            s, t = conventions.status_turn_of(arm, q)
            stated = [f"S {int(a)} T {int(b)}" for a, b in zip(s, t)]
        for row, angles, words in zip(idx.tolist(), q, stated):
            out[row] = (f"; another configuration reaches it: joint angles ({', '.join(f'{v:.1f}' for v in angles)}) "
                        f"deg, which {words} states")
    return out


def _tools(program: Program, model: Compensator, description, rows: np.ndarray) -> np.ndarray:
    """Each target's TCP on the flange [len(rows), 6]: the program's $TOOL where known, else
    the model's (its card), else the description's."""
    tools = np.tile(model_tool(model, description), (len(rows), 1))
    t = program.targets
    for f, here in frames.frame_groups(t.frame[rows]):
        if program.frames[f].tool is not None:
            tools[here] = program.frames[f].tool
    return tools


def configuration_mismatch(program: Program, model: Compensator, rows: np.ndarray, sel: np.ndarray,
                           collect) -> tuple[np.ndarray, list[Diagnostic]]:
    """For a model *without* the ``joints`` input: a mask of the targets whose stated S/T put
    the arm in other joint angles than those the model evaluates (its own IK's, output
    ``ik_joints``/``joints``; without that output the nominal IK nearest HOME, the branch the
    training plans take), to be left as written, and their P313 warnings. Without a robot
    description for the model's robot every target that states S/T is left (it cannot be
    checked). Targets that state no S/T keep the model's branch."""
    from ..robot.conventions import ignored_status_turn

    config = program.targets.config
    stated = (config[rows] >= 0).any(axis=1) if config is not None else np.zeros(len(rows), bool)
    stated &= ~ignored_status_turn(program, rows)  # (a KRL LIN's S/T: not read, the configuration is kept)
    if not stated.any():
        return np.zeros(len(rows), bool), []
    from ..robot import configuration
    from ..robot.arm import Robot

    description = model_description(model)
    if description is None:
        return stated, collect(program, rows[stated], P313, "the target states S/T and postproc has no robot "
                               f"description for the model's robot {model.robot or '(none named)'} to check that the "
                               "model evaluates that arm configuration: left as it is")
    at = np.flatnonzero(stated)
    poses, tools = sel[at], _tools(program, model, description, rows[at])
    status, turn = (np.asarray(config[rows[at], k], int) for k in (0, 1))
    wanted = np.full((len(at), 6), np.nan)
    mine = np.full((len(at), 6), np.nan)
    for tool in np.unique(tools, axis=0):
        here = (tools == tool).all(axis=1)
        robot = Robot(description.replace(tool=tool))
        wanted[here], _ = configuration.stated_joints(robot, poses[here], status[here], turn[here])
        if not model.has_joints:
            mine[here], _ = robot.ik(poses[here], robot.home_q)
    if model.has_joints:
        _, mine = model.predict(poses, with_joints=True)
    with np.errstate(invalid="ignore"):
        differ = ~(np.abs(wanted - mine) <= JOINT_TOLERANCE_DEG).all(axis=1)
    bad = np.zeros(len(rows), bool)
    bad[at[differ]] = True
    return bad, collect(program, rows[bad], P313, "the target's S/T put the arm in another configuration than "
                        "the one this model evaluates (a model without the 'joints' input knows one branch): "
                        "left as it is")


def first_joints(model: Compensator, robot, pose: np.ndarray, tool: np.ndarray | None = None) -> np.ndarray:
    """[1, 6] deg: the axis position compensate assumes before a program's first target (what
    the robot was doing before the program is not in it): the branch the model's own IK gives
    that target (its ``ik_joints`` output), else the nominal IK nearest HOME (NaN: none)."""
    start, _ = robot.ik(pose, robot.home_q)
    if model.has_joints and np.isfinite(start).all():  # the branch of the model's own IK
        _, own = model.predict(pose, joints=start, tool=tool, with_joints=True)
        start = own if own is not None and np.isfinite(own).all() else start
    return start


def _kept_notes(program: Program, robot, rows: np.ndarray, q: np.ndarray, ok: np.ndarray) -> list[Diagnostic]:
    """P314 (notes): KRL LIN/CIRC targets whose written S/T state another configuration than the
    one the robot keeps there (the branch, S bits 0–2, or a joint's sign, T, other than that of
    ``q``: the joint angles of the kept configuration), which they are compensated for."""
    from ..robot import conventions
    from ..robot.configuration import SIGN_TOLERANCE_DEG

    ignored = conventions.ignored_status_turn(program, rows) & ok
    if not ignored.any():
        return []
    at = np.flatnonzero(ignored)
    written = np.asarray(program.targets.config[rows[at]], int)
    kept_s, kept_t = conventions.status_turn_of(robot, q[at])
    near_zero = (np.abs(q[at]) < SIGN_TOLERANCE_DEG).astype(int) << np.arange(6)  # (either sign fits)
    near_zero = near_zero.sum(axis=1)
    other_s = (written[:, 0] >= 0) & (conventions.arm_status(written[:, 0]) != kept_s)
    other_t = (written[:, 1] >= 0) & (((written[:, 1] ^ kept_t) & 0b111111 & ~near_zero) != 0)
    differ = other_s | other_t
    if not differ.any():
        return []
    shown = at[differ]
    kept = [(int(kept_s[i]), int(kept_t[i])) for i in np.flatnonzero(differ)]
    written_st = [tuple(int(v) for v in written[i]) for i in np.flatnonzero(differ)]

    def text(i):
        (s, t), (ws, wt) = kept[i], written_st[i]
        said = ", ".join(x for x in (f"S {ws}" if ws >= 0 else "", f"T {wt}" if wt >= 0 else "") if x)
        return (f"a LIN or CIRC keeps the arm configuration the robot is in (the controller reads S/T on PTP only): "
                f"it runs this target in S {s}, T {t}, not the {said} written here, and it is compensated for the one "
                f"it runs (the S/T stay as written)")

    return [Diagnostic(*where(program, int(rows[r])), P314, text(k), "note") for k, r in enumerate(shown)]


def controller_inputs(program: Program, model: Compensator, rows: np.ndarray, sel: np.ndarray,
                      collect, chain=None, order=None) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None, list[Diagnostic]]:
    """The model's ``joints`` / ``tool`` inputs for targets ``rows`` at base poses ``sel``:
    (rows kept, their poses, joint angles [n, 6] deg or None, TCPs [n, 6] or None, warnings).
    Targets whose configuration has no joint angles on the nominal arm, or is stated in a form
    the model's description cannot say (``configuration.stated_configuration``), are left as
    written (P309). The tool is the program's $TOOL where known, else the model's (its card); where
    its lever arm is so far from the measured TCPs' that the mount rotation the model could not
    separate may add TOOL_WARNING_MM or more, a P319 warning says how much (the target is
    compensated). ``collect`` makes the located warnings (findings.collect). ``chain`` (a
    ``compensator.Chain``, streaming compensate): the rules continue from the part before's last
    target (its ``origin``: the program's start position) and leave this part's last in it."""
    from ..robot import configuration
    from ..robot.arm import Robot

    description = model_description(model)
    if description is None:
        raise PostprocError(f"the model takes joint angles and postproc has no robot description for its robot "
                            f"{model.robot or '(none named)'}", str(model.path), 0, 0, P311)
    default_tool = model_tool(model, description)
    tools = _tools(program, model, description, rows)
    t = program.targets
    warnings: list[Diagnostic] = []
    q = None
    stated = None
    if model.wants_joints:
        stated, unmapped, why = configuration.stated_configuration(program, description, rows)
        if unmapped.any():
            warnings += collect(program, rows[unmapped], P309, lambda i: why[i] + ": left as it is")
            keep = ~unmapped
            rows, sel, tools, stated = rows[keep], sel[keep], tools[keep], stated.take(keep)
            order = None  # (rows dropped: the order of the rest is made again by findings)
    if model.wants_joints and len(rows):
        robot = Robot(description.replace(tool=default_tool))
        first = robot if np.array_equal(tools[0], default_tool) else Robot(description.replace(tool=tools[0]))
        if chain is not None and chain.joints is not None:
            start = chain.origin
        else:
            start = first_joints(model, first, sel[:1], tools[:1] if model.wants_tool else None)
            if chain is not None:
                chain.origin = start
        q, ok = configuration.target_joints(robot, t, rows, sel, tools,
                                            start[0] if np.isfinite(start).all() else None, chain, stated, order)
        warnings += _kept_notes(program, robot, rows, q, ok)
        changes = configuration.linear_changes(robot, t, rows, stated, q, order) & ok
        if changes.any():
            warnings += collect(program, rows[changes], P309, "a linear motion cannot change the arm configuration, and "
                                "the one this target states is not the one its motion keeps: the controller stops "
                                "(ConfL\\On, FANUC) or keeps its own (ConfL\\Off), which the program does not say: left as it is")
            keep = ~changes
            rows, sel, q, tools, ok = rows[keep], sel[keep], q[keep], tools[keep], ok[keep]
        if not ok.all():
            instead = _reachable_instead(description, sel[~ok], tools[~ok])
            warnings += collect(program, rows[~ok], P309, lambda i: "no joint angles for this target in its arm "
                                "configuration (S/T, or the one its motion keeps) on the nominal robot: left as it is"
                                + instead[i])
            rows, sel, q, tools = rows[ok], sel[ok], q[ok], tools[ok]
    if model.wants_tool:
        extra = unseparated_mount_mm(model, tools)
        far = np.flatnonzero(extra >= TOOL_WARNING_MM)
        if len(far):  # (said once per tool, at its first target: the same words for each would repeat)
            _, first, which = np.unique(tools[far], axis=0, return_index=True, return_inverse=True)
            for k in np.argsort(first).tolist():
                mine = far[which.reshape(-1) == k]
                n = len(mine)
                warnings += collect(program, rows[far[first[k]]:far[first[k]] + 1], P319, (
                    f"the $TOOL {[round(float(v), 3) for v in tools[far[first[k]]]]} has another lever arm than the "
                    f"tools the model was measured with ({len(model.tool.get('measured', []))}): the tool mount's "
                    f"rotation they could not separate may add up to {extra[mine].max():.2f} mm "
                    f"{'here' if n == 1 else f'at the {n} targets with this tool (from here on)'} "
                    f"(at {MOUNT_ROTATION_DEG}°); measure with this tool, or with two or three tools"))
    return rows, sel, q, (tools if model.wants_tool else None), warnings

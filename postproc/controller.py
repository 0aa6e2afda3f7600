"""What the controller will use at each target besides its pose: the joint angles of its
arm configuration (S/T, the controller's rules for targets without them, or a pose list's
``q1..q6``) and its tool (the active ``$TOOL``). Only models with the contract inputs
``joints`` / ``tool`` need them (``Compensator.wants_joints`` / ``wants_tool``).

One stage between ``findings.select`` (which targets the model takes, in the robot base)
and the model: it narrows the selection by the targets whose configuration has no joint
angles on the nominal arm (P309, left as written) and attaches the inputs to it.
"""
from __future__ import annotations

import numpy as np

from .compensator import Compensator
from .diagnostics import Diagnostic, PostprocError
from .programs import Program

__all__ = ["model_description", "controller_inputs"]


def model_description(model: Compensator):
    """The robot description of the model's robot (the shipped ``models/*.toml`` whose
    [robot] name is the card's ``robot``), or None."""
    from .resources import model_path
    from .robot import load_description

    folder = model_path("kr500.toml").parent
    for path in sorted(folder.glob("*.toml")):
        description = load_description(path)
        if model.robot and description.name.casefold() == model.robot.casefold():
            return description
    return None


def controller_inputs(program: Program, model: Compensator, rows: np.ndarray, sel: np.ndarray,
                      collect) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None, list[Diagnostic]]:
    """The model's ``joints`` / ``tool`` inputs for targets ``rows`` at base poses ``sel``:
    (rows kept, their poses, joint angles [n, 6] deg or None, TCPs [n, 6] or None, warnings).
    Targets whose configuration has no joint angles on the nominal arm (P309) are left as
    written. The tool is the program's $TOOL where known, else the model's (its card).
    ``collect`` makes the located warnings (findings.collect)."""
    from . import configuration
    from .robot import Robot

    description = model_description(model)
    if description is None:
        raise PostprocError(f"the model takes joint angles and postproc has no robot description for its robot "
                            f"{model.robot or '(none named)'}", str(model.path), 0, 0, "P311")
    card_tool = model.tool.get("frame") if model.tool else None
    default_tool = np.asarray(card_tool if card_tool is not None else description.tool, float)
    tools = np.tile(default_tool, (len(rows), 1))
    t = program.targets
    for f in np.unique(t.frame[rows]):
        if program.frames[f].tool is not None:
            tools[t.frame[rows] == f] = program.frames[f].tool
    warnings: list[Diagnostic] = []
    q = None
    if model.wants_joints and len(rows):
        robot = Robot(description.replace(tool=default_tool))
        first = robot if np.array_equal(tools[0], default_tool) else Robot(description.replace(tool=tools[0]))
        start, _ = first.ik(sel[:1], robot.home_q)
        if model.has_joints and np.isfinite(start).all():  # the branch of the model's own IK
            _, own = model.predict(sel[:1], joints=start, tool=tools[:1] if model.wants_tool else None, with_joints=True)
            start = own if own is not None and np.isfinite(own).all() else start
        q, ok = configuration.target_joints(robot, t, rows, sel, tools,
                                            start[0] if np.isfinite(start).all() else None)
        if not ok.all():
            warnings += collect(program, rows[~ok], "P309", "no joint angles for this target in its arm configuration "
                                "(S/T, or the one its motion keeps) on the nominal robot: left as it is")
            rows, sel, q, tools = rows[ok], sel[ok], q[ok], tools[ok]
    return rows, sel, q, (tools if model.wants_tool else None), warnings

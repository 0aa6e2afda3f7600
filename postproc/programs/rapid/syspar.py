"""An ABB controller's system parameters (a backup's ``SYSPAR/*.cfg``): what the RAPID reader needs
of them.

The text form (RobotWare 5/6/7, *Technical reference manual – System parameters*, 3HAC050948,
"The configuration files"): a first line ``DOMAIN:CFG_1.0:v:r::``; then types, each a line
``TYPE:`` after a ``#`` line, and their instances, each ``-attribute value`` pairs (a value
quoted, a number or a word; an attribute without a value is a flag) over lines continued by a
trailing ``\\``, instances apart by a blank line. Names are compared case-blind (SYS.cfg writes
``-Name``, MOC.cfg ``-name``).

What is taken (:func:`robot_of`): which robot the motion task ``task`` moves (SYS.cfg
``CAB_TASKS -Name task -UseMechanicalUnitGroup g``, MOC.cfg ``MECHANICAL_UNIT_GROUP -name g
-robot r``; a controller of one robot: that one), its base frame (MOC.cfg ``ROBOT
-base_frame_pos_x/y/z`` in metres, ``-base_frame_orient_u0…u3`` a quaternion w, x, y, z; absent
attributes 0, u0 1: the world itself) and the mechanical unit that moves that base
(``-base_frame_coordinated``: a track), and the mechanical units declared (``MECHANICAL_UNIT``)."""
from __future__ import annotations

import os
import re
from dataclasses import dataclass, field

import numpy as np

from ...core import frames as fr

__all__ = ["Instance", "parse", "Robot", "robot_of"]

_PAIR = re.compile(r'-(\w+)(?:[ \t]+("[^"\n]*"|[^\s"-][^\s]*|-[\d.][^\s]*))?')
_TYPE = re.compile(r"^([A-Za-z_][\w]*):[ \t]*$")


@dataclass
class Instance:
    """One instance of a type: its attributes (lower case name → value: a str, "" for a flag), the
    file and the line it starts at, each attribute's line."""

    type: str
    attrs: dict
    path: str
    line: int
    lines: dict = field(default_factory=dict)

    def get(self, name: str, default=None):
        return self.attrs.get(name.lower(), default)

    @property
    def name(self) -> str:
        return self.attrs.get("name", "")


def parse(path: str, text: str) -> dict:
    """The instances of a .cfg text by type (upper case) → [Instance] in the order written."""
    out: dict = {}
    kind = None
    current = None
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.rstrip()
        if not line.strip():
            current = None
            continue
        if line.startswith("#"):
            kind, current = None, None
            continue
        m = _TYPE.match(line)
        if m and not line[0].isspace():
            kind, current = m.group(1).upper(), None
            out.setdefault(kind, [])
            continue
        if kind is None:
            continue  # (the domain's first line)
        body = line[:-1] if line.endswith("\\") else line
        if current is None:
            current = Instance(kind, {}, path, number)
            out[kind].append(current)
        for pm in _PAIR.finditer(body):
            name, value = pm.group(1).lower(), pm.group(2)
            if value is None:
                value = ""
            elif value.startswith('"'):
                value = value[1:-1]
            current.attrs.setdefault(name, value)
            current.lines.setdefault(name, number)
    return out


@dataclass
class Robot:
    """What the system parameters say of the robot a task moves: ``name`` (MOC.cfg ROBOT), its
    base in the world (``base``: 4×4 world ← robot base, mm; None: not stated, the world
    itself) where (``base_at``: (path, line)), the unit that moves the base (``moved_by``: its
    name, ``moved_at``: (path, line)), the mechanical units declared (name upper → (path, line));
    ``unknown``: why the robot is not known (several robots, no task named), else ""."""

    name: str = ""
    base: np.ndarray | None = None
    base_at: tuple = ()
    moved_by: str = ""
    moved_at: tuple = ()
    units: dict = field(default_factory=dict)
    unknown: str = ""


def _of(syspar: dict, wanted: str) -> dict:
    out: dict = {}
    for path, text in syspar.items():
        if os.path.basename(path.replace("\\", "/")).lower() == wanted:
            for kind, items in parse(path, text).items():
                out.setdefault(kind, []).extend(items)
    return out


def _num(inst: Instance, name: str, default: float) -> float:
    v = inst.get(name)
    try:
        return float(v) if v not in (None, "") else default
    except ValueError:
        return default


def _matters(inst: Instance) -> bool:
    return any(k.startswith("base_frame") for k in inst.attrs)


def robot_of(syspar: dict | None, task: str | None = None) -> Robot | None:
    """The robot of ``task`` (a motion task's name, ``T_ROB1``; None: the one motion task or the
    one robot) as ``syspar`` (path → text of the backup's .cfg files) states it; None where
    no MOC.cfg is given."""
    if not syspar:
        return None
    moc = _of(syspar, "moc.cfg")
    if not moc:
        return None
    sys_ = _of(syspar, "sys.cfg")
    robots = {i.name.upper(): i for i in moc.get("ROBOT", [])}
    units = {i.name.upper(): (i.path, i.line) for i in moc.get("MECHANICAL_UNIT", [])}
    groups = {i.name.upper(): i for i in moc.get("MECHANICAL_UNIT_GROUP", [])}
    tasks = [i for i in sys_.get("CAB_TASKS", []) if "motiontask" in i.attrs]
    chosen = None
    if task is not None:
        entry = next((i for i in sys_.get("CAB_TASKS", []) if i.name.upper() == task.upper()), None)
        group = entry.get("usemechanicalunitgroup") if entry is not None else None
        if group and group.upper() in groups:
            chosen = groups[group.upper()].get("robot", "").upper() or None
            if chosen is None:
                return Robot(units=units)  # (a task of a group without a robot: no robot's targets)
    elif len(tasks) == 1 and tasks[0].get("usemechanicalunitgroup", "").upper() in groups:
        chosen = groups[tasks[0].get("usemechanicalunitgroup").upper()].get("robot", "").upper() or None
    if chosen is None:
        if len(robots) == 1:
            chosen = next(iter(robots))
        elif not robots:
            return Robot(units=units)
        elif not any(_matters(i) for i in robots.values()):
            return Robot(units=units)  # (none states a base frame or a unit moving it: nothing to take)
        else:
            why = (f"the system parameters declare {len(robots)} robots ({', '.join(i.name for i in robots.values())})"
                   f" and {'task ' + task + ' names none of them' if task else 'no task is named'}: which one runs "
                   "these modules is not known")
            return Robot(units=units, unknown=why)
    inst = robots.get(chosen)
    if inst is None:
        return Robot(name=chosen, units=units, unknown=f"robot {chosen} is not in MOC.cfg")
    out = Robot(name=inst.name, units=units)
    pos = [_num(inst, f"base_frame_pos_{k}", 0.0) * 1000.0 for k in "xyz"]
    q = [_num(inst, f"base_frame_orient_u{k}", 1.0 if k == 0 else 0.0) for k in range(4)]
    stated = [k for k in [f"base_frame_pos_{c}" for c in "xyz"] + [f"base_frame_orient_u{k}" for k in range(4)]
              if k in inst.attrs]
    if stated:
        m = np.eye(4)
        q = np.asarray(q, float)
        m[:3, :3] = fr.orientation_rotation(q / (np.linalg.norm(q) or 1.0), "quaternion")
        m[:3, 3] = pos
        out.base = m
        out.base_at = (inst.path, inst.lines[stated[0]])
    moved = inst.get("base_frame_coordinated")
    if moved:
        out.moved_by = moved
        out.moved_at = (inst.path, inst.lines["base_frame_coordinated"])
    return out

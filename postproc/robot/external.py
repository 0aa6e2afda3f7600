"""External units: a linear track that carries the robot, a turntable or positioner that carries
the workpiece — one axis each, their nominal kinematics (docs/EXTERNAL.md).

An :class:`ExternalUnit` is one axis: ``type`` "prismatic" (mm) or "rotary" (deg), driven by
the external axis value ``axis`` of each target (``E1``…``E6``: KUKA's E1…E6, RAPID's
``eax_a``…``eax_f``, FANUC's extended axes of group 1; ``GP2.J1``…: FANUC's group-2 axes),
moving along / turning about ``direction`` (a vector in its mount frame). Where it is:

    base_at(e) = mount · joint(e) · flange

``mount`` the unit's root in the world (X,Y,Z,A,B,C mm/deg), ``joint(e)`` the translation e·d
or the rotation by e about d, ``flange`` from the moving carriage/table to what it carries.
``carries`` says what that is:

* ``"robot"`` (a track): the robot's own base — world ← robot base = base_at(e);
* ``"workpiece"`` (a turntable, a positioner): a frame the program's coordinates are in —
  world ← that frame's root = base_at(e), the program's base frame on top of it.

The analysis (``programs.analysis.values.Moving``) keeps a frame that moves with a unit as
``left · base_at(e)^(±1) · right`` until a target says e; a target that does not say it is left
as written (P225). Where a unit comes from: a TOML the user gives (``--external FILE``, the
settings' ``external``; ``[[external]]`` tables, :func:`read_external`), a robot description's
``[[external]]`` (the simulator's track), KUKA machine data (``programs.krl.machine``).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from ..core.diagnostics import P227, PostprocError
from ..core.frames import axis_rotations, frame_to_matrix
from ..core.toml import check_value, key_line, read_toml

__all__ = ["ExternalUnit", "read_external", "parse_external", "units_of", "AXES", "TYPES", "CARRIES"]

TYPES = ("prismatic", "rotary")
CARRIES = ("robot", "workpiece")
_AXIS = re.compile(r"^(?:E[1-6]|GP[2-9]\.J[1-9])$")
AXES = "E1…E6 (KUKA E1…E6, RAPID eax_a…eax_f, FANUC group 1's extended axes) or GP2.J1… (FANUC group 2)"
_KEYS = {"name": "str", "type": "str", "axis": "str", "carries": "str", "direction": "vec:3", "mount": "vec:6",
         "flange": "vec:6", "machine_def": "int", "mech_unit": "str"}


@dataclass(frozen=True)
class ExternalUnit:
    """One external axis and what it carries (see the module). ``machine_def``: the KUKA
    ``MACHINE_DEF[n]`` a base on it names (``MACHINE_FRAME_DAT[k].MACH_DEF_INDEX``);
    ``mech_unit``: the RAPID mechanical unit a work object names (``ufmec``); ``source``: where
    it was read (messages)."""

    name: str
    type: str
    axis: str
    carries: str
    direction: tuple = (0.0, 0.0, 1.0)
    mount: tuple = (0.0,) * 6
    flange: tuple = (0.0,) * 6
    machine_def: int | None = None
    mech_unit: str = ""
    source: str = field(default="", compare=False)

    @cached_property
    def _ends(self) -> tuple:
        """(mount, flange) as 4×4, the unit direction."""
        d = np.asarray(self.direction, float)
        return (frame_to_matrix(np.asarray(self.mount, float)), frame_to_matrix(np.asarray(self.flange, float)),
                d / np.linalg.norm(d))

    def joint(self, e) -> np.ndarray:
        """[..., 4, 4] the joint's motion at values ``e`` (mm or deg)."""
        e = np.asarray(e, float)
        d = self._ends[2]
        t = np.broadcast_to(np.eye(4), e.shape + (4, 4)).copy()
        if self.type == "prismatic":
            t[..., :3, 3] = e[..., None] * d
            return t
        t[..., :3, :3] = axis_rotations(d[None], np.radians(e)[..., None])[..., 0, :, :]
        return t

    def base_at(self, e) -> np.ndarray:
        """[..., 4, 4] world ← what the unit carries, at axis values ``e``."""
        mount, flange, _ = self._ends
        return mount @ self.joint(e) @ flange

    def describe(self) -> str:
        return f"{self.type} unit {self.name} (axis {self.axis}, carries the {self.carries}{self._from()})"

    def _from(self) -> str:
        return f"; {self.source}" if self.source else ""


def parse_external(tables, path: str = "--external", text: str = "") -> tuple:
    """``[[external]]`` tables (a dict or a list of dicts, as TOML gives them) → ExternalUnits;
    PostprocError (P227) at the table's key for anything malformed (located in ``text``, the
    file's TOML, where given)."""
    if isinstance(tables, dict):
        tables = [tables]
    if not isinstance(tables, list):
        raise PostprocError("[external] must be a table or an array of tables ([[external]])", path, 0, 0, P227)
    units = []
    for i, t in enumerate(tables):
        def fail(message, key=None, i=i):
            line = key_line(text, "external", key, i)
            return PostprocError(f"[[external]] {i + 1}: {message}", path, line, 1 if line else 0, P227)

        if not isinstance(t, dict):
            raise fail("must be a table")
        values = {}
        for key, value in t.items():
            if key not in _KEYS:
                raise fail(f"unknown key '{key}' (known: {', '.join(_KEYS)})", key)
            checked = check_value(_KEYS[key], value, key, lambda m, key=key: fail(m, key))
            values[key] = tuple(checked.tolist()) if isinstance(checked, np.ndarray) else checked
        for key in ("type", "axis", "carries"):
            if key not in values:
                raise fail(f"needs '{key}' ({' or '.join(TYPES) if key == 'type' else AXES if key == 'axis' else ' or '.join(CARRIES)})")
        if values["type"] not in TYPES:
            raise fail(f"type must be {' or '.join(TYPES)}, not {values['type']!r}", "type")
        if values["carries"] not in CARRIES:
            raise fail(f"carries must be {' or '.join(CARRIES)}, not {values['carries']!r}", "carries")
        axis = values["axis"].upper()
        if not _AXIS.match(axis):
            raise fail(f"axis must be {AXES}, not {values['axis']!r}", "axis")
        values["axis"] = axis
        d = values.get("direction", (0.0, 0.0, 1.0))
        if np.linalg.norm(d) < 1e-9:
            raise fail("direction must not be zero", "direction")
        values.setdefault("name", f"{values['type']} {axis}")
        line = key_line(text, "external", None, i)
        units.append(ExternalUnit(**values, source=f"{path}:{line}" if line else path))
    axes = [u.axis for u in units]
    dup = next((a for a in axes if axes.count(a) > 1), None)
    if dup is not None:
        raise PostprocError(f"two external units on axis {dup}: one unit per axis", path, 0, 0, P227)
    if sum(u.carries == "robot" for u in units) > 1:
        raise PostprocError("two external units carry the robot: postproc takes one track (one axis)", path, 0, 0,
                            P227)
    return tuple(units)


def read_external(path: str | Path) -> tuple:
    """The ``[[external]]`` units of a TOML file (``--external``; a frames file or settings
    file may hold them too); PostprocError P227 where the file cannot be read or is malformed."""
    path = Path(path)
    text, doc = read_toml(path, P227)
    if "external" not in doc:
        raise PostprocError("no [[external]] table: nothing says the external unit's kinematics", str(path), 0, 0,
                            P227)
    return parse_external(doc["external"], str(path), text)


def units_of(description) -> tuple:
    """The external units of a robot description (its ``[[external]]`` tables; the simulator's
    track or turntable)."""
    raw = getattr(description, "external", ())
    if not raw:
        return ()
    return parse_external(list(raw), description.path or "<robot>", description.text or "")

"""The identified parameters of a model card, named and in their units (torch-free)."""
from __future__ import annotations

import math

_XYZ = ("x", "y", "z")


_R = ("rx", "ry", "rz")


_AXES = tuple(f"A{j}" for j in range(1, 7))


# each group of the card's identified.parameters (training.kinematic.Layout's order): names, unit
PARAMETER_NAMES = {
    "placement": ([f"A{j}.{n}" for j in range(1, 7) for n in _R + _XYZ], ["deg"] * 3 + ["mm"] * 3),
    "base": (list(_R + _XYZ), ["deg"] * 3 + ["mm"] * 3),
    "tool": (list(_XYZ), ["mm"]),
    "mount": (list(_R), ["deg"]),
    "tool_rotation": (list(_R), ["deg"]),
    "zero": (list(_AXES), ["deg"]),
    "compliance": (list(_AXES), ["deg/kNm"]),
    "coupling": (None, ["deg/kNm"]),
    "backlash": (list(_AXES), ["deg"]),
}


UNIT_SCALE = {"deg": math.degrees(1.0), "mm": 1.0, "deg/kNm": math.degrees(1.0) * 1e3}  # from rad, mm, rad/Nm

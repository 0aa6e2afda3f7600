"""The controllers' conventions: motion kinds, controller families and the dialects written for them."""
from __future__ import annotations

from ..core.diagnostics import PostprocError

__all__ = ['DIALECT_CONTROLLERS', 'MOTIONS']


# the controller a program's dialect is written for (a pose list: any robot's), and the one a
# description's [robot] configuration names (a UR-type arm: Universal Robots')
DIALECT_CONTROLLERS = {"krl": "KUKA", "rapid": "ABB", "urscript": "Universal Robots", "fanuc": "FANUC"}


_FORM_CONTROLLERS = {"kuka": "KUKA", "abb": "ABB", "fanuc": "FANUC"}


_DIALECT_NAMES = {"krl": "KRL", "rapid": "RAPID", "urscript": "URScript", "fanuc": "an LS program"}


def controller_of(description) -> str | None:
    """The controller family a robot description names (``[robot] configuration``, or a UR-type
    arm: Universal Robots'); None where it does not say."""
    if description is None:
        return None
    own = _FORM_CONTROLLERS.get(description.configuration)
    if own is None:
        from .arm import Robot

        try:
            own = "Universal Robots" if Robot(description).family == "ur" else None
        except PostprocError:  # (an arm postproc has no closed-form IK for: unknown)
            own = None
    return own


# Motion kinds, stored per target as an index into this tuple.
MOTIONS = ("LIN", "PTP", "CIRC-aux", "CIRC-end", "SLIN", "SPTP", "SCIRC-aux", "SCIRC-end", "SPL", "row")

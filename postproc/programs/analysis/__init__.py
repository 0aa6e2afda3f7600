"""One dataflow analysis of the motion IR for every dialect: what the controller executes.

``analyse(unit, dialect)`` runs the abstract interpretation (``execute.py``, values in
``values.py``, the dialect's meaning of its constructs in a ``dialect.Dialect``) and turns the
motions it recorded into the program's targets (``targets.py``)."""
from __future__ import annotations

from .dialect import Dialect, PoseView
from .execute import Analysis, Recorder
from .targets import Built, build

__all__ = ["analyse", "Analysis", "Recorder", "Dialect", "PoseView", "Built"]


def analyse(unit, dialect) -> Built:
    """The targets of ``unit`` (a lowered program) as the controller executes it."""
    rec = Analysis(unit, dialect).run()
    return build(unit, dialect, rec)

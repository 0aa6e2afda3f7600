"""postproc: compensate industrial-robot positioning error in robot programs.

The public API for CAM post-processor hooks. It imports neither torch nor
Pinocchio: compensating needs only lark, numpy and onnxruntime.
"""
from __future__ import annotations

from .core.version import __version__

__all__ = ["compensate_text", "compensate_file", "load_model", "Settings", "load_settings", "PostprocError",
           "ActiveFrames", "__version__"]


def __getattr__(name: str):
    # Lazy so that `import postproc` stays cheap for CLI start-up and CAM hooks.
    if name == "compensate_text":
        from .compensation.api import compensate_text

        return compensate_text
    if name == "compensate_file":  # (in memory, or a chunk at a time for a long CAM program)
        from .compensation.streaming import compensate_file

        return compensate_file
    if name == "load_model":
        from .model.compensator import load_model

        return load_model
    if name == "ActiveFrames":  # compensate_text(..., active=ActiveFrames.of(base=0, tool="model", robroot="0,0,400,0,0,0"))
        from .programs.model import ActiveFrames

        return ActiveFrames
    if name in ("Settings", "load_settings"):  # compensate_text(..., settings=load_settings()) or its options as keywords
        from . import settings

        return getattr(settings, name)
    if name == "PostprocError":
        from .core.diagnostics import PostprocError

        return PostprocError
    raise AttributeError(name)

"""Settings: the one frozen, validated :class:`Settings` object a run is made with.

Options in a file (``[tool.postproc]`` in pyproject.toml or a ``postproc.toml``: ``file.py``) →
overrides (CLI flags: ``postproc.cli.settings``; API keywords: ``Settings.override``) → one
``Settings`` with a section per use case — ``reading`` (config files, dialect, the frames a
program runs in), ``rules`` (what compensate and check apply), ``check``, ``training``,
``acceptance`` — plus the ``model`` and the ``robot``. Each option is declared once
(``sections.OPTIONS``: name, section, CLI flag, file key, check); every use case takes the
object whole. Things that are not settings (a reachability test, streaming state) are
arguments of the use cases, not fields.

Modules: ``sections`` (the sections, the options and their checks), ``file`` (finding and
reading the settings file).
"""
from .file import SETTINGS_NAME, find_settings, load_settings, read_settings
from .sections import (
    DEFAULT_MAX_CORRECTION_MM, LIMITS, MAX_ITERATIONS, OPTIONS, Acceptance, Check, FreshPair, Reading, Rules,
    Settings, Training,
)

__all__ = [
    "Settings", "Reading", "Rules", "Check", "Training", "Acceptance", "FreshPair", "OPTIONS",
    "DEFAULT_MAX_CORRECTION_MM", "MAX_ITERATIONS", "LIMITS", "SETTINGS_NAME", "find_settings", "load_settings", "read_settings",
]

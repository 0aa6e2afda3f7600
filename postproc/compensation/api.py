"""The public API for CAM hooks: ``compensate_text`` (``postproc.compensate_text``).

The API is where settings are made for a library caller: a ``Settings`` given whole, and/or
its options as keywords (``strict=True``, ``active=ActiveFrames(...)``, ``config=...``: the
names of ``postproc.settings.OPTIONS``), checked and applied at once; the use case gets the
result whole."""
from __future__ import annotations

from pathlib import Path

from ..model.compensator import Compensator, load_model
from ..programs.io import STDIN, config_texts, backup_active, parse_program_text
from ..settings import Settings
from .pipeline import Report, compensate_program

__all__ = ["compensate_text", "settings_of", "model_of"]


def model_of(model: Compensator | str | Path | None) -> Compensator:
    """A loaded model as it is; a path or a shipped model's name loaded; None: the default."""
    return model if isinstance(model, Compensator) else load_model(model)


def settings_of(settings: Settings | None, options: dict) -> Settings:
    """``settings`` (default: the defaults, no file read) with the caller's ``options`` applied."""
    return (settings if settings is not None else Settings()).override(**options)


def compensate_text(
    text: str,
    model: Compensator | str | Path | None = None,
    *,
    name: str = STDIN,
    dat_text: str | None = None,
    settings: Settings | None = None,
    **options,
) -> tuple[str, Report]:
    """Compensate a program given as text; returns the new text and the report.

    For a KRL module pass its .dat as ``dat_text``: the new .dat is
    ``report.outputs[<name>.dat]``. ``model`` is a loaded Compensator (reuse one for many
    calls), a path, or None for the shipped default model. ``settings``: a ``Settings`` (default
    the defaults); ``options``: settings by name over it, e.g. ``strict=True``, ``dialect="krl"``,
    ``config="$config.dat"``, ``active=ActiveFrames(base=0, tool="model")`` (the $BASE/$TOOL in
    force where a KRL program does not set them; else such targets are left as written,
    P220/P221), ``max_correction_mm=2.0``.
    """
    settings = settings_of(settings, options)
    reading = settings.reading
    program = parse_program_text(text, name, reading.dialect, dat_text, config_texts(reading.config_list),
                                 backup_active(reading.config_list, reading.active))
    report = compensate_program(program, model_of(model), settings)
    return report.outputs[program.files[0]], report

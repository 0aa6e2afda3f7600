"""The public API for CAM hooks: ``compensate_text``."""
from __future__ import annotations

from pathlib import Path

from ..model.compensator import Compensator, load_model
from ..programs import ActiveFrames
from ..programs.io import STDIN, _config_texts, backup_active, parse_program_text
from .findings import DEFAULT_MAX_CORRECTION_MM
from .pipeline import Report, compensate_program

__all__ = ['compensate_text']


def _model(model: Compensator | str | Path | None) -> Compensator:
    return model if isinstance(model, Compensator) else load_model(model)


def compensate_text(
    text: str,
    model: Compensator | str | Path | None = None,
    *,
    name: str = STDIN,
    dialect: str | None = None,
    dat_text: str | None = None,
    config: str | Path | list | None = None,
    active: ActiveFrames | None = None,
    iterations: int | None = None,
    strict: bool = False,
    force: bool = False,
    max_correction_mm: float = DEFAULT_MAX_CORRECTION_MM,
    max_std_mm: float | None = None,
    robot: str | None = None,
    fill_partial: bool = True,
    orientation: bool = False,
) -> tuple[str, Report]:
    """Compensate a program given as text; returns the new text and the report.

    For a KRL module pass its .dat as ``dat_text``: the new .dat is
    ``report.outputs[<name>.dat]``. ``model`` is a loaded Compensator (reuse one for many
    calls), a path, or None for the shipped default model. ``active``: the $BASE/$TOOL in
    force where a KRL program does not set them (``ActiveFrames``; else such targets are
    left as written, P220/P221).
    """
    program = parse_program_text(text, name, dialect, dat_text, _config_texts(config), backup_active(config, active))
    report = compensate_program(program, _model(model), iterations=iterations, strict=strict, force=force,
                                max_correction_mm=max_correction_mm, robot=robot, fill_partial=fill_partial,
                                orientation=orientation, max_std_mm=max_std_mm)
    return report.outputs[program.files[0]], report

"""Robot programs as text + the Cartesian targets found in them.

Each dialect module (``krl``, ``poses``) turns the texts of a program into a
:class:`Program`: the untouched texts of its files and, for every Cartesian target, where
its X/Y/Z numbers stand in those texts and in which frame it was programmed. Targets are
kept as columns (numpy arrays), not one object per target: CAM programs have 10^6 of them.
Nothing here knows about models: the compensator and the rewriter work on this.
"""
from __future__ import annotations

from pathlib import Path

from .model import MOTIONS, STAMP_PREFIX, ActiveFrames, Frame, Program, RobotRoot, Targets, TargetsBuilder
from ..diagnostics import P222

__all__ = ["ActiveFrames", "RobotRoot", "Frame", "Targets", "TargetsBuilder", "Program", "read_program", "dialect_of", "STAMP_PREFIX", "MOTIONS",
           "companion_dat", "lower"]

KRL_SUFFIXES = {".src", ".dat", ".sub"}
POSE_SUFFIXES = {".csv", ".txt", ".pose", ".poses", ".xyz"}
RAPID_SUFFIXES = {".mod", ".prg", ".sys", ".modx"}
URSCRIPT_SUFFIXES = {".script"}
FANUC_SUFFIXES = {".ls"}


def dialect_of(path: str | Path) -> str:
    """'krl' for .src/.dat/.sub, 'poses' for .csv/.txt/.pose(s)/.xyz, 'rapid' for
    .mod/.modx/.prg/.sys, 'urscript' for .script, 'fanuc' for .ls; ValueError otherwise."""
    suffix = Path(str(path)).suffix.lower()
    if suffix in KRL_SUFFIXES:
        return "krl"
    if suffix in POSE_SUFFIXES:
        return "poses"
    if suffix in RAPID_SUFFIXES:
        return "rapid"
    if suffix in URSCRIPT_SUFFIXES:
        return "urscript"
    if suffix in FANUC_SUFFIXES:
        return "fanuc"
    raise ValueError(f"unknown program type {suffix!r} (expected .src/.dat, .csv/.txt, .mod/.prg/.sys, .script or .ls)")


def companion_dat(src: Path) -> Path | None:
    """The .dat beside a .src (same stem, any case), if there is one."""
    if src.suffix.lower() != ".src" or not src.parent.is_dir():
        return None
    for candidate in (src.with_suffix(".dat"), src.with_suffix(".DAT")):
        if candidate.is_file():
            return candidate
    stem = src.stem.lower()
    for candidate in src.parent.iterdir():
        if candidate.suffix.lower() == ".dat" and candidate.stem.lower() == stem:
            return candidate
    return None


def read_program(files: list[str], texts: list[str], dialect: str, config: list[str] | None = None,
                 active: ActiveFrames | None = None) -> Program:
    """Parse a program made of ``files`` (for KRL: the .src first, then its .dat if any)
    with contents ``texts``. ``config`` optionally holds ``$config.dat`` text(s) that give
    BASE_DATA / TOOL_DATA (for RAPID: other modules' tooldata / wobjdata; for Fanuc LS: the frame
    file, TOML, of --frames). ``active``: the $BASE / $TOOL in force where a KRL program has not
    set them, and the TCP of a URScript program before its first set_tcp (``tool`` only; the
    other dialects name theirs at every target and refuse it, P222; its ``robroot``, KRL's
    $ROBROOT, they do not need: their targets are in the robot base). Raises
    PostprocError (with file:line:col) on bad input."""
    if dialect == "krl":
        from . import krl

        program = krl.read(files, texts, config=config, active=active)
        program.config = list(config) if config else None
        program.active = active
        program.from_text = True
        return program
    if dialect == "urscript":
        from . import urscript

        program = urscript.read(files, texts, active=active)
        program.active = active
        program.from_text = True
        return program
    external = active.external if active is not None else ()  # (a track, a positioner: every dialect)
    if active is not None and not active.frames_stated:
        active = None  # (only $ROBROOT: the other dialects' targets are in the robot base by definition)
    if active is not None:
        from ..diagnostics import PostprocError

        raise PostprocError(f"--base / --tool state the frames of KRL programs; a {dialect} program names its "
                            "own at every target", files[0] if files else "", 0, 0, P222)
    if dialect == "poses":
        from . import poses

        program = poses.read(files, texts)
        program.from_text = True
        return program
    if dialect == "rapid":
        from . import rapid

        program = rapid.read(files, texts, config=config, external=external)
        program.config = list(config) if config else None
        if external:  # (read again as it was read: guards.check_round_trip)
            program.active = ActiveFrames(external=external)
        program.from_text = True
        return program
    if dialect == "fanuc":
        from . import fanuc

        program = fanuc.read(files, texts, frames=config, external=external)
        program.config = list(config) if config else None
        if external:
            program.active = ActiveFrames(external=external)
        program.from_text = True
        return program
    raise ValueError(f"unknown dialect {dialect!r}")


def lower(files: list[str], texts: list[str], dialect: str, config: list[str] | None = None,
          active: ActiveFrames | None = None):
    """The motion IR of a program and its dialect's meaning: (``ir.Unit``, ``analysis.Dialect``)
    — what ``read_program`` analyses, and what ``interpreter.run`` executes."""
    if dialect == "krl":
        from .krl.reader import lower as krl_lower

        return krl_lower(files, texts, config=config, active=active)
    if dialect == "poses":
        from .poses import lower as poses_lower

        return poses_lower(files, texts)
    module = {"rapid": "rapid", "urscript": "urscript", "fanuc": "fanuc"}.get(dialect)
    if module is None:
        raise ValueError(f"unknown dialect {dialect!r}")
    import importlib

    reader = importlib.import_module(f".{module}", __name__)
    if not hasattr(reader, "lower"):
        raise NotImplementedError(f"the {dialect} reader does not lower to the motion IR yet")
    external = active.external if active is not None else ()
    if dialect == "urscript":  # (its --tool: the TCP before the script's first set_tcp)
        return reader.lower(files, texts, active=active)
    if active is not None and (active.frames_stated or active.robroot is not None):
        raise ValueError(f"active frames are KRL's ($BASE/$TOOL at the start): not {dialect}")
    if dialect == "fanuc":  # (its frame file)
        return reader.lower(files, texts, frames=config, external=external)
    if external:
        return reader.lower(files, texts, config=config, external=external)
    return reader.lower(files, texts, config=config)

"""Programs from disk or text: the dialect of a file, a .src's .dat, reading one program."""
from __future__ import annotations

import re
import sys
from pathlib import Path

from ..core.diagnostics import P108, P111, P222, PostprocError
from ..core.outputs import check_outputs
from .model import ActiveFrames, Program
from .text import decode, read_text

__all__ = [
    "load_program", "parse_program_text", "read_program", "dialect_of", "companion_dat", "lower",
    "check_program_outputs", "sniff_dialect", "backup_active", "STDIN", "check_memory", "MEMORY_PER_INPUT_BYTE",
]


STDIN = "<stdin>"


def sniff_dialect(text: str) -> str:
    """KRL or a pose list, for text that comes without a file name (stdin)."""
    krl = re.search(r"^[ \t]*(?:&ACCESS|(?:GLOBAL\s+)?DEF(?:FCT|DAT)?\b|S?(?:LIN|PTP|CIRC)\b)", text, re.I | re.M)
    return "krl" if krl else "poses"


def parse_program_text(
    text: str,
    name: str = STDIN,
    dialect: str | None = None,
    dat_text: str | None = None,
    config_texts: list[str] | None = None,
    active: ActiveFrames | None = None,
) -> Program:
    """Parse a program given as text (a .src with optional .dat text, or a pose list);
    ``active``: the $BASE/$TOOL stated for a KRL program that does not set them."""
    dialect = dialect or (dialect_of(name) if name != STDIN and Path(name).suffix else sniff_dialect(text))
    files, texts = [name], [text]
    if dat_text is not None:
        files.append(str(Path(name).with_suffix(".dat")) if name != STDIN else "<stdin.dat>")
        texts.append(dat_text)
    return read_program(files, texts, dialect, config=config_texts, active=active)


def config_texts(config: str | Path | list | None) -> list[str] | None:
    if config is None:
        return None
    paths = config if isinstance(config, list | tuple) else [config]
    return [read_text(Path(p)) for p in paths]


def backup_active(config: str | Path | list | None, active: ActiveFrames | None) -> ActiveFrames | None:
    """``active`` with the $ROBROOT of the controller backup a ``System/$config.dat`` of
    ``config`` belongs to (its ``Mada/$machine.dat``), unless ``active`` states one."""
    if config is None:  # no $config.dat, no backup: ``active`` as it is (and no import of the KRL reader)
        return active
    from .krl.machine import with_machine

    return with_machine(active, configs=[] if config is None else (
        list(config) if isinstance(config, list | tuple) else [config]))


def load_program(path: str | Path, config: str | Path | None = None, dialect: str | None = None,
                 active: ActiveFrames | None = None) -> Program:
    """Read a program from disk: a .src with its .dat companion, a lone .dat, or a pose list.
    ``-`` reads standard input. ``config`` is a ``$config.dat`` for BASE_DATA / TOOL_DATA
    (and, in a backup, the ``Mada/$machine.dat`` beside its ``System/``: ``backup_active``);
    ``active`` the $BASE/$TOOL/$ROBROOT stated for a KRL program that does not set them."""
    if dialect in (None, "krl"):
        active = backup_active(config, active)
    if str(path) == "-":
        return parse_program_text(decode(sys.stdin.buffer.read(), STDIN), STDIN, dialect, None, config_texts(config),
                                  active)
    path = Path(path)
    if dialect is None:
        try:
            dialect = dialect_of(path)
        except ValueError as exc:
            raise PostprocError(str(exc), str(path), 0, 0, P108) from None
    dat = companion_dat(path) if dialect == "krl" else None
    check_memory([path] + ([dat] if dat is not None else []))
    files, texts = [str(path)], [read_text(path)]
    if dat is not None:
        files.append(str(dat))
        texts.append(read_text(dat))
    return read_program(files, texts, dialect, config=config_texts(config), active=active)


def check_program_outputs(program: str | Path, output: str | Path, *, in_place: bool = False) -> list[Path]:
    """:func:`check_outputs` for ``compensate``: a .src and its .dat in, the two out (the .dat
    beside ``output``, with the input .dat's suffix)."""
    dat = companion_dat(Path(program)) if str(program) != "-" else None
    outputs = [Path(output)] if str(output) != "-" else []
    if dat is not None and outputs:
        outputs.append(outputs[0].with_suffix(dat.suffix))
    return check_outputs(outputs, [program, dat], in_place=in_place)


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
                 active: ActiveFrames | None = None, data: dict[str, str] | None = None, task: str | None = None,
                 registers: str = "backup") -> Program:
    """Parse a program made of ``files`` (for KRL: the .src first, then its .dat if any)
    with contents ``texts``. ``config`` optionally holds ``$config.dat`` text(s) that give
    BASE_DATA / TOOL_DATA (for RAPID: other modules' tooldata / wobjdata; for Fanuc LS: the frame
    file, TOML, of --frames). ``active``: the $BASE / $TOOL in force where a KRL program has not
    set them, and the TCP of a URScript program before its first set_tcp (``tool`` only; the
    other dialects name theirs at every target and refuse it, P222; its ``robroot``, KRL's
    $ROBROOT, they do not need: their targets are in the robot base). ``data``: a backup's
    system files read with the program (path → text: Fanuc .va, RAPID SYSPAR .cfg), ``task``
    the RAPID task's name, ``registers`` ("backup" or "runtime": settings.reading.registers).
    Raises PostprocError (with file:line:col) on bad input."""
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
        from ..core.diagnostics import PostprocError

        raise PostprocError(f"--base / --tool state the frames of KRL programs; a {dialect} program names its "
                            "own at every target", files[0] if files else "", 0, 0, P222)
    if dialect == "poses":
        from . import poses

        program = poses.read(files, texts)
        program.from_text = True
        return program
    if dialect == "rapid":
        from . import rapid

        program = rapid.read(files, texts, config=config, external=external, **_backup("rapid", data, task, registers))
        program.config = list(config) if config else None
        if external:  # (read again as it was read: guards.check_round_trip)
            program.active = ActiveFrames(external=external)
        program.from_text = True
        return program
    if dialect == "fanuc":
        from . import fanuc

        program = fanuc.read(files, texts, frames=config, external=external,
                             **_backup("fanuc", data, task, registers))
        program.config = list(config) if config else None
        if external:
            program.active = ActiveFrames(external=external)
        program.from_text = True
        return program
    raise ValueError(f"unknown dialect {dialect!r}")


def _backup(dialect: str, data: dict[str, str] | None, task: str | None, registers: str) -> dict:
    """The keyword arguments a reader takes for a backup's system files (none without them): a
    Fanuc reader's .va texts and ``registers``, a RAPID reader's SYSPAR texts and ``task``."""
    if dialect == "fanuc":
        return {"va": data, "registers": registers} if data else {}
    return {"syspar": data, "task": task} if data or task else {}

def lower(files: list[str], texts: list[str], dialect: str, config: list[str] | None = None,
          active: ActiveFrames | None = None, data: dict[str, str] | None = None, task: str | None = None,
          registers: str = "backup"):
    """The motion IR of a program and its dialect's meaning: (``ir.Unit``, ``analysis.Dialect``)
    — what ``read_program`` analyses (with the same arguments), and what ``interpreter.run`` executes."""
    if dialect == "krl":
        from .krl.reader import lower as krl_lower

        return krl_lower(files, texts, config=config, active=active)
    if dialect == "poses":
        from .poses import lower as poses_lower

        return poses_lower(files, texts)
    if dialect == "rapid":
        from . import rapid as reader
    elif dialect == "urscript":
        from . import urscript as reader
    elif dialect == "fanuc":
        from . import fanuc as reader
    else:
        raise ValueError(f"unknown dialect {dialect!r}")
    external = active.external if active is not None else ()
    if dialect == "urscript":  # (its --tool: the TCP before the script's first set_tcp)
        return reader.lower(files, texts, active=active)
    if active is not None and (active.frames_stated or active.robroot is not None):
        raise ValueError(f"active frames are KRL's ($BASE/$TOOL at the start): not {dialect}")
    backup = _backup(dialect, data, task, registers)
    if dialect == "fanuc":  # (its frame file, a backup's .va files)
        return reader.lower(files, texts, frames=config, external=external, **backup)
    if external or backup:
        return reader.lower(files, texts, config=config, external=external, **backup)
    return reader.lower(files, texts, config=config)


# Peak memory of compensating in memory, per byte of program text (benchmarks/compensate_speed.py
# --memory, 2026-12-02, the default model with its approach settling): 83 MB + 38 × on a KRL CAM
# program, 59 × on a 1M-row pose CSV (2.68 GB for 45.5 MB: shorter lines per target). A program
# is refused when 64 × its size is more than the memory available: it would be killed half-way
# otherwise (a KRL .src above 8 MB streams, in ~215 MB whatever its size, and is not held to it).
MEMORY_PER_INPUT_BYTE = 64


def _available_bytes() -> int | None:
    """MemAvailable + SwapFree (Linux), None where unknown."""
    try:
        with open("/proc/meminfo") as fh:
            info = {k: int(v.split()[0]) * 1024 for k, v in (line.split(":", 1) for line in fh)}
    except (OSError, ValueError):
        return None
    return info.get("MemAvailable", 0) + info.get("SwapFree", 0) if "MemAvailable" in info else None


def check_memory(paths: list[Path]) -> None:
    """Refuse (P111) programs whose files will not fit in memory while being compensated."""
    size = sum(p.stat().st_size for p in paths if p.is_file())
    available = _available_bytes()
    if available is None or size * MEMORY_PER_INPUT_BYTE <= available:
        return
    raise PostprocError(f"too large to compensate here: {size / 1e6:,.0f} MB of program needs about "
                        f"{size * MEMORY_PER_INPUT_BYTE / 1e9:,.1f} GB of memory, {available / 1e9:,.1f} GB are "
                        f"available; split it into programs of at most {available / MEMORY_PER_INPUT_BYTE / 1e6:,.0f} MB",
                        str(paths[0]), 0, 0, P111)

"""A robot cell as one unit: the files of one robot's programs, or a controller backup directory.

Every file given is read, or the run refuses (P108: a kind no reader takes; P119: programs of
several robot families in one run): no file is passed over in silence. A directory is searched
for the programs of every family (pose lists are not searched for: a directory holds
measurement CSVs too) and for a backup's system files, which are read and never written.

What one reader call reads (a :class:`Part`; ``Cell.read_all``), by family:

* KRL: every module (.src/.sub with its .dat), data list and ``$config.dat`` — one program
  (``Cell.modules``, ``Cell.data_lists``, ``Cell.config``; ``Cell.read``);
* RAPID: the modules of one task (.mod/.modx/.prg/.sys) — one program per task: a backup's
  tasks are its ``RAPID/TASKn`` folders (``PROGMOD``, ``SYSMOD``), named as its
  ``BACKINFO/backinfo.txt`` says; the ``SYSPAR/*.cfg`` files are read with every task;
* Fanuc LS: every .ls — one program (CALLs resolve across them), with the backup's .va files
  (``sysframe.va``, ``posreg.va``, ``numreg.va``); a binary .tp without its .ls is refused;
* URScript and pose lists: each file its own program.
"""
from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from pathlib import Path

from ..core.diagnostics import P107, P108, P112, P119, PostprocError
from .io import FANUC_SUFFIXES, RAPID_SUFFIXES, URSCRIPT_SUFFIXES, dialect_of, load_program, read_program
from .krl.machine import found_machine, is_machine, with_machine
from .model import ActiveFrames, Program
from .text import read_text

__all__ = ['Cell', 'Part', 'find_cell', 'find_cells', 'load_programs', 'is_config', 'CONFIG_NAME', 'FAMILY_NAMES']


CONFIG_NAME = "$config.dat"


KRL = {".src", ".sub", ".dat"}


MODULES = {".src", ".sub"}


# a backup's system files (read with the programs, never written): the family they belong to
SYSTEM_FILES = {".va": "fanuc", ".cfg": "rapid"}


FAMILY_NAMES = {"krl": "KRL", "rapid": "RAPID", "urscript": "URScript", "fanuc": "Fanuc LS", "poses": "pose list"}


def is_config(path: Path) -> bool:
    return path.name.casefold() == CONFIG_NAME.casefold()


@dataclass
class Part:
    """One program of a cell that is not KRL: its files (read and written) in the order read,
    the system files read with them (a backup's .va / .cfg: path → text), the task's name."""

    dialect: str
    files: list[Path]
    system: list[Path] = field(default_factory=list)
    task: str | None = None

    def read(self, config: list[str] | None = None, active: ActiveFrames | None = None,
             registers: str = "backup", *, texts: dict[Path, str] | None = None) -> Program:
        """The part's program; ``config`` paths read-only (--config); ``texts``: files already
        read (path → text: a backup's system files, read once for all its tasks)."""
        texts = {} if texts is None else texts
        for p in self.system + [Path(c) for c in config or []]:
            if p not in texts:
                texts[p] = read_text(p)
        return read_program([str(f) for f in self.files], [read_text(f) for f in self.files], self.dialect,
                            config=[texts[Path(c)] for c in config] if config else None, active=active,
                            data={str(p): texts[p] for p in self.system} or None, task=self.task,
                            registers=registers)


@dataclass
class Cell:
    """The files of a cell: ``root`` (what output paths are relative to), its ``dialect``; for
    KRL ``modules`` (each its main file, then its .dat if any), ``data_lists`` (.dat without a
    module), ``config`` ($config.dat files: given, or found in the cell); for the other
    families its ``parts`` (one program each)."""

    root: Path
    modules: list[list[Path]] = field(default_factory=list)
    data_lists: list[Path] = field(default_factory=list)
    config: list[Path] = field(default_factory=list)
    active: ActiveFrames | None = None  # the $BASE/$TOOL stated (or machine data) where its programs do not set them
    dialect: str = "krl"
    parts: list[Part] = field(default_factory=list)

    @property
    def files(self) -> list[Path]:
        if self.dialect != "krl":
            return [f for part in self.parts for f in part.files]
        return [p for m in self.modules for p in m] + self.data_lists + [c for c in self.config if self.inside(c)]

    def inside(self, path: Path) -> bool:
        return path.resolve().is_relative_to(self.root.resolve())

    def read(self) -> Program:
        """Every file of a KRL cell as one Program, in one reader call; a ``$config.dat`` from
        outside the cell is read as configuration only (the other families: ``read_all``)."""
        if self.dialect != "krl":
            raise ValueError(f"a {self.dialect} cell is read with read_all")
        files = self.files
        outside = [read_text(c) for c in self.config if not self.inside(c)] or None
        return read_program([str(f) for f in files], [read_text(f) for f in files], "krl", config=outside,
                            active=self.active)

    def read_all(self, config: list[str] | None = None, registers: str = "backup") -> list[Program]:
        """The cell's programs: one for KRL (:meth:`read`), one per part for the other families
        (``config``: the RAPID modules / Fanuc frame file given with --config, read-only)."""
        if self.dialect == "krl":
            return [self.read()] if self.files else []
        texts: dict[Path, str] = {}
        return [part.read(config, self.active, registers, texts=texts) for part in self.parts]


def krl_files(directory: Path) -> list[Path]:
    """The KRL files (.src, .sub, .dat) below ``directory``, sorted."""
    return sorted(q for q in directory.rglob("*") if q.suffix.lower() in KRL and q.is_file())


def _found_config(root: Path) -> list[Path]:
    """``root/System/$config.dat``, else the shallowest ``System/$config.dat`` below ``root``
    (``KRC/`` → ``KRC/R1/System/$config.dat``); several at one depth: refused (P112)."""
    found = sorted(p for p in root.rglob("*") if is_config(p) and p.parent.name.casefold() == "system" and p.is_file())
    if not found:
        return []
    depth = min(len(p.relative_to(root).parts) for p in found)
    shallowest = [p for p in found if len(p.relative_to(root).parts) == depth]
    if len(shallowest) > 1:
        raise PostprocError(f"several $config.dat in this cell ({', '.join(str(p) for p in shallowest)}): give "
                            "--config", str(root), 0, 0, P112)
    return shallowest


def _krl_cell(paths: list[str | Path], config: list[str | Path] | None = None,
              active: ActiveFrames | None = None) -> Cell:
    """The KRL cell made of these files and directories (searched recursively for .src, .sub
    and .dat). ``config`` None: a ``$config.dat`` given among the files, else the one in
    the directory's ``System/`` (see :func:`_found_config`). ``$machine.dat`` files are the
    robot's machine data, not programs: its $ROBROOT goes into ``Cell.active`` unless stated
    (``programs.krl.machine.with_machine``)."""
    files: list[Path] = []
    dirs = []
    machines: list[Path] = []
    for p in map(Path, paths):
        if p.is_dir():
            dirs.append(p)
            files += [f for f in krl_files(p) if not is_machine(f)]
        elif p.is_file():
            (machines if is_machine(p) else files).append(p)
        else:
            raise PostprocError("no such file or directory", str(p), 0, 0, P107)
    if not files:
        raise PostprocError("no KRL files (.src, .sub, .dat) here", str(paths[0]) if paths else "", 0, 0, P107)
    parents = list(dirs) + [f.parent for f in files if not any(f.resolve().is_relative_to(d.resolve()) for d in dirs)]
    root = Path(os.path.commonpath([str(p.resolve()) for p in parents]))
    given = [Path(c) for c in config] if config else []
    found = [f for f in files if is_config(f)]
    if not given:
        given = found or [c for d in dirs for c in _found_config(d)][:1]
    machines = machines or [m for d in dirs for m in found_machine(d)]
    cell = Cell(root=root, config=given, active=with_machine(active, configs=given, machines=machines))
    unique = list(dict.fromkeys(f.resolve() for f in files))
    by_stem: dict[tuple[Path, str], Path] = {}
    for f in unique:
        if f.suffix.lower() in MODULES:
            by_stem.setdefault((f.parent, f.stem.casefold()), f)
    dats = {}
    for f in unique:
        if f.suffix.lower() != ".dat" or is_config(f):
            continue
        owner = by_stem.get((f.parent, f.stem.casefold()))
        if owner is None:
            # (a .dat given alone may still have its .src beside it, not given)
            cell.data_lists.append(f)
        else:
            dats[owner] = f
    for f in unique:
        if f.suffix.lower() in MODULES:
            cell.modules.append([f] + ([dats[f]] if f in dats else []))
    for f in unique:
        if is_config(f) and f not in [c.resolve() for c in cell.config]:
            cell.data_lists.append(f)
    return cell


PROGRAM_SUFFIXES = {**{s: "krl" for s in KRL}, **{s: "rapid" for s in RAPID_SUFFIXES},
                    **{s: "urscript" for s in URSCRIPT_SUFFIXES}, **{s: "fanuc" for s in FANUC_SUFFIXES}}


_BACKINFO_TASK = re.compile(r">>\s*(TASK\d+)\s*:\s*\(\s*([A-Za-z_][A-Za-z0-9_]*)", re.I)


@dataclass
class _Found:
    """What the paths given hold: program files by family, a backup's system files, machine data."""

    programs: dict[str, list[Path]] = field(default_factory=dict)
    system: list[Path] = field(default_factory=list)
    machines: list[Path] = field(default_factory=list)
    dirs: list[Path] = field(default_factory=list)
    files: list[Path] = field(default_factory=list)  # every program file, in the order found
    tp: list[Path] = field(default_factory=list)  # Fanuc binary TP programs found in directories
    backinfo: list[Path] = field(default_factory=list)  # an ABB backup's BACKINFO/backinfo.txt


def _system_file(path: Path) -> bool:
    """A backup's system file read with its programs: a Fanuc .va, a RAPID SYSPAR .cfg."""
    suffix = path.suffix.lower()
    return suffix == ".va" or (suffix == ".cfg" and path.parent.name.casefold() == "syspar")


def _gather(paths: list[str | Path], unreadable: list | None = None) -> _Found:
    """What the paths hold; a file given that cannot be read (no such file, a kind no reader takes)
    is refused, or with ``unreadable`` a list its finding goes into and the others are gathered."""
    found = _Found()
    given_system: list[Path] = []

    def add(path: Path, family: str) -> None:
        found.programs.setdefault(family, []).append(path)
        found.files.append(path)

    for p in map(Path, paths):
        if p.is_dir():
            found.dirs.append(p)
            for q in sorted(p.rglob("*")):
                if not q.is_file():
                    continue
                suffix = q.suffix.lower()
                if is_machine(q):
                    found.machines.append(q)
                elif _system_file(q):
                    found.system.append(q)
                elif suffix in PROGRAM_SUFFIXES:
                    add(q, PROGRAM_SUFFIXES[suffix])
                elif suffix == ".tp":
                    found.tp.append(q)
                elif q.name.casefold() == "backinfo.txt":
                    found.backinfo.append(q)
        elif is_machine(p) and p.is_file():
            found.machines.append(p)
        elif (_system_file(p) or p.suffix.lower() in SYSTEM_FILES) and p.is_file():
            found.system.append(p)
            given_system.append(p)
        else:
            try:
                if not p.is_file():
                    raise PostprocError("no such file or directory", str(p), 0, 0, P107)
                try:
                    family = dialect_of(p)
                except ValueError as exc:
                    raise PostprocError(f"{exc}: every file given is read, or the run refuses", str(p), 0, 0,
                                        P108) from None
            except PostprocError as exc:
                if unreadable is None:
                    raise
                unreadable.append(exc.diagnostic())
                continue
            add(p, family)
    for p in given_system:
        family = SYSTEM_FILES[p.suffix.lower()]
        if found.programs and family not in found.programs:
            raise PostprocError(f"a {FAMILY_NAMES[family]} backup's system file, given with programs of another "
                                f"family ({', '.join(FAMILY_NAMES[f] for f in found.programs)}): it would not be "
                                "read", str(p), 0, 0, P119)
    ls = {(q.parent.resolve(), q.stem.casefold()) for q in found.programs.get("fanuc", [])}
    unread = [q for q in found.tp if (q.parent.resolve(), q.stem.casefold()) not in ls]
    if unread:
        raise PostprocError(f"{len(unread)} binary TP program{'s' * (len(unread) != 1)} (.tp) without its ASCII "
                            f".ls ({', '.join(q.name for q in unread[:5])}{' …' * (len(unread) > 5)}): postproc "
                            "reads .ls; print them to .ls on the controller (a backup 'all as images' with ASCII "
                            "programs, or ROBOGUIDE) and give those", str(unread[0]), 0, 0, P107)
    return found


def _root(found: _Found) -> Path:
    parents = list(found.dirs) + [f.parent for f in found.files + found.system
                                  if not any(f.resolve().is_relative_to(d.resolve()) for d in found.dirs)]
    return Path(os.path.commonpath([str(p.resolve()) for p in parents]))


def _task_of(path: Path) -> Path | None:
    """The ``RAPID/TASKn`` folder of a backup a module lies in, None outside one."""
    parts = path.resolve().parts
    for i in range(len(parts) - 2, 0, -1):
        if re.fullmatch(r"task\d+", parts[i], re.I) and parts[i - 1].casefold() == "rapid":
            return Path(*parts[:i + 1])
    return None


def _task_names(found: _Found) -> dict[str, str]:
    """``TASK1`` → ``T_ROB1``, as the backups' ``BACKINFO/backinfo.txt`` say."""
    names: dict[str, str] = {}
    for info in found.backinfo:
        for m in _BACKINFO_TASK.finditer(read_text(info)):
            names.setdefault(m.group(1).upper(), m.group(2))
    return names


def _parts(family: str, files: list[Path], found: _Found) -> list[Part]:
    system = [f for f in found.system if SYSTEM_FILES.get(f.suffix.lower()) == family]
    unique = list({f.resolve(): f for f in reversed(files)}.values())[::-1]  # (each file once, as given)
    if family == "rapid":
        tasks: dict[Path | None, list[Path]] = {}
        for f in unique:
            tasks.setdefault(_task_of(f), []).append(f)
        names = _task_names(found)
        parts = [Part("rapid", modules, system, names.get(folder.name.upper(), folder.name))
                 for folder, modules in tasks.items() if folder is not None]
        loose = tasks.get(None, [])
        # beside a backup's tasks, a module in no RAPID/TASKn folder (its HOME/, a copy) is loaded by no
        # task: read alone; without tasks, the modules given are one task
        if not parts:
            return [Part("rapid", loose, system)] if loose else []
        return parts + [Part("rapid", [f], system) for f in loose]
    if family == "fanuc":
        return [Part("fanuc", unique, system)]
    return [Part(family, [f]) for f in unique]  # (URScript, pose lists: each file is a program)


def find_cells(paths: list[str | Path], config: list[str | Path] | None = None, active: ActiveFrames | None = None,
               *, unreadable: list | None = None) -> list[Cell]:
    """The cells these files and directories hold, one per robot family (``check`` reads a
    repository of several robots' programs). Every program file given or found is in one of
    them; a file no reader takes is refused (P108), so is a directory without programs (P107);
    ``unreadable``: a list the findings of files given that cannot be read go into instead."""
    said = len(unreadable) if unreadable is not None else 0
    found = _gather(paths, unreadable)
    if not found.programs and unreadable is not None and len(unreadable) > said:
        return []  # (every file given was unreadable: each said)
    if not found.programs:
        kinds = "KRL .src/.sub/.dat, RAPID .mod/.modx/.prg/.sys, URScript .script, Fanuc .ls"
        raise PostprocError(f"no programs here ({kinds}; pose lists are given by name)",
                            str(paths[0]) if paths else "", 0, 0, P107)
    cells = []
    root = _root(found)
    for family, files in found.programs.items():
        if family == "krl":
            krl = [d for d in found.dirs] + [f for f in files if not any(
                f.resolve().is_relative_to(d.resolve()) for d in found.dirs)] + found.machines
            cells.append(_krl_cell(krl, config, active))
        else:
            cells.append(Cell(root=root, dialect=family, parts=_parts(family, files, found), active=active))
    return cells


def find_cell(paths: list[str | Path], config: list[str | Path] | None = None,
              active: ActiveFrames | None = None) -> Cell:
    """The one robot's cell these files and directories make (``find_cells``); programs of
    several families in one run are refused (P119: one model is one robot's)."""
    cells = find_cells(paths, config, active)
    if len(cells) > 1:
        said = "; ".join(f"{FAMILY_NAMES[c.dialect]}: {', '.join(f.name for f in c.files[:3])}"
                         f"{' …' * (len(c.files) > 3)}" for c in cells)
        raise PostprocError(f"programs of {len(cells)} robot families given as one run ({said}): a run is one "
                            "robot's programs, compensated with its model; give each robot's files in a run of its "
                            "own", str(cells[1].files[0]), 0, 0, P119)
    return cells[0]


def load_programs(paths: list[str | Path], config: list[str] | None = None, active: ActiveFrames | None = None,
                  registers: str = "backup", *, families: bool = False) -> list[Program]:
    """The programs of these files and directories as ``compensate`` reads them: one file alone
    (a .src with its .dat beside it) with ``io.load_program``, else the cells of
    :func:`find_cells` (``families``: several robot families allowed, else refused, P119)."""
    if len(paths) == 1 and not Path(paths[0]).is_dir():
        return [load_program(paths[0], config, None, active)]
    cells = find_cells(paths, config, active) if families else [find_cell(paths, config, active)]
    return [program for cell in cells for program in cell.read_all(config, registers)]

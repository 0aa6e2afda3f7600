"""A robot cell as one unit: a set of KRL files or a controller backup directory."""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

from ..core.diagnostics import P107, P112, PostprocError
from .io import read_program
from .krl.machine import found_machine, is_machine, with_machine
from .model import ActiveFrames, Program
from .text import read_text

__all__ = ['Cell', 'find_cell', 'is_config', 'CONFIG_NAME']


CONFIG_NAME = "$config.dat"


KRL = {".src", ".sub", ".dat"}


MODULES = {".src", ".sub"}


def is_config(path: Path) -> bool:
    return path.name.casefold() == CONFIG_NAME.casefold()


@dataclass
class Cell:
    """The files of a cell: ``root`` (what output paths are relative to), ``modules``
    (each its main file, then its .dat if any), ``data_lists`` (.dat without a module),
    ``config`` ($config.dat files: given, or found in the cell)."""

    root: Path
    modules: list[list[Path]] = field(default_factory=list)
    data_lists: list[Path] = field(default_factory=list)
    config: list[Path] = field(default_factory=list)
    active: ActiveFrames | None = None  # the $BASE/$TOOL/$ROBROOT stated (or machine data) where its programs do not set them

    @property
    def files(self) -> list[Path]:
        return [p for m in self.modules for p in m] + self.data_lists + [c for c in self.config if self.inside(c)]

    def inside(self, path: Path) -> bool:
        return path.resolve().is_relative_to(self.root.resolve())

    def read(self) -> Program:
        """Every file of the cell as one Program, in one reader call; a ``$config.dat`` from
        outside the cell is read as configuration only."""
        files = self.files
        outside = [read_text(c) for c in self.config if not self.inside(c)] or None
        return read_program([str(f) for f in files], [read_text(f) for f in files], "krl", config=outside,
                            active=self.active)


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


def find_cell(paths: list[str | Path], config: list[str | Path] | None = None,
              active: ActiveFrames | None = None) -> Cell:
    """The cell made of these files and directories (searched recursively for .src, .sub
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

"""Checks of robot programs for ``postproc check`` and the pre-commit hooks.

Everything here returns :class:`~postproc.core.diagnostics.Diagnostic` lists; nothing prints.
A program is checked for what would make ``postproc compensate`` (with the same model and
settings) refuse or warn, plus what only matters once programs are kept in a repository:

* syntax errors (the dialect reader's ``P1xx``), the reader's warnings (``P2xx``) and notes
  (``P224``: robot base = world assumed, once per program; never a failure);
* targets the nominal robot cannot reach (``P302``, the model's ``reach``; ``P309`` with an
  IK reachability test), outside the training envelope (``P301``), not finite (``P103``),
  with a position or orientation that is not known (``P212``, ``P213``), a $TOOL that is not
  the model's (``P304``) or a model trained on another robot (``P310``), corrections the
  model makes NaN (``P305``) or implausibly large (``P303``), one set of numbers the runs of
  which need other numbers (``P230``): the rules of :mod:`postproc.compensation.findings`, which compensate
  applies too;
  then, if none is an error, the last checks before writing (``P190``, ``P191``);
* stamps: compensated with a model other than the configured one (``P402``), compensated
  twice (``P403``), a .src and .dat that do not come from one compensation (``P404``; a
  file without targets that compensate changes carries no stamp, and needs none);
* freshness of configured source → output pairs (``P405`` stale, ``P406`` output missing,
  ``P407`` output without source), by compensating the source in memory and comparing
  bytes: git checkouts scramble mtimes, so they prove nothing.
"""
from __future__ import annotations

import os
import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..core.atomic import write_atomic
from ..core.diagnostics import (
    P107,
    P230, P322, P401, P402, P403, P404, P405, P406, P407, Diagnostic, PostprocError, line_col,
)
from ..model.compensator import Compensator, load_model
from ..programs import STAMP_PREFIX, Program
from ..programs.io import companion_dat, load_program
from ..settings import Settings
from .findings import findings, run_model, select, std_bound
from .pipeline import compensate_program, output_paths, rewrite_program

__all__ = [
    "Stamp",
    "find_stamps",
    "check_program",
    "check_file",
    "check_files",
    "check_fresh",
    "program_paths",
    "failed",
]

# "path:line:col" of a stamp; the name may hold spaces, the hash is the last word
_STAMP = re.compile(
    # (Fanuc LS: a numbered remark '  7:  ! postproc: … ;')
    r"^[ \t]*(?:\d+:[ \t]*)?(?:;|#|//|!)[ \t]*" + re.escape(STAMP_PREFIX) + r"[ \t]+(?P<name>.*?)[ \t]+"
    r"(?P<sha>[0-9a-fA-F]{6,64})[ \t]*;?[ \t]*\r?$",
    re.M,
)


@dataclass(frozen=True)
class Stamp:
    """One ``; postproc: compensated with model <name> <sha256[:12]>`` line."""

    file: int  # index into Program.files
    line: int
    col: int
    name: str
    sha: str

    def same_model(self, model: Compensator) -> bool:
        return self.name == model.name and model.sha256.startswith(self.sha.lower())


def find_stamps(program: Program) -> list[Stamp]:
    """Every stamp line in every file of the program, in file and line order."""
    out = []
    for index, text in enumerate(program.texts):
        for m in _STAMP.finditer(text):
            line, _ = line_col(text, m.start())
            indent = len(m.group()) - len(m.group().lstrip(" \t"))
            out.append(Stamp(index, line, indent + 1, m.group("name"), m.group("sha")))
    return out


def failed(diagnostics: Iterable[Diagnostic], strict: bool = False) -> bool:
    """Whether the findings fail a check: any error, and under ``strict`` any warning too (a
    note, e.g. P224's assumption, never)."""
    return any(d.severity == "error" or (strict and d.severity != "note") for d in diagnostics)


# --------------------------------------------------------------------------- one program


def _stamp_findings(program: Program, model: Compensator, selection) -> list[Diagnostic]:
    stamps = find_stamps(program)
    out: list[Diagnostic] = []
    first: dict[int, Stamp] = {}
    for s in stamps:
        path = program.files[s.file]
        if s.file in first:
            f = first[s.file]
            out.append(Diagnostic(path, s.line, s.col, P403,
                                  f"compensated twice: a second stamp (the first is on line {f.line}, "
                                  f"model {f.name} {f.sha})", "error"))
            continue
        first[s.file] = s
        if not s.same_model(model):
            what = ("another version of model " + s.name) if s.name == model.name else f"model {s.name}"
            out.append(Diagnostic(path, s.line, s.col, P402,
                                  f"compensated with {what} {s.sha}, not the configured {model.name} "
                                  f"{model.sha256[:12]}", "error"))
    if first and len(program.files) > 1:
        # one compensation stamps every file of a module (its .src/.sub and .dat: one stem in
        # one folder) with the same line (a file without a target compensate would change is
        # not stamped: it did not change); the modules of a cell are compared each on its own
        changes = set(program.targets.file[selection.rows].tolist())
        modules: dict[tuple[str, str], list[int]] = {}
        for i, name in enumerate(program.files):
            path = Path(name)
            modules.setdefault((str(path.parent), path.stem.casefold()), []).append(i)
        for members in modules.values():
            keys = {i: (first[i].name, first[i].sha) if i in first else None for i in members
                    if i in first or i in changes}
            if len(set(keys.values())) <= 1:
                continue
            for i, key in keys.items():
                others = [program.files[j] for j, k in keys.items() if k != key]
                where = (first[i].line, first[i].col) if i in first else (1, 1)
                state = f"stamped {key[0]} {key[1]}" if key else "not stamped"
                out.append(Diagnostic(program.files[i], *where, P404,
                                      f"{state}, unlike {', '.join(others)}: the files of this module do not "
                                      "come from one compensation", "error"))
    return out


def check_program(
    program: Program,
    model: Compensator,
    settings: Settings = Settings(),
    *,
    reachable: Callable[[np.ndarray], np.ndarray] | None = None,
) -> list[Diagnostic]:
    """Every finding about a parsed program (see the module docstring), in no particular order.

    ``settings.robot`` is the robot the program is for (a model trained on another is ``P310``);
    ``reachable`` optionally maps robot-base poses [N, 6] to a bool mask [N] (e.g. IK of
    the nominal robot); targets it rejects are ``P309`` errors. The rules are compensate's
    (:func:`postproc.compensation.findings.findings`); when none is an error, the program is rewritten in
    memory from the same commands, so that the last checks before writing (P190, P191) are
    findings too: a clean check means compensate succeeds.
    """
    selection = select(program, model, settings, reachable=reachable)
    commands = run_model(model, selection, settings.rules.iterations, std=std_bound(model, settings) is not None)
    # a stamp is the stamp rules' business here (P402-P404), not "already compensated"
    out = list(program.diagnostics) + program.notes
    out += [d for d in findings(program, commands, model, settings, reachable=reachable) if d.code != P401]
    out += _stamp_findings(program, model, selection)
    if not failed(out):
        t = program.targets
        try:
            if t.group is not None and (t.group >= 0).any():
                # numbers run more than once: compensate's own agreement of the runs (P230, P322),
                # which needs its rounds (the model again without the groups that disagree)
                # (the check's settings: not strict; forced, because a stamp is the stamp rules' business
                # here and every other finding --force lifts is the rules' above: only P230/P322 are taken)
                rules = replace(settings.rules, strict=False, force=True)
                report = compensate_program(program, model, replace(settings, rules=rules), reachable=reachable)
                said = {(d.path, d.line, d.col, d.code) for d in out}
                out += [d for d in report.warnings + report.notes if d.code in (P230, P322)
                        and (d.path, d.line, d.col, d.code) not in said]
            else:
                rewrite_program(program, commands, model)
        except PostprocError as exc:
            out.append(exc.diagnostic())
    return out


# --------------------------------------------------------------------------- files


def _owner(path: Path) -> Path:
    """The .src a .dat belongs to (same stem, any case, same folder), else the path itself."""
    if path.suffix.lower() != ".dat" or not path.parent.is_dir():
        return path
    stem = path.stem.lower()
    for candidate in sorted(path.parent.iterdir()):
        if candidate.suffix.lower() == ".src" and candidate.stem.lower() == stem and candidate.is_file():
            return candidate
    return path


def program_paths(paths: Iterable[str | Path]) -> list[Path]:
    """The programs to read for these files: a .dat is read with its .src; no program twice."""
    seen: dict[Path, None] = {}
    for p in paths:
        seen.setdefault(_owner(Path(p)), None)
    return list(seen)


def check_file(
    path: str | Path,
    model: Compensator,
    settings: Settings = Settings(),
    *,
    reachable: Callable[[np.ndarray], np.ndarray] | None = None,
) -> list[Diagnostic]:
    """Read and check one program (a .src reads its .dat too) as ``settings.reading`` says; a
    syntax error is a finding."""
    reading = settings.reading
    try:
        program = load_program(path, reading.config_list, reading.dialect, reading.active)
    except PostprocError as exc:
        return [exc.diagnostic()]
    return check_program(program, model, settings, reachable=reachable)


def _data_list_findings(path: Path) -> list[Diagnostic]:
    """A data list without a DEF ($config.dat, a PUBLIC points list): not a program, but its
    syntax is checked (read as the configuration of an empty module)."""
    from ..programs.io import read_program
    from ..programs.text import read_text as _read

    try:
        read_program([str(path.with_suffix(".src"))], ["DEF empty()\nEND\n"], "krl", config=[_read(path)])
    except PostprocError as exc:
        d = exc.diagnostic()
        return [replace(d, path=str(path))]
    return []


def check_files(
    paths: Iterable[str | Path],
    model: Compensator,
    settings: Settings = Settings(),
    *,
    reachable: Callable[[np.ndarray], np.ndarray] | None = None,
) -> list[Diagnostic]:
    """Check the programs these files belong to, as one cell: directories are searched for
    programs of every dialect but pose lists (KRL; RAPID, URScript and Fanuc LS files by their
    suffix: a directory holds measurement CSVs and notes too), a ``$config.dat`` among them is
    the configuration of the others (unless ``settings.reading.config`` is given), a data list
    without a DEF is checked for syntax only; the codes of ``settings.check.ignore`` are not
    reported; findings sorted by path, line, column."""
    from ..programs.cell import KRL, is_config
    from ..programs.io import FANUC_SUFFIXES, RAPID_SUFFIXES, URSCRIPT_SUFFIXES
    from ..programs.krl.machine import found_machine, is_machine, with_machine

    suffixes = set(KRL) | RAPID_SUFFIXES | URSCRIPT_SUFFIXES | FANUC_SUFFIXES

    def in_directory(d: Path) -> list[Path]:  # (one walk; KRL's machine data is not a program)
        return sorted(q for q in d.rglob("*") if q.suffix.lower() in suffixes and q.is_file() and not is_machine(q))

    ignored = settings.check.ignore
    active = settings.reading.active
    files: list[Path] = []
    machines: list[Path] = []  # the robot's machine data ($ROBROOT), not a program
    for p in map(Path, paths):
        files += in_directory(p) if p.is_dir() else [p] * (not is_machine(p))
        machines += found_machine(p) if p.is_dir() else [p] * is_machine(p)
    try:
        active = with_machine(active, machines=machines)
    except PostprocError as exc:
        return [exc.diagnostic()]
    configs = [f for f in files if is_config(f)]
    if settings.reading.config is None and configs:
        settings = replace(settings, reading=replace(settings.reading, config=tuple(configs)))
    settings = replace(settings, reading=replace(settings.reading, active=active))
    out: list[Diagnostic] = []
    krl_files = [f for f in files if f.suffix.lower() in KRL]
    others = [p for p in map(Path, paths) if p.is_dir() or (p.suffix.lower() not in KRL and not is_machine(p))]
    if others:  # RAPID tasks, Fanuc LS programs with their backup's files, URScript, pose lists (programs.cell)
        from ..programs.cell import find_cells

        try:  # (a file that cannot be read is a finding of its own; the others are checked)
            cells = [c for c in find_cells(others, settings.reading.config, active, unreadable=out)
                     if c.dialect != "krl"]
        except PostprocError as exc:
            if exc.code != P107 or not krl_files:  # (a directory of KRL files only: read below)
                out.append(exc.diagnostic())
            cells = []
        for cell in cells:
            for part in cell.parts:
                try:
                    program = part.read(settings.reading.config_list, cell.active, settings.reading.registers)
                except PostprocError as exc:
                    out.append(exc.diagnostic())
                    continue
                out += [d for d in check_program(program, model, settings, reachable=reachable)
                        if d.code not in ignored]
    owners = program_paths(krl_files)
    if len(owners) > 1:  # a cell: read as one, as compensate does (globals, calls across modules)
        out += [d for d in _cell_findings(owners, model, settings, reachable) if d.code not in ignored]
        owners = []
    for path in owners:
        if path.suffix.lower() == ".dat" and (is_config(path) or _data_list(path)):
            found = _data_list_findings(path)
        else:
            found = check_file(path, model, settings, reachable=reachable)
        out += [d for d in found if d.code not in ignored]
    return sorted(out, key=lambda d: (d.path, d.line, d.col, d.code))


def _cell_findings(owners: list[Path], model: Compensator, settings: Settings, reachable=None) -> list[Diagnostic]:
    """The findings of KRL modules and data lists checked as one cell (``cell.find_cell``:
    each module with its .dat, one reader call, ``$config.dat`` among them or ``config``)."""
    from ..programs.cell import find_cell

    paths = list(owners) + [d for d in (companion_dat(p) for p in owners if p.suffix.lower() != ".dat") if d]
    try:
        program = find_cell(paths, settings.reading.config_list, settings.reading.active).read()
    except PostprocError as exc:
        return [exc.diagnostic()]
    return check_program(program, model, settings, reachable=reachable)


def _data_list(path: Path) -> bool:
    """A .dat (with no .src beside it) that holds no DEF: a data list, not a program."""
    try:
        text = path.read_bytes().decode("latin-1")
    except OSError:
        return False
    return re.search(r"^[ \t]*(?:GLOBAL[ \t]+)?DEF(?:FCT)?[ \t]", text, re.I | re.M) is None


# --------------------------------------------------------------------------- freshness


def _shown(path: Path) -> str:
    """A path relative to the current directory when it is below it (as git and ruff show it)."""
    try:
        return os.path.relpath(path) if Path(path).resolve().is_relative_to(Path.cwd().resolve()) else str(path)
    except ValueError:  # another drive
        return str(path)


def _first_difference(expected: str, actual: str) -> int:
    n = min(len(expected), len(actual))
    if expected[:n] == actual[:n]:
        return n
    a, b = np.frombuffer(expected[:n].encode("latin-1"), np.uint8), np.frombuffer(actual[:n].encode("latin-1"), np.uint8)
    return int(np.argmax(a != b))


def _stale(program: Program, report, targets: list[Path], shown_src: str, model: Compensator) -> list[Diagnostic]:
    """P406 for each output of ``program`` missing, P405 for each whose bytes are not the new
    texts of ``report`` (at the first differing byte)."""
    stale: list[Diagnostic] = []
    for target, name in zip(targets, program.files):
        expected = report.outputs[name]
        if not target.is_file():
            stale.append(Diagnostic(shown_src, 0, 0, P406, f"no compensated output {_shown(target)} (`postproc check "
                                    "--fresh --fix` writes it)", "error"))
            continue
        actual = target.read_bytes().decode("latin-1")
        if actual != expected:
            line, col = line_col(actual, _first_difference(expected, actual))
            stale.append(Diagnostic(
                _shown(target), line, col, P405,
                f"stale: compensating {_shown(Path(name))} with {model.name} "
                f"{model.sha256[:12]} gives other bytes from here on (`postproc check --fresh --fix` rewrites it)", "error"))
    return stale


def check_fresh(
    settings: Settings,
    model: Compensator,
    *,
    fix: bool = False,
) -> tuple[list[Diagnostic], list[Path]]:
    """Compare every output of ``settings.check.fresh`` with its source compensated in memory
    (with these settings, as ``postproc compensate`` would).

    ``model`` is the configured model (pairs may name their own). With ``fix`` stale and
    missing outputs are written (atomically, with their .dat) instead of reported.
    Returns the findings and the files written.
    """
    if not settings.check.fresh:  # nothing to compare: not an error (a cell that only wants postproc-check)
        return [], []
    ignored = settings.check.ignore
    models: dict[Path | None, Compensator] = {None: model}
    found: list[Diagnostic] = []
    written: list[Path] = []
    for pair in settings.check.fresh:
        if pair.model not in models:
            models[pair.model] = load_model(pair.model)
        pair_model = models[pair.model]
        reading = settings.reading if pair.config is None else replace(settings.reading, config=pair.config)
        for source, output in pair.matches():
            shown_src, shown_out = _shown(source), _shown(output)
            try:
                program = load_program(source, reading.config_list, active=reading.active)
                report = compensate_program(program, pair_model, replace(settings, reading=reading))
            except PostprocError as exc:
                d = exc.diagnostic()
                found.append(Diagnostic(_shown(Path(d.path)) if d.path else shown_src, d.line, d.col, d.code,
                                        f"{d.message} (while compensating it for {shown_out})", "error"))
                continue
            targets = output_paths(program, output)
            stale = _stale(program, report, targets, shown_src, pair_model)
            if stale and fix:
                write_atomic([(t, report.outputs[f]) for t, f in zip(targets, program.files)])
                written += targets
            else:
                found += stale
        found += [Diagnostic(_shown(p), 0, 0, P407, f"no source matches '{pair.source}' for this output",
                             "warning") for p in pair.orphans()]
    found = [d for d in found if d.code not in ignored]
    return sorted(found, key=lambda d: (d.path, d.line, d.col, d.code)), written

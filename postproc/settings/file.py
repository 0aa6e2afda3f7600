"""Project settings: ``[tool.postproc]`` in pyproject.toml, or the same keys at the top of a
``postproc.toml`` (as ruff reads ``[tool.ruff]`` or ``ruff.toml``).

    [tool.postproc]
    model = "models/cell7.onnx"          # the configured model (check compares stamps with it)
    config = "KRC/R1/System/$config.dat" # $config.dat(s) with BASE_DATA / TOOL_DATA
    strict = false                       # warnings count as findings / refuse to compensate
    max_correction = 5.0                 # mm, refuse larger corrections
    iterations = 2                       # fixed-point iterations (default: the model's)
    robot = "KR500-sim"                  # refuse models trained on another robot (unless --force)
    robroot = "KRC/R1/Mada/$machine.dat" # KRL $ROBROOT where a program does not set it: X,Y,Z,A,B,C or machine data
    external = "cell/track.toml"         # external units' kinematics ([[external]] tables: docs/EXTERNAL.md)
    ignore = ["P301"]                    # check: codes not reported
    fresh = [                            # compensated outputs kept in git beside their sources
      { source = "src/*.src", output = "out/*.src" },
      { source = "cell2/**/*.src", output = "out/cell2/**/*.src", model = "models/cell2.onnx" },
    ]

Paths are relative to the directory of the file that holds them. The wildcards of a pair's
``source`` (``*``, ``?``, ``**/``) are carried over, in order, to its ``output``.
Only tomllib and the standard library here: this module decides nothing about models.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

from ..core.diagnostics import P610, PostprocError, toml_error
from ..programs.model import ActiveFrames

# imported where used (a compensate without a settings file does not pay them): tomllib (_read_toml), difflib
# (_unknown), programs.krl.machine (a settings' robroot)

__all__ = ["Config", "FreshPair", "find_config", "load_config", "CONFIG_NAME"]

CONFIG_NAME = "postproc.toml"
KEYS = ("model", "config", "strict", "max_correction", "iterations", "ignore", "fresh", "robot", "base", "tool",
        "robroot", "external")
PAIR_KEYS = ("source", "output", "model", "config")
# a wildcard of a pair pattern; `**/` (any number of directories, also none) comes first
_WILDCARD = re.compile(r"\*\*/|\*\*|\*|\?")


@dataclass(frozen=True)
class FreshPair:
    """A compensated output kept in the repository beside its source (patterns under ``root``)."""

    source: str
    output: str
    root: Path
    model: Path | None = None  # None: the configuration's model
    config: tuple[Path, ...] | None = None  # None: the configuration's $config.dat

    def matches(self) -> list[tuple[Path, Path]]:
        """(source, output) paths for every existing source file, sorted."""
        regex = _pattern_regex(self.source)
        out = []
        for path in sorted(self.root.glob(self.source)):
            m = regex.fullmatch(path.relative_to(self.root).as_posix())
            if m and path.is_file():
                out.append((path, self.root / _substitute(self.output, m.groups())))
        return out

    def orphans(self) -> list[Path]:
        """Existing outputs whose source does not exist."""
        regex = _pattern_regex(self.output)
        out = []
        for path in sorted(self.root.glob(self.output)):
            m = regex.fullmatch(path.relative_to(self.root).as_posix())
            if m and path.is_file() and not (self.root / _substitute(self.source, m.groups())).is_file():
                out.append(path)
        return out


@dataclass
class Config:
    """The settings; ``path`` is the file they came from (None: no file, all defaults)."""

    path: Path | None = None
    model: Path | None = None
    config: tuple[Path, ...] | None = None
    strict: bool = False
    max_correction_mm: float | None = None
    iterations: int | None = None
    robot: str | None = None  # the robot the programs are for: models trained on another are refused
    active: ActiveFrames | None = None  # base / tool / robroot: the $BASE/$TOOL/$ROBROOT where a KRL program does not set them
    ignore: tuple[str, ...] = ()
    fresh: list[FreshPair] = field(default_factory=list)

    @property
    def root(self) -> Path:
        return self.path.parent if self.path is not None else Path.cwd()


def _pattern_regex(pattern: str) -> re.Pattern:
    pieces, pos = [], 0
    for m in _WILDCARD.finditer(pattern):
        pieces.append(re.escape(pattern[pos:m.start()]))
        pieces.append({"**/": "((?:.*/)?)", "**": "(.*)", "*": "([^/]*)", "?": "([^/])"}[m.group()])
        pos = m.end()
    pieces.append(re.escape(pattern[pos:]))
    return re.compile("".join(pieces))


def _substitute(pattern: str, groups: tuple[str, ...]) -> str:
    values = iter(groups)
    return _WILDCARD.sub(lambda m: next(values), pattern)


def _error(message: str, path: Path, key: str = "") -> PostprocError:
    return PostprocError(message + (f" (key '{key}')" if key else ""), str(path), 0, 0, P610)


def _unknown(keys, allowed, path: Path, where: str) -> None:
    import difflib

    for key in keys:
        if key not in allowed:
            close = difflib.get_close_matches(key, allowed, n=1)
            hint = f"; did you mean '{close[0]}'?" if close else f"; known keys: {', '.join(allowed)}"
            raise _error(f"unknown setting '{key}' in {where}{hint}", path)


def _paths(value, root: Path, path: Path, key: str) -> tuple[Path, ...]:
    items = [value] if isinstance(value, str) else value
    if not isinstance(items, list) or not items or not all(isinstance(v, str) for v in items):
        raise _error("expected a path or a list of paths", path, key)
    return tuple(root / v for v in items)


def _pattern(value, path: Path, key: str) -> str:
    if not isinstance(value, str) or not value:
        raise _error("expected a glob pattern such as 'src/*.src'", path, key)
    if "[" in value or value.startswith("/"):
        raise _error("patterns are relative and use only *, ? and **/", path, key)
    return value


def parse_config(table: dict, path: Path) -> Config:
    """Check the keys of a ``[tool.postproc]`` table and resolve its paths."""
    where = "[tool.postproc]" if path.name == "pyproject.toml" else path.name
    _unknown(table, KEYS, path, where)
    root = path.parent
    cfg = Config(path=path)
    if "model" in table:
        if not isinstance(table["model"], str):
            raise _error("expected the path of an ONNX model", path, "model")
        cfg.model = root / table["model"]
    if "config" in table:
        cfg.config = _paths(table["config"], root, path, "config")
    if "strict" in table:
        if not isinstance(table["strict"], bool):
            raise _error("expected true or false", path, "strict")
        cfg.strict = table["strict"]
    if "max_correction" in table:
        value = table["max_correction"]
        if isinstance(value, bool) or not isinstance(value, int | float) or not value > 0:
            raise _error("expected a positive number of mm", path, "max_correction")
        cfg.max_correction_mm = float(value)
    if "iterations" in table:
        value = table["iterations"]
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise _error("expected a whole number ≥ 1", path, "iterations")
        cfg.iterations = value
    if "robot" in table:
        if not isinstance(table["robot"], str) or not table["robot"].strip():
            raise _error("expected the robot's name, as in the model card (e.g. \"KR500-sim\")", path, "robot")
        cfg.robot = table["robot"].strip()
    if "base" in table or "tool" in table or "robroot" in table or "external" in table:
        from ..programs.krl.machine import robroot_option

        external = ()
        if "external" in table:
            if not isinstance(table["external"], str) or not table["external"].strip():
                raise _error("expected the path of a TOML with [[external]] tables", path, "external")
            from ..robot.external import read_external

            external = read_external(root / table["external"])
        try:
            robroot = robroot_option(table.get("robroot"), root, label="robroot =")
            cfg.active = ActiveFrames.of(base=table.get("base"), tool=table.get("tool"), robroot=robroot,
                                         external=external)
        except ValueError as exc:
            raise _error(str(exc), path, str(exc).split(":")[0]) from None
    if "ignore" in table:
        value = table["ignore"]
        if not isinstance(value, list) or not all(isinstance(v, str) and re.fullmatch(r"P\d{3}", v) for v in value):
            raise _error("expected a list of codes such as [\"P301\"]", path, "ignore")
        cfg.ignore = tuple(value)
    pairs = table.get("fresh", [])
    if not isinstance(pairs, list) or not all(isinstance(p, dict) for p in pairs):
        raise _error("expected a list of {source = ..., output = ...} tables", path, "fresh")
    for i, pair in enumerate(pairs):
        key = f"fresh[{i}]"
        _unknown(pair, PAIR_KEYS, path, key)
        if "source" not in pair or "output" not in pair:
            raise _error("each pair needs both 'source' and 'output'", path, key)
        source, output = _pattern(pair["source"], path, key + ".source"), _pattern(pair["output"], path, key + ".output")
        if _WILDCARD.findall(source) != _WILDCARD.findall(output):
            raise _error(f"'{output}' must have the same wildcards in the same order as '{source}'", path, key)
        if not _WILDCARD.search(source):
            raise _error(f"'{source}' has no wildcard: write the single pair as a pattern, e.g. 'src/*.src'", path, key)
        model = pair.get("model")
        if model is not None and not isinstance(model, str):
            raise _error("expected the path of an ONNX model", path, key + ".model")
        cfg.fresh.append(FreshPair(
            source=source,
            output=output,
            root=root,
            model=root / model if model is not None else None,
            config=_paths(pair["config"], root, path, key + ".config") if "config" in pair else None,
        ))
    return cfg


def _read_toml(path: Path) -> dict:
    import tomllib

    try:
        with path.open("rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise PostprocError("no such file", str(path), 0, 0, P610) from None
    except OSError as exc:
        raise PostprocError(f"cannot read: {exc.strerror}", str(path), 0, 0, P610) from None
    except tomllib.TOMLDecodeError as exc:
        raise toml_error(exc, str(path), P610) from None


def _table(path: Path) -> dict | None:
    data = _read_toml(path)
    if path.name == "pyproject.toml":
        tool = data.get("tool", {})
        return tool.get("postproc") if isinstance(tool, dict) else None
    return data


def find_config(start: str | Path | None = None) -> Path | None:
    """The nearest ``postproc.toml``, or ``pyproject.toml`` with a ``[tool.postproc]`` table,
    in ``start`` (default: the current directory) or a directory above it."""
    start = Path(start or Path.cwd()).resolve()
    for folder in (start, *start.parents):
        candidate = folder / CONFIG_NAME
        if candidate.is_file():
            return candidate
        candidate = folder / "pyproject.toml"
        if candidate.is_file() and _table(candidate) is not None:
            return candidate
    return None


def load_config(path: str | Path | None = None, start: str | Path | None = None) -> Config:
    """Read the settings from ``path``, or from the file :func:`find_config` finds; defaults
    (``Config()``) when there is none. Raises PostprocError (P610) on a bad file or key."""
    found = Path(path) if path is not None else find_config(start)
    if found is None:
        return Config()
    table = _table(found)
    if table is None:
        raise PostprocError("no [tool.postproc] table in this file", str(found), 0, 0, P610)
    if not isinstance(table, dict):
        raise PostprocError("[tool.postproc] must be a table", str(found), 0, 0, P610)
    return parse_config(table, found)

"""Project settings from a file: ``[tool.postproc]`` in pyproject.toml, or the same keys at the
top of a ``postproc.toml`` (as ruff reads ``[tool.ruff]`` or ``ruff.toml``).

    [tool.postproc]
    model = "models/cell7.onnx"          # the configured model (check compares stamps with it)
    config = "KRC/R1/System/$config.dat" # $config.dat(s) with BASE_DATA / TOOL_DATA
    strict = false                       # warnings count as findings / refuse to compensate
    max_correction = 5.0                 # mm, refuse larger corrections
    max_std = 0.2                        # mm, warn where the model's own std is larger (P336)
    iterations = 2                       # fixed-point iterations (default: the model's)
    robot = "KR500-sim"                  # the robot: its name, or its description (models/kr500.toml)
    base = 0                             # KRL $BASE where a program does not set it: N or X,Y,Z,A,B,C
    tool = 1                             # KRL $TOOL likewise (or "model")
    robroot = "KRC/R1/Mada/$machine.dat" # KRL $ROBROOT where a program does not set it: X,Y,Z,A,B,C or machine data
    external = "cell/track.toml"         # external units' kinematics ([[external]] tables: docs/EXTERNAL.md)
    ignore = ["P301"]                    # check: codes not reported
    max_mean = 0.1                       # verify / report: limits a cell's CI holds (also max_p95,
                                         # max_max, max_orientation_mean)
    fresh = [                            # compensated outputs kept in git beside their sources
      { source = "src/*.src", output = "out/*.src" },
      { source = "cell2/**/*.src", output = "out/cell2/**/*.src", model = "models/cell2.onnx" },
    ]

Paths are relative to the directory of the file that holds them. The wildcards of a pair's
``source`` (``*``, ``?``, ``**/``) are carried over, in order, to its ``output``. Each key is an
option of ``sections.OPTIONS``, checked by the same check as the command line's flag; a bad
value is refused with P610 at its line.
"""
from __future__ import annotations

from pathlib import Path

from ..core.diagnostics import P610, PostprocError
from ..core.toml import key_line, read_toml
from .sections import FILE_KEYS, OPTIONS, Settings, Source

__all__ = ["SETTINGS_NAME", "find_settings", "load_settings", "read_settings"]

SETTINGS_NAME = "postproc.toml"


class _File(Source):
    """A settings file as the source of option values: errors at the key's line."""

    def __init__(self, path: Path, text: str, table: str | None):
        self.path, self.text, self.table, self.root = path, text, table, path.parent

    def line(self, key: str) -> int:
        return key_line(self.text, self.table, key) or key_line(self.text, f"{self.table}.{key}" if self.table else key)

    def error(self, name: str, message: str) -> PostprocError:
        """A bad value of option ``name``, at its key's line."""
        key = OPTIONS[name].key or name
        return self.at(key, message if message.startswith(f"{key}:") else f"{key} {message}")

    def at(self, key: str, message: str) -> PostprocError:
        line = self.line(key)
        return PostprocError(message, str(self.path), line, 1 if line else 0, P610)


def _table(path: Path) -> tuple[str, dict | None, str | None]:
    """(text, the settings table or None, its TOML table name) of a settings file."""
    text, data = read_toml(path, P610)
    if path.name == "pyproject.toml":
        tool = data.get("tool", {})
        return text, tool.get("postproc") if isinstance(tool, dict) else None, "tool.postproc"
    return text, data, None


def find_settings(start: str | Path | None = None) -> Path | None:
    """The nearest ``postproc.toml``, or ``pyproject.toml`` with a ``[tool.postproc]`` table,
    in ``start`` (default: the current directory) or a directory above it."""
    start = Path(start or Path.cwd()).resolve()
    for folder in (start, *start.parents):
        candidate = folder / SETTINGS_NAME
        if candidate.is_file():
            return candidate
        candidate = folder / "pyproject.toml"
        if candidate.is_file() and _table(candidate)[1] is not None:
            return candidate
    return None


def read_settings(path: str | Path, over: Settings | None = None) -> Settings:
    """The settings of the file at ``path`` (over ``over``, default the defaults); PostprocError
    P610 at the key's line for a bad file, key or value."""
    path = Path(path)
    text, table, name = _table(path)
    if table is None:
        raise PostprocError("no [tool.postproc] table in this file", str(path), 0, 0, P610)
    if not isinstance(table, dict):
        raise PostprocError("[tool.postproc] must be a table", str(path), 0, 0, P610)
    source = _File(path, text, name)
    where = "[tool.postproc]" if path.name == "pyproject.toml" else path.name
    values = {}
    for key, value in table.items():
        if key not in FILE_KEYS:
            import difflib

            close = difflib.get_close_matches(key, list(FILE_KEYS), n=1)
            hint = f"; did you mean '{close[0]}'?" if close else f"; known keys: {', '.join(FILE_KEYS)}"
            raise source.at(key, f"unknown setting '{key}' in {where}{hint}")
        values[FILE_KEYS[key]] = value
    from dataclasses import replace

    return replace(over or Settings(), path=path).apply(values, source)


def load_settings(path: str | Path | None = None, start: str | Path | None = None) -> Settings:
    """The settings of ``path``, or of the file :func:`find_settings` finds from ``start``;
    the defaults (``Settings()``) when there is none."""
    found = Path(path) if path is not None else find_settings(start)
    return Settings() if found is None else read_settings(found)

"""TOML inputs checked one way: read and parsed with located errors, each value checked against
its kind, each key found at its line. Robot descriptions, external units, settings files and
fleet files all go through here (stdlib tomllib, numpy for the vectors)."""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from .diagnostics import PostprocError, toml_error

__all__ = ["read_toml", "parse_toml", "check_value", "key_line"]

_HEADER = re.compile(r"^\[\[?\s*([A-Za-z0-9_.-]+)\s*\]\]?")


def parse_toml(text: str, path: str, code: str) -> dict:
    """The TOML document of ``text``; a syntax error is a PostprocError ``code`` at its line."""
    import tomllib

    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise toml_error(exc, str(path), code) from None


def read_toml(path: str | Path, code: str, what: str = "") -> tuple[str, dict]:
    """(text, document) of a TOML file; unreadable, not UTF-8 or not TOML: PostprocError ``code``
    (``what``: the kind of file, for the message, e.g. "robot description")."""
    path = Path(path)
    head = f"{what}: " if what else ""
    try:
        text = path.read_bytes().decode("utf-8")
    except FileNotFoundError:
        raise PostprocError(f"{head}no such file", str(path), 0, 0, code) from None
    except OSError as exc:
        raise PostprocError(f"cannot read {what or 'it'}: {exc.strerror or exc}", str(path), 0, 0, code) from None
    except UnicodeDecodeError as exc:
        raise PostprocError(f"{head}not UTF-8 text: {exc.reason}", str(path), 0, 0, code) from None
    return text, parse_toml(text, str(path), code)


def check_value(kind: str, value, where: str, fail) -> object:
    """``value`` as ``kind``: "str", "int", "num" (a finite number), "bool" or "vec:n" (n finite
    numbers, as a float array); else raise ``fail(message)``."""
    if kind == "str":
        if not isinstance(value, str):
            raise fail(f"{where} must be text, got {value!r}")
        return value
    if kind == "bool":
        if not isinstance(value, bool):
            raise fail(f"{where} must be true or false, got {value!r}")
        return value
    if kind == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            raise fail(f"{where} must be an integer, got {value!r}")
        return value
    if kind == "num":
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise fail(f"{where} must be a finite number, got {value!r}")
        return float(value)
    n = int(kind.split(":")[1])
    ok = isinstance(value, list) and len(value) == n and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)
    if not ok:
        raise fail(f"{where} must be a list of {n} finite numbers, got {value!r}")
    return np.asarray(value, dtype=float)


def key_line(text: str, table: str | None, key: str | None = None, index: int = 0) -> int:
    """The 1-based line of ``key`` in the ``index``-th ``[table]`` / ``[[table]]`` of ``text``
    (``key`` None: the table's header; ``table`` None: the keys before the first header); 0 where
    it is not found."""
    current, seen = None, {}
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        head = _HEADER.match(line)
        if head:
            current = head.group(1)
            seen[current] = seen.get(current, -1) + 1
            if key is None and table is not None and current.startswith(table + ".") and index == 0:
                return number  # (a dotted table: [uframe.1] under "uframe")
            if key is None and current == table and seen[current] == index:
                return number
            continue
        if key is not None and current == table and (table is None or seen.get(table) == index):
            if re.match(rf"^[\"']?{re.escape(key)}[\"']?\s*=", line):
                return number
    return 0

"""The benchmark figures of the README and the docs against the results the benchmarks wrote.

    python benchmarks/figures.py [--update] [--list] [FILE.md ...]

Default: every Markdown file of the repository that holds a marker (README.md, docs/**.md,
models/README.md, samples/**/README.md, ...; not .venv/, site/, build/ or other hidden and
generated folders); --list prints them.

A figure taken from a benchmark is written with a marker right after it, invisible in the
rendered page: ``2,535<!-- fig fuzz.outputs -->`` = the value ``figures.outputs`` of
``benchmarks/results/fuzz.json``, shown with the decimals and thousands separators written.
Without --update: lists every figure that differs from its result (or whose result is missing)
and exits 1 if any does. With --update: writes the results' values in place of the figures.
"""
from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results"
FIGURE = re.compile(r"(?P<number>-?\d[\d,]*(?:\.\d+)?)<!-- fig (?P<name>[\w-]+)\.(?P<key>[\w.]+) -->")


def _value(name: str, key: str):
    path = RESULTS / f"{name}.json"
    if not path.is_file():
        return None
    value = json.loads(path.read_text())["figures"]
    for part in key.split("."):
        if not isinstance(value, dict) or part not in value:
            return None
        value = value[part]
    return value


def _shown(value: float, like: str) -> str:
    """``value`` written as ``like`` is: its decimals, its thousands separators."""
    decimals = len(like.partition(".")[2])
    return f"{value:{',' if ',' in like else ''}.{decimals}f}"


def figures(text: str) -> list[tuple[re.Match, str | None]]:
    """Each figure of ``text`` and the text its result gives (None: no such result)."""
    out = []
    for m in FIGURE.finditer(text):
        value = _value(m.group("name"), m.group("key"))
        out.append((m, None if not isinstance(value, int | float) else _shown(value, m.group("number"))))
    return out


SKIPPED = {"site", "build", "dist", "node_modules", "__pycache__"}  # generated folders (and hidden ones: .venv, .git)


def marked_files(root: Path = ROOT) -> list[Path]:
    """Every Markdown file below ``root`` that holds a figure marker, in path order."""
    found = []
    for path in sorted(root.rglob("*.md")):
        parts = path.relative_to(root).parts[:-1]
        if any(part.startswith(".") or part in SKIPPED or part.endswith(".egg-info") for part in parts):
            continue
        if "<!-- fig " in path.read_text(errors="replace"):
            found.append(path)
    return found


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs="*", type=Path, help="default: every Markdown file that holds a marker")
    parser.add_argument("--update", action="store_true", help="write the results' values into the files")
    parser.add_argument("--list", action="store_true", help="print the files checked, one a line, and stop")
    args = parser.parse_args(argv)
    files = args.files or marked_files()
    if args.list:
        print("\n".join(str(p.relative_to(ROOT) if p.is_relative_to(ROOT) else p) for p in files))
        return 0
    bad = 0
    for path in files:
        text = path.read_text()
        found = figures(text)
        for m, shown in found:
            if shown != m.group("number"):
                line = text.count("\n", 0, m.start()) + 1
                where = f"{path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}:{line}"
                if shown is None:
                    print(f"{where}: no result {m.group('name')}.{m.group('key')} in {RESULTS.relative_to(ROOT)}")
                    bad += 1
                elif not args.update:
                    print(f"{where}: {m.group('number')}, the result {m.group('name')}.{m.group('key')} is {shown}")
                    bad += 1
        if args.update:
            new = FIGURE.sub(_replace, text)
            if new != text:
                path.write_text(new)
                print(f"updated {path}")
    return 1 if bad else 0


def _replace(m: re.Match) -> str:
    value = _value(m.group("name"), m.group("key"))
    shown = _shown(value, m.group("number")) if isinstance(value, int | float) else m.group("number")
    return f"{shown}<!-- fig {m.group('name')}.{m.group('key')} -->"


if __name__ == "__main__":
    sys.exit(main())

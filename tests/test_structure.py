"""Imports go one way (docs/ARCHITECTURE.md, "Layers"): a module imports its own package and the
packages on lower lines, never a package on its own line or above; inside ``programs`` and
``robot`` the modules keep their own order; and no import cycle between modules anywhere.

What counts as an import: ``import a.b``, every name of ``from x import a, b`` (a name that is a
module is an arrow to that module, any other an arrow to the module it comes from), and
``importlib.import_module`` calls (an f-string's literal prefix stands for every module under
it), at module level or inside functions; a module importing its own package counts like any
other (the package's ``__init__`` is a module); imports under ``if TYPE_CHECKING:`` do not
count (they never run)."""
from __future__ import annotations

import ast
from dataclasses import dataclass

import pytest

from helpers import REPO

# Lines from the bottom up; a package imports only packages on lower lines.
LAYERS = [
    ["core"],
    ["robot"],
    ["programs", "measurements"],
    ["settings"],
    ["model"],
    ["compensation", "calibration"],
    ["acceptance"],
    ["fleet"],
    ["postproc"],  # the public face, postproc/__init__.py
    ["cli"],
    ["__main__"],
    ["testing"],
]

# Inside a package: lines of modules, bottom up; a name covers the modules under it (``krl``: the
# dialect's package). A module imports modules on lower lines; on its own line only modules of its
# own group (a tuple: modules that work together; each dialect's modules among themselves). Modules
# not listed are free (cycles still fail).
INNER = {
    "programs": [
        ["model", "text", "grammar", "ir", "rewrite"],
        ["analysis"],
        ["krl", "rapid", "urscript", "fanuc", "poses"],  # each dialect independent of the others
        [("io", "programs", "cell", "base_poses", "locate")],  # the only modules that name a dialect
        ["interpreter"],
    ],
    "robot": [
        [("external", "description")],
        ["kinematics"],
        ["arm", "urdf", "approach"],
        [("configuration", "conventions")],
    ],
}
# model.training may import model.*; the runtime never imports model.training.
FORBIDDEN = [("postproc.model", "postproc.model.training")]


@dataclass(frozen=True)
class Arrow:
    source: str  # module
    target: str  # module
    path: str  # file of the source, relative to the repository
    line: int
    names: tuple[str, ...]


def _modules(root) -> dict[str, object]:
    """Dotted module name → path, for every .py under ``root`` (a package directory)."""
    out = {}
    for path in sorted(root.rglob("*.py")):
        parts = list(path.relative_to(root.parent).with_suffix("").parts)
        out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return out


def _type_checking(node) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _nodes(tree):
    """Every node but those under ``if TYPE_CHECKING:``."""
    stack = [tree]
    while stack:
        node = stack.pop()
        yield node
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and _type_checking(child):
                stack.extend(child.orelse)
                continue
            stack.append(child)


def _literal_prefix(arg) -> tuple[str, bool] | None:
    """(text, exact) of import_module's first argument: a constant, or an f-string's literal prefix."""
    if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
        return arg.value, True
    if isinstance(arg, ast.JoinedStr):
        prefix = ""
        for part in arg.values:
            if isinstance(part, ast.Constant):
                prefix += part.value
            else:
                break
        return prefix, False
    return None


def arrows(modules: dict[str, object], root_name: str = "postproc") -> list[Arrow]:
    """Every import arrow between the modules (``modules``: name → path)."""
    found = []
    top = modules[root_name].parent.parent  # (the folder that holds the package: paths are shown from it)
    for name, path in modules.items():
        is_package = path.name == "__init__.py"
        package = name.split(".") if is_package else name.split(".")[:-1]
        rel = str(path.relative_to(top))

        def resolve(level: int, module: str | None) -> str:
            if not level:
                return module or ""
            base = package[: len(package) - level + 1]
            return ".".join(base + ([module] if module else []))

        def owner(target: str) -> str | None:
            while target and target not in modules:
                target = target.rpartition(".")[0]
            return target or None

        def add(target, node, names):
            if target is not None and target != name:
                found.append(Arrow(name, target, rel, node.lineno, tuple(names)))

        tree = ast.parse(path.read_text())
        for node in _nodes(tree):
            if isinstance(node, ast.Import):
                for alias in node.names:
                    add(owner(alias.name), node, [alias.name])
            elif isinstance(node, ast.ImportFrom):
                base = resolve(node.level, node.module)
                for alias in node.names:
                    full = f"{base}.{alias.name}"
                    add(full if full in modules else owner(base), node, [alias.name])
            elif isinstance(node, ast.Call) and node.args and (
                    (isinstance(node.func, ast.Attribute) and node.func.attr == "import_module")
                    or (isinstance(node.func, ast.Name) and node.func.id == "import_module")):
                literal = _literal_prefix(node.args[0])
                if literal is None:
                    continue
                text, exact = literal
                if text.startswith("."):
                    level = len(text) - len(text.lstrip("."))
                    anchor = node.args[1] if len(node.args) > 1 else None
                    # import_module(".x", __name__ / __package__): relative to this module's package
                    base_parts = name.split(".") if (is_package or (isinstance(anchor, ast.Name) and
                                                                   anchor.id == "__package__")) else package
                    text = ".".join(base_parts[: len(base_parts) - level + 1]) + "." + text.lstrip(".")
                elif text.startswith("{") or not text:
                    continue
                text = text.rstrip(".")
                if exact:
                    add(owner(text), node, [text])
                else:
                    under = [m for m in modules if m == text or m.startswith(text + ".") or
                             (not literal[0].endswith(".") and m.startswith(text))]
                    for m in under:
                        add(m, node, [literal[0] + "…"])
                    if not under:
                        add(owner(text), node, [literal[0] + "…"])
    return found


def package_of(module: str) -> str:
    parts = module.split(".")
    return parts[0] if len(parts) == 1 else parts[1]


def _line(package: str) -> int:
    for i, line in enumerate(LAYERS):
        if package in line:
            return i
    raise KeyError(package)


def _inner_line(package: str, module: str) -> tuple[int, str] | None:
    """(line, group: its first name) of a module inside ``package``'s INNER order, or None (not listed)."""
    rest = module.split(".")[2:] if module.count(".") >= 2 else [package]
    if module == f"postproc.{package}":
        rest = [package]
    for i, line in enumerate(INNER.get(package, [])):
        for group in line:
            names = group if isinstance(group, tuple) else (group,)
            if rest and rest[0] in names:
                return i, names[0]
    return None


def violations(found: list[Arrow]) -> list[tuple[Arrow, str]]:
    """The arrows that go up or sideways, with why."""
    bad = []
    for a in found:
        sp, tp = package_of(a.source), package_of(a.target)
        if sp != tp:
            try:
                s, t = _line(sp), _line(tp)
            except KeyError as exc:
                bad.append((a, f"package {exc} is on no line of LAYERS"))
                continue
            if t > s:
                bad.append((a, f"{sp} (line {s}) imports {tp} (line {t}): up"))
            elif t == s:
                bad.append((a, f"{sp} and {tp} are on one line: sideways"))
            continue
        s, t = _inner_line(sp, a.source), _inner_line(sp, a.target)
        if s is not None and t is not None:
            if t[0] > s[0]:
                bad.append((a, f"in {sp}: {s[1]} (line {s[0]}) imports {t[1]} (line {t[0]}): up"))
            elif t[0] == s[0] and t[1] != s[1]:
                bad.append((a, f"in {sp}: {s[1]} and {t[1]} are on one line: sideways"))
        for low, high in FORBIDDEN:
            if (a.source == low or a.source.startswith(low + ".")) and not (
                    a.source == high or a.source.startswith(high + ".")) and (
                    a.target == high or a.target.startswith(high + ".")):
                bad.append((a, f"{low} must not import {high}"))
    return bad


def cycles(found: list[Arrow]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    graph: dict[str, set[str]] = {}
    for a in found:
        graph.setdefault(a.source, set()).add(a.target)
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def package_graph(found: list[Arrow], bad: list[tuple[Arrow, str]]) -> str:
    """The packages by line, top down, each with the packages it imports; ✗ marks an offending arrow."""
    edges: dict[str, set[str]] = {}
    for a in found:
        sp, tp = package_of(a.source), package_of(a.target)
        if sp != tp:
            edges.setdefault(sp, set()).add(tp)
    marked = {(package_of(a.source), package_of(a.target)) for a, _ in bad}
    lines = []
    for i in range(len(LAYERS) - 1, -1, -1):
        for p in LAYERS[i]:
            targets = sorted(edges.get(p, ()), key=lambda t: (-_line(t) if t in sum(LAYERS, []) else 99, t))
            shown = ", ".join(("✗ " if (p, t) in marked else "") + t for t in targets)
            lines.append(f"  {i:>2} {p:<13} → {shown}")
    return "\n".join(lines)


def report(found: list[Arrow], bad: list[tuple[Arrow, str]]) -> str:
    out = ["imports that go up or sideways:"]
    names: dict[tuple, list[str]] = {}
    for a, why in bad:  # (one line per statement and target, with every name it imports)
        names.setdefault((a.path, a.line, a.source, a.target, why), []).extend(a.names)
    for (path, line, source, target, why), imported in names.items():
        out.append(f"  {path}:{line}: {source} → {target} ({', '.join(imported)}): {why}")
    out.append("the package graph, top line first (✗: an offending arrow):")
    out.append(package_graph(found, bad))
    return "\n".join(out)


@pytest.fixture(scope="module")
def found():
    return arrows(_modules(REPO / "postproc"))


def test_imports_go_one_way(found):
    bad = violations(found)
    assert not bad, report(found, bad)


def test_no_import_cycle(found):
    assert cycles(found) == []


def test_every_package_is_on_a_line(found):
    packages = {package_of(m) for m in _modules(REPO / "postproc")}
    assert packages <= set(sum(LAYERS, [])), packages - set(sum(LAYERS, []))


def test_the_top_of_postproc_holds_only_its_face():
    top = sorted(p.name for p in (REPO / "postproc").glob("*.py"))
    assert top == ["__init__.py", "__main__.py"]


# --------------------------------------------------------------------------- the check checks


def _package(tmp_path, files: dict[str, str]):
    root = tmp_path / "postproc"
    for rel, text in files.items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return _modules(root)


def test_every_name_of_a_from_import_is_an_arrow(tmp_path):
    modules = _package(tmp_path, {
        "__init__.py": "", "core/__init__.py": "", "core/a.py": "", "core/b.py": "",
        "robot/__init__.py": "", "robot/arm.py": "from ..core import a, b\n"})
    targets = {a.target for a in arrows(modules) if a.source == "postproc.robot.arm"}
    assert targets == {"postproc.core.a", "postproc.core.b"}


def test_a_module_importing_its_package_is_an_arrow_and_a_cycle(tmp_path):
    modules = _package(tmp_path, {
        "__init__.py": "", "programs/__init__.py": "from .poses import read\n",
        "programs/poses.py": "from . import STAMP\ndef read(): pass\n"})
    found = arrows(modules)
    assert Arrow("postproc.programs.poses", "postproc.programs", "", 1, ("STAMP",)).target in {
        a.target for a in found if a.source == "postproc.programs.poses"}
    assert cycles(found) == [["postproc.programs", "postproc.programs.poses"]]
    bad = violations(found)
    assert [(a.source, a.target) for a, _ in bad] == [("postproc.programs.poses", "postproc.programs")]


def test_import_module_with_an_f_string_reaches_every_module_under_its_prefix(tmp_path):
    modules = _package(tmp_path, {
        "__init__.py": "", "core/__init__.py": "",
        "core/x.py": "import importlib\ndef f(n):\n    return importlib.import_module(f'postproc.cli.{n}')\n",
        "cli/__init__.py": "", "cli/train.py": "", "cli/check.py": ""})
    found = arrows(modules)
    assert {a.target for a in found if a.source == "postproc.core.x"} >= {"postproc.cli.train", "postproc.cli.check"}
    bad = violations(found)
    assert bad and all("up" in why for _, why in bad)


def test_type_checking_imports_do_not_count(tmp_path):
    modules = _package(tmp_path, {
        "__init__.py": "", "core/__init__.py": "", "cli/__init__.py": "",
        "core/x.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from ..cli import main\n"})
    assert [a for a in arrows(modules) if a.source == "postproc.core.x"] == []


def test_a_failure_draws_the_package_graph_with_the_arrow_its_place_and_names(tmp_path):
    modules = _package(tmp_path, {
        "__init__.py": "", "core/__init__.py": "", "core/units.py": "\n\nfrom ..robot.arm import Robot, MM\n",
        "robot/__init__.py": "", "robot/arm.py": "from ..core import units\n"})
    found = arrows(modules)
    bad = violations(found)
    text = report(found, bad)
    assert "postproc/core/units.py:3: postproc.core.units → postproc.robot.arm (Robot, MM)" in text
    assert "core          → ✗ robot" in text
    assert "robot         → core" in text


def test_an_inner_order_is_kept(tmp_path):
    modules = _package(tmp_path, {
        "__init__.py": "", "programs/__init__.py": "",
        "programs/krl/__init__.py": "from ..rapid import syntax\n", "programs/rapid/__init__.py": "",
        "programs/rapid/syntax.py": "", "programs/analysis/__init__.py": "from ..interpreter import run\n",
        "programs/interpreter.py": "def run(): pass\n"})
    why = {(a.source, a.target): w for a, w in violations(arrows(modules))}
    assert "sideways" in why[("postproc.programs.krl", "postproc.programs.rapid.syntax")]
    assert "up" in why[("postproc.programs.analysis", "postproc.programs.interpreter")]

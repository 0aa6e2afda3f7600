"""Data flows one way (docs/ARCHITECTURE.md): no import cycle between postproc's modules,
counting the lazy imports inside functions too."""
import ast

from helpers import REPO

# cycles known and tolerated (none left: cli/train and cli/train_hybrid went with issue 16 item 2)
KNOWN: set[frozenset[str]] = set()


def _module(path) -> str:
    parts = list(path.relative_to(REPO).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_graph() -> dict[str, set[str]]:
    """Module → the postproc modules it imports (at module level or in a function)."""
    paths = {_module(p): p for p in (REPO / "postproc").rglob("*.py")}
    graph = {}
    for name, path in paths.items():
        package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
        deps = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                base = ".".join(package[: len(package) - node.level + 1] + [node.module or ""]).strip(".") \
                    if node.level else (node.module or "")
                targets = [f"{base}.{a.name}" for a in node.names] + [base]
            elif isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            else:
                continue
            for target in targets:
                while target and target not in paths:
                    target = target.rpartition(".")[0]
                # (a package importing its own submodules, or a module its package, is no cycle)
                if target and target != name and not name.startswith(target + "."):
                    deps.add(target)
                    break
        graph[name] = deps
    return graph


def cycles(graph: dict[str, set[str]]) -> list[frozenset[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = set()
            while True:
                w = stack.pop()
                on.discard(w)
                component.add(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(frozenset(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_no_import_cycle():
    assert [sorted(c) for c in cycles(import_graph()) if c not in KNOWN] == []


def test_the_cycle_finder_finds_a_cycle():
    graph = import_graph()
    assert "postproc.outputs" in graph["postproc.compensate"]
    graph["postproc.outputs"] = graph["postproc.outputs"] | {"postproc.compensate"}  # as it was
    assert frozenset({"postproc.compensate", "postproc.outputs"}) in cycles(graph)

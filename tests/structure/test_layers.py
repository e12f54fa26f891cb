"""Layering: a lower layer never imports a higher one (DEVELOPERS guide), and the case layer
(cases/, setup/, runs/) has no import cycle."""

import ast
from pathlib import Path

import polypore

ORDER = ["core", "mesh", "parallel", "discretisation", "assembly", "solvers", "models", "io", "cases", "setup", "runs", "cli"]
CASE_LAYER = ("cases", "setup", "runs")
ROOT = Path(polypore.__file__).parent


def _layer(module: str) -> int | None:
    head = module.split(".")[0]
    return ORDER.index(head) if head in ORDER else None


def _imports(path: Path) -> list[str]:
    """Modules (relative to the package, e.g. ``setup.casefile``) that a file imports, at any depth
    of its syntax tree (an import inside a function is still a dependency)."""
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:  # relative: resolve against the package of this file
                pkg = parts[:-1]
                base = pkg[: len(pkg) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
                # ``from . import x`` imports the submodule x when there is one
                out += [f"{mod}.{a.name}" if mod else a.name for a in node.names] if not node.module else [mod]
            elif node.module and node.module.startswith("polypore."):
                out.append(node.module[len("polypore."):])
        elif isinstance(node, ast.Import):
            out += [a.name[len("polypore."):] for a in node.names if a.name.startswith("polypore.")]
    return out


def _modules() -> dict[str, Path]:
    return {".".join(p.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__"): p
            for p in ROOT.rglob("*.py")}


def test_no_upward_imports():
    bad = []
    for name, path in _modules().items():
        here = _layer(name) if name not in ("__init__", "__main__") else None
        if here is None:
            continue
        for t in _imports(path):
            there = _layer(t)
            if there is not None and there > here:
                bad.append(f"{name} imports {t}")
    assert not bad, "upward imports: " + "; ".join(bad)


def test_no_import_cycle_in_the_case_layer():
    modules = _modules()
    layer = {m: p for m, p in modules.items() if m.split(".")[0] in CASE_LAYER}
    graph = {m: sorted({t for t in _imports(p) if t in layer and t != m}) for m, p in layer.items()}
    # depth-first search for a back edge; report the cycle it closes
    state, stack, cycles = {}, [], []

    def visit(m):
        state[m] = "open"
        stack.append(m)
        for t in graph[m]:
            if state.get(t) == "open":
                cycles.append(" → ".join(stack[stack.index(t):] + [t]))
            elif t not in state:
                visit(t)
        stack.pop()
        state[m] = "done"

    for m in sorted(graph):
        if m not in state:
            visit(m)
    assert not cycles, "import cycles: " + "; ".join(cycles)
    # the graph is not empty: the test would pass vacuously if the imports were not found
    assert "setup.casefile" in graph["runs.static"] and "runs.static" in graph["runs.dispatch"]


def test_cases_holds_data_and_solutions_only():
    """cases/ is the built-in data and exact solutions: it imports no part of the case layer above it."""
    for name, path in _modules().items():
        if name.split(".")[0] == "cases":
            assert not [t for t in _imports(path) if t.split(".")[0] in ("setup", "runs", "cli")], name


def test_layer_packages_exist():
    present = {p.name for p in ROOT.iterdir() if p.is_dir() and (p / "__init__.py").exists()}
    assert set(ORDER) - {"cli"} <= present

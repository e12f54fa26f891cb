"""Layering: a lower layer never imports a higher one (DEVELOPERS guide)."""

import ast
from pathlib import Path

import polypore

ORDER = ["core", "mesh", "discretisation", "assembly", "solvers", "models", "io", "cases", "cli"]
ROOT = Path(polypore.__file__).parent


def _layer(module: str) -> int | None:
    head = module.split(".")[0]
    return ORDER.index(head) if head in ORDER else None


def test_no_upward_imports():
    bad = []
    for path in ROOT.rglob("*.py"):
        rel = path.relative_to(ROOT).with_suffix("")
        parts = rel.parts
        here = _layer(parts[0]) if parts[0] not in ("__init__", "__main__") else None
        if here is None:
            continue
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            targets = []
            if isinstance(node, ast.ImportFrom):
                if node.level:  # relative: resolve against the package of this file
                    pkg = list(parts[:-1])
                    base = pkg[: len(pkg) - (node.level - 1)] if node.level > 1 else pkg
                    mod = ".".join(base + ([node.module] if node.module else []))
                    targets = [mod] if mod else [n.name for n in node.names]
                elif node.module and node.module.startswith("polypore."):
                    targets = [node.module[len("polypore."):]]
            elif isinstance(node, ast.Import):
                targets = [a.name[len("polypore."):] for a in node.names if a.name.startswith("polypore.")]
            for t in targets:
                there = _layer(t)
                if there is not None and there > here:
                    bad.append(f"{rel} imports {t}")
    assert not bad, "upward imports: " + "; ".join(bad)


def test_layer_packages_exist():
    present = {p.name for p in ROOT.iterdir() if p.is_dir() and (p / "__init__.py").exists()}
    assert {"core", "mesh", "io", "cases"} <= present

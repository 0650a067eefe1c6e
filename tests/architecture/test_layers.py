"""The package layering of DESIGN.md section 1, checked on the source with ``ast``.

Packages are ranked in data-flow order; a module may import its own package and packages of a
lower rank only, no import cycle may exist between project modules (function-level imports count
too), and no ``except ImportError`` fallback may hide a missing module.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest
import tomllib

from tests.conftest import REPO

LAYERS = (
    "proxplan.fileio",  # user errors, reading user files, atomic writes
    "proxplan.fanout",  # independent tasks on Dask (local cluster or an existing one)
    "proxplan.physics",  # vehicles, velocity field, disturbance, authority, effects
    "proxplan.costmaps",  # cutoff maps and wrench tables
    "proxplan.identify",  # flight logs -> measured disturbance -> calibrated model
    "proxplan.planfile",  # scenario YAML and plan.json contracts
    "proxplan.verify",  # independent plan checks
    "proxplan.planner",  # sampling, optimisation, timing
    "proxplan.flightsim",  # closed-loop simulation
    "proxplan.certify",  # Monte-Carlo closed-loop flights on Dask
    "proxplan.export",  # flyable files (Crazyflie polynomials, set-points)
    "proxplan.web",  # review app
    "proxplan",  # CLI (proxplan.cli, proxplan.commands)
)
RANK = {name: i for i, name in enumerate(LAYERS)}


def layer(module: str) -> str:
    """The layer (package of LAYERS) a dotted project module belongs to."""
    head = ".".join(module.split(".")[:2])
    return head if head in RANK else "proxplan"


def _modules() -> dict[str, Path]:
    """Every project module by its installed dotted name (pyproject.toml's package-dir mapping)."""
    with open(REPO / "pyproject.toml", "rb") as fh:
        package_dir = tomllib.load(fh)["tool"]["setuptools"]["package-dir"]
    out = {}
    for package, folder in package_dir.items():
        for path in sorted((REPO / folder).rglob("*.py")):
            rel = path.relative_to(REPO / folder).with_suffix("").parts
            parts = tuple(package.split(".")) + rel
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = path
    return out


MODULES = _modules()


def _resolve(name: str) -> str | None:
    """The project module an import of ``name`` loads (its longest known prefix), or None."""
    parts = name.split(".")
    while parts:
        candidate = ".".join(parts)
        if candidate in MODULES:
            return candidate
        parts.pop()
    return None


def _imports(module: str) -> set[str]:
    tree = ast.parse(MODULES[module].read_text())
    package = module if MODULES[module].name == "__init__.py" else module.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                anchor = anchor[: len(anchor) - (node.level - 1)]
                base = ".".join(anchor + ([base] if base else []))
            # "from pkg import sub" loads pkg.sub; "from pkg import name" loads pkg itself. Inside pkg,
            # "from pkg import sub" also counts as importing pkg: it reads like a use of pkg's public
            # API, which re-exports its modules; siblings import each other as "pkg.sub" instead
            subs = [f"{base}.{a.name}" for a in node.names if f"{base}.{a.name}" in MODULES]
            own_package = module.startswith(base + ".")
            targets = subs + ([base] if len(subs) < len(node.names) or own_package else [])
        else:
            continue
        for target in targets:
            resolved = _resolve(target)
            if resolved is not None and resolved != module:
                found.add(resolved)
    return found


GRAPH = {m: _imports(m) for m in MODULES}


def test_every_package_is_found():
    for package in LAYERS:
        assert package in MODULES, f"{package}: __init__.py missing"


@pytest.mark.parametrize("module", sorted(MODULES))
def test_imports_only_downwards(module):
    own = RANK[layer(module)]
    upward = sorted(t for t in GRAPH[module] if RANK[layer(t)] > own)
    assert not upward, f"{module} imports a higher layer: {upward}"


def test_no_import_cycle():
    # Tarjan's strongly connected components; any component of more than one module is a cycle
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in GRAPH[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in GRAPH:
        if v not in index:
            visit(v)
    assert not cycles, f"import cycles: {cycles}"


def test_cycle_detector_finds_a_planted_cycle():
    saved = dict(GRAPH)
    try:
        GRAPH["proxplan.physics.vehicles"] = GRAPH["proxplan.physics.vehicles"] | {"proxplan.physics.disturbance"}
        with pytest.raises(AssertionError, match="import cycles"):
            test_no_import_cycle()
    finally:
        GRAPH.clear()
        GRAPH.update(saved)


@pytest.mark.parametrize("module", sorted(MODULES))
def test_no_import_error_fallback(module):
    tree = ast.parse(MODULES[module].read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.ExceptHandler) and node.type is not None:
            names = [n.id for n in ast.walk(node.type) if isinstance(n, ast.Name)]
            assert not {"ImportError", "ModuleNotFoundError"} & set(names), (
                f"{module}:{node.lineno}: except ImportError hides a missing module"
            )


def test_packages_are_used_through_their_public_api():
    """Across packages, code imports names from the package (its __init__), not deep modules."""
    deep = []
    for module in MODULES:
        own = layer(module)
        tree = ast.parse(MODULES[module].read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module and not node.level:
                top = layer(node.module)
                if node.module.startswith("proxplan") and top != own and node.module != top:
                    deep.append(f"{module}:{node.lineno}: from {node.module}")
    assert not deep, "deep cross-package imports:\n" + "\n".join(deep)

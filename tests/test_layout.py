"""The package's layout, read from its source with ``ast``: imports flow one way (no cycle between
modules, function-level imports included), and the analysis drivers never probe a problem for
attributes (the problem protocol of jointfem.hbm.problem says what every problem has)."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[1] / "jointfem"


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(PKG.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in PKG.rglob("*.py")}


def _resolve(module: str, is_package: bool, node: ast.ImportFrom) -> str:
    if node.level == 0:
        return node.module or ""
    base = module.split(".") if is_package else module.split(".")[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def import_graph() -> dict[str, set[str]]:
    """module -> jointfem modules it imports anywhere in its body (top level or inside functions).
    ``from pkg import name`` counts as an import of ``pkg.name`` when that is a module, else of
    ``pkg``; importing a module does not count as importing its parent packages' __init__."""
    mods = _modules()
    graph: dict[str, set[str]] = {}
    for name, path in mods.items():
        is_pkg = path.name == "__init__.py"
        deps: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = _resolve(name, is_pkg, node)
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in mods else base for a in node.names]
            else:
                continue
            deps.update(t for t in targets if t in mods and t != name)
        graph[name] = deps
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import cycle as [a, b, ..., a], or None (iterative depth-first search)."""
    colour = dict.fromkeys(graph, 0)  # 0 new, 1 on the stack, 2 done
    for start in graph:
        if colour[start]:
            continue
        stack = [(start, iter(sorted(graph[start])))]
        colour[start] = 1
        while stack:
            node, it = stack[-1]
            nxt = next(it, None)
            if nxt is None:
                colour[node] = 2
                stack.pop()
            elif colour[nxt] == 1:
                path = [n for n, _ in stack]
                return path[path.index(nxt):] + [nxt]
            elif colour[nxt] == 0:
                colour[nxt] = 1
                stack.append((nxt, iter(sorted(graph[nxt]))))
    return None


def test_cycle_finder_finds_a_planted_cycle():
    """The checker itself can fail: a cycle through a function-level import is found."""
    g = import_graph()
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set()}) == ["a", "b", "c", "a"]
    assert g["jointfem.cli"], "the graph sees the CLI's imports"
    g["jointfem.harmonics"] = g["jointfem.harmonics"] | {"jointfem.cli"}
    assert find_cycle(g) is not None


def test_no_import_cycles():
    cycle = find_cycle(import_graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


@pytest.mark.parametrize("module, below", [
    ("jointfem.harmonics", ()),  # the bottom layer
    ("jointfem.contact", ("jointfem.harmonics",)),
    ("jointfem.continuation", ()),
    ("jointfem.hbm", ("jointfem.harmonics", "jointfem.contact", "jointfem.models.structure",
                      "jointfem.continuation", "jointfem.linalg")),
])
def test_low_layers_import_only_what_is_below(module, below):
    """harmonics imports nothing of jointfem; contact only harmonics; the HBM layer only the layers
    below it (no ROM, no analysis, no CLI)."""
    g = import_graph()
    for mod, deps in g.items():
        if mod == module or mod.startswith(module + "."):
            bad = {d for d in deps if not (d == module or d.startswith(module + ".")
                                           or any(d == b or d.startswith(b + ".") for b in below))}
            assert not bad, f"{mod} imports {sorted(bad)}"


PROBES = ("hasattr", "getattr")


def _probes(path: Path) -> list[str]:
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in PROBES:
            out.append(f"{path.name}:{node.lineno}: {node.func.id}")
    return out


def test_probe_finder_finds_a_planted_probe(tmp_path):
    f = tmp_path / "driver.py"
    f.write_text("def run(problem):\n    if hasattr(problem, 'mask'):\n        return getattr(problem, 'x', 0)\n")
    assert _probes(f) == ["driver.py:2: hasattr", "driver.py:3: getattr"]


def test_drivers_do_not_probe_problems():
    """The analyses, the continuation, the library layer and the CLI use the problem protocol, never
    hasattr/getattr on the objects they are handed."""
    files = [*sorted((PKG / "analysis").glob("*.py")), *sorted((PKG / "continuation").glob("*.py")),
             PKG / "app.py", PKG / "cli.py", PKG / "hbm" / "problem.py"]
    assert all(f.exists() for f in files), [str(f) for f in files if not f.exists()]
    found = [p for f in files for p in _probes(f)]
    assert not found, found

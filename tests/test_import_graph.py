"""The packages' import graph has no cycle, and every module imports on its own.

The graph is read from the source with ``ast``: every ``import`` and ``from ... import``
statement counts, including those inside functions (a function-local import is a real edge:
it runs when the function does), and any ``importlib.import_module``/``__import__`` call in
``studio/`` is refused outright, so that no edge hides from this test. ``engine`` imports
nothing from ``studio``. A cycle here would catch, e.g., ``cli`` importing ``app`` for its
subcommand while ``app`` imports ``cli`` for an exit code."""
from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("engine", "studio")


def _modules() -> dict[str, Path]:
    out = {}
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = path
    return out


MODULES = _modules()


def _resolve(module: str, is_package: bool, level: int, name: str | None) -> str:
    if level == 0:
        return name or ""
    base = module.split(".") if is_package else module.split(".")[:-1]
    base = base[:len(base) - (level - 1)]
    return ".".join(base + ([name] if name else []))


def _known(name: str) -> str | None:
    """The project module ``name`` names (or the package holding it), else None."""
    while name:
        if name in MODULES:
            return name
        name = name.rpartition(".")[0]
    return None


def _edges(module: str, path: Path) -> set[str]:
    tree = ast.parse(path.read_text(), str(path))
    is_package = path.name == "__init__.py"
    out = set()
    for node in ast.walk(tree):
        targets = []
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = _resolve(module, is_package, node.level, node.module)
            targets = [base] + [f"{base}.{a.name}" for a in node.names]
        for t in targets:
            k = _known(t)
            if k is not None and k != module:
                out.add(k)
    # a package's __init__ is imported with each of its modules: ``a.b`` depends on ``a``,
    # but that is not an edge of the code's own choosing, so it is left out here
    return out


def _graph() -> dict[str, set[str]]:
    return {m: _edges(m, p) for m, p in MODULES.items()}


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    WHITE, GREY, BLACK = 0, 1, 2
    colour = {m: WHITE for m in graph}
    stack: list[str] = []

    def visit(m: str) -> list[str] | None:
        colour[m] = GREY
        stack.append(m)
        for n in sorted(graph[m]):
            if colour.get(n) == GREY:
                return stack[stack.index(n):] + [n]
            if colour.get(n) == WHITE:
                found = visit(n)
                if found:
                    return found
        stack.pop()
        colour[m] = BLACK
        return None

    for m in sorted(graph):
        if colour[m] == WHITE:
            found = visit(m)
            if found:
                return found
    return None


def test_the_import_graph_has_no_cycle():
    graph = _graph()
    cycle = _cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def test_the_cycle_check_finds_a_planted_cycle():
    # the check itself could be wrong (e.g. resolve no relative import): plant one
    graph = _graph()
    graph["studio.exit_codes"] = graph["studio.exit_codes"] | {"studio.cli.main"}
    assert _cycle(graph) is not None
    assert "studio.exit_codes" in _edges("studio.cli.main", MODULES["studio.cli.main"])


def test_every_relative_import_names_a_module_of_the_project():
    # ``from .studies import x`` inside studio/service/jobs/ names studio.service.jobs.studies, which does
    # not exist: the import fails only when the function holding it runs
    bad = []
    for module, path in MODULES.items():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.level:
                base = _resolve(module, path.name == "__init__.py", node.level, node.module)
                if base not in MODULES:
                    bad.append(f"{module}:{node.lineno}: {base}")
    assert not bad, bad


def test_engine_imports_nothing_from_studio():
    graph = _graph()
    bad = {m: sorted(d for d in deps if d.startswith("studio"))
           for m, deps in graph.items() if m.startswith("engine")}
    assert not {m: d for m, d in bad.items() if d}


def test_studio_loads_no_module_by_a_computed_name():
    found = []
    for m, path in MODULES.items():
        if not m.startswith("studio"):
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call):
                f = node.func
                name = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", "")
                if name in ("import_module", "__import__"):
                    found.append(f"{m}:{node.lineno}")
    # the study runner resolves its Dask task by name ("module:function"), by design: a
    # task runs on a worker process that receives only the name
    assert found == [f for f in found if f.startswith("studio.studies.runner:")], found


@pytest.mark.parametrize("module", sorted(MODULES))
def test_each_module_imports_on_its_own(module):
    # a fresh interpreter per module: an import that works only after another module was
    # imported first (a hidden order dependence, or a cycle through partial modules) fails.
    # A package's ``__main__`` is run (``python -m``), not imported: it is run with --help.
    code = (f"import runpy, sys; sys.argv = ['x', '--help']; "
            f"runpy.run_module({module.rpartition('.')[0]!r}, run_name='__main__')"
            if module.endswith(".__main__") else f"import {module}")
    p = subprocess.run([sys.executable, "-c", code], cwd=ROOT,
                       capture_output=True, text=True)
    assert p.returncode == 0, p.stderr[-2000:]

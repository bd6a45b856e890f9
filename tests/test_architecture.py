"""The house's rules (docs/architecture.md), checked on the source so that they stay true:
layers import only downward (import-linter's contracts in pyproject.toml), no import
cycle, argparse only in the command-line layer, no private name crossing modules,
imports at module top unless a heavy optional dependency is deferred on purpose, and
files of one concern (at most 600 lines)."""

from __future__ import annotations

import ast
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("pinquad", "estimators", "viz", "flightgen")
MAX_LINES = 600
# Imported inside functions on purpose: heavy optional dependencies and the viewer, which
# a command loads only when asked for (--view, --estep gtsam, benchmark peers).
DEFERRED = ("gtsam", "estimators.factor_graph", "viser", "imageio", "viz", "jax", "jaxlib",
            "dynamax", "filterpy", "pykalman", "dask", "distributed")
# The benchmark measures each worker process's time and memory: a worker that does not fly
# does not import the simulator (seconds and ~100 MB), each says so where it defers it.
DEFERRED_IN = {"pinquad/experiments/bench_cases.py": ("pinquad.sim.simulator",),
               "pinquad/experiments/bench_workers.py": ("pinquad.sim.simulator",
                                                        "pinquad.experiments.online",
                                                        "pinquad.experiments.bench_discovery")}


def _sources() -> Iterator[Path]:
    for pkg in PACKAGES:
        yield from sorted((ROOT / pkg).rglob("*.py"))


def _module(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _is_cli(path: Path) -> bool:
    rel = path.relative_to(ROOT)
    return rel.parts[:2] == ("pinquad", "cli") or path.name == "__main__.py"


def _imported(node: ast.AST, here: str, is_pkg: bool) -> list[str]:
    if isinstance(node, ast.Import):
        return [a.name for a in node.names]
    assert isinstance(node, ast.ImportFrom)
    if node.level:
        base = here if is_pkg else here.rpartition(".")[0]
        for _ in range(node.level - 1):
            base = base.rpartition(".")[0]
        mod = f"{base}.{node.module}" if node.module else base
    else:
        mod = node.module or ""
    return [f"{mod}.{a.name}" for a in node.names] + [mod]


def _graph() -> dict[str, set[str]]:
    """Module -> the project modules it imports anywhere (functions and TYPE_CHECKING
    blocks included: a type-only import upward is still a dependency upward)."""
    files = list(_sources())
    known = {_module(p) for p in files}
    graph: dict[str, set[str]] = {}
    for p in files:
        here = _module(p)
        deps: set[str] = set()
        for node in ast.walk(ast.parse(p.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import | ast.ImportFrom):
                for name in _imported(node, here, p.name == "__init__.py"):
                    while name and name not in known:
                        name = name.rpartition(".")[0]
                    if name and name != here:
                        deps.add(name)
        graph[here] = deps
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    sys.setrecursionlimit(10_000)

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_cycle_finder_finds_a_cycle():
    """The checker itself: a two-module loop is reported, a chain is not."""
    assert _cycles({"a": {"b"}, "b": {"a"}, "c": {"a"}}) == [["a", "b"]]
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": set()}) == []


def test_no_import_cycle():
    graph = _graph()
    assert len(graph) > 80, "the package was not found"
    assert _cycles(graph) == []


def test_layers_import_only_downward():
    """import-linter's contracts (pyproject.toml): the layers, estimators knowing nothing
    of pinquad, the viewer running no estimation."""
    # through the interpreter running the tests, so that neither PATH nor the location of
    # the console script matters (a venv's python called without the venv on PATH)
    script = ("import sys; from importlinter.cli import lint_imports_command; "
              "sys.argv = ['lint-imports', '--no-cache']; lint_imports_command()")
    out = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True,
                         text=True, env={"PYTHONPATH": str(ROOT)})
    assert out.returncode == 0, out.stdout[-4000:] + out.stderr[-2000:]
    assert "BROKEN" not in out.stdout and "KEPT" in out.stdout


def test_argparse_only_in_the_command_line_layer():
    offenders = []
    for p in _sources():
        if _is_cli(p):
            continue
        for node in ast.walk(ast.parse(p.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import | ast.ImportFrom) and any(
                    n == "argparse" or n.startswith("argparse.")
                    for n in _imported(node, _module(p), p.name == "__init__.py")):
                offenders.append(str(p.relative_to(ROOT)))
    assert offenders == []


def test_no_private_name_crosses_modules():
    """``from pinquad.x import _y`` and ``x._y`` on an imported project module are
    private names used outside their module."""
    offenders = []
    for p in _sources():
        tree = ast.parse(p.read_text(encoding="utf-8"))
        aliases: set[str] = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] in PACKAGES:
                for a in node.names:
                    if a.name.startswith("_") and not a.name.startswith("__"):
                        offenders.append(f"{p.relative_to(ROOT)}:{node.lineno}: {a.name}")
                    else:
                        aliases.add(a.asname or a.name)
            elif isinstance(node, ast.Import):
                for a in node.names:
                    if a.name.split(".")[0] in PACKAGES:
                        aliases.add(a.asname or a.name.split(".")[0])
        for node in ast.walk(tree):
            if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                    and node.value.id in aliases and node.attr.startswith("_")
                    and not node.attr.startswith("__")):
                offenders.append(f"{p.relative_to(ROOT)}:{node.lineno}: "
                                 f"{node.value.id}.{node.attr}")
    assert offenders == []


def test_imports_at_module_top_unless_deferred_on_purpose():
    offenders = []
    for p in _sources():
        tree = ast.parse(p.read_text(encoding="utf-8"))
        for fn in ast.walk(tree):
            if not isinstance(fn, ast.FunctionDef | ast.AsyncFunctionDef):
                continue
            for node in ast.walk(fn):
                if not isinstance(node, ast.Import | ast.ImportFrom):
                    continue
                names = _imported(node, _module(p), p.name == "__init__.py")
                top = names[-1] if isinstance(node, ast.ImportFrom) else names[0]
                allowed = DEFERRED + DEFERRED_IN.get(str(p.relative_to(ROOT)), ())
                if not any(top == d or top.startswith(d + ".") for d in allowed):
                    offenders.append(f"{p.relative_to(ROOT)}:{node.lineno}: {top}")
    assert offenders == []


def test_files_hold_one_concern():
    long = [f"{p.relative_to(ROOT)}: {n} lines" for p in _sources()
            if (n := p.read_text(encoding="utf-8").count("\n")) > MAX_LINES]
    assert long == []

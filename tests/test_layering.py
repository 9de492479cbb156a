"""The floors of docs/architecture.md: every import points down (or stays on its own floor's package).

    0  dsp                    numpy/scipy only, never risloc_rt
    1  risloc_rt.model        signal model
    2  risloc_rt.authoring    scene specs, folders, checks
    3  risloc_rt.hall         ray-traced hall (hall.raytrace: the only sionna-rt/mitsuba/drjit importer)
    4  risloc_rt.io           capture files, result.json, plots
    5  risloc_rt.measured, risloc_rt.studies
    6  risloc_rt.cli

Every ``import`` and ``from ... import`` of every module counts, at top level or inside a function.

Within the floors, no import cycle: :func:`import_cycles` builds the module-level import graph of
every module of ``dsp`` and ``risloc_rt`` and reports each strongly connected component of more
than one module (with the file and line of every import on one of its cycles). What an edge is:

- ``import a.b.c`` is an edge to ``a.b.c``; ``from pkg import name`` to ``pkg.name`` when that is a
  module (a submodule imported by name), else to ``pkg`` (a name ``pkg/__init__.py`` defines or
  re-exports); relative imports are resolved; top-level and function-level imports count alike
  (a function-level import still ties the two modules together: it only defers the failure).
- The packages Python initialises on the way (``a`` and ``a.b`` for ``import a.b.c``) are *not*
  edges. A package whose ``__init__`` re-exports its submodules imports each of them, and each
  submodule's own imports pass through that package: counting those implicit steps would make
  every re-exporting ``__init__`` a cycle with each of its submodules, a cycle Python resolves by
  design (the half-initialised package is already in ``sys.modules`` while its submodule loads).
- An explicit import of a package itself (``from . import name``, ``from .. import __version__``)
  *is* an edge to its ``__init__``: that ``__init__`` must have run up to ``name`` first, so a
  submodule importing its own package's re-export while that ``__init__`` imports the submodule is
  a real cycle (an ImportError or a half-defined name, depending on who is imported first).
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

#: Subpackage -> floor. ``risloc_rt._version``, ``_files``, ``_lazy``, ``_workers`` (floor -1), ``plotting`` (figures) and ``_outputs`` (the output policy), both on ``_files``, and the root package (lazy re-exports) sit below all.
FLOORS = {
    "dsp": 0,
    "risloc_rt._version": -1,
    "risloc_rt._files": -1,
    "risloc_rt._outputs": 0,
    "risloc_rt._lazy": -1,
    "risloc_rt._workers": -1,
    "risloc_rt.plotting": 0,
    "risloc_rt.model": 1,
    "risloc_rt.authoring": 2,
    "risloc_rt.hall": 3,
    "risloc_rt.io": 4,
    "risloc_rt.measured": 5,
    "risloc_rt.studies": 5,
    "risloc_rt.cli": 6,
    "risloc_rt.__main__": 7,
}
HEAVY = {"sionna", "mitsuba", "drjit"}
#: Array libraries of the device seam: imported by dsp/xp.py alone (docs/architecture.md, "Host and device").
DEVICE_LIBS = {"cupy", "cupyx", "array_api_strict"}


def _package_of(module: str) -> str | None:
    """The entry of FLOORS that ``module`` belongs to (longest prefix), or None."""
    best = None
    for name in FLOORS:
        if module == name or module.startswith(name + "."):
            if best is None or len(name) > len(best):
                best = name
    return best


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(REPO).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _module_names() -> dict[str, Path]:
    """Every module of ``dsp`` and ``risloc_rt``: its dotted name -> its file."""
    return {_module_name(p): p for p in _source_files()}


def _imports(path: Path) -> list[tuple[int, str]]:
    """(line, absolute module) of every import in ``path``; relative imports resolved."""
    module = _module_name(path)
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            # ``from pkg import submodule`` imports the submodule
            found += [(node.lineno, f"{target}.{alias.name}") for alias in node.names]
    return found


def _source_files() -> list[Path]:
    return sorted(p for top in ("dsp", "risloc_rt") for p in (REPO / top).rglob("*.py"))


def layering_violations() -> list[str]:
    """'file:line imports X (floor a) from floor b' for every upward or sideways import."""
    bad = []
    for path in _source_files():
        here = _package_of(_module_name(path))
        if here is None:
            if _module_name(path) == "risloc_rt":
                continue  # the root's lazy re-exports
            bad.append(f"{path.relative_to(REPO)} belongs to no floor: add its package to FLOORS and docs/architecture.md")
            continue
        for line, target in _imports(path):
            top = target.split(".")[0]
            if top in DEVICE_LIBS and _module_name(path) != "dsp.xp":
                bad.append(f"{path.relative_to(REPO)}:{line} imports {target}: only dsp.xp (the array seam) may import {top}")
                continue
            if here == "dsp" and top in {"risloc_rt", "matplotlib", "trimesh", *HEAVY}:
                bad.append(f"{path.relative_to(REPO)}:{line} imports {target}: dsp imports numpy/scipy only")
                continue
            if top in HEAVY and not _module_name(path).startswith("risloc_rt.hall.raytrace"):
                bad.append(f"{path.relative_to(REPO)}:{line} imports {target}: only risloc_rt.hall.raytrace may import {top}")
                continue
            if top not in {"dsp", "risloc_rt"}:
                continue
            there = _package_of(target)
            if there is None:
                if target == "risloc_rt" or target.startswith("risloc_rt.__version__"):
                    continue
                bad.append(f"{path.relative_to(REPO)}:{line} imports {target}, which is on no floor")
                continue
            if there != here and FLOORS[there] >= FLOORS[here]:
                bad.append(f"{path.relative_to(REPO)}:{line} imports {target} (floor {FLOORS[there]}, {there}) "
                           f"from floor {FLOORS[here]} ({here}): imports must point down")
    return bad


def import_graph() -> dict[str, dict[str, tuple[Path, int]]]:
    """module -> {imported module: (file, line of its first import)} over ``dsp`` and ``risloc_rt`` (module docstring)."""
    modules = _module_names()
    graph: dict[str, dict[str, tuple[Path, int]]] = {name: {} for name in modules}
    for name, path in modules.items():
        for line, target in sorted(_imports(path)):
            if target not in modules:  # ``from pkg import name``: the name is pkg's, not a submodule
                target = target.rpartition(".")[0]
            if target in modules and target != name:
                graph[name].setdefault(target, (path, line))
    return graph


def strongly_connected(graph: dict[str, dict[str, object]]) -> list[list[str]]:
    """Tarjan's strongly connected components of ``graph`` (an iterative DFS: no recursion limit)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []
    for root in sorted(graph):
        if root in index:
            continue
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        work = [(root, iter(sorted(graph[root])))]
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                parent = work[-1][0]
                low[parent] = min(low[parent], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                out.append(sorted(component))
    return out


def _one_cycle(graph: dict[str, dict[str, tuple[Path, int]]], component: list[str]) -> list[str]:
    """A shortest cycle through the first module of ``component``, staying inside it: [m0, m1, ..., m0]."""
    inside = set(component)
    start = component[0]
    previous: dict[str, str] = {}
    frontier = [start]
    while frontier:
        following = []
        for node in frontier:
            for child in sorted(graph[node]):
                if child == start:
                    path = [start]
                    while node != start:
                        path.append(node)
                        node = previous[node]
                    return [start, *reversed(path[1:]), start]
                if child in inside and child not in previous:
                    previous[child] = node
                    following.append(child)
        frontier = following
    raise AssertionError(f"{component} is not strongly connected")  # pragma: no cover


def import_cycles() -> list[str]:
    """One line per import cycle: its modules, and the file:line of every import around one cycle."""
    graph = import_graph()
    found = []
    for component in strongly_connected(graph):
        if len(component) < 2:
            continue
        cycle = _one_cycle(graph, component)
        steps = []
        for a, b in zip(cycle, cycle[1:]):
            path, line = graph[a][b]
            steps.append(f"{path.relative_to(REPO)}:{line} imports {b}")
        found.append(f"import cycle among {', '.join(component)}: " + "; ".join(steps))
    return found


def test_imports_point_down():
    assert layering_violations() == []


def test_the_checker_catches_an_upward_import(tmp_path, monkeypatch):
    """The checker itself can fail: a model module importing the CLI is reported with file and line."""
    fake = REPO / "risloc_rt" / "model" / "_layering_probe.py"
    fake.write_text("from ..cli import main\n")
    try:
        found = layering_violations()
    finally:
        fake.unlink()
    assert found == ["risloc_rt/model/_layering_probe.py:1 imports risloc_rt.cli.main (floor 6, risloc_rt.cli) "
                     "from floor 1 (risloc_rt.model): imports must point down"]


def test_no_import_cycles():
    assert import_cycles() == []


def test_the_cycle_checker_catches_a_planted_cycle():
    """Two probe modules importing each other (one at top level, one inside a function) are one
    cycle, reported with both files and lines; a third that only imports one of them is not in it."""
    folder = REPO / "risloc_rt" / "model"
    files = {"_cycle_probe_a.py": "from . import _cycle_probe_b\n",
             "_cycle_probe_b.py": "import numpy\n\n\ndef f():\n    from ._cycle_probe_a import x\n",
             "_cycle_probe_c.py": "from ._cycle_probe_a import y\n"}
    before = import_cycles()
    for name, text in files.items():
        (folder / name).write_text(text)
    try:
        found = [c for c in import_cycles() if c not in before]
    finally:
        for name in files:
            (folder / name).unlink()
    assert found == ["import cycle among risloc_rt.model._cycle_probe_a, risloc_rt.model._cycle_probe_b: "
                     "risloc_rt/model/_cycle_probe_a.py:1 imports risloc_rt.model._cycle_probe_b; "
                     "risloc_rt/model/_cycle_probe_b.py:5 imports risloc_rt.model._cycle_probe_a"]


def test_a_package_reexporting_its_submodules_is_no_cycle_but_importing_its_own_reexport_is():
    """``pkg/__init__`` importing ``pkg.mod`` is no cycle by itself (Python resolves the implicit
    parent step); ``pkg.mod`` doing ``from . import name`` (a name of ``pkg/__init__``) closes one."""
    graph = {"p": {"p.a": (REPO / "p" / "__init__.py", 1)}, "p.a": {}}
    assert [c for c in strongly_connected(graph) if len(c) > 1] == []
    graph["p.a"]["p"] = (REPO / "p" / "a.py", 3)
    assert [c for c in strongly_connected(graph) if len(c) > 1] == [["p", "p.a"]]


def test_tarjan_finds_every_component_of_a_known_graph():
    """Two cycles joined by a one-way edge stay two components; a chain adds singletons."""
    graph = {"a": {"b": 0}, "b": {"c": 0}, "c": {"a": 0, "d": 0}, "d": {"e": 0}, "e": {"d": 0, "f": 0}, "f": {}}
    assert sorted(strongly_connected(graph)) == [["a", "b", "c"], ["d", "e"], ["f"]]


@pytest.mark.parametrize("package", sorted(p for p in FLOORS if p.count(".") == 1 and not p.endswith("__main__")
                                           and (REPO / p.replace(".", "/")).is_dir()))
def test_every_subpackage_is_a_floor_in_the_architecture_doc(package):
    assert f"`{package.replace('.', '/')}/`" in (REPO / "docs" / "architecture.md").read_text()


def test_dsp_imports_neither_risloc_rt_nor_heavy_packages():
    forbidden = {"risloc_rt", "matplotlib", "trimesh", *HEAVY}
    code = ("import sys, dsp, dsp.beamscan, dsp.localize, dsp.spectrum, dsp.geometry; "
            "print(sorted({m.split('.')[0] for m in sys.modules} & %r))" % forbidden)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", f"dsp pulled in {out.stdout.strip()}"


def test_the_analytic_simulator_and_the_cli_do_not_load_the_ray_tracer():
    code = ("import sys, risloc_rt, risloc_rt.cli, risloc_rt.model, risloc_rt.io, risloc_rt.hall; "
            "risloc_rt.cli.build_parser(); risloc_rt.paper_scenario; "
            "print(sorted({m.split('.')[0] for m in sys.modules} & {'sionna', 'mitsuba', 'drjit', 'matplotlib'}))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", f"importing the CLI pulled in {out.stdout.strip()}"

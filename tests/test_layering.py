"""The floors of docs/architecture.md: every import points down (or stays on its own floor's package).

    0  dsp                    numpy/scipy only, never risloc_rt
    1  risloc_rt.model        signal model
    2  risloc_rt.authoring    scene specs, folders, checks
    3  risloc_rt.hall         ray-traced hall (hall.raytrace: the only sionna-rt/mitsuba/drjit importer)
    4  risloc_rt.io           capture files, result.json, plots
    5  risloc_rt.measured, risloc_rt.studies
    6  risloc_rt.cli

Every ``import`` and ``from ... import`` of every module counts, at top level or inside a function.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

#: Subpackage -> floor. ``risloc_rt._version``, ``_files``, ``_lazy`` (floor -1), ``plotting`` (figures, on ``_files``) and the root package (lazy re-exports) sit below all.
FLOORS = {
    "dsp": 0,
    "risloc_rt._version": -1,
    "risloc_rt._files": -1,
    "risloc_rt._lazy": -1,
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

"""The rooms of risloc_rt.measured: imports point one way, names are public and say what they hold.

    0  errors     MeasuredFormatError, the text-file reader
    1  ti         TI radar configurations (.cfg, Studio JSON)
    2  dca1000    raw data: layouts, split files, packets, reader, channels, inspection
    3  sweep      schedule, RIS timing, alignment, leakage, import
    4  emulate    raw files, an experiment's folder, a whole recording
    5  compare    traced hall, calibration file and fit, comparison and its page
    6  live       recording from a radar and a DCA1000: radar CLI, DCA1000 link, receiver, live sweeps

A module may import its own room and the rooms before it (every ``import`` counts, at top level or
inside a function); ``measured/__init__.py`` only re-exports. Import cycles between modules are
``tests/test_layering.py``'s (the whole repository).
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import pytest

MEASURED = Path(__file__).resolve().parents[2] / "risloc_rt" / "measured"
ROOMS = ("errors", "ti", "dca1000", "sweep", "emulate", "compare", "live")
PACKAGE = "risloc_rt.measured"
MAX_FUNCTION_LINES = 80
"""Lines of code of one function, its docstring not counted."""


def _module(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join([PACKAGE, *parts])


def _imports(path: Path, root: Path) -> list[tuple[int, str, tuple[str, ...]]]:
    """(line, absolute module, names) of every import of ``path``; relative imports resolved."""
    module = _module(path, root)
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name, ()) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            found.append((node.lineno, target, tuple(alias.name for alias in node.names)))
    return found


def _room(module: str) -> str | None:
    rest = module[len(PACKAGE) + 1:] if module.startswith(PACKAGE + ".") else ""
    return rest.split(".")[0] or None


def _sources(root: Path) -> list[Path]:
    return sorted(p for p in root.rglob("*.py") if p != root / "__init__.py")


def room_violations(root: Path = MEASURED) -> list[str]:
    """'file:line imports X (room a) from room b' for every import that points to a later room."""
    bad = []
    for path in _sources(root):
        here = _room(_module(path, root))
        if here not in ROOMS:
            bad.append(f"{path.relative_to(root)} is in no room: put it in one of {ROOMS} (and the docstrings)")
            continue
        for line, target, names in _imports(path, root):
            if target == PACKAGE:
                bad.append(f"{path.relative_to(root)}:{line} imports {names} from {PACKAGE}: import the module")
                continue
            there = _room(target)
            if there is None or not target.startswith(PACKAGE):
                continue
            if there not in ROOMS or ROOMS.index(there) > ROOMS.index(here):
                bad.append(f"{path.relative_to(root)}:{line} imports {target} (room {there}) from room {here}: "
                           f"rooms import only {ROOMS[:ROOMS.index(here) + 1]}")
    return bad


def test_rooms_import_only_the_rooms_before_them():
    assert room_violations() == []


def test_the_room_checker_catches_a_backward_import(tmp_path):
    (tmp_path / "ti").mkdir()
    (tmp_path / "sweep").mkdir()
    (tmp_path / "ti" / "probe.py").write_text("import numpy\n\n\ndef f():\n    from ..sweep.schedule import x\n")
    (tmp_path / "sweep" / "schedule.py").write_text("from ..ti.probe import f\n")
    assert room_violations(tmp_path) == [
        f"ti/probe.py:5 imports {PACKAGE}.sweep.schedule (room sweep) from room ti: rooms import only "
        "('errors', 'ti')"]


def test_no_module_or_room_is_named_after_the_standard_library():
    names = {p.stem for p in MEASURED.rglob("*.py")} | {p.name for p in MEASURED.iterdir() if p.is_dir()}
    assert sorted(names & set(sys.stdlib_module_names)) == []


def test_imports_between_modules_use_public_names():
    """A name taken from another module of risloc_rt is in that module's ``__all__`` (the seam is public)."""
    import importlib

    bad = []
    for path in _sources(MEASURED):
        for line, target, names in _imports(path, MEASURED):
            if not target.startswith("risloc_rt.") or not names:
                continue
            module = importlib.import_module(target)
            public = set(getattr(module, "__all__", ()))
            for name in names:
                if isinstance(getattr(module, name, None), type(sys)):
                    continue                                     # a submodule
                if name.startswith("_") or name not in public:
                    bad.append(f"{path.relative_to(MEASURED)}:{line} imports {name} from {target}, not in its __all__")
    assert bad == []


@pytest.mark.parametrize("room", ROOMS[1:])
def test_every_room_re_exports_its_public_names(room):
    import importlib

    package = importlib.import_module(f"{PACKAGE}.{room}")
    assert package.__all__ and all(hasattr(package, name) for name in package.__all__)
    docstring = package.__doc__ or ""
    modules = sorted(p.stem for p in (MEASURED / room).glob("*.py") if p.stem != "__init__")
    assert [m for m in modules if f":mod:`.{m}`" not in docstring] == [], "the room's docstring lists every module"


def test_figures_go_through_the_plotting_helper():
    """No module imports matplotlib (so none touches pyplot or the backend) or calls ``savefig`` itself."""
    offenders = []
    for path in _sources(MEASURED):
        for line, target, _ in _imports(path, MEASURED):
            if target.split(".")[0] == "matplotlib":
                offenders.append(f"{path.relative_to(MEASURED)}:{line} imports {target}")
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "savefig":
                offenders.append(f"{path.relative_to(MEASURED)}:{node.lineno} calls savefig")
    assert offenders == [], "draw with risloc_rt.plotting.new_figure, write with save_figure (atomic)"


def test_functions_are_short():
    long = []
    for path in _sources(MEASURED):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                first = node.body[0]
                has_doc = isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) \
                    and isinstance(first.value.value, str)
                start = (node.body[1].lineno if len(node.body) > 1 else first.end_lineno + 1) if has_doc \
                    else first.lineno
                lines = node.end_lineno - start + 1
                if lines > MAX_FUNCTION_LINES:
                    long.append(f"{path.relative_to(MEASURED)}:{node.lineno} {node.name}: {lines} lines")
    assert long == [], f"split these into steps of at most {MAX_FUNCTION_LINES} lines"

"""The seams between modules: public names only, messages that name real modules, figures without global state.

* No module of ``dsp/`` or ``risloc_rt/`` reaches into another module's private names
  (``from .issues import _fmt``, ``plots._save(...)``): a name another module needs is a public,
  documented seam. A package's own private helper *module* (``risloc_rt._files``) is fine: the rule
  is about private names, not private modules.
* Every dotted ``risloc_rt.…`` / ``dsp.…`` name a string literal mentions (error messages, warnings,
  docstrings) exists: a user told to call ``risloc_rt.raytrace.ensure_backend()`` can.
* Importing ``risloc_rt`` and drawing its figures leaves matplotlib's global state as it was: the
  backend is not switched and no pyplot figure is left open.
"""

from __future__ import annotations

import ast
import importlib
import json
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGES = ("dsp", "risloc_rt")


def _source_files() -> list[Path]:
    return sorted(p for pkg in PACKAGES for p in (REPO / pkg).rglob("*.py"))


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(REPO).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _is_private(name: str) -> bool:
    """``_x`` is private; ``__x__`` (``__version__``, ``__all__``) is not."""
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _module_path(module: str) -> Path | None:
    """The file or package folder of a project module, None when it is not one of ours."""
    if module.split(".")[0] not in PACKAGES:
        return None
    base = REPO.joinpath(*module.split("."))
    if base.with_suffix(".py").is_file():
        return base.with_suffix(".py")
    if (base / "__init__.py").is_file():
        return base
    return None


def _is_module(module: str) -> bool:
    """True when ``module`` is a module (file or package) of this project."""
    return _module_path(module) is not None


def _absolute(path: Path, node: ast.ImportFrom) -> str:
    """The absolute module a ``from ... import`` reads from (relative imports resolved)."""
    if not node.level:
        return node.module or ""
    module = _module_name(path)
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    parts = package.split(".")
    base = parts[: len(parts) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def private_name_crossings(path: Path, text: str | None = None) -> list[str]:
    """``file:line: ...`` for every private name ``path`` takes from another module.

    Counted: ``from m import _x`` where ``_x`` is a name (not a submodule ``m/_x.py``) of a
    project module ``m``, and ``alias._x`` where ``alias`` is bound by an import to a project
    module and ``_x`` is not one of its submodules. Imports inside functions count too. ``text``
    replaces the file's content (``path`` then only places it for relative imports).
    """
    rel = path.relative_to(REPO)
    tree = ast.parse(path.read_text() if text is None else text, str(path))
    found: list[str] = []
    modules: dict[str, str] = {}  # local name -> project module it is bound to
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            source = _absolute(path, node)
            for alias in node.names:
                target = f"{source}.{alias.name}"
                if _is_module(target):
                    modules[alias.asname or alias.name] = target
                elif _is_private(alias.name) and _is_module(source):
                    found.append(f"{rel}:{node.lineno}: from {source} import {alias.name}")
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] in PACKAGES and _is_module(alias.name):
                    # ``import a.b.c`` binds ``a``; ``import a.b.c as x`` binds x to a.b.c
                    if alias.asname:
                        modules[alias.asname] = alias.name
                    else:
                        modules[alias.name.split(".")[0]] = alias.name.split(".")[0]
    for node in ast.walk(tree):
        if not (isinstance(node, ast.Attribute) and _is_private(node.attr)):
            continue
        chain = []
        value: ast.expr = node.value
        while isinstance(value, ast.Attribute):
            chain.append(value.attr)
            value = value.value
        if not (isinstance(value, ast.Name) and value.id in modules):
            continue
        owner = ".".join([modules[value.id], *reversed(chain)])
        if _is_module(owner) and not _is_module(f"{owner}.{node.attr}"):
            found.append(f"{rel}:{node.lineno}: {owner}.{node.attr}")
    return found


def test_no_private_name_crosses_modules() -> None:
    found = [f for path in _source_files() for f in private_name_crossings(path)]
    assert not found, "private names used across modules (make the seam public):\n" + "\n".join(found)


def test_the_private_name_scan_finds_each_form() -> None:
    """The scan above can fail: each forbidden form is found, each allowed one is not."""
    probe = REPO / "dsp" / "probe.py"  # a module that is not there: only its place matters
    found = private_name_crossings(probe, textwrap.dedent("""\
        from .spectrum import _private_helper, check_cube
        from . import spectrum, validation as v
        import risloc_rt
        import risloc_rt.plotting as rp
        from risloc_rt import _files
        from risloc_rt._files import atomic_write
        from ._version import __version__

        def f():
            from .detection import _inner
            return spectrum._window_table, v.positive, rp._canvas, _files.atomic_write, risloc_rt._files
        """))
    lines = [f.split(": ", 1)[1] for f in found]
    assert sorted(lines) == sorted([
        "from dsp.spectrum import _private_helper",
        "from dsp.detection import _inner",
        "dsp.spectrum._window_table",
        "risloc_rt.plotting._canvas",
    ]), found
    assert all(f.startswith("dsp/probe.py:") for f in found)


#: ``risloc_rt.x.y`` or ``dsp.x`` in a string, not preceded by a word character, a dot or a slash.
DOTTED = re.compile(r"(?<![\w./])(?:risloc_rt|dsp)(?:\.[A-Za-z_]\w*)+")


def _strings(path: Path) -> list[tuple[int, str]]:
    """(line, text) of every string literal in ``path`` (f-string parts and docstrings included)."""
    tree = ast.parse(path.read_text(), str(path))
    return [(n.lineno, n.value) for n in ast.walk(tree) if isinstance(n, ast.Constant) and isinstance(n.value, str)]


def resolves(dotted: str) -> bool:
    """Import the longest module prefix of ``dotted``, then getattr the rest (dataclass fields count)."""
    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        for name in parts[i:]:
            if hasattr(obj, name):
                obj = getattr(obj, name)
            elif name in getattr(obj, "__dataclass_fields__", {}) or name in getattr(obj, "__annotations__", {}):
                obj = None  # an instance field: nothing further to resolve on the class
            else:
                return False
        return True
    return False


def test_every_module_a_message_names_exists() -> None:
    missing = []
    for path in _source_files():
        for line, text in _strings(path):
            for name in DOTTED.findall(text):
                if not resolves(name):
                    missing.append(f"{path.relative_to(REPO)}:{line}: {name}")
    assert not missing, "strings name modules or objects that do not exist:\n" + "\n".join(missing)


def test_the_dotted_name_check_can_fail() -> None:
    assert resolves("risloc_rt.hall.raytrace.ensure_backend")
    assert resolves("dsp.Localization.flags")
    assert resolves("dsp.Localization.beam_index")  # a field without a default
    assert not resolves("risloc_rt.raytrace.ensure_backend")
    assert not resolves("dsp.no_such_function")
    assert DOTTED.findall("call risloc_rt.raytrace.ensure_backend() first; see dsp.detect.") == [
        "risloc_rt.raytrace.ensure_backend", "dsp.detect"]
    assert DOTTED.findall("scenes/risloc_rt.yaml and my_dsp.x") == []


#: Run in a fresh interpreter: set a headless, non-Agg backend, draw every figure kind cheaply, and
#: report matplotlib's global state before and after as JSON (the last line of stdout).
_DRAW_EVERYTHING = r'''
import json, sys, warnings
from pathlib import Path
from types import SimpleNamespace

import matplotlib
matplotlib.use(sys.argv[2])
out = Path(sys.argv[1])
before = {"backend": matplotlib.get_backend(), "rc": {k: repr(v) for k, v in matplotlib.rcParams.items()}}

import numpy as np
import dsp
import risloc_rt
from risloc_rt.authoring import show_scene
from risloc_rt.io import plots

drawn = []
# a small synthetic sweep: a tone with the relay pattern's beam dependence, in unit noise
radar = dsp.RadarConfig(num_samples=64, num_chirps=16)
processing = dsp.ProcessingConfig(n_dft=127, k_dft=64)
sweep = dsp.BeamSweep.azimuth_grid(*np.deg2rad([-21.0, 21.0, 3.0]))
pattern = dsp.BeamPattern().for_wavelength(radar.wavelength)
pose = dsp.RisPose.facing([0.0, 8.0, 1.5], [0.0, 0.0, 1.5])
tau = 2 * 6.0 / dsp.SPEED_OF_LIGHT + 1.78e-9
f1 = radar.slope * tau * radar.sample_period
k, n = np.arange(radar.num_chirps), np.arange(radar.num_samples)
rng = np.random.default_rng(0)
amp = np.abs(pattern.amplitude(np.deg2rad([5.0, 0.0]), sweep.angles)) * 2.0
cube = amp[:, None, None] * np.exp(2j * np.pi * f1 * n)[None, None, :] * np.ones((1, k.size, 1))
cube = cube + (rng.standard_normal(cube.shape) + 1j * rng.standard_normal(cube.shape)) * np.sqrt(0.5)
loc = dsp.self_localize(cube, sweep=sweep, radar=radar, processing=processing, pose=pose, loopback_delay=1.78e-9,
                        pattern=pattern)
assert loc.detected, loc.flags
ddm = dsp.delay_doppler_map(cube[loc.beam_index], radar, processing)
peak = np.array([np.unravel_index(int(ddm.power.argmax()), ddm.power.shape)])
drawn.append(plots.plot_delay_doppler(ddm, peak, out / "ddm.png"))
drawn.append(plots.plot_sweep(loc, out / "sweep.png"))
drawn.append(plots.plot_range_profile(ddm, loc, out / "profile.svg", loopback_delay=1.78e-9))
profile = SimpleNamespace(distance=ddm.distance, power=ddm.power[0], peaks=[int(ddm.power[0].argmax())],
                          labels=["RIS loop-back"], beam=np.zeros(2))
drawn.append(plots.plot_labelled_profile(profile, out / "labelled.png"))
drawn.append(show_scene(Path(sys.argv[3]) / "scenes" / "paper_hall", out / "hall.png").path)

from risloc_rt.measured import plot_inspection
rd = np.abs(rng.standard_normal((16, 64))) + 1.0
inspection = SimpleNamespace(range_profile=rd.mean(axis=0), range_doppler=rd, doppler_bins=np.arange(-8, 8),
                             peak=SimpleNamespace(range_bin=10, doppler_bin=0))
plot_inspection(inspection, out / "inspection.png")
drawn.append(out / "inspection.png")

import risloc_rt.studies as studies
from risloc_rt.authoring.spec import load_spec
from risloc_rt.studies.figures import plot_map, plot_summary
from risloc_rt.studies.floor_map import MapSettings
name = next(p for p, spec in studies.PARAMETERS.items() if spec.kind == "float")
q = {"distance": 0.01, "angle": 0.001, "position": 0.02}
points = [{"params": {name: x, "estimator": "paper"}, "runs": 3, "mae": q, "crb": q,
           "mae_ci95": {key: [0.5 * v, 2 * v] for key, v in q.items()}} for x in (1.0, 2.0)]
summary = {"x": name, "study": {"name": "state", "vary": [name]}, "points": points}
drawn.append(plot_summary(summary, out / "summary.png"))
hall = load_spec(Path(sys.argv[3]) / "scenes" / "paper_hall" / "spec.toml")
cells = [{"x": x, "y": y, "rmse_position": 0.01 * (1 + x), "detection_probability": 1.0, "peb": 0.005,
          "dominant_flag": "elevation-assumed" if y < 2 else "none"} for x in (1.0, 2.0, 3.0) for y in (1.0, 2.0)]
drawn.append(plot_map(hall, cells, MapSettings(spacing=1.0, runs=3), out / "map.png"))

after = {"backend": matplotlib.get_backend(), "rc": {k: repr(v) for k, v in matplotlib.rcParams.items()}}
pyplot = "matplotlib.pyplot" in sys.modules
fignums = sys.modules["matplotlib.pyplot"].get_fignums() if pyplot else []
print(json.dumps({"before": before, "after": after, "pyplot": pyplot, "fignums": fignums,
                  "drawn": [str(p) for p in drawn]}))
'''


@pytest.mark.parametrize("backend", ["svg", "pdf"])
def test_drawing_every_figure_leaves_matplotlib_global_state_alone(tmp_path: Path, backend: str) -> None:
    """Figures are drawn on their own Agg canvas: the caller's backend and rcParams stay, pyplot is never loaded."""
    run = subprocess.run([sys.executable, "-c", _DRAW_EVERYTHING, str(tmp_path), backend, str(REPO)],
                         capture_output=True, text=True, cwd=REPO, timeout=300)
    assert run.returncode == 0, run.stderr[-3000:]
    state = json.loads(run.stdout.strip().splitlines()[-1])
    assert state["before"]["backend"] == backend  # the state the caller set, not a default
    assert state["after"]["backend"] == backend
    changed = {k for k in state["before"]["rc"] if state["before"]["rc"][k] != state["after"]["rc"].get(k)}
    assert not changed, f"rcParams changed by drawing: {sorted(changed)}"
    assert not state["pyplot"], "matplotlib.pyplot was imported by risloc_rt"
    assert state["fignums"] == []
    drawn = [Path(p) for p in state["drawn"]]
    assert len(drawn) == 8  # io.plots (4), show_scene, plot_inspection, plot_summary, plot_map
    for path in drawn:  # each figure was really drawn and written
        assert path.parent == tmp_path and path.stat().st_size > 5_000, path

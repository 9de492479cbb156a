"""numpydoc on the public surface of ``risloc_rt.studies``, ``risloc_rt.measured`` and every ``risloc`` verb's module.

Every public function and method (defined in the module, name without a leading underscore) has a
docstring; one that takes arguments has a ``Parameters`` section naming each of them, and one
that returns something (a return annotation other than ``None``) has a ``Returns`` section.
"""

from __future__ import annotations

import importlib
import inspect
import re

import pytest

MODULES = ["risloc_rt.studies.engine", "risloc_rt.studies.figures", "risloc_rt.studies.floor_map",
           "risloc_rt.studies.kernel", "risloc_rt.studies.params", "risloc_rt.studies.spec",
           "risloc_rt.studies.speed", "risloc_rt.studies.store", "risloc_rt.studies.summary",
           "risloc_rt.studies.sweep",
           "risloc_rt.cli", "risloc_rt.cli.common", "risloc_rt.cli.demo", "risloc_rt.cli.locate",
           "risloc_rt.cli.trace", "risloc_rt.cli.scene", "risloc_rt.cli.speed", "risloc_rt.cli.study",
           "risloc_rt.cli.capture", "risloc_rt.cli.calibrate", "risloc_rt.cli.compare", "risloc_rt.cli.simulate",
           "risloc_rt.model.paths", "risloc_rt._outputs", "risloc_rt._workers",
           "risloc_rt.measured.compare.calibration_file", "risloc_rt.measured.compare.calibration_fit",
           "risloc_rt.measured.compare.comparison", "risloc_rt.measured.compare.comparison_page",
           "risloc_rt.measured.compare.traced_hall", "risloc_rt.measured.dca1000.channels",
           "risloc_rt.measured.dca1000.inspection", "risloc_rt.measured.dca1000.packets",
           "risloc_rt.measured.dca1000.raw_layout", "risloc_rt.measured.dca1000.reader",
           "risloc_rt.measured.dca1000.split_files", "risloc_rt.measured.emulate.experiment",
           "risloc_rt.measured.emulate.raw_files", "risloc_rt.measured.emulate.recording",
           "risloc_rt.measured.errors", "risloc_rt.measured.sweep.alignment",
           "risloc_rt.measured.sweep.importer", "risloc_rt.measured.sweep.leakage",
           "risloc_rt.measured.sweep.ris_timing", "risloc_rt.measured.sweep.schedule",
           "risloc_rt.measured.ti.chirp_config", "risloc_rt.measured.ti.config_file",
           "risloc_rt.measured.ti.sdk_cfg", "risloc_rt.measured.ti.studio_json"]


def _section(doc: str, title: str) -> str | None:
    """The body of numpydoc section ``title`` (up to the next section), or None."""
    m = re.search(rf"^\s*{title}\n\s*-{{{len(title)}}}\n(.*?)(?=^\s*\w[\w ]*\n\s*-{{3,}}\n|\Z)", doc, re.M | re.S)
    return m.group(1) if m else None


def numpydoc_problems(func, where: str) -> list[str]:
    """What ``func``'s docstring lacks (see the module docstring)."""
    doc = inspect.getdoc(func) or ""
    if not doc.strip():
        return [f"{where}: no docstring"]
    out = []
    sig = inspect.signature(func)
    names = [n for n, p in sig.parameters.items() if n not in ("self", "cls")]
    if names:
        section = _section(doc, "Parameters")
        if section is None:
            out.append(f"{where}: no Parameters section (takes {', '.join(names)})")
        else:
            lines = [re.split(r"\s:\s|\s*$", ln.strip(), maxsplit=1)[0] for ln in section.splitlines()
                     if ln.strip() and not ln.startswith((" ", "\t"))]
            documented = {n.strip().lstrip("*") for ln in lines for n in ln.split(",")}
            missing = [n for n in names if n not in documented]
            if missing:
                out.append(f"{where}: Parameters does not name {', '.join(missing)}")
    ret = sig.return_annotation
    if ret not in (inspect.Signature.empty, None, "None") and _section(doc, "Returns") is None \
            and _section(doc, "Yields") is None:
        out.append(f"{where}: returns {ret} but has no Returns section")
    return out


def _public(module) -> list[tuple[str, object]]:
    found = []
    for name, obj in vars(module).items():
        if name.startswith("_") or getattr(obj, "__module__", None) != module.__name__:
            continue
        if inspect.isfunction(obj):
            found.append((name, obj))
        elif inspect.isclass(obj):
            for attr, member in vars(obj).items():
                if not attr.startswith("_") and inspect.isfunction(member):
                    found.append((f"{name}.{attr}", member))
    return found


@pytest.mark.parametrize("module_name", MODULES)
def test_public_functions_have_numpydoc(module_name):
    module = importlib.import_module(module_name)
    problems = [p for name, func in _public(module) for p in numpydoc_problems(func, f"{module_name}.{name}")]
    assert problems == []


def test_the_checker_finds_a_missing_section_and_a_missing_parameter():
    def good(a: int, b: float) -> float:
        """Sum.

        Parameters
        ----------
        a, b : int, float
            Terms [m].

        Returns
        -------
        float
        """
        return a + b

    def bad(a: int, b: float) -> float:
        """Sum.

        Parameters
        ----------
        a : int
        """
        return a + b

    assert numpydoc_problems(good, "good") == []
    assert numpydoc_problems(bad, "bad") == ["bad: Parameters does not name b",
                                             "bad: returns float but has no Returns section"]

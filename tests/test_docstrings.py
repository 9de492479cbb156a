"""numpydoc on the public surface of ``risloc_rt.studies``, ``risloc_rt.measured`` and every ``risloc`` verb's module.

Every public function and method (defined in the module, name without a leading underscore) has a
docstring; one that takes arguments has a ``Parameters`` section naming each of them, and one
that returns something (a return annotation other than ``None``) has a ``Returns`` section.
"""

from __future__ import annotations

import importlib
import inspect
import re
from pathlib import Path

import pytest

#: Every module of these packages, found on disk (a new module is checked without being listed), and
#: a few more.
PACKAGES = ("risloc_rt.studies", "risloc_rt.cli", "risloc_rt.measured")
EXTRA = ["risloc_rt.model.paths", "risloc_rt.model.time_division", "risloc_rt._outputs", "risloc_rt._workers",
         "risloc_rt.io.fused"]


def _modules() -> list[str]:
    names = []
    for package in PACKAGES:
        folder = Path(__file__).resolve().parent.parent.joinpath(*package.split("."))
        for path in sorted(folder.rglob("*.py")):
            parts = path.relative_to(folder).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            names.append(".".join((package, *parts)))
    return names + EXTRA


MODULES = _modules()


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

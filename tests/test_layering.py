"""The one-way layers of docs/architecture.md: ``dsp`` is numpy/scipy only."""

from __future__ import annotations

import subprocess
import sys

FORBIDDEN = {"risloc_rt", "sionna", "mitsuba", "drjit", "matplotlib", "trimesh"}


def test_dsp_imports_neither_risloc_rt_nor_heavy_packages():
    code = ("import sys, dsp, dsp.beamscan, dsp.localize, dsp.spectrum, dsp.geometry; "
            "print(sorted({m.split('.')[0] for m in sys.modules} & %r))" % FORBIDDEN)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", f"dsp pulled in {out.stdout.strip()}"


def test_the_analytic_simulator_does_not_load_the_ray_tracer():
    code = ("import sys, risloc_rt.cli, risloc_rt.simulate, risloc_rt.scenario; "
            "print(sorted({m.split('.')[0] for m in sys.modules} & {'sionna', 'mitsuba', 'drjit', 'matplotlib'}))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", f"importing the CLI pulled in {out.stdout.strip()}"

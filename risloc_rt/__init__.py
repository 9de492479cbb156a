"""risloc-rt: RIS-enabled self-localization of an FMCW radar, simulated and measured.

The entry points a script needs, loaded on first use (``import risloc_rt`` imports nothing heavy)::

    scenario = risloc_rt.paper_scenario("off-broadside")          # or risloc_rt.hall_scenario("paper_hall")
    capture = risloc_rt.simulate(scenario, rng=np.random.default_rng(0))
    loc, seconds = risloc_rt.process_capture(capture)             # dsp.Localization
    risloc_rt.save_capture(capture, "run.npz"); risloc_rt.load_capture("run.npz")

The subpackages, from the ground up (``docs/architecture.md``): ``dsp`` (separate package),
:mod:`risloc_rt.model`, :mod:`risloc_rt.authoring`, :mod:`risloc_rt.hall`, :mod:`risloc_rt.io`,
:mod:`risloc_rt.cli`.
"""

from __future__ import annotations

from ._lazy import lazy_exports
from ._version import __version__

_EXPORTS = {
    "paper_scenario": "model",
    "analytic_scenario": "model",
    "simulate": "model",
    "Capture": "model",
    "Scenario": "model",
    "hall_scenario": "hall",
    "hall_paths": "hall",
    "load_capture": "io",
    "save_capture": "io",
    "process_capture": "io",
}

__all__ = ["__version__", *sorted(_EXPORTS)]


__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

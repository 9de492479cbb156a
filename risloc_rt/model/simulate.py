"""Simulate captures from scenarios: paths -> eq. (1) beat cube -> noise."""

from __future__ import annotations

import numpy as np

from .beat import add_noise, beat_cube
from .capture import Capture, provenance
from .paths import PathSet
from .scenario import Scenario, analytic_paths

__all__ = ["simulate"]


def simulate(
    scenario: Scenario,
    *,
    rng: np.random.Generator,
    paths: PathSet | None = None,
    noise: bool = True,
    seed: int | None = None,
    provenance_extra: dict | None = None,
) -> Capture:
    """One realization of the beat cube for ``scenario``.

    Parameters
    ----------
    scenario : Scenario
    rng : numpy.random.Generator
        Source of the receiver noise (``numpy.random.default_rng(seed)``).
    paths : PathSet, optional
        Paths to synthesise; by default the paper's analytic ones (:func:`analytic_paths`).
    noise : bool
        Add CN(0, σ_N²) noise (``False`` gives the noiseless cube of eq. (1)).
    seed : int, optional
        Recorded in the capture's provenance (the seed ``rng`` was made from).
    provenance_extra : dict, optional
        More provenance keys (e.g. the traced scene and its content hash).

    Returns
    -------
    Capture
        complex128 cube [M, K, N] [√W] with the scenario's parameters and truth.
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator (numpy.random.default_rng(seed)), got {type(rng).__name__}")
    if paths is None:
        paths = analytic_paths(scenario)
    cube = beat_cube(paths, radar=scenario.radar, sweep=scenario.sweep, ris=scenario.ris)
    if noise:
        cube = add_noise(cube, scenario.radar.noise_power, rng)
    return Capture(
        cube=cube,
        sweep=scenario.sweep,
        radar=scenario.radar,
        ris=scenario.ris,
        processing=scenario.processing,
        frame_index=np.arange(scenario.sweep.num_beams),
        provenance=provenance("simulation", scenario=scenario.name, seed=seed, noise=noise,
                              paths=[{"label": lab, "delay": float(t), "power_dbm": float(10 * np.log10(max(pw, 1e-300)) + 30)}
                                     for lab, t, pw in zip(paths.labels, paths.delay, paths.power)],
                              **(provenance_extra or {})),
        truth=scenario.truth,
    )

"""Simulate captures from scenarios: paths -> eq. (1) beat cube -> noise."""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

import numpy as np

from .beat import NOISE_STREAMS, NoiseStream, add_noise, add_noise_batch, beat_cube
from .capture import Capture, provenance
from .motion import advance_paths, analytic_frame_paths, sweep_reference_time
from .paths import PathFrames, PathSet
from .scenario import Scenario, analytic_paths

if TYPE_CHECKING:  # pragma: no cover
    from dsp.xp import ArrayBackend

__all__ = ["simulate"]

Motion = Literal["sweep", "frozen"]


def simulate(
    scenario: Scenario,
    *,
    rng: np.random.Generator,
    paths: PathSet | PathFrames | None = None,
    noise: bool = True,
    seed: int | None = None,
    provenance_extra: dict | None = None,
    motion: Motion = "sweep",
    noise_stream: NoiseStream = "standard",
    backend: ArrayBackend | None = None,
) -> Capture:
    """One realization of the beat cube for ``scenario``.

    Parameters
    ----------
    scenario : Scenario
    rng : numpy.random.Generator
        Source of the receiver noise (``numpy.random.default_rng(seed)``).
    paths : PathSet or PathFrames, optional
        Paths to synthesise; by default the paper's analytic ones. A ``PathSet`` holds at the
        middle of the sweep (e.g. traced at ``scenario.ue_position``); a ``PathFrames`` is used
        as given.
    noise : bool
        Add CN(0, σ_N²) noise (``False`` gives the noiseless cube of eq. (1)).
    seed : int, optional
        Recorded in the capture's provenance (the seed ``rng`` was made from).
    provenance_extra : dict, optional
        More provenance keys (e.g. the traced scene and its content hash).
    motion : {"sweep", "frozen"}, default "sweep"
        ``"sweep"``: the UE (and any moving target) is where it is during each frame
        (``docs/moving-radar.md``): analytic paths recomputed per frame
        (:func:`risloc_rt.model.motion.analytic_frame_paths`), a given ``PathSet`` advanced to
        first order by its delay rates (:func:`risloc_rt.model.motion.advance_paths`).
        ``"frozen"``: eq. (1)'s frozen geometry, the paths of the middle of the sweep in every
        frame. Both give the same cube, bit for bit, when nothing moves.
    noise_stream : {"standard", "fast", "boxmuller"}
        The receiver noise's stream (:func:`risloc_rt.model.beat.add_noise`): ``"fast"`` and
        ``"boxmuller"`` draw float32 normals per beam, concurrently with the synthesis of each beam
        (a Table I capture in about half the time; ``"boxmuller"`` draws them 2-2.5x faster than
        ``"fast"``); the same distribution, other numbers than ``"standard"``.
    backend : dsp.ArrayBackend, optional
        Where the receiver noise is drawn (``--device``). None or NumPy: :func:`risloc_rt.model.beat.add_noise`
        with ``noise_stream``, as without a backend (the same numbers). Another backend:
        :func:`risloc_rt.model.beat.add_noise_batch` on it (a GPU draws float32 normals with cuRAND seeded
        from ``rng``: the same law, other numbers; ``noise_stream`` then does not apply), the cube copied
        back to the host and the backend's name recorded in the provenance (``noise_backend``).

    Returns
    -------
    Capture
        complex128 cube [M, K, N] [√W] with the scenario's parameters and truth (at the middle
        of the sweep, ``truth.reference_time``).
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator (numpy.random.default_rng(seed)), got {type(rng).__name__}")
    if motion not in ("sweep", "frozen"):
        raise ValueError(f"motion={motion!r} must be 'sweep' (the UE moves between frames) or 'frozen' (eq. (1))")
    m = scenario.sweep.num_beams
    if paths is None:
        paths = analytic_frame_paths(scenario) if motion == "sweep" else analytic_paths(scenario)
    elif isinstance(paths, PathSet) and motion == "sweep":
        paths = advance_paths(paths, radar=scenario.radar, num_beams=m)
    elif isinstance(paths, PathFrames) and motion == "frozen":
        raise ValueError("motion='frozen' needs a PathSet (one geometry for the whole sweep), got a PathFrames")
    on_device = noise and backend is not None and not backend.is_numpy
    if noise_stream not in NOISE_STREAMS:
        raise ValueError(f"noise_stream={noise_stream!r} must be one of {', '.join(NOISE_STREAMS)}")
    if noise and noise_stream != "standard" and not on_device:
        cube = beat_cube(paths, radar=scenario.radar, sweep=scenario.sweep, ris=scenario.ris,
                         noise=(scenario.radar.noise_power, rng), noise_stream=noise_stream)
    else:
        cube = beat_cube(paths, radar=scenario.radar, sweep=scenario.sweep, ris=scenario.ris)
        if on_device:  # drawn where the backend's arrays live, copied back explicitly
            noisy = add_noise_batch(cube, scenario.radar.noise_power, [rng], backend=backend)
            cube = np.ascontiguousarray(backend.to_host(noisy)[0], dtype=np.complex128)
        elif noise:
            cube = add_noise(cube, scenario.radar.noise_power, rng, out=cube, stream=noise_stream)
    # The provenance lists the paths of the middle frame (the reference time) for a moving radar.
    listed = paths
    if isinstance(paths, PathFrames):
        t_ref = sweep_reference_time(scenario.radar, m)
        listed = paths.frame(int(np.argmin(np.abs(paths.times - t_ref))))
    return Capture(
        cube=cube,
        sweep=scenario.sweep,
        radar=scenario.radar,
        ris=scenario.ris,
        processing=scenario.processing,
        frame_index=np.arange(m),
        provenance=provenance("simulation", scenario=scenario.name, seed=seed, noise=noise,
                              motion=motion, **({"noise_stream": noise_stream} if noise_stream != "standard" else {}),
                              **({"noise_backend": backend.name} if on_device else {}),
                              paths=[{"label": lab, "delay": float(t), "power_dbm": float(10 * np.log10(max(pw, 1e-300)) + 30)}
                                     for lab, t, pw in zip(listed.labels, listed.delay, listed.power)],
                              **(provenance_extra or {})),
        truth=scenario.truth,
    )

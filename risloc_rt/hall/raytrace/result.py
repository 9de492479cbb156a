"""Parameters and result of one ray trace: :class:`TraceSettings` and :class:`TraceResult`.

Kept apart from :mod:`risloc_rt.hall.raytrace.tracer` so that the cache can read and write results
without importing the tracer (and neither imports sionna-rt at module level).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from ..traced import TracedPaths

__all__ = ["MAX_DEPTH", "MAX_SAMPLES", "TraceResult", "TraceSettings"]

#: Deepest trace allowed: at 60 GHz each bounce off concrete costs >= 5 dB, so paths beyond 20
#: interactions lie far below the noise floor, and their number (and sionna-rt's memory) grows
#: geometrically with depth.
MAX_DEPTH = 20
#: Most rays (or paths) per source: Dr.Jit indexes them with 32-bit integers.
MAX_SAMPLES = 2**31 - 1
_WHY = {"max_depth": "deeper paths are far below the noise and cost memory geometrically",
        "samples_per_src": "Dr.Jit indexes rays with 32-bit integers",
        "max_num_paths_per_src": "Dr.Jit indexes paths with 32-bit integers",
        "seed": "the ray sampler's seed is a 32-bit integer"}


@dataclass(frozen=True)
class TraceSettings:
    """Options of sionna-rt's ``PathSolver`` that shape the traced paths.

    Attributes
    ----------
    max_depth : int
        Maximum number of interactions per path (>= 0; 0 traces line of sight only).
    samples_per_src : int
        Rays shot from the transmitter (>= 1). The box hall needs >= 1e4 to find every specular
        path up to depth 4; a panel a few centimetres wide needs >= 3e5.
    max_num_paths_per_src : int
        Upper bound on paths kept per transmitter (>= 1).
    specular_reflection, diffuse_reflection, refraction, diffraction : bool
        Interaction types to trace. Refraction is off by default (sionna's default is on): a
        closed hall of thin slabs gives the same paths without it.
    seed : int
        Seed of the ray sampler (>= 0). With the deterministic solver used here the result is
        bit-identical run to run for one seed.
    scattering_coefficient : float or None
        S in [0, 1] given to every material of the scene for this trace (sionna-rt's
        ``RadioMaterial.scattering_coefficient``: a fraction S² of the reflected power is
        scattered diffusely with a Lambertian pattern, the specular part keeps 1 − S²). ``None``
        (default) keeps the scene's own values (0 for the example halls, so diffuse reflection
        finds nothing there without it). Rough concrete at 60 GHz: S ≈ 0.2–0.4.
    """

    max_depth: int = 3
    samples_per_src: int = 100_000
    max_num_paths_per_src: int = 1_000_000
    specular_reflection: bool = True
    diffuse_reflection: bool = False
    refraction: bool = False
    diffraction: bool = False
    seed: int = 42
    scattering_coefficient: float | None = None

    def __post_init__(self) -> None:
        bounds = {"max_depth": (0, MAX_DEPTH), "samples_per_src": (1, MAX_SAMPLES),
                  "max_num_paths_per_src": (1, MAX_SAMPLES), "seed": (0, 2**31 - 1)}
        for name, (low, high) in bounds.items():
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise TypeError(f"{name}={value!r} must be an int")
            if value < low:
                raise ValueError(f"{name}={value!r} must be >= {low}")
            if value > high:
                why = _WHY[name]
                raise ValueError(f"{name}={value!r} must be <= {high} ({why})")
            object.__setattr__(self, name, int(value))
        for name in ("specular_reflection", "diffuse_reflection", "refraction", "diffraction"):
            value = getattr(self, name)
            if not isinstance(value, (bool, np.bool_)):
                raise TypeError(f"{name}={value!r} must be True or False")
            object.__setattr__(self, name, bool(value))
        s = self.scattering_coefficient
        if s is not None:
            if isinstance(s, bool) or not isinstance(s, (int, float, np.integer, np.floating)) or not 0.0 <= float(s) <= 1.0:
                raise ValueError(f"scattering_coefficient={s!r} must be a number in [0, 1] (or None: the scene's own)")
            object.__setattr__(self, "scattering_coefficient", float(s))

    def to_dict(self) -> dict[str, Any]:
        """Plain ``{field: value}`` (JSON-serialisable); inverse: ``TraceSettings(**d)``.

        ``scattering_coefficient`` is left out while it is ``None``, so the trace-cache keys of
        settings that do not use it are those of earlier versions.
        """
        d = asdict(self)
        if d["scattering_coefficient"] is None:
            del d["scattering_coefficient"]
        return d

    def memory_estimate(self, num_receivers: int = 2) -> int:
        """Peak memory of one sionna-rt solve with these settings [bytes] (an upper estimate).

        Notes
        -----
        Measured on the paper hall (sionna-rt 2.2, LLVM backend): 0.12 GB at depth 3, 0.64 GB at
        depth 6 and 17 GB at depth 12 for 10⁵ rays. The candidate paths grow about 1.6× per extra
        bounce until ``max_num_paths_per_src`` caps them, and each costs ~1.5 kB per interaction:
        ``P = min(max_num_paths_per_src, 0.3·samples·1.6^(depth-3))``,
        ``bytes = 1500·P·(depth+1) + 64·samples·(depth+1)·receivers + 300 MB``.
        """
        depth = self.max_depth + 1
        paths = min(float(self.max_num_paths_per_src), 0.3 * self.samples_per_src * 1.6 ** max(self.max_depth - 3, 0))
        return int(1500 * paths * depth + 64 * self.samples_per_src * depth * max(num_receivers, 1) + 300e6)


@dataclass(frozen=True)
class TraceResult:
    """Paths of one radar pose in one scene: the monostatic echoes and one leg per RIS.

    Attributes
    ----------
    monostatic : TracedPaths
        Transmitter and receiver at the radar, both moving with ``radar_velocity``: round-trip
        paths (``delay`` is the round-trip delay [s]).
    legs : tuple of TracedPaths
        One per RIS point, in the order given: transmitter at the radar (moving), receiver at the
        RIS point (static): one-way radar → RIS paths.
    scene_hash : str
        :func:`risloc_rt.hall.raytrace.scene_content_hash` of the traced scene.
    cache_hit : bool
        True when the result was read from a :class:`risloc_rt.hall.raytrace.TraceCache`.
    timing : dict
        Wall-clock seconds of this call: ``hash``, ``cache_read``, ``load`` (0 when the scene was
        already loaded in this process; the first load in a process includes importing sionna-rt,
        about 1 s), ``solve`` (includes Dr.Jit's kernel compilation on a cold ``~/.drjit``),
        ``convert``, ``cache_write``; 0 for steps that did not run (a cache hit runs only ``hash``
        and ``cache_read``).
    settings : TraceSettings
        Solver options used.
    radar_velocity : float array [3]
        Radar velocity the delay rates were computed for [m/s].
    """

    monostatic: TracedPaths
    legs: tuple[TracedPaths, ...]
    scene_hash: str
    cache_hit: bool
    timing: dict[str, float] = field(compare=False)
    settings: TraceSettings = field(default_factory=TraceSettings)
    radar_velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        if not isinstance(self.monostatic, TracedPaths):
            raise TypeError(f"monostatic must be a TracedPaths, got {type(self.monostatic).__name__}")
        legs = tuple(self.legs)
        for i, leg in enumerate(legs):
            if not isinstance(leg, TracedPaths):
                raise TypeError(f"legs[{i}] must be a TracedPaths, got {type(leg).__name__}")
        if not isinstance(self.settings, TraceSettings):
            raise TypeError(f"settings must be a TraceSettings, got {type(self.settings).__name__}")
        velocity = np.array(self.radar_velocity, dtype=float)
        if velocity.shape != (3,) or not np.all(np.isfinite(velocity)):
            raise ValueError(f"radar_velocity={self.radar_velocity!r} must be 3 finite numbers [m/s]")
        velocity.setflags(write=False)
        object.__setattr__(self, "legs", legs)
        object.__setattr__(self, "radar_velocity", velocity)
        object.__setattr__(self, "timing", {k: float(v) for k, v in self.timing.items()})

    @property
    def radar_position(self) -> np.ndarray:
        """Radar position [m], float [3] (``monostatic.tx_position``)."""
        return self.monostatic.tx_position

    @property
    def ris_positions(self) -> np.ndarray:
        """RIS points [m], float [R, 3] (each leg's ``rx_position``)."""
        return np.array([leg.rx_position for leg in self.legs], dtype=float).reshape(-1, 3)

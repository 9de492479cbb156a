"""The RIS beam sweep: one steering angle per frame."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .validation import as_finite_array, finite, positive

__all__ = ["BeamSweep"]


@dataclass(frozen=True)
class BeamSweep:
    """Steering angles of the RIS beams, one beam (frame) after another.

    Parameters
    ----------
    angles : float array [M, 2]
        ``[az, el]`` of beam m relative to RIS broadside, RIS frame [rad]
        (``docs/conventions.md``).
    """

    angles: np.ndarray

    def __post_init__(self) -> None:
        a = as_finite_array(self.angles, "angles", shape=(None, 2)).copy()
        if np.any(np.abs(a) > np.pi / 2):
            raise ValueError(
                "angles must lie within ±π/2 rad of broadside (a beam cannot be steered behind "
                f"the panel); got extremes {np.rad2deg(a.min()):.1f}°, {np.rad2deg(a.max()):.1f}°. "
                "Angles are in radians: convert degrees with numpy.deg2rad"
            )
        a.setflags(write=False)
        object.__setattr__(self, "angles", a)

    @classmethod
    def azimuth_grid(cls, start: float, stop: float, step: float, *, elevation: float = 0.0) -> "BeamSweep":
        """Azimuth sweep ``start, start+step, …, stop`` at a fixed elevation.

        Parameters
        ----------
        start, stop : float
            First and last azimuth (inclusive) [rad].
        step : float
            Azimuth increment, > 0 [rad]; ``(stop - start)/step`` must be a whole number.
        elevation : float
            Elevation of every beam [rad].

        Examples
        --------
        The paper's sweep, -45° to 45° in 1.5° steps (61 beams)::

            BeamSweep.azimuth_grid(*np.deg2rad([-45, 45, 1.5]))
        """
        start = finite(start, "start", "rad")
        stop = finite(stop, "stop", "rad")
        step = positive(step, "step", "rad")
        if stop < start:
            raise ValueError(f"stop={stop} must be >= start={start} [rad]")
        count = (stop - start) / step
        n = int(round(count))
        if abs(count - n) > 1e-6:
            raise ValueError(
                f"(stop - start)/step = {count:.6g} is not a whole number; choose a step that "
                "divides the span so that stop is on the grid"
            )
        az = np.linspace(start, stop, n + 1)
        return cls(np.column_stack([az, np.full_like(az, finite(elevation, "elevation", "rad"))]))

    @property
    def num_beams(self) -> int:
        """M, the number of beams (frames)."""
        return int(self.angles.shape[0])

    @property
    def azimuth(self) -> np.ndarray:
        """Azimuth of each beam [M] [rad]."""
        return self.angles[:, 0]

    @property
    def elevation(self) -> np.ndarray:
        """Elevation of each beam [M] [rad]."""
        return self.angles[:, 1]

    def index_of(self, angle: Any, *, atol: float = 1e-9) -> int | None:
        """Index of the beam steered at ``angle`` ([az, el] [rad]), or ``None`` if off-grid."""
        a = as_finite_array(angle, "angle", shape=(2,))
        hits = np.flatnonzero(np.all(np.abs(self.angles - a) <= atol, axis=1))
        return int(hits[0]) if hits.size else None

    def to_dict(self) -> dict[str, Any]:
        """``{"angles": [[az, el], ...]}`` [rad]."""
        return {"angles": self.angles.tolist()}

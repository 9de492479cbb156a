"""The radar's antenna pattern: how strongly each path is sent and received."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dsp import db_to_linear
from dsp.validation import as_finite_array, finite, non_negative

__all__ = ["RadarAntenna"]


@dataclass(frozen=True)
class RadarAntenna:
    """Rotationally symmetric one-way power pattern of the radar's Tx (and, identically, Rx) antenna.

    ``g(ψ) = max(cos^q ψ, floor)`` for an angle ψ off ``boresight`` (``floor`` also behind the
    radar), normalised to 1 on boresight. The absolute gain stays the paper's combined
    G_trx, so a path leaving and arriving on boresight gets exactly G_trx and the paper's
    free-space link budget is unchanged; a path leaving at ψ_t and arriving from ψ_r gets
    ``G_trx · g(ψ_t) · g(ψ_r)``.

    Parameters
    ----------
    boresight : float array [3]
        Pointing direction, world frame (any non-zero length).
    exponent : float, default 2
        q; 0 makes the pattern isotropic. q = 2 has its one-way half-power points at ±45°,
        close to the AWR6843ISK's ±50° azimuth field of view.
    floor_db : float, default -25
        Lowest one-way pattern value (side and back lobes) relative to boresight [dB].
    """

    boresight: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0]))
    exponent: float = 2.0
    floor_db: float = -25.0

    def __post_init__(self) -> None:
        b = as_finite_array(self.boresight, "boresight", shape=(3,))
        norm = float(np.linalg.norm(b))
        if norm == 0:
            raise ValueError("boresight must be a non-zero vector")
        b = b / norm
        b.setflags(write=False)
        object.__setattr__(self, "boresight", b)
        object.__setattr__(self, "exponent", non_negative(self.exponent, "exponent", "unitless"))
        fl = finite(self.floor_db, "floor_db", "dB")
        if fl > 0:
            raise ValueError(f"floor_db={fl} must be <= 0 dB (relative to boresight)")
        object.__setattr__(self, "floor_db", fl)

    @classmethod
    def isotropic(cls) -> "RadarAntenna":
        """g = 1 in every direction (the paper's point-target simulator)."""
        return cls(exponent=0.0, floor_db=0.0)

    @classmethod
    def facing(cls, position: Any, target: Any, **kwargs: Any) -> "RadarAntenna":
        """Pattern whose boresight points from ``position`` to ``target`` (world, [m])."""
        return cls(boresight=np.asarray(target, float) - np.asarray(position, float), **kwargs)

    def gain(self, directions: Any) -> np.ndarray:
        """One-way power pattern g [...] for unit directions [..., 3] (world frame) [unitless]."""
        d = as_finite_array(directions, "directions", trailing=(3,), allow_empty=True)
        if self.exponent == 0:
            return np.ones(d.shape[:-1])
        cos = np.clip(d @ self.boresight, 0.0, 1.0)
        return np.maximum(cos**self.exponent, float(db_to_linear(self.floor_db)))

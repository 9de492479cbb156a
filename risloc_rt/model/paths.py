"""Propagation paths UE → … → UE that feed the beat-signal model."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from dsp._validate import as_finite_array

__all__ = ["PathSet"]


@dataclass(frozen=True)
class PathSet:
    """A set of L round-trip paths, each a 2-D tone in the beat signal.

    Attributes
    ----------
    gain : complex array [L]
        γ_l, complex amplitude at the radar's ADC, *without* the RIS array response,
        including the carrier phase ``exp(-j2π f_c τ_l)`` [√W].
    delay : float array [L]
        τ_l, round-trip delay, including τ_RB for RIS loop-back paths [s].
    delay_rate : float array [L]
        ν_l = dτ_l/dt, positive when the path lengthens [s/s].
    ris_incidence : float array [L, 2]
        For RIS loop-back paths, ``[az, el]`` (RIS frame) toward where the wave reaching the RIS
        comes from; NaN for paths that do not pass through the RIS re-transmission [rad].
    ris_departure : float array [L, 2]
        For RIS loop-back paths, ``[az, el]`` toward where the re-transmitted wave leaves;
        NaN otherwise [rad].
    labels : tuple of str, length L
        What produced each path (``"ris_loopback"``, ``"ris_structure"``, ``"target"``, …).
    """

    gain: np.ndarray
    delay: np.ndarray
    delay_rate: np.ndarray
    ris_incidence: np.ndarray
    ris_departure: np.ndarray
    labels: tuple[str, ...]

    def __post_init__(self) -> None:
        gain = as_finite_array(self.gain, "gain", shape=(None,), dtype=complex, allow_empty=True)
        n = gain.shape[0]
        delay = as_finite_array(self.delay, "delay", shape=(n,), allow_empty=True)
        rate = as_finite_array(self.delay_rate, "delay_rate", shape=(n,), allow_empty=True)
        inc = np.asarray(self.ris_incidence, dtype=float).reshape(-1, 2) if n else np.zeros((0, 2))
        dep = np.asarray(self.ris_departure, dtype=float).reshape(-1, 2) if n else np.zeros((0, 2))
        for name, value in (("ris_incidence", inc), ("ris_departure", dep)):
            if value.shape != (n, 2):
                raise ValueError(f"{name} has shape {list(value.shape)}, expected [{n}, 2]")
            if np.any(np.isinf(value)):
                raise ValueError(f"{name} contains infinite values; use NaN for non-RIS paths")
        if not np.array_equal(np.isnan(inc).any(axis=1), np.isnan(dep).any(axis=1)):
            raise ValueError("ris_incidence and ris_departure must be NaN on the same paths")
        if np.any(delay < 0):
            raise ValueError(f"delay contains negative values (min {delay.min():.3e} s); delays are >= 0")
        labels = tuple(str(x) for x in self.labels)
        if len(labels) != n:
            raise ValueError(f"labels has {len(labels)} entries, expected {n} (one per path)")
        for name, value in (("gain", gain), ("delay", delay), ("delay_rate", rate),
                            ("ris_incidence", inc), ("ris_departure", dep)):
            value = value.copy()
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "labels", labels)

    @classmethod
    def empty(cls) -> "PathSet":
        """A set with no paths."""
        return cls(np.zeros(0, complex), np.zeros(0), np.zeros(0), np.zeros((0, 2)), np.zeros((0, 2)), ())

    @classmethod
    def concatenate(cls, sets: Any) -> "PathSet":
        """Join several path sets into one (order kept)."""
        sets = list(sets)
        if not sets:
            return cls.empty()
        return cls(
            gain=np.concatenate([s.gain for s in sets]),
            delay=np.concatenate([s.delay for s in sets]),
            delay_rate=np.concatenate([s.delay_rate for s in sets]),
            ris_incidence=np.concatenate([s.ris_incidence for s in sets]),
            ris_departure=np.concatenate([s.ris_departure for s in sets]),
            labels=sum((s.labels for s in sets), ()),
        )

    def __len__(self) -> int:
        return int(self.gain.shape[0])

    @property
    def via_ris(self) -> np.ndarray:
        """Mask [L] of the RIS loop-back paths (those with RIS angles)."""
        return ~np.isnan(self.ris_incidence).any(axis=1)

    @property
    def power(self) -> np.ndarray:
        """|γ_l|² [L] [W] (RIS paths before the array response)."""
        return np.abs(self.gain) ** 2

"""Propagation paths UE → … → UE that feed the beat-signal model, and the operations on them.

:class:`PathSet` (one geometry) and :class:`PathFrames` (one geometry per frame) hold the paths;
:func:`select_paths` keeps some of them and :func:`shift_paths` lengthens them all, e.g. by a
radar's internal range offset (``risloc_rt.measured`` uses both).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from dsp.validation import as_finite_array

__all__ = ["PathFrames", "PathSet", "select_paths", "shift_paths"]


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


@dataclass(frozen=True)
class PathFrames:
    """The same L paths seen from where the UE is during each of M frames (one frame per beam).

    A moving radar (or target) changes every path's delay, delay rate, gain and RIS angles from
    one sweep beam to the next; :func:`risloc_rt.model.beat.beat_cube` synthesises frame m of
    the cube from row m. Path l is the same propagation path in every frame (same label, and it
    goes through the RIS in all frames or in none).

    Attributes
    ----------
    gain : complex array [M, L]
        γ_{m,l} as in :class:`PathSet`: the carrier phase ``exp(-j2π f_c τ)`` at the frame's
        first chirp [√W].
    delay : float array [M, L]
        τ_{m,l}, the round-trip delay at the centre of frame m, which sets the beat frequency
        (no range migration within a frame, as eq. (1)) [s].
    delay_rate : float array [M, L]
        ν_{m,l} during frame m [s/s].
    ris_incidence, ris_departure : float array [M, L, 2]
        RIS angles during frame m; NaN for paths that do not pass through the RIS [rad].
    labels : tuple of str, length L
    times : float array [M]
        Centre time of each frame from the start of the sweep (``RadarConfig.beam_times``) [s].
    """

    gain: np.ndarray
    delay: np.ndarray
    delay_rate: np.ndarray
    ris_incidence: np.ndarray
    ris_departure: np.ndarray
    labels: tuple[str, ...]
    times: np.ndarray

    def __post_init__(self) -> None:
        gain = np.asarray(self.gain, dtype=complex)
        if gain.ndim != 2:
            raise ValueError(f"gain has shape {list(gain.shape)}, expected [M, L] (frames, paths)")
        m, n = gain.shape
        if m < 1:
            raise ValueError("a PathFrames needs at least one frame")
        gain = as_finite_array(gain, "gain", shape=(m, n), dtype=complex, allow_empty=True)
        delay = as_finite_array(self.delay, "delay", shape=(m, n), allow_empty=True)
        rate = as_finite_array(self.delay_rate, "delay_rate", shape=(m, n), allow_empty=True)
        times = as_finite_array(self.times, "times", shape=(m,))
        inc = np.asarray(self.ris_incidence, dtype=float).reshape(m, n, 2)
        dep = np.asarray(self.ris_departure, dtype=float).reshape(m, n, 2)
        for name, value in (("ris_incidence", inc), ("ris_departure", dep)):
            if np.any(np.isinf(value)):
                raise ValueError(f"{name} contains infinite values; use NaN for non-RIS paths")
        via = ~np.isnan(inc).any(axis=2)  # [M, L]
        if not np.array_equal(via, ~np.isnan(dep).any(axis=2)):
            raise ValueError("ris_incidence and ris_departure must be NaN on the same paths")
        if not np.all(via == via[:1]):
            raise ValueError("a path must pass through the RIS in every frame or in none (NaN angles "
                             "on the same paths in every frame)")
        if np.any(delay < 0):
            raise ValueError(f"delay contains negative values (min {delay.min():.3e} s); delays are >= 0")
        labels = tuple(str(x) for x in self.labels)
        if len(labels) != n:
            raise ValueError(f"labels has {len(labels)} entries, expected {n} (one per path)")
        for name, value in (("gain", gain), ("delay", delay), ("delay_rate", rate),
                            ("ris_incidence", inc), ("ris_departure", dep), ("times", times)):
            value = value.copy()
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "labels", labels)

    @classmethod
    def from_frames(cls, frames: Any, times: Any) -> "PathFrames":
        """Stack M :class:`PathSet` (the same L paths in each) into one ``PathFrames``."""
        frames = list(frames)
        if not frames:
            raise ValueError("from_frames needs at least one PathSet")
        labels = frames[0].labels
        for i, f in enumerate(frames):
            if f.labels != labels:
                raise ValueError(f"frame {i} has other paths ({len(f)} labelled {f.labels[:3]}...) than frame 0")
        return cls(
            gain=np.stack([f.gain for f in frames]),
            delay=np.stack([f.delay for f in frames]),
            delay_rate=np.stack([f.delay_rate for f in frames]),
            ris_incidence=np.stack([f.ris_incidence for f in frames]),
            ris_departure=np.stack([f.ris_departure for f in frames]),
            labels=labels,
            times=times,
        )

    @classmethod
    def repeat(cls, paths: PathSet, times: Any) -> "PathFrames":
        """The same paths in every frame (a static geometry), one frame per entry of ``times``."""
        m = np.asarray(times).shape[0]
        tile = lambda x: np.broadcast_to(x, (m,) + x.shape)  # noqa: E731
        return cls(gain=tile(paths.gain), delay=tile(paths.delay), delay_rate=tile(paths.delay_rate),
                   ris_incidence=tile(paths.ris_incidence), ris_departure=tile(paths.ris_departure),
                   labels=paths.labels, times=times)

    def frame(self, m: int) -> PathSet:
        """The paths of frame ``m`` as a :class:`PathSet`.

        Parameters
        ----------
        m : int
            Frame (beam) index.

        Returns
        -------
        PathSet
        """
        return PathSet(gain=self.gain[m], delay=self.delay[m], delay_rate=self.delay_rate[m],
                       ris_incidence=self.ris_incidence[m], ris_departure=self.ris_departure[m],
                       labels=self.labels)

    @property
    def num_frames(self) -> int:
        """M, the number of frames (one per sweep beam)."""
        return int(self.gain.shape[0])

    def __len__(self) -> int:
        return int(self.gain.shape[1])

    @property
    def via_ris(self) -> np.ndarray:
        """Mask [L] of the RIS loop-back paths (those with RIS angles)."""
        return ~np.isnan(self.ris_incidence[0]).any(axis=1)

    @property
    def power(self) -> np.ndarray:
        """|γ_{m,l}|² [M, L] [W] (RIS paths before the array response)."""
        return np.abs(self.gain) ** 2


def select_paths(paths: PathSet, keep: np.ndarray) -> PathSet:
    """The paths of ``paths`` where ``keep`` is true, in their order.

    Parameters
    ----------
    paths : PathSet
        L paths.
    keep : bool array [L]
        Which to keep (e.g. ``paths.via_ris`` or its complement).

    Returns
    -------
    PathSet
        Gains [√W], delays [s], delay rates [s/s], RIS angles [rad] and labels of the kept paths.
    """
    return PathSet(paths.gain[keep], paths.delay[keep], paths.delay_rate[keep], paths.ris_incidence[keep],
                   paths.ris_departure[keep], tuple(lab for lab, k in zip(paths.labels, keep) if k))


def shift_paths(paths: PathSet, delay: float, carrier_frequency: float) -> PathSet:
    """``paths`` with every delay longer by ``delay`` and the carrier phase that goes with it.

    Parameters
    ----------
    paths : PathSet
        L paths.
    delay : float
        Added to every τ_l [s] (a radar's range offset r adds ``2·r/c``).
    carrier_frequency : float
        f_c [Hz]: every gain turns by ``exp(−j2π f_c · delay)``, as eq. (1)'s carrier phase.

    Returns
    -------
    PathSet
        Delays τ_l + ``delay`` [s], gains ``γ_l · exp(−j2π f_c · delay)`` [√W], the rest unchanged.
    """
    return replace(paths, delay=paths.delay + delay,
                   gain=paths.gain * np.exp(-2j * np.pi * carrier_frequency * delay))

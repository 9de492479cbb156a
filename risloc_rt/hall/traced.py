"""Ray-traced paths as plain numpy: the boundary between the ray tracer and the signal model.

:mod:`risloc_rt.hall.raytrace` (the only code that imports sionna-rt, mitsuba and drjit) fills these
containers; everything downstream (RIS leg pairs, the panel's physical-optics reflection,
pruning, the beat cube) works on them with numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from dsp.validation import as_finite_array

__all__ = ["TracedPaths", "INTERACTION_NAMES"]

#: sionna-rt interaction codes (``sionna.rt.InteractionType``) -> short names.
INTERACTION_NAMES: dict[int, str] = {0: "none", 1: "specular", 2: "diffuse", 4: "refraction", 8: "diffraction"}


@dataclass(frozen=True)
class TracedPaths:
    """All paths found between one transmitter and one receiver.

    Attributes
    ----------
    tx_position, rx_position : float array [3]
        World frame [m]. Equal for a monostatic trace.
    frequency : float
        Carrier frequency the materials were evaluated at [Hz].
    delay : float array [L]
        Propagation delay Tx → Rx [s] (round trip for a monostatic trace).
    amplitude : complex array [L]
        Field transfer coefficient with isotropic unit-gain antennas, *without* the propagation
        phase ``exp(-j2π f τ)`` (sionna-rt's ``Paths.a``, V-V): ``|amplitude|² = (λ/(4π L))² Π|Γ|²``
        for specular paths of unfolded length L [unitless].
    departure : float array [L, 3]
        Unit vector along which each path leaves the transmitter, world frame.
    arrival : float array [L, 3]
        Unit vector from the receiver toward where each path comes from (the reverse of the
        propagation direction at the receiver), world frame.
    delay_rate : float array [L]
        dτ/dt from the radios' velocities (positive when the path lengthens) [s/s].
    interactions : int array [L, D]
        Interaction code per bounce (:data:`INTERACTION_NAMES`; 0 = none), D = max depth.
    objects : int array [L, D]
        Index into ``object_names`` of the object hit at each bounce, -1 where none.
    vertices : float array [L, D, 3]
        Interaction points, world frame [m]; NaN where there is no interaction.
    object_names : tuple of str
        Names of the scene objects (shape ids without sionna's ``mesh-`` prefix).
    """

    tx_position: np.ndarray
    rx_position: np.ndarray
    frequency: float
    delay: np.ndarray
    amplitude: np.ndarray
    departure: np.ndarray
    arrival: np.ndarray
    delay_rate: np.ndarray
    interactions: np.ndarray
    objects: np.ndarray
    vertices: np.ndarray
    object_names: tuple[str, ...]

    def __post_init__(self) -> None:
        delay = as_finite_array(self.delay, "delay", shape=(None,), allow_empty=True)
        n = delay.shape[0]
        checks: dict[str, Any] = {
            "tx_position": as_finite_array(self.tx_position, "tx_position", shape=(3,)),
            "rx_position": as_finite_array(self.rx_position, "rx_position", shape=(3,)),
            "delay": delay,
            "amplitude": as_finite_array(self.amplitude, "amplitude", shape=(n,), dtype=complex, allow_empty=True),
            "departure": as_finite_array(self.departure, "departure", shape=(n, 3), allow_empty=True),
            "arrival": as_finite_array(self.arrival, "arrival", shape=(n, 3), allow_empty=True),
            "delay_rate": as_finite_array(self.delay_rate, "delay_rate", shape=(n,), allow_empty=True),
        }
        inter = np.asarray(self.interactions, dtype=np.int64)
        objs = np.asarray(self.objects, dtype=np.int64)
        verts = np.asarray(self.vertices, dtype=float)
        if inter.ndim != 2 or inter.shape[0] != n or objs.shape != inter.shape:
            raise ValueError(f"interactions {list(inter.shape)} and objects {list(objs.shape)} must both be [L={n}, D]")
        if verts.shape != inter.shape + (3,):
            raise ValueError(f"vertices has shape {list(verts.shape)}, expected {list(inter.shape) + [3]}")
        names = tuple(str(x) for x in self.object_names)
        if objs.size and (objs.max() >= len(names) or objs.min() < -1):
            raise ValueError("objects holds an index outside object_names")
        checks.update(interactions=inter, objects=objs, vertices=verts)
        for name, value in checks.items():
            value = np.array(value, copy=True)
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "object_names", names)
        object.__setattr__(self, "frequency", float(self.frequency))

    def __len__(self) -> int:
        return int(self.delay.shape[0])

    @property
    def depth(self) -> np.ndarray:
        """Number of interactions of each path [L] (0 for line of sight)."""
        return (self.interactions != 0).sum(axis=1)

    def describe(self, index: int) -> str:
        """``"specular:wall_x0 > specular:floor"`` for path ``index`` (``"LOS"`` when direct)."""
        parts = [f"{INTERACTION_NAMES.get(int(c), str(int(c)))}:{self.object_names[o] if o >= 0 else '?'}"
                 for c, o in zip(self.interactions[index], self.objects[index]) if c != 0]
        return " > ".join(parts) if parts else "LOS"

    def strongest(self, count: int) -> "TracedPaths":
        """The ``count`` paths of largest |amplitude|, in their original (delay) order.

        Returns ``self`` when it holds no more than ``count`` paths; ties at the cut keep the
        earlier path.
        """
        if len(self) <= count:
            return self
        keep = np.sort(np.argsort(-np.abs(self.amplitude), kind="stable")[:count])
        return TracedPaths(
            tx_position=self.tx_position, rx_position=self.rx_position, frequency=self.frequency,
            delay=self.delay[keep], amplitude=self.amplitude[keep], departure=self.departure[keep],
            arrival=self.arrival[keep], delay_rate=self.delay_rate[keep], interactions=self.interactions[keep],
            objects=self.objects[keep], vertices=self.vertices[keep], object_names=self.object_names,
        )

    def to_arrays(self) -> dict[str, np.ndarray]:
        """Arrays for an ``.npz`` file (object names as a JSON string); inverse: :meth:`from_arrays`."""
        import json

        return {
            "tx_position": self.tx_position, "rx_position": self.rx_position,
            "frequency": np.array(self.frequency), "delay": self.delay, "amplitude": self.amplitude,
            "departure": self.departure, "arrival": self.arrival, "delay_rate": self.delay_rate,
            "interactions": self.interactions, "objects": self.objects, "vertices": self.vertices,
            "object_names": np.array(json.dumps(list(self.object_names))),
        }

    @classmethod
    def from_arrays(cls, arrays: Any) -> "TracedPaths":
        """Inverse of :meth:`to_arrays` (accepts a dict or an open ``NpzFile``)."""
        import json

        return cls(
            tx_position=arrays["tx_position"], rx_position=arrays["rx_position"],
            frequency=float(arrays["frequency"]), delay=arrays["delay"], amplitude=arrays["amplitude"],
            departure=arrays["departure"], arrival=arrays["arrival"], delay_rate=arrays["delay_rate"],
            interactions=arrays["interactions"], objects=arrays["objects"], vertices=arrays["vertices"],
            object_names=tuple(json.loads(str(arrays["object_names"]))),
        )

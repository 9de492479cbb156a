"""Physical-optics scattering of the RIS panel's own structure (a flat rectangular plate)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from dsp import RisPose
from dsp.validation import as_finite_array, positive

__all__ = ["Plate", "plate_scattering", "plate_rcs"]


@dataclass(frozen=True)
class Plate:
    """A thin, flat, perfectly conducting rectangle centred on the RIS pose.

    Parameters
    ----------
    width : float, default 0.10
        Extent along the RIS row axis **u** [m].
    height : float, default 0.05
        Extent along the RIS column axis **w** [m].
    reflection : complex, default -1
        Reflection coefficient of the surface (-1 for a perfect conductor) [unitless].
    """

    width: float = 0.10
    height: float = 0.05
    reflection: complex = -1.0 + 0.0j

    def __post_init__(self) -> None:
        object.__setattr__(self, "width", positive(self.width, "width", "m"))
        object.__setattr__(self, "height", positive(self.height, "height", "m"))
        r = complex(self.reflection)
        if not np.isfinite(r) or abs(r) > 1:
            raise ValueError(f"reflection={self.reflection!r} must be finite with |Γ| <= 1")
        object.__setattr__(self, "reflection", r)

    @property
    def area(self) -> float:
        """A = width · height [m²]."""
        return self.width * self.height


def plate_scattering(plate: Plate, pose: RisPose, incidence: Any, departure: Any, *, wavelength: float) -> np.ndarray:
    """Bistatic physical-optics scattering amplitude S of the plate [L] [unitless].

    Parameters
    ----------
    plate : Plate
    pose : RisPose
        The plate lies in the (u, w) plane of the pose, centred on its position.
    incidence : float array [L, 3]
        Unit vectors from the plate toward where each wave comes from, world frame.
    departure : float array [L, 3]
        Unit vectors from the plate toward where each scattered wave goes, world frame.
    wavelength : float
        λ [m].

    Returns
    -------
    complex array [L]
        S such that a path arriving with one-way coefficient a_p and leaving with a_q has the
        coefficient ``a_p · S · a_q``; ``σ = λ²|S|²/(4π)`` is the bistatic RCS.

    Notes
    -----
    Physical optics for a flat plate of area A, with k = 2π/λ and s = d_inc + d_dep:

        S = Γ · (4π A / λ²) · (n·d_inc + n·d_dep)/2 · sinc(k W s·u / 2) · sinc(k H s·w / 2),

    sinc(x) = sin(x)/x. At normal incidence σ = 4π A²/λ²; monostatically off normal the
    pattern is ``cos²θ · sinc²(k W sinθ)`` in the u plane. A plate lit from behind scatters with
    its back face (normal -n); waves that would cross the plate are blocked (S = 0).
    """
    lam = positive(wavelength, "wavelength", "m")
    d_in = as_finite_array(incidence, "incidence", shape=(None, 3), allow_empty=True)
    d_out = as_finite_array(departure, "departure", shape=(None, 3), allow_empty=True)
    if d_in.shape != d_out.shape:
        raise ValueError(f"incidence {list(d_in.shape)} and departure {list(d_out.shape)} must match")
    k = 2 * np.pi / lam
    n, u, w = pose.normal, pose.row_axis, pose.column_axis
    c_in, c_out = d_in @ n, d_out @ n
    same_side = c_in * c_out > 0
    obliquity = np.where(same_side, np.abs(c_in + c_out) / 2, 0.0)
    s = d_in + d_out
    pattern = np.sinc(k * plate.width * (s @ u) / (2 * np.pi)) * np.sinc(k * plate.height * (s @ w) / (2 * np.pi))
    return plate.reflection * (4 * np.pi * plate.area / lam**2) * obliquity * pattern


def plate_rcs(plate: Plate, pose: RisPose, direction: Any, *, wavelength: float) -> np.ndarray:
    """Monostatic RCS σ [L] [m²] seen from unit ``direction`` [L, 3] (plate toward the radar)."""
    d = as_finite_array(direction, "direction", shape=(None, 3))
    s = plate_scattering(plate, pose, d, d, wavelength=wavelength)
    return wavelength**2 * np.abs(s) ** 2 / (4 * np.pi)

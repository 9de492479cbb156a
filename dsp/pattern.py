"""The RIS beam pattern seen by the radar over a sweep: what the AoD fit and the CRB need.

A RIS of ``num_rows × num_columns`` elements at spacing d, steered at φ_m, returns to a UE at
AoD θ the complex gain (``docs/conventions.md``, "RIS response")

    r_m(θ) ∝ Σ_x exp(j q k x·(d(θ) - d(φ_m))),     k = 2π/λ,

with q = 1 for a relay RIS (Rx beam fixed, Tx beam swept: only the Tx array follows the sweep)
and q = 2 for a reflective RIS (eq. (1): ω_m = exp(-2j Xᵀ g(φ_m)) doubles the phase gradient).
On the centred grid it factorises into two Dirichlet kernels, real and signed,

    A_m(θ) = D_{N_az}(q k d Δu) · D_{N_el}(q k d Δw),   D_N(x) = sin(N x/2) / (N sin(x/2)),

Δu = cos(el) sin(az) - cos(el_m) sin(az_m) and Δw = sin(el) - sin(el_m) the differences of the
direction cosines along the row axis **u** and the column axis **w**; |A| peaks at 1. Everything
the sweep does not change (the relay Rx gain, ζ, the path loss, the carrier phase) is a common
factor and sits in the complex amplitude that the estimators treat as unknown.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .validation import as_finite_array, positive, positive_int
from .geometry import direction_from_angles
from .radar import SPEED_OF_LIGHT

__all__ = ["BeamPattern", "dirichlet"]

#: λ/2 at 60 GHz [m], the default element spacing (as ``risloc_rt``'s RisConfig).
_HALF_WAVELENGTH_60GHZ = SPEED_OF_LIGHT / 60e9 / 2


def dirichlet(x: Any, n: int) -> np.ndarray:
    """Normalised Dirichlet kernel ``sin(n x/2) / (n sin(x/2))`` (1 at x = 0 mod 2π, signed).

    Parameters
    ----------
    x : float array [...]
        Phase step between neighbouring elements [rad].
    n : int
        Number of elements.

    Notes
    -----
    Evaluated on x reduced to [−π, π] (x = 2πj + r, the kernel (−1)^{j(n−1)} times its value at r):
    near a grating lobe (r → 0, j ≠ 0) both sines are then small numbers known to full relative
    precision, where sin(x/2) of the unreduced x loses the digits of r to πj's (1.5 % of the value at
    r = 1e-13 for n = 33). For |x| <= π nothing is reduced.
    """
    x = np.asarray(x, dtype=float)
    j = np.rint(x * (0.5 / np.pi))
    wrapped = j.any()
    r = x - (2.0 * np.pi) * j if wrapped else x
    half = 0.5 * r
    den = n * np.sin(half)
    small = np.abs(den) < 1e-12
    if small.any():  # r = 0 to within 1e-12 · 2/n: the limit, 1
        with np.errstate(invalid="ignore", divide="ignore"):
            out = np.where(small, 1.0, np.sin(n * half) / np.where(small, 1.0, den))
    else:  # the common case (called hundreds of times per fit)
        out = np.sin(n * half) / den
    if wrapped and (n - 1) % 2:
        out = np.where(np.fmod(j, 2.0) != 0, -out, out)
    return out


@dataclass(frozen=True)
class BeamPattern:
    """Array factor of a swept RIS, normalised to a peak magnitude of 1.

    Parameters
    ----------
    num_rows : int, default 16
        Elements along the row axis **u** (azimuth), N_RIS^az.
    num_columns : int, default 4
        Elements along the column axis **w** (elevation), N_RIS^el.
    element_spacing : float, default λ/2 at 60 GHz (2.498 mm)
        Element pitch d [m].
    gradient_factor : {1, 2}, default 1
        q: 1 for a relay RIS (the paper's experiment: Rx fixed, Tx swept), 2 for a reflective
        RIS (eq. (1)'s doubled phase gradient; grating lobes at Δu = ±λ/(2d) = ±1 for λ/2).
    wavelength : float or None, default None
        λ [m]; ``None`` takes the radar's (:meth:`for_wavelength`).
    """

    num_rows: int = 16
    num_columns: int = 4
    element_spacing: float = _HALF_WAVELENGTH_60GHZ
    gradient_factor: int = 1
    wavelength: float | None = None

    def __post_init__(self) -> None:
        set_ = lambda name, value: object.__setattr__(self, name, value)  # noqa: E731
        set_("num_rows", positive_int(self.num_rows, "num_rows"))
        set_("num_columns", positive_int(self.num_columns, "num_columns"))
        set_("element_spacing", positive(self.element_spacing, "element_spacing", "m"))
        if self.gradient_factor not in (1, 2) or isinstance(self.gradient_factor, bool):
            raise ValueError(
                f"gradient_factor={self.gradient_factor!r} must be 1 (relay RIS) or 2 (reflective RIS, eq. (1))"
            )
        set_("gradient_factor", int(self.gradient_factor))
        if self.wavelength is not None:
            set_("wavelength", positive(self.wavelength, "wavelength", "m"))

    @classmethod
    def relay(cls, **kw: Any) -> "BeamPattern":
        """Relay RIS (q = 1), the paper's experiment; keywords as the constructor."""
        return cls(gradient_factor=1, **kw)

    @classmethod
    def reflective(cls, **kw: Any) -> "BeamPattern":
        """Reflective RIS of eq. (1) (q = 2); keywords as the constructor."""
        return cls(gradient_factor=2, **kw)

    def for_wavelength(self, wavelength: float) -> "BeamPattern":
        """This pattern with λ set (kept if already set) [m]."""
        if self.wavelength is not None:
            return self
        return replace(self, wavelength=positive(wavelength, "wavelength", "m"))

    @property
    def num_elements(self) -> int:
        """N_RIS = num_rows · num_columns."""
        return self.num_rows * self.num_columns

    def _phase_per_unit(self) -> float:
        if self.wavelength is None:
            raise ValueError("BeamPattern.wavelength is None; call pattern.for_wavelength(radar.wavelength) first")
        return self.gradient_factor * 2.0 * np.pi / self.wavelength * self.element_spacing

    @property
    def grating_period(self) -> float:
        """Δu between grating lobes, λ/(q d) [unitless direction cosine]."""
        return 2.0 * np.pi / self._phase_per_unit()

    @property
    def null_width(self) -> float:
        """Half-width of the main lobe to its first null along **u**, λ/(q d N_az) [direction cosine]."""
        return self.grating_period / self.num_rows

    def amplitude(self, aod: Any, beams: Any) -> np.ndarray:
        """A_m(θ): real, signed, normalised array factor (|A| <= 1).

        Parameters
        ----------
        aod : float array [..., 2]
            UE direction(s) ``[az, el]`` seen from the RIS [rad].
        beams : float array [M, 2]
            Steering angles φ_m ``[az, el]`` [rad].

        Returns
        -------
        float array [..., M]
        """
        c = self._phase_per_unit()
        d_ue = direction_from_angles(aod)  # [..., 3] (u, w, n)
        d_b = direction_from_angles(as_finite_array(beams, "beams", shape=(None, 2)))  # [M, 3]
        du = d_ue[..., None, 0] - d_b[:, 0]
        dw = d_ue[..., None, 1] - d_b[:, 1]
        return dirichlet(c * du, self.num_rows) * dirichlet(c * dw, self.num_columns)

    def amplitude_u(self, u: Any, beams: Any, *, w: float = 0.0) -> np.ndarray:
        """A_m as a function of the direction cosines (u, w) of the UE [..., M].

        Parameters
        ----------
        u : float array [...]
            cos(el)·sin(az) of the UE [unitless].
        beams : float array [M, 2]
            Steering angles [rad].
        w : float
            sin(el) of the UE [unitless].
        """
        c = self._phase_per_unit()
        d_b = direction_from_angles(as_finite_array(beams, "beams", shape=(None, 2)))
        du = np.asarray(u, dtype=float)[..., None] - d_b[:, 0]
        dw = float(w) - d_b[:, 1]
        return dirichlet(c * du, self.num_rows) * dirichlet(c * dw, self.num_columns)

    def gradient(self, aod: Any, beams: Any, *, step: float = 1e-6) -> np.ndarray:
        """∂A_m/∂(az, el) at ``aod`` [2] by central differences, [M, 2] [1/rad]."""
        a = as_finite_array(aod, "aod", shape=(2,))
        out = []
        for i in range(2):
            e = np.zeros(2)
            e[i] = step
            out.append((self.amplitude(a + e, beams) - self.amplitude(a - e, beams)) / (2 * step))
        return np.stack(out, axis=-1)

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON dictionary of the fields."""
        return {"num_rows": self.num_rows, "num_columns": self.num_columns,
                "element_spacing": self.element_spacing, "gradient_factor": self.gradient_factor,
                "wavelength": self.wavelength}

"""Processing parameters of the delay-Doppler DSP (Sec. III of the seed paper)."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any, Literal

import numpy as np
import scipy.signal

from .validation import dataclass_from_dict, non_negative, positive, positive_int

__all__ = ["ProcessingConfig", "window_vector"]

DopplerSearch = Literal["zoom", "full"]


def window_vector(name: str, length: int) -> np.ndarray:
    """DFT-even window of ``length`` samples by scipy name [length] [unitless].

    ``"hann"`` is the paper's ``w_A(a) = sin²(aπ/A)``, a = 0…A-1 (scipy's periodic Hann).
    """
    try:
        return scipy.signal.get_window(name, positive_int(length, "length"), fftbins=True)
    except ValueError as exc:
        raise ValueError(
            f"window={name!r} is not a window scipy.signal.get_window knows ({exc}); use e.g. "
            "'hann' (the paper's), 'hamming', 'blackman' or 'boxcar'"
        ) from None


@dataclass(frozen=True)
class ProcessingConfig:
    """How a beat cube is turned into delay, Doppler, AoD and position.

    Parameters
    ----------
    n_dft : int, default 1199
        N_DFT, fast-time DFT length after zero padding (>= the radar's N).
    k_dft : int, default 4793
        K_DFT, slow-time DFT length after zero padding (>= the radar's K).
    window : str, default "hann"
        Window applied along both axes; any :func:`scipy.signal.get_window` name.
    delta : float, default 0.33e-9
        Δ, half-width of the delay interval of P_ave, eq. (P_ave) [s].
    min_range : float, default 0
        Near-range exclusion: delay bins with τ·c/2 < ``min_range`` are not searched for the
        peak (e.g. to skip Tx→Rx leakage in measured data) [m].
    doppler_search : {"zoom", "full"}, default "zoom"
        ``"full"`` evaluates the whole N_DFT × K_DFT map per beam, as in the paper.
        ``"zoom"`` screens the delay columns with a complex64 transform at the native grid
        (:mod:`dsp.gridscreen`), evaluates the few that can hold the maximum exactly in float64,
        and finds their Doppler on a coarse grid of ``zoom_oversampling``·K bins refined to the
        exact K_DFT grid in a strip around the strongest coarse bins; the result is the same grid
        maximum and P_ave (tests check it against ``"full"``) at ~1/70 the cost.
    zoom_oversampling : int, default 4
        Coarse slow-time oversampling factor of the ``"zoom"`` search (>= 2).
    zoom_margin_db : float, default 1.0
        Coarse Doppler bins within this many dB of the coarse maximum are refined [dB]; it
        must exceed the window's scalloping loss on the coarse grid (0.1 dB for Hann at 4×).
    """

    n_dft: int = 1199
    k_dft: int = 4793
    window: str = "hann"
    delta: float = 0.33e-9
    min_range: float = 0.0
    doppler_search: DopplerSearch = "zoom"
    zoom_oversampling: int = 4
    zoom_margin_db: float = 1.0

    def __post_init__(self) -> None:
        set_ = lambda name, value: object.__setattr__(self, name, value)  # noqa: E731
        set_("n_dft", positive_int(self.n_dft, "n_dft"))
        set_("k_dft", positive_int(self.k_dft, "k_dft"))
        if not isinstance(self.window, str):
            raise TypeError(f"window={self.window!r} must be a scipy window name such as 'hann'")
        window_vector(self.window, 8)  # fail early on unknown names
        set_("delta", non_negative(self.delta, "delta", "s"))
        set_("min_range", non_negative(self.min_range, "min_range", "m"))
        if self.doppler_search not in ("zoom", "full"):
            raise ValueError(f"doppler_search={self.doppler_search!r} must be 'zoom' or 'full'")
        set_("zoom_oversampling", positive_int(self.zoom_oversampling, "zoom_oversampling"))
        if self.zoom_oversampling < 2:
            raise ValueError(f"zoom_oversampling={self.zoom_oversampling} must be >= 2")
        set_("zoom_margin_db", positive(self.zoom_margin_db, "zoom_margin_db", "dB"))

    def check_against(self, num_samples: int, num_chirps: int) -> None:
        """Raise if the DFT lengths are shorter than the data (zero padding cannot truncate)."""
        if self.n_dft < num_samples:
            raise ValueError(
                f"n_dft={self.n_dft} is smaller than the number of ADC samples N={num_samples}; "
                f"use n_dft >= {num_samples} (the paper uses 2N-1)"
            )
        if self.k_dft < num_chirps:
            raise ValueError(
                f"k_dft={self.k_dft} is smaller than the number of chirps K={num_chirps}; "
                f"use k_dft >= {num_chirps}"
            )

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON dictionary of the fields (SI units)."""
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any], *, require_all: bool = False) -> "ProcessingConfig":
        """Inverse of :meth:`to_dict`; unknown (or, with ``require_all``, missing) keys raise."""
        return dataclass_from_dict(cls, data, "processing", require_all=require_all)

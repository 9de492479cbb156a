"""Self-interference removal: the Tx→Rx leakage and the DC offset near zero range.

A monostatic FMCW radar hears its own transmitter: the Tx→Rx leakage is a strong beat tone a few
centimetres from zero range (its phase noise spreads it along Doppler), and the ADC's DC offset
sits at zero beat frequency. Two documented methods remove them before localization:

``"gate"`` — a **range gate**: every chirp is projected onto the orthogonal complement of the
    discrete prolate spheroidal (Slepian) subspace of the beat frequencies ``|f| ≤ f_g`` with
    ``f_g = 2·S·r_gate/c`` (``scipy.signal.windows.dpss``, time-bandwidth product
    NW = ``N·f_g/f_s``, ``⌊2NW⌋ + 9`` tapers: the Shannon number plus ``EXTRA_TAPERS``). Any
    tone below the gate loses ~90 dB (Table I, 0.5 m gate: −87 … −99 dB), so the leakage, its
    phase-noise skirt and the DC offset go, while a tone beyond the gate keeps its amplitude
    (Table I: −0.6 dB at 0.7 m, −0.2 dB at 1 m, nothing measurable at 13.6 m; a fraction
    ≈ taper count / N of the noise goes too). Needs nothing but the chirp.
``"background"`` — **background subtraction**: the coherent mean of the frames with the RIS
    off (``[K, N]``, per chirp and sample) is subtracted from every frame. It removes
    everything that does not depend on the RIS (leakage, DC, the hall's static echoes, the
    panel's structural reflection) at any range, adds the off-frames' mean noise
    (``σ²/F_off``), and is valid only for a static radar and a static leakage (the jitter of the
    leakage's phase noise stays). Needs RIS-off frames (the sync pattern's off frames, or the
    frames around the sweep).
``"none"`` — keep the cube as recorded.

Both are linear and act on ``[..., K, N]`` arrays.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
import scipy.signal

from dsp import RadarConfig
from dsp.radar import SPEED_OF_LIGHT

from ..errors import MeasuredFormatError

__all__ = ["LEAKAGE_METHODS", "DEFAULT_GATE_RANGE", "LeakageMethod", "range_gate_basis", "apply_range_gate",
           "subtract_background"]

LeakageMethod = Literal["gate", "background", "none"]
LEAKAGE_METHODS = ("gate", "background", "none")
EXTRA_TAPERS = 8
"""Tapers beyond the Shannon number 2NW: they take a tone anywhere below the gate down by ~90 dB
(⌊2NW⌋ + 1 alone: ~25 dB) for ~4 more range cells of transition band."""
DEFAULT_GATE_RANGE = 0.5
"""Default range gate r_gate [m]: leakage and DC lie within a few range cells of zero range."""


def range_gate_basis(radar: RadarConfig, gate_range: float = DEFAULT_GATE_RANGE) -> np.ndarray:
    """Orthonormal Slepian basis ``V [N, T]`` of the beat frequencies below the gate (module docstring).

    Parameters
    ----------
    radar : RadarConfig
        Slope S [Hz/s], sample rate f_s [Hz], N samples.
    gate_range : float
        r_gate [m]; beat frequencies ``|f| ≤ 2·S·r_gate/c`` are removed.

    Returns
    -------
    float array [N, T]
        Orthonormal columns (T tapers) spanning the gated beat frequencies.
    """
    if not np.isfinite(gate_range) or gate_range <= 0:
        raise MeasuredFormatError(f"gate range {gate_range!r} must be a positive number of metres, e.g. 0.5")
    n = radar.num_samples
    f_gate = 2.0 * radar.slope * gate_range / SPEED_OF_LIGHT
    nw = n * f_gate / radar.sample_rate
    count = int(np.floor(2 * nw)) + 1 + EXTRA_TAPERS
    if count >= n // 2:
        raise MeasuredFormatError(
            f"gate range {gate_range:g} m covers {count} of the chirp's {n} samples' degrees of freedom (beat "
            f"frequencies below {f_gate / 1e6:.3g} MHz of {radar.sample_rate / 1e6:.3g} MHz); give a shorter gate, "
            f"e.g. --gate-range {0.1 * radar.max_range:.2g}")
    tapers = scipy.signal.windows.dpss(n, max(nw, 1e-3), Kmax=count, norm=2)      # [T, N], unit energy
    return np.ascontiguousarray(np.atleast_2d(tapers).T)                            # [N, T]


def apply_range_gate(cube: np.ndarray, basis: np.ndarray) -> np.ndarray:
    """``y − (y V) Vᵀ`` along the last (sample) axis: ``cube [..., N]`` without the gated band.

    Parameters
    ----------
    cube : array [..., N]
        Chirps [ADC counts or √W].
    basis : float array [N, T]
        From :func:`range_gate_basis`.

    Returns
    -------
    ndarray [..., N]
        In the cube's unit.
    """
    y = np.asarray(cube)
    return y - (y @ basis) @ basis.T


def subtract_background(cube: np.ndarray, background: np.ndarray) -> np.ndarray:
    """``cube [M, K, N] − background [K, N]`` (the coherent mean of the RIS-off frames).

    Parameters
    ----------
    cube : array [M, K, N]
        The sweep's frames [ADC counts].
    background : array [K, N]
        The mean of the RIS-off frames [ADC counts].

    Returns
    -------
    ndarray [M, K, N]
    """
    y = np.asarray(cube)
    b = np.asarray(background)
    if b.shape != y.shape[-2:]:
        raise MeasuredFormatError(f"background has shape {list(b.shape)}, expected {list(y.shape[-2:])} [K, N]")
    return y - b[None]

"""The delay's drift across the sweep: an unambiguous check of the Doppler velocity.

The slow-time phase measures ν only modulo ``2 ν_max = 1/(f_c T_c)``: a radar approaching at
40 m/s reads as +10 m/s (Table I's ±25 m/s). A moving radar also changes its range from frame to
frame, so the RIS return's delay drifts across the sweep at the true rate ν — coarsely, but without
ambiguity. :func:`delay_drift` measures the delay in each beam that carries the return (fast-time
DTFT around τ̂ at the estimated ν, parabolic peak) and fits a robust (Theil–Sen) line over the
beams' frame times ``RadarConfig.beam_times``; :func:`dsp.flags.sweep_flags` raises ``aliased`` when the drift and
the Doppler disagree by more than ν_max (and five standard deviations of the drift). A capture
simulated with frozen geometry (the paper's eq. (1)) has no drift: there the check cannot see
velocity aliasing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.stats

from .radar import RadarConfig
from .dtft_subspace import as_cube, contract_chirps, dtft_phasors

__all__ = ["DelayDrift", "delay_drift", "motion_rate"]


@dataclass(frozen=True)
class DelayDrift:
    """A straight-line fit of the per-beam delay over the frame times.

    Attributes
    ----------
    rate : float
        dτ/dt of the fit [s/s] (the delay rate ν, unambiguous).
    std : float
        Its 1σ: the residuals' scatter (1.4826 × their median absolute deviation) over
        ``sqrt(Σ (t - t̄)²)`` [s/s].
    beams : int array [B]
        The beams used.
    delays : float array [B]
        Their measured delays [s].
    """

    rate: float
    std: float
    beams: np.ndarray
    delays: np.ndarray


def delay_drift(cube: np.ndarray, radar: RadarConfig, *, delay: float, delay_rate: float, weights: np.ndarray,
                min_weight: float = 0.3, span_cells: float = 3.0, points: int = 121) -> DelayDrift | None:
    """Fit the RIS return's delay over the frames of the beams that carry it.

    Parameters
    ----------
    cube : complex array [M, K, N]
    radar : RadarConfig
    delay, delay_rate : float
        The estimate τ̂ [s] (range-Doppler coupling removed) and ν̂ [s/s].
    weights : float array [M]
        |A_m|, the beam pattern toward the estimated AoD (1 at its peak).
    min_weight : float
        Beams with ``weights >= min_weight`` are measured (at least three, spanning two frames).
    span_cells, points : float, int
        The search covers τ̂ ± ``span_cells`` delay resolutions on ``points`` points.

    Returns
    -------
    DelayDrift or None
        None when fewer than three beams carry the return.
    """
    arr = as_cube(cube)
    m, k, n = arr.shape
    beams = np.flatnonzero(np.asarray(weights) >= min_weight)
    if beams.size < 3:
        return None
    times = radar.beam_times(m)[beams]
    f1 = (delay * radar.slope + radar.carrier_frequency * delay_rate) * radar.sample_period
    f2 = delay_rate * radar.carrier_frequency * radar.chirp_interval
    ek = dtft_phasors(f2, np.arange(k) - (k - 1) / 2.0, np.zeros(1))[0]           # [K]
    z = contract_chirps(arr, ek, beams)                                     # [B, N], on the cube's backend
    step = span_cells * radar.delay_resolution * radar.slope * radar.sample_period
    offsets = np.linspace(-step, step, points)                              # [J] cycles/sample
    basis = dtft_phasors(f1, np.arange(n) - (n - 1) / 2.0, offsets)               # [J, N]
    power = np.abs(z @ basis.T) ** 2                                        # [B, J]
    j = np.clip(np.argmax(power, axis=1), 1, points - 2)
    rows = np.arange(beams.size)
    a, b, c = power[rows, j - 1], power[rows, j], power[rows, j + 1]
    den = a - 2 * b + c
    shift = np.where(den < 0, 0.5 * (a - c) / np.where(den < 0, den, -1.0), 0.0)
    d_off = offsets[0] + (j + shift) * (offsets[1] - offsets[0])
    delays = delay + d_off / (radar.slope * radar.sample_period)             # [B] [s]
    if np.ptp(times) <= 0:
        return None
    # Theil-Sen (median of pairwise slopes): a beam whose peak locks onto a neighbouring return
    # (the panel's structure, τ_RB earlier) does not drag the line, nor, through the median
    # absolute deviation of the residuals, its σ.
    rate, intercept, _, _ = scipy.stats.theilslopes(delays, times)
    resid = delays - intercept - rate * times
    scatter = 1.4826 * float(np.median(np.abs(resid - np.median(resid))))
    std = scatter / float(np.sqrt(np.sum((times - times.mean()) ** 2)))
    return DelayDrift(rate=float(rate), std=std, beams=beams, delays=delays)


def motion_rate(radar: RadarConfig, delay_rate: float, drift: DelayDrift | None) -> float:
    """The rate at which the return's delay moves across the sweep [s/s]: the Doppler ν̂, unwrapped by the drift.

    The Doppler is precise but known only modulo 2 ν_max; the drift is coarse but unambiguous. When
    they disagree by more than ν_max and five drift σ (the ``aliased`` test of :mod:`dsp.flags`), ν̂ is
    moved by the whole number of spans 2 ν_max nearest the drift; otherwise ν̂ itself.

    Parameters
    ----------
    radar : RadarConfig
    delay_rate : float
        ν̂ [s/s].
    drift : DelayDrift or None
        :func:`delay_drift`'s fit, if any.
    """
    nu = float(delay_rate)
    if drift is None or not abs(drift.rate - nu) > max(radar.max_delay_rate, 5.0 * drift.std):
        return nu
    span = 2.0 * radar.max_delay_rate
    return nu + span * round((drift.rate - nu) / span)

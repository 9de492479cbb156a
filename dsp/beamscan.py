"""Per-beam peak search and average power: eqs. (argmaxmap) and (P_ave), vectorised over beams."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.fft

from .budget import check_memory, dsp_memory
from .detection import check_beat_cube
from .devicegrid import device_scan
from .processing import ProcessingConfig
from .radar import SPEED_OF_LIGHT, RadarConfig
from .gridscreen import screened_scan
from .spectrum import CHUNK_BYTES, check_cube, dft_windows, windowed_range_spectrum
from .sweep import BeamSweep
from .threads import thread_count
from .xp import backend_of, is_host_array

__all__ = ["BeamScan", "scan_beams"]


@dataclass(frozen=True)
class BeamScan:
    """The strongest delay-Doppler peak of every beam and its average power.

    Attributes
    ----------
    angles : float array [M, 2]
        Steering angle ``[az, el]`` of each beam, RIS frame [rad].
    delay : float array [M]
        τ_m, delay of the grid maximum of beam m [s].
    delay_rate : float array [M]
        ν_m, delay rate of the grid maximum [s/s].
    peak_power : float array [M]
        |z_m(τ_m, ν_m)|², normalised [W].
    average_power : float array [M]
        P_ave,m: mean of |z_m(τ, ν_m)|² over the delay bins with |τ - τ_m| <= Δ [W].
    delay_bin, doppler_bin : int arrays [M]
        Grid indices p (0…N_DFT-1) and q (FFT order, 0…K_DFT-1) of the maximum.
    bounded : bool array [M] or None
        None for a full scan. From ``scan_beams(..., best_only=True)``: True for the beams that
        were not searched because they cannot be the strongest; their ``peak_power`` and
        ``average_power`` hold a proven upper bound of both (below the best beam's P_ave), their
        delay and delay rate NaN and their bins -1.
    """

    angles: np.ndarray
    delay: np.ndarray
    delay_rate: np.ndarray
    peak_power: np.ndarray
    average_power: np.ndarray
    delay_bin: np.ndarray
    doppler_bin: np.ndarray
    bounded: np.ndarray | None = None

    @property
    def num_beams(self) -> int:
        """M."""
        return int(self.delay.shape[0])

    @property
    def best_beam(self) -> int:
        """m̂ = argmax_m P_ave,m (the first one on a tie)."""
        return int(np.argmax(self.average_power))

    @property
    def distance(self) -> np.ndarray:
        """τ_m·c/2 per beam [M] [m] (loop-back delay not removed)."""
        return self.delay * SPEED_OF_LIGHT / 2.0

    @property
    def velocity(self) -> np.ndarray:
        """ν_m·c/2 per beam, positive receding [M] [m/s]."""
        return self.delay_rate * SPEED_OF_LIGHT / 2.0


def scan_beams(
    cube: Any,
    sweep: BeamSweep,
    radar: RadarConfig,
    processing: ProcessingConfig,
    *,
    best_only: bool = False,
) -> BeamScan:
    """Find each beam's delay-Doppler peak and its average power P_ave.

    Parameters
    ----------
    cube : complex array [M, K, N]
        Beat samples (beams, chirps, ADC samples) [√W]: host data, or an array on a device
        (CuPy, array_api_strict; :mod:`dsp.xp`), which is searched where it lives
        (:func:`dsp.devicegrid.device_scan`; the M results come back).
    sweep : BeamSweep
        The M beam steering angles, in the order of the cube's first axis.
    radar : RadarConfig
    processing : ProcessingConfig
    best_only : bool, default False
        Only what :func:`dsp.localize` reads: the best beam, its peak and P_ave exactly as the full
        scan gives them. On the host's screened search, beams whose proven bound
        (:func:`dsp.gridbound.grid_bound`) stays below a P_ave already found are not searched
        (``BeamScan.bounded``): at Table I's 5–10 dBm 54–55 of 61 beams, 0.25 → 0.15 s per cube
        at 5 dBm and 0.23 → 0.09 s at 10 dBm on one core (docs/benchmarks.md, 2026-11-28); at
        0 dBm (the best within 1–3 dB of the noise beams) and at 20 dBm (no noise-only beam) none. On a device and with ``doppler_search="full"`` every beam is
        searched (``bounded`` all False).

    Returns
    -------
    BeamScan

    Notes
    -----
    eq. (argmaxmap): ``(τ_m, ν_m) = argmax |z_m(τ, ν)|²`` over the N_DFT × K_DFT grid, skipping
    delays below ``2·min_range/c``; eq. (P_ave): ``P_ave,m = mean_{|τ_p - τ_m| <= Δ} |z_m(τ_p, ν_m)|²``,
    the grid version of ``(1/2Δ)∫ |z_m(τ, ν_m)|² dτ``.

    On the host, ``doppler_search="zoom"`` is the screened search (:mod:`dsp.gridscreen`) and
    ``"full"`` the whole grid; on a device, the bounded dense search of :mod:`dsp.devicegrid`
    (``"full"``: the whole grid there). All give the full grid's cell (to ties within ~1e-13).
    A device cube must not be all zeros (:func:`dsp.check_beat_cube`).
    """
    on_device = not is_host_array(cube)
    if on_device:
        arr = check_beat_cube(cube, radar, min_beams=1)  # checked where it lives, complex128 there
    else:
        arr = check_cube(cube, radar)
        check_memory(dsp_memory(arr.shape, n_dft=processing.n_dft, k_dft=processing.k_dft),
                     f"scanning a {list(arr.shape)} cube with n_dft={processing.n_dft}, k_dft={processing.k_dft}",
                     fix="lower processing.n_dft/k_dft or raise $RISLOC_MEMORY_LIMIT")
    if not isinstance(sweep, BeamSweep):
        raise TypeError(f"sweep must be a BeamSweep, got {type(sweep).__name__}")
    if not isinstance(best_only, bool):
        raise TypeError(f"best_only={best_only!r} must be True or False")
    if sweep.num_beams != arr.shape[0]:
        raise ValueError(
            f"cube has {arr.shape[0]} beams (frames) but the sweep has {sweep.num_beams} angles; "
            "every frame needs the angle its RIS beam was steered to"
        )
    processing.check_against(radar.num_samples, radar.num_chirps)

    delays = radar.delay_grid(processing.n_dft)
    rates = radar.delay_rate_grid(processing.k_dft)
    # Delays ascend, so the searchable bins (τ·c/2 >= min_range) are [first, N_DFT).
    first = int(np.searchsorted(delays, 2.0 * processing.min_range / SPEED_OF_LIGHT))
    if first >= processing.n_dft:
        raise ValueError(
            f"min_range={processing.min_range} m excludes every delay bin (the unambiguous range "
            f"is {radar.max_range:.3f} m); lower min_range"
        )

    def average_columns(p: int) -> np.ndarray:
        # ±Δ inclusive; the relative slack keeps a bin exactly Δ away despite rounding.
        return np.flatnonzero(np.abs(delays - delays[p]) <= processing.delta * (1.0 + 1e-9))

    if on_device or processing.doppler_search == "zoom":
        w_k, w_n, gain = dft_windows(radar, processing)
        if on_device:
            q_best, p_best, peak, average = device_scan(arr, processing, first, (w_k, w_n), delays, backend_of(arr))
        else:
            q_best, p_best, peak, average = screened_scan(arr, processing, first, (w_k, w_n), average_columns,
                                                          best_only=best_only)
        bounded = p_best < 0
        return BeamScan(angles=sweep.angles, delay=np.where(bounded, np.nan, delays[p_best]),
                        delay_rate=np.where(bounded, np.nan, rates[q_best]),
                        peak_power=peak / gain**2, average_power=average / gain**2,
                        delay_bin=p_best, doppler_bin=q_best, bounded=bounded if best_only else None)

    spectrum, gain = windowed_range_spectrum(arr, radar, processing)  # [M, K, N_DFT]
    m = arr.shape[0]
    q_best = np.empty(m, dtype=np.int64)
    p_best = np.empty(m, dtype=np.int64)
    peak = np.empty(m)
    rows = np.empty((m, processing.n_dft))  # |z_m(τ, ν_m)|² for P_ave
    # The paper's full search: the whole N_DFT × K_DFT map of every beam.
    step = max(1, CHUNK_BYTES // (16 * processing.k_dft * processing.n_dft))
    for i in range(0, m, step):
        z = scipy.fft.ifft(spectrum[i:i + step], n=processing.k_dft, axis=1, norm="forward", workers=thread_count())
        power = np.abs(z) ** 2 / gain**2  # [c, K_DFT, N_DFT]
        power[:, :, :first] = -1.0
        flat = power.reshape(power.shape[0], -1).argmax(axis=1)
        q, p = np.unravel_index(flat, power.shape[1:])
        idx = np.arange(power.shape[0])
        q_best[i:i + step], p_best[i:i + step] = q, p
        peak[i:i + step] = power[idx, q, p]
        rows[i:i + step] = np.abs(z[idx, q, :]) ** 2 / gain**2

    tau = delays[p_best]
    # ±Δ inclusive; the relative slack keeps a bin exactly Δ away despite rounding.
    in_window = np.abs(delays[None, :] - tau[:, None]) <= processing.delta * (1.0 + 1e-9)
    average = (rows * in_window).sum(axis=1) / in_window.sum(axis=1)
    return BeamScan(
        angles=sweep.angles,
        delay=tau,
        delay_rate=rates[q_best],
        peak_power=peak,
        average_power=average,
        delay_bin=p_best,
        doppler_bin=q_best,
        bounded=np.zeros(m, dtype=bool) if best_only else None,
    )

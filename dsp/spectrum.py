"""The windowed, zero-padded 2-D DFT of eq. (2DDFT): delay-Doppler maps of beat frames.

Axis order everywhere: a beat cube is ``[M, K, N]`` (beams, chirps, ADC samples); a frame is
``[K, N]``; a delay-Doppler map is ``[K_DFT, N_DFT]`` (delay rate, delay).

The DFT follows the paper's sign, ``z(τ, ν) = Σ_k Σ_n Y'[n, k] e^{+j2π S τ n T_s} e^{+j2π f_c ν k T}``,
evaluated on the grid ``τ_p = p/(N_DFT S T_s)``, ``ν_q = q/(K_DFT f_c T)``, and divided by the
coherent gain of the window, ``Σ_n w_N[n] · Σ_k w_K[k]``, so that a noiseless tone of complex
amplitude γ sitting on a grid point has ``|z|² = |γ|²`` [W] there. The normalisation does not move
any peak.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.fft
import scipy.ndimage

from .validation import as_finite_array, finite, require_complex_samples
from .budget import check_memory, dsp_memory
from .processing import ProcessingConfig, window_vector
from .radar import SPEED_OF_LIGHT, RadarConfig
from .threads import thread_count

__all__ = ["DelayDopplerMap", "DelayProfile", "delay_doppler_map", "delay_profile", "check_cube", "dft_windows",
           "windowed_range_spectrum"]

#: Largest intermediate array (bytes) the vectorised transforms allocate at once. Small enough
#: to stay in cache: larger chunks are up to 3x slower on a 2-core machine.
CHUNK_BYTES = 32 * 2**20


def check_cube(cube: Any, radar: RadarConfig, *, name: str = "cube") -> np.ndarray:
    """Validate a beat cube ``[M, K, N]`` against the radar and return it as complex128.

    Real, integer and boolean arrays are refused (:func:`dsp.validation.require_complex_samples`).
    """
    require_complex_samples(cube, name)
    if isinstance(cube, np.ndarray) and cube.dtype == np.complex128 and cube.ndim == 3 and cube.size \
            and np.isfinite(cube.sum()):
        arr = cube  # a NaN or ±inf anywhere makes the sum NaN or infinite: all values are finite
    else:
        arr = as_finite_array(cube, name, shape=(None, None, None), dtype=complex)
    m, k, n = arr.shape
    if (k, n) != (radar.num_chirps, radar.num_samples):
        raise ValueError(
            f"{name} has shape [M, K, N] = {list(arr.shape)}, but the radar has "
            f"K={radar.num_chirps} chirps and N={radar.num_samples} samples; the axis order is "
            "(beams, chirps, samples)"
        )
    return arr


def dft_windows(radar: RadarConfig, processing: ProcessingConfig) -> tuple[np.ndarray, np.ndarray, float]:
    """Slow- and fast-time windows of eq. (2DDFT) and their coherent gain.

    Parameters
    ----------
    radar : RadarConfig
        Gives the window lengths K (chirps) and N (samples).
    processing : ProcessingConfig
        Gives the window's name (``processing.window``).

    Returns
    -------
    w_k : float array [K]
        Slow-time window [unitless].
    w_n : float array [N]
        Fast-time window [unitless].
    gain : float
        The coherent gain Σw_K·Σw_N the 2-D transform is divided by [unitless].

    Raises
    ------
    ValueError
        When the window sums to zero or less.
    """
    w_k = window_vector(processing.window, radar.num_chirps)
    w_n = window_vector(processing.window, radar.num_samples)
    gain = float(w_k.sum() * w_n.sum())
    if gain <= 0:
        raise ValueError(f"window={processing.window!r} has a non-positive sum; choose another window")
    return w_k, w_n, gain


def windowed_range_spectrum(
    cube: np.ndarray, radar: RadarConfig, processing: ProcessingConfig
) -> tuple[np.ndarray, float]:
    """Window both axes, zero pad and transform fast time: ``[M, K, N] -> [M, K, N_DFT]``.

    Returns the spectrum (still indexed by chirp, slow-time window applied) and the coherent
    gain to divide the final 2-D transform by.
    """
    w_k, w_n, gain = dft_windows(radar, processing)
    out = np.empty(cube.shape[:2] + (processing.n_dft,), dtype=complex)
    step = max(1, CHUNK_BYTES // (16 * cube.shape[1] * processing.n_dft))
    for i in range(0, cube.shape[0], step):
        windowed = cube[i:i + step] * (w_k[:, None] * w_n[None, :])
        # Σ_n y[n] e^{+j2π p n / N_DFT}: an unscaled inverse DFT.
        out[i:i + step] = scipy.fft.ifft(windowed, n=processing.n_dft, axis=-1, norm="forward", workers=thread_count())
    return out, gain


@dataclass(frozen=True)
class DelayDopplerMap:
    """|z(τ, ν)|² of one frame on the full N_DFT × K_DFT grid.

    Attributes
    ----------
    power : float array [K_DFT, N_DFT]
        Normalised power |z|² [W] (a grid-centred tone of amplitude γ reads |γ|²).
    delay : float array [N_DFT]
        Round-trip delay of each column, ascending, in [0, 1/(S T_s)) [s].
    delay_rate : float array [K_DFT]
        Delay rate ν of each row, ascending (zero in the middle) [s/s].
    oversampling : (float, float)
        Zero-padding factors (K_DFT/K, N_DFT/N): grid bins per un-padded DFT bin.
    """

    power: np.ndarray
    delay: np.ndarray
    delay_rate: np.ndarray
    oversampling: tuple[float, float] = (1.0, 1.0)

    @property
    def distance(self) -> np.ndarray:
        """τ·c/2 of each column [N_DFT] [m] (no loop-back delay removed)."""
        return self.delay * SPEED_OF_LIGHT / 2.0

    @property
    def velocity(self) -> np.ndarray:
        """Radial velocity ν·c/2 of each row, positive receding [K_DFT] [m/s]."""
        return self.delay_rate * SPEED_OF_LIGHT / 2.0

    def profile(self, delay_rate: float = 0.0) -> np.ndarray:
        """Power along delay [N_DFT] [W] at the row closest to ``delay_rate`` [s/s]."""
        nu = finite(delay_rate, "delay_rate", "s/s")
        return self.power[int(np.argmin(np.abs(self.delay_rate - nu)))]

    def peaks(self, count: int = 3, *, min_delay: float = 0.0, neighbourhood: tuple[int, int] | None = None) -> np.ndarray:
        """Indices ``[P, 2]`` = (row, column) of the ``count`` largest local maxima, strongest first.

        Parameters
        ----------
        count : int
            How many peaks to return (fewer if the map has fewer local maxima).
        min_delay : float
            Ignore columns with delay below this [s].
        neighbourhood : (int, int), optional
            Half-size (rows, columns) of the window a local maximum must dominate; by default
            one un-padded DFT bin on each axis.
        """
        if neighbourhood is None:
            neighbourhood = (int(np.ceil(self.oversampling[0])), int(np.ceil(self.oversampling[1])))
        size = (2 * neighbourhood[0] + 1, 2 * neighbourhood[1] + 1)
        local_max = scipy.ndimage.maximum_filter(self.power, size=size, mode="wrap") == self.power
        local_max[:, self.delay < min_delay] = False
        rows, cols = np.nonzero(local_max)
        order = np.argsort(self.power[rows, cols])[::-1][:count]
        return np.column_stack([rows[order], cols[order]])


def delay_doppler_map(frame: Any, radar: RadarConfig, processing: ProcessingConfig) -> DelayDopplerMap:
    """Full delay-Doppler map of one frame, eq. (2DDFT).

    Parameters
    ----------
    frame : complex array [K, N]
        Beat samples of one beam: K chirps × N ADC samples [√W].
    radar : RadarConfig
    processing : ProcessingConfig

    Returns
    -------
    DelayDopplerMap
        Power on the ``[K_DFT, N_DFT]`` grid with its axes (Doppler axis ascending).

    Notes
    -----
    Costs one K_DFT-point transform per delay bin (0.4 s for Table I on one core); use
    :func:`dsp.scan_beams` to search many beams.
    """
    require_complex_samples(frame, "frame")
    arr = as_finite_array(frame, "frame", shape=(None, None), dtype=complex)
    processing.check_against(radar.num_samples, radar.num_chirps)
    check_memory(dsp_memory((1, *arr.shape), n_dft=processing.n_dft, k_dft=processing.k_dft),
                 f"a delay-Doppler map with n_dft={processing.n_dft}, k_dft={processing.k_dft}",
                 fix="lower processing.n_dft/k_dft or raise $RISLOC_MEMORY_LIMIT")
    spectrum, gain = windowed_range_spectrum(check_cube(arr[None], radar, name="frame[None]"), radar, processing)
    z = scipy.fft.ifft(spectrum[0], n=processing.k_dft, axis=0, norm="forward", workers=thread_count())
    power = np.abs(z) ** 2 / gain**2
    return DelayDopplerMap(
        power=np.fft.fftshift(power, axes=0),
        delay=radar.delay_grid(processing.n_dft),
        delay_rate=np.fft.fftshift(radar.delay_rate_grid(processing.k_dft)),
        oversampling=(processing.k_dft / radar.num_chirps, processing.n_dft / radar.num_samples),
    )


@dataclass(frozen=True)
class DelayProfile:
    """|z(τ, ν_q)|² along delay at one delay-rate row of the grid: one row of a :class:`DelayDopplerMap`.

    Attributes
    ----------
    power : float array [N_DFT] (one frame) or [M, N_DFT] (a cube)
        Normalised power |z|² [W] of each frame at every delay bin.
    delay : float array [N_DFT]
        Round-trip delay of each bin, ascending [s].
    delay_rate : float
        The row's delay rate ν_q [s/s]: the grid's closest to the one asked for.
    """

    power: np.ndarray
    delay: np.ndarray
    delay_rate: float

    @property
    def distance(self) -> np.ndarray:
        """τ·c/2 of each bin [N_DFT] [m] (no loop-back delay removed)."""
        return self.delay * SPEED_OF_LIGHT / 2.0


def delay_profile(frames: Any, radar: RadarConfig, processing: ProcessingConfig,
                  delay_rate: float = 0.0) -> DelayProfile:
    """The row of the delay-Doppler map at ``delay_rate``, of one frame or of every beam of a cube.

    Equal (to rounding, ~1e-15 of the map's largest value) to
    ``delay_doppler_map(frame, radar, processing).profile(delay_rate)`` for each frame, the same row
    included when ``delay_rate`` falls midway between two, without the map: the slow-time DFT of
    that one row is a K-term sum, so a frame costs K·N multiply-adds and one N_DFT-point transform
    instead of the K_DFT-point transform of every delay bin (Table I: 61 beams in 0.03 s instead
    of 18 s on one core).

    Parameters
    ----------
    frames : complex array [K, N] or [M, K, N]
        Beat samples: one frame, or M beams' frames [√W].
    radar : RadarConfig
    processing : ProcessingConfig
    delay_rate : float
        Delay rate ν [s/s] of the row (default 0: zero Doppler); the grid row closest to it is taken.

    Returns
    -------
    DelayProfile
        Power [N_DFT] for a frame, [M, N_DFT] for a cube [W], with its delay axis [s].

    Raises
    ------
    ValueError
        When ``frames`` is not a finite complex array of 2 or 3 axes with the radar's K and N, or
        ``delay_rate`` is not finite.
    """
    require_complex_samples(frames, "frames")
    ndim = np.ndim(frames)
    if ndim not in (2, 3):
        raise ValueError(f"frames has {ndim} axes; give one frame [K, N] or a cube [M, K, N] (beams, chirps, samples)")
    arr = as_finite_array(frames, "frames", shape=(None,) * ndim, dtype=complex)
    nu = finite(delay_rate, "delay_rate", "s/s")
    processing.check_against(radar.num_samples, radar.num_chirps)
    cube = check_cube(arr if ndim == 3 else arr[None], radar, name="frames" if ndim == 3 else "frames[None]")
    k_dft, n_dft = processing.k_dft, processing.n_dft
    # the map's row: the first closest rate in the map's (fftshift-ed) order, as DelayDopplerMap.profile takes it
    order = np.fft.fftshift(np.arange(k_dft))
    rates = radar.delay_rate_grid(k_dft)
    q = int(order[int(np.argmin(np.abs(rates[order] - nu)))])
    w_k, w_n, gain = dft_windows(radar, processing)
    # e^{+j2π q k / K_DFT} with the phase reduced exactly in integers
    slow = w_k * np.exp(2j * np.pi * ((q * np.arange(radar.num_chirps)) % k_dft) / k_dft)
    power = np.empty((cube.shape[0], n_dft))
    step = max(1, CHUNK_BYTES // (16 * cube.shape[1] * cube.shape[2]))
    for i in range(0, cube.shape[0], step):
        rows = np.einsum("k,mkn->mn", slow, cube[i:i + step]) * w_n  # Σ_k w_k e^{+j2π qk/K_DFT} y[k, n] · w_n
        z = scipy.fft.ifft(rows, n=n_dft, axis=-1, norm="forward", workers=thread_count())
        power[i:i + step] = (z.real ** 2 + z.imag ** 2) / gain ** 2
    return DelayProfile(power=power if ndim == 3 else power[0], delay=radar.delay_grid(n_dft),
                        delay_rate=float(rates[q]))

"""From the reader's ``[F, K, V, N]`` to the project's beat cube ``[F, K, N]`` (one channel or a beam), and the
maximal-ratio weights that combine the channels on one return."""

from __future__ import annotations

from typing import Sequence

import numpy as np

from dsp import RadarConfig
from dsp.radar import SPEED_OF_LIGHT

from ..errors import MeasuredFormatError

__all__ = ["combine_channels", "mrc_weights"]


def combine_channels(cube: np.ndarray, *, channels: int | Sequence[int] | None = 0,
                     weights: np.ndarray | None = None) -> np.ndarray:
    """Select one virtual channel, or combine several coherently, giving ``[F, K, N]``.

    The localization DSP (``dsp.scan_beams``) takes ``[M, K, N]`` (beams = frames, chirps,
    samples); a measured cube has a virtual-channel axis in between.

    Parameters
    ----------
    cube : ndarray, complex [F, K, V, N]
        Frames, loops, virtual channels, samples (:func:`risloc_rt.measured.read_raw`).
    channels : int, sequence of int, or None, default 0
        An int picks that virtual channel (no combining; the noise and signal are those of one
        antenna). A sequence, or None for all V, combines those channels.
    weights : ndarray, complex [len(channels)], optional
        Combining weights: the output is ``Σ_v w_v·y_v / Σ_v |w_v|``, a beam whose gain on a
        signal with phases ``arg y_v = −arg w_v`` is the mean amplitude. None: ``w = 1``
        (a broadside beam for a calibrated, phase-aligned array; on an uncalibrated radar the
        channel phases differ and the sum can lose signal — then pick one channel).

    Returns
    -------
    ndarray, complex [F, K, N]
        Same dtype as ``cube``.
    """
    y = np.asarray(cube)
    if y.ndim != 4:
        raise MeasuredFormatError(f"cube has shape {list(y.shape)}, expected [F, K, V, N]")
    V = y.shape[2]
    if isinstance(channels, (int, np.integer)):
        if not -V <= channels < V:
            raise MeasuredFormatError(f"channels={channels} is outside the {V} virtual channels")
        if weights is not None:
            raise MeasuredFormatError("weights need a sequence of channels (or None for all)")
        return y[:, :, channels, :]
    idx = np.arange(V) if channels is None else np.asarray(list(channels), dtype=int)
    if idx.size == 0 or np.any(idx < -V) or np.any(idx >= V):
        raise MeasuredFormatError(f"channels={list(idx)} must be non-empty indices into the {V} virtual channels")
    w = np.ones(idx.size) if weights is None else np.asarray(weights)
    if w.shape != (idx.size,):
        raise MeasuredFormatError(f"weights has shape {list(w.shape)}, expected [{idx.size}]")
    norm = np.sum(np.abs(w))
    if norm == 0:
        raise MeasuredFormatError("weights are all zero")
    out = np.einsum("fkvn,v->fkn", y[:, :, idx, :], w / norm)
    return out.astype(y.dtype, copy=False) if np.iscomplexobj(y) else out


def mrc_weights(cube: np.ndarray, radar: RadarConfig, min_range: float) -> np.ndarray:
    """Maximal-ratio weights ``conj(h_v)·h_0/|h_0|`` [V]: h_v the strongest return's complex amplitude in channel v
    (the combined cube keeps the first channel's phase).

    Parameters
    ----------
    cube : ndarray, complex [M, K, V, N]
        Beams (or frames), chirps, virtual channels, samples [ADC counts].
    radar : RadarConfig
        Slope S [Hz/s], sample rate f_s [Hz]: the range of each bin, ``n·f_s/N·c/(2S)`` [m].
    min_range : float
        Bins nearer than this to zero beat frequency (either side) are not candidates [m].

    Returns
    -------
    ndarray, complex [V]
        The chirp-mean range profile (Hann) of every beam and channel; the strongest (beam, range
        bin) beyond ``min_range``, summed over channels, gives h_v there. For
        :func:`combine_channels` ``weights``.
    """
    N = cube.shape[-1]
    prof = np.fft.ifft(cube.mean(axis=1) * np.hanning(N + 2)[1:-1], axis=-1)              # [M, V, N]
    rng = np.arange(N) * radar.sample_rate / N * SPEED_OF_LIGHT / (2 * radar.slope)
    power = np.sum(np.abs(prof) ** 2, axis=1)
    power[:, (rng < min_range) | (rng > rng[-1] - min_range)] = 0
    m, r = np.unravel_index(int(np.argmax(power)), power.shape)
    h = prof[m, :, r]
    return np.conj(h) * (h[0] / abs(h[0]) if abs(h[0]) > 0 else 1.0)

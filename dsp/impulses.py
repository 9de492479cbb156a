"""Impulsive samples: single ADC samples that no beat signal can produce, found and zeroed before detection.

A beat signal is a sum of tones in fast time (one per path, eq. (1)) plus receiver noise, so within one
chirp its power |y_n|² never stands far above the chirp's typical power: P equal tones reach at most P
times their mean power where they all add in phase, and complex Gaussian noise exceeds its median
power 100 times with probability e^{-69} per sample. One corrupted ADC word (a bit error on the
LVDS or Ethernet link, a sample-ordering slip, an ESD spike) is a lone sample far above the rest: its
spectrum is flat over the whole delay-Doppler grid, the sweep detector sees a beam-dependent return
(it is in one beam only) at an arbitrary cell, and a 3000σ glitch (σ the noise amplitude per
sample) in one beam of a Table I capture moved the fix by 1–11 m with a stated 1σ of 2–8 mm
(measured 2026-11-27; only ``pattern-mismatch`` was raised, whose remedy points at the RIS model).

:func:`screen_impulses` marks a sample impulsive when its power exceeds ``IMPULSE_CREST_DB`` (20 dB)
above the median power of its chirp (beam m, chirp k: the ⌊N/2⌋-th smallest of its N sample
powers, robust to glitches in up to half the chirp; a chirp whose median is 0, e.g. a zero-filled
lost packet, is left to ``damaged-beams``), and zeroes it. The same rule excises a burst of another
radar's interference that covers less than half a chirp and stands 20 dB above it (zeroing is the
usual mitigation of FMCW mutual interference). Measured crest (largest over median power of a chirp) on
legitimate data: ≤ 23 (13.6 dB) on noisy Table I captures of the paper's scenario and of the
example halls (0–40 dBm: the noise's largest of 4.7·10⁶ exponential samples), ≤ 6.5 (8.1 dB) on
their noiseless cubes (37–50 paths), ≤ 11.3 (10.5 dB) on TI's IWR6843 corner-reflector recording
(the reflector 59 dB over the median range bin). A zeroed sample removes 1/N of one chirp's energy from the
RIS return in that beam.

Device-generic (the array API, :mod:`dsp.xp`): the cube is screened where it lives; the count, the
marked samples' indices and the largest crest come back.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .xp import backend_of

__all__ = ["IMPULSE_CREST_DB", "ImpulseScreen", "screen_impulses"]

#: A sample more than this far above its chirp's median power is impulsive [dB] (module notes).
IMPULSE_CREST_DB = 20.0


@dataclass(frozen=True)
class ImpulseScreen:
    """The impulsive samples of a cube (:func:`screen_impulses`), zeroed in the cube it returned.

    Attributes
    ----------
    samples : int array [S, 3]
        (beam, chirp, sample) of each impulsive sample, in C order.
    crest_db : float
        The threshold: power over the chirp's median power [dB].
    largest_db : float
        The largest such ratio among the marked samples [dB] (NaN when none).
    """

    samples: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), np.int64))
    crest_db: float = IMPULSE_CREST_DB
    largest_db: float = float("nan")

    @property
    def count(self) -> int:
        """S, the number of impulsive samples."""
        return int(self.samples.shape[0])

    @property
    def beams(self) -> tuple[int, ...]:
        """The beams (frames of the sweep) that held them, ascending."""
        return tuple(int(b) for b in np.unique(self.samples[:, 0]))

    def describe(self) -> str:
        """One line for the ``impulsive-samples`` flag: how many, how far above, where, what was done."""
        beams = self.beams
        where = ", ".join(str(b) for b in beams[:8]) + (f" and {len(beams) - 8} more" if len(beams) > 8 else "")
        return (f"{self.count} ADC sample(s) stood up to {self.largest_db:.0f} dB above their chirp's median power "
                f"(a beat signal stays within {self.crest_db:.0f} dB: a glitch of the ADC or its link) in beam(s) "
                f"{where}: they were zeroed before detection. Check the capture's link for bit errors")


def screen_impulses(cube: Any, *, crest_db: float = IMPULSE_CREST_DB) -> tuple[Any, ImpulseScreen]:
    """Find the impulsive samples of a beat cube and zero them.

    Parameters
    ----------
    cube : complex array [M, K, N]
        Beat samples [√W], host or device (:mod:`dsp.xp`); not modified.
    crest_db : float
        Power over the chirp's median power above which a sample is impulsive [dB], > 0.

    Returns
    -------
    cube : complex array [M, K, N]
        ``cube`` itself when nothing was found, else a copy (same backend and dtype) with the
        impulsive samples set to 0.
    screen : ImpulseScreen
    """
    crest_db = float(crest_db)
    if not crest_db > 0:
        raise ValueError(f"crest_db={crest_db!r} must be > 0 [dB]; the default is {IMPULSE_CREST_DB}")
    backend = backend_of(cube)
    xp = backend.xp
    power = xp.real(cube) ** 2 + xp.imag(cube) ** 2  # [M, K, N]
    median = backend.kth_smallest(power, int(power.shape[2]) // 2, axis=2)  # [M, K], the upper median
    # a chirp whose median is 0 (zero-filled) has no scale: nothing in it is marked
    limit = xp.where(median > 0, median * 10.0 ** (crest_db / 10.0), xp.full_like(median, float("inf")))
    marked = power > limit[..., None]
    count = int(backend.to_host(xp.sum(xp.astype(marked, xp.int64))))
    if count == 0:
        return cube, ImpulseScreen(crest_db=crest_db)
    samples = backend.to_host(xp.stack(xp.nonzero(marked), axis=1)).astype(np.int64)
    ratio = xp.where(marked, power / xp.where(median > 0, median, xp.ones_like(median))[..., None],
                     xp.zeros_like(power))
    largest = float(backend.to_host(xp.max(ratio)))
    cleaned = xp.where(marked, xp.zeros_like(cube), cube)
    return cleaned, ImpulseScreen(samples=samples, crest_db=crest_db, largest_db=10.0 * np.log10(largest))

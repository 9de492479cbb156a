"""The floor's ladder of the RIS return, and the first arrival.

A radar at position p above a floor (the plane z = z_f) and a RIS at r receive the RIS's
re-transmission on four legs (``docs/estimation.md``, "The floor's ladder"):

- out and back on the straight line: range L₀ = |p − r| (the distance the method measures);
- out straight and back via the floor, or the reverse: two legs of one length, range (L₀ + L₁)/2;
- out and back via the floor: range L₁,

with L₁ = |p − r'|, r' the RIS mirrored in the floor. The rungs are δ = (L₁ − L₀)/2 apart in range
(δ ≈ (h_p − z_f)(h_r − z_f)/L₀ far away: 7 cm at 20 m for a radar and a RIS 1.2 m above a concrete
floor, under two resolution cells of a 4 GHz chirp). Near grazing the floor reflects almost
everything (|Γ| ≈ 0.9 for concrete at 6°), and the two middle legs add: the middle rung is then as
strong as the first or stronger, and a peak search takes it for the return — a distance 7 cm too
long with a σ of a fraction of a millimetre. A 4 × 16 RIS's elevation beam is too wide to
suppress the floor leg.

Physics decides which rung is the radar's: every other leg is longer, so the **first arrival**
is the straight one. :func:`floor_ladder` reads the beam-pattern-weighted power at the rungs
around an estimate (the Hann-windowed DTFT of every beam at the estimate's Doppler, as
:func:`dsp.residual.beam_values`): a RIS return one or two rungs *earlier*, above the noise test
and within :data:`MAX_RUNG_DROP_DB` of the estimate's, says the estimate is a floor leg, and how
many rungs down the first arrival is. The rungs beside the first arrival bias its delay through
the un-windowed DTFT's slope there (the refined estimator's delay step): for a rung of relative
amplitude a at s fast-time bins, the peak moves by a·cos φ·D′(s)/|D″(0)| bins (D the Dirichlet
kernel, φ the unknown relative phase), which :attr:`FloorLadder.bias_std` states as a 1σ with φ
uniform.

Pure numpy/scipy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .dtft_subspace import as_cube
from .radar import RadarConfig
from .residual import beam_values

__all__ = ["MAX_RUNG_DROP_DB", "RUNGS", "STATIC_WEIGHT", "FloorLadder", "floor_ladder", "rung_spacing"]

SPEED_OF_LIGHT = 299_792_458.0
#: The rungs read around an estimate: two earlier, the estimate, two later.
RUNGS = (-2, -1, 0, 1, 2)
#: An earlier rung this far below the estimate's (or less) is the straight leg [dB]. The straight
#: leg is at most a few dB weaker than the middle rung (two legs of |Γ| ≤ 1 add, the RIS's elevation
#: pattern tilts them by a few degrees); a rung 12 dB down is a sidelobe of the estimate's own peak
#: or another return, not the floor's ladder.
MAX_RUNG_DROP_DB = 12.0
#: Beams with |A_m| below this share of the largest hold no RIS return at the estimate's AoD; the mean of
#: their values at a rung is what every beam holds alike (the panel's structural echo, τ_RB earlier than
#: the RIS's straight leg, and its own floor legs, which land between the RIS's earlier rungs), and is
#: removed from every beam before the rungs are read, as :func:`dsp.refine.refine_estimate` removes it.
STATIC_WEIGHT = 0.1


def rung_spacing(ris_position: Any, position: Any, floor_height: float) -> float:
    """δ = (|p − r'| − |p − r|)/2, the range between two rungs of the floor's ladder [m].

    Parameters
    ----------
    ris_position : float array [3]
        r, the RIS centre, world frame [m].
    position : float array [3]
        p, the radar, world frame [m].
    floor_height : float
        z_f, the floor plane's world z [m]; both points must be above it.

    Returns
    -------
    float
        δ [m]; 0 when either point is on the floor.
    """
    r = np.asarray(ris_position, dtype=float)
    p = np.asarray(position, dtype=float)
    mirror = np.array([r[0], r[1], 2.0 * float(floor_height) - r[2]])
    return 0.5 * float(np.linalg.norm(p - mirror) - np.linalg.norm(p - r))


@dataclass(frozen=True)
class FloorLadder:
    """The floor's ladder around an estimate (:func:`floor_ladder`).

    Attributes
    ----------
    spacing : float
        δ, range between rungs [m].
    levels_db : tuple of float
        Beam-weighted power at each rung of :data:`RUNGS`, over its noise-only mean [dB].
    threshold_db : float
        The noise test's level (Gamma(M', 1) at the false-alarm probability shared by the rungs),
        same unit [dB].
    steps_down : int
        Rungs from the estimate down to the first arrival: 0 when the estimate is the first
        arrival, 1 when it is the middle rung, 2 the last.
    bias_std : float
        1σ of the first arrival's delay bias from the rungs beside it, in range [m] (0 when none
        is above the test).
    """

    spacing: float
    levels_db: tuple[float, ...]
    threshold_db: float
    steps_down: int
    bias_std: float


def _dirichlet_slope(s: float) -> float:
    """D′(s) of the normalised Dirichlet kernel sin(πs)/(πs) (large N) at s bins [1/bin]."""
    x = math.pi * s
    return (math.cos(x) * x - math.sin(x)) / (math.pi * s * s) if s != 0 else 0.0


def floor_ladder(cube: Any, radar: RadarConfig, *, delay: float, delay_rate: float, weights: Any,
                 spacing: float, noise_power: float, pfa: float = 1e-3, min_weight: float = 0.3) -> FloorLadder:
    """Read the floor's ladder around an estimate: is an earlier rung the first arrival, and the bias beside it.

    Parameters
    ----------
    cube : complex array [M, K, N]
        Beat samples [√W].
    radar : RadarConfig
    delay, delay_rate : float
        The estimate: τ̂ (coupling removed) [s], ν̂ [s/s].
    weights : float array [M]
        |A_m(θ̂)|, the RIS pattern at the estimate's AoD [unitless].
    spacing : float
        δ [m] (:func:`rung_spacing` at the estimated position).
    noise_power : float
        σ² per sample [W] (``Detection.noise_power``).
    pfa : float, default 1e-3
        False-alarm probability of the test, shared by the earlier rungs [unitless].
    min_weight : float, default 0.3
        Beams with |A_m| >= ``min_weight`` · max |A| are summed [unitless].

    Returns
    -------
    FloorLadder
    """
    import scipy.special

    arr = as_cube(cube)
    m, k, n = arr.shape
    w = np.asarray(weights, dtype=float)
    sel = w >= min_weight * w.max()
    far = w < STATIC_WEIGHT * w.max()
    f2 = delay_rate * radar.carrier_frequency * radar.chirp_interval
    levels = []
    for rung in RUNGS:
        tau = delay + 2.0 * rung * spacing / SPEED_OF_LIGHT
        f1 = (tau * radar.slope + radar.carrier_frequency * delay_rate) * radar.sample_period
        values, gain = beam_values(arr, radar, f1, f2, w)
        if far.sum() >= 4:  # what every beam holds alike (the panel's echo and its own ladder): not the RIS's
            values = values - values[far].mean()
            gain = gain * (1.0 + 1.0 / float(far.sum()))
        levels.append(float(np.sum(np.abs(values[sel]) ** 2) / (gain * noise_power)))
    lv = np.asarray(levels)
    dof = int(sel.sum())
    thr = float(scipy.special.gammainccinv(dof, pfa / 2.0))
    here = RUNGS.index(0)
    drop = 10.0 ** (-MAX_RUNG_DROP_DB / 10.0)
    steps = 0
    for rung in (-1, -2):                      # a chain down from the estimate: the first gap ends it
        level = lv[RUNGS.index(rung)]
        if level <= thr or level < drop * lv[here]:
            break
        steps = -rung
    first = here - steps
    bins = 2.0 * spacing / SPEED_OF_LIGHT * radar.slope * radar.sample_period * n   # one rung, fast-time bins
    cell = SPEED_OF_LIGHT / (2.0 * radar.slope * radar.sample_period * n)             # one bin in range [m]
    var = 0.0
    for j, rung in enumerate(RUNGS):
        offset = rung - RUNGS[first]
        if offset == 0 or lv[j] <= thr:
            continue
        a = math.sqrt(max(lv[j] - dof, 0.0) / max(lv[first] - dof, 1e-300))    # amplitude ratio, noise mean removed
        var += 0.5 * (a * abs(_dirichlet_slope(offset * bins)) / (math.pi**2 / 3.0) * cell) ** 2
    return FloorLadder(spacing=float(spacing), levels_db=tuple(float(10 * np.log10(max(v, 1e-30) / dof)) for v in lv),
                       threshold_db=float(10 * np.log10(thr / dof)), steps_down=steps, bias_std=math.sqrt(var))

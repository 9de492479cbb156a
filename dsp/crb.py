"""Cramér–Rao bounds of the RIS self-localization from one beam sweep (``docs/estimation.md``).

Signal model (eq. (1), RIS return only): beam m, chirp k, sample n,

    y[m, k, n] = β |A_m(θ)| e^{jψ_m} exp(j2π (f₁ n + f₂ k)) + w,   w ~ CN(0, σ²),

with f₁ = -(S τ + f_c ν) T_s and f₂ = -f_c ν T_c the fast- and slow-time frequencies
[cycles/sample], A_m(θ) the RIS array factor of :class:`dsp.BeamPattern` (peak 1), β > 0 the
unknown common amplitude and ψ_m an unknown phase per beam (the carrier phase is not kept from
frame to frame: RIS switching, motion, oscillator drift). The unknowns are
(f₁, f₂, θ, β, ψ₁…ψ_M). With centred indices the Fisher information is block diagonal:
(f₁, f₂ | ψ) and (θ, β). The AoD information comes only from how |A_m| changes with θ; with an
unknown amplitude *per beam* it would be zero, which is why the amplitude goes through the pattern.

SNR convention: ``peak_snr`` ρ = K N β² / σ², the post-integration SNR that a beam steered
exactly at the UE would have (coherent gain of K·N samples, no window). Beam m has ρ A_m².
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from ._validate import as_finite_array, fields_equal, positive, positive_int
from .pattern import BeamPattern
from .radar import SPEED_OF_LIGHT, RadarConfig
from .sweep import BeamSweep

__all__ = ["SweepBound", "sweep_crb", "tone_frequency_crb", "position_std"]


def tone_frequency_crb(snr: float, num_samples: int) -> float:
    """Textbook CRB of the frequency of one complex tone with unknown amplitude and phase.

    ``var(f̂) >= 6 / ((2π)² · snr · N (N² - 1))`` [cycles/sample]² with ``snr = |a|²/σ²`` per
    sample (Rife & Boorstyn 1974).

    Parameters
    ----------
    snr : float
        Per-sample SNR |a|²/σ² [linear].
    num_samples : int
        N.
    """
    s = positive(snr, "snr", "linear")
    n = positive_int(num_samples, "num_samples")
    return 6.0 / ((2 * np.pi) ** 2 * s * n * (n * n - 1))


@dataclass(frozen=True, eq=False)
class SweepBound:
    """1σ Cramér–Rao bounds (square roots of the CRB diagonal) for one sweep.

    Attributes
    ----------
    delay : float
        Of τ (range-Doppler coupling removed) [s].
    delay_rate : float
        Of ν [s/s].
    distance : float
        Of d = (τ - τ_RB)·c/2 [m].
    velocity : float
        Of v = ν·c/2 [m/s].
    aod : float array [2]
        Of [az, el] [rad]; el is NaN when the sweep cannot see it (all beams at one elevation):
        az is then bounded with el known.
    fisher_aod : float array [2, 2]
        Fisher information of (az, el) after removing β [1/rad²].
    total_snr : float
        Σ_m ρ A_m², the sweep-integrated post-integration SNR [linear].
    """

    delay: float
    delay_rate: float
    distance: float
    velocity: float
    aod: np.ndarray
    fisher_aod: np.ndarray
    total_snr: float

    def __eq__(self, other: object) -> bool:
        return fields_equal(self, other)

    __hash__ = None  # type: ignore[assignment]

def sweep_crb(
    *,
    radar: RadarConfig,
    sweep: BeamSweep,
    pattern: BeamPattern,
    aod: Any,
    peak_snr: float,
    beams: Any = None,
) -> SweepBound:
    """CRB of delay, delay rate and AoD from the whole sweep.

    Parameters
    ----------
    radar : RadarConfig
    sweep : BeamSweep
        M steering angles.
    pattern : BeamPattern
        RIS array factor (its wavelength defaults to the radar's).
    aod : float array [2]
        True (or estimated) UE direction ``[az, el]`` [rad].
    peak_snr : float
        ρ = K N β²/σ² [linear] (module docstring).
    beams : bool array [M], optional
        Use only these beams (e.g. to bound a single-beam estimator).

    Returns
    -------
    SweepBound

    Notes
    -----
    ``J_f₁ = 2 (2π)² Σ_m ρ A_m² (N² - 1)/12``, ``J_f₂ = 2 (2π)² Σ_m ρ A_m² (K² - 1)/12``
    (per-beam phases removed, centred indices), then ``ν = -f₂/(f_c T_c)``,
    ``τ = -f₁/(S T_s) - f_c ν/S``. AoD: ``J_θ = 2ρ [Σ ∇A ∇Aᵀ - (Σ A∇A)(Σ A∇A)ᵀ / Σ A²]``.
    """
    pat = pattern.for_wavelength(radar.wavelength)
    th = as_finite_array(aod, "aod", shape=(2,))
    rho = positive(peak_snr, "peak_snr", "linear")
    a = pat.amplitude(th, sweep.angles)  # [M]
    g = pat.gradient(th, sweep.angles)  # [M, 2]
    if beams is not None:
        keep = np.asarray(beams, dtype=bool)
        a, g = a[keep], g[keep]
    total = rho * float(a @ a)
    n, k = radar.num_samples, radar.num_chirps
    two_pi2 = (2 * np.pi) ** 2
    var_f1 = 1.0 / (2 * two_pi2 * total * (n * n - 1) / 12.0) if total > 0 else np.inf
    var_f2 = 1.0 / (2 * two_pi2 * total * (k * k - 1) / 12.0) if (total > 0 and k > 1) else np.inf
    fct = radar.carrier_frequency * radar.chirp_interval
    var_nu = var_f2 / fct**2
    var_tau = var_f1 / (radar.slope * radar.sample_period) ** 2 + (radar.carrier_frequency / radar.slope) ** 2 * var_nu

    s_aa = float(a @ a)
    s_ag = a @ g
    fisher = 2 * rho * (g.T @ g - (np.outer(s_ag, s_ag) / s_aa if s_aa > 0 else 0.0))
    aod_std = np.full(2, np.nan)
    one_d = np.ptp(sweep.angles[:, 1]) < 1e-12
    if not one_d:
        try:
            cov = np.linalg.inv(fisher)
            aod_std = np.sqrt(np.clip(np.diag(cov), 0, None))
        except np.linalg.LinAlgError:
            pass
    if one_d or not np.all(np.isfinite(aod_std)):
        aod_std = np.array([1.0 / np.sqrt(fisher[0, 0]) if fisher[0, 0] > 0 else np.inf, np.nan])
    return SweepBound(
        delay=float(np.sqrt(var_tau)),
        delay_rate=float(np.sqrt(var_nu)),
        distance=float(np.sqrt(var_tau)) * SPEED_OF_LIGHT / 2.0,
        velocity=float(np.sqrt(var_nu)) * SPEED_OF_LIGHT / 2.0,
        aod=aod_std,
        fisher_aod=fisher,
        total_snr=total,
    )


def position_std(
    locate: Callable[[np.ndarray], np.ndarray],
    params: Any,
    stds: Any,
    *,
    steps: Any = None,
) -> np.ndarray:
    """1σ of a position [3] [m] from independent parameter errors, by a numerical Jacobian.

    Parameters
    ----------
    locate : callable
        ``params [P] -> position [3]`` (world frame) [m].
    params : float array [P]
        Point of linearisation.
    stds : float array [P]
        1σ of each parameter (NaN or inf entries are skipped: treated as known).
    steps : float array [P], optional
        Difference steps; default 1e-6 of |param| + 1e-7.

    Returns
    -------
    float array [3]
        1σ along the world axes; the position error bound is ``sqrt(sum(std²))``.
    """
    p = np.asarray(params, dtype=float)
    s = np.asarray(stds, dtype=float)
    h = np.asarray(steps, dtype=float) if steps is not None else 1e-6 * np.abs(p) + 1e-7
    var = np.zeros(3)
    for i in range(p.size):
        if not np.isfinite(s[i]) or s[i] == 0:
            continue
        e = np.zeros_like(p)
        e[i] = h[i]
        col = (np.asarray(locate(p + e)) - np.asarray(locate(p - e))) / (2 * h[i])
        var += (col * s[i]) ** 2
    return np.sqrt(var)

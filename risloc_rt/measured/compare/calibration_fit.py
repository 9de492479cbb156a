"""Fit the radar's range offset, the RIS's τ_RB and ζ, the noise floor and the power offset to a capture.

The model is the traced hall (:mod:`.traced_hall`) with the nominal RIS. For a static radar the
chirp mean of each beam, ``z_m[n] = mean_k y[m, k, n]`` [ADC counts], is::

    z_m[n] = Σ_s a_s e^{−j2π S (τ_s + τ_off) n T_s}  +  β Σ_l g_l r_{m,l} e^{−j2π S (τ_l + τ_off + δ) n T_s}

with the static paths s (hall echoes, the panel's structure) and the RIS loop-back paths l of
the model (delays τ, gains g [√W], RIS responses r of beam m), the radar's range delay
``τ_off = 2·range_offset/c``, the τ_RB correction δ, a free complex amplitude per static path and
one complex β for the RIS. The two delays are found by a coarse grid search (static paths for
τ_off, then the RIS for δ) and refined by nonlinear least squares with the amplitudes projected
out (variable projection); their 1σ is the Gauss–Newton covariance at the solution.
Then, with the delays fixed, one complex α scales the model's own static sum Σ g_s e_s and β the
RIS sum: the power offset is ``|α|²`` (counts² per W), ``ζ = ζ_nominal·|β|²/|α|²``. The noise is
the chirp-to-chirp variance ``Σ|y − z|²/(M (K−1) N)`` [counts²] (× N/(N − T) when a range gate
of T tapers removed part of it), ``noise_power = σ²/|α|²``. A range-gated capture (the import's
default) has the same gate applied to the model. The leakage must have been removed on import
(``gate`` or ``background``): a leakage tone far above the hall's echoes is not in the model.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import scipy.optimize

from dsp.radar import SPEED_OF_LIGHT

from ...model.capture import Capture
from ...model.paths import PathSet
from ...model.ris import ris_response
from ..errors import MeasuredFormatError
from ..sweep.leakage import range_gate_basis
from .calibration_file import Calibration

__all__ = ["calibrate_capture"]

_PS = 1e-12


def _tones(radar, delays: np.ndarray) -> np.ndarray:
    """``e^{−j2π S τ n T_s}`` [L, N]."""
    n = np.arange(radar.num_samples)
    cycles = np.mod(np.outer(radar.slope * delays * radar.sample_period, n), 1.0)
    return np.exp(-2j * np.pi * cycles)


def calibrate_capture(capture: Capture, paths: PathSet, *, max_range_offset: float = 0.3,
                      max_delay_error: float = 0.5e-9, beam_span_db: float = 25.0) -> Calibration:
    """Fit the calibration of ``capture`` against the model ``paths`` (module docstring).

    Parameters
    ----------
    capture : Capture
        A measured (or emulated) capture of a static radar, cube in ADC counts.
    paths : PathSet
        The model's kept paths for the capture's radar position, with the nominal RIS (the
        capture's τ_RB and ζ).
    max_range_offset : float
        Range offsets searched, ±[m].
    max_delay_error : float
        τ_RB errors searched, ±[s].
    beam_span_db : float
        Beams whose modelled RIS power is within this of the best one are used [dB].
    """
    radar, ris = capture.radar, capture.ris
    y = np.asarray(capture.cube)
    M, K, N = y.shape
    via = paths.via_ris
    if not via.any() or via.all():
        raise MeasuredFormatError("the model has no " + ("RIS loop-back" if not via.any() else "static") + " path at "
                                  "this radar position; check the scene, the RIS and --ue")
    z = y.mean(axis=1)                                                                    # [M, N]
    noise = float(np.sum(np.abs(y - z[:, None, :]) ** 2) / (M * (K - 1) * N))             # counts² per sample
    resp = ris_response(ris, capture.sweep, paths.ris_incidence[via], paths.ris_departure[via],
                        wavelength=radar.wavelength)                                       # [M, Lr]
    ris_gain = paths.gain[via][None, :] * resp                                            # [M, Lr]
    ris_power = np.sum(np.abs(ris_gain) ** 2, axis=1)
    beams = np.flatnonzero(ris_power >= ris_power.max() * 10 ** (-beam_span_db / 10))
    gate = None
    leak = capture.provenance.get("leakage") or {}
    if leak.get("method") == "gate":
        gate = range_gate_basis(radar, float(leak["gate_range"]))
    if gate is not None:                        # the gate took gate.shape[1] of the N noise dimensions with it
        noise *= N / (N - gate.shape[1])
    zb = z[beams]                                                                         # [B, N]
    t_static, g_static = paths.delay[~via], paths.gain[~via]
    t_ris, g_ris = paths.delay[via], ris_gain[beams]                                      # [Lr], [B, Lr]

    def project(cols: np.ndarray) -> np.ndarray:                                          # along the last axis
        return cols if gate is None else cols - (cols @ gate) @ gate.T

    def static_cols(off: float) -> np.ndarray:
        return project(_tones(radar, t_static + off))                                     # [S, N]

    def ris_cols(off: float, delta: float) -> np.ndarray:
        return project(g_ris @ _tones(radar, t_ris + off + delta))                        # [B, N]

    def design(off: float, delta: float) -> np.ndarray:
        S = static_cols(off)
        B = len(beams)
        A = np.zeros((B * N, S.shape[0] + 1), complex)
        A[:, :-1] = np.tile(S.T, (B, 1))
        A[:, -1] = ris_cols(off, delta).ravel()
        return A

    data = zb.ravel()

    def residual(theta: np.ndarray) -> np.ndarray:
        A = design(theta[0] * _PS, theta[1] * _PS)
        coef, *_ = np.linalg.lstsq(A, data, rcond=None)
        r = data - A @ coef
        return np.concatenate([r.real, r.imag])

    # Coarse: tau_off on the beam-mean (static dominates), then delta with tau_off fixed.
    step = 0.25 / radar.bandwidth
    mean = zb.mean(axis=0)
    offs = np.arange(-2 * max_range_offset / SPEED_OF_LIGHT, 2 * max_range_offset / SPEED_OF_LIGHT + step / 2, step)
    cost = [np.linalg.norm(mean - static_cols(o).T @ np.linalg.lstsq(static_cols(o).T, mean, rcond=None)[0])
            for o in offs]
    off0 = float(offs[int(np.argmin(cost))])
    deltas = np.arange(-max_delay_error, max_delay_error + step / 2, step)
    cost = [np.sum(residual(np.array([off0, d]) / _PS) ** 2) for d in deltas]
    delta0 = float(deltas[int(np.argmin(cost))])
    fit = scipy.optimize.least_squares(residual, np.array([off0, delta0]) / _PS, x_scale=np.array([1.0, 1.0]),
                                       diff_step=1e-4, method="trf")
    off, delta = fit.x * _PS
    dof = max(fit.fun.size - (2 + 2 * (len(t_static) + 1)), 1)
    s2 = float(np.sum(fit.fun ** 2) / dof)
    try:
        cov = s2 * np.linalg.inv(fit.jac.T @ fit.jac) * _PS ** 2
        std_off, std_delta = (math.sqrt(max(v, 0.0)) for v in np.diag(cov))
    except np.linalg.LinAlgError:
        std_off = std_delta = math.nan

    # Powers: one scale for the model's static sum, one for its RIS sum.
    static_sum = np.tile(g_static @ static_cols(off), len(beams))
    ris_sum = (g_ris @ _tones(radar, t_ris + off + delta))
    ris_sum = project(ris_sum).ravel()
    A = np.stack([static_sum, ris_sum], axis=1)
    (alpha, beta), *_ = np.linalg.lstsq(A, data, rcond=None)
    sigma_z2 = noise / K
    cov_ab = sigma_z2 * np.linalg.inv((A.conj().T @ A)).real
    rel_a = math.sqrt(cov_ab[0, 0]) / abs(alpha)
    rel_b = math.sqrt(cov_ab[1, 1]) / abs(beta)
    gain = abs(alpha) ** 2                                                                 # counts² per W
    dof_noise = M * (K - 1) * N
    details: dict[str, Any] = {
        "beams_used": [int(b) for b in beams], "static_paths": int(len(t_static)), "ris_paths": int(len(t_ris)),
        "noise_counts2": noise, "residual_rms_counts": math.sqrt(s2), "gate": gate is not None,
        "converged": bool(fit.success)}
    return Calibration(
        range_offset=float(off * SPEED_OF_LIGHT / 2), range_offset_std=float(std_off * SPEED_OF_LIGHT / 2),
        loopback_delay=float(ris.loopback_delay + delta), loopback_delay_std=float(std_delta),
        amplification_db=float(ris.amplification_db + 10 * math.log10(abs(beta) ** 2 / gain)),
        amplification_db_std=float(20 / math.log(10) * math.hypot(rel_a, rel_b)),
        noise_power_dbm=float(10 * math.log10(noise / gain) + 30),
        noise_power_dbm_std=float(10 / math.log(10) * math.hypot(1 / math.sqrt(dof_noise), 2 * rel_a)),
        power_offset_db=float(10 * math.log10(gain)), power_offset_db_std=float(20 / math.log(10) * rel_a),
        details=details)

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
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.optimize

from dsp import RadarConfig
from dsp.radar import SPEED_OF_LIGHT

from ...model.capture import Capture
from ...model.paths import PathSet
from ...model.ris import ris_response
from ..errors import MeasuredFormatError
from ..sweep.leakage import range_gate_basis
from .calibration_file import Calibration

__all__ = ["calibrate_capture"]

_PS = 1e-12


def _tones(radar: RadarConfig, delays: np.ndarray) -> np.ndarray:
    """``e^{−j2π S τ n T_s}`` [L, N] for the delays τ [s] (cycle counts reduced before the exponential)."""
    n = np.arange(radar.num_samples)
    cycles = np.mod(np.outer(radar.slope * delays * radar.sample_period, n), 1.0)
    return np.exp(-2j * np.pi * cycles)


@dataclass(frozen=True)
class _BeamModel:
    """The model's chirp-mean beams as columns of delays: static paths and the RIS's paths at the beams used.

    ``t_static`` [S] and ``t_ris`` [Lr] are the model's delays [s], ``g_ris [B, Lr]`` the RIS paths'
    gains times the RIS response at each beam used [√W]; ``gate [N, T]`` the capture's range gate
    (None without one), applied to every column as it was to the capture; ``data [B·N]`` the
    measured chirp means of those beams [ADC counts].
    """

    radar: RadarConfig
    gate: np.ndarray | None
    t_static: np.ndarray
    t_ris: np.ndarray
    g_ris: np.ndarray
    data: np.ndarray

    def project(self, cols: np.ndarray) -> np.ndarray:
        """``cols`` without the gated band (along the last axis)."""
        return cols if self.gate is None else cols - (cols @ self.gate) @ self.gate.T

    def static_cols(self, off: float) -> np.ndarray:
        """The static paths' tones delayed by the range offset's ``off`` [s]: ``[S, N]``."""
        return self.project(_tones(self.radar, self.t_static + off))

    def ris_cols(self, off: float, delta: float) -> np.ndarray:
        """The RIS sum of each beam used, delayed by ``off + delta`` [s]: ``[B, N]``."""
        return self.project(self.g_ris @ _tones(self.radar, self.t_ris + off + delta))

    def residual(self, theta: np.ndarray) -> np.ndarray:
        """Real and imaginary misfit [ADC counts] at ``theta = (off, delta)`` [ps], amplitudes projected out."""
        off, delta = theta[0] * _PS, theta[1] * _PS
        S = self.static_cols(off)
        B = self.g_ris.shape[0]
        N = self.radar.num_samples
        A = np.zeros((B * N, S.shape[0] + 1), complex)
        A[:, :-1] = np.tile(S.T, (B, 1))
        A[:, -1] = self.ris_cols(off, delta).ravel()
        coef, *_ = np.linalg.lstsq(A, self.data, rcond=None)
        r = self.data - A @ coef
        return np.concatenate([r.real, r.imag])


def _fit_delays(model: _BeamModel, mean: np.ndarray, *, max_range_offset: float,
                max_delay_error: float) -> tuple[float, float, float, float, float, bool]:
    """``(off, delta, std_off, std_delta, s2, converged)``: the range offset's delay and the τ_RB correction [s],
    their 1σ [s], the residual variance per real dof [counts²] and whether the least squares converged.

    Coarse: τ_off on the beam-mean ``mean [N]`` (static dominates), then δ with τ_off fixed; then
    nonlinear least squares on both (module docstring).
    """
    radar = model.radar
    step = 0.25 / radar.bandwidth
    offs = np.arange(-2 * max_range_offset / SPEED_OF_LIGHT, 2 * max_range_offset / SPEED_OF_LIGHT + step / 2, step)
    cost = [np.linalg.norm(mean - model.static_cols(o).T @ np.linalg.lstsq(model.static_cols(o).T, mean,
                                                                             rcond=None)[0])
            for o in offs]
    off0 = float(offs[int(np.argmin(cost))])
    deltas = np.arange(-max_delay_error, max_delay_error + step / 2, step)
    cost = [np.sum(model.residual(np.array([off0, d]) / _PS) ** 2) for d in deltas]
    delta0 = float(deltas[int(np.argmin(cost))])
    fit = scipy.optimize.least_squares(model.residual, np.array([off0, delta0]) / _PS, x_scale=np.array([1.0, 1.0]),
                                       diff_step=1e-4, method="trf")
    off, delta = fit.x * _PS
    dof = max(fit.fun.size - (2 + 2 * (len(model.t_static) + 1)), 1)
    s2 = float(np.sum(fit.fun ** 2) / dof)
    try:
        cov = s2 * np.linalg.inv(fit.jac.T @ fit.jac) * _PS ** 2
        std_off, std_delta = (math.sqrt(max(v, 0.0)) for v in np.diag(cov))
    except np.linalg.LinAlgError:
        std_off = std_delta = math.nan
    return off, delta, std_off, std_delta, s2, bool(fit.success)


def _fit_scales(model: _BeamModel, g_static: np.ndarray, off: float, delta: float,
                sigma_z2: float) -> tuple[complex, complex, float, float]:
    """``(α, β, σ_α/|α|, σ_β/|β|)``: one complex scale of the model's static sum and one of its RIS sum, with the
    delays fixed; ``sigma_z2`` is the noise variance of a chirp mean [counts²]."""
    static_sum = np.tile(g_static @ model.static_cols(off), model.g_ris.shape[0])
    ris_sum = model.ris_cols(off, delta).ravel()
    A = np.stack([static_sum, ris_sum], axis=1)
    (alpha, beta), *_ = np.linalg.lstsq(A, model.data, rcond=None)
    cov_ab = sigma_z2 * np.linalg.inv((A.conj().T @ A)).real
    return alpha, beta, math.sqrt(cov_ab[0, 0]) / abs(alpha), math.sqrt(cov_ab[1, 1]) / abs(beta)


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

    Returns
    -------
    Calibration
        Range offset [m], τ_RB [s], ζ [dB], noise power [dBm], power offset [dB], each with its 1σ,
        and the fit's details (beams used, path counts, noise [counts²], residual rms [counts]).
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
    model = _BeamModel(radar=radar, gate=gate, t_static=paths.delay[~via], t_ris=paths.delay[via],
                       g_ris=ris_gain[beams], data=zb.ravel())
    off, delta, std_off, std_delta, s2, converged = _fit_delays(
        model, zb.mean(axis=0), max_range_offset=max_range_offset, max_delay_error=max_delay_error)
    alpha, beta, rel_a, rel_b = _fit_scales(model, paths.gain[~via], off, delta, noise / K)
    gain = abs(alpha) ** 2                                                                 # counts² per W
    dof_noise = M * (K - 1) * N
    details: dict[str, Any] = {
        "beams_used": [int(b) for b in beams], "static_paths": int(len(model.t_static)),
        "ris_paths": int(len(model.t_ris)), "noise_counts2": noise, "residual_rms_counts": math.sqrt(s2),
        "gate": gate is not None, "converged": converged}
    return Calibration(
        range_offset=float(off * SPEED_OF_LIGHT / 2), range_offset_std=float(std_off * SPEED_OF_LIGHT / 2),
        loopback_delay=float(ris.loopback_delay + delta), loopback_delay_std=float(std_delta),
        amplification_db=float(ris.amplification_db + 10 * math.log10(abs(beta) ** 2 / gain)),
        amplification_db_std=float(20 / math.log(10) * math.hypot(rel_a, rel_b)),
        noise_power_dbm=float(10 * math.log10(noise / gain) + 30),
        noise_power_dbm_std=float(10 / math.log(10) * math.hypot(1 / math.sqrt(dof_noise), 2 * rel_a)),
        power_offset_db=float(10 * math.log10(gain)), power_offset_db_std=float(20 / math.log(10) * rel_a),
        details=details)

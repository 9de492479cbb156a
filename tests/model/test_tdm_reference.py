"""A TDM radar in the synthesis: idle time between chirps and frames, several frames per beam, a moving UE.

Until now every equivalence test used back-to-back chirps and frames, where the chirp interval T_c
equals the ramp duration T and the frame timing does not enter; the reference even used T for the
slow-time phase. Here the radar has idle time after each chirp (``chirp_period`` = 2.5 T), between
frames (``frame_period``) and holds each beam for several frames (``frames_per_beam``), and the UE
moves, so that the delay rate ν ≠ 0 makes every slow-time instant matter.

Oracles:

1. **Physics, written out.** One path of delay τ(t) = τ_ref + ν (t - t_ref) (a UE moving straight
   at the RIS: the distance is exactly linear in time). From the timing fields alone: chirp k of
   beam m starts at s_m + k T_c, s_m = m · frames_per_beam · frame_period (the cube holds each
   beam's first frame), the frame centre is t_m = s_m + K T_c / 2 and t_ref the mean of the t_m.
   Sample n of that chirp has the phase

       φ[m, k, n] = -2π [ f_c τ(s_m + k T_c) + (S τ(t_m) + f_c ν) n T_s ]:

   the carrier phase of the delay at the chirp's start, then the beat frequency S τ plus the
   Doppler f_c ν over the fast time n T_s, with the delay of the frame centre (eq. (1)'s model:
   no range migration within a frame, no residual video phase). Both the model
   (``simulate``, which uses ``motion.analytic_frame_paths`` and ``beat.beat_cube``) and the
   exact reference (``beat_reference.beat_cube_reference(motion="sweep")``) must give exactly this
   phase, to 1e-9 rad: f_c τ ≈ 5·10³ cycles is known to ~1e-12 cycles in float64, while any
   error of timing (T for T_c, the frame centre for the chirp start, a frame period for a beam
   period) is a phase error of order one.
2. **The exact reference.** ``beat_cube(advance_paths(paths))`` (the fast path of a moving
   ``PathSet``) against ``beat_cube_reference(paths, motion="sweep")`` (exact rationals) on many
   extreme paths; the bound is written out in :func:`moving_bound`.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dsp import SPEED_OF_LIGHT, BeamSweep
from risloc_rt.model.beat import beat_cube
from risloc_rt.model.beat_reference import beat_cube_reference, sweep_timing
from risloc_rt.model.motion import advance_paths, sweep_reference_time
from risloc_rt.model.paths import PathSet
from risloc_rt.model.ris import ris_response
from risloc_rt.model.scenario import PAPER_DISTANCE, analytic_paths
from risloc_rt.model.simulate import simulate

C = SPEED_OF_LIGHT
T = 50e-6  # the ramp duration of Table I [s]
#: Idle time after every chirp (T_c = 2.5 T), 7.3 ms between frame starts (K T_c = 2 ms on the
#: small radar), three frames per beam: a beam every 21.9 ms.
TDM = dict(chirp_period=2.5 * T, frame_period=7.3e-3, frames_per_beam=3)
#: The phase agreement demanded of a single path [rad] (module docstring).
PHASE_TOLERANCE = 1e-9


def single_path_cycles(radar, num_beams, tau_ref, nu):
    """φ / (-2π) of the module docstring, from the radar's timing fields [M, K, N] [cycles].

    ``tau_ref`` [s] is the delay at t_ref, the middle of the sweep; ``nu`` [s/s] the delay rate.
    """
    t_c = radar.chirp_period
    s = np.arange(num_beams) * radar.frames_per_beam * radar.frame_period  # beam m's first chirp [s]
    k, n = np.arange(radar.num_chirps), np.arange(radar.num_samples)
    t_mid = s + 0.5 * radar.num_chirps * t_c
    t_ref = t_mid.mean()
    tau_chirp = tau_ref + nu * (s[:, None] + k[None, :] * t_c - t_ref)  # τ at each chirp's start [M, K]
    carrier = np.mod(radar.carrier_frequency * tau_chirp, 1.0)
    beat = (radar.slope * (tau_ref + nu * (t_mid - t_ref)) + radar.carrier_frequency * nu) * radar.sample_period
    return carrier[:, :, None] + np.mod(beat[:, None, None] * n[None, None, :], 1.0)


def phase_residual(cube, cycles, sign):
    """Largest deviation of ``cube · e^{+j2πφ}`` from one real constant of sign ``sign[m]`` per beam
    [rad]; beams with sign 0 (at a null of the pattern) are skipped."""
    z = cube * np.exp(2j * np.pi * np.mod(cycles, 1.0))
    worst = 0.0
    for m in np.flatnonzero(sign):
        worst = max(worst, np.abs(np.angle(z[m] * sign[m])).max())
    return worst


def radial_scenario(make_scenario, make_radar, speed):
    """The UE at the origin (at t_ref) walking straight at the RIS 13.38 m away along +y; the RIS
    turned by 7.3° so that the UE sits between beams; no structural reflection: one path."""
    radar = make_radar(**TDM)
    return make_scenario(radar=radar, yaw=np.deg2rad(7.3), structure=False, ue_velocity=(0.0, speed, 0.0))


@pytest.mark.parametrize("speed", [1.5, -2.0])
def test_the_model_gives_the_written_out_phase_of_a_moving_path_on_a_tdm_radar(make_scenario, make_radar, speed):
    scenario = radial_scenario(make_scenario, make_radar, speed)
    radar, m = scenario.radar, scenario.sweep.num_beams
    cube = simulate(scenario, rng=np.random.default_rng(0), noise=False).cube
    tau_ref = 2 * PAPER_DISTANCE / C + scenario.ris.loopback_delay  # the UE at the origin at t_ref
    nu = -2 * speed / C  # towards the RIS: the path shortens
    # The beam's gain through the RIS is N_RIS · A_m(θ), real, with θ fixed by the radial motion.
    a = scenario.ris.beam_pattern().for_wavelength(radar.wavelength).amplitude(scenario.truth.aod, scenario.sweep.angles)
    sign = np.where(np.abs(a) > 1e-6, np.sign(a), 0.0)
    residual = phase_residual(cube, single_path_cycles(radar, m, tau_ref, nu), sign)
    assert residual < PHASE_TOLERANCE, residual
    # The timing matters here: the same phase for back-to-back chirps is off by radians.
    wrong = single_path_cycles(dataclasses.replace(radar, chirp_period=T), m, tau_ref, nu)
    assert phase_residual(cube, wrong, sign) > 0.1


def test_the_reference_gives_the_written_out_phase_of_a_moving_path_on_a_tdm_radar(make_scenario, make_radar):
    scenario = radial_scenario(make_scenario, make_radar, 1.5)
    radar, sweep = scenario.radar, scenario.sweep
    paths = analytic_paths(scenario)  # the path at t_ref (its gain holds there)
    assert len(paths) == 1 and paths.delay_rate[0] == pytest.approx(-3.0 / C, rel=1e-12)
    cube = beat_cube_reference(paths, radar=radar, sweep=sweep, ris=scenario.ris, motion="sweep")
    r = ris_response(scenario.ris, sweep, paths.ris_incidence, paths.ris_departure, wavelength=radar.wavelength)[:, 0]
    sign = np.where(np.abs(r) > 1e-6 * np.abs(r).max(), np.sign(r.real), 0.0)
    # analytic_paths' gain carries the carrier phase of t_ref, exp(-j2π f_c τ_ref), which the
    # written-out phase includes: f_c τ(s_m + k T_c) = f_c τ_ref + f_c ν (s_m + k T_c - t_ref).
    cycles = single_path_cycles(radar, sweep.num_beams, float(paths.delay[0]), float(paths.delay_rate[0]))
    assert phase_residual(cube, cycles, sign) < PHASE_TOLERANCE


# ------------------------------------------------------------------ fast synthesis against the reference
def tdm_paths(radar, rng, n, *, n_ris):
    """n paths, the first n_ris through the RIS, at delays of 30-90 % of the unambiguous range and
    rates up to 90 % of the unambiguous delay rate (a fast radar or target), so that advancing
    them over the sweep keeps every delay positive."""
    tau = radar.max_delay * rng.uniform(0.3, 0.9, n)
    nu = radar.max_delay_rate * rng.uniform(-0.9, 0.9, n)
    nu[rng.choice(n, n // 5, replace=False)] = 0.0  # some paths at rest: grouped by the synthesis
    gain = (rng.standard_normal(n) + 1j * rng.standard_normal(n)) * 10 ** rng.uniform(-6, -3, n)
    inc = np.full((n, 2), np.nan)
    inc[:n_ris] = np.deg2rad(np.c_[rng.uniform(-50, 50, n_ris), rng.uniform(-10, 10, n_ris)])
    dep = inc + np.deg2rad(rng.uniform(-5, 5, (n, 2)))
    return PathSet(gain=gain, delay=tau, delay_rate=nu, ris_incidence=inc, ris_departure=dep, labels=("p",) * n)


def amplitude_sum(paths, radar, sweep, ris):
    """Σ_l |γ_l r_{m,l}| per beam [M] [√W]: the scale of every difference below."""
    amp = np.tile(np.abs(paths.gain), (sweep.num_beams, 1))
    via = paths.via_ris
    amp[:, via] *= np.abs(ris_response(ris, sweep, paths.ris_incidence[via], paths.ris_departure[via],
                                       wavelength=radar.wavelength))
    return amp.sum(axis=1)


def moving_bound(paths, radar, num_beams):
    """Allowed ``|Y_fast - Y_ref| / Σ_l |γ_l r_{m,l}|`` for a moving path set.

    The reference is exact up to one rounding of each cycle count. The fast path computes in
    float64 the frame times (``beam_times``, their mean t_ref, t_m - t_ref: a few roundings of
    times up to the sweep length t_end), the carrier shift ν (t_m - K T_c/2 - t_ref) and the
    delay τ + ν (t_m - t_ref), each rounded relatively by 2⁻⁵³. Allowing 8 such roundings of the
    largest terms, a path's phase is off by at most 2π · 8 · 2⁻⁵³ · (f_c |ν| t_end + S T_s N (τ +
    |ν| t_end)) [rad] (the carrier cycles over the sweep, and the beat cycles over the N samples),
    on top of the 8 (L + 4) 2⁻⁵³ of the sum over paths (test_synthesis_speed_equivalence.py).
    For the paths below that is ~1e-11: a phase error below 1e-11 rad.
    """
    t_end = num_beams * radar.beam_interval
    nu, tau = np.abs(paths.delay_rate).max(), paths.delay.max()
    cycles = radar.carrier_frequency * nu * t_end + radar.slope * radar.sample_period * radar.num_samples * (
        tau + nu * t_end)
    return 2 * np.pi * 8 * 2.0**-53 * cycles + 8 * (len(paths) + 4) * 2.0**-53


@pytest.mark.parametrize("timing", [TDM, dict(chirp_period=2.5 * T), dict(frame_period=7.3e-3),
                                    dict(frames_per_beam=4)])
def test_fast_moving_cube_equals_the_exact_reference_on_a_tdm_radar(timing, make_radar, make_ris):
    radar = make_radar(**timing)
    rng = np.random.default_rng(41)
    sweep = BeamSweep.azimuth_grid(*np.deg2rad([-45.0, 45.0, 7.5]))  # 13 beams
    ris = make_ris()
    paths = tdm_paths(radar, rng, 40, n_ris=25)
    scale = amplitude_sum(paths, radar, sweep, ris)[:, None, None]
    bound = moving_bound(paths, radar, sweep.num_beams)
    for t_ref in (None, 0.0, 0.7 * sweep.num_beams * radar.beam_interval):
        fast = beat_cube(advance_paths(paths, radar=radar, num_beams=sweep.num_beams, reference_time=t_ref),
                         radar=radar, sweep=sweep, ris=ris)
        ref = beat_cube_reference(paths, radar=radar, sweep=sweep, ris=ris, motion="sweep", reference_time=t_ref)
        err = (np.abs(fast - ref) / scale).max()
        assert err < bound, (t_ref, err, bound)
    # Not vacuous: the motion moves every moving path's phase by far more than the bound.
    frozen = beat_cube_reference(paths, radar=radar, sweep=sweep, ris=ris)
    assert (np.abs(frozen - ref) / scale).max() > 0.1


@pytest.mark.parametrize("timing", [TDM, dict(chirp_period=2.5 * T)])
def test_frozen_cube_with_idle_time_equals_the_exact_reference(timing, make_radar, make_ris):
    # Eq. (1) with frozen geometry: the slow-time phase steps by f_c ν T_c per chirp, T_c the chirp
    # *interval*; the bound is the one of the sum over paths (test_synthesis_speed_equivalence.py).
    radar = make_radar(**timing)
    sweep = BeamSweep.azimuth_grid(*np.deg2rad([-45.0, 45.0, 7.5]))
    ris = make_ris()
    paths = tdm_paths(radar, np.random.default_rng(42), 40, n_ris=25)
    fast = beat_cube(paths, radar=radar, sweep=sweep, ris=ris)
    ref = beat_cube_reference(paths, radar=radar, sweep=sweep, ris=ris)
    err = (np.abs(fast - ref) / amplitude_sum(paths, radar, sweep, ris)[:, None, None]).max()
    assert err < 8 * (len(paths) + 4) * 2.0**-53, err


def test_the_reference_clock_is_the_radars():
    # The exact timing the reference reads equals RadarConfig's own (beam_times, the mean of the
    # frame centres) to float64 rounding.
    from dsp import RadarConfig

    for timing in (TDM, {}, dict(frame_period=3e-3, frames_per_beam=2)):
        radar = RadarConfig(num_samples=64, num_chirps=16, **timing)
        t_c, starts, t_mid = sweep_timing(radar, 9)
        assert float(t_c) == radar.chirp_interval
        centres = np.array([float(s + radar.num_chirps * t_c / 2) for s in starts])
        np.testing.assert_allclose(centres, radar.beam_times(9), rtol=1e-15, atol=0)
        assert float(t_mid) == pytest.approx(sweep_reference_time(radar, 9), rel=1e-15)

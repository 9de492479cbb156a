"""A moving radar in the beat-signal synthesis: risloc_rt/model/motion.py, beat.py, simulate.py.

Oracles: geometry in closed form (the UE at ``p + v (t_m - t_ref)`` at the centre of frame m,
t_m from ``RadarConfig.beam_times``, t_ref the middle of the sweep), read back from the cube
itself through the phase of its samples: the phase step from sample to sample is
``-2π (S τ + f_c ν) T_s``, from chirp to chirp ``-2π f_c ν T_c``, and the first sample carries
the carrier phase ``-2π f_c τ`` of the frame's first chirp.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dsp import SPEED_OF_LIGHT as C
from dsp import BeamSweep
from risloc_rt.model.beat import beat_cube
from risloc_rt.model.motion import (advance_paths, analytic_frame_paths, frame_start_times, sweep_reference_time,
                                    ue_positions)
from risloc_rt.model.paths import PathFrames, PathSet
from risloc_rt.model.ris import ris_response
from risloc_rt.model.scenario import PointTarget, Truth, analytic_paths
from risloc_rt.model.simulate import simulate

#: The RIS of the test scenarios: 13.38 m along +y from the UE's reference position.
RIS = np.array([0.0, 13.38, 0.0])


def one_tone_delay(frame: np.ndarray, radar, nu: float) -> float:
    """τ from the mean phase step along fast time of chirp 0: ``(f/T_s - f_c ν) / S`` [s].

    f = ``-Δφ/2π`` modulo 1 is the tone in cycles per sample; complex sampling maps the delays
    [0, 1/(S T_s)) one to one onto [0, 1).
    """
    step = np.angle(np.mean(frame[0, 1:] / frame[0, :-1]))  # rad per sample, |.| < π
    cycles = np.mod(-step / (2 * np.pi), 1.0)
    return (cycles / radar.sample_period - radar.carrier_frequency * nu) / radar.slope


def slow_step(frame: np.ndarray) -> float:
    """Mean phase step from chirp to chirp at sample 0 [rad]."""
    return float(np.angle(np.mean(frame[1:, 0] / frame[:-1, 0])))


# ------------------------------------------------------------------------------ reference time
def test_truth_holds_at_the_middle_of_the_sweep(make_radar, make_scenario):
    radar = make_radar(frame_period=5e-3)
    scenario = make_scenario(radar=radar, ue_velocity=(0.8, -1.5, 0.0))
    truth = scenario.truth
    t = radar.beam_times(scenario.sweep.num_beams)
    assert truth.reference_time == pytest.approx(0.5 * (t[0] + t[-1]), abs=1e-15)
    assert truth.reference_time == pytest.approx(t[30], abs=1e-15)  # the middle beam's frame centre
    np.testing.assert_array_equal(truth.position_at(truth.reference_time), scenario.ue_position)
    np.testing.assert_allclose(truth.position_at(t[0]), scenario.ue_position + (t[0] - t[30]) * np.array([0.8, -1.5, 0]),
                               atol=1e-15)
    np.testing.assert_allclose(ue_positions(scenario)[[0, -1]], [truth.position_at(t[0]), truth.position_at(t[-1])],
                               atol=1e-15)
    # The middle frame's paths are the static ones (the UE is at ue_position there).
    frames = analytic_frame_paths(scenario)
    np.testing.assert_allclose(frames.delay[30], analytic_paths(scenario).delay, rtol=0, atol=1e-20)


def test_truth_round_trips_and_reads_files_without_a_reference_time(make_scenario):
    truth = make_scenario(ue_velocity=(0.3, 0.0, 0.0)).truth
    again = Truth.from_dict(truth.to_dict())
    assert again.reference_time == truth.reference_time
    old = truth.to_dict()
    del old["reference_time"]
    legacy = Truth.from_dict(old)
    assert legacy.reference_time is None
    # Frozen geometry: the truth holds at any time.
    np.testing.assert_array_equal(legacy.position_at(123.0), truth.ue_position)


# ------------------------------------------------------------------------------ static = today
@pytest.mark.parametrize("mode", ["relay", "reflective"])
def test_a_static_ue_gives_exactly_the_frozen_cube(mode, make_scenario):
    scenario = make_scenario(mode=mode, yaw=np.deg2rad(-12.0))
    still = analytic_frame_paths(scenario)
    assert isinstance(still, PathSet)
    np.testing.assert_array_equal(still.gain, analytic_paths(scenario).gain)
    sweep = simulate(scenario, rng=np.random.default_rng(1), motion="sweep", noise=False).cube
    frozen = simulate(scenario, rng=np.random.default_rng(1), motion="frozen", noise=False).cube
    direct = beat_cube(analytic_paths(scenario), radar=scenario.radar, sweep=scenario.sweep, ris=scenario.ris)
    assert sweep.tobytes() == frozen.tobytes() == direct.tobytes()
    # With noise too, for the same seed.
    a = simulate(scenario, rng=np.random.default_rng(2)).cube
    b = simulate(scenario, rng=np.random.default_rng(2), motion="frozen").cube
    assert a.tobytes() == b.tobytes()


def test_frozen_motion_keeps_eq1_for_a_moving_ue(make_scenario):
    scenario = make_scenario(ue_velocity=(1.0, -2.0, 0.0))
    frozen = simulate(scenario, rng=np.random.default_rng(0), motion="frozen", noise=False).cube
    direct = beat_cube(analytic_paths(scenario), radar=scenario.radar, sweep=scenario.sweep, ris=scenario.ris)
    assert frozen.tobytes() == direct.tobytes()
    moving = simulate(scenario, rng=np.random.default_rng(0), noise=False).cube
    assert not np.allclose(moving, frozen)


# ------------------------------------------------------------------------------ delay per frame
@pytest.mark.parametrize("velocity", [(0.0, -2.0, 0.0), (0.0, 1.5, 0.0), (1.8, -0.6, 0.3)])
def test_each_beam_beats_at_the_delay_of_the_ue_at_its_frame_centre(velocity, make_radar, make_scenario):
    # No structural reflection: every beam's frame is one tone; its fast-time phase step gives
    # its delay, which must be the round trip to the RIS from where the UE is at t_m, plus τ_RB.
    radar = make_radar(frame_period=4e-3)  # 61 frames over 0.24 s: up to 0.49 m of travel
    v = np.array(velocity)
    scenario = make_scenario(radar=radar, structure=False, ue_velocity=v, mode="relay")
    cube = simulate(scenario, rng=np.random.default_rng(0), noise=False).cube
    t = radar.beam_times(scenario.sweep.num_beams)
    t_ref = sweep_reference_time(radar, scenario.sweep.num_beams)
    for m in (0, 17, 30, 45, 60):
        p = scenario.ue_position + v * (t[m] - t_ref)
        d = np.linalg.norm(p - RIS)
        tau = 2 * d / C + scenario.ris.loopback_delay
        nu = 2 * v @ (p - RIS) / d / C
        # 1e-18 s = 0.15 nm of range: the phase steps are good to ~1e-15 rad.
        assert one_tone_delay(cube[m], radar, nu) == pytest.approx(tau, abs=1e-18), f"beam {m}"
        # Chirp to chirp: -2π f_c ν T_c with the rate of that frame (radial speed at p).
        assert slow_step(cube[m]) == pytest.approx(-2 * np.pi * radar.carrier_frequency * nu * radar.chirp_interval,
                                                   abs=1e-9)


def test_the_carrier_phase_is_that_of_the_frames_first_chirp(make_radar, make_scenario):
    # Purely radial motion: the distance is linear in time, so the delay at the first chirp of
    # frame m is exactly τ(t_m) - ν K T_c / 2.
    radar = make_radar(frame_period=2e-3)
    scenario = make_scenario(radar=radar, structure=False, ue_velocity=(0.0, -1.2, 0.0))
    cube = simulate(scenario, rng=np.random.default_rng(0), noise=False).cube
    frames = analytic_frame_paths(scenario)
    r = ris_response(scenario.ris, scenario.sweep, frames.ris_incidence[:, 0], frames.ris_departure[:, 0],
                     wavelength=radar.wavelength)[np.arange(61), np.arange(61)]
    t0 = frame_start_times(radar, 61)
    p0 = scenario.ue_position + np.outer(t0 - scenario.truth.reference_time, [0.0, -1.2, 0.0])
    tau0 = 2 * np.linalg.norm(p0 - RIS, axis=1) / C + scenario.ris.loopback_delay
    expected = np.exp(-2j * np.pi * np.mod(radar.carrier_frequency * tau0, 1.0))
    # f_c τ ≈ 5·10³ cycles is known to ~1e-12 cycles in float64: 1e-9 rad is ample.
    np.testing.assert_allclose(cube[:, 0, 0] / (np.abs(frames.gain[:, 0]) * r), expected, atol=1e-9)


# ------------------------------------------------------------------------------ angle per frame
def test_tangential_motion_turns_the_aod_frame_by_frame(make_radar, make_scenario):
    # The UE crosses the RIS broadside along +x: the RIS sees it at az = atan(x_m / 13.38) (the
    # row axis u is +x for a panel at +y facing -y), and each beam's loop-back carries the RIS
    # response at that frame's angle.
    radar = make_radar(frame_period=10e-3)  # 0.61 s sweep: ±0.6 m at 2 m/s
    v = np.array([2.0, 0.0, 0.0])
    scenario = make_scenario(radar=radar, structure=False, ue_velocity=v, mode="relay")
    frames = analytic_frame_paths(scenario)
    x = ue_positions(scenario)[:, 0]
    np.testing.assert_allclose(frames.ris_incidence[:, 0, 0], np.arctan2(x, 13.38), atol=1e-14)
    np.testing.assert_allclose(frames.ris_incidence[:, 0, 1], 0.0, atol=1e-14)
    assert np.ptp(np.rad2deg(frames.ris_incidence[:, 0, 0])) == pytest.approx(np.rad2deg(2 * np.arctan(0.6 / 13.38)),
                                                                              rel=1e-3)
    cube = beat_cube(frames, radar=radar, sweep=scenario.sweep, ris=scenario.ris)
    for m in (0, 10, 30, 50, 60):
        one = BeamSweep(scenario.sweep.angles[m:m + 1])
        r = ris_response(scenario.ris, one, frames.ris_incidence[m], frames.ris_departure[m],
                         wavelength=radar.wavelength)[0, 0]
        assert abs(cube[m, 0, 0]) == pytest.approx(abs(frames.gain[m, 0] * r), rel=1e-12), f"beam {m}"
    # The range stays the same to second order: d(t) = sqrt(13.38² + x²).
    np.testing.assert_allclose(frames.delay[:, 0],
                               2 * np.hypot(13.38, x) / C + scenario.ris.loopback_delay, rtol=0, atol=1e-20)


def test_moving_targets_move_too(make_radar, make_scenario):
    # A target walking with the UE keeps its distance: its path's delay and rate do not change.
    radar = make_radar(frame_period=3e-3)
    v = np.array([0.5, 1.0, 0.0])
    scenario = dataclasses.replace(
        make_scenario(radar=radar, structure=False, ue_velocity=v),
        targets=(PointTarget(position=[2.0, 3.0, 0.0], rcs=1.0, velocity=v, label="companion"),))
    frames = analytic_frame_paths(scenario)
    companion = frames.labels.index("companion")
    np.testing.assert_allclose(frames.delay[:, companion], 2 * np.hypot(2.0, 3.0) / C, rtol=1e-14)
    np.testing.assert_allclose(frames.delay_rate[:, companion], 0.0, atol=1e-22)


def test_a_ue_walking_behind_the_panel_is_refused(make_radar, make_scenario):
    radar = make_radar(frame_period=0.25)  # a 15 s sweep
    scenario = make_scenario(radar=radar, structure=False, ue_velocity=(0.0, 2.0, 0.0))
    with pytest.raises(ValueError, match="on or behind the RIS panel"):
        analytic_frame_paths(scenario)


# ------------------------------------------------------------------------------ first-order update
@pytest.mark.parametrize("velocity, bound", [((0.0, -2.0, 0.0), 1e-19), ((1.5, 0.0, 0.0), None)])
def test_advancing_static_paths_matches_the_geometry_to_second_order(velocity, bound, make_radar, make_scenario):
    # The traced-hall update (τ + ν Δt, angles fixed) against the exact per-frame geometry:
    # exact for radial motion, off by the second-order term v² Δt² / (c d) in delay (both legs)
    # for tangential motion.
    radar = make_radar(frame_period=5e-3)
    v = np.array(velocity)
    scenario = make_scenario(radar=radar, ue_velocity=v)
    exact = analytic_frame_paths(scenario)
    first = advance_paths(analytic_paths(scenario), radar=radar, num_beams=scenario.sweep.num_beams)
    # Crossing broadside the range rate is 0 at t_ref: to first order nothing moves, and the
    # static paths come back.
    assert isinstance(first, PathFrames if velocity[1] else PathSet)
    first = first if isinstance(first, PathFrames) else PathFrames.repeat(first, exact.times)
    np.testing.assert_array_equal(first.times, exact.times)
    dt = exact.times - scenario.truth.reference_time
    if bound is None:
        bound = (np.linalg.norm(v) * np.abs(dt).max()) ** 2 / (C * 13.38)  # 1.5 m/s, 0.15 s: 1.2e-12 s
    assert np.abs(first.delay - exact.delay).max() < bound
    # Angles stay those of the reference time.
    np.testing.assert_array_equal(first.ris_incidence[:, 0], np.tile(scenario.truth.aod, (61, 1)))


def test_advancing_paths_at_rest_returns_them_unchanged(make_radar, tone_paths):
    paths = tone_paths([1e-3, 2e-3], [50e-9, 80e-9], [0.0, 0.0])
    assert advance_paths(paths, radar=make_radar(), num_beams=5) is paths


def test_simulate_advances_given_paths_by_their_delay_rates(make_radar, make_scenario, tone_paths):
    radar = make_radar(frame_period=2e-3)
    scenario = make_scenario(radar=radar, structure=False, ue_velocity=(0.0, -1.0, 0.0))
    paths = tone_paths([1e-3], [60e-9], [2 * 1.0 / C])  # a hall echo receding at 1 m/s
    cube = simulate(scenario, rng=np.random.default_rng(0), paths=paths, noise=False).cube
    t = radar.beam_times(61)
    for m in (0, 30, 60):
        tau = 60e-9 + paths.delay_rate[0] * (t[m] - scenario.truth.reference_time)
        assert one_tone_delay(cube[m], radar, paths.delay_rate[0]) == pytest.approx(tau, abs=1e-18)
    with pytest.raises(ValueError, match="motion='frozen' needs a PathSet"):
        simulate(scenario, rng=np.random.default_rng(0), motion="frozen",
                 paths=advance_paths(paths, radar=radar, num_beams=61))
    with pytest.raises(ValueError, match="motion='walk'"):
        simulate(scenario, rng=np.random.default_rng(0), motion="walk")


# ------------------------------------------------------------------------------ chirp period
def test_chirp_period_scales_the_doppler_phase_and_nothing_else(make_radar, tone_paths):
    paths = tone_paths(1e-3, 70e-9, 2 * 1.7 / C)  # receding at 1.7 m/s
    sweep = BeamSweep(np.zeros((1, 2)))
    back_to_back = make_radar()
    idle = make_radar(chirp_period=2.5 * back_to_back.chirp_duration)
    a = beat_cube(paths, radar=back_to_back, sweep=sweep, ris=None)[0]
    b = beat_cube(paths, radar=idle, sweep=sweep, ris=None)[0]
    nu = paths.delay_rate[0]
    fc = back_to_back.carrier_frequency
    assert slow_step(a) == pytest.approx(-2 * np.pi * fc * nu * back_to_back.chirp_duration, abs=1e-12)
    assert slow_step(b) == pytest.approx(-2 * np.pi * fc * nu * 2.5 * back_to_back.chirp_duration, abs=1e-12)
    # The fast-time tone (slope S = B/T, the ramp) is the same: chirp 0 is identical.
    np.testing.assert_array_equal(a[0], b[0])
    # No chirp_period means T_c = T, bit for bit.
    same = beat_cube(paths, radar=make_radar(chirp_period=back_to_back.chirp_duration), sweep=sweep, ris=None)[0]
    assert same.tobytes() == a.tobytes()


def test_frame_period_spreads_the_frames_in_time(make_radar, make_scenario):
    # With idle time between frames the UE travels farther between beams: the frame-to-frame
    # delay step is 2 v beam_interval / c for radial motion.
    for frame_period in (None, 8e-3):
        radar = make_radar(frame_period=frame_period)
        scenario = make_scenario(radar=radar, structure=False, ue_velocity=(0.0, -2.0, 0.0))
        frames = analytic_frame_paths(scenario)
        np.testing.assert_allclose(np.diff(frames.delay[:, 0]), 2 * 2.0 * radar.beam_interval / C, rtol=1e-6)


def test_path_frames_validate_their_shapes(tone_paths):
    paths = tone_paths([1e-3, 2e-3], [50e-9, 80e-9], [0.0, 1e-9])
    pf = PathFrames.repeat(paths, [0.1, 0.2, 0.3])
    assert pf.num_frames == 3 and len(pf) == 2
    np.testing.assert_array_equal(pf.frame(1).delay_rate, paths.delay_rate)
    with pytest.raises(ValueError, match="expected \\[M, L\\]"):
        PathFrames(gain=paths.gain, delay=paths.delay, delay_rate=paths.delay_rate, ris_incidence=paths.ris_incidence,
                   ris_departure=paths.ris_departure, labels=paths.labels, times=[0.0])
    inc = np.full((2, 2, 2), np.nan)
    inc[1, 0] = 0.0  # through the RIS in frame 1 only
    with pytest.raises(ValueError, match="in every frame or in none"):
        PathFrames(gain=np.ones((2, 2)), delay=np.ones((2, 2)) * 1e-8, delay_rate=np.zeros((2, 2)), ris_incidence=inc,
                   ris_departure=inc, labels=("a", "b"), times=[0.0, 1.0])
    with pytest.raises(ValueError, match="other paths"):
        PathFrames.from_frames([paths, PathSet.concatenate([paths, paths])], [0.0, 1.0])

"""Traced legs -> PathSet: RIS loop-back pairs, the panel's physical optics, antenna, pruning, IF filter.

Pure numpy: the traced legs are built here from geometry, so these tests need no ray tracer.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from dsp import SPEED_OF_LIGHT as C
from dsp import RadarConfig, RisPose
from risloc_rt.hall.antenna import RadarAntenna
from risloc_rt.model.link_budget import one_way_free_space_gain, point_target_gain, ris_loopback_gain
from risloc_rt.hall.multipath import monostatic_paths, ris_loopback_paths, ris_structure_paths
from risloc_rt.model.plate import Plate, plate_rcs, plate_scattering
from risloc_rt.hall.pruning import AliasWarning, ModelSettings, if_filter_gain, processed_noise_floor, prune_paths
from risloc_rt.model.ris import ris_response
from risloc_rt.model.scenario import PAPER_DISTANCE
from risloc_rt.hall.traced import TracedPaths

LAMBDA = C / 60e9


def leg_set(tx, rx, sources, *, coefficients=None, velocity=(0.0, 0.0, 0.0), frequency=60e9) -> TracedPaths:
    """One-way legs tx -> rx, one per (image) source point: each arrives at rx from its (image)
    source, unfolded length L = |rx - source|, |a| = λ/(4π L)·coefficient. The departure vector
    is taken along (rx - source), exact for the direct leg (the only one whose departure the tests
    use: antenna gains are isotropic and velocities are set with direct legs only)."""
    tx, rx = np.asarray(tx, float), np.asarray(rx, float)
    src = np.asarray(sources, float).reshape(-1, 3)
    length = np.linalg.norm(rx - src, axis=1)
    arrival = (src - rx) / length[:, None]
    departure = -arrival
    coef = np.ones(len(src)) if coefficients is None else np.asarray(coefficients, complex)
    v = np.asarray(velocity, float)
    n = len(src)
    return TracedPaths(
        tx_position=tx, rx_position=rx, frequency=frequency,
        delay=length / C, amplitude=coef * (C / frequency) / (4 * np.pi * length),
        departure=departure, arrival=arrival, delay_rate=-(departure @ v) / C,
        interactions=np.zeros((n, 1), int), objects=np.full((n, 1), -1), vertices=np.full((n, 1, 3), np.nan),
        object_names=(),
    )


def db(x):
    return 10 * np.log10(x)


# ------------------------------------------------------------------ RIS loop-back from legs
@pytest.mark.parametrize("mode", ["relay", "reflective"])
def test_direct_leg_in_free_space_reduces_to_the_paper_formula(mode, make_radar, make_ris):
    radar = make_radar()
    ue = np.zeros(3)
    ris = make_ris(mode=mode)
    leg = leg_set(ue, ris.pose.position, [ue])
    paths = ris_loopback_paths(leg, radar=radar, ris=ris, antenna=RadarAntenna.isotropic())
    assert len(paths) == 1
    # |γ0|² = P G |γ_UR|² ζ |γ_RU|², |γ_UR|² = λ²/(4π d)²: to 0.01 dB as the issue requires.
    expected = radar.tx_power * radar.antenna_gain * one_way_free_space_gain(PAPER_DISTANCE, radar.wavelength) ** 2 * ris.amplification
    assert abs(db(paths.power[0]) - db(expected)) < 0.01
    assert abs(db(paths.power[0]) - db(ris_loopback_gain(radar, PAPER_DISTANCE, ris.amplification) ** 2)) < 0.01
    assert paths.delay[0] == pytest.approx(2 * PAPER_DISTANCE / C + ris.loopback_delay, abs=1e-15)
    # Both RIS angles are the UE's angle (broadside here).
    np.testing.assert_allclose(paths.ris_incidence[0], [0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(paths.ris_departure[0], [0.0, 0.0], atol=1e-12)


def test_wall_adds_the_leg_pairs_at_the_geometric_delays(make_radar, make_ris):
    # A wall at x = -3 m (normal +x): the radar->RIS leg via the wall comes from the image of the
    # radar in the wall plane; pairs (direct, wall) appear at τ_d + τ_w + τ_RB in both orders.
    ue = np.zeros(3)
    ris = make_ris()
    image = np.array([-6.0, 0.0, 0.0])
    gamma = -0.39
    leg = leg_set(ue, ris.pose.position, [ue, image], coefficients=[1.0, gamma])
    paths = ris_loopback_paths(leg, radar=make_radar(), ris=ris, antenna=RadarAntenna.isotropic())
    d_direct = np.linalg.norm(ris.pose.position - ue)
    d_wall = np.linalg.norm(ris.pose.position - image)
    expected = sorted([2 * d_direct, d_direct + d_wall, d_direct + d_wall, 2 * d_wall])
    np.testing.assert_allclose(np.sort(paths.delay - ris.loopback_delay) * C, expected, atol=1e-6)
    # The wall pair's power is the direct one's times |Γ|² and the spreading ratio.
    both = np.isclose(paths.delay, 2 * d_wall / C + ris.loopback_delay, atol=1e-15, rtol=0)
    direct = np.isclose(paths.delay, 2 * d_direct / C + ris.loopback_delay, atol=1e-15, rtol=0)
    ratio = paths.power[both][0] / paths.power[direct][0]
    assert ratio == pytest.approx(abs(gamma) ** 4 * (d_direct / d_wall) ** 4, rel=1e-9)
    # The wall leg arrives at the RIS from the image direction.
    wall_angle = ris.pose.angles_to(image)
    assert np.any(np.all(np.isclose(paths.ris_incidence, wall_angle, atol=1e-12), axis=1))


def test_legs_from_behind_the_panel_get_no_ris_response(make_ris, paper_sweep):
    ris = make_ris()  # at y = 13.38 facing -y
    behind = ris.pose.position + np.array([0.0, 5.0, 0.0])
    angles = ris.pose.angles_to(np.stack([np.zeros(3), behind]))
    r = ris_response(ris, paper_sweep(), angles, angles, wavelength=LAMBDA)
    assert np.abs(r[:, 0]).max() > 10  # the UE in front: main lobe ≈ N_RIS
    assert np.all(r[:, 1] == 0)


def test_leg_delay_rates_add(make_radar, make_ris):
    ue = np.zeros(3)
    ris = make_ris()
    v = np.array([0.0, 1.5, 0.0])  # toward the RIS: the distance shrinks
    leg = leg_set(ue, ris.pose.position, [ue], velocity=v)
    paths = ris_loopback_paths(leg, radar=make_radar(), ris=ris, antenna=RadarAntenna.isotropic())
    assert paths.delay_rate[0] == pytest.approx(-2 * 1.5 / C, rel=1e-12)


# ------------------------------------------------------------------ physical-optics plate
def po_integral(plate: Plate, pose: RisPose, d_in: np.ndarray, d_out: np.ndarray, samples=(4000, 50)) -> complex:
    """Brute-force PO: midpoint sum of exp(jk(d_in+d_out)·x) over a grid of the plate, times the
    obliquity, normalised like plate_scattering (an independent discretisation)."""
    k = 2 * np.pi / LAMBDA
    su = (np.arange(samples[0]) + 0.5) / samples[0] - 0.5
    sw = (np.arange(samples[1]) + 0.5) / samples[1] - 0.5
    uu, ww = np.meshgrid(su * plate.width, sw * plate.height, indexing="ij")
    pts = uu[..., None] * pose.row_axis + ww[..., None] * pose.column_axis
    phase = np.exp(1j * k * (pts @ (d_in + d_out)))
    integral = phase.mean() * plate.area
    obliq = abs(pose.normal @ d_in + pose.normal @ d_out) / 2
    return plate.reflection * 4 * np.pi / LAMBDA**2 * obliq * integral


def test_plate_rcs_at_normal_incidence_is_4pi_a2_over_lambda2():
    plate = Plate(width=0.10, height=0.05)
    pose = RisPose.facing([0.0, PAPER_DISTANCE, 0.0], [0.0, 0.0, 0.0])
    sigma = plate_rcs(plate, pose, pose.normal[None, :], wavelength=LAMBDA)[0]
    assert sigma == pytest.approx(4 * np.pi * plate.area**2 / LAMBDA**2, rel=1e-12)
    assert sigma == pytest.approx(12.6, abs=0.05)  # the figure in dependency-facts.md


@pytest.mark.parametrize("theta_deg", [0.5, 1.0, 2.0, 3.0, 7.0, 15.0])
def test_plate_falls_off_with_angle_as_physical_optics(theta_deg):
    plate = Plate(width=0.10, height=0.05)
    pose = RisPose.facing([0.0, 0.0, 0.0], [0.0, -1.0, 0.0])
    th = np.deg2rad(theta_deg)
    d = np.cos(th) * pose.normal + np.sin(th) * pose.row_axis  # monostatic, in the u plane
    s = plate_scattering(plate, pose, d[None], d[None], wavelength=LAMBDA)[0]
    ref = po_integral(plate, pose, d, d)
    # Independent surface integral: the midpoint rule's relative error is ≤ (phase step per
    # cell)²/24 of the plate's full (normal-incidence) amplitude.
    k = 2 * np.pi / LAMBDA
    step = k * 2 * np.sin(th) * plate.width / 4000
    peak = abs(plate_scattering(plate, pose, pose.normal[None], pose.normal[None], wavelength=LAMBDA)[0])
    assert abs(s - ref) <= (step**2 / 24) * peak + 1e-9 * peak
    # Closed form in the u plane: σ(θ) = 4πA²/λ² cos²θ sinc²(k W sinθ).
    k = 2 * np.pi / LAMBDA
    x = k * plate.width * np.sin(th)
    closed = 4 * np.pi * plate.area**2 / LAMBDA**2 * np.cos(th) ** 2 * (np.sin(x) / x) ** 2
    assert plate_rcs(plate, pose, d[None], wavelength=LAMBDA)[0] == pytest.approx(closed, rel=1e-9)


def test_plate_first_null_is_at_sin_theta_lambda_over_2w():
    plate = Plate(width=0.10, height=0.05)
    pose = RisPose.facing([0.0, 0.0, 0.0], [0.0, -1.0, 0.0])
    th = np.arcsin(LAMBDA / (2 * plate.width))
    d = np.cos(th) * pose.normal + np.sin(th) * pose.row_axis
    assert plate_rcs(plate, pose, d[None], wavelength=LAMBDA)[0] < 1e-20


def test_plate_blocks_waves_crossing_it_and_scatters_from_its_back():
    plate = Plate()
    pose = RisPose.facing([0.0, 0.0, 0.0], [0.0, -1.0, 0.0])
    front, back = pose.normal, -pose.normal
    s = plate_scattering(plate, pose, np.stack([front, back, front]), np.stack([back, back, front]), wavelength=LAMBDA)
    assert s[0] == 0
    assert abs(s[1]) == pytest.approx(abs(s[2]), rel=1e-12)


def test_structural_pair_in_free_space_matches_the_radar_equation(make_radar, make_ris):
    radar = make_radar()
    ue = np.zeros(3)
    ris = make_ris()
    plate = Plate()
    leg = leg_set(ue, ris.pose.position, [ue])
    paths = ris_structure_paths(leg, radar=radar, ris=ris, plate=plate, antenna=RadarAntenna.isotropic())
    sigma = 4 * np.pi * plate.area**2 / radar.wavelength**2
    expected = point_target_gain(radar, PAPER_DISTANCE, sigma) ** 2
    assert abs(db(paths.power[0]) - db(expected)) < 0.01
    assert paths.delay[0] == pytest.approx(2 * PAPER_DISTANCE / C, abs=1e-15)
    assert not paths.via_ris.any()


def test_structural_pairs_merge_reciprocal_orders(make_radar, make_ris):
    ue = np.zeros(3)
    ris = make_ris()
    leg = leg_set(ue, ris.pose.position, [ue, [-6.0, 0.0, 0.0], [0.0, 0.0, -3.0]], coefficients=[1, -0.4, -0.4])
    paths = ris_structure_paths(leg, radar=make_radar(), ris=ris, plate=Plate(), antenna=RadarAntenna.isotropic())
    assert len(paths) == 6  # L(L+1)/2 for L = 3
    assert len(np.unique(paths.delay)) == len(paths)


# ------------------------------------------------------------------ monostatic echoes, antenna
def test_monostatic_echo_gain_is_the_traced_coefficient_times_the_link_budget(make_radar):
    radar = make_radar()
    ue = np.zeros(3)
    wall_image = np.array([0.0, 8.0, 0.0])  # a wall 4 m away in +y: round trip 8 m
    mono = leg_set(ue, ue, [wall_image], coefficients=[-0.39])
    paths = monostatic_paths(mono, radar=radar, antenna=RadarAntenna.isotropic())
    expected = radar.tx_power * radar.antenna_gain * 0.39**2 * (radar.wavelength / (4 * np.pi * 8.0)) ** 2
    assert paths.power[0] == pytest.approx(expected, rel=1e-12)


def test_antenna_pattern_values():
    ant = RadarAntenna(boresight=[1.0, 0.0, 0.0], exponent=2.0, floor_db=-25.0)
    dirs = np.array([[1.0, 0, 0], [np.cos(np.pi / 4), np.sin(np.pi / 4), 0], [0, 0, -1.0], [-1.0, 0, 0]])
    g = ant.gain(dirs)
    assert g[0] == pytest.approx(1.0)
    assert 10 * np.log10(g[1]) == pytest.approx(-3.0103, abs=1e-3)  # cos²45° = 1/2
    assert 10 * np.log10(g[2]) == pytest.approx(-25.0)  # floor straight down
    assert 10 * np.log10(g[3]) == pytest.approx(-25.0)  # and behind
    assert np.all(RadarAntenna.isotropic().gain(dirs) == 1.0)
    with pytest.raises(ValueError, match="floor_db"):
        RadarAntenna(floor_db=3.0)
    with pytest.raises(ValueError, match="boresight"):
        RadarAntenna(boresight=[0.0, 0.0, 0.0])


# ------------------------------------------------------------------ pruning and the IF filter
def test_noise_floor_for_hann_is_sigma2_times_1p5_squared_over_nk(make_processing, make_radar):
    radar = make_radar()
    floor = processed_noise_floor(radar, make_processing(radar))
    # Hann's equivalent noise bandwidth is 1.5 bins on each axis.
    assert floor == pytest.approx(radar.noise_power * 1.5**2 / (radar.num_samples * radar.num_chirps), rel=1e-9)


def test_butterworth_if_filter_is_3db_at_the_if_bandwidth():
    radar = RadarConfig()
    settings = ModelSettings(if_filter="butterworth", if_filter_order=4)
    h = if_filter_gain(np.array([0.0, radar.if_bandwidth, 2 * radar.if_bandwidth]), radar, settings)
    assert h[0] == pytest.approx(1.0)
    assert 20 * np.log10(h[1]) == pytest.approx(-3.0103, abs=1e-3)
    assert 20 * np.log10(h[2]) == pytest.approx(-10 * np.log10(1 + 2.0**8), abs=1e-9)  # 24.1 dB, order 4
    ideal = if_filter_gain(np.array([0.99, 1.01]) * radar.if_bandwidth, radar, ModelSettings(if_filter="ideal"))
    np.testing.assert_array_equal(ideal, [1.0, 0.0])


def _echo_paths(radar, distances, rcs=19.0):
    from risloc_rt.model.paths import PathSet

    d = np.asarray(distances, float)
    return PathSet(gain=point_target_gain(radar, d, np.full(d.shape, rcs)).astype(complex), delay=2 * d / C,
                   delay_rate=np.zeros(d.size), ris_incidence=np.full((d.size, 2), np.nan),
                   ris_departure=np.full((d.size, 2), np.nan), labels=tuple(f"t{i}" for i in range(d.size)))


def test_pruning_drops_paths_below_the_floor_margin_and_reports_them(make_processing, paper_sweep):
    radar = RadarConfig()
    processing = make_processing(radar)
    # Point targets from 2 m to 20 m with RCS spanning 100 dB: some far below the floor.
    paths = _echo_paths(radar, [5.0, 5.0, 5.0], rcs=19.0)
    from risloc_rt.model.paths import PathSet

    floor = processed_noise_floor(radar, processing)
    powers = np.array([floor * 1e3, floor * 10 ** (-19.9 / 10), floor * 10 ** (-20.1 / 10)])
    paths = PathSet(gain=np.sqrt(powers).astype(complex), delay=paths.delay, delay_rate=paths.delay_rate,
                    ris_incidence=paths.ris_incidence, ris_departure=paths.ris_departure, labels=paths.labels)
    kept, report = prune_paths(paths, radar=radar, processing=processing, sweep=paper_sweep(), ris=None,
                               settings=ModelSettings(prune_margin_db=20.0, if_filter="none"))
    assert kept.labels == ("t0", "t1")  # -19.9 dB kept, -20.1 dB dropped
    assert (report.total, report.kept, report.below_floor) == (3, 2, 1)
    assert "kept 2 of 3" in report.summary()


def test_ris_paths_are_judged_by_their_best_beam(make_processing, make_ris, paper_sweep):
    # At -5 dBm the loop-back before the array gain (-135.8 dBm) is below the pruning threshold
    # (Table I noise floor -109.0 dBm, minus 20 dB); its best beam adds |r|² = N_RIS² (36.1 dB),
    # so it must be kept.
    radar = RadarConfig(tx_power_dbm=-5.0)
    processing = make_processing(radar)
    ue = np.zeros(3)
    ris = make_ris()
    leg = leg_set(ue, ris.pose.position, [ue])
    paths = ris_loopback_paths(leg, radar=radar, ris=ris, antenna=RadarAntenna.isotropic())
    threshold = processed_noise_floor(radar, processing) / 100
    assert paths.power[0] < threshold
    _, report = prune_paths(paths, radar=radar, processing=processing, sweep=paper_sweep(), ris=ris,
                            settings=ModelSettings(prune_margin_db=20.0))
    h = if_filter_gain(np.array([radar.slope * paths.delay[0]]), radar, ModelSettings())[0]
    # Broadside UE, beam 30 steered at it: the peak is |γ|² N_RIS² times the IF filter.
    assert report.peak_power[0] == pytest.approx(paths.power[0] * ris.num_elements**2 * h**2, rel=1e-9)
    assert report.kept == 1 and report.peak_power[0] > threshold


def test_strong_return_beyond_the_unambiguous_range_warns_and_folds(make_processing, paper_sweep):
    radar = RadarConfig()  # unambiguous range 21.82 m
    processing = make_processing(radar)
    paths = _echo_paths(radar, [10.0, 24.0], rcs=1e4)  # 24 m: beat 11.0 MHz > 10 MHz sample rate
    ghost = 24.0 - radar.max_range  # folds back by the unambiguous range
    with pytest.warns(AliasWarning, match=rf"24\.00 m .* folds back to {ghost:.2f} m"):
        kept, report = prune_paths(paths, radar=radar, processing=processing, sweep=paper_sweep(), ris=None,
                                   settings=ModelSettings(if_filter="butterworth"))
    assert report.aliased == 1 and len(report.warnings) == 1
    # The Butterworth attenuation at 11 MHz (order 4): 10·log10(1 + 1.1^8) = 5.1 dB.
    f_b = radar.slope * 2 * 24.0 / C
    att = 10 * np.log10(1 + (f_b / radar.if_bandwidth) ** 8)
    assert db(kept.power[1] / paths.power[1]) == pytest.approx(-att, abs=1e-9)
    # An ideal IF filter removes it instead, without a warning.
    with warnings.catch_warnings():
        warnings.simplefilter("error", AliasWarning)
        kept_ideal, rep = prune_paths(paths, radar=radar, processing=processing, sweep=paper_sweep(), ris=None,
                                      settings=ModelSettings(if_filter="ideal"))
    assert kept_ideal.labels == ("t0",) and rep.beyond_if == 1


def test_model_settings_validation():
    with pytest.raises(ValueError, match="if_filter"):
        ModelSettings(if_filter="chebyshev")
    with pytest.raises(ValueError, match="prune_margin_db"):
        ModelSettings(prune_margin_db=-1.0)
    with pytest.raises(TypeError, match="if_filter_order"):
        ModelSettings(if_filter_order=2.5)

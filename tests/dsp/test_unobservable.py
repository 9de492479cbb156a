"""A σ only for what the capture can observe (issue 19, item 5).

Oracles: a separable RIS array factor A = A_az(u - u_m)·A_el(v - v_m) with every beam at one
azimuth multiplies all beams by the same A_az factor, which the return's unknown amplitude β
absorbs: the azimuth is unobservable and its Fisher information is 0 (round-off). At |az| = 90°
(beams and UE in the panel's plane) ∂A/∂az = 0: again no information. A well-conditioned 2-D
sweep keeps the plain inverse (bit for bit) and its σ matches the Monte Carlo scatter of the
refined estimator within the statistical window of the sample standard deviation.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import dsp
from dsp.crb import AOD_RANK_RTOL, position_std

C = dsp.SPEED_OF_LIGHT
TAU_RB = 1.78e-9
RADAR = dsp.RadarConfig(num_samples=64, num_chirps=16)
PROCESSING = dsp.ProcessingConfig(n_dft=127, k_dft=64)
RELAY = dsp.BeamPattern().for_wavelength(RADAR.wavelength)
POSE = dsp.RisPose.facing([0.0, 8.0, 1.5], [0.0, 0.0, 1.5])
EL = np.deg2rad(np.arange(-21.0, 22.0, 3.0))
ELEVATION_ONLY = dsp.BeamSweep(np.column_stack([np.zeros_like(EL), EL]))
TWO_D = dsp.BeamSweep(np.array([[a, e] for a in np.deg2rad([-12, -6, 0, 6, 12])
                                for e in np.deg2rad([-20, -10, 0, 10, 20])]))
PANEL_PLANE = dsp.BeamSweep.azimuth_grid(*np.deg2rad([-90.0, 90.0, 6.0]))  # first and last beam along the panel


def tone(tau, nu):
    f1 = (RADAR.slope * tau + RADAR.carrier_frequency * nu) * RADAR.sample_period
    f2 = RADAR.carrier_frequency * nu * RADAR.chirp_interval
    k, n = RADAR.num_chirps, RADAR.num_samples
    return np.exp(-2j * np.pi * ((np.arange(k)[:, None] * f2 + np.arange(n)[None, :] * f1) % 1.0))


def cube_for(rng, sweep, aod, *, distance=6.0, peak_snr=1e3):
    m, k, n = sweep.num_beams, RADAR.num_chirps, RADAR.num_samples
    amp = np.abs(RELAY.amplitude(aod, sweep.angles)) * np.sqrt(peak_snr / (k * n))
    cube = (amp * np.exp(2j * np.pi * rng.random(m)))[:, None, None] * tone(2 * distance / C + TAU_RB, 2 * 0.3 / C)[None]
    return cube + (rng.standard_normal(cube.shape) + 1j * rng.standard_normal(cube.shape)) * np.sqrt(0.5)


def locate(cube, sweep, estimator="refined"):
    return dsp.self_localize(cube, sweep=sweep, radar=RADAR, processing=PROCESSING, pose=POSE,
                             loopback_delay=TAU_RB, estimator=estimator, pattern=RELAY, scan=estimator == "paper")


def crb(sweep, aod, rho=1e3):
    return dsp.sweep_crb(radar=RADAR, sweep=sweep, pattern=RELAY, aod=aod, peak_snr=rho, phases="random")


def test_elevation_only_sweep_bounds_the_elevation_and_not_the_azimuth():
    bound = crb(ELEVATION_ONLY, np.deg2rad([1.5, 5.0]))
    lam = np.linalg.eigvalsh(bound.fisher_aod)
    assert lam[0] < AOD_RANK_RTOL * lam[1]  # the null direction really is there
    assert bound.aod[0] == np.inf  # was 0 (the negative variance clipped)
    assert 0 < bound.aod[1] < np.deg2rad(1.0)
    # the elevation's σ is its information's own: the null direction is the azimuth axis
    assert bound.aod[1] == pytest.approx(1 / np.sqrt(bound.fisher_aod[1, 1]), rel=1e-6)


@pytest.mark.parametrize("estimator", ["refined", "paper"])
def test_elevation_only_capture_is_flagged_and_its_position_sigma_is_infinite(estimator):
    loc = locate(cube_for(np.random.default_rng(3), ELEVATION_ONLY, np.deg2rad([1.5, 5.0])), ELEVATION_ONLY,
                 estimator)
    assert loc.detected
    assert loc.std.aod[0] == np.inf and np.isfinite(loc.std.aod[1]) and loc.std.aod[1] > 0
    assert loc.std.position[0] == np.inf and loc.std.peb == np.inf  # az moves x (the panel's row axis)
    assert "unobservable" in loc.flag_codes
    message = {f.code: f.message for f in loc.flags}["unobservable"]
    assert "azimuth" in message and "elevation" not in message.split(":")[0] and "elevation-only" in message


def test_beams_in_the_panel_plane_give_an_infinite_sigma_not_a_millimetre_one():
    # CRB at the panel's plane: no azimuth information at all
    assert crb(PANEL_PLANE, np.deg2rad([90.0, 0.0])).aod[0] == np.inf
    # a UE at 85° seen through the ±90° beams: the estimate jumps to the plane, metres off
    loc = locate(cube_for(np.random.default_rng(0), PANEL_PLANE, np.deg2rad([85.0, 0.0]), peak_snr=1e5),
                 PANEL_PLANE)
    truth = POSE.position + 6.0 * POSE.to_world(dsp.direction_from_angles(np.deg2rad([85.0, 0.0])))
    assert np.linalg.norm(loc.position - truth) > 10.0  # metres off (az -90°, the other side of the fan) ...
    assert loc.std.peb == np.inf and "unobservable" in loc.flag_codes  # ... so the σ must not claim mm
    assert "panel's plane" in {f.code: f.message for f in loc.flags}["unobservable"]


def test_a_well_conditioned_two_d_sweep_keeps_the_plain_inverse():
    bound = crb(TWO_D, np.deg2rad([4.0, 5.0]))
    assert np.all(np.isfinite(bound.aod))
    assert np.array_equal(bound.aod, np.sqrt(np.diag(np.linalg.inv(bound.fisher_aod))))


@pytest.mark.slow  # 40 refined 2-D fits, about 1.5 min
def test_two_d_sigma_matches_the_monte_carlo_scatter():
    # 40 trials: the sample σ of a Gaussian error has a relative standard error of 1/sqrt(2·39) = 11 %;
    # the window [0.65, 1.5] is 3 of them or more each side (the refined estimator reaches the
    # random-phase bound at high SNR, docs/estimation.md).
    aod = np.deg2rad([4.0, 5.0])
    rng = np.random.default_rng(11)
    est = np.array([locate(cube_for(rng, TWO_D, aod, peak_snr=1e4), TWO_D).aod for _ in range(40)])
    scatter = est.std(axis=0, ddof=1)
    sigma = crb(TWO_D, aod, rho=1e4).aod
    ratio = scatter / sigma
    assert np.all((0.65 < ratio) & (ratio < 1.5)), ratio
    assert np.all(np.abs(est.mean(axis=0) - aod) < 4 * sigma / np.sqrt(40))  # unbiased too


def test_position_std_propagates_an_infinite_sigma_and_skips_a_nan_one():
    def move(p):
        return np.array([p[0], 2 * p[1], 0.0])

    sd = position_std(move, [1.0, 1.0], [np.inf, 0.1])
    assert sd[0] == np.inf and sd[1] == pytest.approx(0.2, rel=1e-6) and sd[2] == 0.0  # inf only where it moves
    assert np.allclose(position_std(move, [1.0, 1.0], [np.nan, 0.1]), [0.0, 0.2, 0.0])


def test_console_prints_unobservable_and_result_json_writes_null():
    from risloc_rt.io.report import CaseResult, case_dict, format_case, json_safe

    loc = locate(cube_for(np.random.default_rng(3), ELEVATION_ONLY, np.deg2rad([1.5, 5.0])), ELEVATION_ONLY,
                 "paper")
    capture = SimpleNamespace(truth=None, provenance={})
    case = CaseResult(name="elev", capture=capture, localization=loc)
    text = format_case(case)
    assert "± unobservable" in text and "flag unobservable:" in text
    nonfinite: list[str] = []
    doc = json_safe(case_dict(case), nonfinite=nonfinite)
    assert doc["estimate"]["std"]["aod"][0] is None and doc["estimate"]["std"]["peb"] is None
    assert "$.estimate.std.aod[0]" in nonfinite and doc["estimate"]["std"]["aod"][1] > 0


def test_a_ris_facing_away_from_the_true_radar_is_a_warning():
    from risloc_rt.io.report import facing_away_flag

    def capture(ue):
        return SimpleNamespace(ris=SimpleNamespace(pose=POSE), truth=SimpleNamespace(ue_position=np.array(ue)))

    assert facing_away_flag(capture([0.0, 2.0, 1.5])) is None  # 6 m in front (POSE faces -y)
    flag = facing_away_flag(capture([0.0, 10.0, 1.5]))  # 2 m behind the panel
    assert flag.code == "ris-facing-away" and "2.000 m behind" in flag.message
    assert facing_away_flag(SimpleNamespace(ris=SimpleNamespace(pose=POSE), truth=None)) is None

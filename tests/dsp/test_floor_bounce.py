"""The floor's ladder of the RIS return (dsp.floor_bounce) and the first arrival (self_localize(floor_height=...)).

Oracles: the mirror-image geometry written out by hand; a synthetic cube holding the three rungs
a radar above a floor receives (the straight leg, the two mixed legs one rung later, the floor leg
two rungs later; the middle rung stronger than the first, as near grazing over concrete); the truth
is the straight leg's distance. Regression: in the traced L-shaped hall a walking radar 20.7 m from
ris0 got distances 62-69 mm too long (the middle rung) with a 1σ under a millimetre.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import dsp
from dsp.floor_bounce import RUNGS, floor_ladder, rung_spacing

C = dsp.SPEED_OF_LIGHT
TAU_RB = 1.78e-9
RADAR = dsp.RadarConfig(num_samples=256, num_chirps=16)
PROCESSING = dsp.ProcessingConfig(n_dft=511, k_dft=64)
SWEEP = dsp.BeamSweep.azimuth_grid(*np.deg2rad([-21.0, 21.0, 3.0]))  # M = 15
PATTERN = dsp.BeamPattern().for_wavelength(RADAR.wavelength)
HEIGHT = 1.5                                                         # RIS and radar above the floor [m]
POSE = dsp.RisPose.facing([0.0, 0.0, HEIGHT], [0.0, 10.0, HEIGHT])
AZ = math.radians(4.2)


def _distance_for(rung_cells: float) -> float:
    """The horizontal distance [m] at which one rung is ``rung_cells`` range cells (radar and RIS at HEIGHT):
    δ = (√(D² + (2h)²) − D)/2  ⇒  D = ((2h)² − 4δ²)/(4δ)."""
    delta = rung_cells * RADAR.range_resolution
    return ((2 * HEIGHT) ** 2 - 4 * delta**2) / (4 * delta)


def _tone(tau, nu):
    f1 = (RADAR.slope * tau + RADAR.carrier_frequency * nu) * RADAR.sample_period
    f2 = RADAR.carrier_frequency * nu * RADAR.chirp_interval
    k, n = RADAR.num_chirps, RADAR.num_samples
    return np.exp(-2j * np.pi * ((np.arange(k)[:, None] * f2 + np.arange(n)[None, :] * f1) % 1.0))


def _ladder_cube(rng, *, distance, gains=(1.0, 1.8, 0.8), phases=None, velocity=0.2, peak_snr=3e3):
    """The RIS return on the floor's three rungs (gains relative to the straight leg, the rung phases
    random unless given), per-beam RIS phases random, plus unit noise. Returns (cube, δ [m])."""
    m, k, n = SWEEP.num_beams, RADAR.num_chirps, RADAR.num_samples
    delta = (math.hypot(distance, 2 * HEIGHT) - distance) / 2
    phases = rng.uniform(0, 2 * np.pi, 3) if phases is None else np.asarray(phases)
    nu = 2 * velocity / C
    legs = sum(g * np.exp(1j * p) * _tone(2 * (distance + r * delta) / C + TAU_RB, nu)
               for r, (g, p) in enumerate(zip(gains, phases)))
    amp = np.abs(PATTERN.amplitude([AZ, 0.0], SWEEP.angles)) * np.sqrt(peak_snr / (k * n))
    cube = (amp * np.exp(2j * np.pi * rng.random(m)))[:, None, None] * legs[None]
    noise = (rng.standard_normal(cube.shape) + 1j * rng.standard_normal(cube.shape)) * np.sqrt(0.5)
    return cube + noise, delta


def _locate(cube, **kw):
    return dsp.self_localize(cube, sweep=SWEEP, radar=RADAR, processing=PROCESSING, pose=POSE,
                             loopback_delay=TAU_RB, pattern=PATTERN, ue_height=HEIGHT, **kw)


def test_the_rung_spacing_is_the_mirror_image_geometry():
    # radar and RIS 1.2 m above the floor, 20 m apart: (sqrt(20^2 + 2.4^2) - 20)/2 = 0.0717426 m
    assert rung_spacing([0, 0, 1.2], [20.0, 0, 1.2], 0.0) == pytest.approx(0.0717426, abs=1e-7)
    # the floor 0.5 m up: 0.7 m above it each; (sqrt(20^2 + 1.4^2) - 20)/2 = 0.0244701 m
    assert rung_spacing([0, 0, 1.2], [0, 20.0, 1.2], 0.5) == pytest.approx(0.0244701, abs=1e-7)
    # a radar at 0.8 m, the RIS at 2.6 m, 12 m apart horizontally: (|p - r'| - |p - r|)/2 by hand
    expected = (math.sqrt(144 + 3.4**2) - math.sqrt(144 + 1.8**2)) / 2
    assert rung_spacing([0, 0, 2.6], [12.0, 0, 0.8], 0.0) == pytest.approx(expected, rel=1e-12)
    # far away, delta -> h_p h_r / L
    assert rung_spacing([0, 0, 1.2], [200.0, 0, 1.2], 0.0) == pytest.approx(1.44 / 200, rel=1e-3)


def test_the_ladder_says_which_rung_the_estimate_is_on():
    rng = np.random.default_rng(5)
    cube, delta = _ladder_cube(rng, distance=_distance_for(1.8), phases=(0.0, 0.0, 0.0))
    weights = np.abs(PATTERN.amplitude([AZ, 0.0], SWEEP.angles))
    tau0 = 2 * _distance_for(1.8) / C + TAU_RB
    on = {r: floor_ladder(cube, RADAR, delay=tau0 + 2 * r * delta / C, delay_rate=2 * 0.2 / C, weights=weights,
                          spacing=delta, noise_power=1.0) for r in (0, 1, 2)}
    assert [on[r].steps_down for r in (0, 1, 2)] == [0, 1, 2]
    # the straight leg's own ladder: nothing earlier but the Hann leakage of the later rungs (the Hann window's
    # response 1.8 bins off a tone is -29 dB; with the noise, more than 15 dB below it), its two later rungs
    # above the test, the middle one the strongest
    levels = dict(zip(RUNGS, on[0].levels_db))
    assert max(levels[-1], levels[-2]) < levels[0] - 15.0
    assert levels[1] > levels[0] > on[0].threshold_db and levels[2] > on[0].threshold_db


def test_without_a_floor_the_middle_rung_is_taken_and_its_sigma_says_sub_millimetre():
    """The bug this module fixes, shown: the peak is the middle rung, δ too long, far outside its 1σ."""
    rng = np.random.default_rng(7)
    distance = _distance_for(1.8)
    cube, delta = _ladder_cube(rng, distance=distance, phases=(0.0, 0.3, 0.0))
    loc = _locate(cube, estimator="refined")
    assert loc.distance - distance == pytest.approx(delta, abs=0.3 * delta)
    assert abs(loc.distance - distance) > 10 * loc.std.distance


@pytest.mark.parametrize("estimator", ["refined", "paper"])
def test_with_the_floor_the_estimate_is_right_or_flagged_and_its_sigma_covers_it(estimator):
    rng = np.random.default_rng(11)
    distance = _distance_for(1.8)
    cube, delta = _ladder_cube(rng, distance=distance, phases=(0.0, 0.3, 0.0))
    loc = _locate(cube, estimator=estimator, floor_height=0.0)
    error = loc.distance - distance
    if estimator == "refined":
        assert "first-arrival" in loc.flag_codes and "floor-leg" not in loc.flag_codes
        assert abs(error) < 0.25 * delta                        # on the straight leg, not a rung later
    else:                                                       # the paper's peak is kept, flagged
        assert "floor-leg" in loc.flag_codes and "floor-leg" in dsp.fusion.DOUBT_CODES
        assert error == pytest.approx(delta, abs=0.3 * delta)
        assert loc.std.distance >= 0.9 * delta                 # δ at the estimate's (one rung too far) position
    assert abs(error) <= 3 * loc.std.distance


def test_the_first_arrival_sigma_covers_the_rungs_bias_over_their_phases():
    """Coverage: over random rung phases the refined distance error is within its 1σ/2σ at least as often
    as a Gaussian's (68 % / 95 %, less a binomial margin for 40 runs)."""
    rng = np.random.default_rng(3)
    distance = _distance_for(1.8)
    z = []
    for _ in range(40):
        cube, _ = _ladder_cube(rng, distance=distance)
        loc = _locate(cube, estimator="refined", floor_height=0.0)
        z.append(abs(loc.distance - distance) / loc.std.distance)
    z = np.asarray(z)
    assert np.mean(z <= 1) >= 0.55 and np.mean(z <= 2) >= 0.88 and np.all(z <= 4)


def test_a_single_return_is_left_alone():
    """No ladder (no floor in the data): the floor check moves nothing and flags nothing."""
    rng = np.random.default_rng(2)
    distance = _distance_for(1.8)
    cube, _ = _ladder_cube(rng, distance=distance, gains=(1.0, 0.0, 0.0))
    with_floor = _locate(cube, estimator="refined", floor_height=0.0)
    without = _locate(cube, estimator="refined")
    assert with_floor.distance == without.distance
    assert not {"first-arrival", "floor-leg"} & set(with_floor.flag_codes)
    assert with_floor.std.distance == pytest.approx(without.std.distance, rel=1e-9)


def test_a_bad_floor_height_is_refused():
    cube, _ = _ladder_cube(np.random.default_rng(1), distance=_distance_for(1.8))
    with pytest.raises(ValueError, match="floor_height"):
        _locate(cube, floor_height=float("nan"))


def test_the_panels_own_ladder_is_not_taken_for_an_earlier_rung():
    """Regression (the default hall with a second RIS, ris1 at 14.3 m and 33° off its boresight: fixes 6-20 m off,
    flagged grating-lobe): the panel's structural echo arrives c·τ_RB/2 = 26.7 cm before the RIS's straight leg,
    in every beam alike, with a floor's ladder of its own; its floor-floor leg then lands on the RIS's rung -1,
    which the ladder read as an earlier RIS return and sent the estimate there. Here δ = c·τ_RB/6 puts that
    leg exactly on rung -1, on Table I's chirp (600 samples: a rung is 2.4 range cells, as in the hall) and a
    ±45° sweep in 1.5° steps (most beams see no RIS return): the ladder must see no earlier rung (what every
    beam holds alike is not the RIS's), and the estimate ends on the straight leg, at the RIS's azimuth."""
    rng = np.random.default_rng(23)
    radar = dsp.RadarConfig(num_chirps=16)
    processing = dsp.ProcessingConfig(n_dft=1199, k_dft=64)
    sweep = dsp.BeamSweep.azimuth_grid(*np.deg2rad([-45.0, 45.0, 1.5]))       # M = 61
    m, k, n = sweep.num_beams, radar.num_chirps, radar.num_samples
    delta = C * TAU_RB / 2 / 3
    height = 1.0                                                             # radar and RIS 1 m above the floor
    distance = ((2 * height) ** 2 - 4 * delta**2) / (4 * delta)              # rung_spacing = δ: 11.2 m
    assert delta / radar.range_resolution > 2.0 and distance < radar.max_range   # resolved rungs, not folded
    nu = 2 * 0.2 / C

    def tone(tau, rate):
        f1 = (radar.slope * tau + radar.carrier_frequency * rate) * radar.sample_period
        f2 = radar.carrier_frequency * rate * radar.chirp_interval
        return np.exp(-2j * np.pi * ((np.arange(k)[:, None] * f2 + np.arange(n)[None, :] * f1) % 1.0))

    def ladder_of(extra, phases):
        return sum(g * np.exp(1j * p) * tone(2 * (distance + r * delta) / C + extra, nu)
                   for r, (g, p) in enumerate(zip((1.0, 1.8, 0.8), phases)))

    pattern = dsp.BeamPattern().for_wavelength(radar.wavelength)
    weights = np.abs(pattern.amplitude([AZ, 0.0], sweep.angles))
    scale = np.sqrt(3e3 / (k * n))
    cube = ((weights * scale * np.exp(2j * np.pi * rng.random(m)))[:, None, None] * ladder_of(TAU_RB, (0.0, 0.3, 0.0))
            + 3.0 * scale * ladder_of(0.0, (0.4, 1.1, 2.0))[None])   # the panel: τ_RB earlier, every beam alike
    cube = cube + (rng.standard_normal(cube.shape) + 1j * rng.standard_normal(cube.shape)) * np.sqrt(0.5)
    ladder = floor_ladder(cube, radar, delay=2 * distance / C + TAU_RB, delay_rate=nu, weights=weights,
                          spacing=delta, noise_power=1.0)
    assert ladder.steps_down == 0
    assert dict(zip(RUNGS, ladder.levels_db))[-1] < ladder.threshold_db + 3.0   # at the noise, not the panel
    pose = dsp.RisPose.facing([0.0, 0.0, height], [0.0, 10.0, height])
    loc = dsp.self_localize(cube, sweep=sweep, radar=radar, processing=processing, pose=pose, loopback_delay=TAU_RB,
                            pattern=pattern, ue_height=height, estimator="refined", floor_height=0.0)
    # the middle rung (1.8x) is the strongest: the estimate starts there and goes down to the straight leg, no further
    assert loc.detected and abs(loc.distance - distance) < 0.25 * delta
    assert abs(loc.aod[0] - AZ) < math.radians(0.5)
    assert not {"grating-lobe", "beam-edge", "floor-leg"} & set(loc.flag_codes)

"""Impulsive samples (``dsp.impulses``): found where no beat signal can put them, zeroed, flagged.

Physics: a beat cube is a sum of tones per chirp plus complex Gaussian noise. Its power never stands
20 dB above the chirp's median unless something other than a beat signal put it there: P equal tones
reach P times their mean power, and Gaussian noise exceeds 100 times its median power with probability
2⁻¹⁰⁰ per sample. A lone corrupted ADC word does: a glitch in one sample of one beam is flat over the
whole delay-Doppler grid and was taken for the RIS return (1-11 m off, stated 1σ of millimetres).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import dsp
from dsp.impulses import screen_impulses
from risloc_rt.model import paper_scenario, simulate

STRICT = dsp.strict_backend("device1")


@pytest.fixture(scope="module")
def capture():
    """The paper's relay scenario, 21° off broadside, 10 dBm (Table I)."""
    scenario = paper_scenario("off-broadside", mode="relay")
    scenario = dataclasses.replace(scenario, radar=dataclasses.replace(scenario.radar, tx_power_dbm=10.0))
    return simulate(scenario, rng=np.random.default_rng(5))


def _locate(cap, cube, estimator):
    return dsp.self_localize(cube, sweep=cap.sweep, radar=cap.radar, processing=cap.processing, pose=cap.ris.pose,
                             loopback_delay=cap.ris.loopback_delay, estimator=estimator, pattern=cap.ris.beam_pattern())


@pytest.mark.parametrize("case", ["broadside", "off-broadside"])
@pytest.mark.parametrize("tx_dbm", [0.0, 40.0])
def test_beat_signals_are_never_marked(case, tx_dbm):
    # 4.7·10⁶ noisy samples per capture (the noise's largest is ~13.5 dB over its chirp's median at Table I)
    # and the noiseless cube (tones only): nothing stands 20 dB above its chirp
    scenario = paper_scenario(case)
    scenario = dataclasses.replace(scenario, radar=dataclasses.replace(scenario.radar, tx_power_dbm=tx_dbm))
    for noise in (True, False):
        cube = simulate(scenario, rng=np.random.default_rng(2), noise=noise).cube
        out, screen = screen_impulses(cube)
        assert screen.count == 0 and out is cube


def test_thirty_equal_tones_with_random_phases_are_not_marked():
    # P tones of equal power reach at most P times their mean where they align: 30 tones stay below 20 dB
    # over the median of their chirp unless nearly all align at one sample
    rng = np.random.default_rng(4)
    n = np.arange(600)
    y = np.zeros((4, 16, 600), complex)
    for _ in range(30):
        y += np.exp(2j * np.pi * (rng.uniform(size=(4, 16, 1)) + rng.uniform() * n))
    assert screen_impulses(y)[1].count == 0


def test_a_glitch_is_found_zeroed_and_nothing_else_changes(capture):
    cube = capture.cube.copy()
    sigma = np.sqrt(capture.radar.noise_power)
    cube[40, 60, 300] = 3000 * sigma
    out, screen = screen_impulses(cube)
    np.testing.assert_array_equal(screen.samples, [[40, 60, 300]])
    assert screen.beams == (40,)
    power = np.abs(cube[40, 60]) ** 2
    median = np.sort(power)[300]  # the upper median of the chirp's 600 powers
    assert screen.largest_db == pytest.approx(10 * np.log10(power[300] / median), abs=1e-9)
    assert out[40, 60, 300] == 0
    keep = np.ones(cube.shape, bool)
    keep[40, 60, 300] = False
    np.testing.assert_array_equal(out[keep], cube[keep])
    assert cube[40, 60, 300] != 0  # the input is not modified


@pytest.mark.parametrize("estimator", ["paper", "refined"])
def test_a_glitch_no_longer_moves_the_fix(capture, estimator):
    # Regression: a 3000σ sample in beam 10 (far from the RIS's beam 44) was taken for the return: the fix
    # moved 11 m (paper) with a stated 1σ of 8 mm, flagged only pattern-mismatch. Now it is zeroed: the fix is
    # the clean capture's to within what one zeroed sample of noise changes, and the flag says what was done.
    clean = _locate(capture, capture.cube, estimator)
    cube = capture.cube.copy()
    cube[10, 60, 300] += 3000 * np.sqrt(capture.radar.noise_power)
    loc = _locate(capture, cube, estimator)
    assert loc.detected and loc.beam_index == clean.beam_index
    assert np.linalg.norm(loc.position - clean.position) < 0.1 * clean.std.distance
    assert "impulsive-samples" in loc.flag_codes and "pattern-mismatch" not in loc.flag_codes
    assert "impulsive-samples" not in clean.flag_codes
    message = next(f.message for f in loc.flags if f.code == "impulsive-samples")
    assert "1 ADC sample" in message and "beam(s) 10" in message and "within 20 dB" in message


def test_an_interference_burst_shorter_than_half_a_chirp_is_excised(capture):
    # Another FMCW radar crossing this one's band leaves a short burst of strong samples in some chirps;
    # 60 samples 30 dB above the noise in 8 chirps of one beam are zeroed and the fix is unchanged
    cube = capture.cube.copy()
    rng = np.random.default_rng(9)
    sigma = np.sqrt(capture.radar.noise_power)
    burst = 30 * sigma * np.exp(2j * np.pi * rng.uniform(size=(8, 60)))
    cube[20, 30:38, 200:260] += burst
    out, screen = screen_impulses(cube)
    assert screen.count == 8 * 60 and screen.beams == (20,)
    assert np.all(out[20, 30:38, 200:260] == 0)
    clean = _locate(capture, capture.cube, "refined")
    loc = _locate(capture, cube, "refined")
    assert np.linalg.norm(loc.position - clean.position) < 0.5 * clean.std.distance


def test_a_zero_filled_chirp_has_no_scale_and_nothing_is_marked():
    y = np.zeros((2, 4, 64), complex)
    y[:, :, :10] = 1.0  # most of each chirp zero-filled (a lost packet): median 0
    assert screen_impulses(y)[1].count == 0


def test_no_detection_still_says_what_was_zeroed():
    scenario = paper_scenario("off-broadside", mode="relay")
    weak = dataclasses.replace(scenario, radar=dataclasses.replace(scenario.radar, tx_power_dbm=-30.0))
    cap = simulate(weak, rng=np.random.default_rng(6))
    cube = cap.cube.copy()
    cube[3, 3, 3] = 1e4 * np.sqrt(cap.radar.noise_power)
    loc = _locate(cap, cube, "paper")
    assert not loc.detected
    assert loc.flag_codes[0] == "no-detection" and "impulsive-samples" in loc.flag_codes


def test_on_a_device_the_same_samples_are_found(capture, impulse_screen_matches_host):
    impulse_screen_matches_host(capture.cube, capture.radar.noise_power, STRICT)


@pytest.mark.parametrize("bad", [0.0, -3.0, float("nan")])
def test_a_bad_threshold_is_one_line(bad):
    with pytest.raises(ValueError, match=r"crest_db=.* must be > 0 \[dB\]"):
        screen_impulses(np.ones((2, 2, 8), complex), crest_db=bad)

"""The delay's drift across the sweep measures ν without the Doppler's ±ν_max ambiguity."""

from __future__ import annotations

import numpy as np
import pytest

from dsp import SPEED_OF_LIGHT, RadarConfig
from dsp.drift import delay_drift


def _cube(radar, *, delay, rate, beams=15, amplitude=1.0, noise=0.0, rng=None):
    """One tone per beam at the delay of its frame time: τ(t_m) = τ0 + ν (t_m - t_mid), Doppler ν."""
    t = radar.beam_times(beams)
    n = np.arange(radar.num_samples)
    k = np.arange(radar.num_chirps)
    taus = delay + rate * (t - t.mean())
    f1 = (taus * radar.slope + radar.carrier_frequency * rate) * radar.sample_period          # [M]
    f2 = rate * radar.carrier_frequency * radar.chirp_interval
    cube = amplitude * np.exp(-2j * np.pi * (f1[:, None, None] * n + f2 * k[:, None]))
    if noise:
        cube = cube + noise * (rng.standard_normal(cube.shape) + 1j * rng.standard_normal(cube.shape)) / np.sqrt(2)
    return cube, taus


@pytest.mark.parametrize("velocity", [-40.0, -1.5, 0.0, 2.0, 33.0])
def test_the_drift_recovers_the_true_rate_even_beyond_the_doppler_span(velocity):
    radar = RadarConfig(num_samples=128, num_chirps=16)
    rate = 2 * velocity / SPEED_OF_LIGHT
    cube, taus = _cube(radar, delay=90e-9, rate=rate)
    # The Doppler the DSP would read is ν wrapped into ±ν_max; the drift does not care.
    span = 2 * radar.max_delay_rate
    wrapped = (rate + span / 2) % span - span / 2
    drift = delay_drift(cube, radar, delay=float(np.mean(taus)), delay_rate=wrapped, weights=np.ones(15))
    # 7 frames of 0.8 ms, delays within a fraction of a resolution cell: 0.3 m/s
    assert abs(drift.rate - rate) * SPEED_OF_LIGHT / 2 < 0.3


def test_one_beam_on_another_return_does_not_drag_the_line(rng):
    radar = RadarConfig(num_samples=128, num_chirps=16)
    rate = 2 * -40.0 / SPEED_OF_LIGHT
    cube, taus = _cube(radar, delay=90e-9, rate=rate, noise=0.05, rng=rng)
    other, _ = _cube(radar, delay=90e-9 - 1.78e-9, rate=rate, amplitude=3.0)  # the panel, τ_RB earlier
    cube[0] = other[0]                                                          # one beam locks onto it
    span = 2 * radar.max_delay_rate
    drift = delay_drift(cube, radar, delay=float(np.mean(taus)), delay_rate=(rate + span / 2) % span - span / 2,
                        weights=np.ones(15))
    assert abs(drift.rate - rate) * SPEED_OF_LIGHT / 2 < 1.0
    assert drift.std * SPEED_OF_LIGHT / 2 < 2.0


def test_too_few_beams_gives_no_drift():
    radar = RadarConfig(num_samples=64, num_chirps=16)
    cube, taus = _cube(radar, delay=50e-9, rate=0.0, beams=5)
    assert delay_drift(cube, radar, delay=50e-9, delay_rate=0.0, weights=np.array([0.1, 0.2, 1.0, 0.5, 0.1])) is None

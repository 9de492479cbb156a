"""Off-grid refinement (dsp/refine.py) and the beam pattern (dsp/pattern.py).

Oracles: a noiseless tone of known delay, delay rate and AoD, all off every grid, is recovered to
numerical precision (the likelihood's maximum is the truth); the AoD comes from the pattern fit,
so a UE halfway between two beams is found halfway, not on a beam; a beam-independent return
three resolution cells away (the panel's structural reflection) does not pull the delay; the
array factor peaks where the beam is steered and a reflective RIS has its grating lobe at
sin φ = sin θ - λ/(2d).
"""

from __future__ import annotations

import numpy as np
import pytest

import dsp

C = dsp.SPEED_OF_LIGHT
RADAR = dsp.RadarConfig(num_samples=64, num_chirps=16)
SWEEP = dsp.BeamSweep.azimuth_grid(*np.deg2rad([-21.0, 21.0, 3.0]))  # M = 15
RELAY = dsp.BeamPattern().for_wavelength(RADAR.wavelength)


@pytest.fixture
def ris_cube(tone):
    """The local cube factory, closing over the ``tone`` fixture."""

    def ris_cube(*, tau, nu, aod, pattern=RELAY, sweep=SWEEP, amplitude=1.0, phases=None):
        a = pattern.amplitude(aod, sweep.angles)
        ph = np.ones(sweep.num_beams) if phases is None else np.exp(1j * phases)
        return (amplitude * np.abs(a) * ph)[:, None, None] * tone(RADAR, tau, nu)[None]

    return ris_cube


def refine(cube, tau0, nu0, pattern=RELAY, sweep=SWEEP, **kw):
    return dsp.refine_estimate(cube, sweep=sweep, radar=RADAR, pattern=pattern, initial_delay=tau0,
                               initial_delay_rate=nu0, **kw)


def test_pattern_peaks_at_the_steered_beam_and_has_the_reflective_grating_lobe():
    beams = np.deg2rad([[0.0, 0.0], [10.0, 0.0], [-30.0, 0.0]])
    for b in beams:
        assert RELAY.amplitude(b, beams)[list(map(tuple, beams)).index(tuple(b))] == pytest.approx(1.0)
    refl = dsp.BeamPattern.reflective().for_wavelength(RADAR.wavelength)
    theta = np.deg2rad(30.0)
    grating = np.arcsin(np.sin(theta) - RADAR.wavelength / (2 * refl.element_spacing))  # -30° for λ/2
    assert abs(refl.amplitude([theta, 0.0], np.array([[grating, 0.0]]))[0]) == pytest.approx(1.0, abs=1e-3)
    assert abs(RELAY.amplitude([theta, 0.0], np.array([[grating, 0.0]]))[0]) < 0.1  # no grating lobe for relay
    # first null of the 16-element relay pattern at Δu = 1/8
    assert RELAY.amplitude([np.arcsin(1 / 8), 0.0], np.zeros((1, 2)))[0] == pytest.approx(0.0, abs=1e-12)


def test_noiseless_off_grid_tone_is_recovered_exactly(ris_cube):
    tau, nu = 2 * 7.3217 / C + 1.78e-9, 2 * (-0.731) / C
    aod = np.array([np.deg2rad(4.567), 0.0])
    cube = ris_cube(tau=tau, nu=nu, aod=aod, phases=np.random.default_rng(0).uniform(0, 6.3, 15))
    # start half a resolution cell away on both axes
    est = refine(cube, tau + 0.45 * RADAR.delay_resolution, nu + 0.45 * RADAR.velocity_resolution * 2 / C)
    assert est.converged
    assert abs(est.delay - tau) * C / 2 < 1e-6  # [m]
    assert abs(est.delay_rate - nu) * C / 2 < 1e-6  # [m/s]
    assert abs(est.aod.aod[0] - aod[0]) < 1e-7  # [rad]
    assert est.amplitude == pytest.approx(1.0, rel=1e-6)


def test_aod_between_two_beams_is_interpolated_not_picked(ris_cube):
    aod = np.array([np.deg2rad(1.5), 0.0])  # halfway between the beams at 0° and 3°
    tau, nu = 2 * 5.0 / C, 0.0
    est = refine(ris_cube(tau=tau, nu=nu, aod=aod), tau, nu)
    assert abs(est.aod.aod[0] - aod[0]) < 1e-7
    fit = dsp.fit_aod(np.abs(RELAY.amplitude(aod, SWEEP.angles)), SWEEP, RELAY)
    assert abs(fit.aod[0] - aod[0]) < 1e-7 and fit.candidates.shape[1] == 2


def test_static_return_nearby_does_not_pull_the_delay(tone, ris_cube):
    # A beam-independent return 3 resolution cells nearer and 20 dB stronger than the RIS peak.
    tau, nu = 2 * 9.0 / C + 1.78e-9, 0.0
    aod = np.array([np.deg2rad(-6.2), 0.0])
    ris = ris_cube(tau=tau, nu=nu, aod=aod)
    clutter = 10.0 * np.exp(0.4j) * tone(RADAR, tau - 3 * RADAR.delay_resolution, 0.0)[None]
    cube = ris + clutter
    with_removal = refine(cube, tau, nu)
    without = refine(cube, tau, nu, remove_static=False)
    err_with = abs(with_removal.delay - tau) * C / 2
    err_without = abs(without.delay - tau) * C / 2
    assert err_with < 1e-4 * RADAR.range_resolution
    assert err_without > 100 * err_with  # the leakage is real, and the template removes it


def test_two_dimensional_sweep_estimates_elevation(ris_cube):
    grid = np.deg2rad([[az, el] for el in (-20.0, -10.0, 0.0, 10.0, 20.0) for az in np.arange(-12.0, 12.1, 3.0)])
    sweep = dsp.BeamSweep(grid)
    aod = np.deg2rad([2.2, 7.3])
    tau, nu = 2 * 6.0 / C, 0.0
    est = refine(ris_cube(tau=tau, nu=nu, aod=aod, sweep=sweep), tau, nu, sweep=sweep)
    assert np.all(np.abs(est.aod.aod - aod) < 1e-5)


def test_beam_dtft_magnitude_is_the_tone_amplitude_times_kn(ris_cube):
    tau, nu = 2 * 4.0 / C, 2 * 0.2 / C
    aod = np.array([0.05, 0.0])
    mags, f1, f2 = dsp.beam_dtft(ris_cube(tau=tau, nu=nu, aod=aod, amplitude=2.0), RADAR, tau, nu)
    expected = 2.0 * np.abs(RELAY.amplitude(aod, SWEEP.angles)) * RADAR.num_chirps * RADAR.num_samples
    np.testing.assert_allclose(mags, expected, rtol=1e-9, atol=1e-9 * expected.max())


def test_pattern_validates_its_fields():
    with pytest.raises(ValueError, match="gradient_factor"):
        dsp.BeamPattern(gradient_factor=3)
    with pytest.raises(ValueError, match="for_wavelength"):
        dsp.BeamPattern().amplitude([0.0, 0.0], np.zeros((1, 2)))

"""A cube on a device (array_api_strict's 'device1', which refuses implicit host copies): checked there, and
dsp.self_localize gives the host's answer for both estimators, the paper's grid search running there too
(dsp.devicegrid: the host's screened search and the device's bounded search pick the same cells)."""

from __future__ import annotations

import numpy as np
import pytest

import dsp
from risloc_rt.model import paper_scenario, simulate

STRICT = dsp.strict_backend("device1")


@pytest.fixture(scope="module")
def capture():
    return simulate(paper_scenario("off-broadside", mode="relay"), rng=np.random.default_rng(4))


def test_a_device_cube_is_checked_where_it_lives(make_radar):
    radar = make_radar(num_chirps=8, num_samples=16)
    good = np.ones((3, 8, 16), dtype=complex)
    assert dsp.check_beat_cube(STRICT.asarray(good), radar).device == STRICT.device  # stays there
    bad = good.copy()
    bad[1, 2, 3] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        dsp.check_beat_cube(STRICT.asarray(bad), radar)
    with pytest.raises(ValueError, match="all zeros"):
        dsp.check_beat_cube(STRICT.asarray(np.zeros_like(good)), radar)
    with pytest.raises(ValueError, match=r"radar has K=8 chirps and N=16 samples"):
        dsp.check_beat_cube(STRICT.asarray(np.ones((3, 8, 15), dtype=complex)), radar)
    with pytest.raises(ValueError, match=r"at least 2 beams"):
        dsp.check_beat_cube(STRICT.asarray(np.ones((1, 8, 16), dtype=complex)), radar)
    with pytest.raises(TypeError, match="complex beat samples"):
        dsp.check_beat_cube(STRICT.asarray(np.ones((3, 8, 16))), radar)
    # the same messages as for host data
    with pytest.raises(ValueError, match="all zeros"):
        dsp.check_beat_cube(np.zeros_like(good), radar)


@pytest.mark.parametrize("estimator", ["refined", "paper"])
def test_self_localize_on_a_device_cube_equals_the_host(capture, estimator):
    kw = dict(sweep=capture.sweep, radar=capture.radar, processing=capture.processing, pose=capture.ris.pose,
              loopback_delay=capture.ris.loopback_delay, estimator=estimator, pattern=capture.ris.beam_pattern())
    host = dsp.self_localize(capture.cube, **kw)
    dev = dsp.self_localize(capture.cube, backend=STRICT, **kw)  # copied to device1 once, read there
    assert dev.detected and host.detected
    assert dev.flag_codes == host.flag_codes and dev.beam_index == host.beam_index
    # the detector's complex64 statistic differs in last digits (NumPy's FFT, not SciPy's); the estimates
    # are float64 projections of the same cube: equal to 1e-9 m and 1e-9 rad
    assert dev.distance == pytest.approx(host.distance, abs=1e-9)
    assert dev.aod[0] == pytest.approx(host.aod[0], abs=1e-9)
    assert dev.std.distance == pytest.approx(host.std.distance, rel=2e-6)
    if estimator == "paper":  # the grid search ran on device1 (no host copy): its bins are the host's
        np.testing.assert_array_equal(dev.scan.delay_bin, host.scan.delay_bin)
        np.testing.assert_array_equal(dev.scan.doppler_bin, host.scan.doppler_bin)

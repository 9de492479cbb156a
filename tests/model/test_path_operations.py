"""Path operations (risloc_rt.model.paths): select_paths and shift_paths, with eq. (1) as the oracle."""

from __future__ import annotations

import numpy as np
import pytest

from dsp import ProcessingConfig, delay_doppler_map
from dsp.radar import SPEED_OF_LIGHT
from risloc_rt.model import paper_scenario
from risloc_rt.model.beat import beat_cube
from risloc_rt.model.link_budget import carrier_phase
from risloc_rt.model.paths import PathSet, select_paths, shift_paths
from risloc_rt.model.scenario import analytic_paths


@pytest.fixture(scope="module")
def scenario():
    return paper_scenario("off-broadside")


def test_select_paths_splits_the_cube_linearly(scenario):
    paths = analytic_paths(scenario)
    via = paths.via_ris
    assert via.any() and (~via).any()
    ris_only, static = select_paths(paths, via), select_paths(paths, ~via)
    assert len(ris_only) + len(static) == len(paths)
    assert ris_only.labels == tuple(lab for lab, v in zip(paths.labels, via) if v)
    assert ris_only.via_ris.all() and not static.via_ris.any()
    np.testing.assert_array_equal(ris_only.delay, paths.delay[via])
    kw = dict(radar=scenario.radar, sweep=scenario.sweep, ris=scenario.ris)
    whole = beat_cube(paths, **kw)
    parts = beat_cube(ris_only, **kw) + beat_cube(static, **kw)
    scale = np.max(np.abs(whole))                                       # [√W]
    assert np.max(np.abs(whole - parts)) <= 1e-9 * scale                # eq. (1) is a sum over paths
    assert len(select_paths(paths, np.zeros(len(paths), bool))) == 0


def test_shift_paths_delays_every_path_with_its_carrier_phase(scenario):
    paths = analytic_paths(scenario)
    radar = scenario.radar
    delta = 2 * 0.75 / SPEED_OF_LIGHT                                   # a 0.75 m range offset [s]
    shifted = shift_paths(paths, delta, radar.carrier_frequency)
    np.testing.assert_allclose(shifted.delay - paths.delay, delta, rtol=0, atol=1e-18)
    # The carrier phase of the longer path: γ · exp(−j2π f_c Δτ), the model's own carrier_phase.
    expected = paths.gain * carrier_phase(delta, radar.carrier_frequency)
    np.testing.assert_allclose(shifted.gain, expected, rtol=1e-9, atol=0)
    np.testing.assert_array_equal(shifted.delay_rate, paths.delay_rate)
    assert shifted.labels == paths.labels and len(shifted) == len(paths)


def test_shifted_paths_move_the_range_peak_by_the_offset(scenario):
    paths = select_paths(analytic_paths(scenario), analytic_paths(scenario).via_ris)
    radar = scenario.radar
    processing = ProcessingConfig(n_dft=8 * radar.num_samples, k_dft=radar.num_chirps)
    offset = 0.75                                                       # [m]
    kw = dict(radar=radar, sweep=scenario.sweep, ris=scenario.ris)
    beam = int(np.argmax(np.sum(np.abs(beat_cube(paths, **kw)) ** 2, axis=(1, 2))))

    def peak(p: PathSet) -> tuple[float, float]:
        """(distance of the zero-Doppler peak, one DFT bin) [m]."""
        ddm = delay_doppler_map(beat_cube(p, **kw)[beam], radar, processing)
        return float(ddm.distance[int(np.argmax(ddm.profile(0.0)))]), float(ddm.distance[1] - ddm.distance[0])

    (before, bin_m), (after, _) = peak(paths), peak(shift_paths(paths, 2 * offset / SPEED_OF_LIGHT,
                                                                 radar.carrier_frequency))
    assert bin_m < 0.01 and abs(after - before - offset) <= bin_m

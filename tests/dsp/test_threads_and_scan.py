"""The DSP's thread budget (dsp.limit_threads) and self_localize(scan=False).

Oracles: the thread count must not change a single number (the studies promise identical results
for any number of workers, each worker single-threaded); skipping the paper's grid search must not
change a number of the refined estimate, only drop ``Localization.scan``.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import dsp
from risloc_rt.model.simulate import simulate


def _localize(scenario, cube, **kw):
    return dsp.self_localize(cube, sweep=scenario.sweep, radar=scenario.radar, processing=scenario.processing,
                             pose=scenario.ris.pose, loopback_delay=scenario.ris.loopback_delay,
                             pattern=scenario.ris.beam_pattern(), **kw)


def _same(a, b, skip=("scan",)):
    for field in dataclasses.fields(a):
        if field.name in skip:
            continue
        x, y = getattr(a, field.name), getattr(b, field.name)
        if field.name == "std":
            x, y = dataclasses.asdict(x), dataclasses.asdict(y)
            for key in x:
                np.testing.assert_array_equal(x[key], y[key], err_msg=f"std.{key}")
        elif field.name == "detection":
            assert x == y
        else:
            np.testing.assert_array_equal(x, y, err_msg=field.name)


@pytest.fixture(scope="module")
def noisy(make_scenario):
    scenario = make_scenario(ue_velocity=(0.2, -0.5, 0.0))
    return scenario, simulate(scenario, rng=np.random.default_rng(11)).cube


def test_limit_threads_nests_and_restores():
    cores = dsp.thread_count()
    assert cores >= 1
    with dsp.limit_threads(1):
        assert dsp.thread_count() == 1
        with dsp.limit_threads(max(2, cores)):
            assert dsp.thread_count() == min(max(2, cores), cores)  # never above the usable cores
        assert dsp.thread_count() == 1
    assert dsp.thread_count() == cores


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "2"])
def test_limit_threads_rejects_a_bad_count(bad):
    with pytest.raises(ValueError, match="must be an integer >= 1"):
        with dsp.limit_threads(bad):
            pass


@pytest.mark.parametrize("estimator", ["paper", "refined"])
def test_one_thread_gives_the_same_numbers(noisy, estimator):
    scenario, cube = noisy
    default = _localize(scenario, cube, estimator=estimator)
    with dsp.limit_threads(1):
        single = _localize(scenario, cube, estimator=estimator)
    assert default.detection.detected
    _same(default, single)
    for field in dataclasses.fields(default.scan):
        np.testing.assert_array_equal(getattr(default.scan, field.name), getattr(single.scan, field.name))


def test_refined_without_the_grid_search_gives_the_same_numbers(noisy):
    scenario, cube = noisy
    full = _localize(scenario, cube, estimator="refined")
    lean = _localize(scenario, cube, estimator="refined", scan=False)
    assert full.scan is not None and lean.scan is None
    assert lean.detection.detected
    _same(full, lean)


def test_the_paper_estimator_without_a_scan_gives_the_same_numbers(noisy):
    # scan=False: the paper's estimator searches only the beams that can be the best
    # (scan_beams(best_only=True)) and keeps no scan; every number is the full scan's.
    scenario, cube = noisy
    loc = _localize(scenario, cube, estimator="paper", scan=False)
    full = _localize(scenario, cube, estimator="paper")
    assert loc.scan is None and full.scan is not None
    _same(loc, full)


def test_no_detection_without_a_scan_names_the_detectors_beam(make_scenario):
    scenario = make_scenario()
    noise = simulate(scenario, rng=np.random.default_rng(3)).cube - simulate(
        scenario, rng=np.random.default_rng(3), noise=False).cube  # the noise alone: nothing to detect
    loc = _localize(scenario, noise, estimator="refined", scan=False)
    assert not loc.detection.detected and loc.scan is None
    assert loc.flag_codes[0] == "no-detection" and np.isnan(loc.distance)
    assert -1 <= loc.beam_index < scenario.sweep.num_beams


def test_scan_must_be_a_bool(noisy):
    scenario, cube = noisy
    with pytest.raises(TypeError, match="scan='no' must be True or False"):
        _localize(scenario, cube, estimator="refined", scan="no")

"""Hard cases for numerical stability and geometry (issue 11): each case of docs/hard-cases.md.

Each test states the documented behaviour: a correct estimate, a named flag, or a clear error.
No case may answer silently wrong.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dsp import SPEED_OF_LIGHT, self_localize
from risloc_rt.model.capture import Capture
from risloc_rt.model.scenario import PAPER_DISTANCE
from risloc_rt.model.simulate import simulate


def _run(scenario, cube=None, estimator="paper"):
    cap = simulate(scenario, rng=np.random.default_rng(0), seed=0, noise=False)
    loc = self_localize(cap.cube if cube is None else cube(cap), sweep=cap.sweep, radar=cap.radar,
                        processing=cap.processing, pose=cap.ris.pose, loopback_delay=cap.ris.loopback_delay,
                        estimator=estimator, pattern=cap.ris.beam_pattern())
    return cap, loc, {f.code for f in loc.flags}


def _range_cell(cap):
    return SPEED_OF_LIGHT / (2 * cap.radar.bandwidth)


def test_hard_complex64_phase_at_long_delays(make_scenario):
    # complex64 keeps 24 bits: a long-delay beat's phase survives because phases are reduced before exp
    # (model/phase.py); the stored complex64 cube localizes exactly as the complex128 one.
    cap, loc128, _ = _run(make_scenario())
    _, loc64, _ = _run(make_scenario(), cube=lambda c: c.cube.astype(np.complex64))
    assert loc64.beam_index == loc128.beam_index and loc64.distance == pytest.approx(loc128.distance, abs=1e-9)
    assert abs(loc64.distance - cap.truth.distance) < cap.radar.max_range / cap.processing.n_dft  # one grid step


def test_hard_two_returns_closer_than_the_range_resolution(make_scenario):
    # The RIS structure (at the RIS) and the re-transmission (tau_RB later) overlap when the UE is
    # moving fast: flagged 'unresolved-peaks'.
    _, loc, flags = _run(make_scenario(ue_velocity=(0.0, 40.0, 0.0)))
    assert "unresolved-peaks" in flags


def test_hard_equal_power_beams_are_not_a_detection(make_scenario):
    # Every beam the same: no beam dependence, so no AoD; never an arbitrary first beam.
    _, loc, flags = _run(make_scenario(), cube=lambda c: np.broadcast_to(c.cube[30], c.cube.shape).copy())
    assert {"no-detection", "no-beam-dependence"} <= flags and np.isnan(loc.distance)


def test_hard_grating_lobes_are_flagged(make_scenario):
    _, loc, flags = _run(make_scenario(ris_kw={"element_spacing": 4 * 0.005}))
    assert "grating-lobe" in flags


def test_hard_return_beyond_the_unambiguous_range(make_scenario, make_radar):
    # 25.4 m folds back to 25.4 - R_max = 3.6 m, and the DSP alone cannot tell; the link budget can
    # (the loop-back arrives 32 dB weaker than predicted at 3.6 m): risloc locate's process_capture
    # flags it. On this small radar (K = 16, N = 128) the return is still detected (about 3 dB above
    # the threshold), so the position is given, folded, and flagged 'aliased'. The same branch at
    # Table I sizes is tests/model/test_power_check.py.
    from risloc_rt.io import process_capture

    cap = simulate(make_scenario(ue_position=(0.0, -12.0, 0.0)), rng=np.random.default_rng(0), seed=0)
    r_max = make_radar().max_range
    assert cap.truth.distance > r_max
    loc, _ = process_capture(cap)
    assert loc.detected and loc.detection.detected
    assert "aliased" in loc.flag_codes
    # the estimate is the folded distance, within one range cell c/(2B)
    assert abs(loc.distance - (cap.truth.distance - r_max)) < _range_cell(cap)


def test_hard_zero_and_nan_cubes_are_errors(make_scenario):
    cap = simulate(make_scenario(), rng=np.random.default_rng(0), seed=0)
    with pytest.raises(ValueError, match="all zeros"):
        _run(make_scenario(), cube=lambda c: np.zeros_like(c.cube))
    with pytest.raises(ValueError, match="NaN or infinite"):
        dataclasses.replace(cap, cube=np.full_like(cap.cube, np.nan))


def test_hard_ue_near_the_ris_plane_grazing(make_scenario):
    # 75° off boresight with a ±45° sweep: the paper's method picks the edge beam, the refined fit a
    # sidelobe beyond the span; both must say the UE may lie outside the sweep.
    for estimator in ("paper", "refined"):
        _, loc, flags = _run(make_scenario(ue_position=(13.0, 10.0, 0.0), ris_facing=(0.0, 0.0, 0.0)),
                             estimator=estimator)
        assert "beam-edge" in flags, estimator


def test_hard_ue_behind_the_ris_or_ris_facing_away_is_refused(make_scenario):
    with pytest.raises(ValueError, match="behind the RIS panel"):
        make_scenario(ue_position=(0.0, 0.0, 0.0), ris_facing=(0.0, 30.0, 0.0))


def test_hard_ue_inside_a_wall_or_outside_the_hall_is_refused():
    from risloc_rt.hall.scenario import hall_scenario

    with pytest.raises(ValueError, match="radar"):
        hall_scenario("paper_hall", ue_position=(-3.0, 9.0, 1.2))  # outside the hall
    with pytest.raises(ValueError, match="radar"):
        hall_scenario("paper_hall", ue_position=(0.0, 9.0, 1.2))  # in the plane of wall_3


def test_hard_ue_in_the_ris_near_field(make_scenario):
    # 0.18 m from a 4 cm aperture (Fraunhofer distance 2D²/λ = 0.64 m): the far-field model still gives
    # the distance within two range cells and the broadside beam.
    cap, loc, flags = _run(make_scenario(ue_position=(0.0, PAPER_DISTANCE - 0.18, 0.0)))
    assert abs(loc.distance - cap.truth.distance) < 2 * _range_cell(cap)
    assert loc.aod[0] == pytest.approx(0.0, abs=1e-12)


def test_hard_doppler_beyond_the_unambiguous_velocity(make_scenario, make_radar):
    # -40 m/s reads as +10 m/s in the Doppler; the delay drifting across the sweep gives it away.
    for estimator in ("paper", "refined"):
        cap, loc, flags = _run(make_scenario(ue_velocity=(0.0, 40.0, 0.0)), estimator=estimator)
        assert abs(cap.truth.velocity) > make_radar().max_velocity
        assert "aliased" in flags, estimator


def test_hard_real_valued_cube_is_refused(make_scenario):
    cap = simulate(make_scenario(), rng=np.random.default_rng(0), seed=0)
    with pytest.raises(TypeError, match="real-valued"):
        Capture(cube=cap.cube.real, sweep=cap.sweep, radar=cap.radar, ris=cap.ris, processing=cap.processing,
                frame_index=cap.frame_index, provenance=cap.provenance)

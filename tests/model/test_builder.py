"""analytic_scenario: a UE placed by position or by RIS-frame distance and AoD, in one call."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from dsp import RisPose, direction_from_angles
from risloc_rt.model import analytic_paths, paper_scenario
from risloc_rt.model.builder import RisMisconfiguredWarning, analytic_scenario, relay_rx_gain


def test_distance_and_aod_place_the_ue_where_geometry_says():
    aod = np.deg2rad([7.3, -4.0])
    s = analytic_scenario(distance=10.0, aod=aod)
    # truth recomputed from the UE position: distance and angles come back to 1e-12
    assert abs(s.truth.distance - 10.0) < 1e-12
    np.testing.assert_allclose(s.truth.aod, aod, atol=1e-12)
    expected = s.ris.pose.position + 10.0 * s.ris.pose.to_world(direction_from_angles(aod))
    np.testing.assert_allclose(s.ue_position, expected, atol=1e-12)


def test_the_paper_cases_are_special_cases():
    for case, yaw in (("broadside", 0.0), ("off-broadside", -21.0)):
        paper = paper_scenario(case)
        built = analytic_scenario(ue_position=[0.0, 0.0, 0.0], ris_yaw=np.deg2rad(yaw), name=paper.name)
        a, b = analytic_paths(paper), analytic_paths(built)
        np.testing.assert_array_equal(a.gain, b.gain)
        np.testing.assert_array_equal(a.delay, b.delay)
        assert a.labels == b.labels == ("ris_loopback", "ris_structure")
        np.testing.assert_array_equal(paper.ris.relay_rx_angle, built.ris.relay_rx_angle)


def test_structure_is_on_by_default_and_can_be_switched_off():
    assert [t.label for t in analytic_scenario(distance=8.0, aod=[0.1, 0.0]).targets] == ["ris_structure"]
    assert analytic_scenario(distance=8.0, aod=[0.1, 0.0], structure=False).targets == ()


def test_relay_rx_beam_points_at_the_ue_unless_told_otherwise():
    s = analytic_scenario(distance=9.0, aod=np.deg2rad([25.0, 0.0]))
    assert relay_rx_gain(s.ris, s.ue_position, wavelength=s.radar.wavelength) == pytest.approx(1.0, abs=1e-12)


def test_a_misconfigured_relay_warns_and_a_good_one_does_not():
    with pytest.warns(RisMisconfiguredWarning, match=r"misses the UE at \[20.0, 0.0\]°"):
        analytic_scenario(distance=10.0, aod=np.deg2rad([20.0, 0.0]), relay_rx_angle=[0.0, 0.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        # 16 elements at λ/2: the half-power half-width is about 3.2°, so 2° off is still fine
        analytic_scenario(distance=10.0, aod=np.deg2rad([2.0, 0.0]), relay_rx_angle=[0.0, 0.0])
        analytic_scenario(distance=10.0, aod=np.deg2rad([20.0, 0.0]), relay_rx_angle=[0.0, 0.0], mode="reflective")


@pytest.mark.parametrize("kw, match", [
    ({}, "either by ue_position"),
    ({"ue_position": [0, 0, 0], "distance": 3.0, "aod": [0, 0]}, "either by ue_position"),
    ({"distance": 3.0}, "distance and aod go together"),
    ({"distance": -3.0, "aod": [0, 0]}, "distance"),
    ({"distance": 3.0, "aod": [0.0, 0.0, 0.0]}, "aod"),
    ({"ue_position": [0, 30, 0]}, "behind the RIS panel"),
    ({"distance": 3.0, "aod": [0, 0], "ris_pose": "north"}, "ris_pose must be a dsp.RisPose"),
])
def test_bad_placements_are_refused_with_the_reason(kw, match):
    with pytest.raises((ValueError, TypeError), match=match):
        analytic_scenario(**kw)


def test_a_given_pose_and_power_are_used():
    pose = RisPose.facing(np.array([2.0, 5.0, 1.0]), np.array([2.0, 0.0, 1.0]))
    s = analytic_scenario(distance=4.0, aod=[0.0, 0.0], ris_pose=pose, tx_power_dbm=5.0)
    np.testing.assert_allclose(s.ue_position, [2.0, 1.0, 1.0], atol=1e-12)
    assert s.radar.tx_power_dbm == 5.0

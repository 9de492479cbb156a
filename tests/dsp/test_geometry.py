"""RIS frame and azimuth/elevation convention (dsp/geometry.py, dsp/sweep.py)."""

from __future__ import annotations

import numpy as np
import pytest

from dsp import BeamSweep, RisPose, angles_from_direction, direction_from_angles

# Pure float64 trigonometry on O(1) numbers: a few ulp, far below 1e-12.
ATOL = 1e-12

OBLIQUE_POSES = [
    RisPose(position=np.array([1.0, 2.0, 3.0]), normal=np.array([0.3, -0.8, 0.5])),
    RisPose(position=np.array([-4.0, 0.5, 2.0]), normal=np.array([1.0, 1.0, 0.0]),
            up=np.array([0.2, 0.1, 1.0])),
    RisPose.facing([3.0, 9.0, 2.5], [0.0, 0.0, 1.0], yaw=np.deg2rad(12.0)),
]


@pytest.mark.parametrize("pose", OBLIQUE_POSES)
def test_frame_is_orthonormal_and_right_handed(pose):
    u, w, n = pose.row_axis, pose.column_axis, pose.normal
    np.testing.assert_allclose(pose.rotation.T @ pose.rotation, np.eye(3), atol=ATOL)
    np.testing.assert_allclose(np.cross(u, w), n, atol=ATOL)
    assert np.linalg.det(pose.rotation) == pytest.approx(1.0, abs=ATOL)
    # w is the projection of "up" onto the panel: it must lean toward up, not away from it.
    assert w @ pose.up > 0


def test_angle_round_trip():
    rng = np.random.default_rng(1)
    # Stay away from the poles (|el| = π/2), where azimuth is undefined.
    angles = np.column_stack([rng.uniform(-np.pi + 1e-6, np.pi, 500), rng.uniform(-1.5, 1.5, 500)])
    d = direction_from_angles(angles)
    np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 1.0, atol=ATOL)
    # arcsin near |el| = 1.5 rad amplifies rounding by 1/cos(el) ≈ 14: still ≪ 1e-10 rad.
    np.testing.assert_allclose(angles_from_direction(d), angles, atol=1e-10)
    # And the other way round, with non-unit lengths (the inverse normalises).
    v = rng.normal(size=(500, 3)) * rng.uniform(0.1, 50.0, (500, 1))
    np.testing.assert_allclose(direction_from_angles(angles_from_direction(v)),
                               v / np.linalg.norm(v, axis=-1, keepdims=True), atol=ATOL)


def test_zero_angles_are_broadside_and_axes_are_where_the_convention_says():
    np.testing.assert_allclose(direction_from_angles([0.0, 0.0]), [0.0, 0.0, 1.0], atol=ATOL)
    # +az turns toward +u, +el toward +w.
    np.testing.assert_allclose(direction_from_angles([np.pi / 2, 0.0]), [1.0, 0.0, 0.0], atol=ATOL)
    np.testing.assert_allclose(direction_from_angles([0.0, np.pi / 2]), [0.0, 1.0, 0.0], atol=ATOL)
    for pose in OBLIQUE_POSES:
        np.testing.assert_allclose(pose.to_world(direction_from_angles([0.0, 0.0])), pose.normal, atol=ATOL)
        np.testing.assert_allclose(pose.angles_to(pose.position + 7.0 * pose.normal), [0.0, 0.0], atol=ATOL)
        np.testing.assert_allclose(pose.angles_to(pose.position + pose.row_axis + pose.normal),
                                   [np.pi / 4, 0.0], atol=ATOL)
        np.testing.assert_allclose(pose.angles_to(pose.position + pose.column_axis + pose.normal),
                                   [0.0, np.pi / 4], atol=ATOL)


@pytest.mark.parametrize("yaw_deg", [-40.0, -21.0, 0.0, 7.5, 30.0])
def test_facing_with_yaw_sees_target_at_minus_yaw(yaw_deg):
    target = np.array([0.0, 0.0, 0.0])
    pose = RisPose.facing([0.0, 13.38, 0.0], target, yaw=np.deg2rad(yaw_deg))
    np.testing.assert_allclose(pose.angles_to(target), [-np.deg2rad(yaw_deg), 0.0], atol=ATOL)
    # The panel stays vertical: its column axis is world up.
    np.testing.assert_allclose(pose.column_axis, [0.0, 0.0, 1.0], atol=ATOL)


@pytest.mark.parametrize("pose", OBLIQUE_POSES)
def test_point_at_inverts_angles_to(pose):
    rng = np.random.default_rng(2)
    points = pose.position + pose.to_world(
        direction_from_angles(np.column_stack([rng.uniform(-1.4, 1.4, 50), rng.uniform(-1.4, 1.4, 50)]))
    ) * rng.uniform(0.5, 30.0, (50, 1))
    distance = np.linalg.norm(points - pose.position, axis=-1)
    # Positions up to 30 m: 1e-12 relative of that.
    np.testing.assert_allclose(pose.point_at(pose.angles_to(points), distance), points, atol=3e-11)


def test_to_local_inverts_to_world():
    pose = OBLIQUE_POSES[1]
    v = np.random.default_rng(3).normal(size=(20, 3))
    np.testing.assert_allclose(pose.to_local(pose.to_world(v)), v, atol=ATOL)


def test_azimuth_grid_is_the_paper_sweep():
    sweep = BeamSweep.azimuth_grid(*np.deg2rad([-45.0, 45.0, 1.5]))
    assert sweep.num_beams == 61
    np.testing.assert_allclose(np.diff(sweep.azimuth), np.deg2rad(1.5), atol=1e-15)
    np.testing.assert_allclose(sweep.azimuth[[0, -1]], np.deg2rad([-45.0, 45.0]), atol=1e-15)
    np.testing.assert_array_equal(sweep.elevation, 0.0)
    assert sweep.index_of(np.deg2rad([21.0, 0.0])) == 44
    assert sweep.index_of(np.deg2rad([21.7, 0.0])) is None

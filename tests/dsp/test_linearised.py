"""The closed-form Jacobians of a RIS fix and a tracking measurement (RisFix.linearised,
RisMeasurement.linearised). Oracle: fourth-order central differences of the residuals, written here."""

from __future__ import annotations

import numpy as np
import pytest

from dsp import RisPose
from dsp.fusion import RisFix
from dsp.tracking import RisMeasurement


def _differences(fun, x, step=1e-4):
    """∂fun/∂x by the fourth-order central difference (error ~ step⁴ · f⁽⁵⁾)."""
    x = np.asarray(x, float)
    cols = []
    for i in range(x.size):
        e = np.zeros(x.size)
        e[i] = step
        cols.append((8 * (fun(x + e) - fun(x - e)) - (fun(x + 2 * e) - fun(x - 2 * e))) / (12 * step))
    return np.column_stack(cols)


def _assert_rows_close(jac, reference):
    """Each row (one measurement, in its σ per metre or per m/s) within 1e-7 of that row's largest entry: the
    differences' own error is ~1e-12 of a row at 0.3–20 m."""
    for row, ref in zip(jac, reference):
        np.testing.assert_allclose(row, ref, rtol=0, atol=1e-7 * float(np.max(np.abs(ref))))


def _random_fix(rng, sees_elevation):
    p = rng.uniform(-5, 5, 3)
    pose = RisPose.facing(p, p + rng.standard_normal(3), yaw=rng.uniform(-0.5, 0.5))
    std_aod = [rng.uniform(1e-4, 1e-2), rng.uniform(1e-4, 1e-2) if sees_elevation else np.nan]
    return RisFix(name="ris", pose=pose, distance=rng.uniform(1, 20), std_distance=rng.uniform(1e-4, 1e-2),
                  aod=rng.uniform(-1, 1, 2), std_aod=np.array(std_aod))


@pytest.mark.parametrize("sees_elevation", [True, False])
def test_a_fixs_jacobian_is_the_derivative_of_its_residuals(sees_elevation):
    rng = np.random.default_rng(7)
    for _ in range(200):
        fix = _random_fix(rng, sees_elevation)
        # 0.3–20 m from the RIS, away from its column axis (where the azimuth turns fast)
        x = fix.pose.point_at(np.array([rng.uniform(-3, 3), rng.uniform(-1.3, 1.3)]), rng.uniform(0.3, 20))
        r, jac = fix.linearised(x)
        np.testing.assert_array_equal(r, fix.residuals(x))
        assert jac.shape == (2 + sees_elevation, 3)
        _assert_rows_close(jac, _differences(fix.residuals, x))


def test_on_the_column_axis_and_at_the_ris_it_falls_back_to_differences():
    fix = _random_fix(np.random.default_rng(3), True)
    up = fix.pose.position + 2.0 * fix.pose.column_axis  # azimuth undefined there
    r, jac = fix.linearised(up)
    assert np.isfinite(jac).all() and jac.shape == (3, 3)
    np.testing.assert_array_equal(r, fix.residuals(up))
    r, jac = fix.linearised(fix.pose.position)
    assert np.isfinite(jac).all() and r[0] == fix.distance / fix.std_distance


def test_a_measurements_jacobian_covers_position_and_velocity():
    rng = np.random.default_rng(8)
    for k in range(100):
        fix = _random_fix(rng, k % 2 == 0)
        m = RisMeasurement(time=0.0, fix=fix, velocity=rng.uniform(-2, 2), std_velocity=rng.uniform(1e-4, 1e-2))
        s = np.concatenate([fix.pose.point_at(np.array([rng.uniform(-1, 1), rng.uniform(-1, 1)]),
                                              rng.uniform(0.5, 15)), rng.uniform(-2, 2, 3)])
        r, jac = m.linearised(s)
        np.testing.assert_array_equal(r, m.normalised_residuals(s))
        assert jac.shape == (fix.measurements + 1, 6)
        np.testing.assert_array_equal(jac[:-1, 3:], 0.0)  # the fix does not see the velocity
        _assert_rows_close(jac, _differences(m.normalised_residuals, s))

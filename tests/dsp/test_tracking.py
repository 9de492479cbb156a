"""The RIS tracker (dsp.tracking): a walk past two RISs, its stated covariance checked by NEES and NIS."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.stats

from dsp import RisPose
from dsp.fusion import RisFix
from dsp.tracking import RisMeasurement, TrackState, predict, start_track, update

Q = 0.05  # white acceleration density [m²/s³] of both the truth and the filter
SD, SAZ, SEL, SV = 3e-3, np.deg2rad(0.3), np.deg2rad(0.6), 0.01
POSES = {"ris-a": RisPose.facing(np.array([0.0, 4.0, 2.5]), np.array([6.0, 4.0, 1.2])),
         "ris-b": RisPose.facing(np.array([12.0, 0.0, 0.8]), np.array([6.0, 4.0, 1.2]))}
STEP = 0.61  # one RIS's sweep every 0.61 s, the two RISs taking turns (time division)


def _truth_walk(rng, steps=16, q=None):
    """A walk from (3, 2, 1.2) at ~1 m/s drawn from the filter's own process model (so NEES is χ²(6))."""
    q = Q if q is None else q
    s = np.array([3.0, 2.0, 1.2, 0.8, 0.5, 0.0])
    f = np.eye(6)
    f[:3, 3:] = np.eye(3) * STEP
    qm = np.block([[np.eye(3) * STEP**3 / 3, np.eye(3) * STEP**2 / 2], [np.eye(3) * STEP**2 / 2, np.eye(3) * STEP]])
    out = [s]
    for _ in range(steps - 1):
        s = f @ s + rng.multivariate_normal(np.zeros(6), q * qm)
        out.append(s)
    return np.array(out)


def _measure(name, t, s, rng, *, sees_el=True, offset=(0.0, 0.0, 0.0, 0.0)):
    pose = POSES[name]
    rel = s[:3] - pose.position
    d = float(np.linalg.norm(rel))
    az, el = pose.angles_to(s[:3])
    v_r = float(s[3:] @ rel) / d
    z = np.array([d, az, el, v_r]) + rng.standard_normal(4) * np.array([SD, SAZ, SEL, SV]) + np.asarray(offset)
    fix = RisFix(name=name, pose=pose, distance=z[0], std_distance=SD, aod=z[1:3],
                 std_aod=np.array([SAZ, SEL if sees_el else np.nan]))
    return RisMeasurement(time=t, fix=fix, velocity=z[3], std_velocity=SV)


def _run(rng, *, sees_el=True, steps=16, q=None):
    q = Q if q is None else q
    truth = _truth_walk(rng, steps, q)
    names = ["ris-a", "ris-b"]
    meas = [_measure(names[k % 2], k * STEP, truth[k], rng, sees_el=sees_el) for k in range(steps)]
    state = start_track(meas[0], speed_std=1.5)
    updates = []
    for m in meas[1:]:
        u = update(state, m, accel_density=q, gate_pfa=1e-6)
        updates.append(u)
        state = u.state
    return truth, meas, state, updates


def test_the_track_is_consistent_nees_and_nis_within_their_bands():
    """200 walks: NEES at the last update χ²(6), NIS χ²(4) per update; means within 99.9 % bands."""
    rng = np.random.default_rng(1)
    nees, nis, dofs = [], [], []
    for _ in range(200):
        truth, _, state, updates = _run(rng)
        e = state.mean - truth[-1]
        nees.append(float(e @ np.linalg.solve(state.covariance, e)))
        nis += [u.nis for u in updates[3:]]  # after the start's broad velocity prior has settled
        dofs += [u.dof for u in updates[3:]]
        assert all(u.accepted for u in updates)
    n = len(nees)
    lo, hi = scipy.stats.chi2.ppf([5e-4, 1 - 5e-4], 6 * n) / n
    assert lo <= np.mean(nees) <= hi, np.mean(nees)
    k = sum(dofs)
    lo, hi = scipy.stats.chi2.ppf([5e-4, 1 - 5e-4], k)
    assert lo <= sum(nis) <= hi, (sum(nis), k)


def test_the_track_beats_the_single_sweep_fixes():
    """A steady walk (q = 0.005 m²/s³: the velocity wanders 5 cm/s per sweep): position RMSE of the track over
    the walk's second half below the median single-sweep fix error (the issue's goal for a tracked walk)."""
    rng = np.random.default_rng(2)
    track_err, fix_err = [], []
    for _ in range(40):
        truth, meas, _, updates = _run(rng, q=0.005)
        for k, u in enumerate(updates[7:], start=8):
            track_err.append(np.linalg.norm(u.state.mean[:3] - truth[k][:3]))
            fix_err.append(np.linalg.norm(meas[k].fix.position() - truth[k][:3]))
    assert np.sqrt(np.mean(np.square(track_err))) < np.median(fix_err)


def test_one_height_without_elevation_keeps_the_height_uncertain_and_says_so_in_the_covariance():
    """Both RISs at 1.2 m, 1-D sweeps: the height is not seen; its 1σ stays near the start's broad prior."""
    rng = np.random.default_rng(3)
    global POSES
    saved = POSES
    POSES = {"ris-a": RisPose.facing(np.array([0.0, 4.0, 1.2]), np.array([6.0, 4.0, 1.2])),
             "ris-b": RisPose.facing(np.array([12.0, 0.0, 1.2]), np.array([6.0, 4.0, 1.2]))}
    try:
        _, _, state, _ = _run(rng, sees_el=False)
    finally:
        POSES = saved
    sd = state.position_std
    assert sd[2] > 100 * max(sd[0], sd[1])


def test_coasting_grows_the_covariance_and_the_track_is_kept():
    rng = np.random.default_rng(4)
    truth, meas, _, _ = _run(rng, steps=6)
    state = start_track(meas[0], speed_std=1.5)
    for m in meas[1:4]:
        state = update(state, m, accel_density=Q).state
    traces = [np.trace(predict(state, state.time + dt, accel_density=Q).covariance[:3, :3]) for dt in (0.5, 1.0, 2.0)]
    assert traces[0] < traces[1] < traces[2]
    later = update(state, meas[5], accel_density=Q)  # two sweeps missed, then a detection
    assert later.accepted and later.nis <= later.gate


def test_an_outlier_is_rejected_at_the_gate_and_changes_nothing():
    rng = np.random.default_rng(5)
    truth, meas, _, _ = _run(rng, steps=8)
    state = start_track(meas[0], speed_std=1.5)
    for m in meas[1:6]:
        state = update(state, m, accel_density=Q).state
    twin = _measure("ris-a", 6 * STEP, truth[6], rng, offset=(0.0, np.deg2rad(25.0), 0.0, 0.0))
    u = update(state, twin, accel_density=Q, gate_pfa=1e-3)
    assert not u.accepted and u.nis > u.gate and u.ris == "ris-a"
    np.testing.assert_array_equal(u.state.mean, predict(state, 6 * STEP, accel_density=Q).mean)


def test_bad_input_is_one_line():
    rng = np.random.default_rng(6)
    _, meas, _, _ = _run(rng, steps=3)
    state = start_track(meas[1])
    with pytest.raises(ValueError, match="before the track's"):
        update(state, meas[0], accel_density=Q)
    with pytest.raises(ValueError, match="velocity and its 1σ together"):
        RisMeasurement(time=0.0, fix=meas[0].fix, velocity=0.3)
    with pytest.raises(ValueError, match="accel_density"):
        predict(state, state.time + 1, accel_density=0.0)
    with pytest.raises(ValueError, match=r"gate_pfa=.* must lie in \(0, 1\)"):
        update(state, meas[2], accel_density=Q, gate_pfa=0.0)
    assert isinstance(state, TrackState)


def test_a_known_height_holds_z_and_the_horizontal_track_is_consistent():
    """Both RISs at 1.2 m, 1-D sweeps, the radar walking at a known 1.2 m (height=(1.2, 0.01)): z stays
    within 3σ_h of 1.2 m with a 1σ near σ_h, and the NEES of (x, y, vx, vy) at the last update over 60
    walks is χ²(4): its mean within the 99.9 % band; the height pseudo-measurement counts in the dof."""
    from dsp.tracking import HORIZONTAL, nees

    rng = np.random.default_rng(7)
    global POSES
    saved = POSES
    POSES = {"ris-a": RisPose.facing(np.array([0.0, 4.0, 1.2]), np.array([6.0, 4.0, 1.2])),
             "ris-b": RisPose.facing(np.array([12.0, 0.0, 1.2]), np.array([6.0, 4.0, 1.2]))}
    q = 0.05
    values = []
    try:
        for _ in range(60):
            s = np.array([3.0, 2.0, 1.2, 0.8, 0.5, 0.0])
            f = np.eye(6)
            f[:3, 3:] = np.eye(3) * STEP
            qm = np.block([[np.eye(3) * STEP**3 / 3, np.eye(3) * STEP**2 / 2], [np.eye(3) * STEP**2 / 2, np.eye(3) * STEP]])
            qm[2, :] = qm[:, 2] = qm[5, :] = qm[:, 5] = 0.0  # the height does not wander
            truth = [s]
            for _ in range(11):
                truth.append(f @ truth[-1] + rng.multivariate_normal(np.zeros(6), q * qm))
            meas = [_measure(["ris-a", "ris-b"][k % 2], k * STEP, truth[k], rng, sees_el=False) for k in range(12)]
            state = start_track(meas[0], speed_std=1.5, height=(1.2, 0.01))
            assert state.mean[2] == 1.2 and state.position_std[2] == pytest.approx(0.01)
            for m in meas[1:]:
                u = update(state, m, accel_density=q, gate_pfa=1e-6, height=(1.2, 0.01))
                assert u.accepted and u.dof == 4  # distance, azimuth, radial velocity, height
                state = u.state
            assert abs(state.mean[2] - 1.2) < 0.03 and state.position_std[2] < 0.012
            values.append(nees(state, truth[-1], axes=HORIZONTAL))
    finally:
        POSES = saved
    n = len(values)
    lo, hi = scipy.stats.chi2.ppf([5e-4, 1 - 5e-4], 4 * n) / n
    assert lo <= np.mean(values) <= hi, np.mean(values)
    with pytest.raises(ValueError, match="height"):
        update(state, meas[-1], accel_density=q, height=(1.2,))


def test_the_nees_band_holds_its_share_of_means():
    """dsp.tracking.nees_band(dof, n): the mean of n χ²(dof) values falls inside it 95 % of the time
    (4000 draws of means of 10 χ²(4): a binomial 99.9 % interval around 95 %)."""
    from dsp.tracking import nees_band

    rng = np.random.default_rng(7)
    means = rng.chisquare(4, size=(4000, 10)).mean(axis=1)
    lo, hi = nees_band(4, 10)
    share = np.mean((means >= lo) & (means <= hi))
    k_lo, k_hi = scipy.stats.binom.ppf([5e-4, 1 - 5e-4], 4000, 0.95) / 4000
    assert k_lo <= share <= k_hi
    assert np.mean(means < lo) == pytest.approx(0.025, abs=0.01)  # two-sided: 2.5 % on each side

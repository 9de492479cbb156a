"""A tracked walk (risloc_rt.studies.walk): the path, the slots, and a short walk through the traced L-shaped hall."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.stats

from dsp import BeamSweep
from risloc_rt.hall.raytrace.tracer import TraceSettings
from risloc_rt.studies.trajectory import Trajectory, TrajectoryError, read_trajectory
from risloc_rt.studies.walk import COLUMNS, plan_walk, run_walk, write_walk

CHEAP = TraceSettings(max_depth=1, samples_per_src=10_000)


def test_the_path_is_walked_at_constant_velocity_between_waypoints(tmp_path):
    path = tmp_path / "w.csv"
    path.write_text("# a walk\nt, x, y, z\n\n0,14,6,1.2\n9,5,6,1.2\n23,5,20,1.2\n")
    tr = read_trajectory(path)
    assert tr.lines.tolist() == [4, 5, 6] and tr.duration == 23 and tr.length == pytest.approx(23.0, abs=1e-12)
    np.testing.assert_allclose(tr.position(4.5), [9.5, 6, 1.2], atol=1e-12)
    np.testing.assert_allclose(tr.velocity(4.5), [-1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(tr.velocity(9.0), [0, 1, 0], atol=1e-12)  # at a waypoint: the next segment
    np.testing.assert_allclose(tr.position(16.0), [5, 13, 1.2], atol=1e-12)


def test_the_slots_follow_the_schedule_and_the_geometry_says_who_sees_the_radar():
    """Back to back ris0, ris1 (61 beams x 6.4 ms = 0.3904 s each); the radar near the long arm's
    east end is seen by ris0 (24° off its broadside) and by ris1 through the short arm's mouth
    (31°); at [11, 20] (the short arm, east) ris0's line of sight passes beside the inner corner but
    the radar is 49.5° off its broadside, outside its ±45° sweep."""
    tr = Trajectory(times=[0.0, 2.0], points=[[14, 6, 1.2], [12, 6, 1.2]])
    slots = plan_walk("l_hall_2ris", tr)
    assert [s.ris for s in slots] == ["ris0", "ris1", "ris0", "ris1", "ris0"]  # the 6th would end at 2.34 s
    sweep = 61 * 6.4e-3
    for s in slots:
        assert s.start == pytest.approx(s.index * sweep, abs=1e-12)
        assert s.time - s.start == pytest.approx(0.5 * sweep - 0.5 * 6.4e-3 + 0.5 * (6.4e-3), abs=4e-3)
        np.testing.assert_allclose(s.position, [14 - s.time, 6, 1.2], atol=1e-12)
        assert s.facing and s.in_view
    far = plan_walk("l_hall_2ris", Trajectory(times=[0.0, 0.5], points=[[11, 20, 1.2], [11, 19.5, 1.2]]))
    assert far[0].ris == "ris0" and far[0].facing and not far[0].in_view


#: A cheap sweep for the walks here: ±45° in 3° steps, 31 beams (0.198 s a sweep; the hall's has 61).
COARSE = BeamSweep.azimuth_grid(*np.deg2rad([-45.0, 45.0, 3.0]))


@pytest.fixture(scope="module")
def quiet_walk():
    """1 s west along the long arm from [14, 6, 1.2] at 1 m/s, 5 sweeps of 31 beams, at -10 dBm: ris0
    (4.4 m away, ~21 dB post-integration SNR) is detected every time, ris1 (17.6 m, ~-1 dB) never:
    its slots coast."""
    tr = Trajectory(times=[0.0, 1.0], points=[[14, 6, 1.2], [13, 6, 1.2]])
    return tr, run_walk("l_hall_2ris", tr, seed=3, tx_power_dbm=-10.0, trace=CHEAP, sweep=COARSE)


@pytest.mark.slow
def test_same_seed_same_rows(quiet_walk):
    """Slot k's noise is default_rng([seed, k]): the first three sweeps again, measured on two worker
    processes ahead of the tracker, give the same rows, bit for bit (but for the smoothed track's columns:
    the smoother uses the sweeps after each, which the shorter walk does not have)."""
    tr, first = quiet_walk
    again = run_walk("l_hall_2ris", tr, seed=3, tx_power_dbm=-10.0, trace=CHEAP, sweep=COARSE, max_sweeps=3,
                     workers=2)
    assert len(first.rows) == 5 and len(again.rows) == 3
    for a, b in zip(first.rows, again.rows):
        for key in COLUMNS:
            if key.startswith(("seconds_", "smooth")) or key == "elapsed":
                continue
            assert (a[key] == b[key]) or (isinstance(a[key], float) and math.isnan(a[key]) and math.isnan(b[key])), key


@pytest.mark.slow
def test_it_coasts_through_the_undetected_ris_and_its_sigma_says_how_far(quiet_walk):
    _, walk = quiet_walk
    rows = walk.rows
    assert [r["status"] for r in rows] == ["fix", "no-detection", "fix", "no-detection", "fix"]
    assert [r["update"] for r in rows] == ["start", "coast", "used", "coast", "used"]
    for before, coast, after in zip(rows[0::2], rows[1::2], rows[2::2]):
        # coasting widens the track (prediction only) and the next fix narrows it again
        assert coast["track_sigma"] > before["track_sigma"] and after["track_sigma"] < coast["track_sigma"]
        assert math.isnan(coast["nis"]) and coast["nis_dof"] == 0 and math.isnan(coast["fix_error"])
    # each row's track error within its stated covariance: NEES (x, y, vx, vy) within the 99.9 % band of χ²(4)
    hi = scipy.stats.chi2.ppf(0.9995, 4)  # the upper edge of χ²(4)'s two-sided 99.9 % band
    for r in rows:
        assert r["nees_dof"] == 4 and r["nees"] <= hi, r


@pytest.mark.slow
def test_the_track_error_is_within_its_covariance_and_the_outputs_are_written(quiet_walk, tmp_path):
    """The track's stated covariance does not understate its error: the mean NEES of the walk's rows
    below the 99 % upper end of a mean of χ²(4) (the floors of MOVING_FLOORS make it conservative on
    a clean straight walk: NEES below the band's lower end is expected here); the fixes within 2 cm
    of the truth at the sweep's middle, the track after three fixes within 2 cm too."""
    _, walk = quiet_walk
    s = walk.summary
    nees = np.array([r["nees"] for r in walk.rows])
    hi = scipy.stats.chi2.ppf(0.995, 4 * len(nees)) / len(nees)  # the mean of n χ²(4): χ²(4n)/n, 99 % band
    assert np.mean(nees) <= hi, nees
    assert s["fixes_in_view"] == 3 and s["sweeps_in_view"] == 5 and s["fix_share_in_view"] == pytest.approx(3 / 5)
    assert s["fix_rmse_m"] < 0.02 and walk.rows[-1]["track_error"] < 0.02
    files = write_walk(walk, tmp_path)
    assert sorted(p.name for p in files) == sorted(["walk.parquet", "summary.json", "plan.png", "error.png",
                                                    "consistency.png"])
    import pyarrow.parquet as pq

    table = pq.read_table(tmp_path / "walk.parquet")
    assert table.num_rows == 5 and table.column_names == list(COLUMNS)
    assert table.column("ris").to_pylist() == ["ris0", "ris1"] * 2 + ["ris0"]


@pytest.mark.slow
def test_the_smoothed_track_knows_more_than_the_causal_one_and_says_so(quiet_walk):
    """The smoothed track (dsp.smoothing) joins the forward track with a backward one over the later sweeps:
    where it is their product its covariance is no larger than the causal track's (information only adds,
    the coasted sweeps most of all, having a fix on each side), its error within its covariance (NEES of
    (x, y, vx, vy) within χ²(4)'s 99.9 % band), and the summary reports it."""
    _, walk = quiet_walk
    hi = scipy.stats.chi2.ppf(0.9995, 4)
    kinds = [r["smooth"] for r in walk.rows]
    assert kinds == ["joined"] * 4 + ["forward"]  # the last sweep has nothing after it
    for r in walk.rows:
        assert r["smooth_sigma"] <= r["track_sigma"] * (1 + 1e-9) and r["smooth_nees"] <= hi, r
    coasted = [r for r in walk.rows if r["update"] == "coast"]
    assert all(r["smooth_sigma"] < 0.9 * r["track_sigma"] for r in coasted), [(r["smooth_sigma"], r["track_sigma"])
                                                                              for r in coasted]
    sm = walk.summary["smoothed"]
    assert sm["kinds"]["joined"] == 4 and sm["turns"] == []
    assert sm["rmse_m"] == pytest.approx(math.sqrt(np.mean([r["smooth_error"] ** 2 for r in walk.rows])))


def test_a_trajectory_is_refused_before_anything_is_traced():
    with pytest.raises(TrajectoryError, match="waypoint 1: t = 0 s repeats"):
        Trajectory(times=[0.0, 0.0], points=[[14, 6, 1.2], [12, 6, 1.2]])
    with pytest.raises(TrajectoryError, match=r"passes through 'wall_2' at \[15.714, 12.000, 1.200\]"):
        plan_walk("l_hall_2ris", Trajectory(times=[0.0, 10.0], points=[[20, 6, 1.2], [10, 20, 1.2]]))


def test_a_detection_without_a_positive_distance_is_no_position_not_a_crash(monkeypatch):
    """Regression: a detection whose distance at the sweep's middle is not > 0 (a return earlier than the
    RIS's own loop-back, ``before-ris-delay``) stopped the walk with a traceback (``RisFix`` refuses a
    distance <= 0). It is now a ``no-position`` row, and the tracker predicts through it."""
    import risloc_rt.studies.walk as walk_module

    real = walk_module._measured
    calls = []

    def second_is_invalid(job):
        calls.append(job.slot.index)
        return (walk_module.NO_POSITION, math.nan, {"seconds_trace": 0.0, "seconds_simulate": 0.0,
                                                    "seconds_dsp": 0.0}) if job.slot.index == 2 else real(job)

    monkeypatch.setattr(walk_module, "_measured", second_is_invalid)
    tr = Trajectory(times=[0.0, 1.0], points=[[14, 6, 1.2], [13, 6, 1.2]])
    walk = run_walk("l_hall_2ris", tr, seed=3, tx_power_dbm=-10.0, trace=CHEAP, sweep=COARSE)
    row = walk.rows[2]
    assert 2 in calls and row["status"] == "no-position" and row["update"] == "coast" and math.isnan(row["fix_x"])
    assert walk.summary["no_position"] == 1 and walk.rows[4]["update"] == "used"


@pytest.mark.parametrize("kwargs, match", [
    (dict(accel_density=0.5, manoeuvres="default"), "not both"),
    (dict(accel_density=0.0), r"accel_density=0.0 must be > 0"),
    (dict(accel_density=float("inf")), "accel_density=inf must be > 0"),
    (dict(manoeuvres=(1e-4, 2.6, 8.4, 0.39)), "must be a dsp.tracking.Manoeuvres"),
    (dict(gate_pfa=1.0), r"gate_pfa=1.0 must lie in \(0, 1\)"),
    (dict(restart_after=0), "restart_after=0 must be an integer >= 1"),
    (dict(restart_after=2.5), "restart_after=2.5 must be an integer >= 1"),
])
def test_the_walk_tracker_refuses_bad_settings_in_one_line(kwargs, match):
    from risloc_rt.studies.walk import WALK_MANOEUVRES, WalkTracker

    if kwargs.get("manoeuvres") == "default":
        kwargs["manoeuvres"] = WALK_MANOEUVRES
    with pytest.raises(ValueError, match=match) as err:
        WalkTracker(**kwargs)
    assert "\n" not in str(err.value)


def test_the_walk_tracker_starts_flags_coasts_and_updates_with_two_models_or_one():
    """No track before the first usable fix; a flagged fix before it starts nothing; then start, coast, a
    flagged fix predicted through, an update: the state is the two-model mixture by default, one model's
    state with accel_density; summary's description names the filter."""
    from dsp import RisPose
    from dsp.fusion import RisFix
    from dsp.tracking import ImmState, RisMeasurement, TrackState
    from risloc_rt.studies.walk import SKIP_FLAGS, WalkTracker

    pose = RisPose.facing(np.array([0.0, 5.0, 1.2]), np.array([6.0, 5.0, 1.2]))

    def meas(t, flags=()):
        x = np.array([2.0 + t, 5.0, 1.2])  # 1 m/s along x, straight at the RIS's broadside
        return RisMeasurement(time=t, fix=RisFix(name="a", pose=pose, distance=float(np.linalg.norm(x - pose.position)),
                                                 std_distance=1e-3, aod=np.array([0.0, 0.0]),
                                                 std_aod=np.array([np.deg2rad(0.05), np.nan]), flags=tuple(flags)),
                              velocity=1.0, std_velocity=1e-3)

    for kwargs, kind in (({}, ImmState), ({"accel_density": 0.5}, TrackState)):
        tracker = WalkTracker(**kwargs)
        steps = [tracker.step(0.0, meas(0.0, flags=SKIP_FLAGS[:1]), height=(1.2, 0.01)),
                 tracker.step(0.4, meas(0.4), height=(1.2, 0.01)), tracker.step(0.8, None),
                 tracker.step(1.2, meas(1.2, flags=SKIP_FLAGS[:1])), tracker.step(1.6, meas(1.6), height=(1.2, 0.01))]
        assert [s[0] for s in steps] == ["none", "start", "coast", "flagged", "used"]
        assert isinstance(tracker.state, kind) and tracker.state.time == 1.6
        assert steps[-1][2] == 4 and np.isfinite(steps[-1][1]) and all(np.isnan(s[1]) for s in steps[:4])
        assert abs(tracker.state.mean[0] - 3.6) < 0.01
    assert WalkTracker().describe()["models"].startswith("IMM")
    assert WalkTracker(accel_density=0.5).describe() == {"models": "nearly constant velocity", "accel_density_m2_s3": 0.5}

"""The two-model tracker (dsp.tracking.Manoeuvres, imm_*): a walk that goes straight and turns at once, its
stated covariance checked by NEES against a known truth over Monte Carlo runs."""

from __future__ import annotations

import numpy as np
import pytest

from dsp import RisPose
from dsp.fusion import RisFix
from dsp.tracking import (HORIZONTAL, ImmState, Manoeuvres, RisMeasurement, imm_predict, imm_start, imm_update, nees,
                          nees_band, start_track, update)

#: Two RISs at the walker's height (1-D sweeps: no elevation), the height known, as on the benchmark walk.
POSES = {"ris-a": RisPose.facing(np.array([0.0, 5.0, 1.2]), np.array([6.0, 5.0, 1.2])),
         "ris-b": RisPose.facing(np.array([6.0, 14.0, 1.2]), np.array([6.0, 5.0, 1.2]))}
SD, SAZ, SV = 1e-3, np.deg2rad(0.02), 1e-3  # 1σ of distance [m], azimuth [rad], radial velocity [m/s]
STEP = 0.3904  # one slot [s], the RISs taking turns
HEIGHT = (1.2, 0.01)
MODELS = Manoeuvres(quiet=1e-4, turning=1.0 / STEP, quiet_time=8.0, turning_time=STEP)


def _turning_walk(rng, steps=40, turn_slots=None):
    """A walker at 1 m/s from near (6, 5) whose heading turns by ±90° at once within two slots (random ones,
    or ``turn_slots``), at a random moment of the slot: the truth [steps, 6] at the slots' times (a path of
    straight legs, no noise)."""
    heading = rng.uniform(0, 2 * np.pi)
    slots = np.arange(8, steps - 4)
    if turn_slots is None:
        turn_slots = rng.choice(slots, 2, replace=False) if slots.size >= 2 else ()
    turns = {int(k): float(rng.choice([-1.0, 1.0])) * np.pi / 2 for k in turn_slots}
    p = np.array([6.0, 5.0, 1.2]) + rng.uniform(-0.5, 0.5, 3) * [1, 1, 0]
    out = []
    for k in range(steps):
        t_turn = rng.uniform(0, STEP) if k in turns else None
        v = np.array([np.cos(heading), np.sin(heading), 0.0])
        if t_turn is not None:  # walk t_turn on the old heading, the rest on the new one
            heading += turns[k]
            w = np.array([np.cos(heading), np.sin(heading), 0.0])
            p = p + v * t_turn + w * (STEP - t_turn)
            v = w
        elif k:
            p = p + v * STEP
        out.append(np.concatenate([p, v]))
    return np.array(out)


def _measure(name, t, s, rng):
    pose = POSES[name]
    rel = s[:3] - pose.position
    d = float(np.linalg.norm(rel))
    az = pose.angles_to(s[:3])[0]
    z = np.array([d, az, float(s[3:] @ rel) / d]) + rng.standard_normal(3) * np.array([SD, SAZ, SV])
    fix = RisFix(name=name, pose=pose, distance=z[0], std_distance=SD, aod=np.array([z[1], 0.0]),
                 std_aod=np.array([SAZ, np.nan]))
    return RisMeasurement(time=t, fix=fix, velocity=z[2], std_velocity=SV)


def _nees_over_runs(rng, runs, *, single_q=None):
    """NEES over (x, y, vx, vy) at every slot after the first five of ``runs`` walks, and the gated count."""
    values, gated = [], 0
    for _ in range(runs):
        truth = _turning_walk(rng)
        meas = [_measure(("ris-a", "ris-b")[k % 2], k * STEP, s, rng) for k, s in enumerate(truth)]
        state = start_track(meas[0], height=HEIGHT) if single_q else imm_start(meas[0], height=HEIGHT)
        for k, m in enumerate(meas[1:], start=1):
            u = (update(state, m, accel_density=single_q, height=HEIGHT) if single_q
                 else imm_update(state, m, MODELS, height=HEIGHT))
            gated += not u.accepted
            state = u.state
            if k >= 5:
                values.append(nees(state, truth[k], axes=HORIZONTAL))
    return np.array(values), gated


def test_the_two_model_track_of_a_turning_walk_does_not_understate_its_error_and_the_quiet_model_alone_does():
    """40 walks of straight legs with two instant 90° turns each, measurements with known Gaussian σ: the
    two-model filter's NEES over the horizontal position and velocity, averaged over every slot after the
    fifth, is not above the 95 % band of a mean of χ²(4) values (the band of 40 independent means, one per
    walk: the rows of one walk are correlated) — its stated covariance does not understate the error, at
    the turns included — and no measurement is gated. It is conservative, not honest to the band: the
    moment-matched mixture carries the turning model's share (2.7 for 4 here, 2.6 on the straight legs),
    and this checks it stays within a factor 2 of χ²(4)'s mean. The quiet model alone (q = 1e-4 m²/s³),
    which cannot follow a turn, is more than ten times above the band."""
    rng = np.random.default_rng(11)
    values, gated = _nees_over_runs(rng, 40)
    per_walk = values.reshape(40, -1).mean(axis=1)
    lo, hi = nees_band(4, 40)  # the mean of 40 walk means, each ~ the mean of a correlated χ²(4) series
    assert gated == 0
    assert 4 / 2 <= per_walk.mean() <= hi, (per_walk.mean(), lo, hi)
    quiet, _ = _nees_over_runs(np.random.default_rng(11), 10, single_q=MODELS.quiet)
    assert quiet.mean() > 10 * hi, quiet.mean()


def test_the_turning_model_takes_over_at_a_turn_and_hands_back_after_it():
    """On one walk: the turning model's weight is below 0.5 on a straight leg, above it at the slot after a turn."""
    rng = np.random.default_rng(12)
    truth = _turning_walk(rng, turn_slots=(12, 28))
    meas = [_measure(("ris-a", "ris-b")[k % 2], k * STEP, s, rng) for k, s in enumerate(truth)]
    speeds = truth[:, 3:5]
    turned = [k for k in range(1, len(truth)) if not np.allclose(speeds[k], speeds[k - 1])]
    state = imm_start(meas[0], height=HEIGHT)
    weights = [0.5]
    for m in meas[1:]:
        state = imm_update(state, m, MODELS, height=HEIGHT).state
        weights.append(float(state.weights[1]))
    k = turned[0]
    assert turned == [12, 28]
    assert weights[k - 1] < 0.5 and max(weights[k:k + 2]) > 0.5
    assert weights[k + 6] < 0.5


def test_coasting_keeps_both_models_and_widens_the_mixture():
    rng = np.random.default_rng(13)
    truth = _turning_walk(rng, steps=8)
    meas = [_measure(("ris-a", "ris-b")[k % 2], k * STEP, s, rng) for k, s in enumerate(truth)]
    state = imm_start(meas[0], height=HEIGHT)
    for m in meas[1:6]:
        state = imm_update(state, m, MODELS, height=HEIGHT).state
    later = [imm_predict(state, state.time + dt, MODELS) for dt in (0.4, 0.8, 1.6)]
    traces = [np.trace(s.covariance[:2, :2]) for s in later]
    assert isinstance(later[0], ImmState) and traces[0] < traces[1] < traces[2]
    assert abs(later[-1].weights.sum() - 1.0) < 1e-12
    # while coasting, the turning model's weight drifts towards its stationary share τ₁ / (τ₀ + τ₁)
    share = MODELS.turning_time / (MODELS.quiet_time + MODELS.turning_time)
    assert abs(later[2].weights[1] - share) < abs(later[0].weights[1] - share)


def test_an_outlier_beyond_every_gate_is_rejected_and_changes_nothing():
    rng = np.random.default_rng(14)
    truth = _turning_walk(rng, steps=10)
    meas = [_measure(("ris-a", "ris-b")[k % 2], k * STEP, s, rng) for k, s in enumerate(truth)]
    state = imm_start(meas[0], height=HEIGHT)
    for m in meas[1:8]:
        state = imm_update(state, m, MODELS, height=HEIGHT).state
    good = meas[8]
    twin = RisMeasurement(time=good.time, fix=RisFix(name=good.fix.name, pose=good.fix.pose,
                                                     distance=good.fix.distance + 2.0, std_distance=SD,
                                                     aod=good.fix.aod, std_aod=good.fix.std_aod),
                          velocity=good.velocity, std_velocity=SV)
    u = imm_update(state, twin, MODELS, height=HEIGHT)
    assert not u.accepted and u.nis > u.gate
    np.testing.assert_array_equal(u.state.mean, imm_predict(state, good.time, MODELS).mean)


@pytest.mark.parametrize("kwargs, match", [
    (dict(quiet=0.0, turning=1.0, quiet_time=8.0, turning_time=0.4), "quiet"),
    (dict(quiet=1e-4, turning=float("nan"), quiet_time=8.0, turning_time=0.4), "turning"),
    (dict(quiet=1.0, turning=0.5, quiet_time=8.0, turning_time=0.4), "must exceed quiet"),
    (dict(quiet=1e-4, turning=1.0, quiet_time=-1.0, turning_time=0.4), "quiet_time"),
    (dict(quiet=1e-4, turning=1.0, quiet_time=8.0, turning_time=0.0), "turning_time"),
])
def test_bad_models_are_one_line(kwargs, match):
    with pytest.raises(ValueError, match=match) as err:
        Manoeuvres(**kwargs)
    assert "\n" not in str(err.value)


def test_bad_starts_and_times_are_one_line():
    rng = np.random.default_rng(15)
    truth = _turning_walk(rng, steps=3)
    meas = [_measure("ris-a", k * STEP, s, rng) for k, s in enumerate(truth)]
    with pytest.raises(ValueError, match=r"turning_share=1.0 must lie in \(0, 1\)"):
        imm_start(meas[0], turning_share=1.0)
    state = imm_start(meas[1])
    with pytest.raises(ValueError, match="before the track's"):
        imm_update(state, meas[0], MODELS)
    with pytest.raises(ValueError, match="gate_pfa"):
        imm_update(state, meas[2], MODELS, gate_pfa=1.5)

"""The smoothed track (dsp.smoothing): forward and backward filters joined, an unseen turn placed where the legs
meet. Oracles: the truth of synthetic walks (straight legs, turns at known times) measured with known Gaussian
errors, and the closed-form product of two Gaussians."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dsp import RisPose
from dsp.fusion import RisFix
from dsp.smoothing import (SMOOTH_KINDS, fuse_estimates, reversed_measurement, reversed_state, smooth_track,
                           turn_time)
from dsp.tracking import (HORIZONTAL, Manoeuvres, RisMeasurement, TrackState, imm_predict, imm_start, imm_update,
                          nees, nees_band, predict, start_track, update)

#: Two RISs at the walker's height (1-D sweeps), the height known: the benchmark walk's setting.
POSES = (RisPose.facing(np.array([0.0, 5.0, 1.2]), np.array([6.0, 5.0, 1.2])),
         RisPose.facing(np.array([6.0, 14.0, 1.2]), np.array([6.0, 5.0, 1.2])))
SD, SAZ, SV = 1e-3, np.deg2rad(0.02), 1e-3  # 1σ of distance [m], azimuth [rad], radial velocity [m/s]
STEP = 0.3904  # one slot [s]
HEIGHT = (1.2, 0.01)
MODELS = Manoeuvres(quiet=1e-4, turning=1.0 / STEP, quiet_time=8.0, turning_time=STEP)
SPEED = 1.0  # [m/s]


def _walk(rng, steps, turn_times, turn_length):
    """A walker at SPEED from near (6, 5) turning by ±90° at each of ``turn_times`` [s]: at once
    (``turn_length`` 0) or on an arc of that duration [s] centred there. The truth [steps, 6] at the slots'
    times, integrated on a 0.1 ms grid."""
    heading0 = rng.uniform(0, 2 * np.pi)
    signs = rng.choice([-1.0, 1.0], len(turn_times))
    dt = 1e-4
    grid = np.arange(0.0, steps * STEP + dt, dt)

    def heading(t):
        h = np.full_like(t, heading0)
        for tt, s in zip(turn_times, signs):
            if turn_length > 0:
                h += s * np.pi / 2 * np.clip((t - tt + turn_length / 2) / turn_length, 0.0, 1.0)
            else:
                h += s * np.pi / 2 * (t >= tt)
        return h

    mid = heading(grid[:-1] + dt / 2)
    pos = [np.concatenate([[0.0], np.cumsum(f(mid))]) * SPEED * dt for f in (np.cos, np.sin)]
    start = np.array([6.0, 5.0]) + rng.uniform(-0.5, 0.5, 2)
    k = np.round(np.arange(steps) * STEP / dt).astype(int)
    h = heading(grid[k])
    return np.stack([start[0] + pos[0][k], start[1] + pos[1][k], np.full(steps, HEIGHT[0]),
                     SPEED * np.cos(h), SPEED * np.sin(h), np.zeros(steps)], axis=1)


def _measure(k, s, rng):
    pose = POSES[k % 2]
    rel = s[:3] - pose.position
    d = float(np.linalg.norm(rel))
    z = np.array([d, pose.angles_to(s[:3])[0], float(s[3:] @ rel) / d]) + rng.standard_normal(3) * [SD, SAZ, SV]
    fix = RisFix(name=f"ris{k % 2}", pose=pose, distance=z[0], std_distance=SD, aod=np.array([z[1], 0.0]),
                 std_aod=np.array([SAZ, np.nan]))
    return RisMeasurement(time=k * STEP, fix=fix, velocity=z[2], std_velocity=SV)


def _filtered(times, meas):
    """The two-model filter over ``meas`` (None: coast) in the order given: the estimate after each slot."""
    state, out = None, []
    for t, m in zip(times, meas):
        if state is None:
            state = imm_start(m, height=HEIGHT) if m is not None else None
        elif m is None:
            state = imm_predict(state, t, MODELS)
        else:
            up = imm_update(state, m, MODELS, height=HEIGHT)
            assert up.accepted
            state = up.state
        out.append(state)
    return out


def _smoothed(truth, rng, unseen, max_turn=0.0):
    """Measure every slot of ``truth`` but the ``unseen`` ones, filter both ways, smooth: (forward, smoothed)."""
    times = np.arange(len(truth)) * STEP
    meas = [None if k in unseen else _measure(k, s, rng) for k, s in enumerate(truth)]
    fwd = _filtered(times, meas)
    back = _filtered(-times[::-1], [None if m is None else reversed_measurement(m) for m in meas[::-1]])[::-1]
    used = [m is not None for m in meas]
    return fwd, smooth_track(times, fwd, back, used, motion=MODELS, axes=HORIZONTAL, max_turn=max_turn)


def _turn_times(rng):
    """Two turns at random moments, one in slots 8–17 and one in 24–33 (legs of ≥ 2.7 s between) [s]."""
    return np.array([rng.integers(8, 18), rng.integers(24, 34)]) * STEP + rng.uniform(0, STEP, 2)


def _errors(runs, seed, turn_length, max_turn=0.0):
    """Walks with the slot after each turn unseen: per slot after the fifth, the forward and smoothed position
    errors [m] and NEES (x, y, vx, vy), the true turns and the placed ones."""
    rng = np.random.default_rng(seed)
    out = {"forward": [], "smoothed": [], "nees": [], "nees_forward": [], "unseen": [], "true": [], "placed": []}
    for _ in range(runs):
        turns = _turn_times(rng)
        truth = _walk(rng, 40, turns, turn_length)
        unseen = {int(np.ceil(x / STEP)) for x in turns}
        fwd, sm = _smoothed(truth, rng, unseen, max_turn=max_turn)
        for k in range(5, len(truth)):
            out["forward"].append(np.linalg.norm(fwd[k].mean[:3] - truth[k, :3]))
            out["smoothed"].append(np.linalg.norm(sm.states[k].mean[:3] - truth[k, :3]))
            out["nees"].append(nees(sm.states[k], truth[k], axes=HORIZONTAL))
            out["nees_forward"].append(nees(fwd[k], truth[k], axes=HORIZONTAL))
            out["unseen"].append(k in unseen)
        out["true"].append(turns)
        out["placed"].append(sm.turns)
    return {k: (v if k in ("true", "placed") else np.array(v)) for k, v in out.items()}


def _rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


@pytest.mark.slow
def test_walks_whose_turns_nobody_saw_are_smoothed_to_millimetres_with_an_honest_sigma():
    """30 walks of straight legs with two instant 90° turns each, the slot after each turn unseen (the
    benchmark walk's 29 s corner): the causal track coasts straight past the corner; the smoothed track
    places the turn where the legs meet and is within millimetres; its NEES over (x, y, vx, vy) is not above
    the 95 % band of 30 walks' means; σ_τ covers the true turn times."""
    e = _errors(30, 1, 0.0)
    assert _rms(e["smoothed"]) < 0.1 * _rms(e["forward"]), (_rms(e["smoothed"]), _rms(e["forward"]))
    assert _rms(e["smoothed"]) < 3e-3  # [m]: the fixes' own errors are 1–3 mm
    assert _rms(e["smoothed"][e["unseen"]]) < 5e-3, _rms(e["smoothed"][e["unseen"]])  # the corner slots
    assert np.mean(e["nees"]) <= nees_band(4, 30)[1], np.mean(e["nees"])
    assert np.mean(e["nees_forward"]) > nees_band(4, 30)[1]  # the causal track's coast past the corner is not
    z = []
    for true, placed in zip(e["true"], e["placed"]):
        for t in true:  # every true turn placed, within its stated σ
            near = min(placed, key=lambda p: abs(p.time - t))
            assert near.start < t < near.end
            z.append(abs(near.time - t) / near.std_time)
    z = np.array(z)
    assert np.mean(z <= 2) >= 0.9 and np.mean(z <= 3) >= 0.95, np.round(z, 1)


@pytest.mark.slow
def test_a_turn_that_takes_time_is_covered_only_when_max_turn_says_so():
    """Turns on 0.5 s arcs, the slot after each unseen: the arc lies between two measurements, where no data
    can tell it from a corner (the corner of the two legs is ~13 cm outside a 90° arc of 0.32 m radius).
    With max_turn = 0 (turns at once) the smoothed track's NEES is far above its band; with max_turn = 0.5 s
    it is not, and the track is still better than the causal one. Turns on 1 s arcs, which the slots
    around them see, are not taken for corners."""
    sharp = _errors(20, 2, 0.5)
    covered = _errors(20, 2, 0.5, max_turn=0.5)
    band = nees_band(4, 20)[1]
    assert np.mean(sharp["nees"]) > 3 * band
    assert np.mean(covered["nees"]) <= band, np.mean(covered["nees"])
    assert _rms(covered["smoothed"]) < 0.5 * _rms(covered["forward"])
    slow = _errors(20, 3, 1.0, max_turn=1.0)
    assert np.mean(slow["nees"]) <= band, np.mean(slow["nees"])
    assert _rms(slow["smoothed"]) < _rms(slow["forward"])


def test_fusing_two_estimates_is_the_product_of_their_gaussians():
    """The information form as the oracle: P = (Pa⁻¹ + Pb⁻¹)⁻¹, x = P (Pa⁻¹ xa + Pb⁻¹ xb)."""
    rng = np.random.default_rng(4)
    a_, b_ = (rng.standard_normal((6, 6)) for _ in range(2))
    pa, pb = a_ @ a_.T + 0.1 * np.eye(6), b_ @ b_.T + 1e-4 * np.eye(6)
    xa, xb = rng.standard_normal(6), rng.standard_normal(6)
    out = fuse_estimates(TrackState(time=2.0, mean=xa, covariance=pa), TrackState(time=2.0, mean=xb, covariance=pb))
    info = np.linalg.inv(pa) + np.linalg.inv(pb)
    np.testing.assert_allclose(out.covariance, np.linalg.inv(info), rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(out.mean, np.linalg.solve(info, np.linalg.solve(pa, xa) + np.linalg.solve(pb, xb)),
                               rtol=1e-8, atol=1e-12)
    with pytest.raises(ValueError, match="same time"):
        fuse_estimates(TrackState(time=2.0, mean=xa, covariance=pa), TrackState(time=2.1, mean=xb, covariance=pb))


def test_time_reversal_flips_the_velocity_and_nothing_else():
    rng = np.random.default_rng(5)
    c = rng.standard_normal((6, 6))
    s = TrackState(time=3.0, mean=rng.standard_normal(6), covariance=c @ c.T)
    r = reversed_state(s)
    assert r.time == -3.0
    np.testing.assert_array_equal(r.mean, np.concatenate([s.mean[:3], -s.mean[3:]]))
    np.testing.assert_array_equal(r.covariance[:3, 3:], -s.covariance[:3, 3:])
    np.testing.assert_array_equal(r.covariance[3:, 3:], s.covariance[3:, 3:])
    back = reversed_state(r)
    np.testing.assert_array_equal(back.mean, s.mean)
    np.testing.assert_array_equal(back.covariance, s.covariance)
    m = _measure(3, np.array([7.0, 6.0, 1.2, 0.6, -0.8, 0.0]), rng)
    rm = reversed_measurement(m)
    assert (rm.time, rm.velocity, rm.std_velocity, rm.fix) == (-m.time, -m.velocity, m.std_velocity, m.fix)


def test_the_turn_time_is_where_the_legs_meet_and_its_sigma_is_their_spread():
    """Legs through a corner c at τ = 10.3 s (east at 1 m/s, then north): τ exactly from noise-free estimates;
    σ_τ against the spread of τ over 4000 draws of the estimates from their covariances (first order)."""
    c, tau = np.array([4.0, 2.0, 1.2]), 10.3
    va, vb = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    ta, tb = 10.0, 10.8
    cov = np.diag([1e-6, 1e-6, 1e-8, 1e-6, 1e-6, 1e-8])
    before = TrackState(time=ta, mean=np.concatenate([c - va * (tau - ta), va]), covariance=cov)
    after = TrackState(time=tb, mean=np.concatenate([c + vb * (tb - tau), vb]), covariance=2 * cov)
    t, sd = turn_time(before, after)
    assert t == pytest.approx(tau, abs=1e-12)
    rng = np.random.default_rng(6)
    draws = [turn_time(TrackState(time=ta, mean=rng.multivariate_normal(before.mean, cov), covariance=cov),
                       TrackState(time=tb, mean=rng.multivariate_normal(after.mean, 2 * cov), covariance=cov))[0]
             for _ in range(4000)]
    assert np.std(draws) == pytest.approx(sd, rel=0.05)
    straight = TrackState(time=tb, mean=np.concatenate([before.mean[:3] + va * (tb - ta), va]), covariance=cov)
    assert math.isinf(turn_time(before, straight)[1])
    with pytest.raises(ValueError, match="after its start"):
        turn_time(after, before)


def test_a_straight_walk_is_joined_everywhere_and_never_worse_than_either_filter():
    """No turn: every slot is the product of the two filters (kind "joined"), its covariance no larger than the
    forward filter's (information only adds), no turn placed. One-model filters (motion = q) too."""
    rng = np.random.default_rng(7)
    truth = _walk(rng, 20, [], 0.0)
    times = np.arange(20) * STEP
    meas = [None if k in (6, 13) else _measure(k, s, rng) for k, s in enumerate(truth)]
    fwd, sm = _smoothed(truth, rng, {6, 13})
    assert set(sm.kinds[:-1]) == {"joined"} and sm.kinds[-1] == "forward" and not sm.turns
    for f, s in zip(fwd, sm.states):
        assert np.trace(s.covariance[:2, :2]) <= np.trace(f.covariance[:2, :2]) * (1 + 1e-9)

    def one_model(order, sign):  # a one-model filter over the slots in ``order``, time sign·t
        state, out = None, [None] * 20
        for k in order:
            m = meas[k] if sign > 0 or meas[k] is None else reversed_measurement(meas[k])
            if state is None:
                state = start_track(m, height=HEIGHT)
            elif m is None:
                state = predict(state, sign * times[k], accel_density=0.05)
            else:
                state = update(state, m, accel_density=0.05, height=HEIGHT).state
            out[k] = state
        return out

    one, bwd = one_model(range(20), 1), one_model(range(19, -1, -1), -1)
    s1 = smooth_track(times, one, bwd, [m is not None for m in meas], motion=0.05, axes=HORIZONTAL)
    err_f = [np.linalg.norm(s.mean[:2] - x[:2]) for s, x in zip(one, truth)]
    err_s = [np.linalg.norm(s.mean[:2] - x[:2]) for s, x in zip(s1.states, truth)]
    assert _rms(err_s) < _rms(err_f) and not s1.turns


@pytest.mark.parametrize("kwargs, match", [
    ({"times": [0.0, 0.0, 1.0]}, "increasing"),
    ({"used": [True, True]}, "equally long"),
    ({"motion": "fast"}, "Manoeuvres or a q > 0"),
    ({"motion": -1.0}, "Manoeuvres or a q > 0"),
    ({"gate_pfa": 0.0}, "gate_pfa"),
    ({"quiet_share": 1.0}, "quiet_share"),
    ({"max_turn": -0.5}, "max_turn"),
])
def test_bad_smoother_inputs_are_one_line(kwargs, match):
    args = {"times": [0.0, 0.4, 0.8], "forward": [None] * 3, "backward": [None] * 3, "used": [False] * 3,
            "motion": MODELS, **kwargs}
    with pytest.raises(ValueError, match=match) as err:
        smooth_track(args.pop("times"), args.pop("forward"), args.pop("backward"), args.pop("used"), **args)
    assert "\n" not in str(err.value)


def test_no_estimate_anywhere_is_none_everywhere():
    out = smooth_track([0.0, 0.4], [None, None], [None, None], [False, False], motion=MODELS)
    assert out.states == (None, None) and out.kinds == ("none", "none") and set(out.kinds) <= set(SMOOTH_KINDS)

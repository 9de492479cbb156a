"""Issue 20, item 9: a wrong RIS model is noticed (``pattern-mismatch``) and its σ widened.

A relay recording imported as ``mode = "reflective"`` gave an AoD "± 0.00°" with no flag: the
fit of the reflective pattern (a main lobe half as wide) to a relay P_ave profile is the best fit
of a wrong model, and its CRB knows nothing of it. The pattern fit's goodness of fit
(:func:`dsp.aod_fit.pattern_fit`: T = Σ (r_m − b̂|A_m|)² / Σ e_m, e_m the expected squared residual
of a Rice magnitude) now raises the flag when T exceeds its χ² level at the detector's pfa, and the
AoD's 1σ (and the position's AoD part) is widened by sqrt(T).

Oracles: magnitudes drawn here from the Rice law of the model (numpy only) for the statistic's
false-alarm rate; the simulator (``risloc_rt.model``: element-by-element RIS response, not
``dsp.BeamPattern``) for the captures.
"""

from __future__ import annotations

import importlib

import numpy as np
import pytest

import dsp
from dsp.aod_fit import PatternFit, pattern_fit
from risloc_rt.model.scenario import paper_scenario
from risloc_rt.model.simulate import simulate

LAMBDA = dsp.SPEED_OF_LIGHT / 60e9
SWEEP = dsp.BeamSweep.azimuth_grid(*np.deg2rad([-45.0, 45.0, 1.5]))
RELAY = dsp.BeamPattern.relay().for_wavelength(LAMBDA)
REFLECTIVE = dsp.BeamPattern.reflective().for_wavelength(LAMBDA)
LOCALIZE = importlib.import_module("dsp.localize")  # the module (dsp.localize is also a function's name)


def rice_magnitudes(rng, pattern, az, peak_snr):
    """|b A_m e^{jψ_m} + w_m|, w ~ CN(0, 1), b² = peak_snr, ψ_m uniform: written out, not the library's."""
    a = np.abs(pattern.amplitude([az, 0.0], SWEEP.angles))
    z = np.sqrt(peak_snr) * a * np.exp(2j * np.pi * rng.random(a.size))
    return np.abs(z + (rng.standard_normal(a.size) + 1j * rng.standard_normal(a.size)) * np.sqrt(0.5))


def test_the_statistic_is_about_one_and_rarely_fires_under_the_right_model():
    # 600 draws over 5-35 dB peak SNR and ±40°: mean T within 0.15 of 1 (the fit removes 2 of ~61
    # degrees of freedom), and the test at pfa = 1e-3 fires on < 1 % of them.
    rng = np.random.default_rng(1)
    stats, fired = [], 0
    for i in range(600):
        snr_db = 5.0 + 30.0 * (i % 7) / 6
        az = np.deg2rad(rng.uniform(-40, 40))
        fit = pattern_fit(rice_magnitudes(rng, RELAY, az, 10 ** (snr_db / 10)), SWEEP, RELAY, noise_variance=1.0)
        stats.append(fit.statistic)
        fired += fit.mismatch
    assert np.mean(stats) == pytest.approx(1.0, abs=0.15)
    assert fired / 600 < 0.01


def test_the_statistic_sees_a_wrong_mode():
    rng = np.random.default_rng(2)
    fit = pattern_fit(rice_magnitudes(rng, RELAY, np.deg2rad(10.0), 10 ** 3.0), SWEEP, REFLECTIVE, noise_variance=1.0)
    assert fit.mismatch and fit.statistic > 10 * fit.threshold
    assert fit.excess == pytest.approx(np.sqrt(fit.statistic))
    right = pattern_fit(rice_magnitudes(rng, RELAY, np.deg2rad(10.0), 10 ** 3.0), SWEEP, RELAY, noise_variance=1.0)
    assert right.excess == 1.0


def test_pattern_fit_rejects_a_bad_noise_variance():
    with pytest.raises(ValueError, match="noise_variance"):
        pattern_fit(np.ones(61), SWEEP, RELAY, noise_variance=0.0)


def capture(case="off-broadside", *, mode="relay", power_dbm=20.0, seed=0):
    sc = paper_scenario(case, mode=mode, radar=dsp.RadarConfig(tx_power_dbm=power_dbm))
    return simulate(sc, rng=np.random.default_rng(seed), seed=seed, noise_stream="fast")


def locate(cap, pattern, estimator="refined", **kw):
    return dsp.self_localize(cap.cube, sweep=cap.sweep, radar=cap.radar, processing=cap.processing,
                             pose=cap.ris.pose, loopback_delay=cap.ris.loopback_delay, estimator=estimator,
                             pattern=pattern, **kw)


@pytest.mark.parametrize("estimator", ["refined", "paper"])
def test_relay_data_located_with_a_reflective_model_is_flagged_and_its_sigma_widened(estimator, monkeypatch):
    cap = capture()
    loc = locate(cap, dsp.BeamPattern.reflective(), estimator)
    assert "pattern-mismatch" in loc.flag_codes
    # the σ the estimator states without the test: pattern_fit answering "fits"
    with monkeypatch.context() as m:
        m.setattr(LOCALIZE, "pattern_fit",
                  lambda *a, **k: PatternFit(statistic=0.0, threshold=1.0, dof=1.0, aod=np.zeros(2)))
        nominal = locate(cap, dsp.BeamPattern.reflective(), estimator)
    assert "pattern-mismatch" not in nominal.flag_codes
    np.testing.assert_array_equal(nominal.position, loc.position)  # the numbers are not touched
    factor = loc.std.aod[0] / nominal.std.aod[0]
    assert factor > 3.0  # measured 8 (paper) to 16 (refined)
    assert loc.std.distance == nominal.std.distance
    # the position's cross-range 1σ (x here: the RIS looks along -y) grows with the AoD's
    assert loc.std.position[0] > 2.0 * nominal.std.position[0]
    assert loc.std.peb > nominal.std.peb
    flag = next(f for f in loc.flags if f.code == "pattern-mismatch")
    assert f"widened {factor:.1f}×" in flag.message


def test_right_model_is_not_flagged_on_a_few_captures():
    # broadside and off-broadside, 0 and 25 dBm, relay data with the relay model
    for case in ("broadside", "off-broadside"):
        for power, seed in ((0.0, 3), (25.0, 4)):
            loc = locate(capture(case, power_dbm=power, seed=seed), dsp.BeamPattern.relay(), scan=False)
            assert loc.detected and "pattern-mismatch" not in loc.flag_codes, (case, power)


@pytest.mark.slow
def test_right_model_false_alarm_rate_below_one_percent_at_0_to_25_dbm():
    # 60 Table I captures (relay RIS, relay model; broadside and 21° off; 0, 5, ..., 25 dBm; the
    # fast noise stream): the flag fires on none (0 of 60 bounds the rate below 4.9 % at 95 %;
    # docs/flags.md: 0 of 360 measured on other seeds, below 0.83 %). 60 rather than 120 keeps the
    # suite's time (75 s for 120 on the 2-core CI machine).
    seeds = np.random.SeedSequence(2020).spawn(60)
    fired = []
    for i, ss in enumerate(seeds):
        power = [0.0, 5.0, 10.0, 15.0, 20.0, 25.0][i % 6]
        case = ("broadside", "off-broadside")[(i // 6) % 2]
        sc = paper_scenario(case, radar=dsp.RadarConfig(tx_power_dbm=power))
        cap = simulate(sc, rng=np.random.default_rng(ss), noise_stream="fast")
        loc = locate(cap, dsp.BeamPattern.relay(), scan=False)
        if "pattern-mismatch" in loc.flag_codes:
            fired.append((case, power))
    assert fired == [], fired


def test_a_radar_walking_across_the_beam_is_not_a_wrong_pattern():
    # 1 m/s across the RIS-radar line, 20 ms frames: the AoD turns 2.6° over the sweep and smears the
    # profile; the pattern held over the sweep does not fit it (static T above the threshold), the
    # pattern whose AoD drifts does, and no flag is raised. Its position is still right.
    import dataclasses

    from dsp.residual import beam_values

    radar = dsp.RadarConfig(frame_period=20e-3, tx_power_dbm=20.0)
    sc = dataclasses.replace(paper_scenario(radar=radar), ue_velocity=np.array([1.0, 0.0, 0.0]))
    cap = simulate(sc, rng=np.random.default_rng(2), seed=2, noise_stream="fast")
    loc = locate(cap, dsp.BeamPattern.relay(), scan=False)
    assert "pattern-mismatch" not in loc.flag_codes
    assert np.linalg.norm(loc.position - cap.truth.position_at(loc.reference_time)) < 0.1
    est = dsp.refine_estimate(cap.cube, sweep=cap.sweep, radar=radar, pattern=RELAY, initial_delay=loc.delay,
                              initial_delay_rate=loc.delay_rate)
    w = np.abs(RELAY.amplitude(loc.aod, cap.sweep.angles))
    values, gain = beam_values(cap.cube, radar, *est.beat_frequency, w, drift_rate=loc.delay_rate,
                               beam_times=radar.beam_times(61))
    s2 = loc.detection.noise_power * gain
    static = pattern_fit(np.abs(values), cap.sweep, RELAY, noise_variance=s2)
    drifting = pattern_fit(np.abs(values), cap.sweep, RELAY, noise_variance=s2, beam_times=radar.beam_times(61),
                           max_aod_rate=2.0 / loc.distance)
    assert static.mismatch and not drifting.mismatch
    assert drifting.static_statistic == pytest.approx(static.statistic)
    # the fitted drift is the motion's: |du/dt| = v cos(az)/d, az = 0
    assert abs(drifting.aod_rate) == pytest.approx(1.0 / 13.38, rel=0.3)
    # the static fit fails, so decide_only (self_localize's) tries the drifting fit too: the same result
    assert pattern_fit(np.abs(values), cap.sweep, RELAY, noise_variance=s2, beam_times=radar.beam_times(61),
                       max_aod_rate=2.0 / loc.distance, decide_only=True) == drifting


def test_decide_only_skips_the_drifting_fit_only_where_it_cannot_change_the_decision():
    # relay magnitudes (Rice, written out here) under the right and a wrong model, the AoD free to drift: with
    # decide_only the decision and the widening are those of the whole fit; where the static fit passes the
    # drifting one is not tried (aod_rate 0, T the static one), where it fails the whole fit is made
    rng = np.random.default_rng(12)
    times = np.arange(SWEEP.num_beams) * 20e-3
    skipped = made = 0
    for pattern in (RELAY, REFLECTIVE):
        for _ in range(20):
            r = rice_magnitudes(rng, RELAY, np.deg2rad(rng.uniform(-30, 30)), 10 ** rng.uniform(1.5, 3))
            full = pattern_fit(r, SWEEP, pattern, noise_variance=1.0, beam_times=times, max_aod_rate=0.15)
            quick = pattern_fit(r, SWEEP, pattern, noise_variance=1.0, beam_times=times, max_aod_rate=0.15,
                                decide_only=True)
            assert (quick.mismatch, quick.excess, quick.threshold) == (full.mismatch, full.excess, full.threshold)
            if quick.static_statistic <= quick.threshold:
                assert quick.aod_rate == 0.0 and quick.statistic == quick.static_statistic
                skipped += 1
            else:
                assert quick == full
                made += 1
    assert skipped >= 10 and made >= 10, (skipped, made)  # both branches, and the wrong model mostly caught
    with pytest.raises(TypeError, match="decide_only"):
        pattern_fit(r, SWEEP, RELAY, noise_variance=1.0, decide_only="yes")

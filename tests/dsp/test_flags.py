"""Results that qualify themselves (dsp.self_localize): detection, uncertainty, flags, no position without a detection.

Oracles: the geometry of each flag's cause, built into a synthetic cube (a UE beyond the sweep,
a grating lobe of a reflective RIS at sin φ = sin θ - 1, a delay shorter than τ_RB, two returns
closer than the resolution, a return at the range wrap); a known height puts the UE at that z;
the paper path's numbers equal localize(scan_beams(...)) exactly; every code is documented in
docs/flags.md.
"""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import numpy as np
import pytest

import dsp

C = dsp.SPEED_OF_LIGHT
TAU_RB = 1.78e-9
RADAR = dsp.RadarConfig(num_samples=64, num_chirps=16)
PROCESSING = dsp.ProcessingConfig(n_dft=127, k_dft=64)
SWEEP = dsp.BeamSweep.azimuth_grid(*np.deg2rad([-21.0, 21.0, 3.0]))  # M = 15
RELAY = dsp.BeamPattern().for_wavelength(RADAR.wavelength)
REFLECTIVE = dsp.BeamPattern.reflective().for_wavelength(RADAR.wavelength)
POSE = dsp.RisPose.facing([0.0, 8.0, 1.5], [0.0, 0.0, 1.5])
DOCS = Path(__file__).resolve().parents[2] / "docs" / "flags.md"


def tone(tau, nu):
    f1 = (RADAR.slope * tau + RADAR.carrier_frequency * nu) * RADAR.sample_period
    f2 = RADAR.carrier_frequency * nu * RADAR.chirp_interval
    k, n = RADAR.num_chirps, RADAR.num_samples
    return np.exp(-2j * np.pi * ((np.arange(k)[:, None] * f2 + np.arange(n)[None, :] * f1) % 1.0))


def cube_for(rng, *, distance=6.0, velocity=0.3, az=np.deg2rad(5.1), peak_snr=1e3, pattern=RELAY, sweep=SWEEP,
             tau=None, extra=None):
    m, k, n = sweep.num_beams, RADAR.num_chirps, RADAR.num_samples
    tau = 2 * distance / C + TAU_RB if tau is None else tau
    nu = 2 * velocity / C
    amp = np.abs(pattern.amplitude([az, 0.0], sweep.angles)) * np.sqrt(peak_snr / (k * n))
    cube = (amp * np.exp(2j * np.pi * rng.random(m)))[:, None, None] * tone(tau, nu)[None]
    if extra is not None:
        cube = cube + extra
    return cube + (rng.standard_normal(cube.shape) + 1j * rng.standard_normal(cube.shape)) * np.sqrt(0.5)


def locate(cube, *, sweep=SWEEP, estimator="refined", pattern=RELAY, **kw):
    kw.setdefault("loopback_delay", TAU_RB)
    return dsp.self_localize(cube, sweep=sweep, radar=RADAR, processing=PROCESSING, pose=POSE,
                             estimator=estimator, pattern=pattern, **kw)


def test_no_detection_means_no_position():
    rng = np.random.default_rng(1)
    loc = locate((rng.standard_normal((15, 16, 64)) + 1j * rng.standard_normal((15, 16, 64))) / np.sqrt(2))
    assert not loc.detected and loc.flag_codes[0] == "no-detection"
    for name in ("aod", "delay", "distance", "delay_rate", "velocity", "direction", "position"):
        assert np.all(np.isnan(getattr(loc, name))), name
    assert loc.std is None
    with pytest.raises(dsp.NoPositionError, match="no RIS return"):
        loc.checked_position()
    assert set(loc.detection.to_dict()) == {"detected", "snr_db", "threshold_db", "false_alarm_probability"}
    assert 0 <= loc.beam_index < 15  # still usable to draw the strongest beam


def rician_moments(rho):
    """G = E[g(x)²] and V = E[(g(x) r - u)²], x = 2ur, r = |u + CN(0, 1)|, u = sqrt(ρ), g = I₁/I₀ [unitless].

    What one beam of per-beam SNR ρ contributes when its phase is random (docs/estimation.md,
    "Random phases"): G scales its delay/Doppler information, V its amplitude score's. Here by
    quadrature over the Rice density p(r) = 2r exp(-(r² + u²)) I₀(2ur), written with the scaled
    Bessel functions (I₀(x) = i0e(x) eˣ) as 2r exp(-(r - u)²) i0e(2ur).
    """
    from scipy import integrate, special

    u = np.sqrt(rho)
    if u == 0:
        return 0.0, 0.0
    pdf = lambda r: 2 * r * np.exp(-((r - u) ** 2)) * special.i0e(2 * u * r)  # noqa: E731
    g = lambda r: special.i1e(2 * u * r) / special.i0e(2 * u * r)  # noqa: E731
    lo, hi = max(0.0, u - 12.0), u + 12.0
    big_g = integrate.quad(lambda r: g(r) ** 2 * pdf(r), lo, hi, epsabs=1e-13, limit=200)[0]
    big_v = integrate.quad(lambda r: (g(r) * r - u) ** 2 * pdf(r), lo, hi, epsabs=1e-13, limit=200)[0]
    return big_g, big_v


def random_phase_bound(aod, rho, *, h=1e-6):
    """1σ of distance [m] and azimuth [rad] with random per-beam phases, written out (docs/estimation.md).

    Per beam m, ρ_m = ρ A_m(θ)². Delay/Doppler: the single-tone Fisher information, summed over
    the beams and scaled by G(ρ_m): J_f₁ = 2(2π)² Σ ρ_m G_m (N² - 1)/12 and J_f₂ the same with K
    [1/cycles²]; ν = f₂/(f_c T_c), τ = f₁/(S T_s) - f_c ν/S, distance τ c/2. Azimuth (elevation
    known, a 1-D sweep): the amplitude scores of (θ, β), J_θ = 4ρ [Σ V_m A'_m² - (Σ V_m A_m A'_m)² /
    Σ V_m A_m²] with A' = ∂A/∂az by a central difference (V → ½ gives the fixed-phase CRB).
    """
    a = RELAY.amplitude(aod, SWEEP.angles)
    da = (RELAY.amplitude(aod + np.array([h, 0.0]), SWEEP.angles)
          - RELAY.amplitude(aod - np.array([h, 0.0]), SWEEP.angles)) / (2 * h)
    gv = np.array([rician_moments(rho * am**2) for am in a])  # [M, 2]
    big_g, big_v = gv[:, 0], gv[:, 1]
    k, n = RADAR.num_chirps, RADAR.num_samples
    info = rho * np.sum(a**2 * big_g)
    var_f1 = 1 / (2 * (2 * np.pi) ** 2 * info * (n**2 - 1) / 12)
    var_f2 = 1 / (2 * (2 * np.pi) ** 2 * info * (k**2 - 1) / 12)
    f_c, slope = RADAR.carrier_frequency, RADAR.slope
    var_nu = var_f2 / (f_c * RADAR.chirp_interval) ** 2
    var_tau = var_f1 / (slope * RADAR.sample_period) ** 2 + (f_c / slope) ** 2 * var_nu
    j_az = 4 * rho * (np.sum(big_v * da**2) - np.sum(big_v * a * da) ** 2 / np.sum(big_v * a**2))
    return np.sqrt(var_tau) * C / 2, 1 / np.sqrt(j_az)


def test_detected_estimate_carries_uncertainty_and_a_reference_time():
    """The stated 1σ is the random-phase bound at the estimate and at the measured SNR: it must
    equal :func:`random_phase_bound` (written out here, its Rician factors by quadrature) within
    1e-4 relative: the library tabulates G and V (to 1.5e-4 for a beam at ρ_m = 0.09, better above,
    and such weak beams carry little weight; measured agreement 4e-7 in distance, 2e-6 in AoD).
    A bound off by √2, an SNR off by 0.1 dB (1.2 %), or the fixed-phase CRB (V = ½, G = 1: 0.16 %
    lower in distance, 2.4 % in AoD at this SNR) fails."""
    rng = np.random.default_rng(2)
    loc = locate(cube_for(rng))
    assert loc.detected and loc.detection.detected
    assert np.all(np.isfinite(loc.checked_position()))
    sd = loc.std
    assert sd.kind == "crb"
    # the measured SNR is the synthesised one (30 dB) within a dB
    assert sd.peak_snr_db == pytest.approx(30.0, abs=1.0)
    rho = 10 ** (sd.peak_snr_db / 10)
    distance, azimuth = random_phase_bound(loc.aod, rho)
    # the refined delay's variance carries the static template's factor F (dsp.refine_estimate; its
    # own tests check F): the distance 1σ is the bound times √F
    cube = cube_for(np.random.default_rng(2))
    factor = dsp.refine_estimate(cube, sweep=SWEEP, radar=RADAR, pattern=RELAY, initial_delay=loc.delay,
                                 initial_delay_rate=loc.delay_rate).delay_variance_factor
    assert 1.0 <= factor < 1.2
    assert sd.distance == pytest.approx(distance * np.sqrt(factor), rel=1e-4)
    assert sd.aod[0] == pytest.approx(azimuth, rel=1e-4)
    fixed = dsp.sweep_crb(radar=RADAR, sweep=SWEEP, pattern=RELAY, aod=loc.aod, peak_snr=rho)
    assert sd.distance > fixed.distance * (1 + 1e-4) and sd.aod[0] > fixed.aod[0] * (1 + 1e-4)
    assert np.isnan(sd.aod[1])  # 1-D sweep: elevation unseen
    assert sd.peb == pytest.approx(np.linalg.norm(sd.position))
    assert 0 < loc.reference_time < 15 * RADAR.beam_interval


def test_paper_path_numbers_equal_the_paper_method():
    rng = np.random.default_rng(3)
    cube = cube_for(rng)
    loc = locate(cube, estimator="paper")
    ref = dsp.localize(dsp.scan_beams(cube, SWEEP, RADAR, PROCESSING), radar=RADAR, pose=POSE, loopback_delay=TAU_RB)
    for f in dataclasses.fields(ref):
        if f.name not in ("scan", "detection", "std", "flags", "estimator", "reference_time", "alternatives"):
            np.testing.assert_array_equal(getattr(loc, f.name), getattr(ref, f.name), err_msg=f.name)
    assert loc.std.kind == "crb+grid"


def test_beam_edge_when_the_ue_is_outside_the_sweep():
    # 25°: beyond the last beam (21°) but inside its main lobe (first null at Δu = 1/8)
    loc = locate(cube_for(np.random.default_rng(4), az=np.deg2rad(25.0)))
    assert "beam-edge" in loc.flag_codes
    assert "beam-edge" not in locate(cube_for(np.random.default_rng(4), az=np.deg2rad(5.0))).flag_codes


def test_grating_lobe_of_a_reflective_ris_lists_both_candidates():
    sweep = dsp.BeamSweep.azimuth_grid(*np.deg2rad([-45.0, 45.0, 3.0]))
    az = np.deg2rad(30.0)
    loc = locate(cube_for(np.random.default_rng(5), az=az, pattern=REFLECTIVE, sweep=sweep), sweep=sweep,
                 pattern=REFLECTIVE)
    flag = next(f for f in loc.flags if f.code == "grating-lobe")
    angles = sorted(float(a) for a in re.findall(r"([+-]\d+\.\d+)°", flag.message)[:2])
    assert angles == pytest.approx([-30.0, 30.0], abs=0.5)


def test_before_ris_delay_gives_a_flagged_negative_distance():
    loc = locate(cube_for(np.random.default_rng(6), distance=1.0), loopback_delay=2 * 1.2 / C + TAU_RB)
    assert loc.distance < 0 and "before-ris-delay" in loc.flag_codes


def test_return_at_the_range_wrap_is_flagged_aliased():
    tau = RADAR.max_delay - 0.5 * RADAR.delay_resolution
    loc = locate(cube_for(np.random.default_rng(7), tau=tau, velocity=0.0))
    assert "aliased" in loc.flag_codes


def test_two_returns_within_the_resolution_are_flagged_unresolved():
    rng = np.random.default_rng(8)
    tau2 = 2 * 6.0 / C + TAU_RB + 0.45 * RADAR.delay_resolution
    second = 0.7 * np.abs(RELAY.amplitude([np.deg2rad(5.1), 0.0], SWEEP.angles))[:, None, None] * np.sqrt(
        1e3 / (16 * 64)) * tone(tau2, 2 * 0.3 / C)[None]
    assert "unresolved-peaks" in locate(cube_for(rng, extra=second)).flag_codes
    assert "unresolved-peaks" not in locate(cube_for(rng)).flag_codes


def test_no_beam_dependence_when_the_only_strong_return_ignores_the_sweep():
    rng = np.random.default_rng(9)
    clutter = 30.0 * np.exp(2j * np.pi * rng.random(15))[:, None, None] * tone(2 * 3.0 / C, 0.0)[None]
    loc = locate(clutter + (rng.standard_normal(clutter.shape) + 1j * rng.standard_normal(clutter.shape)) / np.sqrt(2))
    assert loc.flag_codes == ("no-detection", "no-beam-dependence") and np.all(np.isnan(loc.position))


def test_elevation_assumed_for_a_1d_sweep_and_solved_by_a_known_height():
    rng = np.random.default_rng(10)
    cube = cube_for(rng)
    loc = locate(cube)
    flag = next(f for f in loc.flags if f.code == "elevation-assumed")
    assert "±1.00 m" in flag.message
    height = 0.9  # 0.6 m below the RIS (z = 1.5 m)
    solved = locate(cube, ue_height=height)
    assert "elevation-assumed" not in solved.flag_codes
    assert solved.position[2] == pytest.approx(height, abs=1e-9)
    assert solved.distance == pytest.approx(loc.distance, abs=1e-12)
    # the measured direction cosine along the row axis is kept
    u = lambda a: np.cos(a[1]) * np.sin(a[0])  # noqa: E731
    assert u(solved.aod) == pytest.approx(u(loc.aod), abs=1e-12)
    assert np.isfinite(solved.std.aod[1])


def test_reference_time_moves_the_distance_with_the_radial_velocity():
    cube = cube_for(np.random.default_rng(11), velocity=1.5)
    a = locate(cube)
    b = locate(cube, reference_time=a.reference_time + 0.1)
    assert b.distance - a.distance == pytest.approx(a.velocity * 0.1, rel=1e-9)
    assert b.reference_time == pytest.approx(a.reference_time + 0.1)


@pytest.mark.parametrize("kwargs, match", [
    ({"estimator": "best"}, "estimator"),
    ({"sweep": dsp.BeamSweep(np.zeros((3, 2)))}, "sweep has 3 angles"),
])
def test_bad_arguments_are_rejected(kwargs, match):
    with pytest.raises(ValueError, match=match):
        locate(cube_for(np.random.default_rng(12)), **kwargs)


def test_a_sweep_of_one_beam_is_an_error():
    cube = cube_for(np.random.default_rng(13))[:1]
    with pytest.raises(ValueError, match="at least 2 beams"):
        locate(cube, sweep=dsp.BeamSweep(SWEEP.angles[:1]))


def test_every_flag_code_is_documented_with_cause_and_remedy():
    text = DOCS.read_text(encoding="utf-8")
    for code in dsp.FLAG_CODES:
        section = re.search(rf"^## `{re.escape(code)}`\n(.*?)(?=^## |\Z)", text, flags=re.S | re.M)
        assert section, code
        assert "**Cause.**" in section.group(1) and "**Remedy.**" in section.group(1), code
    with pytest.raises(ValueError, match="not a flag code"):
        dsp.Flag("made-up", "x")


# ------------------------------------------------------------------------------ radar timing
def test_radar_timing_defaults_and_old_files():
    r = dsp.RadarConfig()
    assert r.chirp_interval == r.chirp_duration == 50e-6
    assert r.frame_interval == pytest.approx(128 * 50e-6) and r.frames_per_beam == 1
    old = {k: v for k, v in r.to_dict().items() if k not in ("chirp_period", "frame_period", "frames_per_beam")}
    assert dsp.RadarConfig.from_dict(old, require_all=True) == r
    t = dsp.RadarConfig(chirp_period=60e-6, frame_period=10e-3, frames_per_beam=2)
    assert t.velocity_resolution == pytest.approx(t.wavelength / (2 * 128 * 60e-6))
    assert t.beam_interval == pytest.approx(20e-3)
    assert t.beam_times(3) == pytest.approx(np.array([0.0, 20e-3, 40e-3]) + 128 * 60e-6 / 2)
    # first chirp of beam 0 to the end of beam 2's first frame: two beam intervals and one frame
    assert t.sweep_duration(3) == pytest.approx(40e-3 + 128 * 60e-6)
    assert r.sweep_duration(61) == pytest.approx(61 * 128 * 50e-6)  # frames back to back
    assert dsp.RadarConfig.from_dict(t.to_dict(), require_all=True) == t
    with pytest.raises(ValueError, match="chirp_period"):
        dsp.RadarConfig(chirp_period=40e-6)
    with pytest.raises(ValueError, match="frame_period"):
        dsp.RadarConfig(frame_period=1e-3)


def _context(**change):
    """A FlagContext of a quiet estimate (a 2-D sweep, no cause of any flag), with ``change`` applied."""
    from dsp.aod_fit import AodFit
    from dsp.flags import FlagContext

    grid = np.deg2rad([[az, el] for az in (-12.0, -6.0, 0.0, 6.0, 12.0) for el in (-6.0, 0.0, 6.0)])
    aod = np.deg2rad([1.0, 0.5])
    mags = np.ones(15)
    mags[7] = 5.0
    ctx = FlagContext(detection=dsp.Detection(True, 30.0, 15.0, 1e-3),
                      fit=AodFit(aod=aod, direction_cosine=float(np.sin(aod[0])), amplitude=1.0,
                                 candidates=np.zeros((0, 2))),
                      magnitudes=mags, sweep=dsp.BeamSweep(grid), radar=RADAR, pose=POSE,
                      delay=2 * 6.0 / C + TAU_RB, apparent_delay=0.5 * RADAR.max_delay, delay_rate=0.0,
                      loopback_delay=TAU_RB, distance=6.0, aod=aod, unresolved=None, ue_height=None,
                      height_solved=False, height_range=1.0)
    return dataclasses.replace(ctx, **change)


def test_a_searched_twin_beyond_the_span_raises_grating_lobe_and_a_far_one_does_not():
    from dsp.aod_fit import AodFit
    from dsp.flags import sweep_flags

    quiet = _context()
    assert sweep_flags(quiet) == ()

    def with_twin(searched):
        return AodFit(aod=quiet.aod, direction_cosine=quiet.fit.direction_cosine, amplitude=1.0,
                      candidates=np.zeros((0, 2)), twins=np.array([[np.deg2rad(-47.5), 0.0, searched]]))

    flags = sweep_flags(dataclasses.replace(quiet, fit=with_twin(1.0)))
    assert [f.code for f in flags] == ["grating-lobe"] and "-47.50°" in flags[0].message
    assert "beyond the swept span" in flags[0].message
    assert sweep_flags(dataclasses.replace(quiet, fit=with_twin(0.0))) == ()


def test_pattern_mismatch_is_raised_by_its_fit_only():
    from dsp.aod_fit import PatternFit
    from dsp.flags import sweep_flags

    bad = PatternFit(statistic=50.0, threshold=1.5, dof=59.0, aod=np.zeros(2))
    good = PatternFit(statistic=1.2, threshold=1.5, dof=59.0, aod=np.zeros(2))
    flags = sweep_flags(_context(pattern_fit=bad))
    assert [f.code for f in flags] == ["pattern-mismatch"] and "widened 7.1×" in flags[0].message
    assert sweep_flags(_context(pattern_fit=good)) == ()
    assert bad.excess == pytest.approx(np.sqrt(50.0)) and good.excess == 1.0


def _detected_at(delay, delay_rate=0.0):
    return dsp.Detection(True, 30.0, 15.0, 1e-3, delay=float(delay), delay_rate=float(delay_rate))


def test_off_detection_fires_when_the_estimate_is_more_than_a_cell_from_the_detected_return():
    from dsp.flags import OFF_DETECTION_CELLS, sweep_flags
    from dsp.floor_bounce import FloorLadder

    quiet = _context()
    cell = 2 * RADAR.range_resolution / C  # one range resolution cell of delay [s]
    rate_cell = 2 * RADAR.velocity_resolution / C  # one velocity resolution cell of delay rate [s/s]

    def codes(**change):
        return [f.code for f in sweep_flags(dataclasses.replace(quiet, **change))]

    assert OFF_DETECTION_CELLS == 1.0
    # the detector's cell centre within a cell of the estimate: the same return
    assert codes(detection=_detected_at(quiet.delay)) == []
    assert codes(detection=_detected_at(quiet.delay + 0.9 * cell)) == []
    assert codes(detection=_detected_at(quiet.delay, 0.9 * rate_cell), delay_rate=0.0) == []
    # more than a cell away in range, or in velocity: another peak
    assert codes(detection=_detected_at(quiet.delay - 1.1 * cell)) == ["off-detection"]
    assert codes(detection=_detected_at(quiet.delay, -1.1 * rate_cell)) == ["off-detection"]
    far = [f for f in sweep_flags(dataclasses.replace(quiet, detection=_detected_at(quiet.delay - 40 * cell)))]
    detected = quiet.distance - 40 * RADAR.range_resolution
    assert f"({detected:.3f} m, +0.00 m/s)" in far[0].message
    assert f"{40 * RADAR.range_resolution:.3f} m" in far[0].message
    # a floor rung away (the floor's leg of the same return) is not another peak, half a rung off is
    ladder = FloorLadder(3 * RADAR.range_resolution, (0.0, 0.0, 20.0, 9.0, 0.0), 5.0, steps_down=0, bias_std=0.0)
    rung = 2 * ladder.spacing / C
    assert codes(detection=_detected_at(quiet.delay + rung), floor=ladder) == []
    assert codes(detection=_detected_at(quiet.delay - 2 * rung), floor=ladder) == []
    half = _detected_at(quiet.delay + 0.5 * rung)  # 1.5 cells from the estimate and from the rung
    assert codes(detection=half, floor=ladder) == ["off-detection"]
    # moved down the floor's ladder on purpose: first-arrival says so, not off-detection
    moved = codes(detection=_detected_at(quiet.delay + 5 * cell), floor=ladder, floor_moved=True)
    assert moved == ["first-arrival"]
    # a detection without a cell (NaN delay): nothing to compare
    assert codes(detection=dsp.Detection(True, 30.0, 15.0, 1e-3)) == []


def test_off_detection_allows_a_moving_returns_drift_over_the_sweep():
    from dsp.flags import sweep_flags

    radar = dataclasses.replace(RADAR, frame_period=20e-3)  # a beam every 20 ms: the sweep lasts 0.28 s
    quiet = _context(radar=radar)
    v = 5.0  # [m/s] radial: the return moves 5 m/s x the sweep's span between its first and last beam
    rate = 2 * v / C
    times = radar.beam_times(quiet.sweep.num_beams)
    drift = v * (float(times[-1] - times[0]) + radar.frame_duration)  # [m]
    assert drift > 2 * radar.range_resolution  # the test is about the drift, not the cell
    inside = _detected_at(quiet.delay + 2 * (0.9 * drift) / C, rate)
    outside = _detected_at(quiet.delay + 2 * (drift + 1.1 * radar.range_resolution) / C, rate)
    inside, outside = (dataclasses.replace(quiet, delay_rate=rate, detection=d) for d in (inside, outside))
    assert [f.code for f in sweep_flags(inside)] == []
    assert [f.code for f in sweep_flags(outside)] == ["off-detection"]


@pytest.mark.slow
def test_the_paper_estimators_noise_peaks_are_flagged_off_detection_and_its_good_runs_are_not():
    # Table I at 0 dBm (17.8 dB after integration), the study path on the ziggurat noise stream ("fast", where
    # these runs were picked): runs 79, 88 and 194 of study seed 1 are the paper estimator's noise peaks (its
    # best-P_ave beam's grid maximum is noise, metres from the RIS return the detector found); 80 and 89 are not. The oracle is the truth: flagged exactly when the distance is
    # off by more than 10 cm (far beyond the stated 1σ, 5-30 mm).
    from risloc_rt.studies.kernel import prepare_point, run_runs
    from risloc_rt.studies.params import complete_point

    prep = prepare_point(complete_point({"aod_deg": 10.3, "estimator": "paper", "tx_power_dbm": 0.0}))
    rows = run_runs(prep, study_seed=1, point=0, runs=[79, 80, 88, 89, 194], noise_stream="fast")
    gross = [abs(r["distance_error"]) > 0.1 for r in rows]
    flagged = ["off-detection" in r["flags"].split(",") for r in rows]
    assert all(r["detected"] for r in rows)
    assert 0 < sum(gross) < len(rows)  # both kinds are among them
    assert flagged == gross, [(r["run"], r["distance_error"], r["flags"]) for r in rows]
    assert all(abs(r["distance_error"]) < 3 * r["std_distance"] for r, g in zip(rows, gross) if not g)


def test_grating_lobe_names_grating_lobes_only_where_the_array_has_them():
    from dsp.aod_fit import AodFit
    from dsp.flags import sweep_flags

    quiet = _context()
    lobe = AodFit(aod=quiet.aod, direction_cosine=quiet.fit.direction_cosine, amplitude=1.0,
                  candidates=np.array([[np.deg2rad(-30.0), -1.0]]))

    def message(pattern):
        (flag,) = sweep_flags(dataclasses.replace(quiet, fit=lobe, pattern=pattern))
        assert flag.code == "grating-lobe"
        return flag.message

    # the period of the array factor in u is λ/(q·d): 2 for a relay at λ/2 (no second lobe in |u| <= 1),
    # 1 for a reflective RIS at λ/2 (a lobe at u ∓ 1), 1 for a relay at a pitch of λ
    assert "no grating lobe in visible space (relay, element pitch 0.50 λ)" in message(RELAY)
    assert "(reflective, element pitch 0.50 λ) has grating lobes (sin φ = sin θ ∓ 1.00)" in message(REFLECTIVE)
    wide = dsp.BeamPattern(element_spacing=RADAR.wavelength).for_wavelength(RADAR.wavelength)
    assert "(relay, element pitch 1.00 λ) has grating lobes (sin φ = sin θ ∓ 1.00)" in message(wide)
    assert "a reflective RIS with λ/2 spacing has grating lobes" in message(None)  # unknown pattern: the general cause

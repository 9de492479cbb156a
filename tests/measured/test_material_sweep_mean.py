"""The sweep-mean static peaks of ``risloc calibrate --materials`` (``risloc_rt.measured.compare.sweep_mean_peaks``).

Oracles: a Monte Carlo of the whole processing (complex mean of M noisy frames, windowed delay-Doppler map, zero-Doppler
profile) for the power σ, with the single frame's noise per bin measured from noise-only profiles (not taken from
the code's window formula); and the hall's geometry for the triple bounce wall_0 > wall_1 > wall_2 (its image through
the three walls lies 60 m from the radar at (6, 9), so its round trip is 60 m) and 10 log10 M for the SNR gain.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from dsp import SPEED_OF_LIGHT, ProcessingConfig, RadarConfig, delay_doppler_map
from risloc_rt.measured.compare.sweep_mean_peaks import sweep_mean_power_sigma_db, sweep_mean_profile


def test_sweep_mean_peak_power_sigma_matches_a_monte_carlo_of_the_processing():
    radar = RadarConfig(num_samples=64, num_chirps=16, sample_rate=2e6, bandwidth=1e9, chirp_duration=40e-6)
    proc = ProcessingConfig(n_dft=128, k_dft=16)
    rng = np.random.default_rng(23)
    beams, k, n = 61, radar.num_chirps, radar.num_samples
    t = np.arange(n)
    static = 0.003 * np.exp(-2j * np.pi * (12 / 64) * t)[None, :] * np.ones((k, 1))     # the same in every beam
    varying = 3.0 * np.exp(-2j * np.pi * (40 / 64) * t)[None, :] * np.ones((k, 1))     # a beam-dependent echo elsewhere
    noise = 1e-3                                                                        # σ² per sample [counts²]
    clean = delay_doppler_map(static, radar, proc).profile(0.0)
    at = int(np.argmax(clean))
    power = float(clean[at])
    floor = np.mean([np.mean(delay_doppler_map(np.sqrt(noise / 2) * (rng.standard_normal((k, n)) + 1j * rng.standard_normal(
        (k, n))), radar, proc).profile(0.0)) for _ in range(200)])                      # one frame's noise per bin
    reads = []
    for _ in range(800):
        phases = np.exp(2j * np.pi * rng.random(beams))[:, None, None]
        cube = static[None] + phases * varying[None] + np.sqrt(noise / 2) * (
            rng.standard_normal((beams, k, n)) + 1j * rng.standard_normal((beams, k, n)))
        prof = sweep_mean_profile(cube, radar, proc)
        reads.append(10 * np.log10(prof[at]))
    snr_db = 10 * math.log10(power / floor)
    sigma = sweep_mean_power_sigma_db(power, floor, beams)
    spread = float(np.std(reads, ddof=1))
    print(f"single-frame SNR {snr_db:.1f} dB; sigma {sigma:.3f} dB by the formula, {spread:.3f} dB over 800 draws; "
          f"one frame's {sweep_mean_power_sigma_db(power, floor, 1):.3f} dB")
    assert 0 < snr_db < 12                                  # a peak the single frame's thresholds would not keep
    assert spread == pytest.approx(sigma, rel=0.10)         # 800 draws: the std is known to 2.5 %
    # the mean's noise floor is the single frame's over M
    mean_floor = np.mean([np.mean(sweep_mean_profile(np.sqrt(noise / 2) * (rng.standard_normal((beams, k, n)) + 1j
                                                                           * rng.standard_normal((beams, k, n))),
                                                     radar, proc)) for _ in range(20)])
    assert mean_floor == pytest.approx(floor / beams, rel=0.05)
    assert sweep_mean_power_sigma_db(power, floor, beams, 0.3) == pytest.approx(math.hypot(sigma, 0.3))
    with pytest.raises(ValueError, match="beams"):
        sweep_mean_power_sigma_db(power, floor, 0)


def test_repeats_lower_the_mean_floor_by_their_count_and_a_common_phase_does_not_matter():
    """Repeats (captures of the same sweep from the same place): the joint mean's noise floor is one frame's over
    C·M (measured from noise-only draws); a repeat recorded with a common phase turn (a radar's phase drift between
    recordings) gives the joint mean of the unturned one to float precision (the strong static echo sets the turn);
    cubes of another shape are refused in one line."""
    from risloc_rt.measured.compare.sweep_mean_peaks import joint_mean_frame

    radar = RadarConfig(num_samples=64, num_chirps=16, sample_rate=2e6, bandwidth=1e9, chirp_duration=40e-6)
    proc = ProcessingConfig(n_dft=128, k_dft=16)
    rng = np.random.default_rng(29)
    beams, k, n, noise, repeats = 61, radar.num_chirps, radar.num_samples, 1e-3, 4

    def noisy():
        return np.sqrt(noise / 2) * (rng.standard_normal((beams, k, n)) + 1j * rng.standard_normal((beams, k, n)))

    t = np.arange(n)
    static = 0.5 * np.exp(-2j * np.pi * (12 / 64) * t)[None, None, :] * np.ones((beams, k, 1))  # sets the alignment
    far = slice(64, 128)  # profile bins far from the echo's (24 of 128): noise only
    # one draw's mean over those bins scatters by 23 % (the window correlates them): 200 draws know each mean to
    # 1.6 %, their ratio to 2.3 %; 8 % is 3.5 of that
    floor = np.mean([np.mean(sweep_mean_profile(static + noisy(), radar, proc)[far]) for _ in range(200)])
    joint = np.mean([np.mean(sweep_mean_profile([static + noisy() for _ in range(repeats)], radar, proc)[far])
                     for _ in range(200)])
    assert joint == pytest.approx(floor / repeats, rel=0.08)
    a, b = static + noisy(), static + noisy()
    plain = joint_mean_frame([a, b])
    turned = joint_mean_frame([a, b * np.exp(1.1j)])
    np.testing.assert_allclose(turned, plain, rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="shapes differ") as err:
        joint_mean_frame([a, b[:, :8]])
    assert "\n" not in str(err.value)


@pytest.mark.slow
def test_a_static_triple_bounce_enters_the_sweep_mean_observation(tmp_path):
    from risloc_rt.hall.raytrace.tracer import TraceSettings
    from risloc_rt.hall.scenario import hall_paths, hall_scenario
    from risloc_rt.measured import RecordingPlan, dca1000_radar, emulate_recording, import_capture
    from risloc_rt.measured.compare.material_peaks import capture_observation
    from risloc_rt.measured.compare.sweep_mean_peaks import sweep_mean_observation
    from risloc_rt.measured.compare.traced_hall import hall_model

    settings = TraceSettings(max_depth=3, samples_per_src=20000)
    hs = hall_scenario("paper_hall", radar_index=0, radar=dca1000_radar(RadarConfig()), trace=settings)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        traced = hall_paths(hs)
    plan = RecordingPlan(lead_frames=3.0, sync_on=2, sync_off=2, sync_cycles=2, sync_gap=1, tail_frames=2)
    rec = emulate_recording(hs.base, tmp_path / "rec", plan=plan, paths=traced.paths, rng=np.random.default_rng(23))
    exp = rec.experiment
    capture = import_capture(exp.raw_path, exp.config_path, exp.schedule_path,
                             first_frame=round(rec.start))
    model = hall_model(capture, "paper_hall", capture.truth.ue_position, trace=settings)
    mean = sweep_mean_observation(capture, model, ["concrete-200mm"], settings=settings, model_sigma_db=0.0)
    best = capture_observation(capture, model, ["concrete-200mm"], settings=settings, model_sigma_db=0.0,
                               comparison=mean.comparison)
    labels = [u["label"] for u in mean.used]
    print("sweep mean:", [(u["label"], round(u["snr_db"], 1), round(u["sigma_db"], 3)) for u in mean.used])
    print("best beam:", [(u["label"], round(u["snr_db"], 1), round(u["sigma_db"], 3)) for u in best.used])
    print("left out:", mean.left_out)
    triple = [u for u in mean.used if u["label"].count(">") == 2 and "wall_1" in u["label"]]
    assert triple, labels
    assert abs(triple[0]["delay_s"] * SPEED_OF_LIGHT / 2 - 30.0) <= 5e-3    # its image 60 m away: a 60 m round trip
    # no RIS path and not the panel's structural echo; the panel's echo is left out with its reason
    assert all(label.startswith("hall:") for label in labels)
    assert any("structural echo" in why for _, why in mean.left_out)
    # the wall_1 echo in both: the mean's SNR is the best beam's plus 10 log10(61) = 17.9 dB, its sigma sqrt(61) smaller
    w_mean = next(u for u in mean.used if u["label"] == "hall: specular:wall_1")
    w_best = next(u for u in best.used if u["label"] == "hall: specular:wall_1")
    assert w_mean["snr_db"] - w_best["snr_db"] == pytest.approx(10 * math.log10(61), abs=1.5)
    assert mean.observation.path_weight is not None and len(mean.observation) == len(mean.used)
    # without a change of material the residuals of the mean's peaks are noise: within 4 sigma
    for u in mean.used:
        assert abs(u["power_residual_db"]) <= 4 * u["sigma_db"], u


def test_path_weights_scale_the_model_power_of_their_paths():
    """The engine's per-path weights (the antenna pattern of a capture): a constant weight is a constant offset, a path
    of weight 0 explains nothing, and a weight per path of the wrong length is refused in one line."""
    from dataclasses import replace

    from risloc_rt.hall.material_fit import fit_materials, synthetic_observations
    from risloc_rt.hall.raytrace.material_gradients import material_jacobian
    from risloc_rt.hall.raytrace.tracer import TraceSettings

    from risloc_rt.authoring.scene_folder import scene_directory

    settings = TraceSettings(max_depth=1, samples_per_src=20000)
    position = [6.0, 9.0, 1.2]
    hall = scene_directory("paper_hall")
    obs, _ = synthetic_observations(hall, [position], {"concrete-200mm": (6.1, 0.6)}, sigma_db=0.5,
                                    rng=np.random.default_rng(23), settings=settings)
    paths = material_jacobian(hall / "scene.xml", position, ["concrete-200mm"], settings=settings).paths
    kw = dict(settings=settings, max_iter=0, profile_check=False)
    plain = fit_materials(hall, obs, ["concrete-200mm"], **kw)
    c = 1e-3
    scaled = replace(obs[0], offset_db=obs[0].offsets() - 10 * math.log10(c), path_weight=np.full(len(paths.delay), c))
    assert np.allclose(fit_materials(hall, [scaled], ["concrete-200mm"], **kw).residuals_db, plain.residuals_db,
                       atol=1e-9)
    first = int(np.argmin(np.abs(paths.delay - obs[0].delay[0])))
    weight = np.ones(len(paths.delay))
    weight[np.abs(paths.delay - paths.delay[first]) < 1e-12] = 0.0
    dropped = fit_materials(hall, [replace(obs[0], path_weight=weight)], ["concrete-200mm"], **kw)
    assert len(dropped.residuals_db) == len(plain.residuals_db) - 1
    with pytest.raises(ValueError, match="path_weight has 3 entries"):
        fit_materials(hall, [replace(obs[0], path_weight=np.ones(3))], ["concrete-200mm"], **kw)
    with pytest.raises(ValueError, match="path_weight must be finite and >= 0"):
        replace(obs[0], path_weight=-np.ones(len(paths.delay)))

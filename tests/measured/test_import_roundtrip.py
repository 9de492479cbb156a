"""End to end: simulate -> DCA1000 folder (raw, .cfg, sweep.toml) -> risloc capture import -> locate.

A small radar (N = 128 samples, K = 16 chirps) keeps it fast; the analytic scenario is the truth.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from dsp import ProcessingConfig, RadarConfig
from risloc_rt.cli import main
from risloc_rt.io.capture_file import load_capture
from risloc_rt.io.report import process_capture
from risloc_rt.measured import (AdcImpairments, Recording, dca1000_radar, emulate_capture, format_sweep_schedule,
                                import_capture, parse_sweep_schedule, read_sdk_cfg, read_sweep_schedule,
                                write_raw_capture)
from risloc_rt.measured.emulate.experiment import full_scale
from risloc_rt.model.builder import analytic_scenario
from risloc_rt.model.simulate import simulate

DISTANCE, AOD_DEG = 9.3, (17.2, 0.0)


@pytest.fixture(scope="module")
def experiment(tmp_path_factory):
    radar = dca1000_radar(RadarConfig(num_samples=128, num_chirps=16))
    processing = ProcessingConfig(n_dft=255, k_dft=64)
    scenario = analytic_scenario(distance=DISTANCE, aod=np.deg2rad(AOD_DEG), radar=radar, processing=processing)
    capture = simulate(scenario, rng=np.random.default_rng(5))
    folder = tmp_path_factory.mktemp("exp") / "dca"
    return capture, emulate_capture(capture, folder)


def _import(exp, out, *extra: str) -> int:
    return main(["capture", "import", str(exp.raw_path), "--config", str(exp.config_path),
                 "--sweep", str(exp.schedule_path), "-o", str(out), *extra])


def test_round_trip_recovers_distance_and_aod(experiment, tmp_path, capsys):
    sim, exp = experiment
    out = tmp_path / "imported.npz"
    assert _import(exp, out, "--leakage", "none") == 0        # the cube as recorded, compared below
    summary = capsys.readouterr().out.strip()
    assert summary.count("\n") == 1 and "61 beams" in summary and "distance 9.3000 m" in summary
    assert "alignment manual: first frame 0" in summary and "leakage removal: none" in summary
    cap = load_capture(out)
    M, K, N = sim.cube.shape
    assert cap.cube.shape == (M, K, N) and cap.cube.dtype == np.complex128
    np.testing.assert_array_equal(cap.frame_index, np.arange(M))
    np.testing.assert_allclose(cap.sweep.angles, sim.sweep.angles, atol=1e-12)
    assert cap.processing.n_dft == 2 * N - 1 and cap.processing.k_dft == 64
    assert cap.radar.slope == pytest.approx(sim.radar.slope, rel=1e-9)   # dca1000_radar put it on the device step
    assert cap.radar.num_samples == N and cap.radar.num_chirps == K and cap.radar.sample_rate == sim.radar.sample_rate
    assert cap.ris.mode == sim.ris.mode and cap.ris.loopback_delay == pytest.approx(sim.ris.loopback_delay)
    np.testing.assert_allclose(cap.ris.pose.normal, sim.ris.pose.normal, atol=1e-12)
    prov = cap.provenance
    assert prov["source"] == "measurement" and len(prov["raw_files"][0]["sha256"]) == 64
    assert prov["config"]["text"].startswith("%") and "frames_per_beam = 1" in prov["schedule"]
    assert prov["reader"]["dropped_packets"] == [] and prov["reader"]["truncated_bytes"] == 0
    # each beam's chirps: frame m, chirps 0..K-1; the given first frame agrees with the recording (no flag)
    assert prov["alignment"]["beam_chirps"] == [[[m, 0, K]] for m in range(M)]
    assert prov["alignment"]["check"]["mismatch"] is False and prov["import_flags"] == []
    assert cap.truth.distance == pytest.approx(DISTANCE, abs=1e-9)
    np.testing.assert_allclose(np.rad2deg(cap.truth.aod), AOD_DEG, atol=1e-9)

    # The imported cube is the simulated one in ADC counts (noise at a few LSB, quantization below it).
    counts = 2.0 ** 15 / full_scale(sim.radar)
    resid = cap.cube - sim.cube * counts
    assert np.std(resid) < 0.5 and 2.0 < np.std(sim.cube * counts) < 5.0

    loc, _ = process_capture(cap)
    grid_step = cap.radar.range_resolution * N / cap.processing.n_dft
    step_deg = 1.5
    d_err, az_err = loc.distance - DISTANCE, np.rad2deg(loc.aod[0]) - AOD_DEG[0]
    print(f"round trip: distance error {d_err * 1e3:+.2f} mm (grid step {grid_step * 1e3:.1f} mm), "
          f"AoD error {az_err:+.3f} deg (sweep step {step_deg} deg)")
    assert abs(d_err) <= 2 * grid_step
    assert abs(az_err) <= step_deg
    paper, _ = process_capture(cap, estimator="paper")                  # the seed paper's grid method
    assert abs(paper.distance - DISTANCE) <= 2 * grid_step and abs(np.rad2deg(paper.aod[0]) - AOD_DEG[0]) <= step_deg
    assert main(["locate", str(out)]) == 0


def test_first_frame_and_frames_per_beam_select_the_first_frame_of_each_beam(experiment, tmp_path):
    sim, exp = experiment
    M = sim.cube.shape[0]
    lead, fpb = 3, 2
    junk = np.full_like(sim.cube[:1], 0.05 * full_scale(sim.radar))
    frames = [junk] * lead
    for m in range(M):
        frames += [sim.cube[m:m + 1], junk]
    cube = np.concatenate(frames)[:, :, None, :]
    cfg = read_sdk_cfg(exp.config_path).config
    folder = tmp_path / "rec"
    folder.mkdir()
    raw = write_raw_capture(cube, cfg, folder, impairments=AdcImpairments(full_scale=full_scale(sim.radar)))
    sched = replace(read_sweep_schedule(exp.schedule_path), first_frame=lead, frames_per_beam=fpb)
    cap = import_capture(raw.files[0], raw.cfg_path, sched)
    direct = import_capture(exp.raw_path, exp.config_path, exp.schedule_path)
    np.testing.assert_array_equal(cap.frame_index, lead + fpb * np.arange(M))
    np.testing.assert_array_equal(cap.cube, direct.cube)
    assert cap.radar.frames_per_beam == fpb


def test_simulate_dca1000_cli_writes_the_experiment_folder(tmp_path, capsys):
    folder = tmp_path / "exp"
    argv = ["simulate", "--distance", "8", "--aod", "10,0", "--no-noise", "--format", "dca1000", "-o", str(folder)]
    assert main(argv) == 0
    assert "adc_data_Raw_0.bin" in capsys.readouterr().out
    assert sorted(p.name for p in folder.iterdir() if not p.name.startswith(".")) == \
        ["adc_data.cfg", "adc_data_Raw_0.bin", "sweep.toml"]
    cfg = read_sdk_cfg(folder / "adc_data.cfg").config
    assert (cfg.num_samples, cfg.num_loops, cfg.num_frames, cfg.num_rx) == (600, 128, 61, 1)
    assert cfg.loop_period == pytest.approx(70e-6)        # Table I's 600 samples at 10 Msps need > 50 us
    sched = read_sweep_schedule(folder / "sweep.toml")
    assert sched.num_beams == 61 and sched.truth_ue_position is not None
    # never over an existing capture
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "does not overwrite" in err


def _error_line(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0, err
    return err


def test_missing_raw_file(experiment, tmp_path, capsys):
    _, exp = experiment
    assert main(["capture", "import", str(tmp_path / "adc_data_Raw_0.bin"), "--config", str(exp.config_path),
                 "--sweep", str(exp.schedule_path), "-o", str(tmp_path / "c.npz")]) == 2
    assert "adc_data_Raw_0.bin" in _error_line(capsys)
    assert not (tmp_path / "c.npz").exists()


def _late(text: str) -> str:
    return format_sweep_schedule(replace(parse_sweep_schedule(text), first_frame=4))


@pytest.mark.parametrize("edit, message", [
    (lambda text: text.replace("frames_per_beam", "frame_per_beam"), "did you mean 'frames_per_beam'"),
    (_late, "holds 61 whole frame(s) but the sweep schedule needs 65"),
    (lambda text: text.replace("first_frame = 0", 'first_frame = "later"'), "first_frame = 'later' must be an integer >= 0"),
], ids=["misspelt-key", "too-few-frames", "bad-first-frame"])
def test_bad_schedules_are_one_line_errors(experiment, tmp_path, capsys, edit, message):
    _, exp = experiment
    path = tmp_path / "sweep.toml"
    path.write_text(edit(exp.schedule_path.read_text()))
    assert main(["capture", "import", str(exp.raw_path), "--config", str(exp.config_path), "--sweep", str(path),
                 "-o", str(tmp_path / "c.npz")]) == 2
    assert message in _error_line(capsys)
    assert not (tmp_path / "c.npz").exists()


def test_lanes_and_iq_swap_flags_reach_the_reader(experiment, tmp_path, capsys):
    sim, exp = experiment
    cfg = read_sdk_cfg(exp.config_path).config
    folder = tmp_path / "swapped"
    folder.mkdir()
    raw = write_raw_capture(sim.cube[:, :, None, :], cfg, folder, recording=Recording(lanes=4, iq_swap=True),
                            impairments=AdcImpairments(full_scale=full_scale(sim.radar)))
    base = ["capture", "import", str(raw.files[0]), "--config", str(raw.cfg_path), "--sweep", str(exp.schedule_path)]
    assert main([*base, "-o", str(tmp_path / "a.npz"), "--lanes", "4", "--iq-swap"]) == 0
    assert main([*base, "-o", str(tmp_path / "b.npz")]) == 0            # read as 2 lanes, I first: scrambled
    direct = import_capture(exp.raw_path, exp.config_path, exp.schedule_path)
    np.testing.assert_array_equal(load_capture(tmp_path / "a.npz").cube, direct.cube)
    assert not np.array_equal(load_capture(tmp_path / "b.npz").cube, direct.cube)
    prov = load_capture(tmp_path / "a.npz").provenance["reader"]
    assert prov["lanes"] == 4 and prov["iq_swap"] is True


def test_dropped_packets_are_reported_and_the_sweep_still_localizes(experiment, tmp_path):
    sim, _ = experiment
    exp = emulate_capture(sim, tmp_path / "lossy", dropped_packets_rate=0.003, rng=np.random.default_rng(3))
    assert exp.raw.dropped_sequences
    cap = import_capture(exp.raw_path, exp.config_path, exp.schedule_path)
    reader = cap.provenance["reader"]
    assert reader["form"] == "packets" and reader["dropped_packets"] and reader["damaged_beams"]
    assert sum(d["count"] for d in reader["dropped_packets"]) == len(exp.raw.dropped_sequences)
    loc, _ = process_capture(cap)
    assert abs(np.rad2deg(loc.aod[0]) - AOD_DEG[0]) <= 1.5

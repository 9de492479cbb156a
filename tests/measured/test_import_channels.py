"""Import with several virtual channels: maximal-ratio combining on the RIS return."""

from __future__ import annotations

import numpy as np
import pytest

from dsp import ProcessingConfig, RadarConfig
from risloc_rt.io.report import process_capture
from risloc_rt.measured import (AdcImpairments, TiChirpConfig, dca1000_radar, emulate_capture, import_capture,
                                write_raw_capture)
from risloc_rt.measured.emulate.experiment import ADC_START_TIME, RAMP_MARGIN, full_scale
from risloc_rt.model.builder import analytic_scenario
from risloc_rt.model.simulate import simulate


def test_four_channels_combine_coherently_and_halve_the_noise(tmp_path):
    radar = dca1000_radar(RadarConfig(num_samples=128, num_chirps=16))
    scenario = analytic_scenario(distance=9.3, aod=np.deg2rad((17.2, 0.0)), radar=radar,
                                 processing=ProcessingConfig(n_dft=255, k_dft=64))
    clean = simulate(scenario, rng=np.random.default_rng(0), noise=False)
    exp = emulate_capture(clean, tmp_path / "one")                        # for its sweep.toml
    phase = np.exp(2j * np.pi * np.array([0.0, 0.31, 0.62, 0.17]))       # uncalibrated channel phases
    rng = np.random.default_rng(1)
    sigma = np.sqrt(radar.noise_power / 2)
    cube = clean.cube[:, :, None, :] * phase[None, None, :, None]
    cube = cube + sigma * (rng.standard_normal(cube.shape) + 1j * rng.standard_normal(cube.shape))
    cfg = TiChirpConfig.from_radar(radar, rx_mask=0b1111, tx_order=(0b001,), adc_start_time=ADC_START_TIME,
                                   ramp_margin=RAMP_MARGIN, num_frames=cube.shape[0], adc_format="complex1x")
    folder = tmp_path / "four"
    folder.mkdir()
    raw = write_raw_capture(cube, cfg, folder, impairments=AdcImpairments(full_scale=full_scale(radar)))
    counts = 2.0 ** 15 / full_scale(radar)
    one = import_capture(raw.files[0], raw.cfg_path, exp.schedule_path, leakage="none")
    mrc = import_capture(raw.files[0], raw.cfg_path, exp.schedule_path, leakage="none", channels=[0, 1, 2, 3])
    assert mrc.provenance["channels"] == {"channels": [0, 1, 2, 3], "combine": "mrc",
                                          "weights": mrc.provenance["channels"]["weights"]}
    # Channel phases undone: the combined cube is channel 0's signal; noise falls by sqrt(4) (equal gains).
    ref = clean.cube * counts
    noise_one = np.std(one.cube - ref)
    noise_mrc = np.std(mrc.cube - ref)
    print(f"noise: one channel {noise_one:.3f} LSB, 4-channel MRC {noise_mrc:.3f} LSB")
    assert noise_mrc == pytest.approx(noise_one / 2, rel=0.1)
    loc, _ = process_capture(mrc)
    assert abs(loc.distance - 9.3) < 0.02 and abs(np.rad2deg(loc.aod[0]) - 17.2) < 1.5
    with pytest.raises(ValueError, match="must be distinct virtual channel indices"):
        import_capture(raw.files[0], raw.cfg_path, exp.schedule_path, channels=[1, 1])

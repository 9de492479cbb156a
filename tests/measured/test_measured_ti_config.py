"""TI chirp description → dsp.RadarConfig: slope, chirp spacing, carrier; quantized slope; timing checks."""

from __future__ import annotations

import dsp
import pytest

from risloc_rt.measured import MeasuredFormatError, TiChirpConfig, slope_step


def test_ramp_sets_the_slope_and_the_tdm_loop_the_slow_time_period(make_config):
    cfg = make_config()
    radar = cfg.to_radar_config(quantize_slope=False)
    t_loop = 2 * (7e-6 + 24e-6)                                  # two TDM chirps of idle + ramp
    assert radar.chirp_duration == pytest.approx(24e-6)           # the ramp
    assert radar.bandwidth == pytest.approx(60e12 * 24e-6)        # the swept RF bandwidth
    assert radar.chirp_interval == pytest.approx(t_loop)
    assert radar.slope == pytest.approx(60e12, rel=1e-12)         # S = B/T preserved
    assert radar.carrier_frequency == 60.25e9
    assert (radar.num_samples, radar.sample_rate, radar.num_chirps) == (32, 2e6, 8)
    # unambiguous velocity λ/(4 T_loop): the TDM loop, not one chirp
    assert radar.max_velocity == pytest.approx(dsp.SPEED_OF_LIGHT / 60.25e9 / (4 * t_loop))


def test_centre_carrier(make_config):
    cfg = make_config()
    radar = cfg.to_radar_config(carrier="center", quantize_slope=False)
    assert radar.bandwidth == pytest.approx(60e12 * 24e-6)
    assert radar.carrier_frequency == pytest.approx(60.25e9 + 60e12 * (6e-6 + 8e-6))


def test_slope_is_quantized_to_the_60ghz_step(make_config):
    step = slope_step(60e9)
    assert step == pytest.approx(36.2097e9, rel=1e-5)             # 2.7e9·900/2^26 Hz per µs
    assert slope_step(77e9) == pytest.approx(48.2797e9, rel=1e-5)
    cfg = make_config(slope=64.985e12)
    q = cfg.quantized_slope
    assert abs(q - 64.985e12) <= step / 2 and (q / step) == pytest.approx(round(q / step), abs=1e-9)
    assert cfg.to_radar_config().slope == pytest.approx(q, rel=1e-12)


def test_device_issues(make_config):
    assert make_config().device_issues() == ()
    long_adc = make_config(num_samples=64)                        # 32 µs of samples in an 18 µs window
    assert any("outside the ramp" in s for s in long_adc.device_issues())
    assert any("device band" in s for s in make_config(start_frequency=63.9e9).device_issues())
    assert any("frame period" in s for s in make_config(frame_periodicity=1e-4).device_issues())


def test_from_radar_round_trip(make_config):
    radar = dsp.RadarConfig(num_samples=64, sample_rate=4e6, num_chirps=16, chirp_duration=100e-6, bandwidth=3e9)
    cfg = TiChirpConfig.from_radar(radar, tx_order=(1, 4))
    back = cfg.to_radar_config(quantize_slope=False)
    assert back.slope == pytest.approx(radar.slope) and back.chirp_interval == pytest.approx(radar.chirp_interval)
    with pytest.raises(MeasuredFormatError, match="less than the ramp"):
        TiChirpConfig.from_radar(dsp.RadarConfig())                # Table I: 60 µs of samples in a 50 µs chirp


def test_validation_names_the_field(make_config):
    with pytest.raises(MeasuredFormatError, match="adc_bits=13"):
        make_config(adc_bits=13)
    with pytest.raises(MeasuredFormatError, match="outside the enabled tx_mask"):
        make_config(tx_mask=0b001)

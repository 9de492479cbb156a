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
    # the carrier is the centre of the ADC window, f0 + S·(adc_start + N/(2 fs)) = 60.25 GHz + 60 MHz/µs · 14 µs
    fc = 60.25e9 + 60e12 * (6e-6 + 32 / 2e6 / 2)
    assert fc == pytest.approx(61.09e9)
    assert radar.carrier_frequency == pytest.approx(fc, rel=1e-15)
    assert (radar.num_samples, radar.sample_rate, radar.num_chirps) == (32, 2e6, 8)
    # unambiguous velocity λ/(4 T_loop) at that carrier: the TDM loop, not one chirp
    assert radar.max_velocity == pytest.approx(dsp.SPEED_OF_LIGHT / fc / (4 * t_loop))


def test_start_carrier_on_request(make_config):
    cfg = make_config()
    radar = cfg.to_radar_config(carrier="start", quantize_slope=False)
    assert radar.bandwidth == pytest.approx(60e12 * 24e-6)
    assert radar.carrier_frequency == 60.25e9


def test_slope_is_truncated_to_the_60ghz_step_as_ti_firmware_does(make_config):
    # mmWave SDK CLI: freqSlopeConst = (int)(S[MHz/us] * 2^26 / (2.7e3 * 900)) for 60 GHz parts
    # (3.6e3 for 77 GHz): a C cast, i.e. truncation. Table I's 68.69 MHz/us is 1896.9991 steps -> 1896.
    step = slope_step(60e9)
    assert step == pytest.approx(36.2097e9, rel=1e-5)             # 2.7e9·900/2^26 Hz per µs
    assert slope_step(77e9) == pytest.approx(48.2797e9, rel=1e-5)
    cfg = make_config(slope=68.69e12)
    assert cfg.quantized_slope == pytest.approx(1896 * 2.7e3 * 900 / 2**26 * 1e12, rel=1e-13)
    assert cfg.quantized_slope == pytest.approx(68.6538e12, abs=0.0001e12)   # not 68.6900 (rounding)
    assert cfg.to_radar_config().slope == pytest.approx(cfg.quantized_slope, rel=1e-12)
    # a value written back from an exact multiple of the step keeps its step count
    exact = make_config(slope=1896 * step)
    assert exact.quantized_slope == pytest.approx(1896 * step, rel=1e-13)
    assert make_config(slope=1896 * step * (1 - 1e-5)).quantized_slope == pytest.approx(1895 * step, rel=1e-13)


def test_start_frequency_is_truncated_to_its_step(make_config):
    # startFreqConst = (int)(f[GHz] * 2^26 / 2.7): 60.25 GHz is 1497521872.59 steps -> 1497521872
    cfg = make_config()
    f_q = 1497521872 * 2.7e9 / 2**26
    assert cfg.quantized_start_frequency == pytest.approx(f_q, abs=1e-3)
    assert 60.25e9 - cfg.quantized_start_frequency == pytest.approx(23.8, abs=0.1)   # Hz
    radar = cfg.to_radar_config()
    assert radar.carrier_frequency == pytest.approx(f_q + cfg.quantized_slope * (6e-6 + 8e-6), abs=1e-3)


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
    assert back.carrier_frequency == pytest.approx(radar.carrier_frequency, rel=1e-15)   # the ADC window's centre
    assert cfg.start_frequency == pytest.approx(60e9 - radar.slope * (6e-6 + 64 / 4e6 / 2), rel=1e-15)
    with pytest.raises(MeasuredFormatError, match="less than the ramp"):
        TiChirpConfig.from_radar(dsp.RadarConfig())                # Table I: 60 µs of samples in a 50 µs chirp


def test_validation_names_the_field(make_config):
    with pytest.raises(MeasuredFormatError, match="adc_bits=13"):
        make_config(adc_bits=13)
    with pytest.raises(MeasuredFormatError, match="outside the enabled tx_mask"):
        make_config(tx_mask=0b001)

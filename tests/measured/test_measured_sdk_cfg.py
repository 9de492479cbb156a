"""mmWave SDK .cfg: fields in SI, TDM order, round trip, and errors that name the line."""

from __future__ import annotations

import pytest

from risloc_rt.measured import MeasuredFormatError, format_sdk_cfg, parse_sdk_cfg



def test_fields_are_mapped_to_si_units(cfg_text):
    cfg = parse_sdk_cfg(cfg_text).config
    assert cfg.start_frequency == pytest.approx(60.25e9, rel=1e-15)
    assert cfg.slope == pytest.approx(64.985e12, rel=1e-15)                    # MHz/µs -> Hz/s
    assert (cfg.idle_time, cfg.adc_start_time, cfg.ramp_end_time) == pytest.approx((7e-6, 6e-6, 60e-6))
    assert cfg.tx_start_time == pytest.approx(1e-6)
    assert cfg.sample_rate == 5e6 and cfg.num_samples == 256
    assert (cfg.num_loops, cfg.num_frames, cfg.frame_periodicity) == (64, 8, pytest.approx(0.040))
    assert (cfg.rx_mask, cfg.tx_mask, cfg.num_rx, cfg.num_virtual) == (15, 7, 4, 12)
    assert cfg.adc_bits == 16 and cfg.adc_format == "complex1x" and cfg.iq_swap
    # TDM order follows chirpCfg (TX0, TX2, TX1), not the pin numbers
    assert cfg.tx_order == (0b001, 0b100, 0b010)


def test_skipped_commands_are_listed_with_line_numbers(cfg_text):
    parsed = parse_sdk_cfg(cfg_text)
    assert (2, "sensorStop") in parsed.skipped and (15, "cfarCfg") in parsed.skipped


def test_write_then_parse_gives_the_same_config(cfg_text):
    cfg = parse_sdk_cfg(cfg_text).config
    text = format_sdk_cfg(cfg, comment="round trip")
    assert text.startswith("% round trip\n")
    assert parse_sdk_cfg(text).config == cfg
    # the writer judged by the hand-written file, not by its own parser: every mapped command, field by field
    wanted = [ln for ln in cfg_text.splitlines() if ln.split()[0] in
              ("dfeDataOutputMode", "channelCfg", "adcCfg", "adcbufCfg", "profileCfg", "chirpCfg", "frameCfg")]
    written = [ln for ln in text.splitlines() if ln.split()[0] in
               ("dfeDataOutputMode", "channelCfg", "adcCfg", "adcbufCfg", "profileCfg", "chirpCfg", "frameCfg")]
    assert written == wanted


@pytest.mark.parametrize("old, new, match", [
    ("frameCfg 0 2 64 8 40 1 0", "frameCfg 0 2 64 8 40 1 0 0", r":13: frameCfg takes 7 arguments .* got 8 .*MCU\+ SDK"),
    ("cfarCfg", "cfarCfgg", r":15: unknown command 'cfarCfgg'"),
    ("chirpCfg 2 2 0 0 0 0 0 2", "chirpCfg 2 2 0 0 0 0 0 8", r":12: chirpCfg txEnable=0b1000 .*channelCfg \(line 5\)"),
    ("frameCfg 0 2 64", "frameCfg 0 3 64", r":13: frameCfg uses chirp 3, which no chirpCfg defines"),
    ("adcbufCfg -1 0 1 1 1", "adcbufCfg -1 1 1 1 1", r":7: adcbufCfg says real samples but adcCfg \(line 6\)"),
    ("lowPower 0 0", "channelCfg 15 7 0", r":8: channelCfg given again \(first at line 5\)"),
    ("profileCfg 0 60.25 7", "profileCfg 0 60.x5 7", r":9: startFreq='60.x5' is not a number"),
    ("adcCfg 2 1", "adcCfg 2 3", r":6: adcCfg adcOutputFmt=3"),
    ("chirpCfg 1 1 0", "chirpCfg 1 1 1", r":11: chirpCfg uses profile 1, which no profileCfg defines"),
])
def test_errors_name_the_line(old, new, match, cfg_text):
    with pytest.raises(MeasuredFormatError, match=match):
        parse_sdk_cfg(cfg_text.replace(old, new, 1), source="x.cfg")


def test_missing_command_and_lenient_mode(cfg_text):
    with pytest.raises(MeasuredFormatError, match="no frameCfg line"):
        parse_sdk_cfg("\n".join(ln for ln in cfg_text.splitlines() if not ln.startswith("frameCfg")))
    parsed = parse_sdk_cfg(cfg_text.replace("cfarCfg", "myVendorCmd"), strict=False)
    assert (15, "myVendorCmd") in parsed.skipped


def test_error_is_one_line_and_a_value_error(cfg_text):
    with pytest.raises(ValueError) as info:
        parse_sdk_cfg(cfg_text.replace("adcCfg 2 1", "adcCfg 2"))
    assert "\n" not in str(info.value) and ":6: adcCfg takes 2 arguments" in str(info.value)


@pytest.mark.parametrize("line, message", [
    ("chirpCfg 0 60e9 0 0 0 0 0 1", "must lie in 0…511"),      # found by fuzzing: 6e10 chirps hung the parser
    ("chirpCfg -3 0 0 0 0 0 0 1", "must lie in 0…511"),
])
def test_chirp_indices_are_bounded_before_anything_is_built(line, message):
    from risloc_rt.measured import TiChirpConfig
    import dsp

    text = format_sdk_cfg(TiChirpConfig.from_radar(dsp.RadarConfig(num_samples=32, num_chirps=8)))
    bad = "\n".join(line if ln.startswith("chirpCfg") else ln for ln in text.splitlines())
    with pytest.raises(MeasuredFormatError, match=message):
        parse_sdk_cfg(bad)


def test_loop_count_is_bounded():
    from risloc_rt.measured import TiChirpConfig
    import dsp

    text = format_sdk_cfg(TiChirpConfig.from_radar(dsp.RadarConfig(num_samples=32, num_chirps=8)))
    bad = "\n".join("frameCfg 0 0 100000 3 0.4 1 0" if ln.startswith("frameCfg") else ln for ln in text.splitlines())
    with pytest.raises(MeasuredFormatError, match=r"numLoops=100000 must be 1…255"):
        parse_sdk_cfg(bad)


# ----------------------------------------------------------------------------- SampleSwap (issue 20)
CORNER = __import__("pathlib").Path(__file__).resolve().parents[2].parent / "shared" / "captures" / \
    "iwr6843_corner_reflector" / "adc_data_Raw_0.bin"


def test_sample_swap_must_be_0_or_1(cfg_text):
    assert not parse_sdk_cfg(cfg_text.replace("adcbufCfg -1 0 1 1 1", "adcbufCfg -1 0 0 1 1")).config.iq_swap
    with pytest.raises(MeasuredFormatError, match=r":7: adcbufCfg sampleSwap=2 must be 0 \(I in LSB\) or 1"):
        parse_sdk_cfg(cfg_text.replace("adcbufCfg -1 0 1 1 1", "adcbufCfg -1 0 2 1 1"), source="x.cfg")


@pytest.mark.skipif(not CORNER.is_file(), reason="shared corner-reflector capture absent")
def test_sdk_sample_swap_is_the_adc_buffer_order_not_the_files(cfg_text, tmp_path):
    """mmWave SDK user's guide: SampleSwap 1 = "Q in LSB, I in MSB" of the ADC buffer (the only value the demos
    accept). The corner-reflector capture (IWR6843, 3 Tx x 4 Rx, 256 samples, 64 loops) has I first: read with the
    SDK cfg's flag recorded but not applied, it peaks at bin 38 with no iq-order flag; applying the flag would
    mirror it to 256 - 38."""
    from risloc_rt.measured.dca1000 import file_iq_swap, inspect_capture

    path = tmp_path / "iwr6843.cfg"
    path.write_text(cfg_text.replace("frameCfg 0 2 64 8 40 1 0", "frameCfg 0 2 64 1 40 1 0"))
    assert file_iq_swap(path) is False and file_iq_swap(path, iq_swap=True) is True
    result = inspect_capture(CORNER, path)
    assert result.config_iq_swap is True and result.layout.iq_swap is False
    assert result.peak.range_bin == 38 and "iq-order" not in [f.code for f in result.flags]
    applied = inspect_capture(CORNER, path, iq_swap=True)
    assert applied.peak.range_bin == 256 - 38
    flag = next(f for f in applied.flags if f.code == "iq-order")
    assert "iq_swap=False" in flag.message and "on-chip ADC buffer" in flag.message

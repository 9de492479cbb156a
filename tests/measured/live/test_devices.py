"""Device families: their figures against TI's documents, each limit's one-line error, and known configs by hand.

The expected figures are written out here from the vendor documents, not taken from the module:

- IWR6843 data sheet (SWRS219; the AOP board's SWRS237 is the same chip): "60- to 64-GHz", 4 receive
  and 3 transmit channels, IF band-pass "up to 10 MHz", LVDS: two data lanes, at most 900 Mbps
  (450 MHz DDR clock);
- AWR/IWR1843 data sheets (SWRS228): 76-81 GHz, 4 Rx, 3 Tx, IF up to 10 MHz, two LVDS lanes;
- AWR/IWR1642 data sheets (SWRS203/SWRS212): 76-81 GHz, 4 Rx, 2 Tx, IF up to 5 MHz, two LVDS lanes;
- xWR1443: four LVDS lanes (DCA1000EVM user's guide; ``dependency-facts.md``), IF 15 MHz;
- mmWaveLink ``rl_sensor.h``, ``rlProfileCfg_t.digOutSampleRate``: regular ADC mode, IF 15 MHz:
  37.5 Msps real / 18.75 complex 1x / 37.5 complex 2x; IF 10 MHz: 25 / 12.5 / 25; IF 5 MHz: 12.5 /
  6.25 / 12.5 Msps; ``numAdcSamples``: 4 Rx complex → at most 1024 samples, 4 Rx real → 2048,
  2 Rx complex → 2048, 2 Rx real → 4096 (2 bytes per real, 4 per complex sample);
- DCA1000EVM: 600 Mbps (TI E2E thread 927693), data packets of at most 1456 bytes.
"""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import pytest

from risloc_rt.measured.errors import MeasuredFormatError
from risloc_rt.measured.ti.devices import DEVICE_FAMILIES, check_device_config, device_family
from risloc_rt.measured.ti.sdk_cfg import parse_sdk_cfg

VENDOR = {  # name: (band [Hz], Rx, Tx, lanes, complex-1x max [Hz], real max [Hz], IF bandwidth [Hz])
    "IWR6843": ((60e9, 64e9), 4, 3, 2, 12.5e6, 25e6, 10e6),
    "xWR1843": ((76e9, 81e9), 4, 3, 2, 12.5e6, 25e6, 10e6),
    "xWR1642": ((76e9, 81e9), 4, 2, 2, 6.25e6, 12.5e6, 5e6),
    "xWR1443": ((76e9, 81e9), 4, 3, 4, 18.75e6, 37.5e6, 15e6),
}
#: rl_sensor.h numAdcSamples table: (receivers, complex?) -> most samples; 16384 bytes in every row.
ADC_TABLE = {(4, True): 1024, (4, False): 2048, (2, True): 2048, (2, False): 4096}

CORNER_REFLECTOR = Path("/work/shared/captures/iwr6843_corner_reflector/adc_data_Raw_0.bin")

# tests/measured/test_ti_chirp_truth.py's .cfg (one Tx, one Rx, 256 complex samples at 10 Msps, 64 loops, 20 ms)
TRUTH_CFG = """sensorStop
flushCfg
dfeDataOutputMode 1
channelCfg 1 1 0
adcCfg 2 1
adcbufCfg -1 0 1 1 1
profileCfg 0 60 16 6 34 0 0 68.69 0 256 10000 0 0 30
chirpCfg 0 0 0 0 0 0 0 1
frameCfg 0 0 64 1 20 1 0
"""
# tests/measured/conftest.py's IWR6843_3TX (3 Tx x 4 Rx TDM, 256 complex samples at 5 Msps, 64 loops, 40 ms)
TDM_CFG = """% IWR6843 3Tx x 4Rx TDM, 256 samples
sensorStop
flushCfg
dfeDataOutputMode 1
channelCfg 15 7 0
adcCfg 2 1
adcbufCfg -1 0 1 1 1
lowPower 0 0
profileCfg 0 60.25 7 6 60 0 0 64.985 1 256 5000 0 0 30
chirpCfg 0 0 0 0 0 0 0 1
chirpCfg 1 1 0 0 0 0 0 4
chirpCfg 2 2 0 0 0 0 0 2
frameCfg 0 2 64 8 40 1 0
guiMonitor -1 1 1 0 0 0 1
cfarCfg -1 0 2 8 4 3 0 15 1
sensorStart
"""
TDM_IN_BAND = TDM_CFG.replace("profileCfg 0 60.25 ", "profileCfg 0 60 ")


def _cfg(*swaps: tuple[str, str], text: str = TDM_IN_BAND):
    """The in-band TDM cfg (or ``text``) with each ``(old, new)`` replaced once, parsed."""
    for old, new in swaps:
        assert old in text, old
        text = text.replace(old, new, 1)
    return parse_sdk_cfg(text, source="x.cfg")


@pytest.mark.parametrize("name", sorted(VENDOR))
def test_family_figures_are_the_vendor_documents(name):
    band, rx, tx, lanes, cplx, real, if_bw = VENDOR[name]
    f = DEVICE_FAMILIES[name]
    assert (f.band, f.num_rx, f.num_tx, f.lvds_lanes) == (band, rx, tx, lanes)
    assert (f.max_complex_sample_rate, f.max_real_sample_rate, f.if_bandwidth) == (cplx, real, if_bw)
    assert f.max_sample_rate("complex1x") == cplx and f.max_sample_rate("complex2x") == real
    assert f.max_sample_rate("real") == real
    assert f.ethernet_rate == 600e6
    assert f.sources


def test_six_eight_four_three_lvds_lane_rate_is_the_data_sheet():
    assert DEVICE_FAMILIES["IWR6843"].max_lvds_lane_rate == 900e6      # 450 MHz DDR clock: 2 bits per cycle


@pytest.mark.parametrize("spelling, name", [
    ("IWR6843", "IWR6843"), ("iwr6843isk", "IWR6843"), ("IWR6843AOP", "IWR6843"), ("IWR6843AOPEVM", "IWR6843"),
    ("iwr6843-isk", "IWR6843"), ("xwr1843", "xWR1843"), ("AWR1843BOOST", "xWR1843"), ("IWR1843", "xWR1843"),
    ("AWR1642", "xWR1642"), ("iwr1642boost", "xWR1642"), ("xWR1642", "xWR1642"), ("IWR1443", "xWR1443"),
    ("IWR6843ISK-ODS", "IWR6843"), ("awr1642 evm", "xWR1642"), ("XWR68XX", "IWR6843"),
])
def test_usual_spellings(spelling, name):
    assert device_family(spelling).name == name


def test_unknown_device_is_one_line_listing_the_known_ones():
    with pytest.raises(MeasuredFormatError) as info:
        device_family("IWR9999")
    msg = str(info.value)
    assert "\n" not in msg and "'IWR9999'" in msg
    assert all(name in msg for name in VENDOR)


# ---------------------------------------------------------------- configs that pass, worked out by hand
def test_truth_cfg_passes_with_hand_sizes():
    check = check_device_config(parse_sdk_cfg(TRUTH_CFG), "IWR6843")
    # 256 complex samples x 1 Rx x 4 bytes (I, Q int16) = 1024 bytes/chirp; 1 chirp x 64 loops
    assert (check.lanes, check.adc_bits, check.adc_format, check.bytes_per_sample) == (2, 16, "complex1x", 4)
    assert check.bytes_per_chirp == 1024 and check.frame_bytes == 65536
    assert check.data_rate == pytest.approx(65536 / 0.020, rel=1e-12)               # 3.2768 MB/s
    assert check.ethernet_duty == pytest.approx(65536 * 8 / 0.020 / 600e6, rel=1e-12)
    # while chirping: 1024 bytes every 16 + 34 us, over 2 lanes x 900 Mbps
    assert check.burst_rate == pytest.approx(1024 / 50e-6, rel=1e-12)
    assert check.lvds_duty == pytest.approx(1024 * 8 / 50e-6 / 1.8e9, rel=1e-12)
    assert check.packets_per_frame == pytest.approx(65536 / 1456, rel=1e-12)
    assert check.lvds_header is None


def test_tdm_cfg_in_band_passes_with_hand_sizes():
    check = check_device_config(_cfg(), "iwr6843isk")
    # 256 x 4 Rx x 4 bytes = 4096 bytes/chirp; 3 chirps/loop x 64 loops = 192 chirps = 786432 bytes; 40 ms
    assert check.bytes_per_chirp == 4096 and check.frame_bytes == 786_432
    assert check.data_rate == pytest.approx(786_432 / 0.040, rel=1e-12)           # 19.6608 MB/s
    assert check.burst_rate == pytest.approx(4096 / 67e-6, rel=1e-12)             # idle 7 + ramp 60 us
    assert "IWR6843: 2 LVDS lanes, 16-bit complex1x, 4096 B/chirp, 786432 B/frame" in check.describe()


def test_the_repositorys_tdm_fixture_ramps_past_64_ghz():
    # conftest's IWR6843_3TX: 60.25 GHz + 64.985 MHz/us x 60 us = 64.149 GHz > 64 GHz: a real IWR6843 refuses
    # it at sensorStart (Error -1); the check says so before the radar does.
    with pytest.raises(MeasuredFormatError, match=r"sweep 60\.25-64\.15 GHz, outside the IWR6843's 60-64 GHz band"):
        check_device_config(parse_sdk_cfg(TDM_CFG), "IWR6843")
    # the same waveform at 77 GHz is inside the xWR1843's band
    assert check_device_config(_cfg(("profileCfg 0 60.25 ", "profileCfg 0 77 "), text=TDM_CFG), "xWR1843").frame_bytes \
        == 786_432


def test_corner_reflector_capture_matches_the_frame_size():
    # TI publishes no .cfg with this capture; its README gives 256 complex samples, 64 loops, 3 Tx x 4 Rx TDM:
    # the in-band TDM cfg has those numbers, and one frame must be the file's size.
    check = check_device_config(_cfg(), "IWR6843AOP")
    assert check.frame_bytes == 256 * 64 * 12 * 2 * 2 == 786_432
    if CORNER_REFLECTOR.exists():
        assert CORNER_REFLECTOR.stat().st_size == check.frame_bytes


def test_real_samples_and_twelve_bits():
    check = check_device_config(_cfg(("adcCfg 2 1", "adcCfg 0 0"), ("adcbufCfg -1 0 1", "adcbufCfg -1 1 1")), "IWR6843")
    assert (check.adc_bits, check.adc_format, check.bytes_per_sample, check.is_complex) == (12, "real", 2, False)
    assert check.bytes_per_chirp == 256 * 4 * 2


@pytest.mark.parametrize("rx_mask, is_complex", [(15, True), (15, False), (3, True), (3, False)])
def test_adc_buffer_is_the_rl_sensor_table(rx_mask, is_complex):
    most = ADC_TABLE[(bin(rx_mask).count("1"), is_complex)]
    fmt = [] if is_complex else [("adcCfg 2 1", "adcCfg 2 0"), ("adcbufCfg -1 0 1", "adcbufCfg -1 1 1")]
    for n, ok in ((most, True), (most + 2, False)):
        # 2 Msps, a ramp long enough for the samples (at most 2055 us), 1 MHz/us x ramp inside 60-64 GHz
        ramp = 6 + n / 2 + 1
        cfg = _cfg(("channelCfg 15 7 0", f"channelCfg {rx_mask} 7 0"), *fmt,
                   ("profileCfg 0 60 7 6 60 0 0 64.985 1 256 5000", f"profileCfg 0 60 7 6 {ramp:g} 0 0 1 1 {n} 2000"),
                   ("frameCfg 0 2 64 8 40", "frameCfg 0 2 2 8 400"))
        if ok:
            assert check_device_config(cfg, "IWR6843").bytes_per_chirp == 16384
        else:
            with pytest.raises(MeasuredFormatError, match=r"do not fit the IWR6843's 16384-byte ADC buffer"):
                check_device_config(cfg, "IWR6843")


# ---------------------------------------------------------------- each limit's one-line error
VIOLATIONS = [
    ("start below the band", "IWR6843", [("profileCfg 0 60 7", "profileCfg 0 59.9 7")],
     r"sweep 59\.9-63\.8 GHz, outside the IWR6843's 60-64 GHz band \(data sheet\)"),
    ("77 GHz on a 60 GHz chip", "IWR6843", [("profileCfg 0 60 7", "profileCfg 0 77 7")],
     r"outside the IWR6843's 60-64 GHz band"),
    ("60 GHz on a 77 GHz chip", "xWR1642", [], r"outside the xWR1642's 76-81 GHz band"),
    ("five receivers", "IWR6843", [("channelCfg 15 7 0", "channelCfg 31 7 0")],
     r"rxChannelEn=0b11111 enables receivers the IWR6843 does not have \(it has 4"),
    ("TX2 on a two-Tx chip", "xWR1642", [("profileCfg 0 60 7", "profileCfg 0 77 7")],
     r"txChannelEn=0b111 enables transmitters the xWR1642 does not have \(it has 2"),
    ("complex 1x over 12.5 Msps", "IWR6843", [("1 256 5000", "1 256 12600")],
     r"digOutSampleRate=12600 ksps exceeds the IWR6843's 12500 ksps for complex1x samples"),
    ("complex 1x over 6.25 Msps on a 1642", "xWR1642",
     [("channelCfg 15 7 0", "channelCfg 15 3 0"), ("profileCfg 0 60 7", "profileCfg 0 77 7"),
      ("1 256 5000", "1 256 6300"), ("chirpCfg 1 1 0 0 0 0 0 4", "chirpCfg 1 1 0 0 0 0 0 1")],
     r"6300 ksps exceeds the xWR1642's 6250 ksps"),
    ("chirps over the ADC buffer", "IWR6843", [("adcbufCfg -1 0 1 1 1", "adcbufCfg -1 0 1 1 5")],
     r"5 chirp\(s\) of 256 samples x 4 Rx x 4 bytes = 20480 bytes do not fit .* 16384-byte ADC buffer"),
    ("samples after the ramp", "IWR6843", [("profileCfg 0 60 7 6 60", "profileCfg 0 60 7 6 50")],
     r"ADC samples until 57\.2 us .* after the ramp ends at rampEndTime=50 us"),
    ("frame longer than its period", "IWR6843", [("frameCfg 0 2 64 8 40", "frameCfg 0 2 64 8 12")],
     r"chirps take 12\.86 ms, longer than frameCfg framePeriodicity=12 ms"),
    ("odd complex sample count on 2 lanes", "IWR6843", [("1 256 5000", "1 255 5000")],
     r"numAdcSamples=255 is odd: 2-lane complex data interleaves sample pairs"),
]


@pytest.mark.parametrize("what, family, swaps, match", VIOLATIONS, ids=[v[0] for v in VIOLATIONS])
def test_each_limit_gives_one_line(what, family, swaps, match):
    with pytest.raises(MeasuredFormatError) as info:
        check_device_config(_cfg(*swaps), family)
    msg = str(info.value)
    assert "\n" not in msg
    assert re.search(match, msg), msg


def test_ethernet_limit_by_hand():
    # 786432 bytes every 13 ms = 483.96 Mbps: inside 600 Mbps; 32 loops (6.4 ms of chirps) = 393216 bytes every
    # 5 ms... would not fit its period: 16 loops = 196608 bytes every 2.5 ms = 629.1 Mbps > 600 Mbps
    ok = check_device_config(_cfg(("frameCfg 0 2 64 8 40", "frameCfg 0 2 64 8 13")), "IWR6843")
    assert ok.ethernet_duty == pytest.approx(786_432 * 8 / 0.013 / 600e6, rel=1e-12)
    with pytest.raises(MeasuredFormatError, match=r"196608 bytes every 2\.5 ms = 629\.1 Mbps exceeds the DCA1000's "
                                                 r"600 Mbps Ethernet throughput"):
        check_device_config(_cfg(("frameCfg 0 2 64 8 40", "frameCfg 0 2 16 8 2.5")), "IWR6843")
    # the same frame against a slower link the caller names (e.g. a DCA1000 packet delay)
    with pytest.raises(MeasuredFormatError, match=r"786432 bytes every 13 ms = 484 Mbps exceeds the DCA1000's 400 Mbps"):
        check_device_config(_cfg(("frameCfg 0 2 64 8 40", "frameCfg 0 2 64 8 13")), "IWR6843", ethernet_rate=400e6)


def test_lvds_lane_rate_by_hand():
    # 4096 bytes per 67 us chirp = 489.1 Mbps: over 2 lanes x 200 Mbps of a family with slow lanes
    slow = dataclasses.replace(device_family("IWR6843"), max_lvds_lane_rate=200e6)
    with pytest.raises(MeasuredFormatError, match=r"chirp 0: 4096 bytes in 67 us = 489\.1 Mbps exceeds 2 LVDS lanes "
                                                 r"x 200 Mbps"):
        check_device_config(_cfg(), slow)


def test_frame_of_half_words_across_two_lanes():
    # real samples, one Rx, 255 samples, one chirp, one loop: 510 bytes, not a whole number of 4-byte lane words
    text = TRUTH_CFG.replace("adcCfg 2 1", "adcCfg 2 0").replace("adcbufCfg -1 0 1", "adcbufCfg -1 1 1") \
        .replace("34 0 0 68.69 0 256 10000", "34 0 0 68.69 0 255 10000").replace("frameCfg 0 0 64", "frameCfg 0 0 1")
    with pytest.raises(MeasuredFormatError, match=r"a frame of 510 bytes is not a whole number of 4-byte words across "
                                                 r"the 2 LVDS lanes"):
        check_device_config(parse_sdk_cfg(text), "IWR6843")


@pytest.mark.parametrize("line, match", [
    ("lvdsStreamCfg -1 1 1 0", r"enableHeader=1 puts an HSI header"),
    ("lvdsStreamCfg -1 0 0 0", r"dataFmt=0: the DCA1000 records plain ADC samples only with dataFmt 1"),
    ("lvdsStreamCfg -1 0 1 1", r"enableSW=1 appends"),
])
def test_lvds_stream_cfg(line, match):
    with pytest.raises(MeasuredFormatError, match=match):
        check_device_config(parse_sdk_cfg(TDM_IN_BAND.replace("sensorStart", line + "\nsensorStart")), "IWR6843")


def test_lvds_stream_cfg_parsed_and_still_listed_as_skipped():
    parsed = parse_sdk_cfg(TDM_IN_BAND.replace("sensorStart", "lvdsStreamCfg -1 0 1 0\nsensorStart"))
    assert (16, "lvdsStreamCfg") in parsed.skipped
    assert parsed.lvds_stream.data_format == 1 and not parsed.lvds_stream.enable_header
    assert parsed.lvds_stream.line == 16 and parsed.chirp_threshold == 1
    assert check_device_config(parsed, "IWR6843").lvds_header is False
    with pytest.raises(MeasuredFormatError, match=r":16: lvdsStreamCfg takes 4 arguments"):
        parse_sdk_cfg(TDM_IN_BAND.replace("sensorStart", "lvdsStreamCfg -1 0 1\nsensorStart"))


def test_several_violations_stay_one_line():
    with pytest.raises(MeasuredFormatError) as info:
        check_device_config(_cfg(("channelCfg 15 7 0", "channelCfg 31 7 0"), ("profileCfg 0 60 7", "profileCfg 0 59 7")),
                            "IWR6843")
    msg = str(info.value)
    assert "\n" not in msg and "band" in msg and "(and 1 more: " in msg and "receivers" in msg

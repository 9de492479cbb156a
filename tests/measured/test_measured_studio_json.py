"""mmWave Studio JSON export → the same TiChirpConfig as the equivalent .cfg."""

from __future__ import annotations

import json

import pytest

from risloc_rt.measured import MeasuredFormatError, parse_sdk_cfg, parse_studio_json, read_studio_json


def studio_doc(devices_as_list: bool = True) -> dict:
    dev = {
        "mmWaveDeviceId": 0,
        "rfConfig": {
            "rlChanCfg_t": {"rxChannelEn": "0xF", "txChannelEn": "0x7", "cascading": 0},
            "rlAdcOutCfg_t": {"fmt": {"b2AdcBits": 2, "b8FullScaleReducFctr": 0, "b2AdcOutFmt": 1}},
            "rlProfiles": [{"rlProfileCfg_t": {
                "profileId": 0, "pfVcoSelect": "0x0", "startFreqConst_GHz": 60.25, "idleTimeConst_usec": 7.0,
                "adcStartTimeConst_usec": 6.0, "rampEndTime_usec": 60.0, "txOutPowerBackoffCode": "0x0",
                "freqSlopeConst_MHz_usec": 64.985, "txStartTime_usec": 1.0, "numAdcSamples": 256,
                "digOutSampleRate": 5000.0, "hpfCornerFreq1": 0, "hpfCornerFreq2": 0, "rxGain_dB": "0x1E"}}],
            "rlChirps": [
                {"rlChirpCfg_t": {"chirpStartIdx": i, "chirpEndIdx": i, "profileId": 0, "startFreqVar_MHz": 0.0,
                                  "freqSlopeVar_KHz_usec": 0.0, "idleTimeVar_usec": 0.0,
                                  "adcStartTimeVar_usec": 0.0, "txEnable": tx}}
                for i, tx in enumerate(["0x1", "0x4", "0x2"])],
            "rlFrameCfg_t": {"chirpStartIdx": 0, "chirpEndIdx": 2, "numLoops": 64, "numFrames": 8,
                             "framePeriodicity_msec": 40.0, "triggerSelect": 1, "frameTriggerDelay": 0.0},
        },
        "rawDataCaptureConfig": {"rlDevDataFmtCfg_t": {"iqSwapSel": 1, "chInterleave": 1},
                                 "rlDevLaneEnable_t": {"laneEn": "0x3"}},
    }
    return {"mmWaveDevices": [dev] if devices_as_list else dev}


@pytest.mark.parametrize("as_list", [True, False])
def test_studio_json_maps_like_the_sdk_cfg(as_list, cfg_text):
    parsed = parse_studio_json(studio_doc(as_list))
    assert parsed.config == parse_sdk_cfg(cfg_text).config
    assert parsed.lanes == 2


def test_missing_key_is_named_by_its_path(tmp_path):
    doc = studio_doc()
    del doc["mmWaveDevices"][0]["rfConfig"]["rlFrameCfg_t"]["numLoops"]
    path = tmp_path / "capture.mmwave.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(MeasuredFormatError, match=r"mmWaveDevices\[0\]\.rfConfig\.rlFrameCfg_t\.numLoops is missing"):
        read_studio_json(path)


def test_bad_json_and_bad_values(tmp_path):
    path = tmp_path / "bad.json"
    path.write_text("{ not json")
    with pytest.raises(MeasuredFormatError, match="not valid JSON"):
        read_studio_json(path)
    doc = studio_doc()
    doc["mmWaveDevices"][0]["rfConfig"]["rlChirps"][1]["rlChirpCfg_t"]["txEnable"] = "0xZ"
    with pytest.raises(MeasuredFormatError, match=r"rlChirps\[1\]\.rlChirpCfg_t\.txEnable='0xZ'"):
        parse_studio_json(doc)


# ----------------------------------------------------------------------------- iqSwapSel (issue 20)
CORNER = __import__("pathlib").Path(__file__).resolve().parents[2].parent / "shared" / "captures" / \
    "iwr6843_corner_reflector" / "adc_data_Raw_0.bin"


def test_iq_swap_sel_must_be_0_or_1():
    doc = studio_doc()
    doc["mmWaveDevices"][0]["rawDataCaptureConfig"]["rlDevDataFmtCfg_t"]["iqSwapSel"] = 2
    with pytest.raises(MeasuredFormatError, match=r"rlDevDataFmtCfg_t\.iqSwapSel=2 must be 0 \(I first\) or 1"):
        parse_studio_json(doc)


@pytest.mark.skipif(not CORNER.is_file(), reason="shared corner-reflector capture absent")
@pytest.mark.parametrize("sel, peak", [(0, 38), (1, 256 - 38)])
def test_studio_iq_swap_sel_sets_the_files_order(tmp_path, sel, peak):
    """mmWaveLink rl_device.h: iqSwapSel 0 = I first, 1 = Q first, set by rlDeviceSetDataFmtConfig (the LVDS/CSI2
    output format), so the reader applies it by default. The corner-reflector capture (I first) read through a
    Studio export of the same chirp with iqSwapSel = 1 is mirrored and flagged, as a Q-first reading must be."""
    from risloc_rt.measured import inspect_capture

    doc = studio_doc()
    dev = doc["mmWaveDevices"][0]
    dev["rawDataCaptureConfig"]["rlDevDataFmtCfg_t"]["iqSwapSel"] = sel
    dev["rfConfig"]["rlFrameCfg_t"]["numFrames"] = 1
    path = tmp_path / "capture.mmwave.json"
    path.write_text(json.dumps(doc))
    result = inspect_capture(CORNER, path)
    assert result.layout.iq_swap is bool(sel) and result.config_iq_swap is bool(sel)
    assert result.peak.range_bin == peak
    assert ("iq-order" in [f.code for f in result.flags]) is bool(sel)

"""risloc capture inspect on TI's real corner-reflector capture: the documented answer, bin 38 / Doppler 0."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from risloc_rt.cli import main

RAW = Path(__file__).resolve().parents[3] / "shared" / "captures" / "iwr6843_corner_reflector" / "adc_data_Raw_0.bin"
needs_capture = pytest.mark.skipif(not RAW.is_file(), reason=f"shared capture {RAW} is not present")


@needs_capture
def test_json_summary_has_the_documented_peak(capsys):
    assert main(["capture", "inspect", str(RAW), "--layout", "256,4,3,64", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["peak"]["range_bin"] == 38 and doc["peak"]["doppler_bin"] == 0
    assert (doc["frames"], doc["chirps"], doc["channels"], doc["samples"]) == (1, 64, 12, 256)
    assert doc["dropped_packets"] == 0 and doc["truncated_bytes"] == 0


@needs_capture
def test_plot_and_text_summary(tmp_path, capsys):
    png = tmp_path / "inspect.png"
    assert main(["capture", "inspect", str(RAW), "--layout", "256,4,3,64", "--plot", str(png)]) == 0
    out = capsys.readouterr().out
    assert "peak: range bin 38, Doppler bin 0" in out and f"wrote {png}" in out
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@needs_capture
@pytest.mark.parametrize("argv, message", [
    (["--layout", "256,4,4,64"], "likely cause"),
    (["--layout", "256,4"], "must be four integers"),
    ([], "--config CFG"),
    (["--layout", "256,4,3,64", "--config", "x.cfg"], "not both"),
])
def test_bad_layouts_are_one_line_errors(capsys, argv, message):
    assert main(["capture", "inspect", str(RAW), *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("risloc capture inspect: error: ") and message in err and err.count("\n") == 1

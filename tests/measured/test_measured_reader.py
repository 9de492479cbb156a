"""The streaming reader: the real corner-reflector capture, split files, sizes that do not fit.

Expected samples come from the test-side reference decoder (``ti_reference``, written from TI's
documents) reading the same files, never from the emulator's codes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from risloc_rt.measured import (MeasuredFormatError, RawLayout, Recording, capture_files, inspect_capture, iter_frames,
                                open_raw, read_raw, write_raw_capture)
import ti_reference as ref  # registered by tests/measured/conftest.py (this folder is not on sys.path)
SHAPE = ref.Shape(N=32, R=4, C=2, K=8)          # make_config(): 32 complex samples, 4 rx, 2 chirps, 8 loops

#: The shared folder lives next to the repository: <repo>/../shared.
CORNER = Path(__file__).resolve().parents[2].parent / "shared" / "captures" / "iwr6843_corner_reflector" / \
    "adc_data_Raw_0.bin"
CORNER_LAYOUT = RawLayout(num_samples=256, num_rx=4, chirps_per_loop=3, num_loops=64)
needs_corner = pytest.mark.skipif(not CORNER.is_file(), reason=f"shared capture {CORNER} is absent "
                                  "(the shared folder sits next to the repository)")


@needs_corner
def test_corner_reflector_peaks_at_range_bin_38_and_zero_doppler():
    result = inspect_capture(CORNER, CORNER_LAYOUT)
    assert (result.peak.range_bin, result.peak.doppler_bin) == (38, 0)
    assert result.peak.snr_db > 50                                     # README: ~59 dB above the median
    assert result.to_dict()["peak"] == {"range_bin": 38, "doppler_bin": 0, "snr_db": pytest.approx(58, abs=3),
                                        "range": None, "velocity": None}
    assert result.positive_frequency_excess_db > 20 and not result.flags


@needs_corner
def test_corner_reflector_wrong_decodings_move_the_peak():
    cube = read_raw(CORNER, CORNER_LAYOUT, convention="ti").cube[0]    # [K, V, N]
    np.testing.assert_array_equal(cube, ref.ti_complex(CORNER.read_bytes(), ref.Shape(N=256, R=4, C=3, K=64))[0])
    words = np.fromfile(CORNER, "<i2").reshape(64, 12, 256, 2)         # the wrong I0 Q0 I1 Q1 interleave
    wrong = words[..., 0] + 1j * words[..., 1]
    w = np.hanning(256)

    def peak(c):
        return int(np.argmax(np.mean(np.abs(np.fft.fft(c * w, axis=-1)) ** 2, axis=(0, 1))))

    assert peak(cube) == 38 and peak(wrong) == 90
    assert inspect_capture(CORNER, CORNER_LAYOUT, iq_swap=True).peak.range_bin == 256 - 38   # mirrored
    swapped = inspect_capture(CORNER, CORNER_LAYOUT, iq_swap=True)
    assert "iq-order" in [f.code for f in swapped.flags]
    assert inspect_capture(CORNER, CORNER_LAYOUT, lanes=4).peak.range_bin == 104


def _emulated(tmp_path, make_config, make_tone, frames=5, **rec):
    cfg = make_config()
    cube = make_tone(cfg, frames, range_bin=5, amplitude=0.3)
    return write_raw_capture(cube, cfg, tmp_path, recording=Recording(**rec))


def test_split_files_read_as_one_stream(tmp_path, make_config, make_tone):
    em = _emulated(tmp_path, make_config, make_tone, max_file_size=3001)     # cut mid-sample on purpose
    assert len(em.files) > 3 and all(f.stat().st_size <= 3001 for f in em.files)
    assert capture_files(em.files[0]) == em.files
    cap = read_raw(em.files[0], em.layout, expected_frames=5, convention="ti")
    assert [f.name for f in em.files] == ref.split_names("adc_data", len(em.files))
    np.testing.assert_array_equal(cap.cube, ref.ti_complex(ref.read_split(tmp_path, "adc_data"), SHAPE))


def test_blocks_stream_every_frame_once(tmp_path, make_config, make_tone):
    em = _emulated(tmp_path, make_config, make_tone, frames=7)
    info = open_raw(em.files[0], em.layout)
    blocks = list(iter_frames(info, frames_per_block=3))
    assert [b.first_frame for b in blocks] == [0, 3, 6] and [len(b.cube) for b in blocks] == [3, 3, 1]
    np.testing.assert_array_equal(np.concatenate([b.cube for b in blocks]),
                                  np.conj(ref.ti_complex(ref.read_split(tmp_path, "adc_data"), SHAPE)))
    assert sum(len(b.cube) for b in iter_frames(info, max_frames=4, frames_per_block=3)) == 4


def test_missing_split_file_is_named(tmp_path, make_config, make_tone):
    em = _emulated(tmp_path, make_config, make_tone, max_file_size=4096)
    em.files[1].unlink()
    with pytest.raises(MeasuredFormatError, match=r"split file .*adc_data_Raw_1\.bin is missing"):
        read_raw(em.files[0], em.layout)


def test_truncated_final_frame_is_reported_and_dropped(tmp_path, make_config, make_tone):
    em = _emulated(tmp_path, make_config, make_tone, truncate_bytes=100)
    cap = read_raw(em.files[0], em.layout, expected_frames=5)
    assert cap.info.num_frames == 4 and cap.info.truncated_bytes == em.layout.frame_bytes - 100
    assert any("final frame 4 is truncated" in n for n in cap.info.notes)
    want = ref.ti_complex(ref.read_split(tmp_path, "adc_data"), SHAPE)      # whole frames only: 4
    assert want.shape[0] == 4
    np.testing.assert_array_equal(cap.cube, np.conj(want))                   # nothing shifted


def test_size_errors_give_expected_actual_and_cause(tmp_path, make_config, make_tone):
    em = _emulated(tmp_path, make_config, make_tone, frames=2)
    real = RawLayout.from_config(make_config(adc_format="real"))
    with pytest.raises(MeasuredFormatError, match=r"16384 bytes of samples, expected 8192 .*complex but the config "
                                                  r"says real"):
        open_raw(em.files[0], real, expected_frames=2)
    small = em.files[0].parent / "short.bin"
    small.write_bytes(em.files[0].read_bytes()[:1000])
    with pytest.raises(MeasuredFormatError, match=r"1000 bytes of samples, less than one frame of 8192 bytes"):
        open_raw(small, em.layout)
    three_rx = RawLayout.from_config(make_config(rx_mask=0b0111))
    with pytest.raises(MeasuredFormatError, match=r"4 rx x 2 chirps/loop were recorded, not 3 x 2"):
        open_raw(em.files[0], three_rx, expected_frames=2)
    with pytest.raises(MeasuredFormatError, match="does not exist"):
        open_raw(tmp_path / "nope.bin", em.layout)


@pytest.mark.parametrize("size", [1 << 20, 720 * 1456])
def test_a_missing_last_split_file_is_named(tmp_path, size):
    """Regression: the check for a missing *last* split file compared the bytes read with the frames
    expected (``total < expected``), so it never fired and a capture cut at a recorder's size limit read
    as "stopped early". A file of exactly 1 MiB (mmWave Studio's limit) or of the last whole 1456-byte
    packet under it (720 × 1456 = 1048320 bytes: TI's DCA1000 CLI with ``maxRecFileSize_MB`` = 1) with
    fewer frames than configured says a split file is missing."""
    layout = RawLayout(num_samples=256, num_rx=1, chirps_per_loop=1, num_loops=16)     # 16384 bytes per frame
    raw = tmp_path / "adc_data_Raw_0.bin"
    raw.write_bytes(np.random.default_rng(0).integers(-300, 300, size // 2, dtype=np.int16).tobytes())
    with pytest.raises(MeasuredFormatError, match=r"a split file after adc_data_Raw_0\.bin is missing"):
        read_raw(raw, layout, expected_frames=100, form="raw")


def test_a_capture_stopped_early_is_not_a_missing_split_file(tmp_path):
    layout = RawLayout(num_samples=256, num_rx=1, chirps_per_loop=1, num_loops=16)
    raw = tmp_path / "adc_data_Raw_0.bin"
    raw.write_bytes(np.random.default_rng(0).integers(-300, 300, 40 * 16384 // 2, dtype=np.int16).tobytes())
    cap = read_raw(raw, layout, expected_frames=100, form="raw")
    assert cap.info.num_frames == 40 and any("stopped early" in n for n in cap.info.notes)

"""Emulator: quantization, clipping, impairments; write -> read gives back the codes; physics in bins and metres."""

from __future__ import annotations

import json

import numpy as np
import pytest

from risloc_rt.measured import (AdcImpairments, MeasuredFormatError, Recording, combine_channels, inspect_capture,
                                plot_inspection, quantize_cube, read_raw, read_sdk_cfg, write_raw_capture)


@pytest.mark.parametrize("form", ["raw", "packets"])
@pytest.mark.parametrize("lanes, fmt, swap", [(2, "complex1x", False), (2, "complex2x", True), (4, "complex1x", True),
                                              (2, "real", False), (4, "real", False)])
def test_write_then_read_gives_the_quantized_samples_exactly(tmp_path, make_config, make_tone, form, lanes, fmt, swap):
    cfg = make_config(adc_format=fmt)
    cube = make_tone(cfg, 3, range_bin=4.3, doppler_bin=1, amplitude=0.7)
    em = write_raw_capture(cube, cfg, tmp_path, recording=Recording(form=form, lanes=lanes, iq_swap=swap,
                                                                    payload_size=1000))
    parsed = read_sdk_cfg(em.cfg_path).config
    assert parsed == em.config and parsed.num_frames == 3
    cap = read_raw(em.files[0], em.layout, expected_frames=parsed.num_frames)
    assert cap.info.form == form and cap.cube.dtype == np.complex64 and cap.cube.shape == (3, 8, 8, 32)
    np.testing.assert_array_equal(cap.cube, em.quantized.as_complex())
    # and the codes are the cube (same convention in and out) at 2^15 counts per full scale, ±½ LSB
    ref = (cube.real if fmt == "real" else cube) * 2 ** 15
    assert np.max(np.abs(cap.cube - ref)) <= 0.5 * np.sqrt(2) + 1e-6


def test_quantization_levels_and_clipping():
    cube = np.array([0.0, 0.5, -1.0, 1.0, 2.0, 1 / 2 ** 15 * 0.49, -3.0]).reshape(1, 1, 1, 7).astype(complex)
    q = quantize_cube(cube, adc_bits=16, real=True)
    np.testing.assert_array_equal(q.i.ravel(), [0, 16384, -32768, 32767, 32767, 0, -32768])
    assert q.clipped == 3                                       # +1.0 -> 32768 clipped, 2.0, -3.0
    q12 = quantize_cube(cube, adc_bits=12, real=True)
    np.testing.assert_array_equal(q12.i.ravel(), [0, 1024, -2048, 2047, 2047, 0, -2048])


def test_iq_imbalance_and_dc_offset_are_recovered_by_inspect(tmp_path, make_config):
    cfg = make_config()
    rng = np.random.default_rng(7)
    shape = (4, 8, 8, 32)
    noise = (rng.normal(size=shape) + 1j * rng.normal(size=shape)) * 0.05
    imp = AdcImpairments(dc_offset=0.02 - 0.01j, iq_gain_imbalance_db=1.5, iq_phase_imbalance=np.deg2rad(6))
    em = write_raw_capture(noise, cfg, tmp_path, impairments=imp)
    res = inspect_capture(em.files[0], em.cfg_path)
    assert res.dc_offset.real == pytest.approx(0.02 * 2 ** 15, abs=30)          # counts; noise σ/√n ≈ 0.05·2^15/90
    assert res.dc_offset.imag == pytest.approx(-0.01 * 2 ** 15, abs=30)
    assert res.iq_gain_imbalance_db == pytest.approx(1.5, abs=0.2)
    assert np.rad2deg(res.iq_phase_imbalance) == pytest.approx(6, abs=1)
    assert {"dc-offset", "iq-imbalance"} <= {f.code for f in res.flags}


def test_noise_is_seeded_and_needs_a_generator(make_config, make_tone):
    cfg = make_config()
    cube = make_tone(cfg, 1, range_bin=3, amplitude=0.1)
    imp = AdcImpairments(noise_rms=0.01)
    a = quantize_cube(cube, impairments=imp, rng=np.random.default_rng(5))
    b = quantize_cube(cube, impairments=imp, rng=np.random.default_rng(5))
    np.testing.assert_array_equal(a.i, b.i)
    with pytest.raises(MeasuredFormatError, match="noise_rms > 0 needs rng"):
        quantize_cube(cube, impairments=imp)


def test_emulated_target_lands_in_its_range_and_doppler_bin_and_metres(tmp_path, make_config):
    cfg = make_config()
    c = 299_792_458.0
    # By hand from the configuration (not from to_radar_config): the slow-time phase advances at the
    # centre of the ADC window, f0 + S (adc_start + N/(2 fs)) = 60.25 GHz + 60 MHz/µs · 14 µs, once per
    # TDM loop of one virtual channel, 2 × (7 µs idle + 24 µs ramp) = 62 µs (not the 24 µs ramp).
    fc, t_loop, slope, fs = 60.25e9 + 60e12 * 14e-6, 62e-6, 60e12, 2e6
    bin_velocity = c / fc / (2 * cfg.num_loops * t_loop)        # one Doppler bin [m/s]
    distance, velocity = 3.0, 2 * bin_velocity                   # [m] (< 5 m unambiguous), receding, on bin 2
    tau, nu = 2 * distance / c, 2 * velocity / c
    n, k = np.arange(cfg.num_samples), np.arange(cfg.num_loops)
    # eq. (1): exp(-j2π (S τ + f_c ν) n T_s) exp(-j2π f_c ν k T_loop)
    y = 0.3 * np.exp(-2j * np.pi * ((slope * tau + fc * nu) * n[None, :] / fs + fc * nu * k[:, None] * t_loop))
    cube = np.broadcast_to(y[None, :, None, :], (2, cfg.num_loops, cfg.num_virtual, cfg.num_samples))
    em = write_raw_capture(cube, cfg, tmp_path, impairments=AdcImpairments(noise_rms=1e-3),
                           rng=np.random.default_rng(0))
    res = inspect_capture(em.files[0], em.cfg_path)
    expect_bin = round(slope * tau * cfg.num_samples / fs)
    assert res.peak.range_bin == expect_bin
    assert res.peak.range == pytest.approx(distance, abs=c / (2 * slope * cfg.num_samples / fs))
    assert res.peak.doppler_bin == 2
    # exactly on its bin: the reported velocity is the injected one (with the ramp instead of the loop,
    # 5.02 m/s would be read; with the start frequency instead of the centre, 1.4 % more)
    assert res.peak.velocity == pytest.approx(velocity, rel=1e-6)
    doc = json.loads(res.to_json())
    assert doc["peak"]["range_bin"] == expect_bin and doc["frames"] == 2 and doc["channels"] == 8
    out = tmp_path / "inspect.png"
    plot_inspection(res, out)
    assert out.stat().st_size > 10_000


def test_inspect_flags_lost_packets_clipping_and_truncation(tmp_path, make_config, make_tone):
    cfg = make_config()
    cube = make_tone(cfg, 4, range_bin=6, amplitude=1.5)                   # beyond full scale: clips
    em = write_raw_capture(cube, cfg, tmp_path, recording=Recording(form="packets", drop_packets=(4,),
                                                                    truncate_bytes=10))
    res = inspect_capture(em.files[0], em.cfg_path)
    names = {f.code for f in res.flags}
    assert {"dropped-packets", "truncated-frame", "clipping"} <= names
    assert res.frames == 3 and res.dropped_packets == 1 and res.damaged_frames == (0,)
    assert res.clipped_fraction > 0.1 and res.peak.range_bin == 6


def test_inspect_flags_a_glitch_and_not_a_clean_recording(tmp_path, make_config, make_tone):
    # one ADC sample of frame 1 (loop 2, channel 3) 33 dB above its chirp's tone: a glitch, no beat signal
    cfg = make_config()
    cube = make_tone(cfg, 3, range_bin=6, amplitude=0.02)                  # [frames, loops, channels, samples]
    (tmp_path / "clean").mkdir()
    (tmp_path / "glitch").mkdir()
    em = write_raw_capture(cube, cfg, tmp_path / "clean")
    clean = inspect_capture(em.files[0], em.cfg_path)
    assert "impulsive-samples" not in {f.code for f in clean.flags} and clean.impulsive_samples == 0
    cube[1, 2, 3, 10] = 0.9
    em = write_raw_capture(cube, cfg, tmp_path / "glitch")
    res = inspect_capture(em.files[0], em.cfg_path)
    flag = next(f for f in res.flags if f.code == "impulsive-samples")
    assert res.impulsive_samples == 1 and res.impulsive_frames == (1,) and "frames [1]" in flag.message
    assert res.impulsive_largest_db == pytest.approx(20 * np.log10(0.9 / 0.02), abs=0.1)
    assert res.to_dict()["impulsive_samples"]["count"] == 1


def test_combine_channels_gives_the_localization_cube(make_config, make_tone):
    cfg = make_config()
    cube = make_tone(cfg, 2, range_bin=3).astype(np.complex64)             # random phase per channel
    one = combine_channels(cube, channels=5)
    assert one.shape == (2, 8, 32) and np.array_equal(one, cube[:, :, 5])
    phases = cube[0, 0, :, 0] / np.abs(cube[0, 0, :, 0])
    beam = combine_channels(cube, channels=None, weights=np.conj(phases))   # phase-aligned: full amplitude
    assert np.allclose(np.abs(beam), 0.5, atol=1e-5)
    assert np.abs(combine_channels(cube, channels=None)).max() < 0.5       # unaligned sum loses amplitude
    with pytest.raises(MeasuredFormatError, match="outside the 8 virtual channels"):
        combine_channels(cube, channels=8)


def test_split_files_appear_together_or_not_at_all(tmp_path, make_config, make_tone):
    """Atomic split writes: an error mid-stream leaves no split file; an existing capture is not overwritten."""
    from risloc_rt.measured.dca1000.split_files import SplitWriter

    with pytest.raises(RuntimeError, match="link down"):
        with SplitWriter(tmp_path, "adc_data", max_file_size=100) as writer:
            writer.write(b"x" * 250)                 # three files begun
            raise RuntimeError("link down")
    assert list(tmp_path.iterdir()) == []            # neither split files nor temporaries
    cfg = make_config()
    em = write_raw_capture(make_tone(cfg, 2, range_bin=3), cfg, tmp_path, recording=Recording(max_file_size=3000))
    assert len(em.files) >= 2 and all(p.is_file() for p in em.files)
    before = [p.read_bytes() for p in em.files]
    with pytest.raises(MeasuredFormatError, match="does not overwrite a capture"):
        write_raw_capture(make_tone(cfg, 2, range_bin=5), cfg, tmp_path)
    assert [p.read_bytes() for p in em.files] == before
    again = write_raw_capture(make_tone(cfg, 2, range_bin=5), cfg, tmp_path, overwrite=True,
                              recording=Recording(max_file_size=3000))
    assert [p.read_bytes() for p in again.files] != before
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]

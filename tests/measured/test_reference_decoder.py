"""The test-side TI reference decoder (``ti_reference``) pinned to hand-tabulated words, and the reader judged by it.

Issue 20: the emulator and the reader share reshapes, the header packer and constants, so their
round trips prove only that one inverts the other. Here the expected values come from words
written out by hand (from TI's SWRA581 and DCA1000 user's guide) or from ``ti_reference``, which
imports nothing from the project.
"""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from risloc_rt.measured import (AdcImpairments, RawLayout, Recording, inspect_capture, iter_frames, open_raw, read_raw,
                                read_sdk_cfg, write_raw_capture)
import ti_reference as ref  # registered by tests/measured/conftest.py (this folder is not on sys.path)
CORNER = Path(__file__).resolve().parents[2].parent / "shared" / "captures" / "iwr6843_corner_reflector" / \
    "adc_data_Raw_0.bin"
needs_corner = pytest.mark.skipif(not CORNER.is_file(), reason=f"shared capture {CORNER} is absent")
LSB = 1.0 / 32768                                  # one 16-bit code for full_scale = 1


def test_reference_imports_nothing_from_the_project():
    tree = ast.parse(Path(ref.__file__).read_text())
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            names.add((node.module or "").split(".")[0])
    assert names <= {"__future__", "struct", "dataclasses", "numpy", "pathlib"}, names


# ------------------------------------------------------------------ the reference against hand-tabulated words
def _words(*values: int) -> bytes:
    return np.array(values, "<i2").tobytes()


def test_reference_two_lane_complex_by_hand():
    # SWRA581 s.5: rx0 I0 I1 Q0 Q1 I2 I3 Q2 Q3, then rx1 the same; rx0 = 1+10j, 2+20j, 3+30j, 4+40j
    data = _words(1, 2, 10, 20, 3, 4, 30, 40, 101, 102, 110, 120, 103, 104, 130, 140)
    z = ref.ti_complex(data, ref.Shape(N=4, R=2, C=1, K=1))
    assert z[0, 0].tolist() == [[1 + 10j, 2 + 20j, 3 + 30j, 4 + 40j], [101 + 110j, 102 + 120j, 103 + 130j, 104 + 140j]]
    q_first = ref.ti_complex(data, ref.Shape(N=4, R=2, C=1, K=1, q_first=True))
    assert q_first[0, 0, 0].tolist() == [10 + 1j, 20 + 2j, 30 + 3j, 40 + 4j]


def test_reference_four_lane_and_real_by_hand():
    # SWRA581 s.4: per sample, I of rx0..rx2 then Q of rx0..rx2
    data = _words(1, 2, 3, -1, -2, -3, 4, 5, 6, -4, -5, -6)
    z = ref.ti_complex(data, ref.Shape(N=2, R=3, C=1, K=1, lanes=4))
    assert z[0, 0].tolist() == [[1 - 1j, 4 - 4j], [2 - 2j, 5 - 5j], [3 - 3j, 6 - 6j]]
    assert ref.ti_complex(_words(0, 1, 2, 3, 4, 5), ref.Shape(N=3, R=2, C=1, K=1, complex_=False))[0, 0].tolist() \
        == [[0, 1, 2], [3, 4, 5]]
    assert ref.ti_complex(_words(0, 1, 2, 3, 4, 5), ref.Shape(N=3, R=2, C=1, K=1, complex_=False, lanes=4))[0, 0] \
        .tolist() == [[0, 2, 4], [1, 3, 5]]


def test_reference_header_and_zero_fill_by_hand():
    # DCA1000 user's guide: <u32 sequence (first = 1), 48-bit byte count, little-endian
    assert ref.header(1, 0) == bytes([1, 0, 0, 0, 0, 0, 0, 0, 0, 0])
    assert ref.header(0x01020304, 0x0A0B0C0D0E0F) == bytes([4, 3, 2, 1, 0x0F, 0x0E, 0x0D, 0x0C, 0x0B, 0x0A])
    stream = bytes(range(1, 41))                                           # 40 bytes, payload 8: 5 packets
    data = ref.packetize(stream, payload=8, lost=frozenset({2, 3}))
    assert len(data) == 3 * 18 and data[:10] == ref.header(1, 0) and data[18:28] == ref.header(4, 24)
    back, gaps = ref.depacketize(data, 8)
    assert back == bytes(range(1, 9)) + bytes(16) + bytes(range(25, 41))
    assert gaps == [ref.Lost(first=2, count=2, offset=8, num_bytes=16)]
    assert ref.zero_fill_raw(stream, payload=8, lost=frozenset({2, 3})) == back
    assert ref.zero_packets(back, payload=8) == [2, 3]


@pytest.mark.parametrize("shape", [ref.Shape(N=4, R=3, C=2, K=2), ref.Shape(N=2, R=4, C=1, K=3, lanes=4),
                                   ref.Shape(N=4, R=2, C=2, K=1, q_first=True),
                                   ref.Shape(N=3, R=2, C=2, K=2, complex_=False, lanes=4)])
def test_reference_encoder_inverts_its_decoder(shape):
    rng = np.random.default_rng(5)
    size = (2, shape.K, shape.C * shape.R, shape.N)
    i = rng.integers(-32768, 32768, size)
    q = rng.integers(-32768, 32768, size) if shape.complex_ else np.zeros(size, int)
    data = ref.encode(i, q, shape)
    assert len(data) == 2 * shape.frame_bytes
    i2, q2 = ref.decode(data, shape)
    assert np.array_equal(i2, i) and np.array_equal(q2, q)


# ------------------------------------------------------------------------------ the real capture, by the reference
@needs_corner
def test_corner_reflector_reference_and_reader_agree_peak_at_bin_38():
    data = CORNER.read_bytes()
    z = ref.ti_complex(data, ref.Shape(N=256, R=4, C=3, K=64))                # [1, 64, 12, 256], I + jQ
    cap = read_raw(CORNER, RawLayout(num_samples=256, num_rx=4, chirps_per_loop=3, num_loops=64), convention="ti")
    assert np.array_equal(cap.cube, z) and cap.dropped == () and cap.damaged_frames == ()
    spectrum = np.fft.fft(z[0] * np.hanning(256), axis=-1)                  # TI: targets at positive frequencies
    profile = np.mean(np.abs(spectrum) ** 2, axis=(0, 1))
    assert int(np.argmax(profile)) == 38
    assert int(np.argmax(np.abs(np.fft.fft(spectrum[:, :, 38], axis=0)).sum(axis=1))) == 0    # zero Doppler
    words = np.frombuffer(data, "<i2")
    assert np.mean(words == 0) < 1e-3                                        # noise: 0.007 % exact zeros


# ---------------------------------------------------------------------------------- raw-mode lost packets
def _noisy(make_config, make_tone, frames, *, noise_lsb=3.0, amplitude=0.02, **cfg_kw):
    cfg = make_config(**cfg_kw)
    return cfg, make_tone(cfg, frames, range_bin=5, doppler_bin=1, amplitude=amplitude)


#: Issue 20's case: 9 lost packets (the first, a pair, one across a frame boundary, the last whole one).
NINE = (1, 4, 5, 12, 17, 18, 19, 26, 33)


@pytest.mark.parametrize("form", ["packets", "raw"])
def test_issue_20_nine_lost_packets_found_in_both_forms(tmp_path, make_config, make_tone, form):
    cfg, cube = _noisy(make_config, make_tone, 6)                           # 6 frames x 8192 bytes = 33.76 packets
    em = write_raw_capture(cube, cfg, tmp_path, recording=Recording(form=form, drop_packets=NINE),
                           impairments=AdcImpairments(noise_rms=3 * LSB), rng=np.random.default_rng(1))
    assert em.dropped_sequences == NINE
    cap = read_raw(em.files[0], em.layout, expected_frames=6)
    found = sorted(s for d in cap.dropped for s in range(d.first_sequence, d.first_sequence + d.count))
    assert found == list(NINE)                                               # 9 of 9 in either form
    assert all(d.probable == (form == "raw") for d in cap.dropped)
    # the stream the reference zero-fills (packet form: from the headers; raw form: the file itself)
    data = ref.read_split(tmp_path, "adc_data")
    stream = ref.depacketize(data, 1456)[0] if form == "packets" else data
    assert ref.zero_packets(stream) == list(NINE)
    shape = ref.Shape(N=32, R=4, C=2, K=8)
    assert np.array_equal(cap.cube, np.conj(ref.ti_complex(stream, shape)))   # paper convention: I - jQ
    fb = shape.frame_bytes
    hit = sorted({f for s in NINE for f in range((s - 1) * 1456 // fb, min((s * 1456 - 1) // fb, 5) + 1)})
    assert list(cap.damaged_frames) == hit
    blocks = list(iter_frames(open_raw(em.files[0], em.layout), frames_per_block=2))
    assert [int(b.first_frame + j) for b in blocks for j in np.flatnonzero(b.damaged)] == hit
    assert sum(d.count for b in blocks for d in b.dropped) == 9


def test_raw_losses_reach_inspection_as_probable(tmp_path, make_config, make_tone):
    cfg, cube = _noisy(make_config, make_tone, 6)
    em = write_raw_capture(cube, cfg, tmp_path, recording=Recording(drop_packets=(3, 20)),
                           impairments=AdcImpairments(noise_rms=3 * LSB), rng=np.random.default_rng(2))
    result = inspect_capture(em.files[0], em.cfg_path)
    assert result.dropped_packets == 2 and result.probable_dropped_packets == 2
    flag = next(f for f in result.flags if f.code == "dropped-packets")
    assert "2 probable lost packets" in flag.message and "packets lost" not in flag.message.split("probable")[0]
    assert result.to_dict()["probable_dropped_packets"] == 2


def test_digital_silence_is_not_called_lossy(tmp_path, make_config):
    cfg = make_config()
    em = write_raw_capture(np.zeros((3, 8, 8, 32), complex), cfg, tmp_path)   # noise-free, no signal: all zeros
    assert not any(ref.read_split(tmp_path, "adc_data"))
    cap = read_raw(em.files[0], em.layout)
    assert cap.dropped == () and cap.damaged_frames == ()
    assert any("digital silence" in n for n in cap.info.notes)
    result = inspect_capture(em.files[0], em.cfg_path)
    assert "dropped-packets" not in [f.code for f in result.flags]


def test_no_false_alarm_on_noise_only_captures_at_one_lsb(tmp_path, make_config):
    """20 noise-only captures, σ = 1 LSB per word (P(word = 0) = 0.38): no packet is called lost."""
    cfg = make_config(num_loops=64)                                          # 64 KiB per frame, 45 packets
    rng = np.random.default_rng(7)
    alarms = packets = 0
    for trial in range(20):
        folder = tmp_path / f"t{trial}"
        folder.mkdir()
        em = write_raw_capture(np.zeros((4, 64, 8, 32), complex), cfg, folder,
                               impairments=AdcImpairments(noise_rms=LSB), rng=rng)
        words = np.frombuffer(ref.read_split(folder, "adc_data"), "<i2")
        assert 0.3 < np.mean(words == 0) < 0.45
        cap = read_raw(em.files[0], em.layout)
        alarms += cap.dropped_packets
        packets += words.nbytes // 1456
    assert alarms == 0 and packets == 20 * 180


def test_payload_grid_and_switch(tmp_path, make_config, make_tone):
    cfg, cube = _noisy(make_config, make_tone, 4)
    em = write_raw_capture(cube, cfg, tmp_path, recording=Recording(payload_size=1024, drop_packets=(7,)),
                           impairments=AdcImpairments(noise_rms=3 * LSB), rng=np.random.default_rng(3))
    got = read_raw(em.files[0], em.layout, form="raw", payload_size=1024).dropped          # the grid of the search
    assert [(d.first_sequence, d.count, d.stream_offset, d.num_bytes, d.probable) for d in got] == \
        [(7, 1, 6144, 1024, True)]
    assert read_raw(em.files[0], em.layout).dropped == ()                  # on the 1456 grid it is not whole packets
    assert read_raw(em.files[0], em.layout, form="raw", payload_size=1024, find_zero_packets=False).dropped == ()


def test_random_raw_losses_are_all_found(tmp_path, make_config, make_tone):
    cfg, cube = _noisy(make_config, make_tone, 12)
    em = write_raw_capture(cube, cfg, tmp_path, recording=Recording(drop_probability=0.1, max_file_size=30_000),
                           impairments=AdcImpairments(noise_rms=3 * LSB), rng=np.random.default_rng(4))
    assert len(em.files) > 1 and len(em.dropped_sequences) > 3
    cap = read_raw(em.files[0], em.layout)
    whole = 12 * 8192 // 1456
    expect = [s for s in em.dropped_sequences if s <= whole]                # the final short packet is not judged
    assert sorted(s for d in cap.dropped for s in range(d.first_sequence, d.first_sequence + d.count)) == expect
    assert ref.zero_packets(ref.read_split(tmp_path, "adc_data")) == expect


# --------------------------------------------------------------------------------------------- SampleSwap
def test_emulated_cfg_states_sample_swap_1_and_the_file_has_i_first(tmp_path, make_config, make_tone):
    cfg, cube = _noisy(make_config, make_tone, 2)
    em = write_raw_capture(cube, cfg, tmp_path)
    assert "adcbufCfg -1 0 1 1 1" in em.cfg_path.read_text().splitlines()    # the only value SDK demos accept
    assert read_sdk_cfg(em.cfg_path).config.iq_swap
    i, q = ref.decode(ref.read_split(tmp_path, "adc_data"), ref.Shape(N=32, R=4, C=2, K=8))   # I first
    assert np.array_equal(i, em.quantized.i) and np.array_equal(q, em.quantized.q)
    result = inspect_capture(em.files[0], em.cfg_path)                      # default: I first despite the flag
    assert result.layout.iq_swap is False and result.config_iq_swap is True
    assert result.positive_frequency_excess_db > 20 and "iq-order" not in [f.code for f in result.flags]


def test_q_first_file_is_flagged_and_the_message_names_the_config_flag(tmp_path, make_config, make_tone):
    cfg, cube = _noisy(make_config, make_tone, 2)
    em = write_raw_capture(cube, cfg, tmp_path, recording=Recording(iq_swap=True),
                           impairments=AdcImpairments(noise_rms=3 * LSB), rng=np.random.default_rng(6))
    assert "cannot state" in em.cfg_path.read_text().splitlines()[0]
    i, q = ref.decode(ref.read_split(tmp_path, "adc_data"), ref.Shape(N=32, R=4, C=2, K=8, q_first=True))
    assert np.array_equal(i, em.quantized.i) and np.array_equal(q, em.quantized.q)
    wrong = inspect_capture(em.files[0], em.cfg_path)
    flag = next(f for f in wrong.flags if f.code == "iq-order")
    assert "iq_swap=True" in flag.message and "swap flag is 1" in flag.message
    assert inspect_capture(em.files[0], em.cfg_path, iq_swap=True).positive_frequency_excess_db > 20


@pytest.mark.slow
def test_raw_losses_mark_the_imported_beams_damaged(tmp_path):
    """The importer's damaged-beam logic (block.damaged) sees raw-form losses as it sees packet-form ones."""
    from dsp import ProcessingConfig, RadarConfig
    from risloc_rt.measured import dca1000_radar, emulate_capture, import_capture
    from risloc_rt.measured.emulate.experiment import full_scale
    from risloc_rt.model.builder import analytic_scenario
    from risloc_rt.model.simulate import simulate

    radar = dca1000_radar(RadarConfig(num_samples=128, num_chirps=16))
    scenario = analytic_scenario(distance=9.3, aod=np.deg2rad((17.2, 0.0)), radar=radar,
                                 processing=ProcessingConfig(n_dft=255, k_dft=64))
    sim = simulate(scenario, rng=np.random.default_rng(5))
    exp = emulate_capture(sim, tmp_path / "dca")                             # the .cfg and sweep.toml
    cfg = read_sdk_cfg(exp.config_path).config
    lost = (2, 50, 51, 52, 100, 171, 200, 250, 343)                          # 61 frames x 8192 B = 343.2 packets
    folder = tmp_path / "lossy"
    folder.mkdir()
    raw = write_raw_capture(sim.cube[:, :, None, :], cfg, folder, recording=Recording(drop_packets=lost),
                            impairments=AdcImpairments(full_scale=full_scale(sim.radar)))
    cap = import_capture(raw.files[0], raw.cfg_path, exp.schedule_path)
    reader = cap.provenance["reader"]
    assert reader["form"] == "raw" and all(d["probable"] for d in reader["dropped_packets"])
    assert sorted(s for d in reader["dropped_packets"] for s in range(d["first_sequence"],
                                                                      d["first_sequence"] + d["count"])) == list(lost)
    fb = 16 * 128 * 4
    beams = sorted({f for s in lost for f in range((s - 1) * 1456 // fb, (s * 1456 - 1) // fb + 1)})
    assert reader["damaged_beams"] == beams                                  # one frame per beam, first frame 0


@needs_corner
def test_corner_reflector_recording_has_no_impulsive_samples():
    # A real recording (TI's IWR6843 corner reflector, decoded by the reference): its largest sample
    # stands 10.5 dB over its chirp's median power (the reflector 59 dB over the median range bin), far
    # below the 20 dB a lone glitch must exceed: the glitch screen leaves measured beat signals alone.
    from dsp.impulses import screen_impulses

    z = ref.ti_complex(CORNER.read_bytes(), ref.Shape(N=256, R=4, C=3, K=64))[0]  # [64 loops, 12 antennas, 256]
    cube = np.ascontiguousarray(z.transpose(1, 0, 2))  # a "beam" per virtual antenna, its 64 chirps
    power = np.abs(cube) ** 2
    crest = power.max(axis=-1) / np.sort(power, axis=-1)[..., 128]
    assert 10 * np.log10(crest.max()) < 14.0  # 6 dB of margin under the documented 20 dB
    out, screen = screen_impulses(cube)
    assert screen.count == 0 and out is cube

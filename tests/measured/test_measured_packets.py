"""Packet-recorded captures: 10-byte headers, lost packets zero-filled in place, never shifted.

Files are built with the test-side header packer and judged by the reference decoder
(``ti_reference``, from TI's DCA1000 user's guide and SWRA581), never by the project's own
``pack_header`` or the emulator's codes.
"""

from __future__ import annotations

import numpy as np
import pytest

from risloc_rt.measured import (MeasuredFormatError, RawLayout, Recording, detect_payload_size, pack_header, read_raw,
                                write_raw_capture)
import ti_reference as ref  # registered by tests/measured/conftest.py (this folder is not on sys.path)


def test_project_header_packer_matches_bytes_by_hand():
    assert pack_header(1, 0) == bytes([1, 0, 0, 0, 0, 0, 0, 0, 0, 0])
    assert pack_header(0x01020304, 0x0A0B0C0D0E0F) == bytes([4, 3, 2, 1, 0x0F, 0x0E, 0x0D, 0x0C, 0x0B, 0x0A])
    assert pack_header(7, 7 * 1456) == ref.header(7, 7 * 1456)


def test_hand_built_packet_file(tmp_path):
    lay = RawLayout(num_samples=4, num_rx=1, chirps_per_loop=1, num_loops=2)      # 32 bytes per frame
    stream = np.arange(48, dtype="<i2").tobytes()                                  # 3 frames
    P = 20
    packets = [stream[i:i + P] for i in range(0, len(stream), P)]                  # 5 payloads: 20,20,20,20,16
    data = b"".join(ref.header(k + 1, k * P) + p for k, p in enumerate(packets) if k != 2)   # packet 3 lost
    path = tmp_path / "adc_data_Raw_0.bin"
    path.write_bytes(data)
    assert detect_payload_size(data[:200]) == P
    cap = read_raw(path, lay, convention="ti")
    assert cap.info.form == "packets" and cap.info.num_frames == 3
    assert [(d.first_sequence, d.count, d.stream_offset, d.num_bytes, d.probable) for d in cap.dropped] == \
        [(3, 1, 40, 20, False)]
    # by hand: words 20..29 (bytes 40..59) zero; per frame I0 I1 Q0 Q1 I2 I3 Q2 Q3 twice (2 loops)
    expected = np.arange(48).reshape(3, 2, 2, 2, 2).astype(float)      # frame, loop, pair, (I|Q), lane
    expected.reshape(-1)[20:30] = 0
    want = (expected[..., 0, :] + 1j * expected[..., 1, :]).reshape(3, 2, 1, 4)
    np.testing.assert_array_equal(cap.cube, want)
    back, gaps = ref.depacketize(data, P)
    assert gaps == [ref.Lost(first=3, count=1, offset=40, num_bytes=20)]
    np.testing.assert_array_equal(cap.cube, ref.ti_complex(back, ref.Shape(N=4, R=1, C=1, K=2)))
    assert cap.damaged_frames == (1,)


def _capture(tmp_path, make_config, make_tone, **rec):
    cfg = make_config()
    cube = make_tone(cfg, 6, range_bin=7, doppler_bin=2, amplitude=0.4)
    return write_raw_capture(cube, cfg, tmp_path, recording=Recording(form="packets", **rec))


SHAPE = ref.Shape(N=32, R=4, C=2, K=8)          # make_config(): 32 complex samples, 4 rx, 2 chirps, 8 loops


def test_dropped_packet_is_zero_filled_at_its_place(tmp_path, make_config, make_tone):
    em = _capture(tmp_path, make_config, make_tone, drop_packets=(9,), max_file_size=20_000)
    assert len(em.files) > 1 and em.dropped_sequences == (9,)
    cap = read_raw(em.files[0], em.layout, expected_frames=6, convention="ti")
    assert cap.dropped_packets == 1 and cap.dropped[0].stream_offset == 8 * 1456
    stream, gaps = ref.depacketize(ref.read_split(tmp_path, "adc_data"), 1456)
    assert gaps == [ref.Lost(first=9, count=1, offset=8 * 1456, num_bytes=1456)]
    np.testing.assert_array_equal(cap.cube, ref.ti_complex(stream, SHAPE))
    # the reference's stream equals the emulator's codes except the lost packet's 1456 bytes, which are zeros
    i, q = ref.decode(stream, SHAPE)
    diff = np.flatnonzero(((i != em.quantized.i) | (q != em.quantized.q)).ravel())
    first = 8 * 1456 // 4                                                       # 4 bytes per complex sample
    assert diff.size and diff.min() >= first - 1 and diff.max() < first + 365
    assert cap.damaged_frames == (8 * 1456 // em.layout.frame_bytes,)


def test_first_packets_lost_and_random_losses(tmp_path, make_config, make_tone):
    cfg = make_config()
    cube = make_tone(cfg, 6, range_bin=7)
    em = write_raw_capture(cube, cfg, tmp_path, rng=np.random.default_rng(3),
                           recording=Recording(form="packets", drop_packets=(1, 2), drop_probability=0.05,
                                               payload_size=1000))
    cap = read_raw(em.files[0], em.layout)
    lost = sorted(s for d in cap.dropped for s in range(d.first_sequence, d.first_sequence + d.count))
    assert lost == sorted(em.dropped_sequences) and lost[:2] == [1, 2] and len(lost) > 2
    assert cap.dropped[0].stream_offset == 0
    stream, gaps = ref.depacketize(ref.read_split(tmp_path, "adc_data"), 1000)
    assert sorted(s for g in gaps for s in range(g.first, g.first + g.count)) == lost
    np.testing.assert_array_equal(cap.cube, np.conj(ref.ti_complex(stream, SHAPE)))


def test_random_loss_needs_an_explicit_generator(tmp_path, make_config, make_tone):
    cfg = make_config()
    for form in ("packets", "raw"):
        with pytest.raises(MeasuredFormatError, match="rng=numpy.random.default_rng"):
            write_raw_capture(make_tone(cfg, 1, range_bin=1), cfg, tmp_path,
                              recording=Recording(form=form, drop_probability=0.1))
        assert not list(tmp_path.iterdir())                                    # nothing written
    with pytest.raises(MeasuredFormatError, match="payload_size=1457 must be even"):
        Recording(form="raw", drop_packets=(3,), payload_size=1457)


def test_duplicate_packet_is_reported_not_placed(tmp_path):
    lay = RawLayout(num_samples=4, num_rx=1, chirps_per_loop=1, num_loops=1)       # 16 bytes per frame
    stream = np.arange(16, dtype="<i2").tobytes()
    P = 8
    pk = [ref.header(k + 1, k * P) + stream[k * P:(k + 1) * P] for k in range(4)]
    path = tmp_path / "dup_Raw_0.bin"
    path.write_bytes(pk[0] + pk[1] + pk[1] + pk[2] + pk[3])
    cap = read_raw(path, lay, payload_size=P, form="packets")
    assert cap.info.num_frames == 2 and len(cap.issues) == 1 and "duplicate" in cap.issues[0].message
    np.testing.assert_array_equal(read_raw(path, lay, payload_size=P, form="packets", convention="ti").cube.ravel(),
                                  [0 + 2j, 1 + 3j, 4 + 6j, 5 + 7j, 8 + 10j, 9 + 11j, 12 + 14j, 13 + 15j])


def test_raw_bytes_are_not_mistaken_for_packets_and_forced_packets_fail(tmp_path, make_config, make_tone):
    cfg = make_config()
    em = write_raw_capture(make_tone(cfg, 2, range_bin=3), cfg, tmp_path)
    assert read_raw(em.files[0], em.layout).info.form == "raw"
    with pytest.raises(MeasuredFormatError, match="not a DCA1000 packet header.*form='raw'"):
        read_raw(em.files[0], em.layout, form="packets")

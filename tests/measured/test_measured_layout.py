"""Byte layouts checked word by word against hand-built frames (TI SWRA581 s.4-5), the int16 sign, and both
directions judged by the test-side reference decoder ``ti_reference`` (never by each other)."""

from __future__ import annotations

import numpy as np
import pytest

from risloc_rt.measured import MeasuredFormatError, RawLayout, decode_frames, encode_frames
import ti_reference as ref  # registered by tests/measured/conftest.py (this folder is not on sys.path)


def _layout(**kw):
    params = dict(num_samples=4, num_rx=2, chirps_per_loop=1, num_loops=1)
    params.update(kw)
    return RawLayout(**params)


def test_two_lane_complex_is_i0_i1_q0_q1_per_receiver():
    # rx0 samples 1+10j, 2+20j, 3+30j, 4+40j ; rx1 the same plus 100 (TI convention I + jQ)
    words = np.array([1, 2, 10, 20, 3, 4, 30, 40, 101, 102, 110, 120, 103, 104, 130, 140], "<i2")
    cube = decode_frames(words, _layout(), convention="ti")
    assert cube.shape == (1, 1, 2, 4)
    np.testing.assert_array_equal(cube[0, 0, 0], [1 + 10j, 2 + 20j, 3 + 30j, 4 + 40j])
    np.testing.assert_array_equal(cube[0, 0, 1], [101 + 110j, 102 + 120j, 103 + 130j, 104 + 140j])


def test_paper_convention_is_the_conjugate_and_iq_swap_exchanges_the_words():
    words = np.array([1, 2, 10, 20, 3, 4, 30, 40] * 2, "<i2")
    paper = decode_frames(words, _layout(), convention="paper")
    np.testing.assert_array_equal(paper[0, 0, 0], [1 - 10j, 2 - 20j, 3 - 30j, 4 - 40j])
    swapped = decode_frames(words, _layout(iq_swap=True), convention="ti")
    np.testing.assert_array_equal(swapped[0, 0, 0], [10 + 1j, 20 + 2j, 30 + 3j, 40 + 4j])


def test_four_lane_complex_is_one_lane_per_receiver():
    # xWR14xx: per sample, I of rx0..rx3 then Q of rx0..rx3
    N, R = 2, 4
    words = []
    for n in range(N):
        words += [10 * r + n for r in range(R)] + [-(10 * r + n) - 1 for r in range(R)]
    cube = decode_frames(np.array(words, "<i2"), _layout(num_samples=N, num_rx=R, lanes=4), convention="ti")
    for r in range(R):
        np.testing.assert_array_equal(cube[0, 0, r], [10 * r + n + 1j * (-(10 * r + n) - 1) for n in range(N)])


def test_real_formats_two_and_four_lanes():
    two = decode_frames(np.arange(8, dtype="<i2"), _layout(adc_format="real"))
    np.testing.assert_array_equal(two[0, 0], [[0, 1, 2, 3], [4, 5, 6, 7]])
    assert not two.imag.any()
    four = decode_frames(np.arange(8, dtype="<i2"), _layout(adc_format="real", lanes=4))
    np.testing.assert_array_equal(four[0, 0], [[0, 2, 4, 6], [1, 3, 5, 7]])


def test_samples_are_signed_int16_not_uint16():
    raw = np.array([-1, -32768, 32767, 0], "<i2").tobytes() * 4
    cube = decode_frames(np.frombuffer(raw, "<i2"), _layout(), convention="ti")
    assert cube[0, 0, 0, 0] == -1 + 32767j            # I0 = -1, Q0 = 32767
    assert cube[0, 0, 0, 1] == -32768 + 0j            # I1 = -32768 (0x8000), not +32768
    with pytest.raises(MeasuredFormatError, match="signed"):
        decode_frames(np.frombuffer(raw, "<u2"), _layout())


def test_tdm_chirps_become_virtual_channels_chirp_major():
    lay = _layout(num_samples=2, num_rx=2, chirps_per_loop=3, num_loops=2, adc_format="real")
    # file order [loop][chirp][rx][sample]: value = 1000 loop + 100 chirp + 10 rx + sample
    words = np.array([1000 * k + 100 * c + 10 * r + n for k in range(2) for c in range(3) for r in range(2)
                      for n in range(2)], "<i2")
    cube = decode_frames(words, lay).real
    assert cube.shape == (1, 2, 6, 2)
    for c in range(3):
        for r in range(2):
            np.testing.assert_array_equal(cube[0, 1, 2 * c + r], [1000 + 100 * c + 10 * r, 1001 + 100 * c + 10 * r])


def _shape(lay: RawLayout):
    return ref.Shape(N=lay.num_samples, R=lay.num_rx, C=lay.chirps_per_loop, K=lay.num_loops,
                     complex_=lay.is_complex, lanes=lay.lanes, q_first=lay.iq_swap)


@pytest.mark.parametrize("lanes", [2, 4])
@pytest.mark.parametrize("fmt", ["complex1x", "complex2x", "real"])
@pytest.mark.parametrize("swap", [False, True])
def test_decoder_and_encoder_each_agree_with_the_reference(lanes, fmt, swap):
    lay = RawLayout(num_samples=6, num_rx=3, chirps_per_loop=2, num_loops=3, adc_format=fmt, lanes=lanes, iq_swap=swap)
    rng = np.random.default_rng(1)
    shape = lay.cube_shape(2)
    i = rng.integers(-32768, 32768, shape)
    q = rng.integers(-32768, 32768, shape) if fmt != "real" else None
    data = ref.encode(i, q, _shape(lay))                                    # the reference writes the bytes
    assert len(data) == 2 * lay.frame_bytes
    out = decode_frames(np.frombuffer(data, "<i2"), lay, convention="ti")   # the project reads them
    np.testing.assert_array_equal(out.real, i)
    np.testing.assert_array_equal(out.imag, q if q is not None else 0)
    words = encode_frames(i.astype(np.int16), None if q is None else q.astype(np.int16), lay)
    i2, q2 = ref.decode(words.tobytes(), _shape(lay))                       # the project writes, the reference reads
    np.testing.assert_array_equal(i2, i)
    np.testing.assert_array_equal(q2, q if q is not None else 0)


def test_tone_lands_in_its_range_bin():
    lay = RawLayout(num_samples=64, num_rx=1, chirps_per_loop=1, num_loops=1)
    n = np.arange(64)
    ti = 8000 * np.exp(2j * np.pi * 11 * n / 64)            # TI data: target at a positive beat frequency
    i, q = np.rint(ti.real).astype(int), np.rint(ti.imag).astype(int)
    words = np.frombuffer(ref.encode(i.reshape(1, 1, 1, 64), q.reshape(1, 1, 1, 64), _shape(lay)), "<i2")
    paper = decode_frames(words, lay)[0, 0, 0]
    assert np.argmax(np.abs(np.fft.ifft(paper))) == 11        # eq. (2DDFT) sign, e^{+j2πpn/N}
    assert np.argmax(np.abs(np.fft.fft(decode_frames(words, lay, convention="ti")[0, 0, 0]))) == 11


def test_layout_rejects_impossible_settings():
    with pytest.raises(MeasuredFormatError, match="even"):
        RawLayout(num_samples=5, num_rx=1, chirps_per_loop=1, num_loops=1)
    with pytest.raises(MeasuredFormatError, match="lanes"):
        RawLayout(num_samples=4, num_rx=1, chirps_per_loop=1, num_loops=1, lanes=3)
    with pytest.raises(MeasuredFormatError, match="one receiver per lane"):
        RawLayout(num_samples=4, num_rx=5, chirps_per_loop=1, num_loops=1, lanes=4)

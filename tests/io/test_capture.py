"""Capture files (risloc_rt/capture.py): lossless round trip and clear errors on malformed files."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dsp import self_localize
from risloc_rt.model.capture import Capture
from risloc_rt.io.capture_file import CaptureFormatError, load_capture, save_capture
from risloc_rt.model.simulate import simulate


@pytest.fixture
def capture(make_scenario) -> Capture:
    scenario = make_scenario(mode="reflective", yaw=np.deg2rad(-12.0), ue_velocity=(0.5, -1.5, 0.0))
    return simulate(scenario, rng=np.random.default_rng(99), seed=99)


def test_round_trip_preserves_everything(capture, tmp_path):
    written = save_capture(capture, tmp_path / "run")
    assert written == tmp_path / "run.npz"
    loaded = load_capture(written)
    assert loaded.cube.dtype == capture.cube.dtype
    assert loaded.cube.tobytes() == capture.cube.tobytes()
    assert loaded.sweep.angles.tobytes() == capture.sweep.angles.tobytes()
    np.testing.assert_array_equal(loaded.frame_index, capture.frame_index)
    assert loaded.radar == capture.radar
    assert loaded.processing == capture.processing
    assert loaded.ris.to_dict() == capture.ris.to_dict()
    np.testing.assert_array_equal(loaded.ris.pose.normal, capture.ris.pose.normal)
    assert loaded.truth.to_dict() == capture.truth.to_dict()
    assert loaded.provenance == capture.provenance
    assert loaded.provenance["seed"] == 99


def test_round_trip_gives_the_same_localization(capture, tmp_path):
    loaded = load_capture(save_capture(capture, tmp_path / "run.npz"))
    a, b = (self_localize(c.cube, sweep=c.sweep, radar=c.radar, processing=c.processing, pose=c.ris.pose,
                          loopback_delay=c.ris.loopback_delay) for c in (capture, loaded))
    assert a.beam_index == b.beam_index
    np.testing.assert_array_equal(a.position, b.position)
    np.testing.assert_array_equal(a.scan.average_power, b.scan.average_power)


def test_complex64_cube_keeps_its_dtype(capture, tmp_path):
    small = dataclasses.replace(capture, cube=capture.cube.astype(np.complex64))
    loaded = load_capture(save_capture(small, tmp_path / "c64"))
    assert loaded.cube.dtype == np.complex64
    assert loaded.cube.tobytes() == small.cube.astype(np.complex64).tobytes()


def test_capture_without_truth_round_trips(capture, tmp_path):
    loaded = load_capture(save_capture(dataclasses.replace(capture, truth=None), tmp_path / "nt"))
    assert loaded.truth is None


@pytest.mark.parametrize("array", ["beam_angles", "cube", "frame_index", "metadata"])
def test_missing_array_is_named(capture, tmp_path, array, rewrite):
    path = rewrite(save_capture(capture, tmp_path / "run"), drop=(array,))
    with pytest.raises(CaptureFormatError, match=rf"missing array\(s\) \['{array}'\]"):
        load_capture(path)


@pytest.mark.parametrize("key", ["radar", "ris", "processing", "provenance", "truth"])
def test_missing_metadata_block_is_named(capture, tmp_path, key, rewrite):
    path = rewrite(save_capture(capture, tmp_path / "run"), meta=lambda m: m.pop(key))
    with pytest.raises(CaptureFormatError, match=rf"metadata is missing \['{key}'\]"):
        load_capture(path)


@pytest.mark.parametrize("block, field", [("radar", "bandwidth"), ("radar", "chirp_duration"),
                                          ("processing", "n_dft"), ("ris", "loopback_delay"),
                                          ("truth", "aod")])
def test_missing_field_is_named(capture, tmp_path, block, field, rewrite):
    # Nothing is taken from a default on reading: a missing field is an error naming it.
    path = rewrite(save_capture(capture, tmp_path / "run"), meta=lambda m: m[block].pop(field))
    with pytest.raises(CaptureFormatError, match=rf"{block}: missing field\(s\) \['{field}'\]"):
        load_capture(path)


def test_wrong_format_or_version(capture, tmp_path, rewrite):
    saved = save_capture(capture, tmp_path / "run")
    with pytest.raises(CaptureFormatError, match="not 'risloc-capture'"):
        load_capture(rewrite(saved, meta=lambda m: m.update(format="something-else")))
    with pytest.raises(CaptureFormatError, match="version 2 is not supported"):
        load_capture(rewrite(saved, meta=lambda m: m.update(version=2)))


def test_inconsistent_shapes(capture, tmp_path, rewrite):
    saved = save_capture(capture, tmp_path / "run")
    # Metadata says N = 64, the cube has 128 samples per chirp.
    with pytest.raises(CaptureFormatError, match="N=64 samples"):
        load_capture(rewrite(saved, meta=lambda m: m["radar"].update(num_samples=64)))
    # One beam angle fewer than frames.
    with pytest.raises(CaptureFormatError, match="sweep has 60 beam angles"):
        load_capture(rewrite(saved, arrays={"beam_angles": capture.sweep.angles[:-1]}))
    # Beam angles in degrees.
    with pytest.raises(CaptureFormatError, match="Angles are in radians"):
        load_capture(rewrite(saved, arrays={"beam_angles": np.rad2deg(capture.sweep.angles)}))


def test_not_a_capture(tmp_path):
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"this is not a zip archive")
    with pytest.raises(CaptureFormatError, match="not a readable .npz capture"):
        load_capture(junk)
    with pytest.raises(FileNotFoundError, match="does not exist"):
        load_capture(tmp_path / "absent.npz")

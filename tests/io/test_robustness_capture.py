"""Issue 11 regressions for capture files: real cubes, damaged archives, metadata types and ranges,
memory bounds, concurrent and interrupted writers."""

from __future__ import annotations

import dataclasses
import multiprocessing
import os
import signal
import subprocess
import sys

import numpy as np
import pytest

from dsp.budget import BudgetError, check_memory, dsp_memory, parse_bytes
from risloc_rt.io.capture_file import CaptureFormatError, load_capture, save_capture


@pytest.mark.parametrize("dtype", [np.float64, np.float32, np.int16, np.bool_])
def test_issue_11_real_integer_boolean_cubes_are_refused(capture, tmp_path, dtype, rewrite):
    # Defect 2: a real ADC cube was cast to complex and localized 5.5 m off; now refused, never guessed.
    with pytest.raises(TypeError, match="real-valued.*analytic signal"):
        dataclasses.replace(capture, cube=capture.cube.real.astype(dtype))
    path = save_capture(capture, tmp_path / "c.npz")
    bad = rewrite(path, arrays={"cube": capture.cube.real.astype(dtype)})
    with pytest.raises(CaptureFormatError, match="cube has dtype .*complex64 or complex128"):
        load_capture(bad)


def test_issue_11_flipped_bytes_and_truncation_are_format_errors(capture, tmp_path):
    # Defect 5: BadZipFile tracebacks. Every single flipped byte and every truncation is a clear error
    # (or, where the byte is not covered by the CRC such as zip padding, a capture equal to the original).
    path = save_capture(capture, tmp_path / "c.npz")
    data = path.read_bytes()
    rng = np.random.default_rng(0)
    for pos in rng.choice(len(data), 60, replace=False):
        damaged = bytearray(data)
        damaged[pos] ^= 0xFF
        (tmp_path / "d.npz").write_bytes(bytes(damaged))
        try:
            got = load_capture(tmp_path / "d.npz")
        except (CaptureFormatError, BudgetError):
            continue
        assert got.cube.tobytes() == capture.cube.tobytes(), f"byte {pos} changed the cube silently"
    for cut in (0, 10, len(data) // 2, len(data) - 1):
        (tmp_path / "t.npz").write_bytes(data[:cut])
        with pytest.raises(CaptureFormatError):
            load_capture(tmp_path / "t.npz")


@pytest.mark.parametrize("block,field,value,match", [
    ("radar", "bandwidth", True, "must be a number"),
    ("radar", "bandwidth", 1e-300, "physical range"),
    ("radar", "chirp_duration", 1e-30, r"physical range 1e-08 s"),
    ("radar", "num_chirps", 16.5, "integer"),
    ("processing", "k_dft", "4793", "must be a number"),
])
def test_issue_11_absurd_metadata_values_are_refused_with_units(capture, tmp_path, block, field, value, match,
                                                               rewrite):
    path = save_capture(capture, tmp_path / "c.npz")
    bad = rewrite(path, meta=lambda m: m[block].__setitem__(field, value))
    with pytest.raises(CaptureFormatError, match=match):
        load_capture(bad)


def test_issue_11_unknown_top_level_key_suggests_the_nearest(capture, tmp_path, rewrite):
    path = save_capture(capture, tmp_path / "c.npz")
    bad = rewrite(path, meta=lambda m: m.__setitem__("proccessing", {}))
    with pytest.raises(CaptureFormatError, match="did you mean 'processing'"):
        load_capture(bad)


def test_issue_11_huge_k_dft_is_refused_before_allocating(capture, tmp_path, monkeypatch, rewrite):
    # Defect 4: k_dft = 1e9 grew to 17 GB and hung; now refused naming the parameter, estimate and limit.
    path = save_capture(capture, tmp_path / "c.npz")
    bad = rewrite(path, meta=lambda m: m["processing"].__setitem__("k_dft", 10**9))
    with pytest.raises(BudgetError, match=r"k_dft=1000000000.*needs about .*iB of memory, more than the limit"):
        load_capture(bad)
    monkeypatch.setenv("RISLOC_MEMORY_LIMIT", "1K")
    with pytest.raises(BudgetError, match=r"\$RISLOC_MEMORY_LIMIT"):
        load_capture(path)


def test_budget_helpers():
    assert parse_bytes("8G") == 8 << 30 and parse_bytes("512M") == 512 << 20 and parse_bytes("1e3") == 1000
    with pytest.raises(ValueError):
        parse_bytes("lots")
    assert check_memory(10, "x", limit=10) == 10
    with pytest.raises(BudgetError, match="x needs about 11 B"):
        check_memory(11, "x", limit=10)
    # Table I: the fast-time transform (61 x 128 x 1199) and one 4793 x 1199 map dominate.
    assert 200e6 < dsp_memory((61, 128, 600), n_dft=1199, k_dft=4793) < 1e9


def _writer(path: str, seed: int) -> None:
    from risloc_rt.io.capture_file import load_capture, save_capture  # noqa: F401 - fresh process

    cap = np.load(path + ".src.npy", allow_pickle=True).item()
    for _ in range(5):
        save_capture(cap, path)


def test_issue_11_concurrent_writers_leave_one_valid_file(capture, tmp_path):
    # Defect 3: the temporary file had a fixed name; 4 of 10 concurrent runs corrupted the output.
    target = tmp_path / "same.npz"
    np.save(str(target) + ".src.npy", np.array(capture, dtype=object), allow_pickle=True)
    ctx = multiprocessing.get_context("fork")
    procs = [ctx.Process(target=_writer, args=(str(target), i)) for i in range(4)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(60)
        assert p.exitcode == 0
    assert load_capture(target).cube.tobytes() == capture.cube.tobytes()
    assert not [p.name for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporary files left


def test_issue_11_sigkill_during_simulate_leaves_no_partial_file_and_rerun_is_bit_identical(tmp_path):
    # Fault tolerance: kill 'risloc simulate' at several moments; the output is absent or complete,
    # never half-written, and a clean run afterwards gives the same bits as an uninterrupted one.
    out = tmp_path / "run.npz"
    cmd = [sys.executable, "-m", "risloc_rt", "simulate", "--no-noise", "-o", str(out)]
    reference = tmp_path / "ref.npz"
    subprocess.run(cmd[:-1] + [str(reference)], check=True, capture_output=True, timeout=300)
    for delay in (0.5, 1.5, 3.0):
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            proc.wait(delay)
        except subprocess.TimeoutExpired:
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait()
        if out.exists():
            assert load_capture(out).cube.tobytes() == load_capture(reference).cube.tobytes()
        for leftover in tmp_path.glob(".run.npz.*.tmp"):
            leftover.unlink()  # a killed writer may leave its unique temporary file, never the output
    subprocess.run(cmd, check=True, capture_output=True, timeout=300)
    assert load_capture(out).cube.tobytes() == load_capture(reference).cube.tobytes()

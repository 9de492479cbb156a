"""Issue 19 item 3: sizes a capture file declares are checked against $RISLOC_MEMORY_LIMIT before anything of
that size is allocated (the RIS's num_rows x num_columns, the decompressed size of every array read)."""

from __future__ import annotations

import io
import json
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from dsp.budget import BudgetError
from risloc_rt.io.capture_file import load_capture, save_capture
from risloc_rt.model.ris import ris_response, ris_response_memory

#: Peak RSS of a child refused by a size check may exceed the limit by no more than this [bytes]
#: (the interpreter with numpy and scipy imported is about 110 MiB).
RSS_MARGIN = 200 << 20


def _ris(n_rows: int, n_columns: int):
    def edit(meta: dict) -> None:
        meta["ris"].update(num_rows=n_rows, num_columns=n_columns)
    return edit


def _member(zf: zipfile.ZipFile, name: str, shape: tuple[int, ...], dtype, *, data_bytes: int | None = None) -> None:
    """A ``.npy`` member whose header declares ``shape``; its data are ``data_bytes`` zeros (default: all of
    them, streamed through deflate without building the array)."""
    head = io.BytesIO()
    np.lib.format.write_array_header_1_0(head, {"descr": np.lib.format.dtype_to_descr(np.dtype(dtype)),
                                                "fortran_order": False, "shape": shape})
    n = int(np.prod(shape)) * np.dtype(dtype).itemsize if data_bytes is None else data_bytes
    chunk = bytes(1 << 24)
    with zf.open(f"{name}.npy", "w", force_zip64=True) as fh:
        fh.write(head.getvalue())
        while n > 0:
            fh.write(chunk[:min(n, len(chunk))])
            n -= len(chunk)


def zip_bomb(good: Path, out: Path, *, beams: int = 15_000_000, full: bool = True) -> Path:
    """A deflated capture whose arrays declare 3.6 GB (beams x 1 x 1 cube, 5 beams' angles and 10 frame indices
    per beam), with the metadata of ``good`` and n_dft = k_dft = 1 so that the DSP estimate stays small.
    ``full=False`` writes the headers with 16 bytes of data each (a truncated archive, written in no time)."""
    with np.load(good, allow_pickle=False) as f:
        meta = json.loads(str(f["metadata"]))
    meta["processing"].update(n_dft=1, k_dft=1)
    data = None if full else 16
    with zipfile.ZipFile(out, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        _member(zf, "cube", (beams, 1, 1), np.complex64, data_bytes=data)
        _member(zf, "beam_angles", (5 * beams, 2), np.float64, data_bytes=data)
        _member(zf, "frame_index", (10 * beams,), np.int64, data_bytes=data)
        with zf.open("metadata.npy", "w") as fh:
            np.lib.format.write_array(fh, np.array(json.dumps(meta)))
    return out


def test_ris_elements_in_metadata_are_checked_before_the_response(capture, tmp_path, rewrite, monkeypatch):
    # 1500 x 1500 elements x 61 beams reached 4.4 GB of RSS under RISLOC_MEMORY_LIMIT=1G in 'risloc locate'.
    monkeypatch.setenv("RISLOC_MEMORY_LIMIT", "1G")
    path = rewrite(save_capture(capture, tmp_path / "c.npz"), meta=_ris(1500, 1500))
    with pytest.raises(BudgetError, match=r"edited\.npz: metadata ris: num_rows = 1,500 x num_columns = 1,500 "
                                          r"\(2,250,000 elements\) x 61 beams needs about 4\.31 GiB .*limit 1 GiB"):
        load_capture(path)
    # The paper's 16 x 4 RIS loads under the same limit.
    assert load_capture(save_capture(capture, tmp_path / "ok.npz")).ris.num_elements == 64


def test_ris_response_refuses_before_allocating(capture, monkeypatch):
    # Every caller of ris_response (simulation, pruning, the link-budget check) is covered, with M and L.
    monkeypatch.setenv("RISLOC_MEMORY_LIMIT", "1G")
    from dataclasses import replace

    ris = replace(capture.ris, num_rows=6000, num_columns=6000)
    angle = np.zeros((3, 2))
    with pytest.raises(BudgetError, match=r"num_rows = 6,000 x num_columns = 6,000 .* x 61 beams x 3 paths"):
        ris_response(ris, capture.sweep, angle, angle, wavelength=capture.radar.wavelength)
    # The formula: 8 N (6 + 7 L + 4 M).
    assert ris_response_memory(64, 61, 2) == 8 * 64 * (6 + 14 + 244)


def test_decompressed_array_sizes_are_checked_from_the_headers(capture, tmp_path, monkeypatch):
    # A 2.4 MB deflated archive declaring 3.6 GB reached 3.7 GB of RSS before it was found to be no capture.
    monkeypatch.setenv("RISLOC_MEMORY_LIMIT", "1G")
    good = save_capture(capture, tmp_path / "good.npz")
    bomb = zip_bomb(good, tmp_path / "bomb.npz", full=False)
    with pytest.raises(BudgetError, match=r"bomb\.npz: the arrays cube \[15000000, 1, 1\] complex64, beam_angles "
                                          r"\[75000000, 2\] float64, frame_index \[150000000\] int64.* needs about "
                                          r"2\.35 GiB .*decompressed size"):
        load_capture(bomb)


@pytest.mark.slow
def test_hostile_captures_stay_within_the_limit_in_a_child(capture, tmp_path, rewrite):
    """``risloc locate`` on the worst captures, in a child under RISLOC_MEMORY_LIMIT=1G: exit 2, one line on
    stderr naming the field, and a peak RSS below the limit + 200 MB."""
    good = save_capture(capture, tmp_path / "good.npz")
    cases = {"metadata ris: num_rows = 6,000": rewrite(good, meta=_ris(6000, 6000)).rename(tmp_path / "ris6000.npz"),
             "beam_angles [75000000, 2]": zip_bomb(good, tmp_path / "bomb.npz")}
    assert os.path.getsize(cases["beam_angles [75000000, 2]"]) < 10 << 20  # small file, 3.6 GB declared
    limit = 1 << 30
    probe = ("import resource, subprocess, sys; r = subprocess.run(sys.argv[1:], capture_output=True, text=True); "
             "print(r.returncode); print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024); "
             "sys.stderr.write(r.stderr)")
    for field, path in cases.items():
        done = subprocess.run([sys.executable, "-c", probe, sys.executable, "-m", "risloc_rt", "locate", str(path)],
                              capture_output=True, text=True, timeout=300,
                              env={**os.environ, "RISLOC_MEMORY_LIMIT": "1G"})
        status, peak = (int(v) for v in done.stdout.split())
        lines = done.stderr.strip().splitlines()
        assert status == 2, (field, done.stderr)
        assert len(lines) == 1 and field in lines[0] and "more than the limit 1 GiB" in lines[0], lines
        assert peak < limit + RSS_MARGIN, f"{field}: peak RSS {peak / 2**20:.0f} MiB"

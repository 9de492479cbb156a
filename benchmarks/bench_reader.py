"""Benchmark: DCA1000 raw-capture reader throughput and peak memory on a multi-gigabyte file.

Generates a capture of ``--size-gb`` GB (IWR6843 3 Tx x 4 Rx TDM, 256 complex samples, 64 loops:
768 KiB per frame) in a temporary folder, in raw and/or packet-recorded form, reads it back with
``risloc_rt.measured.iter_frames`` in a child process (so the peak RSS is the reader's alone) and
deletes it. Every frame carries its index in its first I word and a tone at range bin 38; the
reader checks both on every frame, so speed and correctness are printed side by side. The file
was just written, so it is read from the page cache: the figure is decoding speed, not disk speed.

    .venv/bin/python benchmarks/bench_reader.py [--size-gb 2] [--forms raw,packets] [--frames-per-block 8]
"""

from __future__ import annotations

import argparse
import json
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from risloc_rt.measured import RawLayout, encode_frames, iter_frames, open_raw
from risloc_rt.measured.dca1000.split_files import SplitWriter
from risloc_rt.measured.dca1000.packets import PacketRecorder

LAYOUT = RawLayout(num_samples=256, num_rx=4, chirps_per_loop=3, num_loops=64)
TONE_BIN = 38
TILE = 16                                                      # frames written per call


def base_frames() -> np.ndarray:
    """int16 words of TILE frames holding a tone at TONE_BIN (TI convention: positive frequency)."""
    n = np.arange(LAYOUT.num_samples)
    tone = 8000 * np.exp(2j * np.pi * TONE_BIN * n / LAYOUT.num_samples)
    rng = np.random.default_rng(0)
    cube = np.broadcast_to(tone, LAYOUT.cube_shape(TILE)) + 50 * (rng.normal(size=LAYOUT.cube_shape(TILE))
                                                                  + 1j * rng.normal(size=LAYOUT.cube_shape(TILE)))
    i, q = np.rint(cube.real).astype(np.int16), np.rint(cube.imag).astype(np.int16)
    return encode_frames(i, q, LAYOUT)


def generate(folder: Path, form: str, frames: int) -> list[Path]:
    words = base_frames().reshape(TILE, -1)
    writer = SplitWriter(folder, "adc_data", max_file_size=1 << 30, record_size=1466 if form == "packets" else None)
    sink = PacketRecorder(writer) if form == "packets" else writer
    with writer:
        for start in range(0, frames, TILE):
            k = min(TILE, frames - start)
            words[:, 0] = (np.arange(start, start + TILE) % 32768).astype(np.int16)   # frame counter in I0
            sink.write(words[:k].reshape(-1).view(np.uint8).data)
        files = sink.close()
    return list(files)


def read(path: str, frames_per_block: int) -> dict:
    info = open_raw(path, LAYOUT, form="auto")
    t0 = time.perf_counter()
    ok_counter = ok_tone = frames = 0
    for block in iter_frames(info, frames_per_block=frames_per_block, convention="ti"):
        cube = block.cube
        idx = np.arange(block.first_frame, block.first_frame + len(cube)) % 32768
        ok_counter += int(np.count_nonzero(cube[:, 0, 0, 0].real == idx))
        spec = np.abs(np.fft.fft(cube[:, 1, 0, :], axis=-1))                      # one chirp per frame
        ok_tone += int(np.count_nonzero(np.argmax(spec, axis=-1) == TONE_BIN))
        frames += len(cube)
    elapsed = time.perf_counter() - t0
    return {"form": info.form, "frames": frames, "bytes": info.stream_bytes, "files": len(info.files),
            "seconds": elapsed, "ok_counter": ok_counter, "ok_tone": ok_tone,
            "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size-gb", type=float, default=2.0)
    ap.add_argument("--forms", default="raw,packets")
    ap.add_argument("--frames-per-block", type=int, default=8)
    ap.add_argument("--_read", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args._read:
        print(json.dumps(read(args._read, args.frames_per_block)))
        return
    frames = int(args.size_gb * 1e9 // LAYOUT.frame_bytes)
    print(f"risloc-rt raw-reader benchmark: {frames} frames x {LAYOUT.frame_bytes} bytes "
          f"({frames * LAYOUT.frame_bytes / 1e9:.2f} GB), {LAYOUT.describe()}; "
          f"{platform.processor() or platform.machine()}, numpy {np.__version__}")
    print(f"{'form':<8} {'files':>5} {'write [s]':>9} {'read [s]':>8} {'MB/s':>7} {'peak RSS [MB]':>13} "
          f"{'frames':>7} {'counter ok':>10} {'tone ok':>8}")
    for form in args.forms.split(","):
        with tempfile.TemporaryDirectory(prefix="bench_reader_") as tmp:
            t0 = time.perf_counter()
            files = generate(Path(tmp), form, frames)
            t_write = time.perf_counter() - t0
            out = subprocess.run([sys.executable, __file__, "--_read", str(files[0]),
                                  "--frames-per-block", str(args.frames_per_block)],
                                 capture_output=True, text=True, check=True)
            r = json.loads(out.stdout)
            print(f"{r['form']:<8} {r['files']:>5} {t_write:>9.1f} {r['seconds']:>8.1f} "
                  f"{r['bytes'] / r['seconds'] / 1e6:>7.0f} {r['peak_rss_mb']:>13.0f} {r['frames']:>7} "
                  f"{r['ok_counter'] == frames!s:>10} {r['ok_tone'] == frames!s:>8}")


if __name__ == "__main__":
    main()

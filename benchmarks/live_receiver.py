"""Live receiver benchmark: DatagramReceiver + RecordingWriter against the emulated DCA1000 on loopback.

The emulated DCA1000 (``risloc_rt.measured.emulate.dca1000_server``) runs in a *separate process*
(so its sender does not share the receiver's interpreter lock) on 127.0.0.2 and streams a source
file to 127.0.0.1 at a multiple of Table I's data rate (600 samples x 128 chirps, complex 16-bit,
one receiver: 307,200 bytes per 6.4 ms frame = 48 MB/s) and at the DCA1000EVM's maximum
(600 Mbit/s = 75 MB/s, TI E2E thread 927693, ``ti.devices.DCA1000_ETHERNET_RATE``). This process
configures it over the real protocol (``Dca1000Link``), receives with the receive-only thread and
writes the recording to a temporary folder exactly as ``risloc capture record`` does. Reported per
rate: what the sender sent, the datagrams the receiver lost (sent - received; must be 0), the
kernel's drops (``SO_MEMINFO``), the rate sustained at the receiver [MB/s], the socket buffer's
high-water mark, the largest queue between the thread and the writer, and whether the recording
equals the source.

    .venv/bin/python benchmarks/live_receiver.py [--seconds 3] [--max-bytes 400e6] [--rates 1,4,16,dca] [--rcvbuf BYTES]

Nothing leaves 127.0.0.0/8. Every run writes up to ``--max-bytes`` to a temporary folder (removed).
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import platform
import shutil
import socket
import tempfile
import time
from pathlib import Path

import numpy as np

TABLE_I_FRAME_BYTES = 600 * 128 * 4          # N samples x K chirps x (I, Q) x 2 bytes, one receiver
TABLE_I_FRAME_PERIOD = 6.4e-3                # dsp.RadarConfig().frame_interval [s]
TABLE_I_RATE = TABLE_I_FRAME_BYTES / TABLE_I_FRAME_PERIOD
DCA1000_RATE = 600e6 / 8                     # ti.devices.DCA1000_ETHERNET_RATE [bytes/s]


def free_port_pair() -> tuple[int, int]:
    """Two UDP ports free on 127.0.0.1 and 127.0.0.2."""
    ports = []
    while len(ports) < 2:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as a:
            a.bind(("127.0.0.1", 0))
            port = a.getsockname()[1]
            try:
                with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as b:
                    b.bind(("127.0.0.2", port))
            except OSError:
                continue
        if port not in ports:
            ports.append(port)
    return ports[0], ports[1]


def write_source(path: Path, nbytes: int, seed: int = 0) -> None:
    """``nbytes`` of random bytes (a 4 MiB random block repeated with a changing first word)."""
    block = np.random.default_rng(seed).integers(0, 256, 4 << 20, dtype=np.uint8)
    with open(path, "wb") as fh:
        k, left = 0, nbytes
        while left > 0:
            block[:8] = np.frombuffer(k.to_bytes(8, "little"), np.uint8)
            fh.write(block[:min(left, block.size)].tobytes())
            left -= block.size
            k += 1


def emulator(conn, source: str, frame_bytes: int, frame_period: float, speed: float, ports) -> None:
    """Child process: the emulated DCA1000 until told to stop; sends back what it sent."""
    from risloc_rt.measured.emulate.dca1000_server import EmulatedDca1000

    with EmulatedDca1000(Path(source), frame_bytes=frame_bytes, frame_period=frame_period, speed=speed,
                         config_port=ports[0], data_port=ports[1]) as dca:
        conn.send("ready")
        conn.recv()                                   # the parent received the whole stream
        conn.send((len(dca.sent_sequences), len(dca.lost_sequences), dca.stream_bytes))


def run_case(label: str, rate: float, seconds: float, max_bytes: float, tmp: Path, rcvbuf: int) -> dict:
    """One rate: stream, receive, write; the figures of the table."""
    from risloc_rt.measured.dca1000.control import FpgaConfig, PacketConfig
    from risloc_rt.measured.live.addresses import Endpoints
    from risloc_rt.measured.live.dca1000_link import Dca1000Link
    from risloc_rt.measured.live.receiver import DatagramReceiver
    from risloc_rt.measured.live.recording_writer import RecordingWriter

    nbytes = int(min(rate * seconds, max_bytes)) // TABLE_I_FRAME_BYTES * TABLE_I_FRAME_BYTES
    source = tmp / f"source_{label}.bin"
    write_source(source, nbytes)
    ports = free_port_pair()
    ep = Endpoints.loopback(*ports)
    parent, child = mp.get_context("spawn").Pipe()
    proc = mp.get_context("spawn").Process(target=emulator, args=(child, str(source), TABLE_I_FRAME_BYTES,
                                                                  TABLE_I_FRAME_PERIOD, rate / TABLE_I_RATE, ports))
    proc.start()
    out = tmp / f"rec_{label}"
    try:
        assert parent.recv() == "ready"
        with DatagramReceiver(ep, rcvbuf=rcvbuf, silence_timeout=0.5) as rx, RecordingWriter(out) as w, \
                Dca1000Link(ep, timeout=2.0) as link:
            link.connect()
            link.configure(FpgaConfig(lanes=2, data_bits=16), PacketConfig(delay=5e-6))   # the fastest pacing
            link.start_record()
            queue_max, t0 = 0, time.monotonic()
            while not rx.silent and (rx.first_time is not None or time.monotonic() - t0 < 5.0):
                d = rx.get(timeout=0.05)
                queue_max = max(queue_max, rx.queued)
                while d is not None:
                    w.write(d)
                    d = rx.get_nowait()
                w.tick()
                if w.stream_bytes >= nbytes:
                    break
            link.stop_record()
            rx.stop(drain=0.1)
            d = rx.get_nowait()
            while d is not None:
                w.write(d)
                d = rx.get_nowait()
            stats = rx.stats()
        parent.send("done")
        sent, sender_lost, stream = parent.recv()
    finally:
        proc.join(timeout=30)
        if proc.is_alive():
            proc.kill()
    same = (out / "adc_data_Raw_0.bin").stat().st_size == nbytes and _same(out, source)
    shutil.rmtree(out, ignore_errors=True)
    source.unlink()
    span = stats.last_time - stats.first_time
    return {"case": label, "asked MB/s": rate / 1e6, "bytes": nbytes, "sent": sent, "received": stats.datagrams,
            "not received": sent - stats.datagrams, "kernel drops": stats.kernel_drops,
            "MB/s": (stats.bytes - 10 * stats.datagrams) / span / 1e6 if span > 0 else float("nan"),
            "high-water kB": stats.high_water / 1e3, "queue max": queue_max, "zero-filled": len(w.lost),
            "equal": same, "rcvbuf MB": rx.buffer.granted / 1e6}


def _same(folder: Path, source: Path) -> bool:
    files = sorted(folder.glob("adc_data_Raw_*.bin"), key=lambda p: int(p.stem.rsplit("_", 1)[1]))
    with open(source, "rb") as src:
        for f in files:
            with open(f, "rb") as fh:
                while True:
                    a = fh.read(1 << 22)
                    if not a:
                        break
                    if src.read(len(a)) != a:
                        return False
        return not src.read(1)


def main() -> None:
    """Parse the options, run every rate, print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=3.0, help="stream length per rate [s] (default 3)")
    ap.add_argument("--max-bytes", type=float, default=400e6, help="largest stream per rate [bytes]")
    ap.add_argument("--rates", default="1,4,16,dca", help="multiples of Table I's rate, 'dca' = 75 MB/s")
    ap.add_argument("--rcvbuf", type=int, default=64 << 20,
                    help="receive buffer to ask for [bytes] (212992: a stock Linux rmem_max; default 64 MiB)")
    args = ap.parse_args()
    rates = [(f"{r}x Table I", float(r) * TABLE_I_RATE) if r != "dca" else ("DCA1000 max", DCA1000_RATE)
             for r in args.rates.split(",")]
    print(f"{platform.node()}: {os.cpu_count()} cores, Python {platform.python_version()}, "
          f"rmem_max {Path('/proc/sys/net/core/rmem_max').read_text().strip()} B; Table I rate "
          f"{TABLE_I_RATE / 1e6:.1f} MB/s")
    tmp = Path(tempfile.mkdtemp(prefix="risloc-live-bench-"))
    try:
        rows = [run_case(label.split()[0].replace("x", "") if "x" in label else "dca", rate, args.seconds,
                         args.max_bytes, tmp, args.rcvbuf) | {"case": label} for label, rate in rates]
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    keys = ["case", "asked MB/s", "MB/s", "bytes", "sent", "received", "not received", "kernel drops",
            "high-water kB", "queue max", "zero-filled", "equal", "rcvbuf MB"]
    print(" | ".join(keys))
    for row in rows:
        print(" | ".join(f"{row[k]:.1f}" if isinstance(row[k], float) else str(row[k]) for k in keys))


if __name__ == "__main__":
    main()

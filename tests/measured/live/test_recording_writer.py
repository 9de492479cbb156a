"""RecordingWriter: DCA1000 datagrams -> the raw-mode files, packet log and lost-packet list TI's CLI would write.

Expected bytes come from a test-side packet builder and reader that import nothing from ``risloc_rt``:

- data datagram (TI DCA1000EVM user's guide, SPRUIJ4, data-port raw-mode packet format): ``<u4``
  sequence number from 1, 48-bit little-endian byte count of the data sent before the packet, up
  to 1456 data bytes;
- raw-mode files (TI's DCA1000 CLI, ``DCA1000EVM_CLI_Record``, ``recorddatarecv.cpp``): payloads only,
  a lost packet's bytes zero at their offset, ``<prefix>_Raw_<i>.bin`` cut at the largest multiple of
  1456 bytes not above ``maxRecFileSize_MB`` MiB; packet log ``<prefix>_Raw_LogFile.csv`` with one
  ``,offset,bytes,`` line per zero-filled run and the summary lines (out-of-sequence count, first and
  last packet ID, received packets, zero-filled packets and bytes, duration).
"""

from __future__ import annotations

import re
import signal
import struct
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from risloc_rt.measured.errors import MeasuredFormatError
from risloc_rt.measured.live.recording_writer import RecordingWriter

P = 1456                                   # DCA1000EVM user's guide: data bytes per packet


# -- test-side builder and reader (no risloc_rt) -------------------------------------------------------

def datagram(seq: int, offset: int, payload: bytes) -> bytes:
    """A DCA1000 data datagram: u32 sequence, u48 byte count, payload (little-endian)."""
    return struct.pack("<I", seq) + offset.to_bytes(6, "little") + payload


def packets_of(stream: bytes) -> list[bytes]:
    """The stream cut into datagrams of P bytes (the last shorter), sequence from 1."""
    return [datagram(k // P + 1, k, stream[k:k + P]) for k in range(0, len(stream), P)]


def split_files(folder: Path, prefix: str = "adc_data") -> list[Path]:
    found = {int(m[1]): q for q in folder.iterdir() if (m := re.fullmatch(rf"{prefix}_Raw_(\d+)\.bin", q.name))}
    assert sorted(found) == list(range(len(found)))
    return [found[i] for i in sorted(found)]


def read_stream(folder: Path) -> bytes:
    return b"".join(p.read_bytes() for p in split_files(folder))


def zeroed(stream: bytes, lost_indices) -> bytes:
    out = bytearray(stream)
    for j in lost_indices:
        out[j * P:(j + 1) * P] = bytes(len(out[j * P:(j + 1) * P]))
    return bytes(out)


def read_log(folder: Path) -> tuple[list[tuple[int, int]], dict[str, str]]:
    text = (folder / "adc_data_Raw_LogFile.csv").read_text()
    runs = [(int(a), int(b)) for a, b in re.findall(r"^,(\d+),(\d+),$", text, re.M)]
    fields = dict(re.findall(r"^([A-Za-z][^-\n]*?) - (.*)$", text, re.M))
    return runs, fields


def read_lost_csv(folder: Path) -> list[tuple[int, int, int, int]]:
    lines = (folder / "lost_packets.csv").read_text().splitlines()
    assert lines[0] == "first_sequence,count,stream_offset,num_bytes"
    return [tuple(int(x) for x in ln.split(",")) for ln in lines[1:]]


@pytest.fixture
def stream() -> bytes:
    rng = np.random.default_rng(7)
    return rng.integers(1, 256, 40 * P + 300, dtype=np.uint8).tobytes()      # no zero byte: zeros mean fill


def test_in_order_payloads_are_the_stream_and_files_cut_on_whole_packets(tmp_path, stream):
    split = 7 * P + 5                                    # TI's cut: the largest multiple of 1456 below it
    with RecordingWriter(tmp_path / "rec", split_size=split) as w:
        for d in packets_of(stream):
            w.write(d)
    folder = tmp_path / "rec"
    files = split_files(folder)
    assert [f.stat().st_size for f in files[:-1]] == [7 * P] * (len(files) - 1)
    assert len(files) == -(-len(stream) // (7 * P))
    assert read_stream(folder) == stream
    assert w.final_bytes == len(stream) and w.lost == []
    runs, fields = read_log(folder)
    assert runs == []
    assert fields["First Packet ID"] == "1" and fields["Last Packet ID"] == str(len(packets_of(stream)))
    assert fields["Number of received packets"] == str(len(packets_of(stream)))
    assert fields["Number of zero filled packets"] == "0" and fields["Out of sequence count"] == "0"
    assert read_lost_csv(folder) == []


def test_lost_packets_are_zero_at_their_offset_and_listed(tmp_path, stream):
    pk = packets_of(stream)
    lost = [0, 5, 6, 20]                                  # the first one, a pair, a single one
    with RecordingWriter(tmp_path / "rec") as w:
        for j, d in enumerate(pk):
            if j not in lost:
                w.write(d)
    folder = tmp_path / "rec"
    assert read_stream(folder) == zeroed(stream, lost)
    expected = [(1, 1, 0, P), (6, 2, 5 * P, 2 * P), (21, 1, 20 * P, P)]   # 1-based sequences
    assert read_lost_csv(folder) == expected
    runs, fields = read_log(folder)
    assert runs == [(off, n) for _, _, off, n in expected]
    assert fields["Number of zero filled packets"] == "4"
    assert fields["Number of zero filled bytes"] == str(4 * P)
    assert fields["Number of received packets"] == str(len(pk) - 4)
    assert [(d.first_sequence, d.count, d.stream_offset, d.num_bytes) for d in w.lost] == expected


def test_reordering_within_the_window_loses_nothing(tmp_path, stream):
    pk = packets_of(stream)
    order = list(range(len(pk)))
    order[3], order[4] = order[4], order[3]
    order.insert(25, order.pop(15))                       # packet 16 arrives ten packets late
    with RecordingWriter(tmp_path / "rec", reorder_window=16) as w:
        for j in order:
            w.write(pk[j])
    assert read_stream(tmp_path / "rec") == stream
    assert w.lost == [] and w.duplicates == 0 and w.late == 0
    seqs = [j + 1 for j in order]                          # TI's count: a sequence that is not previous + 1
    expected_oos = sum(1 for a, b in zip(seqs, seqs[1:]) if b != a + 1)
    assert w.out_of_sequence == expected_oos > 0
    assert read_log(tmp_path / "rec")[1]["Out of sequence count"] == str(expected_oos)


def test_duplicates_are_dropped_and_counted(tmp_path, stream):
    pk = packets_of(stream)
    with RecordingWriter(tmp_path / "rec") as w:
        for j, d in enumerate(pk):
            w.write(d)
            if j in (2, 9):
                w.write(d)                                 # already placed
        w.write(pk[30])
    assert read_stream(tmp_path / "rec") == stream
    assert w.duplicates == 3 and w.lost == []


def test_a_packet_later_than_the_window_stays_lost(tmp_path, stream):
    pk = packets_of(stream)
    order = [j for j in range(len(pk)) if j != 8] + [8]    # packet 9 comes after 31 later ones
    with RecordingWriter(tmp_path / "rec", reorder_window=4) as w:
        for j in order:
            w.write(pk[j])
    assert read_stream(tmp_path / "rec") == zeroed(stream, [8])
    assert w.late == 1 and [(d.first_sequence, d.count) for d in w.lost] == [(9, 1)]


def test_a_gap_is_declared_after_the_reorder_timeout(tmp_path, stream):
    now = [0.0]
    pk = packets_of(stream)
    w = RecordingWriter(tmp_path / "rec", reorder_timeout=0.1, clock=lambda: now[0])
    try:
        for d in pk[:3] + pk[4:6]:                         # packet 4 missing, 5 and 6 wait
            w.write(d)
        w.tick()
        assert w.stream_bytes == 3 * P and w.waiting == 2
        now[0] = 0.2
        w.tick()                                  # waited too long: 4 is lost, 5 and 6 placed, all flushed
        assert w.waiting == 0 and w.stream_bytes == 6 * P
        assert w.final_bytes == 6 * P and w.final_time == 0.2
        assert read_stream(tmp_path / "rec") == zeroed(stream[:6 * P], [3])
    finally:
        w.close()


def test_final_bytes_are_on_disk_while_recording(tmp_path, stream):
    pk = packets_of(stream)
    w = RecordingWriter(tmp_path / "rec", split_size=5 * P)
    try:
        for d in pk[:12]:
            w.write(d)
        assert w.final_bytes == 0                          # staged, not yet handed over
        w.flush()
        assert w.final_bytes == 12 * P
        assert read_stream(tmp_path / "rec") == stream[:12 * P]    # another reader sees it now
    finally:
        w.close()


def test_max_bytes_keeps_exactly_the_frames_asked(tmp_path, stream):
    limit = 10 * P + 100
    with RecordingWriter(tmp_path / "rec", max_bytes=limit) as w:
        for d in packets_of(stream):
            w.write(d)
            if w.full:
                break
    assert read_stream(tmp_path / "rec") == stream[:limit]


def test_an_existing_recording_is_refused_and_left_alone(tmp_path):
    folder = tmp_path / "rec"
    folder.mkdir()
    (folder / "adc_data_Raw_0.bin").write_bytes(b"user data")
    with pytest.raises(MeasuredFormatError) as err:
        RecordingWriter(folder)
    assert "already holds a recording" in str(err.value) and "\n" not in str(err.value)
    assert (folder / "adc_data_Raw_0.bin").read_bytes() == b"user data"
    assert not (folder / "lost_packets.csv").exists()
    (tmp_path / "log").mkdir()
    (tmp_path / "log" / "adc_data_Raw_LogFile.csv").write_text("x")
    with pytest.raises(MeasuredFormatError):
        RecordingWriter(tmp_path / "log")


def test_a_killed_writer_leaves_a_readable_recording(tmp_path, stream):
    """SIGKILL (no cleanup at all) after a flush: the files hold the final bytes, the losses are listed."""
    source = tmp_path / "source.bin"
    source.write_bytes(stream)
    script = textwrap.dedent(f"""
        import struct, sys, time
        from risloc_rt.measured.live.recording_writer import RecordingWriter
        P = {P}
        stream = open({str(source)!r}, "rb").read()
        w = RecordingWriter({str(tmp_path / "rec")!r}, split_size=6 * P, reorder_window=2)
        for j, k in enumerate(range(0, 25 * P, P)):
            if j in (4, 11):
                continue
            w.write(struct.pack("<I", j + 1) + k.to_bytes(6, "little") + stream[k:k + P])
        w.flush()
        print(w.final_bytes, flush=True)
        time.sleep(60)
    """)
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True,
                            cwd=Path(__file__).resolve().parents[3])
    try:
        line = proc.stdout.readline()
        assert line.strip() == str(25 * P), line
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
        proc.stdout.close()
    folder = tmp_path / "rec"
    assert read_stream(folder) == zeroed(stream[:25 * P], [4, 11])
    assert read_lost_csv(folder) == [(5, 1, 4 * P, P), (12, 1, 11 * P, P)]
    runs, fields = read_log(folder)
    assert runs == [(4 * P, P), (11 * P, P)] and "First Packet ID" not in fields   # no summary: killed


def test_the_project_reader_reads_the_result(tmp_path, stream):
    """``open_raw`` (what every command uses) reads the split files as one raw stream."""
    from risloc_rt.measured.dca1000.raw_layout import RawLayout
    from risloc_rt.measured.dca1000.reader import read_raw

    layout = RawLayout(num_samples=8, num_rx=2, chirps_per_loop=1, num_loops=4)   # 512 bytes per frame
    data = stream[:layout.frame_bytes * 60]
    with RecordingWriter(tmp_path / "rec", split_size=9 * P) as w:
        for d in packets_of(data):
            w.write(d)
    cap = read_raw(tmp_path / "rec" / "adc_data_Raw_0.bin", layout, form="raw", find_zero_packets=False)
    (tmp_path / "whole.bin").write_bytes(data)                       # the same stream in one plain file
    ref = read_raw(tmp_path / "whole.bin", layout, form="raw", find_zero_packets=False)
    assert len(split_files(tmp_path / "rec")) == -(-len(data) // (9 * P)) > 1
    assert cap.cube.shape[0] == 60 and np.array_equal(cap.cube, ref.cube)

"""Issue 19: Ctrl-C in a terminal goes to the whole foreground process group, a study's worker
processes included. The workers ignore it (``risloc_rt._workers``), so the study ends with its one
line and exit 130, not with a ``KeyboardInterrupt`` traceback per worker before it (benchmarks/
interrupts.py found 85 lines on stderr with two workers)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from .conftest import small_cli_args


def _children(pid: int) -> list[int]:
    """Processes whose parent is ``pid`` (Linux ``/proc``)."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                found.append(int(entry.name))
    return found


def test_ctrl_c_to_the_process_group_prints_one_line(tmp_path):
    out = tmp_path / "study"
    risloc = Path(sys.executable).with_name("risloc")
    argv = [str(risloc), "study", "sweep", "--vary", "tx_power_dbm=0,10,20,30", "--runs", "400", "--workers", "2",
            "--force-workers", "--quiet", "--out", str(out), *small_cli_args()]
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and proc.poll() is None and len(_children(proc.pid)) < 2:
        time.sleep(0.02)                     # the workers are starting
    assert proc.poll() is None, "the study ended before it could be interrupted"
    time.sleep(0.3)                          # the workers are importing NumPy and SciPy: the worst moment
    os.killpg(proc.pid, signal.SIGINT)       # what a terminal's Ctrl-C does
    _, err = proc.communicate(timeout=120)
    lines = err.decode().strip().splitlines()
    assert proc.returncode == 130, lines
    assert len(lines) == 1 and lines[0].startswith("risloc study: interrupted"), lines

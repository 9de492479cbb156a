"""Crash safety (SIGKILL mid-study, restart), worker-count and Dask invariance, dead workers retried."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from risloc_rt.studies import read_runs_table, run_study
from risloc_rt.studies.engine import DIE_ONCE

from .conftest import small_cli_args

REPO = Path(__file__).resolve().parents[2]


def _table(folder: Path) -> dict:
    """The run table without the per-run times (the only column allowed to differ)."""
    return read_runs_table(folder / "runs.parquet").drop(["seconds"]).to_pydict()


def _running_worker(pid: str) -> bool:
    """Is ``pid`` still a live multiprocessing child (not a zombie, not a recycled pid)?"""
    try:
        cmd = Path(f"/proc/{pid}/cmdline").read_text(errors="ignore")
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return "multiprocessing" in cmd and state != "Z"


def _cli(out: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "risloc_rt", "study", "sweep", "--vary", "tx_power_dbm=25,35", "--runs", "30",
            "--seed", "11", "--out", str(out), *small_cli_args(), *extra]


@pytest.mark.slow
def test_a_study_killed_with_sigkill_continues_and_ends_identical(tmp_path):
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    killed = tmp_path / "killed"
    proc = subprocess.Popen(_cli(killed, "--workers", "2", "--quiet"), cwd=REPO, env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    log = killed / "runs.jsonl"
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and proc.poll() is None:
        if log.exists() and log.read_bytes().count(b"\n") >= 10:
            break
        time.sleep(0.02)
    assert proc.poll() is None, f"the study ended before it could be killed: {proc.stderr.read()!r}"
    children = subprocess.run(["pgrep", "-P", str(proc.pid)], capture_output=True, text=True).stdout.split()
    assert children  # its worker processes
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    deadline = time.monotonic() + 10  # the workers die with it (parent-death signal), no orphans left running
    while time.monotonic() < deadline and any(_running_worker(c) for c in children):
        time.sleep(0.1)
    assert not any(_running_worker(c) for c in children)
    done = log.read_bytes().count(b"\n")
    assert 10 <= done < 60  # killed mid-way
    assert not (killed / "summary.json").exists()
    again = subprocess.run(_cli(killed, "--workers", "1", "--quiet"), cwd=REPO, env=env, capture_output=True, text=True)
    assert again.returncode == 0, again.stderr
    whole = subprocess.run(_cli(tmp_path / "whole", "--workers", "1", "--quiet"), cwd=REPO, env=env,
                           capture_output=True, text=True)
    assert whole.returncode == 0, whole.stderr
    assert _table(killed) == _table(tmp_path / "whole")  # also: 2 workers (restarted) == 1 worker
    assert len(_table(killed)["run"]) == 60


def test_a_torn_last_line_is_cut_off_and_its_run_redone(small_spec, tmp_path):
    spec = small_spec(runs=3)
    run_study(spec, tmp_path / "a", workers=1, quiet=True, figures=False)
    log = tmp_path / "a" / "runs.jsonl"
    data = log.read_bytes()
    log.write_bytes(data[: len(data) - 40])  # a SIGKILL in the middle of the last write
    res = run_study(spec, tmp_path / "a", workers=1, quiet=True, figures=False)
    assert res.new_runs == 1
    run_study(spec, tmp_path / "b", workers=1, quiet=True, figures=False)
    assert _table(tmp_path / "a") == _table(tmp_path / "b")


@pytest.mark.slow
def test_a_dead_worker_is_retried_and_reported(small_spec, tmp_path, monkeypatch):
    monkeypatch.setenv(DIE_ONCE, str(tmp_path / "died"))
    spec = small_spec(runs=4)
    res = run_study(spec, tmp_path / "s", workers=2, quiet=True, figures=False)
    assert (tmp_path / "died").exists()  # a worker did die
    assert any("worker process died" in m for m in res.summary["retried"])
    monkeypatch.delenv(DIE_ONCE)
    run_study(spec, tmp_path / "ref", workers=1, quiet=True, figures=False)
    assert _table(tmp_path / "s") == _table(tmp_path / "ref")  # nothing dropped, nothing changed


@pytest.mark.slow
def test_a_dask_cluster_gives_the_local_result(small_spec, tmp_path):
    from distributed import LocalCluster

    spec = small_spec(runs=5)
    local = run_study(spec, tmp_path / "local", workers=1, quiet=True, figures=False)
    with LocalCluster(n_workers=1, threads_per_worker=2, processes=False, dashboard_address=None) as cluster:
        remote = run_study(spec, tmp_path / "dask", dask=cluster.scheduler_address, quiet=True, figures=False)
    assert _table(tmp_path / "dask") == _table(tmp_path / "local")
    for a, b in zip(local.summary["points"], remote.summary["points"]):
        assert a["mae"] == b["mae"] and a["rmse"] == b["rmse"] and a["crb"] == b["crb"]


def test_batches_sharing_a_process_keep_blas_single_threaded_until_the_last_leaves(monkeypatch):
    """Dask runs several batches on the threads of one worker; BLAS's thread count is process-wide,
    so a batch that finishes first must not hand the others a multi-threaded BLAS back (their last
    digits would then differ from a local run). BLAS is stood in for by a recorder of what
    threadpoolctl is asked to do (OpenBLAS's own thread count reads differently from thread to thread)."""
    import threading

    import threadpoolctl

    from risloc_rt.studies import engine

    blas = {"threads": 2}

    class Limiter:
        def __init__(self, limits, user_api):
            assert (limits, user_api) == (1, "blas")
            self.original, blas["threads"] = blas["threads"], limits

        def restore_original_limits(self):
            blas["threads"] = self.original

    monkeypatch.setattr(threadpoolctl, "threadpool_limits", Limiter)
    long_entered, first_left = threading.Event(), threading.Event()
    seen: dict[str, int] = {}

    def first_batch() -> None:  # enters first and leaves first: the other batch still runs
        with engine.one_thread():
            long_entered.wait(10)
            seen["first"] = blas["threads"]
        first_left.set()

    def long_batch() -> None:
        with engine.one_thread():
            long_entered.set()
            first_left.wait(10)
            seen["long, after the first left"] = blas["threads"]

    a, b = threading.Thread(target=first_batch), threading.Thread(target=long_batch)
    a.start()
    time.sleep(0.05)
    b.start()
    a.join()
    b.join()
    assert seen == {"first": 1, "long, after the first left": 1}
    assert blas["threads"] == 2  # restored when the last batch left

"""Start-up of risloc-rt's worker processes: the standard library only, importable from every floor.

A study's workers are spawned processes (:mod:`risloc_rt.studies.engine`). A terminal's Ctrl-C
goes to the whole foreground process group, workers included; a worker that took it would print
its own ``KeyboardInterrupt`` traceback (while importing SciPy, or in a batch) before the study's
one line. So the first thing a worker does, before it imports anything heavy, is to ignore
``SIGINT``: the study process alone handles Ctrl-C and stops the pool. This module is that first
thing; importing it (to unpickle :func:`init_worker` in the child) loads nothing but the standard
library and risloc-rt's lazy root package.
"""

from __future__ import annotations

import os
import signal
import threading
import time

__all__ = ["init_worker"]


def init_worker(parent: int, one_thread: tuple[str, ...] = ()) -> None:
    """Worker start-up: ignore Ctrl-C, single-threaded numerical libraries, die with the parent.

    Parameters
    ----------
    parent : int
        The study process's pid: the worker exits when it is gone (Linux's parent-death signal,
        else a watchdog thread polling ``getppid``), so a SIGKILLed study leaves no orphan running.
    one_thread : tuple of str
        Environment variables set to ``"1"`` unless set (``OPENBLAS_NUM_THREADS``, ...): the
        workers are the parallelism.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    for name in one_thread:
        os.environ.setdefault(name, "1")
    try:
        import ctypes

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):  # pragma: no cover - not Linux
        pass

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(1.0)
        os._exit(1)

    threading.Thread(target=watch, daemon=True).start()

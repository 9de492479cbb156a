"""How many threads the DSP's transforms and beam chunks may use.

By default every core the process may run on. A caller that is itself parallel — a Monte Carlo
study running one worker process per core — limits it to one, so that workers do not fight for
the cores::

    with dsp.limit_threads(1):
        dsp.self_localize(...)

These threads (FFT workers, chunks of beams) never change a result, only the time. BLAS's own
thread count is not set here: a multi-threaded BLAS may sum long matrix products in another order
and change last digits (1e-12 rad in the refined AoD was seen); the studies pin it to one thread
with threadpoolctl (``risloc_rt.studies.engine``).
"""

from __future__ import annotations

import contextvars
import os
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["limit_threads", "thread_count"]

_LIMIT: contextvars.ContextVar[int | None] = contextvars.ContextVar("dsp_thread_limit", default=None)


def _cores() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def thread_count() -> int:
    """Threads the DSP may use now: the innermost :func:`limit_threads`, else the usable cores."""
    limit = _LIMIT.get()
    return _cores() if limit is None else limit


@contextmanager
def limit_threads(count: int) -> Iterator[None]:
    """Run the enclosed DSP calls on at most ``count`` threads (``count`` >= 1)."""
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise ValueError(f"thread count {count!r} must be an integer >= 1")
    token = _LIMIT.set(min(count, _cores()))
    try:
        yield
    finally:
        _LIMIT.reset(token)

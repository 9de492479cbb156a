"""Run a study: batches of runs on local processes or a Dask cluster, appended as they finish.

Each batch is (point, first run, last run); its numbers depend only on the study seed, the point
and the run indices (:func:`risloc_rt.studies.kernel.run_rng`), so the table is the same for any
number of workers, any order, and after any number of restarts.

The engine knows no particular study. A study is a :class:`StudyPlan` (its points as plain data)
and a *point preparer*: a module-level function ``prepare(params) -> PreparedPoint`` that makes what
every run of a point shares (``kernel.prepare_point`` for a sweep, ``floor_map.prepare_cell`` for a
floor map). Worker processes and Dask workers receive the preparer by its qualified name (pickle
sends a module-level function as a reference), so :func:`execute` refuses a lambda, a closure or a
bound method with a one-line error (:func:`check_preparer`) rather than failing inside a worker. A worker process that dies (killed,
out of memory) breaks the pool: the batches it was running are retried on a fresh pool, reported,
and after :data:`MAX_ATTEMPTS` failures the study stops with an error naming the batch. Nothing is
dropped silently: the summary is only written when every run of every point is in the log.
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
import threading
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator, Protocol

from .kernel import PreparedPoint, run_once
from .store import RunLog

__all__ = ["StudyError", "StudyPlan", "Preparer", "Batch", "plan_batches", "check_preparer", "run_batch", "execute",
           "default_workers", "connect_dask"]

#: A batch whose worker died this many times stops the study.
MAX_ATTEMPTS = 3
#: Test hook: with this variable naming a file that does not exist yet, the worker running the first
#: batch creates it and dies (exit without cleanup), as a worker killed by the OOM killer would.
DIE_ONCE = "RISLOC_STUDY_TEST_DIE_ONCE"
#: Single-threaded numerical libraries in worker processes: the workers are the parallelism.
_ONE_THREAD = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


class StudyError(RuntimeError):
    """A study could not go on (a worker died too often, the cluster is unreachable, ...)."""


class StudyPlan(Protocol):
    """What :func:`execute` needs of a study: a :class:`~risloc_rt.studies.spec.StudySpec` is one,
    a floor map's cells are another.

    Attributes
    ----------
    name : str
        Shown on the progress bar.
    runs : int
        Monte Carlo runs per point.
    seed : int
        The study seed (run r of point p draws its noise from ``SeedSequence(seed, spawn_key=(p, r))``).
    key : str
        A hash of the settings: names the Dask tasks.
    """

    name: str
    runs: int
    seed: int

    @property
    def key(self) -> str: ...  # noqa: D102

    def points(self) -> list[dict[str, Any]]:
        """The points, in order.

        Returns
        -------
        list of dict
            Plain (picklable) data, one per point: the argument of the point preparer.
        """
        ...


#: A point preparer: a module-level function ``params -> PreparedPoint`` (see the module docstring).
Preparer = Callable[[dict[str, Any]], PreparedPoint]


@dataclass(frozen=True)
class Batch:
    """Runs ``start`` … ``stop - 1`` of point ``point`` (whose parameters are ``params``)."""

    point: int
    start: int
    stop: int
    params: dict[str, Any] = field(hash=False, compare=False)

    @property
    def label(self) -> str:
        """``"point P runs A-B"`` for messages."""
        return f"point {self.point} runs {self.start}-{self.stop - 1}"


def default_workers() -> int:
    """All cores this process may use.

    Returns
    -------
    int
        The number of CPUs in this process's affinity mask (>= 1).
    """
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def plan_batches(spec: StudyPlan, done: set[tuple[int, int]], *, workers: int) -> list[Batch]:
    """The missing runs of every point, cut into batches (point-major, so a worker reuses its cube).

    Parameters
    ----------
    spec : StudyPlan
        The study.
    done : set of (int, int)
        The (point, run) pairs already in the log.
    workers : int
        Worker count: batches hold at most ``runs / (2 workers)`` runs (and at most 25), so every
        worker gets work.

    Returns
    -------
    list of Batch
        Runs of consecutive indices, point by point.
    """
    size = max(1, min(25, math.ceil(spec.runs / max(1, 2 * workers))))
    out: list[Batch] = []
    for p, params in enumerate(spec.points()):
        missing = [r for r in range(spec.runs) if (p, r) not in done]
        i = 0
        while i < len(missing):
            j = i
            while j + 1 < len(missing) and j + 1 - i < size and missing[j + 1] == missing[j] + 1:
                j += 1
            out.append(Batch(p, missing[i], missing[j] + 1, params))
            i = j + 1
    return out


def check_preparer(prepare: Any) -> str:
    """Refuse a point preparer that worker processes and Dask could not find by name.

    Parameters
    ----------
    prepare : callable
        The point preparer.

    Returns
    -------
    str
        Its qualified name, ``module.function``.

    Raises
    ------
    TypeError
        ``prepare`` is not a module-level function (a lambda, a closure, a bound method, ...).
    """
    module = getattr(prepare, "__module__", None)
    qualname = getattr(prepare, "__qualname__", "")
    found = getattr(sys.modules.get(module or ""), qualname, None) if "." not in qualname else None
    if not callable(prepare) or found is not prepare:
        raise TypeError(f"the point preparer {prepare!r} must be a module-level function (worker processes and "
                        "Dask import it by its qualified name); define it at the top level of a module")
    return f"{module}.{qualname}"


_CACHE: dict[str, Any] = {}


def _prepared(prepare: Preparer, params: dict[str, Any]) -> PreparedPoint:
    """The point's shared cube and bound, made by ``prepare`` once per worker and point."""
    import json

    key = f"{prepare.__module__}.{prepare.__qualname__} " + json.dumps(params, sort_keys=True)
    prep = _CACHE.get(key)
    if prep is None:
        _CACHE.clear()  # one point per worker at a time: a Table I cube is 75 MB
        prep = prepare(params)
        _CACHE[key] = prep
    return prep


_BLAS_LOCK = threading.Lock()
_blas_users = 0
_blas_limiter: Any = None


@contextlib.contextmanager
def _one_thread() -> Iterator[None]:
    """One DSP thread and one BLAS thread for the enclosed work (see :func:`run_batch`).

    BLAS's thread count is process-wide: batches running at once on the threads of one Dask
    worker share one limiter, set by the first to enter and restored by the last to leave (a
    batch leaving early must not give the others back a multi-threaded BLAS).
    """
    global _blas_users, _blas_limiter
    from threadpoolctl import threadpool_limits

    from dsp import limit_threads

    with _BLAS_LOCK:
        if _blas_users == 0:
            _blas_limiter = threadpool_limits(limits=1, user_api="blas")
        _blas_users += 1
    try:
        with limit_threads(1):
            yield
    finally:
        with _BLAS_LOCK:
            _blas_users -= 1
            if _blas_users == 0:
                _blas_limiter.restore_original_limits()
                _blas_limiter = None


def run_batch(prepare: Preparer, params: dict[str, Any], point: int, start: int, stop: int,
              study_seed: int) -> dict[str, Any]:
    """Run one batch (in a worker): the point prepared by ``prepare``, then runs ``start`` … ``stop - 1``.

    Always on one thread — the DSP's (``dsp.limit_threads``) and BLAS's (threadpoolctl) — in a
    worker process, a Dask task or this process alike: the workers are the parallelism, and a
    multi-threaded BLAS sums long products in another order (last-digit differences, e.g. in the
    refined AoD), so this is what makes a study's numbers the same for any number of workers.

    Parameters
    ----------
    prepare : Preparer
        The point preparer (a module-level function).
    params : dict
        The point, as the plan's ``points()`` gave it.
    point, start, stop : int
        Point index and the runs' half-open index range.
    study_seed : int
        The study seed.

    Returns
    -------
    dict
        Plain, picklable data: ``rows`` (one dict per run, :func:`risloc_rt.studies.kernel.run_once`),
        ``crb`` (the point's bounds [m, rad, m/s] and ``peak_snr_db`` [dB]), ``prepare_seconds`` [s]
        and ``warnings`` (the preparer's, e.g. range aliasing).
    """
    import numpy as np

    marker = os.environ.get(DIE_ONCE)
    if marker and point == 0 and start == 0 and not os.path.exists(marker):  # the retry test's dying worker
        Path(marker).touch()
        os._exit(9)

    with _one_thread():
        prep = _prepared(prepare, params)
        buffer = np.empty_like(prep.cube)
        rows = [run_once(prep, study_seed=study_seed, point=point, run=r, buffer=buffer) for r in range(start, stop)]
    return {"rows": rows, "crb": prep.crb, "prepare_seconds": prep.seconds,
            "warnings": list(prep.params.get("warnings", ()))}


def _init_worker(parent: int) -> None:
    """Worker start-up: single-threaded BLAS, and die with the study process (a SIGKILLed study
    leaves no orphan workers running): Linux's parent-death signal, else a watchdog thread."""
    import signal
    import threading

    for name in _ONE_THREAD:
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


def execute(spec: StudyPlan, log: RunLog, *, prepare: Preparer, workers: int, dask: Any = None, quiet: bool = False,
            notice: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Run every missing run of ``spec`` and append it to ``log``.

    Parameters
    ----------
    spec : StudyPlan
        The study: a :class:`~risloc_rt.studies.spec.StudySpec`, or a floor map's cells.
    log : RunLog
        The open run log; its finished runs are skipped.
    prepare : Preparer
        The point preparer, a module-level function (:func:`check_preparer`).
    workers : int
        Local worker processes; 1 runs in this process. Ignored with ``dask``.
    dask : str or distributed.Client, optional
        A scheduler address or a client: run the batches there.
    quiet : bool
        No progress bar (retries go to ``notice``).
    notice : callable, optional
        Receives the retry messages when ``quiet`` (default: print to stderr).

    Returns
    -------
    dict
        ``{"crb": {point: {...}}, "prepare_seconds": {point: s}, "warnings": {point: [...]},
        "retried": [messages], "wall_seconds": s, "new_runs": n}`` (bounds in m, rad, m/s; times in s).

    Raises
    ------
    TypeError
        ``prepare`` is not a module-level function.
    StudyError
        A batch killed its worker :data:`MAX_ATTEMPTS` times, or the Dask cluster gave up on it.
    """
    from tqdm import tqdm

    check_preparer(prepare)
    notice = notice or (lambda msg: print(msg, file=sys.stderr))
    batches = plan_batches(spec, log.done(), workers=workers)
    total = spec.runs * len(spec.points())
    done_before = sum(1 for (p, r) in log.done() if r < spec.runs)
    info: dict[str, Any] = {"crb": {}, "prepare_seconds": {}, "warnings": {}, "retried": [], "new_runs": 0}
    start = time.perf_counter()
    bar = tqdm(total=total, initial=done_before, unit="run", desc=spec.name, disable=quiet, smoothing=0.05,
               dynamic_ncols=True, file=sys.stderr)

    def take(result: dict[str, Any], batch: Batch) -> None:
        log.append(result["rows"])
        info["crb"][batch.point] = result["crb"]
        info["prepare_seconds"][batch.point] = result["prepare_seconds"]
        info["warnings"][batch.point] = result.get("warnings", [])
        info["new_runs"] += len(result["rows"])
        bar.update(len(result["rows"]))

    def say(msg: str) -> None:
        info["retried"].append(msg)
        if quiet:
            notice(msg)
        else:
            bar.write(msg, file=sys.stderr)

    try:
        if dask is not None:
            _run_dask(spec, prepare, batches, dask, take, say)
        elif workers == 1:
            for b in batches:
                take(run_batch(prepare, b.params, b.point, b.start, b.stop, spec.seed), b)
        else:
            _run_pool(spec, prepare, batches, workers, take, say)
        # bounds of points whose runs were all done before this start (needed by the summary)
        for p, params in enumerate(spec.points()):
            if p not in info["crb"]:
                with _one_thread():
                    prep = _prepared(prepare, params)
                info["crb"][p], info["prepare_seconds"][p] = prep.crb, prep.seconds
                info["warnings"][p] = list(prep.params.get("warnings", ()))
    finally:
        bar.close()
    info["wall_seconds"] = time.perf_counter() - start
    return info


def _run_pool(spec: StudyPlan, prepare: Preparer, batches: list[Batch], workers: int, take: Callable,
              say: Callable) -> None:
    import multiprocessing

    attempts = {b: 0 for b in batches}
    queue = list(batches)
    saved = {k: os.environ.get(k) for k in _ONE_THREAD}
    for k in _ONE_THREAD:  # spawned workers read them when they import numpy
        os.environ.setdefault(k, "1")
    try:
        while queue:
            pool = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                                       initializer=_init_worker, initargs=(os.getpid(),))
            running: dict[Any, Batch] = {}
            broken: list[Batch] = []
            try:
                while queue or running:
                    try:
                        while queue and len(running) < workers:  # one batch per worker: a death names its batch
                            b = queue[0]
                            running[pool.submit(run_batch, prepare, b.params, b.point, b.start, b.stop,
                                                spec.seed)] = b
                            queue.pop(0)
                    except BrokenProcessPool:  # a worker died since the last wait: the running batches retry
                        broken += list(running.values())
                        running.clear()
                        break
                    finished, _ = wait(running, return_when=FIRST_COMPLETED)
                    for fut in finished:
                        b = running.pop(fut)
                        try:
                            result = fut.result()
                        except BrokenProcessPool:
                            broken.append(b)
                            continue
                        take(result, b)
                    if broken:
                        broken += list(running.values())
                        running.clear()
                        break
            finally:
                pool.shutdown(wait=not broken, cancel_futures=True)
            for b in broken:
                attempts[b] += 1
                if attempts[b] >= MAX_ATTEMPTS:
                    raise StudyError(f"{b.label}: its worker process died {attempts[b]} times (killed or out of "
                                     "memory); the finished runs are kept, rerun with fewer --workers to continue")
                say(f"warning: a worker process died while running {b.label} (attempt {attempts[b]}); retrying it")
            queue = broken + queue
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def connect_dask(address: Any, *, timeout: float = 10.0) -> Any:
    """A ``distributed.Client`` for ``address`` (or the client given), with a one-line error when unreachable.

    Parameters
    ----------
    address : str or distributed.Client
        A scheduler address (``tcp://host:8786``); a client is returned as it is.
    timeout : float
        How long to wait for the scheduler [s].

    Returns
    -------
    distributed.Client

    Raises
    ------
    StudyError
        The scheduler cannot be reached within ``timeout`` (or ``distributed`` is missing).
    """
    try:
        from distributed import Client
    except ImportError as exc:  # pragma: no cover - a pinned dependency
        raise StudyError(f"--dask needs the 'distributed' package ({exc}); run ./setup.sh") from None
    if not isinstance(address, str):
        return address
    try:
        return Client(address, timeout=timeout, set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        raise StudyError(f"cannot reach the Dask scheduler at {address!r} within {timeout:g} s ({type(exc).__name__}); "
                         "start one with 'dask scheduler' and workers with 'dask worker ADDRESS' (docs/studies.md), "
                         "or leave out --dask to run on this machine") from None


def _run_dask(spec: StudyPlan, prepare: Preparer, batches: list[Batch], address: Any, take: Callable,
              say: Callable) -> None:
    from distributed import as_completed
    from distributed.scheduler import KilledWorker

    client = connect_dask(address)
    try:
        futures = {client.submit(run_batch, prepare, b.params, b.point, b.start, b.stop, spec.seed,
                                 key=f"risloc-study-{spec.key}-{b.point}-{b.start}-{b.stop}", pure=False,
                                 retries=MAX_ATTEMPTS - 1): b for b in batches}
        with client.as_current():
            for fut in as_completed(list(futures)):
                b = futures[fut]
                try:
                    take(fut.result(), b)
                except KilledWorker as exc:
                    raise StudyError(f"{b.label}: Dask workers died running it ({exc}); the finished runs are kept, "
                                     "rerun the same command to continue") from None
    finally:
        if isinstance(address, str):
            client.close()

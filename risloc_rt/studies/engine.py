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

from .._workers import init_worker
from .kernel import PreparedPoint, detector_workspace, run_once, run_runs
from .store import HOST_STREAM, RunLog, host_noise

__all__ = ["ONE_THREAD_ENV", "StudyError", "StudyPlan", "Preparer", "Batch", "plan_batches", "count_missing",
           "check_preparer", "check_rows_memory", "run_batch", "execute", "default_workers", "choose_workers", "connect_dask",
           "one_thread", "one_thread_environment", "worker_pool"]

#: A batch whose worker died this many times stops the study.
MAX_ATTEMPTS = 3
#: Test hook: with this variable naming a file that does not exist yet, the worker running the first
#: batch creates it and dies (exit without cleanup), as a worker killed by the OOM killer would.
DIE_ONCE = "RISLOC_STUDY_TEST_DIE_ONCE"
#: Single-threaded numerical libraries in worker processes: the workers are the parallelism.
#: The environment variables a worker sets to "1" (its numerical libraries single-threaded: the
#: workers are the parallelism); :func:`risloc_rt._workers.init_worker` takes them.
ONE_THREAD_ENV = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
#: Memory one worker process needs [bytes]: 0.57 GiB measured at Table I (docs/benchmarks.md), rounded up.
WORKER_BYTES = int(0.6 * (1 << 30))
#: Memory one finished run costs the study process [bytes]: its row in the run log's table, the
#: Parquet table and the summary (measured 2.0 KiB per row in ``RunLog.rows``; 2x margin).
ROW_BYTES = 4 << 10
#: A study expected to take longer than this [s] is refused unless ``long_ok`` (``--force-long``).
LONG_SECONDS = 24 * 3600.0
#: Fewer missing runs than this cannot make a long study: no calibration run, no time estimate.
CALIBRATE_ABOVE = 50
#: The largest batch of runs for a GPU worker (its detector takes up to dsp.budget.DEVICE_BATCH realizations per call).
DEVICE_BATCH_RUNS = 256
#: Batches in flight on a Dask cluster at once (the plan is lazy: the rest are submitted as these finish).
DASK_WINDOW = 1000


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


def plan_batches(spec: StudyPlan, done: set[tuple[int, int]], *, workers: int, max_size: int = 25) -> Iterator[Batch]:
    """The missing runs of every point, cut into batches (point-major, so a worker reuses its cube), lazily.

    The batches are generated as they are taken, from the gaps between the finished runs of each
    point: time and memory grow with the number of finished runs and of batches taken, never with
    ``spec.runs`` (a study of 10⁹ runs per point plans its first batches in microseconds).

    Parameters
    ----------
    spec : StudyPlan
        The study.
    done : set of (int, int)
        The (point, run) pairs already in the log.
    workers : int
        Worker count: batches hold at most ``runs / (2 workers)`` runs (and at most ``max_size``), so
        every worker gets work.
    max_size : int
        The largest batch: 25 on the host, :data:`DEVICE_BATCH_RUNS` on a GPU (whose realizations are
        evaluated many at a time).

    Yields
    ------
    Batch
        Runs of consecutive indices, point by point.
    """
    runs = int(spec.runs)
    size = max(1, min(int(max_size), math.ceil(runs / max(1, 2 * workers))))
    finished: dict[int, list[int]] = {}
    for p, r in done:
        if 0 <= r < runs:
            finished.setdefault(p, []).append(r)
    for p, params in enumerate(spec.points()):
        stops = sorted(finished.get(p, ())) + [runs]
        first = 0
        for stop in stops:  # the missing runs first ... stop - 1, in batches of at most ``size``
            while first < stop:
                yield Batch(p, first, min(stop, first + size), params)
                first = min(stop, first + size)
            first = stop + 1


def count_missing(spec: StudyPlan, done: set[tuple[int, int]]) -> tuple[int, int]:
    """How many runs of ``spec`` are not in the log, and in how many points, without listing them.

    Parameters
    ----------
    spec : StudyPlan
    done : set of (int, int)
        The (point, run) pairs already in the log.

    Returns
    -------
    missing : int
        Runs to do.
    points : int
        Points with at least one run to do.
    """
    n_points = len(spec.points())
    per_point: dict[int, int] = {}
    for p, r in done:
        if 0 <= p < n_points and 0 <= r < spec.runs:
            per_point[p] = per_point.get(p, 0) + 1
    missing = n_points * int(spec.runs) - sum(per_point.values())
    full = sum(1 for n in per_point.values() if n >= spec.runs)
    return missing, n_points - full


def choose_workers(workers: int | None, *, insist: bool = False,
                   notice: Callable[[str], None] | None = None) -> int:
    """The worker processes a local study gets: at most the cores and what the memory limit allows.

    Parameters
    ----------
    workers : int or None
        Asked for (``--workers``); None: as many as the cores and the memory limit allow.
    insist : bool
        Keep ``workers`` above the core count (``--force-workers``); the memory limit still holds.
    notice : callable, optional
        Receives the one-line note when ``workers`` is lowered (default: print to stderr).

    Returns
    -------
    int
        The worker count (>= 1).

    Raises
    ------
    ValueError
        ``workers`` < 1.
    dsp.budget.BudgetError
        ``insist`` and ``workers`` × :data:`WORKER_BYTES` exceed the memory limit.
    """
    from dsp.budget import check_memory, format_bytes, memory_limit

    if workers is not None and (isinstance(workers, bool) or int(workers) < 1):
        raise ValueError(f"--workers {workers} must be >= 1")
    cores = default_workers()
    limit, source = memory_limit()
    by_memory = max(1, limit // WORKER_BYTES)
    if workers is None:
        return max(1, min(cores, by_memory))
    workers = int(workers)
    if insist:
        if workers > 1:
            check_memory(workers * WORKER_BYTES, f"--workers {workers} (about {format_bytes(WORKER_BYTES)} each)",
                         fix=f"use at most {by_memory} workers, or raise $RISLOC_MEMORY_LIMIT")
        return workers
    cap = min(cores, by_memory)
    if workers > cap:
        (notice or (lambda msg: print(msg, file=sys.stderr)))(
            f"note: --workers {workers} lowered to {cap}: {cores} core(s), and the memory limit "
            f"{format_bytes(limit)} ({source.split(';')[0]}) holds {by_memory} workers of about "
            f"{format_bytes(WORKER_BYTES)}; add --force-workers to keep {workers}")
        return cap
    return workers


def _format_seconds(seconds: float) -> str:
    """``42 s``, ``12 min``, ``3.5 h``, ``41 days``."""
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min"
    if seconds < 3 * 86400:
        return f"{seconds / 3600:.1f} h"
    return f"{seconds / 86400:.3g} days"


def _calibrate(prepare: Preparer, batch: Batch, study_seed: int) -> tuple[float, float]:
    """Time the preparation of ``batch``'s point and its first run in this process [s] (nothing is logged;
    the prepared point stays in this process's cache, so ``workers=1`` does not prepare it again)."""
    import numpy as np

    with one_thread():
        prep = _prepared(prepare, batch.params)
        t0 = time.perf_counter()
        run_once(prep, study_seed=study_seed, point=batch.point, run=batch.start, buffer=np.empty_like(prep.cube))
        seconds = time.perf_counter() - t0
    return float(prep.seconds), seconds


def check_rows_memory(name: str, points: int, runs: int) -> int:
    """Refuse a study whose rows (``points × runs ×`` :data:`ROW_BYTES`) exceed the memory limit.

    :func:`check_budget` checks it before any run; the study commands call it before their folder is
    made, so a refused ``--runs`` leaves nothing behind.

    Parameters
    ----------
    name : str
        The study, for the message.
    points : int
        Its points (cells × RISs for a map).
    runs : int
        Runs per point.

    Returns
    -------
    int
        ``points × runs``, the study's runs.

    Raises
    ------
    dsp.budget.BudgetError
        Over the limit: one line naming the runs, the estimate, the limit and the remedy.
    """
    from dsp.budget import check_memory

    total = int(points) * int(runs)
    check_memory(total * ROW_BYTES, f"{name}: {points} point(s) x --runs {runs} = {total:,} runs "
                 f"(a row of about {ROW_BYTES >> 10} KiB each kept in memory)",
                 fix="use fewer --runs or points (a study continues where it stopped: raise --runs later)")
    return total


def check_budget(spec: StudyPlan, done: set[tuple[int, int]], *, prepare: Preparer, workers: int,
                 long_ok: bool = False, say: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Check a study's memory and time before it starts, and say what it will cost.

    Memory: every run of the study ends as a row held by the study process (the run log's table,
    then the Parquet table): ``points × runs ×`` :data:`ROW_BYTES` is checked against the memory
    limit (:func:`dsp.budget.check_memory`) before any run. Time: with more than
    :data:`CALIBRATE_ABOVE` runs to do, the first missing run's point is prepared and one run timed
    in this process (a *calibration run*, not logged); the expected time is
    ``(points to do × preparation + runs to do × run time) / workers``. A study expected to take
    longer than :data:`LONG_SECONDS` is refused unless ``long_ok``.

    Parameters
    ----------
    spec : StudyPlan
    done : set of (int, int)
        The (point, run) pairs already in the log.
    prepare : Preparer
    workers : int
        Workers the runs are spread over.
    long_ok : bool
        Run a study expected to be long (``--force-long``).
    say : callable, optional
        Receives the one-line announcement (run count and expected time); None: silent.

    Returns
    -------
    dict
        ``missing`` (runs to do), ``points`` (points to do), ``expected_seconds`` [s] (None without calibration).

    Raises
    ------
    dsp.budget.BudgetError
        The rows of the study exceed the memory limit.
    StudyError
        The expected time exceeds :data:`LONG_SECONDS` and ``long_ok`` is not given.
    """
    n_points = len(spec.points())
    total = check_rows_memory(spec.name, n_points, int(spec.runs))
    missing, points = count_missing(spec, done)
    out: dict[str, Any] = {"missing": missing, "points": points, "expected_seconds": None}
    head = f"{spec.name}: {n_points} point(s) x {spec.runs:,} runs = {total:,} runs, {missing:,} to do"
    if missing > CALIBRATE_ABOVE:
        first = next(plan_batches(spec, done, workers=workers))
        prep_s, run_s = _calibrate(prepare, first, spec.seed)
        if workers > 1:  # the workers prepare their own points: do not hold this one (75 MB at Table I)
            _CACHE.clear()
        expected = (points * prep_s + missing * run_s) / max(1, workers)
        out["expected_seconds"] = expected
        line = (f"{head} on {workers} worker(s): expected about {_format_seconds(expected)} "
                f"(calibration: {run_s:.2f} s per run, {prep_s:.2f} s per point's preparation)")
        if expected > LONG_SECONDS and not long_ok:
            raise StudyError(f"{line}, more than the {_format_seconds(LONG_SECONDS)} a study may take without "
                             "--force-long; use fewer --runs or points, or add --force-long")
        if say:
            say(line)
    elif say and missing:
        say(f"{head}")
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
def one_thread() -> Iterator[None]:
    """One DSP thread and one BLAS thread for the enclosed work (see :func:`run_batch`).

    BLAS's thread count is process-wide: batches running at once on the threads of one Dask
    worker share one limiter, set by the first to enter and restored by the last to leave (a
    batch leaving early must not give the others back a multi-threaded BLAS).

    Yields
    ------
    None
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
              study_seed: int, device: str = "cpu", share: int = 1, stream: str = HOST_STREAM) -> dict[str, Any]:
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
    device : {"cpu", "cuda", "auto"}
        Where the noise and the detector of the runs go (:func:`dsp.backend_for`, resolved in the
        worker: a Dask worker uses its own GPU, the one ``$CUDA_VISIBLE_DEVICES`` or ``$RISLOC_GPU``
        gives it). The rows' realizations are evaluated B at a time
        (:func:`risloc_rt.studies.kernel.run_runs`; B from the memory estimate).
    share : int
        Worker processes sharing this machine's GPU (the local pool's size): each sizes its batches
        from its share of the GPU's free memory.
    stream : str
        The study folder's noise stream (:data:`risloc_rt.studies.store.HOST_STREAMS`, ``"cuda"``): which
        host stream the runs draw (:func:`risloc_rt.studies.store.host_noise`).

    Returns
    -------
    dict
        Plain, picklable data: ``rows`` (one dict per run, :func:`risloc_rt.studies.kernel.run_once`),
        ``crb`` (the point's bounds [m, rad, m/s] and ``peak_snr_db`` [dB]), ``prepare_seconds`` [s],
        ``warnings`` (the preparer's, e.g. range aliasing) and ``device`` (what ran the DSP and the
        trace: :func:`risloc_rt.io.report.run_environment`).
    """
    marker = os.environ.get(DIE_ONCE)
    if marker and point == 0 and start == 0 and not os.path.exists(marker):  # the retry test's dying worker
        Path(marker).touch()
        os._exit(9)

    from dsp import backend_for

    from ..io.report import run_environment

    backend = _BACKENDS.get(device)
    if backend is None:
        backend = _BACKENDS.setdefault(device, backend_for(device))
    with one_thread():
        prep = _prepared(prepare, params)
        buffer, workspace = _host_buffer(prep.cube.shape) if not backend.name == "cupy" else (None, None)
        rows = run_runs(prep, study_seed=study_seed, point=point, runs=range(start, stop), backend=backend,
                        buffer=buffer, share=share, noise_stream=host_noise(stream), workspace=workspace)
    return {"rows": rows, "crb": prep.crb, "prepare_seconds": prep.seconds,
            "warnings": list(prep.params.get("warnings", ())), "device": run_environment(backend)}


_BACKENDS: dict[str, Any] = {}
_BUFFER = threading.local()  # per thread: the threads of one Dask worker run batches at once


def _host_buffer(shape: tuple[int, ...]) -> tuple[Any, Any]:
    """This thread's host scratch space, kept between batches: a batch of noisy cubes ``[B, M, K, N]`` (complex128)
    and their detector's half-bin transform ``[B, M, 2K, 2N]`` (complex64)."""
    import numpy as np

    from dsp.budget import detect_batch_size

    b = detect_batch_size(shape)
    cubes = (b,) + tuple(int(v) for v in shape)
    buf = getattr(_BUFFER, "cubes", None)
    if buf is None or buf[0].shape != cubes:
        _BUFFER.cubes = None  # the old pair is freed before the new one is made
        buf = _BUFFER.cubes = (np.empty(cubes, dtype=np.complex128), detector_workspace(shape, b))
    return buf


def execute(spec: StudyPlan, log: RunLog, *, prepare: Preparer, workers: int, dask: Any = None, quiet: bool = False,
            notice: Callable[[str], None] | None = None, long_ok: bool = False, device: str = "cpu") -> dict[str, Any]:
    """Run every missing run of ``spec`` and append it to ``log``.

    Parameters
    ----------
    spec : StudyPlan
        The study: a :class:`~risloc_rt.studies.spec.StudySpec`, or a floor map's cells.
    log : RunLog
        The open run log; its finished runs are skipped, and its ``noise_stream`` is the one the runs draw.
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
    long_ok : bool
        Run a study whose expected time exceeds :data:`LONG_SECONDS` (:func:`check_budget`).
    device : {"cpu", "cuda", "auto"}
        Where each batch's noise and detector run (:func:`run_batch`); checked here first, so a
        missing GPU is a one-line :class:`dsp.DeviceError` before any work (on a Dask cluster the
        workers resolve it on their own machines).

    Returns
    -------
    dict
        ``{"crb": {point: {...}}, "prepare_seconds": {point: s}, "warnings": {point: [...]},
        "retried": [messages], "wall_seconds": s, "new_runs": n, "devices": [...]}`` (bounds in m,
        rad, m/s; times in s; ``devices``: the distinct :func:`risloc_rt.io.report.run_environment` of
        this sitting's batches, each also recorded beside the log, :meth:`RunLog.record_device`).

    Raises
    ------
    TypeError
        ``prepare`` is not a module-level function.
    StudyError
        A batch killed its worker :data:`MAX_ATTEMPTS` times, the Dask cluster gave up on it, or the
        study is expected to take longer than :data:`LONG_SECONDS` without ``long_ok``.
    dsp.budget.BudgetError
        The study's rows would exceed the memory limit (:func:`check_budget`).
    """
    from tqdm import tqdm

    check_preparer(prepare)
    from dsp import backend_for

    if dask is None:
        backend_for(device)  # a missing GPU or CuPy: one line now, not a failure in every worker
    notice = notice or (lambda msg: print(msg, file=sys.stderr))
    if dask is None:
        check_budget(spec, log.done(), prepare=prepare, workers=workers, long_ok=long_ok,
                     say=None if quiet else (lambda msg: print(msg, file=sys.stderr)))
    else:
        check_budget(spec, log.done(), prepare=prepare, workers=_dask_threads(dask), long_ok=long_ok,
                     say=None if quiet else (lambda msg: print(msg, file=sys.stderr)))
    batches = plan_batches(spec, log.done(), workers=workers, max_size=DEVICE_BATCH_RUNS if device != "cpu" else 25)
    stream = log.noise_stream
    total = spec.runs * len(spec.points())
    done_before = sum(1 for (p, r) in log.done() if r < spec.runs)
    info: dict[str, Any] = {"crb": {}, "prepare_seconds": {}, "warnings": {}, "retried": [], "new_runs": 0,
                            "devices": []}
    start = time.perf_counter()
    bar = tqdm(total=total, initial=done_before, unit="run", desc=spec.name, disable=quiet, smoothing=0.05,
               dynamic_ncols=True, file=sys.stderr)

    def take(result: dict[str, Any], batch: Batch) -> None:
        if result.get("device") is not None and result["device"] not in info["devices"]:
            info["devices"].append(result["device"])
            log.record_device(result["device"])  # in the folder before its rows: no row without its device
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
            _run_dask(spec, prepare, batches, dask, take, say, device, stream)
        elif workers == 1:
            for b in batches:
                take(run_batch(prepare, b.params, b.point, b.start, b.stop, spec.seed, device, 1, stream), b)
        else:
            _run_pool(spec, prepare, batches, workers, take, say, device, stream)
        # bounds of points whose runs were all done before this start (needed by the summary)
        for p, params in enumerate(spec.points()):
            if p not in info["crb"]:
                with one_thread():
                    prep = _prepared(prepare, params)
                info["crb"][p], info["prepare_seconds"][p] = prep.crb, prep.seconds
                info["warnings"][p] = list(prep.params.get("warnings", ()))
    finally:
        bar.close()
    info["wall_seconds"] = time.perf_counter() - start
    return info


def _run_pool(spec: StudyPlan, prepare: Preparer, batches: Iterator[Batch], workers: int, take: Callable,
              say: Callable, device: str = "cpu", stream: str = HOST_STREAM) -> None:
    import multiprocessing

    attempts: dict[Batch, int] = {}
    retry: list[Batch] = []  # batches whose worker died, run again before the rest of the (lazy) plan
    plan = iter(batches)

    def next_batch() -> Batch | None:
        return retry.pop(0) if retry else next(plan, None)

    with one_thread_environment():
        b: Batch | None = next_batch()
        while b is not None:
            pool = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                                       initializer=init_worker, initargs=(os.getpid(), ONE_THREAD_ENV))
            running: dict[Any, Batch] = {}
            broken: list[Batch] = []
            try:
                while b is not None or running:
                    try:
                        while b is not None and len(running) < workers:  # one batch per worker: a death names its batch
                            running[pool.submit(run_batch, prepare, b.params, b.point, b.start, b.stop,
                                                spec.seed, device, workers, stream)] = b
                            b = next_batch()
                    except BrokenProcessPool:  # a worker died since the last wait: the running batches retry
                        broken += list(running.values())
                        running.clear()
                        break
                    finished, _ = wait(running, return_when=FIRST_COMPLETED)
                    for fut in finished:
                        done_batch = running.pop(fut)
                        try:
                            result = fut.result()
                        except BrokenProcessPool:
                            broken.append(done_batch)
                            continue
                        take(result, done_batch)
                    if broken:
                        broken += list(running.values())
                        running.clear()
                        break
            finally:
                pool.shutdown(wait=not broken, cancel_futures=True)
            for d in broken:
                attempts[d] = attempts.get(d, 0) + 1
                if attempts[d] >= MAX_ATTEMPTS:
                    raise StudyError(f"{d.label}: its worker process died {attempts[d]} times (killed or out of "
                                     "memory); the finished runs are kept, rerun with fewer --workers to continue")
                say(f"warning: a worker process died while running {d.label} (attempt {attempts[d]}); retrying it")
            if broken:
                if b is not None:
                    retry.append(b)  # taken from the plan but not submitted: after the broken ones
                retry[:0] = broken
                retry.sort(key=lambda x: (x.point, x.start))
                b = next_batch()


@contextlib.contextmanager
def one_thread_environment() -> Iterator[None]:
    """:data:`ONE_THREAD_ENV` set to ``"1"`` (unless set) while worker processes are spawned, then as it was.

    Spawned workers read them when they import NumPy, before their initializer could set them.

    Yields
    ------
    None
    """
    saved = {k: os.environ.get(k) for k in ONE_THREAD_ENV}
    for k in ONE_THREAD_ENV:
        os.environ.setdefault(k, "1")
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


@contextlib.contextmanager
def worker_pool(workers: int) -> Iterator[ProcessPoolExecutor]:
    """``workers`` spawned processes started as a study's (``risloc_rt._workers.init_worker``).

    Each ignores Ctrl-C (this process handles it), runs its numerical libraries on one thread and
    dies with this process. On an exception (Ctrl-C included) the pool drops what has not started
    and is not waited for; otherwise it is shut down when every task is done.

    Parameters
    ----------
    workers : int
        Processes (>= 1).

    Yields
    ------
    concurrent.futures.ProcessPoolExecutor
    """
    import multiprocessing

    with one_thread_environment():
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                                   initializer=init_worker, initargs=(os.getpid(), ONE_THREAD_ENV))
        try:
            yield pool
        except BaseException:
            pool.shutdown(wait=False, cancel_futures=True)
            raise
        pool.shutdown(wait=True)


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


def _dask_threads(address: Any) -> int:
    """Threads of the Dask cluster at ``address`` (a client, or an address: connected to and closed)."""
    client = connect_dask(address)
    try:
        return max(1, sum(client.nthreads().values()))
    except Exception:  # noqa: BLE001 - an estimate only; the run itself reports a failing cluster
        return 1
    finally:
        if isinstance(address, str):
            client.close()


def _run_dask(spec: StudyPlan, prepare: Preparer, batches: Iterator[Batch], address: Any, take: Callable,
              say: Callable, device: str = "cpu", stream: str = HOST_STREAM) -> None:
    from distributed import as_completed
    from distributed.scheduler import KilledWorker

    client = connect_dask(address)
    plan = iter(batches)

    def submit(b: Batch) -> Any:
        fut = client.submit(run_batch, prepare, b.params, b.point, b.start, b.stop, spec.seed, device, 1, stream,
                            key=f"risloc-study-{spec.key}-{b.point}-{b.start}-{b.stop}", pure=False,
                            retries=MAX_ATTEMPTS - 1)
        futures[fut] = b
        return fut

    try:
        futures: dict[Any, Batch] = {}
        first = [submit(b) for b, _ in zip(plan, range(DASK_WINDOW))]  # a window of the lazy plan
        with client.as_current():
            pending = as_completed(first)
            for fut in pending:
                b = futures.pop(fut)
                try:
                    take(fut.result(), b)
                except KilledWorker as exc:
                    raise StudyError(f"{b.label}: Dask workers died running it ({exc}); the finished runs are kept, "
                                     "rerun the same command to continue") from None
                nxt = next(plan, None)
                if nxt is not None:
                    pending.add(submit(nxt))
    finally:
        if isinstance(address, str):
            client.close()

"""``run_study``: a study folder from a spec, resumable, on local processes or a Dask cluster.

The points are the spec's grid; the engine prepares each with :func:`risloc_rt.studies.kernel.prepare_point`
(the analytic scenario or a traced hall) and runs it with :func:`risloc_rt.studies.kernel.run_once`.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .._files import atomic_write_bytes
from .._outputs import output_folder
from .engine import check_rows_memory, choose_workers, default_workers, execute
from .figures import plot_summary
from .kernel import prepare_point
from .spec import StudySpec
from .store import SUMMARY, TABLE, open_study_folder, study_device, write_parquet
from .summary import summarize

__all__ = ["StudyResult", "run_study"]


@dataclass(frozen=True)
class StudyResult:
    """What a finished study wrote and how it went.

    Attributes
    ----------
    summary : dict
        The content of ``summary.json`` (errors in m and rad, times in s).
    folder : Path
    table, summary_path, figure : Path
        ``runs.parquet``, ``summary.json`` and the figure (None with ``figures=False``).
    new_runs : int
        Runs computed by this call (the rest came from the log of an earlier start).
    wall_seconds : float
        Wall-clock time of this call's runs [s].
    """

    summary: dict[str, Any]
    folder: Path
    table: Path
    summary_path: Path
    figure: Path | None
    new_runs: int
    wall_seconds: float


def run_study(spec: StudySpec, out: str | Path, *, workers: int | None = None, dask: Any = None,
              quiet: bool = False, force: bool = False, figures: bool = True, force_long: bool = False,
              force_workers: bool = False, device: str | None = None) -> StudyResult:
    """Run (or continue) ``spec`` in folder ``out``; see ``docs/studies.md``.

    Parameters
    ----------
    spec : StudySpec
        What to vary and how many runs per point.
    out : path
        The study folder: created, or reopened to continue the same study.
    workers : int, optional
        Local worker processes (default: all cores, as far as the memory limit allows); 1 runs in this
        process. More than the cores or the memory limit allows are lowered with a note
        (:func:`risloc_rt.studies.engine.choose_workers`) unless ``force_workers``.
    dask : str or distributed.Client, optional
        A Dask scheduler address (``tcp://host:8786``) or client: run the batches there instead.
    quiet : bool
        No progress bar.
    force : bool
        Reuse a folder that holds another study (its log is kept under another name).
    figures : bool
        Draw ``study.png``.
    force_long : bool
        Run a study expected to take longer than a day (``--force-long``;
        :func:`risloc_rt.studies.engine.check_budget`).
    force_workers : bool
        Keep ``workers`` above the core count (``--force-workers``).
    device : {"cpu", "cuda", "auto"}, optional
        Where the runs' noise and detector go (``--device``; default ``$RISLOC_DEVICE``, else ``cpu``):
        :func:`risloc_rt.studies.engine.run_batch`. On a given device the rows do not depend on it
        otherwise (batch size, workers, Dask); on another device the noise is another stream with
        the same law (``docs/studies.md``).

    Returns
    -------
    StudyResult

    Raises
    ------
    StudyFolderError
        ``out`` holds another study (or no study) and ``force`` is not given.
    StudyError
        A batch killed its worker too often, the Dask cluster gave up on it, or the study is expected
        to take longer than a day without ``force_long``.
    dsp.budget.BudgetError
        The study's rows, or ``force_workers``'s workers, exceed the memory limit.
    ValueError
        ``workers`` < 1.
    """
    if dask is None:
        workers = choose_workers(workers, insist=force_workers)
    else:  # batch sizes only: the cluster's threads are the parallelism
        workers = choose_workers(workers, insist=True) if workers is not None else default_workers()
    folder = Path(out)
    device, stream = study_device(device, local=dask is None)  # one line before any folder is made
    check_rows_memory(spec.name, len(spec.points()), int(spec.runs))  # and a --runs beyond memory too
    log = open_study_folder(folder, spec, force=force, stream=stream)
    try:
        info = execute(spec, log, prepare=prepare_point, workers=workers, dask=dask, quiet=quiet, long_ok=force_long,
                       device=device)
        rows = list(log.rows.values())
    finally:
        log.close()
    summary = summarize(spec, rows, info)
    summary["wall_seconds"] = info["wall_seconds"]
    summary["workers"] = "dask" if dask is not None else workers
    summary["devices"] = log.devices  # what ran the runs, every sitting's: DSP device and library, trace variant
    summary["noise_stream"] = log.noise_stream  # which random stream drew the receiver noise (store.HOST_STREAMS)
    from ..io.report import json_safe

    # the derived files are moved in together (risloc_rt._outputs): an interrupt leaves the old set or
    # the new one, never a new summary beside an old figure; the folder is the study's (its manifest
    # was checked above), so its derived files are replaced
    with output_folder(folder, force=True, flag="--out") as stage:
        write_parquet(stage / TABLE, rows, spec.points(), study_seed=spec.seed, runs=spec.runs)
        atomic_write_bytes(stage / SUMMARY, json.dumps(json_safe(summary), indent=1).encode() + b"\n")
        if figures:
            plot_summary(summary, stage / "study.png")
    table, path = folder / TABLE, folder / SUMMARY
    fig = folder / "study.png" if figures else None
    return StudyResult(summary=summary, folder=folder, table=table, summary_path=path, figure=fig,
                       new_runs=info["new_runs"], wall_seconds=info["wall_seconds"])

"""The speed study of ``risloc speed``: speed against error of every estimator and trace setting.

For every hall and radar position it traces the hall with a grid of ray-tracer settings (depth,
rays per source, and the mechanisms beyond specular reflection: diffuse reflection, diffraction,
refraction), synthesises noisy Table I captures with the same noise realizations for every
setting, and localizes each with every estimator: the paper's grid method with its full 2-D DFT
(``full``, the reference: the paper's current method), the same grid maximum found by the
screened zoom search (``zoom``), and the refined estimator (``refined``). Each row holds time per
realization [s] beside the model error against a reference trace [dB] and the position RMSE [m]
against the Cramér–Rao bound; :func:`format_table` adds the ratios against the paper's full-grid
method, :func:`mechanism_verdicts` says per hall which mechanisms change the localization and
which only cost time, :func:`plot_tradeoff` draws the trade-off. ``docs/benchmarks.md`` holds a run.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..plotting import new_figure, save_figure

__all__ = ["TRACE_GRID", "REFERENCE", "ESTIMATORS", "MOVE_FRACTION", "run_speed_study", "model_error_db",
           "format_table", "mechanism_verdicts", "plot_tradeoff"]

#: (label, TraceSettings overrides). The first is the default, against which shifts are measured.
TRACE_GRID: tuple[tuple[str, dict[str, Any]], ...] = (
    ("d3 1e5 (default)", {}),
    ("d1 1e4", {"max_depth": 1, "samples_per_src": 10_000}),
    ("d2 1e4", {"max_depth": 2, "samples_per_src": 10_000}),
    ("d3 1e4", {"max_depth": 3, "samples_per_src": 10_000}),
    ("d4 1e5", {"max_depth": 4, "samples_per_src": 100_000}),
    ("d3 1e6", {"max_depth": 3, "samples_per_src": 1_000_000}),
    ("+diffuse S=0.3", {"diffuse_reflection": True, "scattering_coefficient": 0.3}),
    ("+diffraction", {"diffraction": True}),
    ("+refraction", {"refraction": True}),
    ("+all three", {"diffuse_reflection": True, "scattering_coefficient": 0.3, "diffraction": True,
                    "refraction": True}),
)
#: The model reference: the cube every setting's is compared with (``model_error_db``).
REFERENCE = {"max_depth": 4, "samples_per_src": 1_000_000}
#: Estimators: (label, ProcessingConfig.doppler_search, estimator).
#: The paper's two are timed as ``dsp.localize(dsp.scan_beams(...))``; the refined one as ``process_capture``
#: (detection, refinement, uncertainty and flags included). Its 1σ (PEB) is the CRB of every row.
ESTIMATORS = (("full", "full", "paper"), ("zoom", "zoom", "paper"), ("refined", "zoom", "refined"))
#: A mechanism "changes the localization" when it moves the refined estimate by more than this fraction of its 1σ.
MOVE_FRACTION = 0.1


@dataclass
class _Cell:
    """One (scene, trace setting, estimator) cell of the study, filled realization by realization."""

    scene: str
    setting: str
    estimator: str
    trace_s: list[float] = field(default_factory=list)
    paths: list[int] = field(default_factory=list)
    model_db: list[float] = field(default_factory=list)
    synth_s: list[float] = field(default_factory=list)
    dsp_s: list[float] = field(default_factory=list)
    err: list[float] = field(default_factory=list)
    peb: list[float] = field(default_factory=list)
    shift: list[float] = field(default_factory=list)  # |Δ position| against the default setting [m]

    def summary(self) -> dict[str, Any]:
        """The cell's row: medians of the times [s], RMSE and PEB [m] (see :func:`run_speed_study`)."""
        med = lambda x: float(np.median(x)) if x else float("nan")  # noqa: E731
        rmse = float(np.sqrt(np.mean(np.square(self.err)))) if self.err else float("nan")
        peb = float(np.sqrt(np.mean(np.square(self.peb)))) if self.peb else float("nan")
        return {"scene": self.scene, "setting": self.setting, "estimator": self.estimator,
                "n": len(self.err), "trace_s": med(self.trace_s), "paths": med(self.paths),
                "model_error_db": med(self.model_db), "synthesis_s": med(self.synth_s), "dsp_s": med(self.dsp_s),
                "rmse_m": rmse, "peb_m": peb, "rmse_over_crb": rmse / peb if peb > 0 else float("nan"),
                "max_shift_m": float(np.max(self.shift)) if self.shift else float("nan")}


def model_error_db(cube: np.ndarray, ref: np.ndarray) -> float:
    """How far a noiseless beat cube is from the reference one: 20 log10(‖Y − Y_ref‖ / ‖Y_ref‖).

    Parameters
    ----------
    cube, ref : complex ndarray, shape (M, K, N)
        The cubes [√W], same shape.

    Returns
    -------
    float
        The relative error [dB]; −inf when the cubes are equal.
    """
    diff = np.linalg.norm(cube - ref)
    return float("-inf") if diff == 0 else float(20 * np.log10(diff / np.linalg.norm(ref)))


def _trace(scene: str, position: int, overrides: dict[str, Any]) -> tuple[Any, Any, float]:
    """(HallScenario, HallPaths, warm trace seconds): traced twice, the second time timed."""
    from ..hall.raytrace.result import TraceSettings
    from ..hall.scenario import hall_paths, hall_scenario
    from ..hall.pruning import AliasWarning

    hs = hall_scenario(scene, radar_index=position, trace=TraceSettings(**overrides))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AliasWarning)
        hall_paths(hs)  # compiles the solver kernels for this setting (once per machine) and loads the scene
        hp = hall_paths(hs)
    return hs, hp, hp.trace.timing["solve"]


def run_speed_study(scenes: list[str], *, realizations: int, full: int, seed: int, positions: int,
                    grid: tuple[tuple[str, dict[str, Any]], ...] = TRACE_GRID,
                    reference: dict[str, Any] = REFERENCE,
                    log: Callable[[str], None] = print, backend: Any = None) -> list[dict[str, Any]]:
    """Speed against error of every estimator and trace setting (module docstring).

    Parameters
    ----------
    scenes : list of str
        Halls in ``scenes/`` (or scene folders).
    realizations : int
        Noise realizations per setting and radar position (the boxmuller noise stream; the same
        realizations for every setting).
    full : int
        How many of them the paper's full 2-D DFT also processes, at the first setting only.
    seed : int
        Noise seed: realization r at position p of scene s draws from
        ``SeedSequence([seed, p, sum(map(ord, s))]).spawn(realizations)[r]``.
    positions : int
        Radar positions per scene (the first ones of its spec).
    grid : tuple of (str, dict)
        (label, ``TraceSettings`` overrides); the first is the default that shifts are measured against.
    reference : dict
        ``TraceSettings`` overrides of the model reference (default :data:`REFERENCE`).
    log : callable
        Receives one progress line per scene, position and setting.
    backend : dsp.ArrayBackend, optional
        Where the refined estimator's whole-cube work runs (detector and reads of the cube; ``--device``;
        :func:`risloc_rt.io.report.process_capture`); default NumPy. The synthesis and the paper's two grid
        methods run on the host.

    Returns
    -------
    list of dict
        One row per (scene, setting, estimator), in the order first met: ``n`` (realizations),
        medians of ``trace_s`` (warm trace), ``synthesis_s`` and ``dsp_s`` [s] and of ``paths``
        (kept) and ``model_error_db`` [dB]; ``rmse_m`` (position RMSE [m]), ``peb_m`` (RMS of the
        refined estimator's 1σ on the same captures [m]), ``rmse_over_crb``, ``max_shift_m``
        (largest move against the default setting with the same noise [m]; NaN for the default).
    """
    import dsp

    from ..authoring.scene_folder import scene_directory
    from ..authoring.spec import load_spec
    from ..io.report import process_capture
    from ..model.beat import beat_cube
    from ..model.simulate import simulate

    rows: dict[tuple[str, str, str], _Cell] = {}
    for scene in scenes:
        n_pos = min(positions, len(load_spec(scene_directory(scene) / "spec.toml").radar_positions()))
        for pos in range(n_pos):
            _, ref_paths, _ = _trace(scene, pos, reference)
            base_positions: dict[tuple[str, int], np.ndarray] = {}
            for label, overrides in grid:
                hs, hp, t_trace = _trace(scene, pos, overrides)
                sc = hs.base
                ref = beat_cube(ref_paths.paths, radar=sc.radar, sweep=sc.sweep, ris=sc.ris)
                clean = beat_cube(hp.paths, radar=sc.radar, sweep=sc.sweep, ris=sc.ris)
                model_db = model_error_db(clean, ref)
                log(f"  {scene} radar {pos} {label}: {len(hp.paths)} paths kept of {len(hp.candidates)}, "
                    f"warm trace {t_trace:.3f} s, model error {model_db:.1f} dB")
                streams = np.random.SeedSequence([seed, pos, sum(map(ord, scene))]).spawn(realizations)
                for r, ss in enumerate(streams):
                    t0 = time.perf_counter()
                    cap = simulate(sc, rng=np.random.default_rng(ss), paths=hp.paths, noise_stream="boxmuller")
                    t_synth = time.perf_counter() - t0
                    refined, t_ref = process_capture(cap, estimator="refined", backend=backend)
                    peb = float(refined.std.peb) if refined.std is not None else float("nan")
                    for est, search, _ in ESTIMATORS:
                        if est == "full" and (label != grid[0][0] or r >= full):
                            continue
                        if est == "refined":
                            loc, t_dsp = refined, t_ref
                        else:  # the paper's method exactly: localize(scan_beams(cube))
                            t0 = time.perf_counter()
                            loc = dsp.localize(dsp.scan_beams(cap.cube, cap.sweep, cap.radar,
                                                              replace(sc.processing, doppler_search=search)),
                                               radar=cap.radar, pose=cap.ris.pose, loopback_delay=cap.ris.loopback_delay)
                            t_dsp = time.perf_counter() - t0
                        row = rows.setdefault((scene, label, est), _Cell(scene, label, est))
                        row.trace_s.append(t_trace)
                        row.paths.append(len(hp.paths))
                        row.model_db.append(model_db)
                        row.synth_s.append(t_synth)
                        row.dsp_s.append(t_dsp)
                        row.err.append(float(np.linalg.norm(loc.position - sc.truth.ue_position)))
                        row.peb.append(peb)
                        key = (est, r)
                        if label == grid[0][0]:
                            base_positions[key] = loc.position
                        elif key in base_positions:
                            row.shift.append(float(np.linalg.norm(loc.position - base_positions[key])))
    return [row.summary() for row in rows.values()]


def format_table(summaries: list[dict[str, Any]]) -> str:
    """The study as a Markdown table, with ratios against the paper's full-grid method per scene.

    Parameters
    ----------
    summaries : list of dict
        The rows of :func:`run_speed_study`.

    Returns
    -------
    str
        A header, a separator and one line per row: times [s], RMSE and shift [mm], "time / full"
        (synthesis + DSP over the scene's ``full`` row's) and "RMSE / full" (NaN without one).
    """
    lines = ["| scene | trace setting | estimator | n | warm trace [s] | kept paths | model error [dB] | "
             "synthesis [s] | DSP [s] | time / full | position RMSE [mm] | RMSE/CRB | RMSE / full | "
             "max shift vs default [mm] |", "|" + " --- |" * 14]
    for s in summaries:
        full = next((x for x in summaries if x["scene"] == s["scene"] and x["estimator"] == "full"), None)
        per_real = s["synthesis_s"] + s["dsp_s"]
        t_ratio = per_real / (full["synthesis_s"] + full["dsp_s"]) if full else float("nan")
        e_ratio = s["rmse_m"] / full["rmse_m"] if full and full["rmse_m"] > 0 else float("nan")
        model = "reference" if s["model_error_db"] == float("-inf") else f"{s['model_error_db']:.1f}"
        shift = "–" if np.isnan(s["max_shift_m"]) else f"{1e3 * s['max_shift_m']:.2f}"
        lines.append(f"| {s['scene']} | {s['setting']} | {s['estimator']} | {s['n']} | {s['trace_s']:.3f} | "
                     f"{s['paths']:.0f} | {model} | {s['synthesis_s']:.3f} | {s['dsp_s']:.3f} | {t_ratio:.3f} | "
                     f"{1e3 * s['rmse_m']:.2f} | {s['rmse_over_crb']:.2f} | {e_ratio:.2f} | {shift} |")
    return "\n".join(lines)


def mechanism_verdicts(summaries: list[dict[str, Any]]) -> list[str]:
    """Per scene and mechanism: does it move the refined estimate by more than 10 % of its 1σ?

    Parameters
    ----------
    summaries : list of dict
        The rows of :func:`run_speed_study`; the mechanism rows are the refined ones whose setting
        starts with ``+``.

    Returns
    -------
    list of str
        One line per mechanism row: "changes the localization" when ``max_shift_m`` >
        :data:`MOVE_FRACTION` × ``peb_m``, else "only costs time", with the shift and 1σ [mm], the
        model change [dB] and the warm trace time [s].
    """
    out = []
    for s in summaries:
        if s["estimator"] != "refined" or not s["setting"].startswith("+"):
            continue
        moved = s["max_shift_m"] > MOVE_FRACTION * s["peb_m"]
        out.append(f"{s['scene']}: {s['setting']} {'changes the localization' if moved else 'only costs time'} "
                   f"(largest shift {1e3 * s['max_shift_m']:.2f} mm against 1σ = {1e3 * s['peb_m']:.2f} mm; "
                   f"model change {s['model_error_db']:.1f} dB; warm trace {s['trace_s']:.2f} s)")
    return out


def plot_tradeoff(summaries: list[dict[str, Any]], path: str | Path) -> Path:
    """Two panels: trace time against model error per setting; time per realization against RMSE.

    Parameters
    ----------
    summaries : list of dict
        The rows of :func:`run_speed_study` (the reference's −inf dB is drawn at −200 dB).
    path : path-like
        The PNG to write (atomically, :func:`risloc_rt.plotting.save_figure`).

    Returns
    -------
    Path
        ``path``.
    """
    fig, (a, b) = new_figure(figsize=(12, 4.8), nrows=1, ncols=2)
    scenes = sorted({s["scene"] for s in summaries})
    for i, scene in enumerate(scenes):
        colour = f"C{i}"
        trace = [s for s in summaries if s["scene"] == scene and s["estimator"] == "zoom"]
        for s in trace:
            y = -200.0 if s["model_error_db"] == float("-inf") else s["model_error_db"]
            a.scatter(s["trace_s"], y, color=colour, label=scene if s is trace[0] else None)
            a.annotate(s["setting"].replace(" (default)", "*"), (s["trace_s"], y), fontsize=6)
        for marker, est in zip("osD", ("full", "zoom", "refined")):
            pts = [s for s in summaries if s["scene"] == scene and s["estimator"] == est]
            b.scatter([s["synthesis_s"] + s["dsp_s"] for s in pts], [1e3 * s["rmse_m"] for s in pts], color=colour,
                      marker=marker, label=f"{scene} {est}")
    a.set(xscale="log", xlabel="warm trace time [s]", ylabel="model error against depth 4, 10⁶ rays [dB]",
          title="ray-trace settings")
    b.set(xscale="log", yscale="log", xlabel="synthesis + DSP per realization [s]", ylabel="position RMSE [mm]",
          title="estimators (every trace setting)")
    a.legend(fontsize=7)
    b.legend(fontsize=6, ncol=2)
    return save_figure(fig, path)

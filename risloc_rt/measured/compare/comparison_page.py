"""The ``risloc compare`` folder: PNG figures, ``comparison.json`` and a self-contained ``index.html``.

``index.html`` needs nothing but the folder: the figures are PNG files next to it (relative
links), the style is inline, nothing is fetched from a network. A small inline script marks each
figure ``data-loaded="yes"`` once the browser has decoded it (``complete && naturalWidth > 0``)
and writes the count into ``#figure-status``, so a headless browser can check the page.
"""

from __future__ import annotations

import html
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from ..._files import atomic_write_bytes
from ...plotting import new_figure, save_figure
from .comparison import Comparison

__all__ = ["BASELINE_KEYS", "FIGURES", "baseline_document", "sweep_mean_document", "write_comparison"]

FIGURES = {"range_profiles": "range_profiles.png", "delay_doppler": "delay_doppler.png", "sweep": "sweep_power.png"}
DPI = 90
"""Resolution of the PNG figures [dots per inch]."""


def _db(x: np.ndarray) -> np.ndarray:
    return 10 * np.log10(np.maximum(np.asarray(x, float), 1e-300))


def _range_profiles(c: Comparison, path: Path) -> None:
    """Zero-Doppler range profiles [dB counts²] against range [m]: the best beam (peaks labelled), the sweep mean."""
    angle = np.rad2deg(c.measured.sweep.angles[:, 0])
    fig, axes = new_figure(figsize=(10, 7), nrows=2, ncols=1, sharex=True)
    for ax, (meas, sim, title) in zip(axes, ((c.profile_measured, c.profile_simulated,
                                               f"best beam {c.beam} ({angle[c.beam]:+.1f}°)"),
                                              (c.mean_profile_measured, c.mean_profile_simulated, "mean over the sweep"))):
        ax.plot(c.distance, _db(meas), lw=1.0, label="measured")
        ax.plot(c.distance, _db(sim), lw=1.0, alpha=0.8, label="ray-traced")
        ax.set_ylabel("power [dB counts²]")
        ax.set_title(f"zero-Doppler range profile, {title}")
        ax.grid(alpha=0.3)
    for p in c.peaks:
        axes[0].annotate(p["label"][:40], (p["distance_m"], p["power_db"]), fontsize=6, rotation=30,
                         color="k" if p["explained"] else "r")
    axes[0].legend()
    axes[1].set_xlabel("range τ·c/2 [m]")
    save_figure(fig, path, tight=True, dpi=DPI)


def _delay_doppler(c: Comparison, path: Path) -> None:
    """The best beam's delay-Doppler maps [dB counts²], measured and ray-traced, on one colour scale (70 dB)."""
    dm, ds = _db(c.ddm_measured.power), _db(c.ddm_simulated.power)
    vmax = max(dm.max(), ds.max())
    vmin = vmax - 70
    fig, axes = new_figure(figsize=(12, 4.5), nrows=1, ncols=2, sharey=True)
    for ax, d, ddm, title in ((axes[0], dm, c.ddm_measured, "measured"), (axes[1], ds, c.ddm_simulated, "ray-traced")):
        im = ax.imshow(d, aspect="auto", origin="lower", vmin=vmin, vmax=vmax, cmap="viridis",
                       extent=(ddm.distance[0], ddm.distance[-1], ddm.velocity[0], ddm.velocity[-1]))
        ax.set_title(f"delay-Doppler map, {title}, beam {c.beam}")
        ax.set_xlabel("range τ·c/2 [m]")
    axes[0].set_ylabel("velocity [m/s]")
    fig.colorbar(im, ax=axes, label="power [dB counts²] (one scale)")
    save_figure(fig, path, tight=False, dpi=DPI)


def _sweep_power(c: Comparison, path: Path) -> None:
    """P_ave [dB counts²] of every beam against its azimuth [deg], measured and ray-traced."""
    angle = np.rad2deg(c.measured.sweep.angles[:, 0])
    fig, ax = new_figure(figsize=(8, 4), nrows=1)
    ax.plot(angle, _db(c.pave_measured), "o-", ms=3, label="measured")
    ax.plot(angle, _db(c.pave_simulated), "s-", ms=3, alpha=0.8, label="ray-traced")
    ax.set_xlabel("RIS beam azimuth [deg]")
    ax.set_ylabel("P_ave [dB counts²]")
    ax.set_title("sweep power P_ave")
    ax.grid(alpha=0.3)
    ax.legend()
    save_figure(fig, path, tight=True, dpi=DPI)


def _figures(c: Comparison, folder: Path) -> None:
    """The three PNG figures of :data:`FIGURES`, each written atomically (:mod:`risloc_rt.plotting`)."""
    _range_profiles(c, folder / FIGURES["range_profiles"])
    _delay_doppler(c, folder / FIGURES["delay_doppler"])
    _sweep_power(c, folder / FIGURES["sweep"])


def _fmt(v: Any, digits: int = 3) -> str:
    if v is None:
        return "–"
    if isinstance(v, float):
        return f"{v:.{digits}f}"
    return html.escape(str(v))


def _html(c: Comparison, doc: dict[str, Any]) -> str:
    s = doc["summary"]
    base = (doc.get("baseline") or {}).get("peaks")
    extra = (lambda i: f"<td>{_fmt(base[i]['delay_residual_mm'], 2)}</td><td>{_fmt(base[i]['power_residual_db'], 2)}</td>"
             if base else "")
    rows = "\n".join(
        f"<tr class=\"{'explained' if p['explained'] else 'unexplained'}\"><td>{i}</td><td>{_fmt(p['distance_m'], 4)}</td>"
        f"<td>{_fmt(p['power_db'], 2)}</td><td>{_fmt(p['label'])}</td><td>{_fmt(p['simulated_distance_m'], 4)}</td>"
        f"<td>{_fmt(p['delay_residual_mm'], 2)}</td><td>{_fmt(p['power_residual_db'], 2)}</td>{extra(i)}</tr>"
        for i, p in enumerate(doc["peaks"]))
    base_heads = "<th>delay residual, baseline [mm]</th><th>power residual, baseline [dB]</th>" if base else ""
    summary = "\n".join(f"<tr><th>{html.escape(k)}</th><td id=\"summary-{html.escape(k)}\">{_fmt(v, 3)}</td></tr>"
                        for k, v in s.items() if not isinstance(v, list))
    figs = "\n".join(f"<figure><img src=\"{name}\" alt=\"{key}\" data-figure=\"{key}\"><figcaption>{key.replace('_', ' ')}"
                     f"</figcaption></figure>" for key, name in FIGURES.items())
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>risloc compare: measured vs ray-traced</title>
<style>body{{font-family:sans-serif;margin:1.5em;max-width:1250px}} table{{border-collapse:collapse;margin:1em 0}}
td,th{{border:1px solid #bbb;padding:2px 8px;text-align:right}} tr.unexplained td{{color:#b00}}
img{{max-width:100%;border:1px solid #ddd}} figure{{margin:1em 0}}</style></head>
<body>
<h1>Measured vs ray-traced</h1>
<p>Scene <code>{html.escape(doc['scene'])}</code>, radar at {html.escape(str([round(v, 3) for v in doc['ue_position_m']]))} m
({html.escape(doc['ue_source'])}), best beam {doc['best_beam']}, {'calibrated' if doc['calibrated'] else 'not calibrated'};
numbers in <a href="comparison.json">comparison.json</a>. Figures loaded: <span id="figure-status">0/{len(FIGURES)}</span>.</p>
<h2>Summary</h2>
<table id="summary">{summary}</table>
{_baseline_html(doc)}<h2>Peaks of the measured range profile (best beam)</h2>
<table id="peaks"><tr><th>#</th><th>range [m]</th><th>power [dB]</th><th>traced path</th><th>simulated range [m]</th>
<th>delay residual [mm]</th><th>power residual [dB]</th>{base_heads}</tr>
{rows}
</table>
{_sweep_mean_html(doc)}{figs}
<script>
function markFigures() {{
  var imgs = document.querySelectorAll("img[data-figure]"), ok = 0;
  for (var i = 0; i < imgs.length; i++) {{
    var good = imgs[i].complete && imgs[i].naturalWidth > 0;
    imgs[i].setAttribute("data-loaded", good ? "yes" : "no");
    if (good) ok++;
  }}
  document.getElementById("figure-status").textContent = ok + "/" + imgs.length;
}}
window.addEventListener("load", markFigures);
</script>
</body></html>
"""


#: The summary's numbers a baseline comparison sets beside this one's (``before`` → ``after``).
BASELINE_KEYS = ("explained", "unexplained", "delay_residual_rms_mm", "power_residual_rms_db",
                 "power_residual_mean_db", "pave_rms_difference_db")


def baseline_document(c: Comparison, baseline: Comparison) -> dict[str, Any]:
    """``comparison.json``'s ``baseline``: the same capture against another hall (e.g. before a material fit).

    The measured peaks do not depend on the hall (found on the measured profile at the measured best
    beam), so the baseline's peak k is this comparison's peak k; only what explains it differs.

    Parameters
    ----------
    c, baseline : Comparison
        The capture against the scene and against the baseline scene (:func:`~.comparison.compare_capture`).

    Returns
    -------
    dict
        ``scene``; ``summary`` (:data:`BASELINE_KEYS`, residuals in mm and dB); ``peaks``, per measured peak
        its baseline ``label``, ``explained``, ``delay_residual_mm`` and ``power_residual_db``; ``change``,
        this comparison's value minus the baseline's for each number of the summary both have.

    Raises
    ------
    ValueError
        When the two are not of the same capture (other measured peaks or best beam).
    """
    same = (c.beam == baseline.beam and len(c.peaks) == len(baseline.peaks)
            and all(a["distance_m"] == b["distance_m"] for a, b in zip(c.peaks, baseline.peaks)))
    if not same:
        raise ValueError("the baseline comparison is not of the same capture (its measured peaks or best beam differ); "
                         "compare one capture against both scenes")
    summary = {k: baseline.summary.get(k) for k in BASELINE_KEYS}
    change = {k: (c.summary[k] - summary[k] if isinstance(c.summary.get(k), (int, float))
                  and isinstance(summary[k], (int, float)) else None) for k in BASELINE_KEYS}
    peaks = [{k: p[k] for k in ("label", "explained", "delay_residual_mm", "power_residual_db")} for p in baseline.peaks]
    return {"scene": baseline.info.get("scene"), "summary": summary, "change": change, "peaks": peaks}


def _baseline_html(doc: dict[str, Any]) -> str:
    """The page's "before and after" table: the baseline scene's summary beside this scene's."""
    base = doc.get("baseline")
    if not base:
        return ""
    rows = "\n".join(f"<tr><th>{html.escape(k)}</th><td id=\"baseline-{html.escape(k)}\">{_fmt(base['summary'][k], 3)}</td>"
                     f"<td>{_fmt(doc['summary'].get(k), 3)}</td><td>{_fmt(base['change'][k], 3)}</td></tr>"
                     for k in BASELINE_KEYS)
    return (f"<h2>Before and after</h2>\n<p>The same capture against the baseline scene "
            f"<code>{html.escape(str(base['scene']))}</code> (before) and <code>{html.escape(doc['scene'])}</code> "
            f"(after).</p>\n<table id=\"baseline\"><tr><th></th><th>before</th><th>after</th><th>change</th></tr>\n"
            f"{rows}\n</table>\n")


def sweep_mean_document(scene: dict[str, Any], baseline: dict[str, Any] | None = None) -> dict[str, Any]:
    """``comparison.json``'s ``sweep_mean``: the static peaks of the sweep's complex mean against the hall, and
    against the baseline hall beside them.

    Parameters
    ----------
    scene : dict
        :func:`~.sweep_mean_peaks.sweep_mean_residuals` against the scene.
    baseline : dict, optional
        The same against the baseline scene. Its peaks are matched to ``scene``'s by their measured range
        (the measured mean is the same; which peaks a hall explains may differ).

    Returns
    -------
    dict
        ``scene``'s document, with ``baseline`` (its ``power_residual_rms_db`` [dB], ``delay_residual_rms_mm`` [mm],
        ``power_residual_weighted_rms_db`` [dB], ``power_chi2`` over its ``peaks_explained`` peaks,
        ``peaks``: per peak of ``scene`` the baseline's ``power_residual_db`` and ``delay_residual_mm``, None where
        the baseline hall leaves that peak out) when a baseline is given.
    """
    doc = dict(scene)
    if baseline is not None:
        by_range = {round(p["distance_m"], 9): p for p in baseline["peaks"]}
        doc["baseline"] = {
            **{k: baseline.get(k) for k in ("power_residual_rms_db", "delay_residual_rms_mm",
                                            "power_residual_weighted_rms_db", "power_chi2")},
            "peaks_explained": len(baseline["peaks"]),
            "peaks": [{k: (by_range.get(round(p["distance_m"], 9)) or {}).get(k)
                       for k in ("power_residual_db", "delay_residual_mm")} for p in scene["peaks"]]}
    return doc


def _sweep_mean_html(doc: dict[str, Any]) -> str:
    """The page's table of the sweep mean's static peaks (with the baseline's residuals beside them)."""
    sm = doc.get("sweep_mean")
    if sm is None:
        return ""
    base = sm.get("baseline")
    heads = "<th>power residual, baseline [dB]</th><th>delay residual, baseline [mm]</th>" if base else ""
    rows = "\n".join(
        f"<tr><td>{_fmt(p['distance_m'], 4)}</td><td>{_fmt(p['label'])}</td><td>{_fmt(p['snr_db'], 1)}</td>"
        f"<td>{_fmt(p['sigma_db'], 2)}</td><td>{_fmt(p['power_residual_db'], 2)}</td>"
        f"<td>{_fmt(p['delay_residual_mm'], 2)}</td><td>{_fmt(p['delay_sigma_mm'], 2)}</td>"
        + (f"<td>{_fmt(base['peaks'][i]['power_residual_db'], 2)}</td><td>{_fmt(base['peaks'][i]['delay_residual_mm'], 2)}"
           f"</td>" if base else "") + "</tr>"
        for i, p in enumerate(sm["peaks"]))
    n = len(sm["peaks"])
    rms = (f"power residual rms {_fmt(sm['power_residual_rms_db'], 3)} dB, weighted by 1/σ² "
           f"{_fmt(sm.get('power_residual_weighted_rms_db'), 3)} dB, χ² {_fmt(sm.get('power_chi2'), 3)} for {n} peak(s) "
           f"(a hall that predicts every peak within its noise: {n} ± {_fmt(math.sqrt(2 * n), 2)}); delay residual rms "
           f"{_fmt(sm['delay_residual_rms_mm'], 3)} mm")
    if base:
        rms += (f" (baseline scene: {_fmt(base['power_residual_rms_db'], 3)} dB, weighted "
                f"{_fmt(base.get('power_residual_weighted_rms_db'), 3)} dB, χ² {_fmt(base.get('power_chi2'), 3)} for "
                f"{base.get('peaks_explained', n)} peak(s); {_fmt(base['delay_residual_rms_mm'], 3)} mm)")
    left = len(sm["left_out"])
    return (f"<h2>Static peaks of the sweep mean</h2>\n<p>The complex mean over the sweep's {sm['beams']} beams: a "
            f"static echo keeps its power, the noise falls by the beam count (the peaks a material fit uses; "
            f"docs/calibration-materials.md). {len(sm['peaks'])} static peak(s), {left} other peak(s) of the mean left "
            f"out (reasons in comparison.json); <span id=\"sweep-mean-rms\">{rms}</span>.</p>\n"
            f"<table id=\"sweep-mean\"><tr><th>range [m]</th><th>traced path</th><th>SNR in the mean [dB]</th>"
            f"<th>power σ [dB]</th><th>power residual [dB]</th><th>delay residual [mm]</th><th>delay σ [mm]</th>"
            f"{heads}</tr>\n{rows}\n</table>\n")


def write_comparison(c: Comparison, folder: str | Path, *, baseline: Comparison | None = None,
                     sweep_mean: dict[str, Any] | None = None) -> dict[str, Path]:
    """Write the figures, ``comparison.json`` and ``index.html`` into ``folder``, each atomically.

    Parameters
    ----------
    c : Comparison
        From :func:`~.comparison.compare_capture`.
    folder : path
        Created when missing; the page's files in it are replaced.
    baseline : Comparison, optional
        The same capture against another hall (before a material fit, say): its residuals are set beside
        ``c``'s (:func:`baseline_document`; the page's "Before and after" table, the peak table's
        baseline columns, ``comparison.json``'s ``baseline``).
    sweep_mean : dict, optional
        :func:`sweep_mean_document`: the static peaks of the sweep mean (the page's "Static peaks of the sweep
        mean", ``comparison.json``'s ``sweep_mean``).

    Returns
    -------
    dict of str to Path
        ``index``, ``json`` and one entry per figure of :data:`FIGURES`.
    """
    folder = Path(folder)
    doc = c.to_json()
    if baseline is not None:
        doc["baseline"] = baseline_document(c, baseline)
    if sweep_mean is not None:
        doc["sweep_mean"] = sweep_mean
    folder.mkdir(parents=True, exist_ok=True)
    _figures(c, folder)
    doc["figures"] = dict(FIGURES)
    atomic_write_bytes(folder / "comparison.json", (json.dumps(doc, indent=2, allow_nan=False) + "\n").encode("utf-8"))
    atomic_write_bytes(folder / "index.html", _html(c, doc).encode("utf-8"))
    return {"index": folder / "index.html", "json": folder / "comparison.json",
            **{k: folder / v for k, v in FIGURES.items()}}

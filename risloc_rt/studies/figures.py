"""Figures of a study in the paper's style (Figs 6–8): MAE of distance, angle and position against
the varied parameter, log scale, the Cramér–Rao bound dashed (matplotlib imported when drawing)."""

from __future__ import annotations

import io
import math
from pathlib import Path
from typing import Any

from .._files import atomic_write_bytes
from .params import PARAMETERS, ris_size

__all__ = ["plot_summary", "x_value"]

_PANELS = (("distance", "distance MAE [m]", 1.0), ("angle", "angle MAE [deg]", 180 / math.pi),
           ("position", "position MAE [m]", 1.0))


def x_value(name: str, value: Any) -> float | None:
    """A numeric x for ``value`` of parameter ``name`` (RIS size: its number of elements)."""
    if name == "ris_size":
        r, c = ris_size(value)
        return float(r * c)
    if PARAMETERS[name].kind in ("float", "int"):
        return float(value)
    return None


def _label(name: str) -> str:
    if name == "ris_size":
        return "RIS elements N_RIS (rows × columns)"
    unit = PARAMETERS[name].unit
    return f"{name} [{unit}]" if unit else name


def plot_summary(summary: dict[str, Any], path: str | Path, *, title: str | None = None) -> Path:
    """Three panels (distance, angle, position): MAE with 95 % intervals and CRB (dashed) vs the x parameter.

    Other varied parameters give one line each. Returns the PNG's path (written atomically).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    xname = summary["x"]
    others = [n for n in summary["study"]["vary"] if n != xname]
    groups: dict[str, list[dict[str, Any]]] = {}
    for pt in summary["points"]:
        label = ", ".join(f"{n}={pt['params'][n]}" for n in others)
        groups.setdefault(label, []).append(pt)
    categorical = xname is None or x_value(xname, summary["points"][0]["params"][xname]) is None
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8), constrained_layout=True)
    for ax, (q, ylabel, scale) in zip(axes, _PANELS):
        for i, (label, pts) in enumerate(groups.items()):
            if categorical:
                xs = list(range(len(pts)))
            else:
                xs = [x_value(xname, p["params"][xname]) for p in pts]
            order = sorted(range(len(pts)), key=lambda j: xs[j])
            xs = [xs[j] for j in order]
            pts = [pts[j] for j in order]
            mae = [p["mae"][q] * scale for p in pts]
            lo = [max(m - p["mae_ci95"][q][0] * scale, 0) if math.isfinite(p["mae_ci95"][q][0]) else 0 for m, p in zip(mae, pts)]
            hi = [max(p["mae_ci95"][q][1] * scale - m, 0) if math.isfinite(p["mae_ci95"][q][1]) else 0 for m, p in zip(mae, pts)]
            color = f"C{i}"
            ax.errorbar(xs, mae, yerr=[lo, hi], marker="o", color=color, capsize=3, label=f"{label}: MAE" if label else "MAE (95 % CI)")
            crb = [p["crb"][q] * scale for p in pts]
            ax.plot(xs, crb, "--", color=color, alpha=0.8, label=f"{label}: CRB" if label else "CRB (1σ)")
        ax.set_yscale("log")
        ax.set_xlabel(_label(xname) if xname else "point")
        if categorical and groups:
            first = next(iter(groups.values()))
            ax.set_xticks(range(len(first)), [str(p["params"][xname]) for p in first])
        if xname == "ris_size":
            first = next(iter(groups.values()))
            ax.set_xscale("log", base=2)
            ticks = sorted({x_value(xname, p["params"][xname]) for p in first})
            ax.set_xticks(ticks, [str(int(t)) for t in ticks])
        ax.set_ylabel(ylabel)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=7)
    runs = summary["points"][0]["runs"] if summary["points"] else 0
    fig.suptitle(title or f"{summary['study']['name']}: {runs} runs per point, "
                 f"estimator {summary['points'][0]['params']['estimator'] if summary['points'] else '?'}")
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    return atomic_write_bytes(path, buf.getvalue())

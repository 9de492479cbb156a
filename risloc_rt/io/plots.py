"""PNG figures of a localization: delay-Doppler map, P_ave over the sweep, range profile."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from dsp import SPEED_OF_LIGHT, DelayDopplerMap, Localization

from ..model.scenario import Truth
from ..plotting import new_figure, save_figure

__all__ = ["plot_delay_doppler", "plot_sweep", "plot_range_profile", "plot_labelled_profile"]


def _dbm(power_w: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore"):
        return 10 * np.log10(np.maximum(power_w, 1e-300)) + 30


def plot_delay_doppler(
    ddm: DelayDopplerMap, peaks: np.ndarray, path: str | os.PathLike[str], *, title: str = "", dynamic_range_db: float = 60.0
) -> Path:
    """Delay-Doppler map (apparent distance τc/2 vs velocity) with ``peaks`` [P, 2] numbered.

    Left: the whole unambiguous range, velocity cropped to the span that holds the peaks (at
    least ±3 m/s). Right: a zoom of ±1 m and ±1 m/s around the strongest peak.
    """
    vel, dist = ddm.velocity, ddm.distance
    span = max(3.0, 1.5 * float(np.max(np.abs(vel[peaks[:, 0]]))) if len(peaks) else 3.0)
    top = float(_dbm(ddm.power.max()))
    fig, axes = new_figure(nrows=1, ncols=2, figsize=(11, 4.5), dpi=110, gridspec_kw={"width_ratios": [3, 2]})
    r0, c0 = peaks[0] if len(peaks) else np.unravel_index(int(ddm.power.argmax()), ddm.power.shape)
    views = [(np.abs(vel) <= span, np.ones(dist.size, bool)),
             (np.abs(vel - vel[r0]) <= 1.0, np.abs(dist - dist[c0]) <= 1.0)]
    for ax, (rows, cols) in zip(axes, views):
        r, c = np.flatnonzero(rows), np.flatnonzero(cols)
        mesh = ax.imshow(_dbm(ddm.power[np.ix_(r, c)]), origin="lower", aspect="auto", cmap="viridis",
                         vmin=top - dynamic_range_db, vmax=top, interpolation="nearest",
                         extent=[dist[c[0]], dist[c[-1]], vel[r[0]], vel[r[-1]]])
        for i, (pr, pc) in enumerate(peaks, start=1):
            if rows[pr] and cols[pc]:
                ax.plot(dist[pc], vel[pr], "o", mfc="none", mec="red", ms=10, mew=1.5)
                ax.annotate(str(i), (dist[pc], vel[pr]), xytext=(6, 6), textcoords="offset points", color="red")
        ax.set_xlabel("apparent distance τc/2 [m]")
        ax.set_ylabel("radial velocity [m/s]")
    fig.colorbar(mesh, ax=axes, label="|z|² [dBm]")
    legend = "\n".join(f"{i}: {dist[pc]:.3f} m, {vel[pr]:+.2f} m/s, {float(_dbm(ddm.power[pr, pc])):.1f} dBm"
                        for i, (pr, pc) in enumerate(peaks, start=1))
    axes[1].text(0.02, 0.02, legend, transform=axes[1].transAxes, fontsize=8, color="white", va="bottom",
                 bbox={"facecolor": "black", "alpha": 0.5})
    axes[0].set_title("whole map")
    axes[1].set_title("zoom on peak 1")
    fig.suptitle(title or "delay-Doppler map of the chosen beam")
    return save_figure(fig, path, tight=False)


def plot_sweep(loc: Localization, path: str | os.PathLike[str], *, truth: Truth | None = None, title: str = "") -> Path:
    """P_ave,m over the sweep's azimuth, estimate circled, true AoD marked."""
    scan = loc.scan
    az = np.rad2deg(scan.angles[:, 0])
    pave = _dbm(scan.average_power)
    fig, ax = new_figure(nrows=1, figsize=(8, 4), dpi=110)
    ax.plot(az, pave, ".-", color="C0", label="P_ave,m")
    if truth is not None:
        ax.axvline(np.rad2deg(truth.aod[0]), color="red", lw=6, alpha=0.3, label=f"true AoD {np.rad2deg(truth.aod[0]):+.2f}°")
    ax.plot(az[loc.beam_index], pave[loc.beam_index], "o", mfc="none", mec="red", ms=12, mew=2,
            label=f"estimate {az[loc.beam_index]:+.2f}°")
    ax.set_xlabel("RIS beam azimuth φ_m [deg]")
    ax.set_ylabel("P_ave [dBm]")
    ax.set_title(title or "average power over the RIS sweep")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return save_figure(fig, path)


def plot_range_profile(
    ddm: DelayDopplerMap,
    loc: Localization,
    path: str | os.PathLike[str],
    *,
    loopback_delay: float,
    truth: Truth | None = None,
    title: str = "",
) -> Path:
    """|z(τ, ν≈ν̂)|² of the chosen beam over apparent distance τc/2, with the expected peaks marked.

    Without a detection (NaN estimates) the profile is taken at the strongest beam's grid peak and
    no estimate is marked.
    """
    detected = bool(np.isfinite(loc.distance))
    nu = loc.delay_rate if detected else float(loc.scan.delay_rate[loc.beam_index])
    profile = _dbm(ddm.profile(nu))
    fig, ax = new_figure(nrows=1, figsize=(8, 4), dpi=110)
    ax.plot(ddm.distance, profile, color="C0", lw=1, label=f"profile at ν ≈ {nu * SPEED_OF_LIGHT / 2:+.2f} m/s (c/2·ν)")
    offset = loopback_delay * SPEED_OF_LIGHT / 2
    if truth is not None:
        ax.axvline(truth.distance, color="gray", ls="--", lw=1, label=f"structural reflection, d = {truth.distance:.3f} m")
        ax.axvline(truth.distance + offset, color="red", ls="--", lw=1,
                   label=f"re-transmission, d + τ_RB c/2 = {truth.distance + offset:.3f} m")
    if detected:
        est = loc.distance + offset
        ax.plot(est, profile[int(np.argmin(np.abs(ddm.distance - est)))], "o", mfc="none", mec="red", ms=10, mew=1.5,
                label=f"estimate d̂ = {loc.distance:.3f} m")
    else:
        est = float(ddm.distance[int(np.argmax(profile))])
        ax.plot([], [], " ", label="nothing detected: no estimate")
    ax.set_xlabel("apparent distance τc/2 [m]")
    ax.set_ylabel("|z|² [dBm]")
    ax.set_ylim(profile.max() - 80, profile.max() + 5)
    ax.set_title(title or "range profile of the chosen beam")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="lower left")
    zoom = ax.inset_axes([0.70, 0.55, 0.28, 0.40])
    near = np.abs(ddm.distance - est) <= 0.6
    zoom.plot(ddm.distance[near], profile[near], color="C0", lw=1)
    for x, color in ([(truth.distance, "gray"), (truth.distance + offset, "red")] if truth is not None else []):
        zoom.axvline(x, color=color, ls="--", lw=1)
    zoom.tick_params(labelsize=7)
    zoom.set_title("±0.6 m", fontsize=7)
    return save_figure(fig, path)


def plot_labelled_profile(profile, path: str | os.PathLike[str], *, title: str = "") -> Path:
    """A :class:`risloc_rt.hall.path_table.LabelledProfile`: range profile with each peak named by its path."""
    db = _dbm(profile.power)
    fig, ax = new_figure(nrows=1, figsize=(10, 5), dpi=110)
    ax.plot(profile.distance, db, color="C0", lw=1)
    for rank, p in enumerate(profile.peaks):
        ax.plot(profile.distance[p], db[p], "v", color="red", ms=6)
        text = profile.labels[rank]
        if len(text) > 70:
            text = text[:67] + "..."
        ax.annotate(f"{profile.distance[p]:.2f} m: {text}", (profile.distance[p], db[p]),
                    xytext=(5, -10 - 11 * rank), textcoords="offset points", fontsize=7, color="darkred",
                    arrowprops={"arrowstyle": "-", "color": "gray", "lw": 0.5})
    ax.set_xlabel("apparent distance τc/2 [m]")
    ax.set_ylabel("|z|² [dBm] (noiseless)")
    ax.set_ylim(db.max() - 70, db.max() + 5)
    ax.grid(alpha=0.3)
    ax.set_title(title or f"range profile from the traced paths, beam az {np.rad2deg(profile.beam[0]):+.1f}°")
    return save_figure(fig, path)

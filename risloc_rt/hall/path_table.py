"""Inspecting traced path sets: a printable table, a file, and a labelled range profile."""

from __future__ import annotations

import json
import os
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.signal

from dsp import SPEED_OF_LIGHT, BeamSweep, ProcessingConfig, RadarConfig, delay_profile

from .._files import atomic_open
from ..model.beat import beat_cube
from ..model.paths import PathSet
from .pruning import PruneReport
from ..model.ris import RisConfig

__all__ = ["apparent_distance", "format_path_table", "save_path_set", "load_path_set", "LabelledProfile",
           "labelled_range_profile"]


def apparent_distance(paths: PathSet, radar: RadarConfig) -> np.ndarray:
    """Where each path appears on the range axis: ``((τ + f_c ν/S) mod 1/(S T_s))·c/2`` [L] [m]."""
    tau = (paths.delay + radar.carrier_frequency * paths.delay_rate / radar.slope) % radar.max_delay
    return tau * SPEED_OF_LIGHT / 2


def _dbm(power: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore"):
        return 10 * np.log10(np.maximum(power, 1e-300)) + 30


def format_path_table(candidates: PathSet, report: PruneReport, radar: RadarConfig, *, show_pruned: bool = False,
                      limit: int | None = None) -> str:
    """A table of paths sorted by delay: delay [ns], true and apparent distance τc/2 [m], power at the
    best beam after the IF filter [dBm], whether kept, and what produced it.

    Parameters
    ----------
    candidates : PathSet
        All paths before pruning (``HallPaths.candidates``).
    report : PruneReport
        Its pruning report (peak powers, keep mask).
    radar : RadarConfig
    show_pruned : bool
        List pruned paths too (by default only the kept ones are listed, pruned ones counted).
    limit : int, optional
        At most this many rows, strongest first, then sorted by delay.
    """
    idx = np.arange(len(candidates)) if show_pruned else np.flatnonzero(report.keep)
    if limit is not None and len(idx) > limit:
        idx = idx[np.argsort(report.peak_power[idx])[::-1][:limit]]
    idx = idx[np.argsort(candidates.delay[idx], kind="stable")]
    app = apparent_distance(candidates, radar)
    lines = [f"{'#':>5} {'delay [ns]':>10} {'τc/2 [m]':>9} {'shown at [m]':>12} {'power [dBm]':>11} {'kept':>5}  path"]
    for i in idx:
        true_d = candidates.delay[i] * SPEED_OF_LIGHT / 2
        alias = " (aliased)" if abs(app[i] - true_d) > 1e-6 and true_d >= radar.max_range else ""
        lines.append(f"{i:>5} {candidates.delay[i] * 1e9:>10.3f} {true_d:>9.3f} {app[i]:>12.3f} "
                     f"{float(_dbm(report.peak_power[i])):>11.1f} {'yes' if report.keep[i] else 'no':>5}  "
                     f"{candidates.labels[i]}{alias}")
    lines.append(f"{report.summary()}; noise floor {float(_dbm(report.noise_floor)):.1f} dBm per delay-Doppler cell")
    return "\n".join(lines)


def save_path_set(path: str | os.PathLike[str], candidates: PathSet, report: PruneReport, *,
                  metadata: dict | None = None) -> Path:
    """Write every candidate path, the keep mask and the report to an ``.npz`` file.

    Arrays: ``gain`` [L] complex [√W], ``delay`` [L] [s], ``delay_rate`` [L] [s/s],
    ``ris_incidence``/``ris_departure`` [L, 2] [rad], ``peak_power`` [L] [W], ``kept`` [L] bool,
    ``labels`` and ``metadata`` as JSON strings.
    """
    out = Path(path)
    if out.suffix != ".npz":
        out = out.with_name(out.name + ".npz")
    with atomic_open(out) as fh:
        np.savez(fh, gain=candidates.gain, delay=candidates.delay, delay_rate=candidates.delay_rate,
                 ris_incidence=candidates.ris_incidence, ris_departure=candidates.ris_departure,
                 peak_power=report.peak_power, kept=report.keep,
                 labels=np.array(json.dumps(list(candidates.labels))),
                 metadata=np.array(json.dumps({"format": "risloc-paths", "version": 1,
                                               "noise_floor": report.noise_floor, **(metadata or {})})))
    return out


def load_path_set(path: str | os.PathLike[str]) -> tuple[PathSet, np.ndarray, dict]:
    """Read :func:`save_path_set`'s file: (all paths, kept mask [L], metadata).

    Raises
    ------
    FileNotFoundError
        No such file.
    ValueError
        Not a path file, or damaged (flipped bytes, truncated): one line naming the file.
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"path file {str(p)!r} does not exist")
    names = ("gain", "delay", "delay_rate", "ris_incidence", "ris_departure", "kept", "labels", "metadata")
    try:
        with np.load(p, allow_pickle=False) as f:
            missing = [k for k in names if k not in f.files]
            if missing:
                raise ValueError(f"{p}: not a risloc path file, missing {missing}")
            labels = json.loads(str(f["labels"]))
            metadata = json.loads(str(f["metadata"]))
            if not isinstance(labels, list) or not isinstance(metadata, dict) or metadata.get("format") != "risloc-paths":
                raise ValueError(f"{p}: not a risloc path file (labels or metadata malformed)")
            paths = PathSet(gain=f["gain"], delay=f["delay"], delay_rate=f["delay_rate"],
                            ris_incidence=f["ris_incidence"], ris_departure=f["ris_departure"],
                            labels=tuple(str(x) for x in labels))
            kept = f["kept"]
            if kept.dtype != bool or kept.shape != (len(paths.labels),):
                raise ValueError(f"{p}: 'kept' must be a bool array [{len(paths.labels)}], got {kept.dtype} "
                                 f"{list(kept.shape)}")
            return paths, kept, metadata
    except ValueError as exc:
        if str(exc).startswith(str(p)):
            raise
        raise ValueError(f"{p}: damaged or not a path file ({' '.join(str(exc).split())[:200]})") from None
    except (OSError, EOFError, KeyError, TypeError, zipfile.BadZipFile, zlib.error, RecursionError, NotImplementedError,
            RuntimeError, UnicodeDecodeError, SyntaxError, OverflowError) as exc:
        raise ValueError(f"{p}: damaged or not a path file ({type(exc).__name__}: "
                         f"{' '.join(str(exc).split())[:200]}); write it again") from None


@dataclass(frozen=True)
class LabelledProfile:
    """Noiseless range profile of one beam built from a path set, with its peaks explained.

    Attributes
    ----------
    distance : float array [N_DFT]
        Apparent distance τc/2 [m].
    power : float array [N_DFT]
        |z(τ, ν=0)|² [W].
    peaks : int array [P]
        Indices of the labelled peaks, strongest first.
    labels : tuple of str
        For each peak, the strongest path within one range resolution cell of it.
    beam : float array [2]
        The beam's ``[az, el]`` [rad].
    """

    distance: np.ndarray
    power: np.ndarray
    peaks: np.ndarray
    labels: tuple[str, ...]
    beam: np.ndarray


def labelled_range_profile(paths: PathSet, *, radar: RadarConfig, processing: ProcessingConfig, ris: RisConfig,
                           beam: np.ndarray, max_peaks: int = 8, dynamic_range_db: float = 50.0) -> LabelledProfile:
    """The range profile at ν ≈ 0 of the RIS beam ``beam`` ([az, el] [rad]), peaks labelled by path."""
    sweep = BeamSweep(np.asarray(beam, float)[None, :])
    frame = beat_cube(paths, radar=radar, sweep=sweep, ris=ris)[0]
    ddm = delay_profile(frame, radar, processing)  # the map's zero-Doppler row
    profile = ddm.power
    db = 10 * np.log10(np.maximum(profile, profile.max() * 1e-30))
    found, props = scipy.signal.find_peaks(db, prominence=3.0, height=db.max() - dynamic_range_db)
    found = found[np.argsort(props["peak_heights"])[::-1][:max_peaks]]
    app = apparent_distance(paths, radar)
    response = np.ones(len(paths))
    if paths.via_ris.any():
        from ..model.ris import ris_response

        response[paths.via_ris] = np.abs(ris_response(ris, sweep, paths.ris_incidence[paths.via_ris],
                                                      paths.ris_departure[paths.via_ris], wavelength=radar.wavelength)[0]) ** 2
    contribution = paths.power * response
    labels = []
    for p in found:
        near = np.flatnonzero(np.abs(app - ddm.distance[p]) <= radar.range_resolution)
        labels.append(paths.labels[near[np.argmax(contribution[near])]] if near.size else "?")
    return LabelledProfile(distance=ddm.distance, power=profile, peaks=found, labels=tuple(labels),
                           beam=np.asarray(beam, float))

"""What the ``risloc`` verbs share: argument types, flags, the error type and the traced-hall helpers.

Degrees in flags, SI units and radians inside.
"""

from __future__ import annotations

import argparse
import warnings
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from dsp import ProcessingConfig

__all__ = ["CliError", "vector", "angle_pair", "processing_overrides", "trace_cache", "trace_settings", "quiet_hall_paths",
           "plot_traced_profile", "add_trace_flags", "add_processing_flags", "add_estimator_flags",
           "estimator_options", "add_force_flag", "npz_target", "EXIT_NO_DETECTION", "add_device_flag",
           "device_backend"]


class CliError(Exception):
    """A user error: printed as one line, exit status 2."""


def vector(text: str, name: str) -> np.ndarray:
    """Three comma-separated finite numbers ``X,Y,Z``.

    Parameters
    ----------
    text : str
        The flag's value, e.g. ``1.0,2.5,1.2`` [m or m/s].
    name : str
        The flag, named in the error.

    Returns
    -------
    ndarray, shape (3,)
        The numbers, in the flag's unit.

    Raises
    ------
    CliError
        Not three finite numbers.
    """
    try:
        values = [float(x) for x in text.split(",")]
    except ValueError:
        raise CliError(f"{name} {text!r} must be three comma-separated numbers, e.g. 1.0,2.5,1.2") from None
    if len(values) != 3 or not np.all(np.isfinite(values)):
        raise CliError(f"{name} {text!r} must be three finite comma-separated numbers, e.g. 1.0,2.5,1.2")
    return np.array(values)


def angle_pair(text: str, name: str) -> np.ndarray:
    """Two comma-separated finite angles ``AZ,EL`` in degrees -> radians.

    Parameters
    ----------
    text : str
        The flag's value, e.g. ``7.3,0`` [deg].
    name : str
        The flag, named in the error.

    Returns
    -------
    ndarray, shape (2,)
        Azimuth and elevation [rad].

    Raises
    ------
    CliError
        Not two finite numbers.
    """
    try:
        values = [float(x) for x in text.split(",")]
    except ValueError:
        raise CliError(f"{name} {text!r} must be two comma-separated angles in degrees, e.g. 7.3,0") from None
    if len(values) != 2 or not np.all(np.isfinite(values)):
        raise CliError(f"{name} {text!r} must be two finite comma-separated angles in degrees, e.g. 7.3,0")
    return np.deg2rad(values)


def processing_overrides(args: argparse.Namespace, base: ProcessingConfig) -> ProcessingConfig:
    """``base`` with ``--doppler-search`` and ``--min-range`` applied.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed flags (:func:`add_processing_flags`).
    base : dsp.ProcessingConfig
        The capture's or scenario's processing.

    Returns
    -------
    dsp.ProcessingConfig
        ``base`` itself when neither flag is given.
    """
    changes: dict[str, Any] = {}
    if getattr(args, "doppler_search", None):
        changes["doppler_search"] = args.doppler_search
    if getattr(args, "min_range", None) is not None:
        changes["min_range"] = args.min_range
    return replace(base, **changes) if changes else base


def trace_cache(args: argparse.Namespace) -> Any:
    """The user's trace cache, or ``None`` with ``--no-cache``.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed flags (:func:`add_trace_flags`).

    Returns
    -------
    risloc_rt.hall.raytrace.cache.TraceCache or None
    """
    if args.no_cache:
        return None
    from ..hall.raytrace.cache import TraceCache, default_cache_dir

    return TraceCache(default_cache_dir())


def trace_settings(args: argparse.Namespace) -> Any:
    """:class:`TraceSettings` with ``--depth``, ``--samples`` and the mechanism flags applied.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed flags (:func:`add_trace_flags`).

    Returns
    -------
    risloc_rt.hall.raytrace.tracer.TraceSettings

    Raises
    ------
    CliError
        ``--diffuse`` outside [0, 1].
    """
    from ..hall.raytrace.tracer import TraceSettings

    changes = {}
    if args.depth is not None:
        changes["max_depth"] = args.depth
    if args.samples is not None:
        changes["samples_per_src"] = args.samples
    if getattr(args, "diffuse", None) is not None:
        if not 0.0 <= args.diffuse <= 1.0:
            raise CliError(f"--diffuse {args.diffuse:g} must be a scattering coefficient in [0, 1] (e.g. 0.3 for rough concrete)")
        changes.update(diffuse_reflection=True, scattering_coefficient=args.diffuse)
    for flag in ("diffraction", "refraction"):
        if getattr(args, flag, False):
            changes[flag] = True
    return TraceSettings(**changes)


def quiet_hall_paths(hs: Any, cache: Any) -> Any:
    """hall_paths with its AliasWarnings collected in the report only (the CLI prints them once).

    Parameters
    ----------
    hs : risloc_rt.hall.HallScenario
        The hall and radar position.
    cache : TraceCache or None
        The trace cache (:func:`trace_cache`).

    Returns
    -------
    risloc_rt.hall.HallPaths
    """
    from ..hall.pruning import AliasWarning
    from ..hall.scenario import hall_paths

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AliasWarning)
        return hall_paths(hs, cache=cache)


def plot_traced_profile(hs: Any, traced: Any, path: Path) -> None:
    """The labelled range profile of ``traced`` at the beam nearest the true AoD, as a PNG.

    Parameters
    ----------
    hs : risloc_rt.hall.HallScenario
        The hall and radar position (radar, sweep, RIS, true AoD [rad]).
    traced : risloc_rt.hall.HallPaths
        Its traced paths.
    path : Path
        The PNG to write (atomically).
    """
    from ..hall.path_table import labelled_range_profile
    from ..io import plots as plotting

    beam = hs.base.sweep.angles[int(np.argmin(np.linalg.norm(hs.base.sweep.angles - hs.base.truth.aod, axis=1)))]
    profile = labelled_range_profile(traced.paths, radar=hs.base.radar, processing=hs.base.processing,
                                     ris=hs.base.ris, beam=beam)
    plotting.plot_labelled_profile(profile, path, title=f"{hs.name}: range profile from the traced paths, "
                                                         f"beam {np.rad2deg(beam[0]):+.1f}° (noiseless)")


def add_trace_flags(p: argparse.ArgumentParser) -> None:
    """Add ``--depth``, ``--samples``, ``--diffuse``, ``--diffraction``, ``--refraction``, ``--no-cache``.

    Parameters
    ----------
    p : argparse.ArgumentParser
        A verb's parser.
    """
    p.add_argument("--depth", type=int, help="ray-tracing depth (default 3)")
    p.add_argument("--samples", type=int, help="rays per source (default 100000)")
    p.add_argument("--diffuse", type=float, metavar="S",
                   help="trace diffuse reflection with scattering coefficient S in [0, 1] on every material "
                        "(Lambertian; rough concrete at 60 GHz: 0.2-0.4; the 256 strongest radar-RIS legs are kept)")
    p.add_argument("--diffraction", action="store_true", help="trace first-order edge diffraction (sionna-rt)")
    p.add_argument("--refraction", action="store_true", help="trace refraction through walls and objects (sionna-rt)")
    p.add_argument("--no-cache", action="store_true", help="always re-trace (default: reuse cached traces)")


def npz_target(text: str) -> Path:
    """The file a capture named ``text`` is written to: ``text`` itself, ``.npz`` appended when missing.

    Parameters
    ----------
    text : str
        The ``-o`` value.

    Returns
    -------
    Path
        What :func:`risloc_rt.io.capture_file.save_capture` will write.
    """
    out = Path(text)
    return out if out.suffix == ".npz" else out.with_name(out.name + ".npz")


def add_force_flag(p: argparse.ArgumentParser, what: str = "an existing output") -> None:
    """Add ``--force``: replace ``what`` although risloc-rt did not write it (``risloc_rt._outputs``).

    Parameters
    ----------
    p : argparse.ArgumentParser
        A verb's parser.
    what : str
        The outputs it concerns, for the help text.
    """
    p.add_argument("--force", action="store_true",
                   help=f"replace {what} that risloc-rt did not write, or that was changed since (never a folder)")


#: Exit status of ``locate`` and ``demo`` when a capture holds no detectable RIS return (no position).
EXIT_NO_DETECTION = 3


def add_estimator_flags(p: argparse.ArgumentParser) -> None:
    """Add ``--estimator``, ``--ue-height`` [m], ``--pfa``, ``--floor-height`` [m].

    Parameters
    ----------
    p : argparse.ArgumentParser
        A verb's parser.
    """
    p.add_argument("--estimator", choices=["refined", "paper"], default="refined",
                   help="'refined' (default): off-grid delay/Doppler from all beams, AoD from a fit of the RIS beam "
                        "pattern; 'paper': the seed paper's grid method")
    p.add_argument("--ue-height", type=float, metavar="Z",
                   help="known radar height z [m]: resolves the elevation a 1-D (azimuth) sweep cannot see")
    p.add_argument("--pfa", type=float, metavar="P",
                   help="detector false-alarm probability per capture (default 1e-3)")
    p.add_argument("--floor-height", default="auto", metavar="{auto,none,Z}",
                   help="world z [m] of the floor under the radar and the RIS: the DSP reads the floor's ladder of "
                        "the RIS return and takes the first arrival, not the stronger return via the floor "
                        "(docs/estimation.md); 'auto' (default): 0 for a ray-traced hall's capture, none otherwise; "
                        "'none': no floor")


def estimator_options(args: argparse.Namespace, *, traced: bool = False) -> dict[str, Any]:
    """The keyword options of :func:`risloc_rt.io.report.process_capture` from the flags.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed flags (:func:`add_estimator_flags`).
    traced : bool, default False
        Whether the capture is a ray-traced hall's (``--floor-height auto`` is then the hall's floor,
        ``risloc_rt.hall.scenario.FLOOR_HEIGHT``).

    Returns
    -------
    dict
        ``estimator``, ``ue_height`` [m] (or None), ``pfa`` (or None) and ``floor_height`` [m] (or None).

    Raises
    ------
    CliError
        ``--floor-height`` neither ``auto``, ``none`` nor a finite number (one line).
    """
    text = str(getattr(args, "floor_height", "auto")).strip().lower()
    if text == "auto":
        floor = None
        if traced:
            from ..hall.scenario import FLOOR_HEIGHT

            floor = FLOOR_HEIGHT
    elif text == "none":
        floor = None
    else:
        try:
            floor = float(text)
        except ValueError:
            floor = float("nan")
        if not np.isfinite(floor):
            raise CliError(f"--floor-height {args.floor_height!r} must be 'auto', 'none' or the floor's world z in "
                           "metres, e.g. 0")
    return {"estimator": args.estimator, "ue_height": args.ue_height, "pfa": args.pfa, "floor_height": floor}


def add_processing_flags(p: argparse.ArgumentParser) -> None:
    """Add ``--doppler-search``, ``--min-range`` [m].

    Parameters
    ----------
    p : argparse.ArgumentParser
        A verb's parser.
    """
    p.add_argument("--doppler-search", choices=["zoom", "full"],
                   help="peak search over Doppler: 'zoom' (default, exact on the grid, fast) or 'full' (the paper's full 2-D DFT)")
    p.add_argument("--min-range", type=float, metavar="M",
                   help="ignore peaks closer than M metres (e.g. Tx-Rx leakage in measured data)")


def add_device_flag(p: argparse.ArgumentParser) -> None:
    """Add ``--device {cpu,cuda,auto}``: where the DSP's whole-cube work runs (``dsp.xp``).

    No ``choices``: the value is checked by :func:`dsp.xp.device_choice` (as ``$RISLOC_DEVICE`` is), so
    a wrong name from the flag or the environment gets the same one-line error.

    Parameters
    ----------
    p : argparse.ArgumentParser
        A verb's parser.
    """
    p.add_argument("--device", metavar="{cpu,cuda,auto}",
                   help="where the DSP's whole-cube work (receiver noise, detector, the estimators' reads of the "
                        "cube) runs: cpu (NumPy), cuda (CuPy on an NVIDIA GPU; pip install '.[gpu]') or auto (the "
                        "GPU when CuPy finds one, else cpu); default $RISLOC_DEVICE, else cpu")


def device_backend(args: argparse.Namespace) -> Any:
    """The array backend of ``--device`` (else ``$RISLOC_DEVICE``, else ``cpu``): :func:`dsp.backend_for`.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed flags (:func:`add_device_flag`).

    Returns
    -------
    dsp.ArrayBackend

    Raises
    ------
    dsp.DeviceError
        An unknown device name (flag or ``$RISLOC_DEVICE``), or ``cuda`` without CuPy or a GPU: a
        ``ValueError`` whose one line names the problem and the fix (exit status 2, :func:`risloc_rt.cli.main`).
    """
    from dsp import backend_for

    return backend_for(getattr(args, "device", None))



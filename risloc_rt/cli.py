"""The ``risloc`` command line: demo, simulate, locate.

Degrees in flags, SI units and radians inside.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Sequence

import numpy as np

from dsp import SPEED_OF_LIGHT, ProcessingConfig, delay_doppler_map

from .capture import Capture, CaptureFormatError, load_capture, save_capture
from .raytrace.backend import BackendError
from .report import CaseResult, format_case, process_capture, write_result
from .scenario import PAPER_CASES, Scenario, paper_scenario
from .simulate import simulate

__all__ = ["main"]


class CliError(Exception):
    """A user error: printed as one line, exit status 2."""


def _vector(text: str, name: str) -> np.ndarray:
    try:
        values = [float(x) for x in text.split(",")]
    except ValueError:
        raise CliError(f"{name} {text!r} must be three comma-separated numbers, e.g. 1.0,2.5,1.2") from None
    if len(values) != 3 or not np.all(np.isfinite(values)):
        raise CliError(f"{name} {text!r} must be three finite comma-separated numbers, e.g. 1.0,2.5,1.2")
    return np.array(values)


def _processing_overrides(args: argparse.Namespace, base: ProcessingConfig) -> ProcessingConfig:
    changes = {}
    if getattr(args, "doppler_search", None):
        changes["doppler_search"] = args.doppler_search
    if getattr(args, "min_range", None) is not None:
        changes["min_range"] = args.min_range
    return replace(base, **changes) if changes else base


def _report_case(name: str, capture: Capture, out_dir: Path | None, processing: ProcessingConfig,
                 timing: dict[str, float]) -> CaseResult:
    loc, dsp_time = process_capture(capture, processing=processing)
    timing = {**timing, "dsp": dsp_time}
    plots: dict[str, str] = {}
    if out_dir is not None:
        from . import plots as plotting

        start = time.perf_counter()
        frame = capture.cube[loc.beam_index]
        ddm = delay_doppler_map(frame, capture.radar, processing)
        peaks = ddm.peaks(3, min_delay=2 * processing.min_range / SPEED_OF_LIGHT)
        az = np.rad2deg(loc.aod[0])
        files = {
            "delay_doppler": plotting.plot_delay_doppler(
                ddm, peaks, out_dir / name / "delay_doppler.png",
                title=f"{name}: delay-Doppler map, beam {loc.beam_index} (φ = {az:+.1f}°), 3 largest peaks"),
            "sweep": plotting.plot_sweep(loc, out_dir / name / "aod_sweep.png", truth=capture.truth,
                                         title=f"{name}: P_ave over the RIS sweep"),
            "range_profile": plotting.plot_range_profile(
                ddm, loc, out_dir / name / "range_profile.png", loopback_delay=capture.ris.loopback_delay,
                truth=capture.truth, title=f"{name}: range profile at ν ≈ ν̂, beam {loc.beam_index}"),
        }
        plots = {k: str(v.relative_to(out_dir)) for k, v in files.items()}
        timing["plots"] = time.perf_counter() - start
    return CaseResult(name=name, capture=capture, localization=loc, timing=timing, plots=plots)


def _cmd_demo(args: argparse.Namespace) -> int:
    if args.analytic:
        return _demo_analytic(args)
    return _demo_hall(args)


def _trace_cache(args: argparse.Namespace):
    if args.no_cache:
        return None
    from .raytrace.cache import TraceCache, default_cache_dir

    return TraceCache(default_cache_dir())


def _trace_settings(args: argparse.Namespace):
    from .raytrace.tracer import TraceSettings

    changes = {}
    if args.depth is not None:
        changes["max_depth"] = args.depth
    if args.samples is not None:
        changes["samples_per_src"] = args.samples
    return TraceSettings(**changes)


def _demo_hall(args: argparse.Namespace) -> int:
    from .authoring.spec import load_spec
    from .hall import hall_scenario, scene_directory

    out = Path(args.out)
    folder = scene_directory(args.scene)
    count = len(load_spec(folder / "spec.toml").radar_positions())
    cache = _trace_cache(args)
    settings = _trace_settings(args)
    print(f"risloc demo: ray-traced hall {folder.name!r} ({count} radar position(s)), RIS mode {args.mode}, "
          f"seed {args.seed}, trace depth {settings.max_depth}, {settings.samples_per_src:g} samples per source")
    cases = []
    for index, ss in enumerate(np.random.SeedSequence(args.seed).spawn(count)):
        hs = hall_scenario(folder, radar_index=index, mode=args.mode, trace=settings)
        processing = _processing_overrides(args, hs.base.processing)
        traced = _quiet_hall_paths(hs, cache)
        start = time.perf_counter()
        capture = simulate(hs.base, rng=np.random.default_rng(ss), paths=traced.paths, seed=args.seed)
        timing = {"trace" + (" (cached)" if traced.trace.cache_hit else ""): traced.timing["trace"],
                  "paths": traced.timing["paths"], "synthesis": time.perf_counter() - start}
        result = _report_case(hs.name.replace("#", "-"), capture, out, processing, timing)
        _plot_traced_profile(hs, traced, out / result.name / "traced_profile.png")
        result = replace(result, plots={**result.plots, "traced_profile": f"{result.name}/traced_profile.png"})
        print(format_case(result))
        print(f"  paths: {traced.counts['hall']} hall echoes, {traced.counts['ris_loopback']} RIS loop-back and "
              f"{traced.counts['ris_structure']} panel leg pairs; {traced.report.summary()}")
        for w in traced.report.warnings:
            print(f"  warning: {w}")
        cases.append(result)
    path = write_result(out, cases)
    print(f"wrote {path} and plots under {out}/")
    return 0


def _quiet_hall_paths(hs, cache):
    """hall_paths with its AliasWarnings collected in the report only (the CLI prints them once)."""
    import warnings

    from .hall import hall_paths
    from .pruning import AliasWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AliasWarning)
        return hall_paths(hs, cache=cache)


def _plot_traced_profile(hs, traced, path: Path) -> None:
    from . import plots as plotting
    from .path_table import labelled_range_profile

    beam = hs.base.sweep.angles[int(np.argmin(np.linalg.norm(hs.base.sweep.angles - hs.base.truth.aod, axis=1)))]
    profile = labelled_range_profile(traced.paths, radar=hs.base.radar, processing=hs.base.processing,
                                     ris=hs.base.ris, beam=beam)
    plotting.plot_labelled_profile(profile, path, title=f"{hs.name}: range profile from the traced paths, "
                                                         f"beam {np.rad2deg(beam[0]):+.1f}° (noiseless)")


def _demo_analytic(args: argparse.Namespace) -> int:
    out = Path(args.out)
    cases = []
    print(f"risloc demo: the paper scenario (Table I), UE-RIS 13.38 m, RIS mode {args.mode}, seed {args.seed}")
    seeds = np.random.SeedSequence(args.seed).spawn(len(PAPER_CASES))
    for case_name, ss in zip(PAPER_CASES, seeds):
        scenario = paper_scenario(case_name, mode=args.mode)  # type: ignore[arg-type]
        processing = _processing_overrides(args, scenario.processing)
        start = time.perf_counter()
        capture = simulate(scenario, rng=np.random.default_rng(ss), seed=args.seed)
        result = _report_case(scenario.name, capture, out, processing, {"synthesis": time.perf_counter() - start})
        print(format_case(result))
        cases.append(result)
    path = write_result(out, cases)
    print(f"wrote {path} and plots under {out}/")
    return 0


def _scenario_from_args(args: argparse.Namespace) -> Scenario:
    scenario = paper_scenario(args.case, mode=args.mode or "relay")
    radar = scenario.radar
    if args.tx_power_dbm is not None:
        radar = replace(radar, tx_power_dbm=args.tx_power_dbm)
    ue = scenario.ue_position if args.ue is None else _vector(args.ue, "--ue")
    velocity = scenario.ue_velocity if args.ue_velocity is None else _vector(args.ue_velocity, "--ue-velocity")
    return replace(scenario, radar=radar, ris=scenario.ris.with_rx_toward(ue), ue_position=ue,
                   ue_velocity=velocity, processing=_processing_overrides(args, scenario.processing))


def _cmd_simulate(args: argparse.Namespace) -> int:
    if args.scene is None:
        scenario = _scenario_from_args(args)
        paths, extra = None, None
    else:
        from .hall import hall_scenario

        ue = None if args.ue is None else _vector(args.ue, "--ue")
        velocity = None if args.ue_velocity is None else _vector(args.ue_velocity, "--ue-velocity")
        hs = hall_scenario(args.scene, radar_index=args.radar_index, mode=args.mode, trace=_trace_settings(args),
                           ue_position=ue, ue_velocity=velocity)
        if args.tx_power_dbm is not None:
            hs = replace(hs, base=replace(hs.base, radar=replace(hs.base.radar, tx_power_dbm=args.tx_power_dbm)))
        scenario = replace(hs.base, processing=_processing_overrides(args, hs.base.processing))
        traced = _quiet_hall_paths(hs, _trace_cache(args))
        paths = traced.paths
        extra = {"scene": str(hs.scene_xml), "scene_hash": traced.trace.scene_hash,
                 "trace_settings": hs.trace.to_dict(), "model": hs.model.to_dict(),
                 "pruning": traced.report.summary()}
        print(f"traced {hs.scene_xml}: {traced.report.summary()}")
        for w in traced.report.warnings:
            print(f"warning: {w}")
    capture = simulate(scenario, rng=np.random.default_rng(args.seed), noise=not args.no_noise, seed=args.seed,
                       paths=paths, provenance_extra=extra)
    if args.complex64:
        capture = replace(capture, cube=capture.cube.astype(np.complex64))
    path = save_capture(capture, args.output)
    t = capture.truth
    print(f"wrote {path}: {capture.cube.shape[0]} beams x {capture.cube.shape[1]} chirps x "
          f"{capture.cube.shape[2]} samples ({capture.cube.dtype}); truth: distance {t.distance:.4f} m, "
          f"AoD {np.rad2deg(t.aod[0]):+.2f}° az {np.rad2deg(t.aod[1]):+.2f}° el")
    return 0


def _cmd_locate(args: argparse.Namespace) -> int:
    capture = load_capture(args.capture)
    processing = _processing_overrides(args, capture.processing)
    name = Path(args.capture).stem
    out = Path(args.out) if args.out else None
    result = _report_case(name, capture, out, processing, {})
    print(format_case(result))
    if out is not None:
        print(f"wrote {write_result(out, [result])} and plots under {out}/")
    return 0


def _cmd_trace(args: argparse.Namespace) -> int:
    from .hall import hall_scenario
    from .path_table import format_path_table, save_path_set

    ue = _vector(args.ue, "--ue")
    velocity = None if args.ue_velocity is None else _vector(args.ue_velocity, "--ue-velocity")
    hs = hall_scenario(args.scene, mode=args.mode, trace=_trace_settings(args), ue_position=ue, ue_velocity=velocity)
    traced = _quiet_hall_paths(hs, _trace_cache(args))
    t = hs.base.truth
    print(f"{hs.scene_xml}: radar at {ue.tolist()} m, RIS at {hs.base.ris.pose.position.tolist()} m "
          f"(distance {t.distance:.3f} m, AoD {np.rad2deg(t.aod[0]):+.2f}° az {np.rad2deg(t.aod[1]):+.2f}° el); "
          f"{len(traced.trace.monostatic)} monostatic paths and {len(traced.trace.legs[0])} radar->RIS legs traced in "
          f"{traced.timing['trace']:.2f} s{' (cache hit)' if traced.trace.cache_hit else ''}")
    print(format_path_table(traced.candidates, traced.report, hs.base.radar, show_pruned=args.all, limit=args.limit))
    for w in traced.report.warnings:
        print(f"warning: {w}")
    if args.output:
        meta = {"scene": str(hs.scene_xml), "scene_hash": traced.trace.scene_hash, "radar_position": ue.tolist(),
                "ris": hs.base.ris.to_dict(), "trace_settings": hs.trace.to_dict(), "model": hs.model.to_dict()}
        print(f"wrote {save_path_set(args.output, traced.candidates, traced.report, metadata=meta)}")
    if args.plot:
        _plot_traced_profile(hs, traced, Path(args.plot))
        print(f"wrote {args.plot}")
    return 0


def _add_trace_flags(p: argparse.ArgumentParser) -> None:
    p.add_argument("--depth", type=int, help="ray-tracing depth (default 3)")
    p.add_argument("--samples", type=int, help="rays per source (default 100000)")
    p.add_argument("--no-cache", action="store_true", help="always re-trace (default: reuse cached traces)")


def _add_processing_flags(p: argparse.ArgumentParser) -> None:
    p.add_argument("--doppler-search", choices=["zoom", "full"],
                   help="peak search over Doppler: 'zoom' (default, exact on the grid, fast) or 'full' (the paper's full 2-D DFT)")
    p.add_argument("--min-range", type=float, metavar="M",
                   help="ignore peaks closer than M metres (e.g. Tx-Rx leakage in measured data)")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``risloc``."""
    parser = argparse.ArgumentParser(prog="risloc", description="RIS-enabled self-localization of an FMCW radar")
    sub = parser.add_subparsers(dest="command", required=True)

    demo = sub.add_parser("demo", help="localize end to end in the default ray-traced hall (or --analytic: the paper's point-target scenario)")
    demo.add_argument("--out", default="risloc-demo", help="output directory for result.json and plots (default: %(default)s)")
    demo.add_argument("--seed", type=int, default=0, help="noise seed (default: %(default)s)")
    demo.add_argument("--mode", choices=["relay", "reflective"], default="relay", help="RIS mode (default: %(default)s)")
    demo.add_argument("--scene", default="paper_hall", help="scene name in scenes/ or folder (default: %(default)s)")
    demo.add_argument("--analytic", action="store_true", help="the paper's analytic scenario (RIS loop-back + point target) instead of a traced hall")
    _add_trace_flags(demo)
    _add_processing_flags(demo)
    demo.set_defaults(func=_cmd_demo)

    sim = sub.add_parser("simulate", help="simulate a capture file: the paper scenario, or a ray-traced hall with --scene")
    sim.add_argument("-o", "--output", required=True, help="capture file to write (.npz)")
    sim.add_argument("--scene", help="ray trace this hall (name in scenes/ or folder) instead of the analytic paper scenario")
    sim.add_argument("--radar-index", type=int, default=0, help="with --scene: which radar position of the spec (default: %(default)s)")
    sim.add_argument("--case", choices=list(PAPER_CASES), default="broadside", help="analytic paper case (default: %(default)s)")
    sim.add_argument("--mode", choices=["relay", "reflective"], help="RIS mode (default: relay, or the scene's)")
    sim.add_argument("--ue", metavar="X,Y,Z", help="UE position [m] (default: the origin, or the scene's radar position)")
    sim.add_argument("--ue-velocity", metavar="VX,VY,VZ", help="UE velocity [m/s] (default: 0)")
    sim.add_argument("--tx-power-dbm", type=float, help="transmit power [dBm] (default: Table I, 20)")
    sim.add_argument("--seed", type=int, default=0, help="noise seed (default: %(default)s)")
    sim.add_argument("--no-noise", action="store_true", help="write the noiseless cube")
    sim.add_argument("--complex64", action="store_true", help="store the cube as complex64 (half the size)")
    _add_trace_flags(sim)
    _add_processing_flags(sim)
    sim.set_defaults(func=_cmd_simulate)

    trace = sub.add_parser("trace", help="ray trace a hall for one radar position and list the paths")
    trace.add_argument("scene", help="scene name in scenes/ or folder with scene.xml and spec.toml")
    trace.add_argument("--ue", required=True, metavar="X,Y,Z", help="radar position [m]")
    trace.add_argument("--ue-velocity", metavar="VX,VY,VZ", help="radar velocity [m/s] (default: the spec's)")
    trace.add_argument("--mode", choices=["relay", "reflective"], help="override the RIS mode of the spec")
    trace.add_argument("-o", "--output", help="save every path, kept or pruned, to this .npz file")
    trace.add_argument("--plot", metavar="PNG", help="plot the range profile built from the paths, peaks labelled")
    trace.add_argument("--all", action="store_true", help="list pruned paths too")
    trace.add_argument("--limit", type=int, default=60, help="list at most this many paths, strongest first (default: %(default)s)")
    _add_trace_flags(trace)
    trace.set_defaults(func=_cmd_trace)

    from .authoring.cli import add_scene_parser

    add_scene_parser(sub)

    loc = sub.add_parser("locate", help="run the DSP on a capture file")
    loc.add_argument("capture", help="capture file (.npz) from 'risloc simulate' or a converter")
    loc.add_argument("--out", help="directory for result.json and plots (default: print only)")
    _add_processing_flags(loc)
    loc.set_defaults(func=_cmd_locate)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``risloc``; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except (CliError, CaptureFormatError, FileNotFoundError, ValueError, TypeError, BackendError) as exc:
        print(f"risloc {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

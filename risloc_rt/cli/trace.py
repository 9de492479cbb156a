"""``risloc trace``: ray trace a hall for one radar position and list the paths."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from .._outputs import check_output_file, output_file
from .common import (add_force_flag, add_trace_flags, npz_target, plot_traced_profile, quiet_hall_paths, trace_cache,
                     trace_settings, vector)

__all__ = ["add_parser"]


def _run(args: argparse.Namespace) -> int:
    from ..hall.path_table import format_path_table, save_path_set
    from ..hall.scenario import hall_scenario

    ue = vector(args.ue, "--ue")
    output = npz_target(args.output) if args.output else None
    for flag, given in (("-o", output), ("--plot", args.plot)):
        if given:  # refused before the trace, not after it
            check_output_file(given, force=args.force, flag=flag)
    velocity = None if args.ue_velocity is None else vector(args.ue_velocity, "--ue-velocity")
    hs = hall_scenario(args.scene, mode=args.mode, trace=trace_settings(args), ue_position=ue, ue_velocity=velocity)
    traced = quiet_hall_paths(hs, trace_cache(args))
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
        with output_file(output, force=args.force, flag="-o") as target:
            save_path_set(target, traced.candidates, traced.report, metadata=meta)
        print(f"wrote {output}")
    if args.plot:
        with output_file(args.plot, force=args.force, flag="--plot") as target:
            plot_traced_profile(hs, traced, Path(target))
        print(f"wrote {args.plot}")
    return 0


def add_parser(sub) -> None:
    """Add ``trace`` to an ``add_subparsers()`` object.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        What ``ArgumentParser.add_subparsers()`` returned; the verb's parser is added to it, its
        ``func`` set to the verb (which takes the parsed arguments and returns the exit status).
    """
    trace = sub.add_parser("trace", help="ray trace a hall for one radar position and list the paths")
    trace.add_argument("scene", help="scene name in scenes/ or folder with scene.xml and spec.toml")
    trace.add_argument("--ue", required=True, metavar="X,Y,Z", help="radar position [m]")
    trace.add_argument("--ue-velocity", metavar="VX,VY,VZ", help="radar velocity [m/s] (default: the spec's)")
    trace.add_argument("--mode", choices=["relay", "reflective"], help="override the RIS mode of the spec")
    trace.add_argument("-o", "--output", help="save every path, kept or pruned, to this .npz file")
    trace.add_argument("--plot", metavar="PNG", help="plot the range profile built from the paths, peaks labelled")
    add_force_flag(trace, "an existing -o or --plot file")
    trace.add_argument("--all", action="store_true", help="list pruned paths too")
    trace.add_argument("--limit", type=int, default=60, help="list at most this many paths, strongest first (default: %(default)s)")
    add_trace_flags(trace)
    trace.set_defaults(func=_run)

"""``risloc demo``: a ray-traced hall end to end (or, with ``--analytic``, the paper's scenario)."""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from .._outputs import output_folder, safe_name
from ..io.report import format_case, format_environment, report_capture, run_environment, write_result
from ..model.scenario import PAPER_CASES, paper_scenario
from ..model.simulate import simulate
from .common import (EXIT_NO_DETECTION, add_device_flag, add_estimator_flags, add_force_flag, add_processing_flags,
                     add_trace_flags, device_backend, estimator_options, plot_traced_profile, processing_overrides,
                     quiet_hall_paths, trace_cache, trace_settings)

__all__ = ["add_parser"]


def _run(args: argparse.Namespace) -> int:
    out = Path(args.out)
    backend = device_backend(args)  # a missing GPU or a bad --device: one line before anything is written
    with output_folder(out, force=args.force, flag="--out", expect=("result.json",)) as stage:
        status = (_demo_analytic if args.analytic else _demo_hall)(args, stage, backend)
    print(f"wrote {out / 'result.json'} and plots under {out}/")
    return status


def _demo_hall(args: argparse.Namespace, out: Path, backend) -> int:
    from ..authoring.scene_folder import scene_directory
    from ..authoring.spec import load_spec
    from ..hall.scenario import hall_scenario

    folder = scene_directory(args.scene)
    count = len(load_spec(folder / "spec.toml").radar_positions())
    cache = trace_cache(args)
    settings = trace_settings(args)
    print(f"risloc demo: ray-traced hall {folder.name!r} ({count} radar position(s)), RIS mode {args.mode}, "
          f"seed {args.seed}, trace depth {settings.max_depth}, {settings.samples_per_src:g} samples per source")
    cases = []
    for index, ss in enumerate(np.random.SeedSequence(args.seed).spawn(count)):
        hs = hall_scenario(folder, radar_index=index, mode=args.mode, trace=settings)
        processing = processing_overrides(args, hs.base.processing)
        traced = quiet_hall_paths(hs, cache)
        start = time.perf_counter()
        capture = simulate(hs.base, rng=np.random.default_rng(ss), paths=traced.paths, seed=args.seed)
        timing = {"trace" + (" (cached)" if traced.trace.cache_hit else ""): traced.timing["trace"],
                  "paths": traced.timing["paths"], "synthesis": time.perf_counter() - start}
        result = report_capture(safe_name(hs.name.replace("#", "-")), capture, out_dir=out, processing=processing, timing=timing,
                                backend=backend, **estimator_options(args, traced=True))
        plot_traced_profile(hs, traced, out / result.name / "traced_profile.png")
        result = replace(result, plots={**result.plots, "traced_profile": f"{result.name}/traced_profile.png"})
        print(format_case(result))
        print(f"  paths: {traced.counts['hall']} hall echoes, {traced.counts['ris_loopback']} RIS loop-back and "
              f"{traced.counts['ris_structure']} panel leg pairs; {traced.report.summary()}")
        for w in traced.report.warnings:
            print(f"  warning: {w}")
        cases.append(result)
    _finish(out, cases, backend)
    return 0 if all(c.localization.detected for c in cases) else EXIT_NO_DETECTION


def _finish(out: Path, cases: list, backend) -> None:
    """Say what ran where (one line) and write ``result.json`` with it (its ``"device"`` object)."""
    env = run_environment(backend)
    print(format_environment(env))
    write_result(out, cases, device=env)


def _demo_analytic(args: argparse.Namespace, out: Path, backend) -> int:
    cases = []
    print(f"risloc demo: the paper scenario (Table I), UE-RIS 13.38 m, RIS mode {args.mode}, seed {args.seed}")
    seeds = np.random.SeedSequence(args.seed).spawn(len(PAPER_CASES))
    for case_name, ss in zip(PAPER_CASES, seeds):
        scenario = paper_scenario(case_name, mode=args.mode)  # type: ignore[arg-type]
        processing = processing_overrides(args, scenario.processing)
        start = time.perf_counter()
        capture = simulate(scenario, rng=np.random.default_rng(ss), seed=args.seed)
        result = report_capture(safe_name(scenario.name), capture, out_dir=out, processing=processing,
                                timing={"synthesis": time.perf_counter() - start}, backend=backend,
                                **estimator_options(args))
        print(format_case(result))
        cases.append(result)
    _finish(out, cases, backend)
    return 0 if all(c.localization.detected for c in cases) else EXIT_NO_DETECTION


def add_parser(sub) -> None:
    """Add ``demo`` to an ``add_subparsers()`` object.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        What ``ArgumentParser.add_subparsers()`` returned; the verb's parser is added to it, its
        ``func`` set to the verb (which takes the parsed arguments and returns the exit status).
    """
    demo = sub.add_parser("demo", help="localize end to end in the default ray-traced hall (or --analytic: the paper's point-target scenario)")
    demo.add_argument("--out", default="risloc-demo", help="output directory for result.json and plots (default: %(default)s)")
    add_force_flag(demo, "a result.json or plot in --out")
    demo.add_argument("--seed", type=int, default=0, help="noise seed (default: %(default)s)")
    demo.add_argument("--mode", choices=["relay", "reflective"], default="relay", help="RIS mode (default: %(default)s)")
    demo.add_argument("--scene", default="paper_hall", help="scene name in scenes/ or folder (default: %(default)s)")
    demo.add_argument("--analytic", action="store_true", help="the paper's analytic scenario (RIS loop-back + point target) instead of a traced hall")
    add_trace_flags(demo)
    add_processing_flags(demo)
    add_estimator_flags(demo)
    add_device_flag(demo)
    demo.set_defaults(func=_run)

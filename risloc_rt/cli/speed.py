"""``risloc speed``: speed against error of every estimator and trace setting, measured in one run.

A thin verb over :mod:`risloc_rt.studies.speed`: it prints the study's table (times beside the
model error and the position RMSE against the Cramér–Rao bound, ratios against the paper's
full-grid method) and the mechanism verdicts, and writes the rows as JSON (``--json``) and the
trade-off figure (``--plot``). ``--device`` chooses where the refined estimator's whole-cube work runs; the
line ``device: ...`` and the JSON's ``"device"`` object say what ran the DSP and the ray tracer.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from .common import add_device_flag, add_force_flag, device_backend

__all__ = ["add_parser"]


def _run(args: argparse.Namespace) -> int:
    from .._files import atomic_write_bytes
    from .._outputs import check_output_file, output_file
    from ..authoring.scene_folder import SCENES_DIR
    from ..io.report import format_environment, run_environment
    from ..studies.speed import format_table, mechanism_verdicts, plot_tradeoff, run_speed_study
    from .common import CliError

    scenes = args.scene or sorted(p.parent.name for p in SCENES_DIR.glob("*/spec.toml"))
    if args.realizations < 1 or args.positions < 1 or args.full < 0:
        raise CliError("--realizations and --positions must be >= 1 and --full >= 0")
    backend = device_backend(args)  # a missing GPU or a bad --device: one line before the study
    for flag, given in (("--json", args.json), ("--plot", args.plot)):
        if given:  # refused before the study, not after it
            check_output_file(given, force=args.force, flag=flag)
    print(f"risloc speed: scenes {', '.join(scenes)}; {args.realizations} noise realizations per setting and radar "
          f"position (fast noise stream), the paper's full 2-D DFT on {min(args.full, args.realizations)} of them "
          f"at the default trace setting; reference model: depth 4, 10⁶ rays")
    summaries = run_speed_study(scenes, realizations=args.realizations, full=args.full, seed=args.seed,
                                positions=args.positions, backend=backend)
    env = run_environment(backend)
    print(format_table(summaries))
    for line in mechanism_verdicts(summaries):
        print(line)
    print(format_environment(env))
    if args.json:
        with output_file(args.json, force=args.force, flag="--json") as target:
            atomic_write_bytes(target, json.dumps({"device": env, "rows": summaries}, indent=1).encode())
        print(f"wrote {args.json}")
    if args.plot:
        with output_file(args.plot, force=args.force, flag="--plot") as target:
            plot_tradeoff(summaries, Path(target))
        print(f"wrote {args.plot}")
    return 0


def add_parser(sub: Any) -> None:
    """Register ``risloc speed``.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        What ``ArgumentParser.add_subparsers()`` returned; ``speed`` is added to it, its ``func``
        set to the verb (which returns the exit status).
    """
    p = sub.add_parser("speed", help="speed against error of every estimator and trace setting, in one run",
                       description=__doc__.splitlines()[0])
    p.add_argument("--scene", action="append", help="scene name (repeatable; default: every scene in scenes/)")
    p.add_argument("--realizations", type=int, default=3, help="noise realizations per setting and position (3)")
    p.add_argument("--full", type=int, default=1,
                   help="realizations also processed with the paper's full 2-D DFT, default setting only (1)")
    p.add_argument("--positions", type=int, default=2, help="radar positions per scene (first N of its spec; 2)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--json", metavar="FILE",
                   help='write {"device": what ran the DSP and the trace, "rows": the summaries} as JSON')
    p.add_argument("--plot", metavar="PNG", help="draw the trade-off curves")
    add_force_flag(p, "an existing --json or --plot file")
    add_device_flag(p)
    p.set_defaults(func=_run)

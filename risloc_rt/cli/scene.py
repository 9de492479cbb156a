"""``risloc scene``: build, check and draw hall specs.

Each command function returns the exit status: 0 on success (for ``check``: no errors, warnings
allowed), 1 when ``check`` finds errors, 2 for a spec, file or value it cannot use (one line on
stderr)."""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path
from typing import Any, Callable

from .common import add_force_flag

__all__ = ["add_parser"]


def _guarded(name: str, func: Callable[[argparse.Namespace], int]) -> Callable[[argparse.Namespace], int]:
    """``func`` under the name ``cmd_scene_<name>``; its errors reach :func:`risloc_rt.cli.main`, which
    prints them as one line (``risloc scene NAME: error: ...``) with exit status 2 or 1."""

    def run(args: argparse.Namespace) -> int:
        return func(args)

    run.__name__ = f"cmd_scene_{name}"
    return run


def _scene_path(text: str) -> Path:
    """A spec file or scene folder; a bare name that is neither means ``scenes/<name>``."""
    path = Path(text)
    if path.is_file() and path.suffix == ".xml":
        return path.parent
    if path.exists():
        return path
    from ..authoring.scene_folder import scene_directory

    return scene_directory(text)  # FileNotFoundError listing the available scenes


def _cmd_build(args: argparse.Namespace) -> int:
    from ..authoring.build import build_scene

    spec = _scene_path(args.spec)
    if spec.is_dir():
        spec = spec / "spec.toml"
    if not spec.is_file():
        raise FileNotFoundError(f"spec {str(spec)!r} does not exist")
    built = build_scene(spec, args.out if args.out is not None else spec.parent, force=args.force)
    print(f"{built.xml_path}  sha256 {built.content_hash}")
    print(f"  {len(built.mesh_paths)} objects: {', '.join(built.object_names)}")
    return 0


def _cmd_check(args: argparse.Namespace) -> int:
    from ..authoring.check import check_scene

    report = check_scene(_scene_path(args.scene))
    print(report.format())
    return 0 if report.ok else 1


def _traced_folder(scene: Path, stack: Any) -> Path:
    """A built folder for ``scene``: the folder itself, the spec's folder when built from it, else a temporary build."""
    from ..authoring.build import build_scene

    if scene.is_dir():
        return scene
    if not scene.is_file():
        raise FileNotFoundError(f"{str(scene)!r} does not exist")
    folder = scene.parent
    if (folder / "scene.xml").is_file() and (folder / "spec.toml").is_file() \
            and (folder / "spec.toml").read_bytes() == scene.read_bytes():
        return folder
    tmp = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="risloc-show-")))
    build_scene(scene, tmp)
    return tmp


def _cmd_show(args: argparse.Namespace) -> int:
    from contextlib import ExitStack

    from ..authoring.show import show_scene

    from .._outputs import output_file

    scene = _scene_path(args.scene)
    paths = None
    with ExitStack() as stack:
        target = stack.enter_context(output_file(args.output, force=args.force, flag="-o"))
        if args.paths is not None:
            from ..hall.raytrace.tracer import TraceSettings
            from ..hall.scenario import hall_scenario
            from .common import quiet_hall_paths

            folder = _traced_folder(scene, stack)
            changes = {k: v for k, v in (("max_depth", args.depth), ("samples_per_src", args.samples)) if v is not None}
            hs = hall_scenario(folder, radar_index=args.paths, trace=TraceSettings(**changes))
            paths = quiet_hall_paths(hs, None)
        fig = show_scene(scene, target, radar_index=args.paths, paths=paths)
    extra = ""
    if paths is not None:
        extra = (f" with {fig.counts['monostatic_paths']} traced echoes and {fig.counts['ris_legs']} radar->RIS legs "
                 f"of radar position {args.paths}")
    print(f"wrote {args.output}{extra}")
    return 0


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``scene`` (with ``build``, ``check``, ``show``) to an ``add_subparsers()`` object.

    Each sub-command sets ``func``: ``args.func(args)`` runs it and returns the exit status.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        What ``ArgumentParser.add_subparsers()`` returned.

    Returns
    -------
    argparse.ArgumentParser
        The ``scene`` parser.
    """
    scene = subparsers.add_parser(
        "scene", help="author hall scenes: build a spec, check it, draw it",
        description="Build a hall spec (TOML) into a sionna-rt scene folder, validate it, or draw its plan and "
                    "elevation. Schema: risloc_rt/authoring/spec.py; tutorial: docs/scene-authoring.md.")
    sub = scene.add_subparsers(dest="scene_command", required=True, metavar="{build,check,show}")

    build = sub.add_parser("build", help="write scene.xml, meshes/*.ply and spec.toml (byte-identical run to run)")
    build.add_argument("spec", help="the spec file (TOML), a scene folder with its spec.toml, or a name in scenes/")
    build.add_argument("-o", "--out", type=Path, default=None, help="output folder (default: the spec's folder)")
    build.add_argument("--force", action="store_true",
                       help="replace files in the output folder that the build did not generate (or that were edited "
                            "since); files it did not generate are never deleted")
    build.set_defaults(func=_guarded("build", _cmd_build))

    check = sub.add_parser("check", help="validate a spec or a built scene folder (exit 1 on errors)",
                           description="Validate a spec (built into a temporary folder) or a built scene folder: "
                                       "mesh quality, closure of the hall, radar and RIS placement, materials at "
                                       "the carrier, grating lobes and the unambiguous range. Exit status 0 when "
                                       "there are no errors (warnings allowed), 1 otherwise, 2 when the input "
                                       "cannot be read.")
    check.add_argument("scene", metavar="SPEC|DIR", help="a spec file (TOML), a scene folder, or a name in scenes/")
    check.set_defaults(func=_guarded("check", _cmd_check))

    show = sub.add_parser("show", help="draw the plan and elevation into a PNG, optionally with traced paths")
    show.add_argument("scene", metavar="SPEC|DIR", help="a spec file (TOML), a scene folder, or a name in scenes/")
    show.add_argument("-o", "--output", required=True, metavar="PNG", help="the PNG to write")
    show.add_argument("--paths", type=int, metavar="RADAR_INDEX",
                      help="trace the hall from this radar position of the spec and draw the paths")
    show.add_argument("--depth", type=int, help="ray-tracing depth for --paths (default 3)")
    show.add_argument("--samples", type=int, help="rays per source for --paths (default 100000)")
    add_force_flag(show, "an existing -o file")
    show.set_defaults(func=_guarded("show", _cmd_show))
    return scene


"""Ray-traced hall scenarios: trace → paths (hall echoes, RIS loop-back, panel reflection) → pruning.

The only ray-tracing call goes through :mod:`risloc_rt.hall.raytrace` (sionna-rt); everything else
here is numpy.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from dsp import BeamSweep, ProcessingConfig, RadarConfig

from .antenna import RadarAntenna
from .multipath import monostatic_paths, ris_loopback_paths, ris_structure_paths
from ..model.paths import PathSet
from ..model.plate import Plate
from .pruning import ModelSettings, PruneReport, prune_paths
from .raytrace.tracer import TraceResult, TraceSettings
from ..model.ris import RisMode, check_ris_memory
from ..model.scenario import Scenario
from ..authoring.scene_folder import DEFAULT_SCENE, SceneError, scene_directory

__all__ = ["HallScenario", "HallPaths", "check_up_to_date", "hall_paths", "hall_scenario"]


@dataclass(frozen=True)
class HallScenario:
    """One radar placement in a ray-traced hall.

    Attributes
    ----------
    base : Scenario
        Radar, RIS, sweep, processing, UE position and velocity (no point targets).
    scene_xml : Path
        Mitsuba scene sionna-rt loads (walls, floor, ceiling, objects; *not* the RIS panel).
    plate : Plate
        The RIS panel's structure, modelled by physical optics.
    antenna : RadarAntenna
        The radar's antenna pattern.
    trace : TraceSettings
        Ray-tracer settings.
    model : ModelSettings
        IF filter and pruning.
    """

    base: Scenario
    scene_xml: Path
    plate: Plate = field(default_factory=Plate)
    antenna: RadarAntenna = field(default_factory=RadarAntenna.isotropic)
    trace: TraceSettings = field(default_factory=TraceSettings)
    model: ModelSettings = field(default_factory=ModelSettings)

    def __post_init__(self) -> None:
        xml = Path(self.scene_xml)
        if not xml.is_file():
            raise FileNotFoundError(f"scene file {str(xml)!r} does not exist; build it with 'risloc scene build'")
        object.__setattr__(self, "scene_xml", xml)

    @property
    def name(self) -> str:
        """The scenario name."""
        return self.base.name


@dataclass(frozen=True)
class HallPaths:
    """The paths that feed the beat model for one hall scenario.

    Attributes
    ----------
    paths : PathSet
        Kept paths, IF-filter gain applied.
    report : PruneReport
        What was pruned (indices refer to ``candidates``).
    candidates : PathSet
        Every path before pruning: hall echoes, then RIS loop-back pairs, then structural pairs.
    trace : TraceResult
        The ray-tracer output (monostatic paths and radar→RIS legs).
    counts : dict of str -> int
        Candidates per kind (``hall``, ``ris_loopback``, ``ris_structure``).
    timing : dict of str -> float
        Seconds: ``trace`` (0 on a cache hit apart from loading), ``paths``.
    """

    paths: PathSet
    report: PruneReport
    candidates: PathSet
    trace: TraceResult
    counts: dict[str, int]
    timing: dict[str, float]


def hall_paths(scenario: HallScenario, *, cache: Any = None) -> HallPaths:
    """Trace the hall and build the pruned path set of eq. (1) for ``scenario``.

    Parameters
    ----------
    scenario : HallScenario
    cache : risloc_rt.hall.raytrace.TraceCache, optional
        Reuse traces keyed on scene content, positions and solver settings.
    """
    from .raytrace.tracer import trace_scene

    base = scenario.base
    start = time.perf_counter()
    traced = trace_scene(
        scenario.scene_xml,
        radar_position=base.ue_position,
        ris_positions=base.ris.pose.position[None, :],
        radar_velocity=base.ue_velocity,
        frequency=base.radar.carrier_frequency,
        settings=scenario.trace,
        cache=cache,
    )
    t_trace = time.perf_counter() - start
    start = time.perf_counter()
    leg = traced.legs[0]
    parts = {
        "hall": monostatic_paths(traced.monostatic, radar=base.radar, antenna=scenario.antenna),
        "ris_loopback": ris_loopback_paths(leg, radar=base.radar, ris=base.ris, antenna=scenario.antenna),
        "ris_structure": ris_structure_paths(leg, radar=base.radar, ris=base.ris, plate=scenario.plate,
                                             antenna=scenario.antenna),
    }
    candidates = PathSet.concatenate(parts.values())
    kept, report = prune_paths(candidates, radar=base.radar, processing=base.processing, sweep=base.sweep,
                               ris=base.ris, settings=scenario.model)
    return HallPaths(
        paths=kept, report=report, candidates=candidates, trace=traced,
        counts={k: len(v) for k, v in parts.items()},
        timing={"trace": t_trace, "paths": time.perf_counter() - start},
    )


def check_up_to_date(folder: Path, spec: Any = None) -> None:
    """Refuse a scene folder whose ``scene.xml`` or meshes are not what its ``spec.toml`` builds.

    The folder is built in memory and compared byte for byte, so a spec edited after its build,
    a hand-edited XML or a changed or missing generated mesh is caught before the ray tracer would
    silently trace the old geometry.

    Raises
    ------
    SceneError
        Naming the files that differ and the command that fixes it.
    """
    from ..authoring.build import stale_files

    stale = stale_files(folder, spec)
    if stale:
        raise SceneError(
            f"scene {folder} is out of date: {', '.join(stale[:4])}{' ...' if len(stale) > 4 else ''} differ(s) from "
            "what its spec.toml builds (the spec was edited after the build, or a generated file was edited or "
            f"removed); run 'risloc scene build {folder}' (add --force to replace hand-edited files)")


def hall_scenario(
    scene: str | Path = DEFAULT_SCENE,
    *,
    radar_index: int = 0,
    mode: RisMode | None = None,
    radar: RadarConfig | None = None,
    processing: ProcessingConfig | None = None,
    sweep: BeamSweep | None = None,
    trace: TraceSettings | None = None,
    model: ModelSettings | None = None,
    ue_position: Any = None,
    ue_velocity: Any = None,
) -> HallScenario:
    """The scenario of a built scene folder: its first RIS and one of its radar positions.

    Parameters
    ----------
    scene : str or Path
        A name in ``scenes/`` (default ``"paper_hall"``) or a scene folder.
    radar_index : int
        Which of the spec's radar positions to use.
    mode : {"relay", "reflective"}, optional
        Override the RIS mode of the spec.
    radar, processing, sweep, trace, model
        Overrides of Table I's radar, the processing, the paper's sweep and the default
        ray-tracer and model settings.
    ue_position, ue_velocity : float array [3], optional
        Override the spec's radar position and velocity [m], [m/s].
    """
    from ..authoring.geometry import load_geometry
    from ..authoring.spec import load_spec

    folder = scene_directory(scene)
    spec = load_spec(folder / "spec.toml")
    check_up_to_date(folder, spec)
    ris_list = spec.ris_configs()
    if not ris_list:
        raise ValueError(f"scene {folder} has no RIS; add a [[ris]] table to its spec")
    positions = spec.radar_positions()
    if not 0 <= radar_index < len(positions):
        raise ValueError(f"radar_index={radar_index} is out of range: the scene has {len(positions)} radar position(s)")
    ue = np.asarray(positions[radar_index] if ue_position is None else ue_position, dtype=float)
    velocity = np.asarray(spec.radar_velocity() if ue_velocity is None else ue_velocity, dtype=float)
    ris = ris_list[0]
    if mode is not None:
        ris = replace(ris, mode=mode)
    if spec.ris[0].relay_rx_toward is None:  # as in the experiment: the Rx beam points at the UE
        ris = ris.with_rx_toward(ue)
    load_geometry(folder / "scene.xml").check_point(ue, what="radar")
    base = Scenario(
        radar=radar or RadarConfig(),
        ris=ris,
        sweep=sweep or BeamSweep.azimuth_grid(*np.deg2rad([-45.0, 45.0, 1.5])),
        processing=processing or ProcessingConfig(),
        ue_position=ue,
        ue_velocity=velocity,
        name=f"{spec.name}#{radar_index}" if ue_position is None else f"{spec.name}@{ue.tolist()}",
    )
    # Every simulation of the hall evaluates the RIS response for each beam of the sweep.
    check_ris_memory(ris, base.sweep.num_beams, where=f"{folder / 'spec.toml'}: ris[0] (rows, columns)",
                     fix=f"give ris[0] fewer rows and columns in {folder / 'spec.toml'} (the paper's panel has 16 x 4), "
                         "or sweep fewer beams")
    panel = spec.ris_panels()[0]
    return HallScenario(
        base=base,
        scene_xml=folder / "scene.xml",
        plate=panel,
        antenna=RadarAntenna.facing(ue, spec.radar_facing_point(ris_index=0)),
        trace=trace or TraceSettings(),
        model=model or ModelSettings(),
    )

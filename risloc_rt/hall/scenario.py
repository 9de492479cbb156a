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
from .multipath import (idle_parked_paths, idle_structure_paths, monostatic_paths, ris_loopback_paths,
                        ris_structure_paths)
from ..model.paths import PathSet
from ..model.plate import Plate
from .pruning import ModelSettings, PruneReport, prune_paths
from .raytrace.tracer import TraceResult, TraceSettings
from ..model.ris import RisConfig, RisMode, check_ris_memory
from ..model.scenario import Scenario
from ..authoring.scene_folder import DEFAULT_SCENE, SceneError, scene_directory

__all__ = ["FLOOR_HEIGHT", "HallScenario", "HallPaths", "IdleRis", "IDLE_STATES", "check_up_to_date", "hall_paths", "hall_scenario",
           "hall_slots", "facing_radar", "ris_index"]

#: What a RIS does while another one sweeps (time division, ``docs/ray-tracing.md`` "Several RISs"):
#: ``"off"``: a relay RIS's amplifier is off, only its panel's structural reflection remains (a
#: reflective RIS cannot be switched off: it holds its parked beam); ``"parked"``: it keeps
#: re-transmitting (relay) or reflecting with one fixed beam, its loop-back a static echo.
IDLE_STATES = ("off", "parked")
#: World z of every traced hall's floor [m]: a spec's footprint is the floor polygon at z = 0
#: (``risloc_rt.authoring.spec``). The DSP reads the floor's ladder of the RIS return against it
#: (``process_capture(floor_height=...)``, :func:`dsp.floor_bounce.floor_ladder`).
FLOOR_HEIGHT = 0.0


@dataclass(frozen=True)
class IdleRis:
    """A RIS of the scene that does not sweep in this slot: an echo in the sweeping RIS's capture.

    Attributes
    ----------
    name : str
        Its name in the spec.
    ris : RisConfig
        Its pose and hardware.
    plate : Plate
        Its panel's structure (always present: an echo by physical optics).
    parked_beam : float array [2] or None
        ``[az, el]`` of the beam it holds, RIS frame [rad]; None: switched off (a relay RIS with its
        amplifier off, no re-transmission).
    """

    name: str
    ris: RisConfig
    plate: Plate
    parked_beam: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.parked_beam is not None:
            beam = np.asarray(self.parked_beam, dtype=float).reshape(2)
            if not np.all(np.isfinite(beam)) or np.any(np.abs(beam) > np.pi / 2):
                raise ValueError(f"parked_beam of RIS {self.name!r} must be finite [az, el] within ±90° of broadside "
                                 f"[rad], got {beam.tolist()}")
            beam.setflags(write=False)
            object.__setattr__(self, "parked_beam", beam)


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
    ris_name : str
        The spec's name of the sweeping RIS (``base.ris``).
    idle : tuple of IdleRis
        The scene's other RISs, which do not sweep in this slot (their panels and, parked, their
        loop-back are static echoes of the hall).
    """

    base: Scenario
    scene_xml: Path
    plate: Plate = field(default_factory=Plate)
    antenna: RadarAntenna = field(default_factory=RadarAntenna.isotropic)
    trace: TraceSettings = field(default_factory=TraceSettings)
    model: ModelSettings = field(default_factory=ModelSettings)
    ris_name: str = "ris0"
    idle: tuple[IdleRis, ...] = ()

    def __post_init__(self) -> None:
        xml = Path(self.scene_xml)
        if not xml.is_file():
            raise FileNotFoundError(f"scene file {str(xml)!r} does not exist; build it with 'risloc scene build'")
        object.__setattr__(self, "scene_xml", xml)
        idle = tuple(self.idle)
        for other in idle:
            if not isinstance(other, IdleRis):
                raise TypeError(f"idle must hold IdleRis, got {type(other).__name__}")
        object.__setattr__(self, "idle", idle)

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
        Candidates per kind (``hall``, ``ris_loopback``, ``ris_structure``; with idle RISs
        ``idle_structure`` and, parked, ``idle_parked``).
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
    positions = [base.ris.pose.position] + [other.ris.pose.position for other in scenario.idle]
    traced = trace_scene(
        scenario.scene_xml,
        radar_position=base.ue_position,
        ris_positions=np.array(positions),
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
    if scenario.idle:
        parts["idle_structure"] = PathSet.concatenate([
            idle_structure_paths(traced.legs[i + 1], other, radar=base.radar, antenna=scenario.antenna)
            for i, other in enumerate(scenario.idle)])
        parked = [idle_parked_paths(traced.legs[i + 1], other, radar=base.radar, antenna=scenario.antenna)
                  for i, other in enumerate(scenario.idle) if other.parked_beam is not None]
        if parked:
            parts["idle_parked"] = PathSet.concatenate(parked)
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


def ris_index(spec: Any, ris: int | str, *, where: str = "--ris") -> int:
    """The index of one of a spec's RISs, given by its name or its index.

    Parameters
    ----------
    spec : risloc_rt.authoring.spec.HallSpec
        The scene's spec.
    ris : int or str
        A RIS name of the spec (``"ris1"``) or its index in spec order (an int or a decimal string).
    where : str
        What gave ``ris``, for the message.

    Returns
    -------
    int
        The index into ``spec.ris``.

    Raises
    ------
    ValueError
        One line naming the RISs the spec has, when it has no such RIS.
    """
    names = [r.name for r in spec.ris]
    if isinstance(ris, str) and ris in names:
        return names.index(ris)
    try:
        index = int(ris)
    except (TypeError, ValueError):
        index = -1
    if isinstance(ris, bool) or not 0 <= index < len(names) or (isinstance(ris, float) and ris != index):
        raise ValueError(f"{where}={ris!r}: the scene {spec.name!r} has no such RIS; it has "
                         f"{', '.join(names) or 'none'} (give a name or an index 0..{len(names) - 1})")
    return index


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
    ris: int | str = 0,
    idle: str = "off",
    parked_beam: Any = (0.0, 0.0),
) -> HallScenario:
    """The scenario of a built scene folder: one of its RISs sweeping, at one of its radar positions.

    Parameters
    ----------
    scene : str or Path
        A name in ``scenes/`` (default ``"paper_hall"``) or a scene folder.
    radar_index : int
        Which of the spec's radar positions to use.
    mode : {"relay", "reflective"}, optional
        Override the RIS mode of the spec (of the sweeping RIS).
    radar, processing, sweep, trace, model
        Overrides of Table I's radar, the processing, the paper's sweep and the default
        ray-tracer and model settings.
    ue_position, ue_velocity : float array [3], optional
        Override the spec's radar position and velocity [m], [m/s].
    ris : int or str
        The RIS that sweeps (its name or index; default the first). With several RISs, time
        division: the others are idle (``idle``) and their panels are echoes of this capture.
    idle : {"off", "parked"}
        What the other RISs do meanwhile (:data:`IDLE_STATES`): ``"off"`` (default; a relay's
        amplifier is off, a reflective RIS cannot be and holds ``parked_beam``) or ``"parked"``.
    parked_beam : float array [2]
        ``[az, el]`` a parked RIS holds, its own frame [rad] (default broadside).

    Notes
    -----
    The radar's boresight: ``radar.facing`` of the spec when it is a point; when it names a RIS (or
    is left out), the radar faces the RIS that sweeps in this slot (a UE turned toward each RIS
    in its slot, as the one-RIS experiment; give a point to model a fixed boresight).
    """
    from ..authoring.geometry import load_geometry
    from ..authoring.spec import load_spec

    if idle not in IDLE_STATES:
        raise ValueError(f"idle={idle!r} must be one of {IDLE_STATES} (what the other RISs do while one sweeps)")
    folder = scene_directory(scene)
    spec = load_spec(folder / "spec.toml")
    check_up_to_date(folder, spec)
    ris_list = spec.ris_configs()
    if not ris_list:
        raise ValueError(f"scene {folder} has no RIS; add a [[ris]] table to its spec")
    index = ris_index(spec, ris, where="ris")
    positions = spec.radar_positions()
    if not 0 <= radar_index < len(positions):
        raise ValueError(f"radar_index={radar_index} is out of range: the scene has {len(positions)} radar position(s)")
    ue = np.asarray(positions[radar_index] if ue_position is None else ue_position, dtype=float)
    velocity = np.asarray(spec.radar_velocity() if ue_velocity is None else ue_velocity, dtype=float)
    panels = spec.ris_panels()
    configs = []
    for i, cfg in enumerate(ris_list):
        if i == index and mode is not None:
            cfg = replace(cfg, mode=mode)
        if spec.ris[i].relay_rx_toward is None:  # as in the experiment: the Rx beam points at the UE
            cfg = cfg.with_rx_toward(ue)
        configs.append(cfg)
    sweeping = configs[index]
    load_geometry(folder / "scene.xml").check_point(ue, what="radar")
    suffix = "" if len(ris_list) == 1 else f"/{spec.ris[index].name}"
    base = Scenario(
        radar=radar or RadarConfig(),
        ris=sweeping,
        sweep=sweep or BeamSweep.azimuth_grid(*np.deg2rad([-45.0, 45.0, 1.5])),
        processing=processing or ProcessingConfig(),
        ue_position=ue,
        ue_velocity=velocity,
        name=(f"{spec.name}#{radar_index}" if ue_position is None else f"{spec.name}@{ue.tolist()}") + suffix,
    )
    # Every simulation of the hall evaluates the RIS response for each beam of the sweep.
    check_ris_memory(sweeping, base.sweep.num_beams, where=f"{folder / 'spec.toml'}: ris[{index}] (rows, columns)",
                     fix=f"give ris[{index}] fewer rows and columns in {folder / 'spec.toml'} (the paper's panel has "
                         "16 x 4), or sweep fewer beams")
    parked = np.asarray(parked_beam, dtype=float)
    others = tuple(
        IdleRis(name=spec.ris[i].name, ris=configs[i], plate=panels[i],
                parked_beam=parked if (idle == "parked" or configs[i].mode == "reflective") else None)
        for i in range(len(configs)) if i != index)
    facing = spec.radar.facing
    target = np.array(facing, dtype=float) if isinstance(facing, tuple) else sweeping.pose.position
    return HallScenario(
        base=base,
        scene_xml=folder / "scene.xml",
        plate=panels[index],
        antenna=RadarAntenna.facing(ue, target),
        trace=trace or TraceSettings(),
        model=model or ModelSettings(),
        ris_name=spec.ris[index].name,
        idle=others,
    )


def hall_slots(scene: str | Path = DEFAULT_SCENE, *, order: Any = None,
               **kwargs: Any) -> tuple[HallScenario | None, ...]:
    """One :class:`HallScenario` per RIS of a scene: time division, each RIS sweeping in its own slot.

    Parameters
    ----------
    scene : str or Path
        A name in ``scenes/`` or a scene folder.
    order : sequence of int or str, optional
        The RISs in slot order (names or indices; default every RIS in spec order).
    **kwargs
        As :func:`hall_scenario` (``ue_position``, ``idle``, ``sweep``, ...), the same for every slot.

    Returns
    -------
    tuple of HallScenario or None
        Slot k's scenario: ``order[k]`` sweeps, the others idle. None where the radar stands
        behind that RIS's plane (its sweep cannot reach the radar: that slot gives no return, and
        is not simulated).
    """
    from ..authoring.spec import load_spec

    if "ris" in kwargs:
        raise TypeError("hall_slots takes the RISs as order=[...], not ris=")
    spec = load_spec(scene_directory(scene) / "spec.toml")
    order = list(range(len(spec.ris))) if order is None else list(order)
    if not order:
        raise ValueError("order is empty: name at least one RIS to sweep")
    indices = [ris_index(spec, r, where="order") for r in order]
    if len(set(indices)) != len(indices):
        raise ValueError(f"order={order!r} names a RIS twice; each RIS sweeps in one slot")
    position = kwargs.get("ue_position")
    if position is None:
        position = spec.radar_positions()[kwargs.get("radar_index", 0)]
    configs = spec.ris_configs()
    return tuple(hall_scenario(scene, ris=i, **kwargs) if facing_radar(configs[i], position) else None
                 for i in indices)


def facing_radar(ris: RisConfig, position: Any) -> bool:
    """Whether ``position`` [m] lies in front of the RIS's plane (its sweep can reach it).

    Parameters
    ----------
    ris : RisConfig
        The RIS (its pose).
    position : float array [3]
        The radar, world frame [m].

    Returns
    -------
    bool
        True when the radar's azimuth in the RIS frame is within ±90° (not on or behind the plane).
    """
    az = float(ris.pose.angles_to(np.asarray(position, dtype=float))[0])
    return abs(az) < np.pi / 2

"""``risloc simulate``: write a capture file of the analytic scenario or of a ray-traced hall."""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np

from .._outputs import output_file, output_folder
from ..io.capture_file import save_capture
from ..model.builder import analytic_scenario
from ..model.scenario import PAPER_CASES, Scenario, paper_scenario
from ..model.simulate import simulate
from .common import (CliError, add_device_flag, add_force_flag, add_processing_flags, add_trace_flags, angle_pair,
                     device_backend, npz_target, processing_overrides, quiet_hall_paths, trace_cache, trace_settings,
                     vector)

__all__ = ["add_parser"]


def _scenario_from_args(args: argparse.Namespace) -> Scenario:
    """The analytic scenario of ``--case`` with ``--ue`` [m], ``--ue-velocity`` [m/s], ``--tx-power-dbm`` [dBm].

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line (``--distance``/``--aod`` hand over to :func:`_placed_scenario`).

    Returns
    -------
    Scenario
    """
    if args.distance is not None or args.aod is not None:
        return _placed_scenario(args)
    scenario = paper_scenario(args.case, mode=args.mode or "relay")
    radar = scenario.radar
    if args.tx_power_dbm is not None:
        radar = replace(radar, tx_power_dbm=args.tx_power_dbm)
    ue = scenario.ue_position if args.ue is None else vector(args.ue, "--ue")
    velocity = scenario.ue_velocity if args.ue_velocity is None else vector(args.ue_velocity, "--ue-velocity")
    return replace(scenario, radar=radar, ris=scenario.ris.with_rx_toward(ue), ue_position=ue,
                   ue_velocity=velocity, processing=processing_overrides(args, scenario.processing))


def _placed_scenario(args: argparse.Namespace) -> Scenario:
    """--distance [m] and --aod [deg]: the UE placed in the RIS frame of the --case's RIS.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.

    Returns
    -------
    Scenario
    """
    if args.ue is not None:
        raise CliError("--ue and --distance/--aod both place the UE; give one of them")
    if args.distance is None or args.aod is None:
        raise CliError("--distance and --aod go together, e.g. --distance 10 --aod 7.3,0")
    aod = angle_pair(args.aod, "--aod")
    velocity = (0.0, 0.0, 0.0) if args.ue_velocity is None else vector(args.ue_velocity, "--ue-velocity")
    paper = paper_scenario(args.case)
    return analytic_scenario(distance=args.distance, aod=aod, ue_velocity=velocity, mode=args.mode or "relay",
                             tx_power_dbm=args.tx_power_dbm, ris_pose=paper.ris.pose,
                             processing=processing_overrides(args, paper.processing),
                             name=f"analytic-{args.distance:g}m-{args.aod}")


def _run(args: argparse.Namespace) -> int:
    """``risloc simulate``: check ``-o`` (``risloc_rt._outputs``), then :func:`_simulate` into it.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.

    Returns
    -------
    int
        The exit status of :func:`_simulate`.
    """
    backend = device_backend(args)  # a missing GPU or a bad --device: one line before anything is written
    if args.format == "dca1000":
        from ..measured.emulate.experiment import check_folder

        folder = check_folder(args.output)
        with output_folder(folder, force=args.force, flag="-o") as stage:
            summary = _simulate(args, stage, backend)
        print(f"wrote {folder}: {summary}")
        return 0
    path = npz_target(args.output)
    with output_file(path, force=args.force, flag="-o") as target:
        summary = _simulate(args, target, backend)
    print(f"wrote {path}: {summary}")
    return 0


def _simulate(args: argparse.Namespace, target: Path, backend=None) -> str:
    """``risloc simulate``: a capture file of the analytic scenario or a traced hall (``--format dca1000``: a folder).

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line (--scene, --case, --ue [m], --calibration, --format, ...).
    target : Path
        The capture file to write, or with ``--format dca1000`` the (staging) folder.
    backend : dsp.ArrayBackend, optional
        Where the receiver noise is drawn (``--device``; :func:`risloc_rt.model.simulate.simulate`).

    Returns
    -------
    str
        What was written, for the ``wrote`` line; bad input raises ``CliError`` or
        ``MeasuredFormatError`` (exit 2).
    """
    cal = None
    if args.calibration is not None:
        from ..measured.compare.calibration_file import apply_to_scenario, calibrated_paths, read_calibration

        cal = read_calibration(args.calibration)
    if args.scene is None:
        given = [flag for flag, value in (("--ris", args.ris), ("--idle", args.idle), ("--schedule", args.schedule))
                 if value is not None]
        if given:
            raise CliError(f"{given[0]} chooses among the RISs of a hall; give --scene NAME with it")
        scenario = _scenario_from_args(args)
        if cal is not None:
            scenario = apply_to_scenario(scenario, cal)
        paths, extra = None, None
    elif args.distance is not None or args.aod is not None:
        raise CliError("--distance/--aod place the UE of the analytic scenario; with --scene use --ue X,Y,Z")
    else:
        names = _ris_names(args.scene)
        if args.format == "dca1000" and args.ris is None and len(names) > 1:
            return _time_division(args, names, cal, target, backend)
        if args.schedule is not None:
            raise CliError("--schedule places the slots of several RISs in one recording: give it with --format "
                           "dca1000 and without --ris, on a scene with several RISs")
        index = 0 if args.ris is None else _ris_choice(args.scene, args.ris)
        if len(names) > 1 and not _facing(args)[index]:
            raise CliError(f"--ris {names[index]}: the radar stands behind {names[index]}'s panel, so its sweep cannot "
                           "reach the radar; choose another --ris or move the radar (--ue, --radar-index)")
        hs = _hall(args, cal, index, args.idle or "off")
        scenario, paths, extra = _traced(args, hs)
    if args.format == "dca1000":
        from ..measured.emulate.experiment import dca1000_radar

        scenario = replace(scenario, radar=dca1000_radar(scenario.radar))
    if cal is not None:
        paths = calibrated_paths(scenario, paths, cal)
        extra = {**(extra or {}), "calibration": str(args.calibration)}
    capture = simulate(scenario, rng=np.random.default_rng(args.seed), noise=not args.no_noise, seed=args.seed,
                       paths=paths, provenance_extra=extra, motion="frozen" if args.frozen_geometry else "sweep",
                       backend=backend)
    t = capture.truth
    if args.format == "dca1000":
        return _write_dca1000(args, capture, target)
    if args.complex64:
        capture = replace(capture, cube=capture.cube.astype(np.complex64))
    save_capture(capture, target)
    return (f"{capture.cube.shape[0]} beams x {capture.cube.shape[1]} chirps x "
            f"{capture.cube.shape[2]} samples ({capture.cube.dtype}); truth: distance {t.distance:.4f} m, "
            f"AoD {np.rad2deg(t.aod[0]):+.2f}° az {np.rad2deg(t.aod[1]):+.2f}° el")


def _ris_names(scene: str) -> list[str]:
    """The names of the scene's RISs, in spec order.

    Parameters
    ----------
    scene : str
        ``--scene``: a name in ``scenes/`` or a scene folder.

    Returns
    -------
    list of str
    """
    from ..authoring.scene_folder import scene_directory
    from ..authoring.spec import load_spec

    return [r.name for r in load_spec(scene_directory(scene) / "spec.toml").ris]


def _ris_choice(scene: str, ris: str) -> int:
    """``--ris NAME|INDEX`` as an index into the scene's RISs (one line naming the RISs it has, else).

    Parameters
    ----------
    scene : str
        ``--scene``.
    ris : str
        ``--ris``: a RIS name of the spec or its index.

    Returns
    -------
    int
    """
    from ..authoring.scene_folder import scene_directory
    from ..authoring.spec import load_spec
    from ..hall.scenario import ris_index

    return ris_index(load_spec(scene_directory(scene) / "spec.toml"), ris, where="--ris")


def _hall(args: argparse.Namespace, cal, ris: int | str, idle: str, parked_beam=(0.0, 0.0)):
    """The hall scenario of ``--scene`` with RIS ``ris`` sweeping, the others ``idle``; ``--tx-power-dbm``, calibration.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line (--scene, --radar-index, --mode, --ue [m], --ue-velocity [m/s], ...).
    cal : Calibration or None
        ``--calibration``'s content.
    ris : int or str
        The sweeping RIS (index or name).
    idle : {"off", "parked"}
        What the other RISs do.
    parked_beam : (float, float)
        The beam a parked RIS holds [az, el] [rad].

    Returns
    -------
    HallScenario
    """
    from ..hall.scenario import hall_scenario

    ue = None if args.ue is None else vector(args.ue, "--ue")
    velocity = None if args.ue_velocity is None else vector(args.ue_velocity, "--ue-velocity")
    hs = hall_scenario(args.scene, radar_index=args.radar_index, mode=args.mode, trace=trace_settings(args),
                       ue_position=ue, ue_velocity=velocity, ris=ris, idle=idle, parked_beam=parked_beam)
    if args.tx_power_dbm is not None:
        hs = replace(hs, base=replace(hs.base, radar=replace(hs.base.radar, tx_power_dbm=args.tx_power_dbm)))
    if cal is not None:
        from ..measured.compare.calibration_file import apply_to_scenario

        hs = replace(hs, base=apply_to_scenario(hs.base, cal))
    return hs


def _facing(args: argparse.Namespace) -> list[bool]:
    """Whether the radar (``--ue`` or the spec's ``--radar-index`` position) is in front of each RIS of ``--scene``.

    Parameters
    ----------
    args : argparse.Namespace
        ``--scene``, ``--ue`` [m], ``--radar-index``.

    Returns
    -------
    list of bool
        One per RIS, spec order (:func:`risloc_rt.hall.scenario.facing_radar`).
    """
    from ..authoring.scene_folder import scene_directory
    from ..authoring.spec import load_spec
    from ..hall.scenario import facing_radar

    spec = load_spec(scene_directory(args.scene) / "spec.toml")
    positions = spec.radar_positions()
    if args.ue is not None:
        ue = vector(args.ue, "--ue")
    elif 0 <= args.radar_index < len(positions):
        ue = positions[args.radar_index]
    else:
        raise CliError(f"--radar-index {args.radar_index} is out of range: the scene has {len(positions)} radar "
                       "position(s)")
    return [facing_radar(cfg, ue) for cfg in spec.ris_configs()]


def _traced(args: argparse.Namespace, hs) -> tuple[Scenario, object, dict]:
    """Trace one slot of the hall: its scenario (processing flags applied), paths and provenance; prints the pruning.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line (trace and processing flags).
    hs : HallScenario
        The slot.

    Returns
    -------
    (Scenario, PathSet, dict)
    """
    scenario = replace(hs.base, processing=processing_overrides(args, hs.base.processing))
    traced = quiet_hall_paths(hs, trace_cache(args))
    extra = {"scene": str(hs.scene_xml), "scene_hash": traced.trace.scene_hash,
             "trace_settings": hs.trace.to_dict(), "model": hs.model.to_dict(),
             "pruning": traced.report.summary(), "ris_name": hs.ris_name,
             "idle_ris": [{"name": o.name, "parked_beam": None if o.parked_beam is None else
                           np.asarray(o.parked_beam).tolist()} for o in hs.idle]}
    print(f"traced {hs.scene_xml}" + (f" ({hs.ris_name} sweeping)" if hs.idle else "") +
          f": {traced.report.summary()}")
    for w in traced.report.warnings:
        print(f"warning: {w}")
    return scenario, traced.paths, extra


def _division(args: argparse.Namespace, names: list[str], sweep_duration: float):
    """The time division of ``--schedule FILE`` (its ``[schedule]`` table), or every RIS back to back.

    Parameters
    ----------
    args : argparse.Namespace
        ``--schedule``, ``--idle``.
    names : list of str
        The scene's RISs.
    sweep_duration : float
        One slot: M beams × the radar's beam interval [s].

    Returns
    -------
    TimeDivision
    """
    import tomllib

    from ..model.time_division import TimeDivision, parse_time_division

    if args.schedule is None:
        return TimeDivision.consecutive(names, sweep_duration, idle=args.idle or "off")
    path = Path(args.schedule)
    if not path.is_file():
        raise CliError(f"--schedule {path} does not exist; give a TOML file with a [schedule] table (docs/formats.md, "
                       "\"Several RISs\")")
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise CliError(f"--schedule {path}: not valid TOML ({exc}); check quotes, brackets and '=' signs") from None
    other = [k for k in doc if k != "schedule"]
    if other or "schedule" not in doc:
        what = f"has {other[0]!r}" if other else "has no [schedule] table"
        raise CliError(f"--schedule {path} {what}; the file holds one [schedule] table (order, gap_ms, idle, "
                       "parked_deg, start_ms, cycle_ms)")
    if args.idle is not None:
        raise CliError("--idle and --schedule both say what the idle RISs do; give idle = ... in the [schedule] table")
    return parse_time_division(doc["schedule"], ris_names=names, sweep_duration=sweep_duration,
                               where=f"{path}: [schedule]", error=CliError)


def _time_division(args: argparse.Namespace, names: list[str], cal, folder: Path, backend=None) -> str:
    """--format dca1000 on a scene with several RISs: one recording, each RIS sweeping in its own slot.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
    names : list of str
        The scene's RISs, in spec order.
    cal : Calibration or None
        ``--calibration``'s content.
    folder : Path
        The (staging) folder to write.
    backend : dsp.ArrayBackend, optional
        Where the receiver noise is drawn.

    Returns
    -------
    str
        What was written, for the ``wrote`` line.
    """
    from ..measured.emulate.experiment import dca1000_radar
    from ..measured.emulate.time_division import emulate_time_division, idle_frame, slot_first_frames

    faces = dict(zip(names, _facing(args)))
    if not any(faces.values()):
        raise CliError("the radar stands behind every RIS of the scene: no slot has a return; move it (--ue)")
    first = _hall(args, cal, names.index(next(n for n in names if faces[n])), args.idle or "off")
    if np.any(first.base.ue_velocity != 0):
        raise CliError("a moving radar in a time-division recording is not modelled (one truth for every slot); "
                       "give --ue-velocity 0,0,0, or simulate one RIS with --ris")
    radar = dca1000_radar(first.base.radar)
    td = _division(args, names, first.base.sweep.num_beams * radar.beam_interval)
    firsts = slot_first_frames(td, radar.frame_interval)
    captures, configs, idle = [], [], None
    for k, name in enumerate(td.order):
        if not faces[name]:
            print(f"note: the radar stands behind {name}'s panel: its slot holds no return")
            configs.append(_spec_ris(args, name))
            captures.append(None)
            continue
        hs = _hall(args, cal, name, td.idle, td.parked_beam)
        configs.append(hs.base.ris)
        scenario, paths, extra = _traced(args, hs)
        scenario = replace(scenario, radar=radar)
        if cal is not None:
            from ..measured.compare.calibration_file import calibrated_paths

            paths = calibrated_paths(scenario, paths, cal)
        idle = idle_frame(scenario, paths) if idle is None else idle
        captures.append(simulate(scenario, rng=np.random.default_rng([args.seed, 2, k]), noise=not args.no_noise,
                                 seed=args.seed, paths=paths, provenance_extra=extra, motion="frozen",
                                 backend=backend))
    rec = emulate_time_division(list(td.order), configs, captures, folder, idle=idle,
                                rng=np.random.default_rng([args.seed, 1]), first_frames=firsts,
                                division={k: v for k, v in td.to_dict().items() if k in ("order", "idle",
                                                                                          "parked_deg")},
                                noise=not args.no_noise, **_adc_options(args, radar))
    t = next(c for c in captures if c is not None).truth
    slots = ", ".join(f"{n} frames {f}..{f + first.base.sweep.num_beams - 1}" for n, f in zip(td.order, firsts))
    return (f"{rec.raw_path.name} ({rec.num_frames} frames), {rec.config_path.name}, {rec.schedule_path.name}: "
            f"{len(td.order)} RISs in time division ({slots}; the others {td.idle}); truth: radar at "
            f"{np.round(t.ue_position, 4).tolist()} m")


def _spec_ris(args: argparse.Namespace, name: str):
    """The spec's RIS ``name`` of ``--scene`` (pose, hardware), for the schedule of a slot that is not simulated.

    Parameters
    ----------
    args : argparse.Namespace
        ``--scene``.
    name : str
        The RIS's name in the spec.

    Returns
    -------
    RisConfig
    """
    from ..authoring.scene_folder import scene_directory
    from ..authoring.spec import load_spec

    spec = load_spec(scene_directory(args.scene) / "spec.toml")
    return spec.ris_configs()[[r.name for r in spec.ris].index(name)]


def _adc_options(args: argparse.Namespace, radar) -> dict:
    """The ADC keywords of the emulators: ``--adc-bits``, ``--dropped-packets-rate``, ``--dc-offset`` [LSB], ...

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
    radar : RadarConfig
        The TI-compatible radar (its full scale, for the calibration's ADC gain).

    Returns
    -------
    dict
        ``adc_bits``, ``dropped_packets_rate``, ``dc_offset`` [LSB], ``iq_gain_db`` [dB], ``power_offset_db`` [dB].
    """
    dc = 0j
    if args.dc_offset is not None:
        try:
            i, q = (float(x) for x in args.dc_offset.split(","))
        except ValueError:
            raise CliError(f"--dc-offset {args.dc_offset!r} must be two comma-separated numbers I,Q in LSB counts, "
                           "e.g. 12,-5") from None
        dc = complex(i, q)
    if args.complex64:
        raise CliError("--complex64 applies to --format npz; a DCA1000 capture holds int16 ADC codes")
    offset = 0.0
    if args.calibration is not None:
        from ..measured.compare.calibration_file import adc_power_offset_db, read_calibration
        from ..measured.emulate.experiment import full_scale

        offset = adc_power_offset_db(read_calibration(args.calibration), 2.0 ** (args.adc_bits - 1) /
                                     full_scale(radar))
    return {"adc_bits": args.adc_bits, "dropped_packets_rate": args.dropped_packets_rate, "dc_offset": dc,
            "iq_gain_db": args.iq_gain_db, "power_offset_db": offset}


def _write_dca1000(args: argparse.Namespace, capture, folder: Path) -> str:
    """--format dca1000: the folder of a real experiment (risloc_rt.measured.emulate.experiment).

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line (``--adc-bits``, ``--dc-offset`` [LSB], ``--iq-gain-db`` [dB], ...).
    capture : Capture
        The simulated capture (its radar made TI-compatible with ``dca1000_radar``).
    folder : Path
        The folder to write (the staging folder of ``-o``).

    Returns
    -------
    str
        What was written, for the ``wrote`` line.
    """
    from ..measured.emulate.experiment import emulate_capture

    exp = emulate_capture(capture, folder, rng=np.random.default_rng([args.seed, 1]),
                          **_adc_options(args, capture.radar))
    t = capture.truth
    return (f"{exp.raw_path.name} ({len(exp.raw.files)} file(s), {exp.raw.stream_bytes} bytes, "
            f"{len(exp.raw.dropped_sequences)} dropped packet(s)), {exp.config_path.name}, {exp.schedule_path.name}: "
            f"{capture.cube.shape[0]} beams x {capture.cube.shape[1]} chirps x {capture.cube.shape[2]} samples, "
            f"{args.adc_bits}-bit, full scale {exp.full_scale:.4g} sqrt(W); truth: distance {t.distance:.4f} m, "
            f"AoD {np.rad2deg(t.aod[0]):+.2f}° az {np.rad2deg(t.aod[1]):+.2f}° el")


def add_parser(sub) -> None:
    """Add ``simulate`` to an ``add_subparsers()`` object.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        What ``ArgumentParser.add_subparsers()`` returned; the verb's parser is added to it, its
        ``func`` set to the verb (which takes the parsed arguments and returns the exit status).
    """
    sim = sub.add_parser("simulate", help="simulate a capture file: the paper scenario, or a ray-traced hall with --scene")
    sim.add_argument("-o", "--output", required=True, help="capture file to write (.npz), or with --format dca1000 "
                                                           "the folder")
    add_force_flag(sim, "an existing -o file")
    sim.add_argument("--scene", help="ray trace this hall (name in scenes/ or folder) instead of the analytic paper scenario")
    sim.add_argument("--ris", metavar="NAME|INDEX",
                     help="with --scene: the RIS that sweeps (its name in the spec, or index; default the first); the "
                          "others are idle (--idle). Without it, --format dca1000 on a scene with several RISs writes "
                          "one recording of every RIS, each in its own slot (time division)")
    sim.add_argument("--idle", choices=["off", "parked"],
                     help="with --scene: what the other RISs do meanwhile: off (a relay's amplifier off: only its panel's "
                          "echo) or parked (holds one beam, broadside: its loop-back a static echo); a reflective RIS is "
                          "always parked (default: off)")
    sim.add_argument("--schedule", metavar="FILE",
                     help="with --scene and --format dca1000: a TOML file with a [schedule] table (order, gap_ms, idle, "
                          "parked_deg, start_ms, cycle_ms) placing each RIS's slot (default: every RIS in spec order, "
                          "back to back; docs/formats.md \"Several RISs\")")
    sim.add_argument("--radar-index", type=int, default=0, help="with --scene: which radar position of the spec (default: %(default)s)")
    sim.add_argument("--case", choices=list(PAPER_CASES), default="broadside", help="analytic paper case (default: %(default)s)")
    sim.add_argument("--mode", choices=["relay", "reflective"], help="RIS mode (default: relay, or the scene's)")
    sim.add_argument("--ue", metavar="X,Y,Z", help="UE position [m] (default: the origin, or the scene's radar position)")
    sim.add_argument("--distance", type=float, metavar="M",
                     help="UE-RIS distance [m]; with --aod places the UE in the RIS frame of --case's RIS")
    sim.add_argument("--aod", metavar="AZ,EL", help="AoD of the UE seen from the RIS [deg], with --distance")
    sim.add_argument("--ue-velocity", metavar="VX,VY,VZ", help="UE velocity [m/s] (default: 0)")
    sim.add_argument("--frozen-geometry", action="store_true",
                     help="freeze the UE's position over the sweep, as the paper's eq. (1) (default: a moving UE is "
                          "placed where it is at each frame; positions refer to the middle of the sweep)")
    sim.add_argument("--tx-power-dbm", type=float, help="transmit power [dBm] (default: Table I, 20)")
    sim.add_argument("--seed", type=int, default=0, help="noise seed (default: %(default)s)")
    sim.add_argument("--no-noise", action="store_true", help="write the noiseless cube")
    sim.add_argument("--complex64", action="store_true", help="store the cube as complex64 (half the size)")
    sim.add_argument("--format", choices=["npz", "dca1000"], default="npz",
                     help="npz: a capture file; dca1000: -o is a folder that gets the raw DCA1000 files, the .cfg "
                          "and sweep.toml of the experiment (docs/measured-captures.md) (default: %(default)s)")
    sim.add_argument("--adc-bits", type=int, choices=[12, 14, 16], default=16, help="dca1000: ADC bits (default: 16)")
    sim.add_argument("--dropped-packets-rate", type=float, default=0.0, metavar="P",
                     help="dca1000: probability of losing each UDP packet (packet-recorded form; default: 0)")
    sim.add_argument("--dc-offset", metavar="I,Q", help="dca1000: ADC DC offset [LSB counts] (default: 0,0)")
    sim.add_argument("--iq-gain-db", type=float, default=0.0, help="dca1000: Q/I gain imbalance [dB] (default: 0)")
    sim.add_argument("--calibration", metavar="FILE",
                     help="a calibration file from 'risloc calibrate': range offset, tau_RB, zeta, noise power (and, "
                          "with --format dca1000, the ADC counts per watt)")
    add_trace_flags(sim)
    add_processing_flags(sim)
    add_device_flag(sim)
    sim.set_defaults(func=_run)

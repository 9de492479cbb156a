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
        scenario = _scenario_from_args(args)
        if cal is not None:
            scenario = apply_to_scenario(scenario, cal)
        paths, extra = None, None
    elif args.distance is not None or args.aod is not None:
        raise CliError("--distance/--aod place the UE of the analytic scenario; with --scene use --ue X,Y,Z")
    else:
        from ..hall.scenario import hall_scenario

        ue = None if args.ue is None else vector(args.ue, "--ue")
        velocity = None if args.ue_velocity is None else vector(args.ue_velocity, "--ue-velocity")
        hs = hall_scenario(args.scene, radar_index=args.radar_index, mode=args.mode, trace=trace_settings(args),
                           ue_position=ue, ue_velocity=velocity)
        if args.tx_power_dbm is not None:
            hs = replace(hs, base=replace(hs.base, radar=replace(hs.base.radar, tx_power_dbm=args.tx_power_dbm)))
        if cal is not None:
            hs = replace(hs, base=apply_to_scenario(hs.base, cal))
        scenario = replace(hs.base, processing=processing_overrides(args, hs.base.processing))
        traced = quiet_hall_paths(hs, trace_cache(args))
        paths = traced.paths
        extra = {"scene": str(hs.scene_xml), "scene_hash": traced.trace.scene_hash,
                 "trace_settings": hs.trace.to_dict(), "model": hs.model.to_dict(),
                 "pruning": traced.report.summary()}
        print(f"traced {hs.scene_xml}: {traced.report.summary()}")
        for w in traced.report.warnings:
            print(f"warning: {w}")
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
                                     full_scale(capture.radar))
    exp = emulate_capture(capture, folder, adc_bits=args.adc_bits, dropped_packets_rate=args.dropped_packets_rate,
                          dc_offset=dc, iq_gain_db=args.iq_gain_db, power_offset_db=offset,
                          rng=np.random.default_rng([args.seed, 1]))
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

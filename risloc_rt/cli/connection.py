"""Options shared by the verbs that record or import a RIS sweep: ``capture record``, ``capture import``, ``locate --live``.

:func:`add_connection_flags` adds the radar and DCA1000 connection options to a parser (or an argument
group) and :func:`record_plan` turns them into the :class:`~risloc_rt.measured.live.record.RecordPlan`
both ``capture record`` and ``locate --live`` record with; :func:`add_sweep_import_flags` and
:func:`sweep_import_options` are the sweep import's options (``--first-frame``, ``--leakage``,
``--gate-range``, ``--channels``, ``--min-confidence``) of ``capture import`` and ``locate --live``.
"""

from __future__ import annotations

import argparse
from typing import Any

from .common import CliError

__all__ = ["add_connection_flags", "add_sweep_import_flags", "record_plan", "sweep_import_options"]


def add_connection_flags(p: Any, *, required: bool, device_flag: str = "--device") -> None:
    """Add ``--config``, ``--serial``, ``--frames``/``--duration``, the device family, ``--host-ip``,
    ``--fpga-ip``, ``--config-port``, ``--data-port``, ``--split-size`` [bytes] and ``--baudrate``.

    Parameters
    ----------
    p : argparse.ArgumentParser or argument group
        Where the options go.
    required : bool
        Whether ``--config`` and ``--serial`` are required (``capture record``) or checked later
        (``locate --live``, whose other uses do not need them).
    device_flag : str, default ``"--device"``
        The device family's flag (``locate`` has ``--device`` for the DSP: there it is ``--radar-device``);
        its value is ``args.radar_device`` either way.
    """
    from ..measured.live.addresses import CONFIG_PORT, DATA_PORT, DEFAULT_FPGA_IP, DEFAULT_HOST_IP
    from ..measured.live.recording_writer import DEFAULT_SPLIT_SIZE

    p.add_argument("--config", required=required, metavar="RADAR.cfg",
                   help="the mmWave SDK .cfg, sent to the radar line by line (its lanes and ADC format configure "
                        "the DCA1000; copied into the recording's folder as adc_data.cfg)")
    p.add_argument("--serial", required=required, metavar="PORT",
                   help="the radar's CLI (user) UART, e.g. /dev/ttyUSB0 or /dev/ttyACM0 (you need the dialout group)")
    stop = p.add_mutually_exclusive_group()
    stop.add_argument("--frames", type=int, metavar="N",
                      help="stop after N frames (default: the .cfg's frameCfg numFrames)")
    stop.add_argument("--duration", type=float, metavar="S", help="stop after S seconds")
    p.add_argument(device_flag, dest="radar_device", default="IWR6843", metavar="FAMILY",
                   help="the radar's device family: IWR6843 (ISK, AOP), xWR1843, xWR1642, xWR1443 "
                        "(default: %(default)s)")
    p.add_argument("--host-ip", default=DEFAULT_HOST_IP,
                   help="this computer's address on the DCA1000's Ethernet port (default: %(default)s)")
    p.add_argument("--fpga-ip", default=DEFAULT_FPGA_IP, help="the DCA1000's address (default: %(default)s)")
    p.add_argument("--config-port", type=int, default=CONFIG_PORT,
                   help="the DCA1000's UDP configuration port, on both sides (default: %(default)s)")
    p.add_argument("--data-port", type=int, default=DATA_PORT,
                   help="the UDP port this computer receives the data on (default: %(default)s)")
    p.add_argument("--split-size", type=int, default=DEFAULT_SPLIT_SIZE, metavar="BYTES",
                   help="start a new adc_data_Raw_<i>.bin at this size, rounded down to whole 1456-byte packets "
                        "(default: %(default)s = 1024 MiB, TI's DCA1000 CLI default)")
    p.add_argument("--baudrate", type=int, default=115200, help="the CLI UART's baud rate (default: %(default)s)")


def record_plan(args: argparse.Namespace) -> Any:
    """The recording the connection options describe.

    Parameters
    ----------
    args : argparse.Namespace
        ``config``, ``serial``, ``out``, ``frames``, ``duration``, ``sweep``, ``radar_device``, ``host_ip``,
        ``fpga_ip``, ``config_port``, ``data_port``, ``split_size``, ``baudrate``.

    Returns
    -------
    risloc_rt.measured.live.record.RecordPlan

    Raises
    ------
    CliError
        Both ``--frames`` and ``--duration`` (one line).
    """
    from ..measured.live.addresses import Endpoints
    from ..measured.live.record import RecordPlan

    if args.frames is not None and args.duration is not None:
        raise CliError("give --frames N or --duration S, not both")
    return RecordPlan(config=args.config, serial_port=args.serial, out=args.out, frames=args.frames,
                      duration=args.duration, sweep=args.sweep,
                      endpoints=Endpoints(host_ip=args.host_ip, fpga_ip=args.fpga_ip, config_port=args.config_port,
                                          data_port=args.data_port),
                      device=args.radar_device, split_size=args.split_size, baudrate=args.baudrate)


def add_sweep_import_flags(p: Any, *, first_frame_help: str) -> None:
    """Add ``--first-frame``, ``--leakage``, ``--gate-range`` [m], ``--channels`` and ``--min-confidence``.

    Parameters
    ----------
    p : argparse.ArgumentParser or argument group
        Where the options go.
    first_frame_help : str
        The verb's words for ``--first-frame`` (one recording, or a sweep of a live recording).
    """
    from ..measured.sweep.importer import DEFAULT_LEAKAGE
    from ..measured.sweep.leakage import DEFAULT_GATE_RANGE, LEAKAGE_METHODS

    p.add_argument("--first-frame", metavar="N|auto", help=first_frame_help)
    p.add_argument("--leakage", choices=list(LEAKAGE_METHODS), default=DEFAULT_LEAKAGE,
                   help="self-interference (Tx-Rx leakage, DC) removal: gate (range gate), background (subtract "
                        "the RIS-off frames) or none (default: %(default)s; docs/measured-captures.md)")
    p.add_argument("--gate-range", type=float, default=DEFAULT_GATE_RANGE, metavar="M",
                   help="range gate [m] (default: %(default)s)")
    p.add_argument("--channels", metavar="V,V,...",
                   help="virtual channels to combine (maximal-ratio on the RIS return; default: the schedule's "
                        "channel)")
    p.add_argument("--min-confidence", type=float, default=0.5, metavar="P",
                   help="refuse an automatic alignment less sure than this (default: %(default)s)")


def sweep_import_options(args: argparse.Namespace) -> dict[str, Any]:
    """The ``import_capture`` keywords of :func:`add_sweep_import_flags`'s options.

    Parameters
    ----------
    args : argparse.Namespace
        ``first_frame``, ``leakage``, ``gate_range``, ``channels``, ``min_confidence``.

    Returns
    -------
    dict
        ``first_frame`` (int ≥ 0, ``"auto"`` or None), ``leakage``, ``gate_range`` [m], ``channels`` (list of
        int or None), ``min_confidence``.

    Raises
    ------
    CliError
        A ``--first-frame`` or ``--channels`` that is not one (one line).
    """
    first = args.first_frame
    if first is not None and first != "auto":
        try:
            first = int(first)
        except ValueError:
            raise CliError(f"--first-frame {args.first_frame!r} must be 'auto' or a frame index >= 0") from None
        if first < 0:
            raise CliError(f"--first-frame {first} must be >= 0 (the recorded frame of the first beam), or 'auto'")
    channels = None
    if args.channels is not None:
        try:
            channels = [int(c) for c in args.channels.split(",")]
        except ValueError:
            raise CliError(f"--channels {args.channels!r} must be comma-separated virtual channel indices, "
                           "e.g. 0,1,2,3") from None
    return {"first_frame": first, "leakage": args.leakage, "gate_range": args.gate_range, "channels": channels,
            "min_confidence": args.min_confidence}

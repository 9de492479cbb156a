"""The radar and DCA1000 connection options shared by ``risloc capture record`` and ``risloc locate --live``.

:func:`add_connection_flags` adds them to a parser (or an argument group); :func:`record_plan` turns the
parsed options into the :class:`~risloc_rt.measured.live.record.RecordPlan` both verbs record with.
"""

from __future__ import annotations

import argparse
from typing import Any

from .common import CliError

__all__ = ["add_connection_flags", "record_plan"]


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

"""The DCA1000's configuration link: one UDP socket on the host's configuration port, commands and their answers.

The host binds ``(host_ip, config_port)`` and sends each command to ``(fpga_ip, config_port)``;
the FPGA answers on the same port with the command code and a status (user's guide section 5;
the packets are :mod:`risloc_rt.measured.dca1000.control`'s). A command waits for the answer
to *its* code; answers to other codes are dropped and the asynchronous SYSTEM_ERROR packets the
FPGA sends during a recording are kept in :attr:`Dca1000Link.async_events`. Silence or a non-zero
status is one :class:`Dca1000Error` line naming the command, the address, the status and the fix.

The order TI's CLI follows (``DCA1000EVM_CLI_Control fpga``, ``record``, ``start_record``):
SYSTEM_CONNECT, READ_FPGA_VERSION, CONFIG_FPGA_GEN, CONFIG_PACKET_DATA, then RECORD_START before
the radar's ``sensorStart`` and RECORD_STOP after its ``sensorStop``.
"""

from __future__ import annotations

import errno
import select
import socket
import time
from dataclasses import dataclass

from ..dca1000.control import (ASYNC_STATUS_TEXT, Command, FpgaConfig, FpgaVersion, PacketConfig, Response,
                               decode_async_status, decode_response, encode_command)
from ..errors import MeasuredFormatError
from .addresses import Endpoints

__all__ = ["AsyncEvent", "Dca1000Error", "Dca1000Link", "send_record_stop"]

_FIX_SILENT = ("check the Ethernet cable, that this computer has {host} on that port, and that the DCA1000's "
               "SW2.5 is set to 'SW config'")
_FIX_STATUS = {
    Command.CONFIG_FPGA_GEN: "the FPGA refused the mode: check the lane count and data format against the radar, "
                             "power-cycle the DCA1000 and try again",
    Command.RECORD_START: "the FPGA could not start recording: send RECORD_STOP (or reset the FPGA) and try again",
}


class Dca1000Error(MeasuredFormatError):
    """The DCA1000 did not answer, refused a command, or its port could not be opened (one line)."""


@dataclass(frozen=True)
class AsyncEvent:
    """An asynchronous SYSTEM_ERROR packet the FPGA sent unasked.

    Attributes
    ----------
    time : float
        ``time.monotonic()`` when it was read [s].
    status : int
        Its u16 status word (a bit set, :class:`risloc_rt.measured.dca1000.control.AsyncStatus`).
    """

    time: float
    status: int

    def describe(self) -> str:
        """The conditions in words, e.g. ``record completed``.

        Returns
        -------
        str
        """
        names = [ASYNC_STATUS_TEXT[s] for s in decode_async_status(self.status)]
        return ", ".join(names) or f"status 0x{self.status:04X}"


def _bind(sock: socket.socket, ip: str, port: int, what: str) -> None:
    try:
        sock.bind((ip, port))
    except OSError as exc:
        sock.close()
        if exc.errno == errno.EADDRNOTAVAIL:
            raise Dca1000Error(f"this computer has no address {ip}, so it cannot open the DCA1000's {what} port "
                               f"{port}: give the Ethernet port wired to the DCA1000 that address (e.g. 'sudo ip addr "
                               f"add {ip}/24 dev <interface>') or pass --host-ip with one it has") from None
        if exc.errno == errno.EADDRINUSE:
            raise Dca1000Error(f"UDP port {port} on {ip} ({what}) is in use by another program (mmWave Studio, "
                               "TI's DCA1000EVM_CLI, another risloc): close it and try again") from None
        if exc.errno == errno.EACCES:
            raise Dca1000Error(f"binding UDP {ip}:{port} ({what}) was refused (permission denied): use a port "
                               "above 1023 or run with the right to bind it") from None
        raise Dca1000Error(f"cannot open UDP {ip}:{port} ({what}): {exc.strerror or exc}") from None


class Dca1000Link:
    """The DCA1000's configuration port, as a context manager.

    Parameters
    ----------
    endpoints : Endpoints
        The host's and the FPGA's addresses and the configuration port.
    timeout : float, default 1.0
        How long one try waits for an answer [s].
    retries : int, default 1
        Tries after the first when no answer comes (UDP may drop a datagram); a refusal is not
        retried.

    Examples
    --------
    >>> with Dca1000Link(Endpoints.loopback()) as link:        # doctest: +SKIP
    ...     version = link.connect()
    ...     link.configure(FpgaConfig(lanes=2, data_bits=16), PacketConfig())
    ...     link.start_record()
    """

    def __init__(self, endpoints: Endpoints, timeout: float = 1.0, retries: int = 1) -> None:
        if not isinstance(endpoints, Endpoints):
            raise MeasuredFormatError(f"endpoints must be an Endpoints, not {type(endpoints).__name__}")
        if not timeout > 0:
            raise MeasuredFormatError(f"timeout={timeout!r} s must be > 0")
        if isinstance(retries, bool) or not isinstance(retries, int) or retries < 0:
            raise MeasuredFormatError(f"retries={retries!r} must be an integer >= 0")
        self.endpoints, self.timeout, self.retries = endpoints, float(timeout), retries
        self.async_events: list[AsyncEvent] = []
        self._sock: socket.socket | None = None

    @property
    def fpga_address(self) -> tuple[str, int]:
        """``(fpga_ip, config_port)``, where commands go."""
        return (self.endpoints.fpga_ip, self.endpoints.config_port)

    def open(self) -> "Dca1000Link":
        """Bind the host's configuration port (done by ``with``).

        Returns
        -------
        Dca1000Link
            self.
        """
        if self._sock is None:
            sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            _bind(sock, self.endpoints.host_ip, self.endpoints.config_port, "configuration")
            self._sock = sock
        return self

    def close(self) -> None:
        """Close the socket (idempotent)."""
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def __enter__(self) -> "Dca1000Link":
        return self.open()

    def __exit__(self, *exc) -> None:
        self.close()

    def _where(self) -> str:
        return f"{self.endpoints.fpga_ip}:{self.endpoints.config_port}"

    def _await(self, command: Command, deadline: float) -> Response | None:
        """The answer to ``command`` before ``deadline`` (monotonic [s]), or None."""
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            ready, _, _ = select.select([self._sock], [], [], left)
            if not ready:
                return None
            try:
                data, sender = self._sock.recvfrom(2048)
            except (ConnectionRefusedError, OSError):
                continue                          # an ICMP error from an earlier datagram: keep waiting
            if sender[0] != self.endpoints.fpga_ip:
                continue
            try:
                response = decode_response(data)
            except MeasuredFormatError:
                continue
            if response.command == Command.SYSTEM_ERROR and command != Command.SYSTEM_ERROR:
                self.async_events.append(AsyncEvent(time.monotonic(), response.status))
                continue
            if response.command == command:
                return response

    def command(self, cmd: Command | int, payload: bytes = b"") -> Response:
        """Send one command and wait for its answer.

        Parameters
        ----------
        cmd : Command or int
            The command.
        payload : bytes, default empty
            Its data.

        Returns
        -------
        Response
            The answer (status 0, or the version word for READ_FPGA_VERSION).

        Raises
        ------
        Dca1000Error
            No answer within ``timeout`` on every try, or a non-zero status (one line each).
        """
        if self._sock is None:
            raise MeasuredFormatError("the DCA1000 link is not open: use 'with Dca1000Link(...) as link:'")
        cmd = Command(cmd)
        packet = encode_command(cmd, payload)
        for _ in range(self.retries + 1):
            try:
                self._sock.sendto(packet, self.fpga_address)
            except OSError as exc:
                raise Dca1000Error(f"cannot send {cmd.name} to the DCA1000 at {self._where()}: "
                                   f"{exc.strerror or exc}; check the network interface and --fpga-ip") from None
            response = self._await(cmd, time.monotonic() + self.timeout)
            if response is None:
                continue
            if not response.ok:
                fix = _FIX_STATUS.get(cmd, "power-cycle the DCA1000 (or send RESET_FPGA) and try again")
                raise Dca1000Error(f"the DCA1000 at {self._where()} refused {cmd.name} with status "
                                   f"{response.status} (0x{response.status:04X}): {fix}")
            return response
        tries = self.retries + 1
        raise Dca1000Error(f"no answer from the DCA1000 at {self._where()} to {cmd.name} within {self.timeout:g} s"
                           f"{f' ({tries} tries)' if tries > 1 else ''}: "
                           + _FIX_SILENT.format(host=self.endpoints.host_ip))

    def connect(self) -> FpgaVersion:
        """SYSTEM_CONNECT, then READ_FPGA_VERSION.

        Returns
        -------
        FpgaVersion
            The FPGA's version; a playback bitfile cannot record (one-line error).
        """
        self.command(Command.SYSTEM_CONNECT)
        version = FpgaVersion.from_status(self.command(Command.READ_FPGA_VERSION).status)
        if version.playback:
            raise Dca1000Error(f"the DCA1000 at {self._where()} runs the playback FPGA bitfile ({version}), which "
                               "cannot record: flash the record bitfile (DCA1000EVM user's guide) and try again")
        return version

    def configure(self, fpga: FpgaConfig, packets: PacketConfig = PacketConfig()) -> None:
        """CONFIG_FPGA_GEN then CONFIG_PACKET_DATA.

        Parameters
        ----------
        fpga : FpgaConfig
            Lanes, data format, modes.
        packets : PacketConfig, default ``PacketConfig()``
            Packet size and inter-packet delay [s].
        """
        self.command(Command.CONFIG_FPGA_GEN, fpga.payload())
        self.command(Command.CONFIG_PACKET_DATA, packets.payload())

    def start_record(self) -> None:
        """RECORD_START: the FPGA streams what the radar sends on LVDS to the data port."""
        self.command(Command.RECORD_START)

    def stop_record(self) -> None:
        """RECORD_STOP."""
        self.command(Command.RECORD_STOP)

    def reset_fpga(self) -> None:
        """RESET_FPGA."""
        self.command(Command.RESET_FPGA)

    def reset_radar(self) -> None:
        """RESET_AR_DEVICE: the DCA1000 resets the radar device through its reset line."""
        self.command(Command.RESET_AR_DEVICE)

    def stop_record_quietly(self) -> bool:
        """Send RECORD_STOP once without waiting, for cleanup paths; never raises.

        Returns
        -------
        bool
            Whether the datagram left this computer.
        """
        if self._sock is None:
            return send_record_stop(self.endpoints)
        try:
            self._sock.sendto(encode_command(Command.RECORD_STOP), self.fpga_address)
            return True
        except OSError:
            return False


def send_record_stop(endpoints: Endpoints) -> bool:
    """Send one RECORD_STOP to the DCA1000 best-effort (cleanup paths: Ctrl-C, a failed recording); never raises.

    The datagram leaves from an ephemeral port on ``endpoints.host_ip`` (the configuration port
    may still be held by a link); no answer is awaited.

    Parameters
    ----------
    endpoints : Endpoints
        Where the DCA1000 is.

    Returns
    -------
    bool
        Whether the datagram was sent.
    """
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            try:
                sock.bind((endpoints.host_ip, 0))
            except OSError:
                pass
            sock.sendto(encode_command(Command.RECORD_STOP), (endpoints.fpga_ip, endpoints.config_port))
        return True
    except Exception:                                   # noqa: BLE001 - best effort by contract
        return False

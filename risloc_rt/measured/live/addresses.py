"""Where the DCA1000 and the host listen: IPv4 addresses and UDP ports of a live recording.

The DCA1000EVM's factory set-up (DCA1000EVM user's guide; TI's DCA1000 CLI JSON defaults) is the
host at 192.168.33.30 and the FPGA at 192.168.33.180, the configuration port 4096 on both sides
and the data port 4098 on the host. These are only the documented defaults of a user's own bench:
tests, benchmarks and emulators use :meth:`Endpoints.loopback` (the host side 127.0.0.1, the
emulated DCA1000 127.0.0.2; the whole 127.0.0.0/8 is local on Linux) and never send elsewhere.
"""

from __future__ import annotations

import ipaddress
from dataclasses import dataclass

from ..errors import MeasuredFormatError

__all__ = ["CONFIG_PORT", "DATA_PORT", "DEFAULT_FPGA_IP", "DEFAULT_HOST_IP", "Endpoints",
           "LOOPBACK_FPGA_IP", "LOOPBACK_HOST_IP"]

#: The host's address on a DCA1000 bench (the DCA1000EVM's factory set-up).
DEFAULT_HOST_IP = "192.168.33.30"
#: The DCA1000 FPGA's factory address.
DEFAULT_FPGA_IP = "192.168.33.180"
#: UDP port of the configuration commands, on the host and on the FPGA.
CONFIG_PORT = 4096
#: UDP port the host receives the ADC data stream on.
DATA_PORT = 4098
#: The host side of a loopback bench (tests, emulators).
LOOPBACK_HOST_IP = "127.0.0.1"
#: The emulated DCA1000 of a loopback bench.
LOOPBACK_FPGA_IP = "127.0.0.2"


def _ipv4(text: str, option: str) -> str:
    try:
        return str(ipaddress.IPv4Address(text))
    except ValueError:
        raise MeasuredFormatError(f"{option} {text!r} is not an IPv4 address: give four numbers 0-255 "
                                  f"separated by dots, e.g. {DEFAULT_HOST_IP}") from None


def _port(value: int, option: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= 65535:
        raise MeasuredFormatError(f"{option} {value!r} is not a UDP port: give an integer 1-65535")
    return value


@dataclass(frozen=True)
class Endpoints:
    """The two ends of a DCA1000 link.

    Parameters
    ----------
    host_ip : str, default :data:`DEFAULT_HOST_IP`
        The address this computer receives on (its Ethernet port wired to the DCA1000).
    fpga_ip : str, default :data:`DEFAULT_FPGA_IP`
        The DCA1000's address.
    config_port : int, default :data:`CONFIG_PORT`
        UDP port of the configuration commands (both sides).
    data_port : int, default :data:`DATA_PORT`
        UDP port of the data stream on the host.

    Raises
    ------
    MeasuredFormatError
        An address that is not IPv4 or a port outside 1-65535 (one line, naming the option).
    """

    host_ip: str = DEFAULT_HOST_IP
    fpga_ip: str = DEFAULT_FPGA_IP
    config_port: int = CONFIG_PORT
    data_port: int = DATA_PORT

    def __post_init__(self):
        object.__setattr__(self, "host_ip", _ipv4(self.host_ip, "--host-ip"))
        object.__setattr__(self, "fpga_ip", _ipv4(self.fpga_ip, "--fpga-ip"))
        _port(self.config_port, "config port")
        _port(self.data_port, "data port")
        if self.host_ip == self.fpga_ip:
            raise MeasuredFormatError(f"--host-ip and --fpga-ip are both {self.host_ip}: the DCA1000 and this "
                                      "computer need addresses of their own")

    @classmethod
    def loopback(cls, config_port: int = CONFIG_PORT, data_port: int = DATA_PORT) -> "Endpoints":
        """The loopback bench of the tests and emulators: host 127.0.0.1, DCA1000 127.0.0.2.

        Parameters
        ----------
        config_port : int, default :data:`CONFIG_PORT`
            Configuration port (a free port when the real one is taken).
        data_port : int, default :data:`DATA_PORT`
            Data port.

        Returns
        -------
        Endpoints
            Both ends on the loopback range.
        """
        return cls(LOOPBACK_HOST_IP, LOOPBACK_FPGA_IP, config_port, data_port)

    @property
    def is_loopback(self) -> bool:
        """Whether both ends are on 127.0.0.0/8 (nothing leaves this computer)."""
        return all(ipaddress.IPv4Address(a).is_loopback for a in (self.host_ip, self.fpga_ip))

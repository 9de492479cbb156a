"""Live recording from a TI radar and a DCA1000 on Linux, without mmWave Studio.

Room 6 of :mod:`risloc_rt.measured` (imports :mod:`..errors`, :mod:`..ti`, :mod:`..dca1000`,
:mod:`..sweep`):

- :mod:`.addresses`: :class:`Endpoints`, the DCA1000's and the host's addresses and UDP ports.
"""

from .addresses import (CONFIG_PORT, DATA_PORT, DEFAULT_FPGA_IP, DEFAULT_HOST_IP, LOOPBACK_FPGA_IP,
                        LOOPBACK_HOST_IP, Endpoints)

__all__ = ["CONFIG_PORT", "DATA_PORT", "DEFAULT_FPGA_IP", "DEFAULT_HOST_IP", "Endpoints", "LOOPBACK_FPGA_IP",
           "LOOPBACK_HOST_IP"]

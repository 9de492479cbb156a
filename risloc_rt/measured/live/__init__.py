"""Live recording from a TI radar and a DCA1000 on Linux, without mmWave Studio (``docs/live-capture.md``).

Room 6 of :mod:`risloc_rt.measured` (imports :mod:`..errors`, :mod:`..ti`, :mod:`..dca1000`,
:mod:`..sweep`, and ``io`` for the localization of a live sweep; ``pyserial`` only when a port is opened):

- :mod:`.addresses`: :class:`Endpoints`, the DCA1000's and the host's addresses and UDP ports;
- :mod:`.radar_cli`: :class:`RadarCli`, the radar's CLI port (a ``.cfg`` sent line by line);
- :mod:`.dca1000_link`: :class:`Dca1000Link`, the DCA1000's configuration link over UDP;
- :mod:`.receiver`: :class:`DatagramReceiver`, a thread that only receives the data stream;
- :mod:`.recording_writer`: :class:`RecordingWriter`, the raw files written in place, lost packets zero-filled;
- :mod:`.record`: :func:`record`, the whole session (radar, DCA1000, receiver, writer, progress, stop);
- :mod:`.live_sweeps`: the sweeps of a recording in progress, each localized as soon as it is complete.
"""

from .addresses import (CONFIG_PORT, DATA_PORT, DEFAULT_FPGA_IP, DEFAULT_HOST_IP, LOOPBACK_FPGA_IP,
                        LOOPBACK_HOST_IP, Endpoints)
from .dca1000_link import Dca1000Error, Dca1000Link
from .live_sweeps import FusedLiveFix, LiveFix, SweepWatcher
from .radar_cli import RadarCli, RadarCliError
from .receiver import DatagramReceiver, ReceiverStats
from .record import RecordingError, RecordingProgress, RecordingSummary, RecordPlan, record
from .recording_writer import RecordingWriter

__all__ = ["CONFIG_PORT", "DATA_PORT", "DEFAULT_FPGA_IP", "DEFAULT_HOST_IP", "Endpoints", "LOOPBACK_FPGA_IP",
           "LOOPBACK_HOST_IP", "Dca1000Error", "Dca1000Link", "RadarCli", "RadarCliError", "DatagramReceiver",
           "ReceiverStats", "RecordPlan", "RecordingError", "RecordingProgress", "RecordingSummary", "RecordingWriter",
           "record", "FusedLiveFix", "LiveFix", "SweepWatcher"]

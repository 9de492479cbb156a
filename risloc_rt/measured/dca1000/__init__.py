"""DCA1000 raw ADC data: byte layouts, split files, the packet-recorded form, the streaming reader, inspection.

Room 2 of :mod:`risloc_rt.measured` (imports :mod:`..ti` and :mod:`..errors`):

- :mod:`.raw_layout`: :class:`RawLayout`, one frame's int16 words ↔ the cube ``[F, K, V, N]``;
- :mod:`.split_files`: ``<prefix>_Raw_<i>.bin`` files found, read and written as one stream;
- :mod:`.packets`: the packet-recorded form (10-byte headers, lost packets zero-filled);
- :mod:`.zero_packets`: probable lost packets of a raw-mode stream (whole packets of zeros);
- :mod:`.reader`: :func:`open_raw`, :func:`iter_frames`, :func:`read_raw`;
- :mod:`.channels`: virtual channels ``[F, K, V, N]`` → ``[F, K, N]`` (one, or combined);
- :mod:`.inspection`: :func:`inspect_capture` (peak, lost packets, clipping, DC, I/Q) and its figure;
- :mod:`.control`: the DCA1000's configuration protocol (commands, responses, FPGA and packet settings).
"""

from .channels import combine_channels, mrc_weights
from .control import Command, FpgaConfig, FpgaVersion, PacketConfig, Response, decode_response, encode_command
from .inspection import CaptureInspection, Peak, file_iq_swap, inspect_capture, plot_inspection
from .packets import DroppedPackets, PacketIssue, PacketRecorder, detect_payload_size, pack_header
from .raw_layout import Convention, RawLayout, decode_frames, encode_frames
from .reader import CaptureInfo, FrameBlock, RawCapture, iter_frames, open_raw, read_raw
from .split_files import SplitWriter, capture_files

__all__ = [
    "Command", "FpgaConfig", "FpgaVersion", "PacketConfig", "Response", "decode_response", "encode_command",
    "CaptureInfo", "CaptureInspection", "Convention", "DroppedPackets", "FrameBlock", "PacketIssue", "PacketRecorder",
    "Peak", "RawCapture", "RawLayout", "SplitWriter", "capture_files", "combine_channels", "decode_frames",
    "detect_payload_size", "encode_frames", "file_iq_swap", "inspect_capture", "iter_frames", "mrc_weights", "open_raw",
    "pack_header", "plot_inspection", "read_raw",
]

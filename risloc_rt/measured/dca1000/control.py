"""The DCA1000EVM's configuration protocol: command and response packets, their payloads (pure, no sockets).

Sources (the vendor's): the *DCA1000EVM Data Capture Card User's Guide* (TI SPRUIJ4A), section 5
("DCA1000EVM ... UDP protocol": 14 predefined commands on the configuration port, answered on the
same port), and TI's DCA1000 CLI source shipped with mmWave Studio
(``ReferenceCode/DCA1000/SourceCode``): ``Common/rf_api.h`` (command codes, enumerations, the
request and response structures), ``RF_API/rf_api.cpp`` (how each payload is filled),
``RF_API/defines.h`` (packet size, clock and version constants), ``RF_API/configdatarecv.cpp``
(the asynchronous status packets), ``Common/globals.h`` (packet-delay limits, the FPGA timer).
``docs/dca1000-link.md`` has the tables.

Every field is little-endian (the CLI ``memcpy``\\ s packed structures on x86)::

    command:   A55A header u16 | command code u16 | payload size u16 | payload | EEAA footer u16
    response:  A55A header u16 | command code u16 | status u16       | EEAA footer u16

so the SYSTEM_CONNECT command is the 8 bytes ``5A A5 09 00 00 00 AA EE``. A status of 0 is
success, except READ_FPGA_VERSION, whose status word *is* the version, and the asynchronous
SYSTEM_ERROR packets (code 0x0A) the FPGA sends unasked, whose status is a bit set of
:class:`AsyncStatus`.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Literal

from ..errors import MeasuredFormatError
from ..ti.chirp_config import TiChirpConfig

__all__ = ["ASYNC_STATUS_TEXT", "FPGA_CLOCK_PERIOD", "FPGA_TIMER", "FOOTER", "HEADER", "MAX_COMMAND_PAYLOAD",
           "MAX_PACKET_DELAY", "MIN_PACKET_DELAY", "PACKET_SIZE", "RESPONSE_BYTES", "AsyncStatus", "Command",
           "CommandPacket", "FpgaConfig", "FpgaVersion", "PacketConfig", "Response", "async_status_word",
           "decode_async_status", "decode_command", "decode_response", "encode_command", "encode_response"]

#: Header of every command and response (``rf_api.h`` HEADER_START_BYTES); bytes ``5A A5`` on the wire.
HEADER = 0xA55A
#: Footer of every command and response (``rf_api.h`` FOOTER_STOP_BYTES); bytes ``AA EE`` on the wire.
FOOTER = 0xEEAA
#: Largest command payload [bytes] (``rf_api.h`` MAX_DATA_BYTES).
MAX_COMMAND_PAYLOAD = 504
#: Length of a response packet [bytes] (``rf_api.h`` DATA_CAPTURE_RESP: four u16).
RESPONSE_BYTES = 8
#: The packet size the DCA1000 CLI always sends in CONFIG_PACKET_DATA [bytes] (``defines.h`` MAX_BYTES_PER_PACKET).
PACKET_SIZE = 1470
#: Period of the FPGA clock that counts the inter-packet delay [s] (``defines.h`` FPGA_CLK_PERIOD_IN_NANO_SEC = 8).
FPGA_CLOCK_PERIOD = 8e-9
#: Shortest inter-packet delay the CLI accepts [s] (``globals.h`` MIN_RECORD_DELAY = 5 µs).
MIN_PACKET_DELAY = 5e-6
#: Longest inter-packet delay the CLI accepts [s] (``globals.h`` MAX_RECORD_DELAY = 500 µs).
MAX_PACKET_DELAY = 500e-6
#: The LVDS timer the CLI always sends in CONFIG_FPGA_GEN (``globals.h`` FPGA_CONFIG_DEFAULT_TIMER = 30).
FPGA_TIMER = 30

_VERSION_BITS, _VERSION_SHIFT, _PLAYBACK_BIT = 0x7F, 7, 0x4000      # defines.h VERSION_*, PLAYBACK_BIT_DECODE


class Command(enum.IntEnum):
    """Command codes of the configuration port (user's guide section 5; ``rf_api.h`` ``CMD_CODE_*``).

    The names are the user's guide's (``*_CMD_CODE``); ``rf_api.h`` calls 0x09 SYSTEM_ALIVENESS,
    0x0A SYSTEM_ASYNC_STATUS, 0x0B CONFIG_RECORD and 0x0C CONFIG_AR_DEV.
    """

    RESET_FPGA = 0x01
    RESET_AR_DEVICE = 0x02
    CONFIG_FPGA_GEN = 0x03
    CONFIG_EEPROM = 0x04
    RECORD_START = 0x05
    RECORD_STOP = 0x06
    PLAYBACK_START = 0x07
    PLAYBACK_STOP = 0x08
    SYSTEM_CONNECT = 0x09
    SYSTEM_ERROR = 0x0A
    CONFIG_PACKET_DATA = 0x0B
    CONFIG_DATA_MODE_AR_DEV = 0x0C
    INIT_FPGA_PLAYBACK = 0x0D
    READ_FPGA_VERSION = 0x0E


class AsyncStatus(enum.IntEnum):
    """Bits of an asynchronous SYSTEM_ERROR status word (``rf_api.h`` ``enum SYS_ASYNC_STATUS``).

    The FPGA sends ``A55A | 0x000A | status | EEAA`` on the configuration port unasked; bit ``i``
    of the status set means the condition with value ``i`` (``configdatarecv.cpp`` tests the 16 bits
    one by one).
    """

    NO_LVDS_DATA = 0
    NO_HEADER = 1
    EEPROM_FAILURE = 2
    SD_CARD_DETECTED = 3
    SD_CARD_REMOVED = 4
    SD_CARD_FULL = 5
    MODE_CONFIG_FAILURE = 6
    DDR_FULL = 7
    RECORD_COMPLETED = 8
    LVDS_BUFFER_FULL = 9
    PLAYBACK_COMPLETED = 10
    PLAYBACK_OUT_OF_SEQUENCE = 11


#: What each asynchronous status means, for messages.
ASYNC_STATUS_TEXT: dict[AsyncStatus, str] = {
    AsyncStatus.NO_LVDS_DATA: "no LVDS data from the radar",
    AsyncStatus.NO_HEADER: "LVDS data without a header",
    AsyncStatus.EEPROM_FAILURE: "EEPROM failure",
    AsyncStatus.SD_CARD_DETECTED: "SD card detected",
    AsyncStatus.SD_CARD_REMOVED: "SD card removed",
    AsyncStatus.SD_CARD_FULL: "SD card full",
    AsyncStatus.MODE_CONFIG_FAILURE: "mode configuration failed",
    AsyncStatus.DDR_FULL: "FPGA DDR buffer full",
    AsyncStatus.RECORD_COMPLETED: "record completed",
    AsyncStatus.LVDS_BUFFER_FULL: "LVDS buffer full",
    AsyncStatus.PLAYBACK_COMPLETED: "playback completed",
    AsyncStatus.PLAYBACK_OUT_OF_SEQUENCE: "playback out of sequence",
}


def _hex(data: bytes) -> str:
    return " ".join(f"{b:02X}" for b in data)


def _u16(data: bytes, at: int) -> int:
    return int.from_bytes(data[at:at + 2], "little")


def _command_name(code: int) -> str:
    try:
        return Command(code).name
    except ValueError:
        return f"0x{code:04X}"


def encode_command(command: Command | int, payload: bytes = b"") -> bytes:
    """The bytes of a command packet: ``A55A | code | size | payload | EEAA``, little-endian.

    Parameters
    ----------
    command : Command or int
        The command code (0x01-0x0E).
    payload : bytes, default empty
        The command's data (at most :data:`MAX_COMMAND_PAYLOAD` bytes).

    Returns
    -------
    bytes
        ``8 + len(payload)`` bytes.
    """
    command = Command(command)
    payload = bytes(payload)
    if len(payload) > MAX_COMMAND_PAYLOAD:
        raise MeasuredFormatError(f"{command.name} payload of {len(payload)} bytes is longer than the DCA1000's "
                                  f"{MAX_COMMAND_PAYLOAD}-byte limit (rf_api.h MAX_DATA_BYTES)")
    return (HEADER.to_bytes(2, "little") + int(command).to_bytes(2, "little") + len(payload).to_bytes(2, "little")
            + payload + FOOTER.to_bytes(2, "little"))


@dataclass(frozen=True)
class CommandPacket:
    """A decoded command packet.

    Attributes
    ----------
    command : Command
        Its code.
    payload : bytes
        Its data (empty for most commands).
    """

    command: Command
    payload: bytes = b""


def _check_header(data: bytes, what: str) -> None:
    if len(data) < 2 or _u16(data, 0) != HEADER:
        raise MeasuredFormatError(f"{what} bytes 0-1 are {_hex(data[:2]) or 'missing'}, not the header 5A A5 "
                                  f"(0xA55A): not a DCA1000 configuration packet ({_hex(data[:16])})")


def decode_command(data: bytes) -> CommandPacket:
    """A command packet from its bytes; a malformed one is a one-line error naming the wrong byte.

    Parameters
    ----------
    data : bytes
        One UDP datagram received on the configuration port.

    Returns
    -------
    CommandPacket
        The command and its payload.
    """
    data = bytes(data)
    what = f"DCA1000 command packet ({len(data)} bytes)"
    _check_header(data, what)
    if len(data) < 8:
        raise MeasuredFormatError(f"{what} ends at byte {len(data)}: a command packet has at least 8 bytes "
                                  "(header, code, size, footer)")
    code = _u16(data, 2)
    if code not in Command._value2member_map_:
        raise MeasuredFormatError(f"{what} bytes 2-3 ({_hex(data[2:4])}) are command code 0x{code:04X}, which the "
                                  "DCA1000 does not have (codes 0x01-0x0E)")
    size = _u16(data, 4)
    if len(data) != 8 + size:
        raise MeasuredFormatError(f"{what} bytes 4-5 ({_hex(data[4:6])}) announce a {size}-byte payload, so "
                                  f"{8 + size} bytes in all, but the packet has {len(data)}")
    if _u16(data, 6 + size) != FOOTER:
        raise MeasuredFormatError(f"{what} bytes {6 + size}-{7 + size} are {_hex(data[6 + size:])}, not the "
                                  "footer AA EE (0xEEAA)")
    return CommandPacket(Command(code), data[6:6 + size])


@dataclass(frozen=True)
class Response:
    """A decoded response (or asynchronous status) packet.

    Attributes
    ----------
    command : Command
        The command answered (SYSTEM_ERROR for an asynchronous status).
    status : int
        The u16 status word: 0 for success, the version word for READ_FPGA_VERSION, a bit set of
        :class:`AsyncStatus` for SYSTEM_ERROR.
    """

    command: Command
    status: int

    @property
    def ok(self) -> bool:
        """Whether the status means success (READ_FPGA_VERSION always answers with its version)."""
        return self.command == Command.READ_FPGA_VERSION or self.status == 0


def encode_response(command: Command | int, status: int = 0) -> bytes:
    """The 8 bytes of a response: ``A55A | code | status | EEAA``, little-endian.

    Parameters
    ----------
    command : Command or int
        The command answered.
    status : int, default 0
        Status word (0-0xFFFF).

    Returns
    -------
    bytes
        :data:`RESPONSE_BYTES` bytes.
    """
    command = Command(command)
    if not 0 <= int(status) <= 0xFFFF:
        raise MeasuredFormatError(f"status {status} of {command.name} does not fit the response's u16 (0-65535)")
    return (HEADER.to_bytes(2, "little") + int(command).to_bytes(2, "little") + int(status).to_bytes(2, "little")
            + FOOTER.to_bytes(2, "little"))


def decode_response(data: bytes) -> Response:
    """A response packet from its 8 bytes; a malformed one is a one-line error naming the wrong byte.

    Parameters
    ----------
    data : bytes
        One UDP datagram received from the DCA1000's configuration port.

    Returns
    -------
    Response
        The command answered and its status.
    """
    data = bytes(data)
    what = f"DCA1000 response ({len(data)} bytes)"
    _check_header(data, what)
    if len(data) != RESPONSE_BYTES:
        raise MeasuredFormatError(f"{what} has {len(data)} bytes where a response has {RESPONSE_BYTES} "
                                  f"(header, code, status, footer): {_hex(data[:16])}")
    code = _u16(data, 2)
    if code not in Command._value2member_map_:
        raise MeasuredFormatError(f"{what} bytes 2-3 ({_hex(data[2:4])}) are command code 0x{code:04X}, which the "
                                  "DCA1000 does not have (codes 0x01-0x0E)")
    if _u16(data, 6) != FOOTER:
        raise MeasuredFormatError(f"{what} bytes 6-7 are {_hex(data[6:8])}, not the footer AA EE (0xEEAA)")
    return Response(Command(code), _u16(data, 4))


def decode_async_status(status: int) -> tuple[AsyncStatus, ...]:
    """The conditions set in an asynchronous SYSTEM_ERROR status word.

    Parameters
    ----------
    status : int
        The u16 status of a SYSTEM_ERROR packet.

    Returns
    -------
    tuple of AsyncStatus
        The documented bits set, lowest first (undocumented bits are left out).
    """
    return tuple(s for s in AsyncStatus if status >> int(s) & 1)


def async_status_word(*conditions: AsyncStatus) -> int:
    """The status word of an asynchronous SYSTEM_ERROR packet reporting ``conditions``.

    Parameters
    ----------
    *conditions : AsyncStatus
        The conditions to set.

    Returns
    -------
    int
        The u16 bit set.
    """
    word = 0
    for c in conditions:
        word |= 1 << int(AsyncStatus(c))
    return word


LoggingMode = Literal["raw", "multi"]
TransferMode = Literal["capture", "playback"]
CaptureMode = Literal["ethernet", "sd_card"]

# rf_api.h enumerations: CONFIG_LOG_MODE, CONFIG_LVDS_MODE, CONFIG_TRANSFER_MODE, CONFIG_CAPTURE_MODE, CONFIG_FORMAT_MODE
_LOG = {"raw": 1, "multi": 2}
_LANES = {4: 1, 2: 2}
_TRANSFER = {"capture": 1, "playback": 2}
_CAPTURE = {"sd_card": 1, "ethernet": 2}
_FORMAT = {12: 1, 14: 2, 16: 3}


@dataclass(frozen=True)
class FpgaConfig:
    """The CONFIG_FPGA_GEN settings (``rf_api.h`` ``strFpgaConfigMode``), six one-byte fields.

    Parameters
    ----------
    lanes : {2, 4}, default 2
        LVDS lanes: 2 for xWR16xx/18xx/68xx, 4 for xWR12xx/14xx (byte 1: 1 = four, 2 = two).
    data_bits : {12, 14, 16}, default 16
        ADC data format, the ``.cfg``'s ``adcCfg`` numADCBits (byte 4: 1/2/3).
    logging_mode : {"raw", "multi"}, default "raw"
        Raw mode (one data stream, what risloc records) or multi mode (byte 0: 1/2).
    transfer_mode : {"capture", "playback"}, default "capture"
        LVDS capture or playback (byte 2: 1/2).
    capture_mode : {"ethernet", "sd_card"}, default "ethernet"
        Stream over Ethernet or store on the SD card (byte 3: 2/1).
    timeout : int, default :data:`FPGA_TIMER`
        The FPGA's LVDS timer (byte 5; ``rf_api.h``: "Timeout value for LVDS data"); the CLI always
        sends 30. Taken as seconds [s]; the sources give no unit.
    """

    lanes: int = 2
    data_bits: int = 16
    logging_mode: LoggingMode = "raw"
    transfer_mode: TransferMode = "capture"
    capture_mode: CaptureMode = "ethernet"
    timeout: int = FPGA_TIMER

    def __post_init__(self) -> None:
        checks = (("lanes", self.lanes, _LANES, "2 (xWR16xx/18xx/68xx) or 4 (xWR12xx/14xx)"),
                  ("data_bits", self.data_bits, _FORMAT, "12, 14 or 16 (adcCfg numADCBits 0/1/2)"),
                  ("logging_mode", self.logging_mode, _LOG, "'raw' or 'multi'"),
                  ("transfer_mode", self.transfer_mode, _TRANSFER, "'capture' or 'playback'"),
                  ("capture_mode", self.capture_mode, _CAPTURE, "'ethernet' or 'sd_card'"))
        for name, value, table, allowed in checks:
            if isinstance(value, bool) or value not in table:
                raise MeasuredFormatError(f"FpgaConfig {name}={value!r}: the DCA1000 takes {allowed}")
        if isinstance(self.timeout, bool) or not isinstance(self.timeout, int) or not 0 <= self.timeout <= 255:
            raise MeasuredFormatError(f"FpgaConfig timeout={self.timeout!r} must be an integer 0-255 s (one byte)")

    @classmethod
    def from_chirp_config(cls, config: TiChirpConfig, lanes: int, *, logging_mode: LoggingMode = "raw",
                          timeout: int = FPGA_TIMER) -> "FpgaConfig":
        """The FPGA settings of a capture of ``config`` (a parsed ``.cfg``): data format from ``adcCfg``.

        Parameters
        ----------
        config : TiChirpConfig
            The radar configuration (:func:`risloc_rt.measured.ti.sdk_cfg.read_sdk_cfg`).
        lanes : {2, 4}
            The device family's LVDS lane count.
        logging_mode : {"raw", "multi"}, default "raw"
            Logging mode.
        timeout : int, default :data:`FPGA_TIMER`
            LVDS timer [s].

        Returns
        -------
        FpgaConfig
            Ethernet-streamed LVDS capture with the configuration's ADC bits.
        """
        return cls(lanes=lanes, data_bits=config.adc_bits, logging_mode=logging_mode, timeout=timeout)

    def payload(self) -> bytes:
        """The six payload bytes: log mode, LVDS mode, transfer mode, capture mode, format, timer.

        Returns
        -------
        bytes
            6 bytes, e.g. ``01 02 01 02 03 1E`` for a raw 2-lane 16-bit Ethernet capture.
        """
        return bytes([_LOG[self.logging_mode], _LANES[self.lanes], _TRANSFER[self.transfer_mode],
                      _CAPTURE[self.capture_mode], _FORMAT[self.data_bits], self.timeout])

    @classmethod
    def from_payload(cls, payload: bytes) -> "FpgaConfig":
        """The settings a CONFIG_FPGA_GEN payload asks for; a wrong byte is a one-line error naming it.

        Parameters
        ----------
        payload : bytes
            The command's 6 payload bytes.

        Returns
        -------
        FpgaConfig
        """
        payload = bytes(payload)
        if len(payload) != 6:
            raise MeasuredFormatError(f"CONFIG_FPGA_GEN payload has {len(payload)} bytes ({_hex(payload)}); it has 6")
        fields = []
        for i, (name, table) in enumerate((("logging mode", _LOG), ("LVDS mode", _LANES),
                                            ("transfer mode", _TRANSFER), ("capture mode", _CAPTURE),
                                            ("data format", _FORMAT))):
            inverse = {code: value for value, code in table.items()}
            if payload[i] not in inverse:
                raise MeasuredFormatError(f"CONFIG_FPGA_GEN payload byte {i} ({name}) is {payload[i]}, not one of "
                                          f"{sorted(inverse)} (rf_api.h)")
            fields.append(inverse[payload[i]])
        log, lanes, transfer, capture, bits = fields
        return cls(lanes=lanes, data_bits=bits, logging_mode=log, transfer_mode=transfer, capture_mode=capture,
                   timeout=payload[5])


@dataclass(frozen=True)
class PacketConfig:
    """The CONFIG_PACKET_DATA settings: data packet size and inter-packet delay (``rf_api.cpp`` ConfigureRFDCCard_Record).

    Payload: three little-endian u16: the packet size [bytes], the delay in FPGA clock cycles of
    :data:`FPGA_CLOCK_PERIOD` (8 ns: the CLI sends ``delay_us · 1000 / 8``), and 0.

    Parameters
    ----------
    packet_size : int, default :data:`PACKET_SIZE`
        Largest data packet [bytes]; the CLI always sends 1470.
    delay : float, default 25e-6
        Pause between two data packets [s], :data:`MIN_PACKET_DELAY` to :data:`MAX_PACKET_DELAY`
        (TI's CLI JSON ``packetDelay_us``, 25 µs in its example); a whole number of 8 ns cycles.
    """

    packet_size: int = PACKET_SIZE
    delay: float = 25e-6

    def __post_init__(self) -> None:
        if isinstance(self.packet_size, bool) or not isinstance(self.packet_size, int) \
                or not 16 <= self.packet_size <= PACKET_SIZE:
            raise MeasuredFormatError(f"PacketConfig packet_size={self.packet_size!r} must be an integer 16-"
                                      f"{PACKET_SIZE} bytes (the DCA1000 CLI sends {PACKET_SIZE})")
        delay = float(self.delay)
        if not MIN_PACKET_DELAY * (1 - 1e-9) <= delay <= MAX_PACKET_DELAY * (1 + 1e-9):
            raise MeasuredFormatError(f"PacketConfig delay={self.delay!r} s is outside the DCA1000's "
                                      f"{MIN_PACKET_DELAY * 1e6:g}-{MAX_PACKET_DELAY * 1e6:g} µs (TI CLI "
                                      "MIN/MAX_RECORD_DELAY): give the delay in seconds, e.g. 25e-6")
        object.__setattr__(self, "delay", self.delay_cycles * FPGA_CLOCK_PERIOD)

    @property
    def delay_cycles(self) -> int:
        """The delay in 8 ns FPGA clock cycles, the payload's second word."""
        return int(round(float(self.delay) / FPGA_CLOCK_PERIOD))

    def payload(self) -> bytes:
        """The six payload bytes: packet size, delay cycles, 0 (u16 each, little-endian).

        Returns
        -------
        bytes
            6 bytes, e.g. ``BE 05 35 0C 00 00`` for 1470 bytes and 25 µs.
        """
        return (self.packet_size.to_bytes(2, "little") + self.delay_cycles.to_bytes(2, "little")
                + (0).to_bytes(2, "little"))

    @classmethod
    def from_payload(cls, payload: bytes) -> "PacketConfig":
        """The settings a CONFIG_PACKET_DATA payload asks for; a wrong field is a one-line error naming its bytes.

        Parameters
        ----------
        payload : bytes
            The command's 6 payload bytes.

        Returns
        -------
        PacketConfig
        """
        payload = bytes(payload)
        if len(payload) != 6:
            raise MeasuredFormatError(f"CONFIG_PACKET_DATA payload has {len(payload)} bytes ({_hex(payload)}); "
                                      "it has 6")
        if _u16(payload, 4) != 0:
            raise MeasuredFormatError(f"CONFIG_PACKET_DATA payload bytes 4-5 are {_hex(payload[4:6])}, not the "
                                      "reserved 00 00")
        cycles = _u16(payload, 2)
        delay = cycles * FPGA_CLOCK_PERIOD
        if not MIN_PACKET_DELAY * (1 - 1e-9) <= delay <= MAX_PACKET_DELAY * (1 + 1e-9):
            raise MeasuredFormatError(f"CONFIG_PACKET_DATA payload bytes 2-3 ({_hex(payload[2:4])}) ask for "
                                      f"{cycles} cycles = {delay * 1e6:g} µs, outside 5-500 µs")
        size = _u16(payload, 0)
        if not 16 <= size <= PACKET_SIZE:
            raise MeasuredFormatError(f"CONFIG_PACKET_DATA payload bytes 0-1 ({_hex(payload[0:2])}) ask for "
                                      f"{size}-byte packets, outside 16-{PACKET_SIZE}")
        return cls(packet_size=size, delay=delay)


@dataclass(frozen=True)
class FpgaVersion:
    """The FPGA firmware version, decoded from READ_FPGA_VERSION's status word (``rf_api.cpp``).

    Bits 0-6 are the major version, bits 7-13 the minor, bit 14 set means a playback bitfile
    (``defines.h`` VERSION_BITS_DECODE 0x7F, VERSION_NUM_OF_BITS 7, PLAYBACK_BIT_DECODE 0x4000).

    Attributes
    ----------
    major : int
        0-127.
    minor : int
        0-127.
    playback : bool
        The FPGA runs the playback bitfile (it cannot record).
    """

    major: int
    minor: int
    playback: bool = False

    def __post_init__(self) -> None:
        for name in ("major", "minor"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or not 0 <= v <= _VERSION_BITS:
                raise MeasuredFormatError(f"FpgaVersion {name}={v!r} must be an integer 0-127 (7 bits)")
        object.__setattr__(self, "playback", bool(self.playback))

    @classmethod
    def from_status(cls, status: int) -> "FpgaVersion":
        """The version in a READ_FPGA_VERSION status word.

        Parameters
        ----------
        status : int
            The response's u16 status.

        Returns
        -------
        FpgaVersion
        """
        return cls(status & _VERSION_BITS, status >> _VERSION_SHIFT & _VERSION_BITS, bool(status & _PLAYBACK_BIT))

    def status(self) -> int:
        """The status word that encodes this version (what the FPGA answers).

        Returns
        -------
        int
            u16.
        """
        return self.major | self.minor << _VERSION_SHIFT | (_PLAYBACK_BIT if self.playback else 0)

    def __str__(self) -> str:
        return f"{self.major}.{self.minor} [{'Playback' if self.playback else 'Record'}]"

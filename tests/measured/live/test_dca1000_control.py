"""The DCA1000 configuration protocol against the vendor's documents, byte for byte.

Expected bytes are written out here from TI's documents, not from our encoder:

- *DCA1000EVM Data Capture Card User's Guide* (SPRUIJ4A), section 5: a command is ``header | command
  code | data size | data | footer``, a response ``header | command code | status | footer``;
- TI's DCA1000 CLI source (mmWave Studio ``ReferenceCode/DCA1000/SourceCode``): ``rf_api.h``
  (``HEADER_START_BYTES 0xA55A``, ``FOOTER_STOP_BYTES 0xEEAA``, ``CMD_CODE_*`` 0x01-0x0E, the enums
  ``RAW_MODE=1 MULTI_MODE``, ``FOUR_LANE=1 TWO_LANE``, ``CAPTURE=1 PLAYBACK``, ``SD_STORAGE=1
  ETH_STREAM``, ``BIT12=1 BIT14 BIT16``, ``enum SYS_ASYNC_STATUS``), ``rf_api.cpp``
  (``ConfigureRFDCCard_Fpga``: six u8; ``ConfigureRFDCCard_Record``: u16 ``MAX_BYTES_PER_PACKET``, u16
  ``delay_us * 1000 / 8``, u16 0; ``ReadRFDCCard_FpgaVersion``: major = status & 0x7F, minor = status
  >> 7 & 0x7F, playback bit 0x4000), ``defines.h`` (``MAX_BYTES_PER_PACKET 1470``,
  ``FPGA_CLK_PERIOD_IN_NANO_SEC 8``), ``globals.h`` (``FPGA_CONFIG_DEFAULT_TIMER 30``,
  ``MIN/MAX_RECORD_DELAY 5/500``).

The test-side decoder below (:func:`ref_command`, :func:`ref_response`) imports nothing from
``risloc_rt``; it checks the encoder's output and decodes the emulator's answers on loopback.
"""

from __future__ import annotations

import itertools
import socket
import struct

import pytest

from risloc_rt.measured.dca1000.control import (AsyncStatus, Command, FpgaConfig, FpgaVersion, PacketConfig,
                                                Response, async_status_word, decode_async_status, decode_command,
                                                decode_response, encode_command, encode_response)
from risloc_rt.measured.emulate.dca1000_server import EmulatedDca1000
from risloc_rt.measured.errors import MeasuredFormatError
from risloc_rt.measured.ti.sdk_cfg import parse_sdk_cfg

# rf_api.h CMD_CODE_* (names as in the user's guide's command table)
VENDOR_CODES = {
    "RESET_FPGA": 0x01, "RESET_AR_DEVICE": 0x02, "CONFIG_FPGA_GEN": 0x03, "CONFIG_EEPROM": 0x04,
    "RECORD_START": 0x05, "RECORD_STOP": 0x06, "PLAYBACK_START": 0x07, "PLAYBACK_STOP": 0x08,
    "SYSTEM_CONNECT": 0x09, "SYSTEM_ERROR": 0x0A, "CONFIG_PACKET_DATA": 0x0B, "CONFIG_DATA_MODE_AR_DEV": 0x0C,
    "INIT_FPGA_PLAYBACK": 0x0D, "READ_FPGA_VERSION": 0x0E,
}
# rf_api.h enum SYS_ASYNC_STATUS, in its order (value = bit index of the status word, configdatarecv.cpp)
VENDOR_ASYNC = ["NO_LVDS_DATA", "NO_HEADER", "EEPROM_FAILURE", "SD_CARD_DETECTED", "SD_CARD_REMOVED", "SD_CARD_FULL",
                "MODE_CONFIG_FAILURE", "DDR_FULL", "RECORD_COMPLETED", "LVDS_BUFFER_FULL", "PLAYBACK_COMPLETED",
                "PLAYBACK_OUT_OF_SEQUENCE"]


def ref_command(data: bytes) -> tuple[int, bytes]:
    """Test-side decoder of a command packet (user's guide section 5): (code, payload)."""
    header, code, size = struct.unpack_from("<HHH", data, 0)
    assert header == 0xA55A, data.hex(" ")
    assert len(data) == 8 + size, data.hex(" ")
    (footer,) = struct.unpack_from("<H", data, 6 + size)
    assert footer == 0xEEAA, data.hex(" ")
    return code, bytes(data[6:6 + size])


def ref_response(data: bytes) -> tuple[int, int]:
    """Test-side decoder of a response packet: (code, status)."""
    assert len(data) == 8, data.hex(" ")
    header, code, status, footer = struct.unpack("<HHHH", data)
    assert (header, footer) == (0xA55A, 0xEEAA), data.hex(" ")
    return code, status


def b(text: str) -> bytes:
    return bytes.fromhex(text)


# ---------------------------------------------------------------------------------------------- commands
def test_system_connect_is_the_documented_eight_bytes():
    assert encode_command(Command.SYSTEM_CONNECT) == b("5A A5 09 00 00 00 AA EE")


@pytest.mark.parametrize("name,code", sorted(VENDOR_CODES.items(), key=lambda kv: kv[1]))
def test_every_command_code_is_rf_api_h(name, code):
    assert Command[name] == code
    assert encode_command(Command[name]) == bytes([0x5A, 0xA5, code, 0x00, 0x00, 0x00, 0xAA, 0xEE])
    assert decode_command(bytes([0x5A, 0xA5, code, 0, 0, 0, 0xAA, 0xEE])).command == Command[name]


def test_there_are_exactly_the_fourteen_documented_commands():
    assert {c.name: int(c) for c in Command} == VENDOR_CODES


def test_config_fpga_gen_of_a_raw_two_lane_16_bit_ethernet_capture():
    # RAW_MODE=1, TWO_LANE=2, CAPTURE=1, ETH_STREAM=2, BIT16=3, FPGA_CONFIG_DEFAULT_TIMER=30=0x1E
    packet = encode_command(Command.CONFIG_FPGA_GEN, FpgaConfig(lanes=2, data_bits=16).payload())
    assert packet == b("5A A5 03 00 06 00 01 02 01 02 03 1E AA EE")


@pytest.mark.parametrize("lanes,bits,lvds_byte,format_byte", [(4, 12, 0x01, 0x01), (4, 14, 0x01, 0x02),
                                                               (2, 12, 0x02, 0x01), (2, 14, 0x02, 0x02),
                                                               (4, 16, 0x01, 0x03)])
def test_config_fpga_gen_lane_and_format_bytes(lanes, bits, lvds_byte, format_byte):
    assert FpgaConfig(lanes=lanes, data_bits=bits).payload() == bytes([0x01, lvds_byte, 0x01, 0x02, format_byte, 30])


def test_multi_mode_playback_sd_card_bytes():
    cfg = FpgaConfig(logging_mode="multi", transfer_mode="playback", capture_mode="sd_card", timeout=7)
    assert cfg.payload() == bytes([0x02, 0x02, 0x02, 0x01, 0x03, 0x07])


def test_fpga_payload_round_trips_every_combination():
    for lanes, bits, log, xfer, cap in itertools.product((2, 4), (12, 14, 16), ("raw", "multi"),
                                                         ("capture", "playback"), ("ethernet", "sd_card")):
        cfg = FpgaConfig(lanes=lanes, data_bits=bits, logging_mode=log, transfer_mode=xfer, capture_mode=cap)
        assert FpgaConfig.from_payload(cfg.payload()) == cfg


CFG = """\
sensorStop
flushCfg
dfeDataOutputMode 1
channelCfg 15 5 0
adcCfg {bits} 1
adcbufCfg -1 0 1 1 1
profileCfg 0 60.25 7 6 60 0 0 64.985 1 256 5000 0 0 30
chirpCfg 0 0 0 0 0 0 0 1
chirpCfg 1 1 0 0 0 0 0 4
frameCfg 0 1 32 8 40 1 0
sensorStart
"""


@pytest.mark.parametrize("code,bits,format_byte", [(0, 12, 0x01), (1, 14, 0x02), (2, 16, 0x03)])
def test_fpga_config_from_the_cfg_adc_bits(code, bits, format_byte):
    cfg = parse_sdk_cfg(CFG.format(bits=code)).config          # adcCfg numADCBits 0/1/2 = 12/14/16 bits
    fpga = FpgaConfig.from_chirp_config(cfg, lanes=2)
    assert fpga.data_bits == bits
    assert fpga.payload() == bytes([0x01, 0x02, 0x01, 0x02, format_byte, 0x1E])
    assert FpgaConfig.from_chirp_config(cfg, lanes=4).payload()[1] == 0x01


@pytest.mark.parametrize("kwargs,needle", [({"lanes": 3}, "lanes=3"), ({"data_bits": 10}, "data_bits=10"),
                                           ({"logging_mode": "Raw"}, "logging_mode"), ({"timeout": 256}, "0-255")])
def test_bad_fpga_settings_are_one_line(kwargs, needle):
    with pytest.raises(MeasuredFormatError, match=needle) as exc:
        FpgaConfig(**kwargs)
    assert "\n" not in str(exc.value)


@pytest.mark.parametrize("payload,needle", [("01 03 01 02 03 1E", "byte 1 (LVDS mode) is 3"),
                                            ("01 02 01 02 04 1E", "byte 4 (data format) is 4"),
                                            ("00 02 01 02 03 1E", "byte 0 (logging mode) is 0"),
                                            ("01 02 01 02 03", "has 5 bytes")])
def test_bad_fpga_payload_names_the_byte(payload, needle):
    with pytest.raises(MeasuredFormatError, match=needle.replace("(", r"\(").replace(")", r"\)")):
        FpgaConfig.from_payload(b(payload))


@pytest.mark.parametrize("delay,wire", [(25e-6, "BE 05 35 0C 00 00"),    # 25*1000/8 = 3125 = 0x0C35
                                        (20e-6, "BE 05 C4 09 00 00"),    # 2500 = 0x09C4
                                        (5e-6, "BE 05 71 02 00 00"),     # 625 = 0x0271
                                        (500e-6, "BE 05 24 F4 00 00")])  # 62500 = 0xF424
def test_config_packet_data_payload(delay, wire):
    cfg = PacketConfig(delay=delay)
    assert encode_command(Command.CONFIG_PACKET_DATA, cfg.payload()) == b("5A A5 0B 00 06 00") + b(wire) + b("AA EE")
    back = PacketConfig.from_payload(b(wire))
    assert back.packet_size == 1470
    assert back.delay == pytest.approx(delay, abs=1e-12)


@pytest.mark.parametrize("delay", [4e-6, 501e-6, 25.0])
def test_packet_delay_outside_the_cli_limits_is_refused(delay):
    with pytest.raises(MeasuredFormatError, match="5-500 µs") as exc:
        PacketConfig(delay=delay)
    assert "\n" not in str(exc.value)


def test_packet_payload_with_a_nonzero_reserved_word_names_bytes_4_5():
    with pytest.raises(MeasuredFormatError, match="bytes 4-5"):
        PacketConfig.from_payload(b("BE 05 35 0C 01 00"))


# ---------------------------------------------------------------------------------------------- malformed
@pytest.mark.parametrize("wire,needle", [
    ("5A A6 09 00 00 00 AA EE", "bytes 0-1 are 5A A6"),
    ("A5 5A 09 00 00 00 AA EE", "bytes 0-1 are A5 5A"),          # big-endian header
    ("5A A5 0F 00 00 00 AA EE", "bytes 2-3 (0F 00) are command code 0x000F"),
    ("5A A5 09 00 02 00 AA EE", "bytes 4-5 (02 00) announce a 2-byte payload"),
    ("5A A5 09 00 00 00 EE AA", "bytes 6-7 are EE AA"),
    ("5A A5 03 00 01 00 07 AA ED", "bytes 7-8 are AA ED"),
    ("5A A5 09", "ends at byte 3"),
    ("", "bytes 0-1 are missing"),
])
def test_a_malformed_command_is_one_line_naming_the_byte(wire, needle):
    with pytest.raises(MeasuredFormatError) as exc:
        decode_command(b(wire))
    assert needle in str(exc.value)
    assert "\n" not in str(exc.value)


@pytest.mark.parametrize("wire,needle", [("5A A5 09 00 00 00 AA EE 00", "has 9 bytes"),
                                         ("5A A5 09 00 00 00 AA EF", "bytes 6-7 are AA EF"),
                                         ("5A A5 20 00 00 00 AA EE", "bytes 2-3 (20 00)"),
                                         ("5B A5 09 00 00 00 AA EE", "bytes 0-1 are 5B A5")])
def test_a_malformed_response_is_one_line_naming_the_byte(wire, needle):
    with pytest.raises(MeasuredFormatError) as exc:
        decode_response(b(wire))
    assert needle in str(exc.value)
    assert "\n" not in str(exc.value)


def test_too_long_a_payload_is_refused():
    with pytest.raises(MeasuredFormatError, match="504"):
        encode_command(Command.CONFIG_EEPROM, bytes(505))


# ---------------------------------------------------------------------------------------------- responses
def test_responses_decode_as_documented():
    assert decode_response(b("5A A5 09 00 00 00 AA EE")) == Response(Command.SYSTEM_CONNECT, 0)
    refused = decode_response(b("5A A5 05 00 01 00 AA EE"))
    assert (refused.command, refused.status, refused.ok) == (Command.RECORD_START, 1, False)
    assert encode_response(Command.RECORD_STOP, 0) == b("5A A5 06 00 00 00 AA EE")
    assert encode_response(Command.CONFIG_FPGA_GEN, 0x1234) == b("5A A5 03 00 34 12 AA EE")


def test_fpga_version_word():
    # rf_api.cpp: major = s & 0x7F, minor = (s >> 7) & 0x7F, playback = s & 0x4000
    word = 2 | 9 << 7                                     # 0x0482: "2.9 [Record]"
    version = FpgaVersion.from_status(word)
    assert (version.major, version.minor, version.playback) == (2, 9, False)
    assert str(version) == "2.9 [Record]"
    assert FpgaVersion.from_status(0x4000 | 3 | 1 << 7) == FpgaVersion(3, 1, True)
    assert FpgaVersion(2, 9).status() == 0x0482
    assert decode_response(b("5A A5 0E 00 82 04 AA EE")).ok            # the version word is not a failure


def test_async_status_bits_follow_the_enum_order():
    assert [s.name for s in sorted(AsyncStatus)] == VENDOR_ASYNC
    assert [int(s) for s in sorted(AsyncStatus)] == list(range(12))
    assert decode_async_status(1 << 8) == (AsyncStatus.RECORD_COMPLETED,)
    assert decode_async_status(0b10_1000_0001) == (AsyncStatus.NO_LVDS_DATA, AsyncStatus.DDR_FULL,
                                                   AsyncStatus.LVDS_BUFFER_FULL)
    assert async_status_word(AsyncStatus.NO_LVDS_DATA, AsyncStatus.DDR_FULL) == 0x0081
    assert decode_async_status(1 << 15) == ()                          # undocumented bit


# ---------------------------------------------------------------------------------------------- test-side decoder
def test_the_encoder_agrees_with_the_test_side_decoder():
    payloads = [b"", FpgaConfig().payload(), PacketConfig().payload(), bytes(range(20))]
    for cmd, payload in itertools.product(Command, payloads):
        assert ref_command(encode_command(cmd, payload)) == (int(cmd), payload)
        assert decode_command(encode_command(cmd, payload)).payload == payload
    for cmd, status in itertools.product(Command, (0, 1, 0x482, 0xFFFF)):
        assert ref_response(encode_response(cmd, status)) == (int(cmd), status)


def test_the_emulator_answers_vendor_bytes(loopback_endpoints):
    host_ip, fpga_ip, config_port, data_port = loopback_endpoints
    sent = [("5A A5 09 00 00 00 AA EE", 0x09, 0),                       # SYSTEM_CONNECT
            ("5A A5 0E 00 00 00 AA EE", 0x0E, 2 | 9 << 7),              # READ_FPGA_VERSION: 2.9 record
            ("5A A5 03 00 06 00 01 02 01 02 03 1E AA EE", 0x03, 0),     # CONFIG_FPGA_GEN
            ("5A A5 0B 00 06 00 BE 05 35 0C 00 00 AA EE", 0x0B, 0),     # CONFIG_PACKET_DATA
            ("5A A5 01 00 00 00 AA EE", 0x01, 0)]                       # RESET_FPGA
    with EmulatedDca1000(bytes(4096), frame_bytes=4096, frame_period=0.1, host_ip=host_ip, fpga_ip=fpga_ip,
                         config_port=config_port, data_port=data_port) as emu, \
            socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as host:
        host.bind((host_ip, config_port))
        host.settimeout(2.0)
        for wire, code, status in sent:
            host.sendto(b(wire), (fpga_ip, config_port))
            data, sender = host.recvfrom(64)
            assert sender == (fpga_ip, config_port)
            assert ref_response(data) == (code, status)
        host.sendto(b("5A A5 09 00 00 00 AA ED"), (fpga_ip, config_port))      # bad footer: no answer
        host.settimeout(0.3)
        with pytest.raises(socket.timeout):
            host.recvfrom(64)
    assert emu.fpga_config == FpgaConfig(lanes=2, data_bits=16)
    assert emu.packet_config.delay_cycles == 3125
    assert len(emu.malformed) == 1 and "bytes 6-7 are AA ED" in emu.malformed[0]

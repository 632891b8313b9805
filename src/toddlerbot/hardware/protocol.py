"""Dynamixel Protocol 2.0 framing: CRC-16, byte stuffing, packet building and an incremental stream parser.

Packet layout: ``FF FF FD 00 | ID | LEN_L LEN_H | INST | PARAMS... | CRC_L CRC_H`` where LEN counts INST,
PARAMS and CRC, and the CRC (polynomial 0x8005, initial value 0, no reflection) covers every byte before it.
Byte stuffing: inside INST..PARAMS, every ``FF FF FD`` is followed by an extra ``FD`` so that no header
appears in a packet's body; LEN counts the stuffed bytes.
"""

from __future__ import annotations

from dataclasses import dataclass

HEADER = b"\xff\xff\xfd\x00"
BROADCAST_ID = 0xFE
MAX_ID = 252

# Instructions.
PING = 0x01
READ = 0x02
WRITE = 0x03
FACTORY_RESET = 0x06
REBOOT = 0x08
STATUS = 0x55
SYNC_READ = 0x82
SYNC_WRITE = 0x83
FAST_SYNC_READ = 0x8A
BULK_READ = 0x92

# Status-packet error numbers (low 7 bits of the error byte); bit 7 is the hardware alert flag.
ERR_RESULT_FAIL = 0x01
ERR_INSTRUCTION = 0x02
ERR_CRC = 0x03
ERR_DATA_RANGE = 0x04
ERR_DATA_LENGTH = 0x05
ERR_DATA_LIMIT = 0x06
ERR_ACCESS = 0x07
ALERT = 0x80

MAX_LENGTH = 1024
"""Longest LEN field the parser accepts; anything longer is treated as noise."""


def _crc_table() -> list[int]:
    table = []
    for byte in range(256):
        crc = byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x8005) if crc & 0x8000 else (crc << 1)
        table.append(crc & 0xFFFF)
    return table


_CRC_TABLE = _crc_table()


def crc16(data: bytes | bytearray, crc: int = 0) -> int:
    """CRC-16 of Protocol 2.0 (poly 0x8005), continuing from `crc`."""
    for byte in data:
        crc = ((crc << 8) ^ _CRC_TABLE[((crc >> 8) ^ byte) & 0xFF]) & 0xFFFF
    return crc


def stuff(body: bytes) -> bytes:
    """Insert an FD after every FF FF FD in a packet body (instruction and parameters).

    The two bytes before the body (``LEN_H`` and ``INST``... ) never form FF FF, so only the body is scanned."""
    out = bytearray()
    for byte in body:
        out.append(byte)
        if byte == 0xFD and len(out) >= 3 and out[-3] == 0xFF and out[-2] == 0xFF:
            out.append(0xFD)
    return bytes(out)


def unstuff(body: bytes) -> bytes:
    """Remove the FD inserted after every FF FF FD."""
    out = bytearray()
    i = 0
    while i < len(body):
        out.append(body[i])
        if body[i] == 0xFD and len(out) >= 3 and out[-3] == 0xFF and out[-2] == 0xFF:
            i += 1  # skip the stuffing byte
        i += 1
    return bytes(out)


def build_packet(dxl_id: int, instruction: int, params: bytes = b"") -> bytes:
    """A complete instruction packet (stuffed, with CRC)."""
    body = stuff(bytes([instruction]) + bytes(params))
    head = HEADER + bytes([dxl_id]) + (len(body) + 2).to_bytes(2, "little")
    packet = head + body
    return packet + crc16(packet).to_bytes(2, "little")


def build_status(dxl_id: int, error: int, params: bytes = b"") -> bytes:
    """A status packet: instruction 0x55, then the error byte, then the parameters."""
    return build_packet(dxl_id, STATUS, bytes([error]) + bytes(params))


@dataclass(frozen=True)
class Packet:
    """A parsed packet (body unstuffed)."""

    id: int
    instruction: int
    params: bytes


@dataclass(frozen=True)
class CrcMismatch:
    """A complete packet whose CRC did not match (the device answers with a CRC error if addressed)."""

    id: int
    instruction: int


class PacketParser:
    """Incremental parser: feed it bytes as they arrive, get back whole packets.

    Never raises on any input: garbage before a header is skipped, a LEN beyond `MAX_LENGTH` or a reserved
    byte other than 00 makes it resynchronise one byte later, and a CRC mismatch yields a `CrcMismatch`.
    Memory is bounded: at most one pending packet (MAX_LENGTH + 7 bytes) is buffered.
    """

    def __init__(self) -> None:
        self._buffer = bytearray()

    def feed(self, data: bytes) -> list[Packet | CrcMismatch]:
        self._buffer += data
        out: list[Packet | CrcMismatch] = []
        buf = self._buffer
        while True:
            start = buf.find(b"\xff\xff\xfd")
            if start < 0:
                del buf[: max(0, len(buf) - 2)]  # keep a possible partial header
                break
            del buf[:start]
            if len(buf) < 7:
                break
            length = buf[5] | (buf[6] << 8)
            if buf[3] != 0x00 or length < 3 or length > MAX_LENGTH:
                del buf[:1]
                continue
            total = 7 + length
            if len(buf) < total:
                break
            packet = bytes(buf[:total])
            del buf[:total]
            crc = packet[-2] | (packet[-1] << 8)
            if crc16(packet[:-2]) != crc:
                out.append(CrcMismatch(packet[4], packet[7]))
                continue
            body = unstuff(packet[7:-2])
            out.append(Packet(packet[4], body[0], body[1:]))
        return out

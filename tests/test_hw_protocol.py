"""Protocol 2.0 framing: CRC, byte stuffing, packet bytes, and a parser that survives any byte stream."""

import random

from hypothesis import given, settings
from hypothesis import strategies as st

from toddlerbot.hardware import protocol as p


def test_ping_packet_bytes_match_the_emanual_example():
    # e-Manual Protocol 2.0, ping example for ID 1
    assert p.build_packet(1, p.PING) == bytes.fromhex("FFFFFD0001030001194E")


def test_read_packet_bytes_match_the_emanual_example():
    # read 4 bytes from address 132 (present position) of ID 1
    assert p.build_packet(1, p.READ, bytes([0x84, 0x00, 0x04, 0x00])) == bytes.fromhex("FFFFFD0001070002840004001D15")


@given(st.binary(max_size=300))
def test_crc_equals_the_official_sdk(data):
    from dynamixel_sdk import PacketHandler

    assert p.crc16(data) == PacketHandler(2.0).updateCRC(0, list(data), len(data))


def test_crc_continues_across_chunks():
    data = bytes(range(200))
    assert p.crc16(data[120:], p.crc16(data[:120])) == p.crc16(data)


def test_stuffing_inserts_fd_after_every_header_pattern():
    body = bytes([0x03, 0xFF, 0xFF, 0xFD, 0x10, 0xFF, 0xFF, 0xFD])
    assert p.stuff(body) == bytes([0x03, 0xFF, 0xFF, 0xFD, 0xFD, 0x10, 0xFF, 0xFF, 0xFD, 0xFD])
    assert p.unstuff(p.stuff(body)) == body
    packet = p.build_packet(5, p.WRITE, bytes([0x74, 0x00, 0xFF, 0xFF, 0xFD, 0x00]))
    assert packet[5] == 10  # LEN counts the stuffing byte: INST + 6 params + 1 FD + CRC
    assert packet.count(b"\xff\xff\xfd") == 2  # the header and the stuffed body pattern (FF FF FD FD)


@given(st.integers(0, 252), st.integers(0, 255), st.binary(max_size=200))
def test_parser_round_trips_any_packet(dxl_id, instruction, params):
    packets = p.PacketParser().feed(p.build_packet(dxl_id, instruction, params))
    assert packets == [p.Packet(dxl_id, instruction, params)]


@settings(max_examples=300)
@given(st.binary(max_size=2000), st.binary(max_size=50), st.integers(1, 64))
def test_parser_never_raises_and_finds_packets_in_garbage(garbage, params, chunk):
    """Random bytes never crash the parser; a valid packet after garbage is still found (possibly after
    a spurious CRC-mismatch report for a fake header inside the garbage)."""
    parser = p.PacketParser()
    stream = garbage + p.build_packet(7, p.WRITE, params) * 2
    found = []
    for i in range(0, len(stream), chunk):
        found += parser.feed(stream[i : i + chunk])
    assert found.count(p.Packet(7, p.WRITE, params)) >= 1
    assert len(parser._buffer) <= p.MAX_LENGTH + 7


@given(st.binary(min_size=1, max_size=40), st.randoms(use_true_random=False))
def test_corrupted_packets_are_reported_not_parsed(params, rnd: random.Random):
    packet = bytearray(p.build_packet(3, p.WRITE, params))
    i = rnd.randrange(7, len(packet))
    packet[i] ^= 1 << rnd.randrange(8)
    out = p.PacketParser().feed(bytes(packet))
    assert p.Packet(3, p.WRITE, params) not in out

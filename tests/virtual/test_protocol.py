"""Feetech protocol 0: packet framing, the receiver's resync rules, encodings, wire bytes."""

from __future__ import annotations

import doctest
import random

import pytest

import so101_kinematics.virtual.protocol as fp

PING_1 = fp.instruction_packet(1, fp.INST_PING)
READ_3 = fp.instruction_packet(3, fp.INST_READ, bytes((56, 2)))


def test_docstring_examples_hold():
    result = doctest.testmod(fp)
    assert result.attempted > 0 and result.failed == 0


def test_packet_layout_and_checksum():
    assert PING_1 == bytes.fromhex("ffff010201fb")
    status = fp.status_packet(6, fp.ERR_OVERLOAD, bytes((0x34, 0x12)))
    assert status[:5] == bytes((0xFF, 0xFF, 6, 4, fp.ERR_OVERLOAD))
    assert status[-1] == fp.checksum(status[2:-1])
    assert (sum(status[2:]) & 0xFF) == 0xFF  # body + checksum sums to 0xFF (mod 256)


def test_complete_packets_are_taken_in_order_and_consumed():
    rx = bytearray(PING_1 + READ_3)
    assert fp.take_packets(rx) == [PING_1, READ_3]
    assert rx == bytearray()


def test_garbage_before_a_header_is_discarded():
    rx = bytearray(b"\x00\x12\xfe" + PING_1)
    assert fp.take_packets(rx) == [PING_1]
    assert rx == bytearray()


def test_a_partial_packet_waits_for_its_bytes():
    rx = bytearray(PING_1 + READ_3[:5])
    assert fp.take_packets(rx) == [PING_1]
    assert rx == bytearray(READ_3[:5])
    rx += READ_3[5:]
    assert fp.take_packets(rx) == [READ_3]


def test_a_trailing_ff_is_kept_as_a_possible_header():
    rx = bytearray(b"\x00\x00\xff")
    assert fp.take_packets(rx) == []
    assert rx == bytearray(b"\xff")


def test_bad_checksum_is_skipped_and_the_next_packet_found():
    corrupt = bytearray(PING_1)
    corrupt[-1] ^= 0x01
    rx = bytearray(corrupt + READ_3)
    assert fp.take_packets(rx) == [READ_3]


def test_length_below_two_is_skipped():
    rx = bytearray(b"\xff\xff\x01\x01" + PING_1)
    assert fp.take_packets(rx) == [PING_1]


def test_longer_preamble_is_accepted():
    rx = bytearray(b"\xff" + PING_1)
    assert fp.take_packets(rx) == [PING_1]


@pytest.mark.parametrize("register", sorted(fp.SIGN_BITS))
def test_sign_magnitude_round_trips_in_range(register):
    sign_bit = fp.SIGN_BITS[register]
    rng = random.Random(sign_bit)
    size = fp.ADDR[register][1]
    for value in [0, 1, -1, (1 << sign_bit) - 1, -((1 << sign_bit) - 1)] + [
            rng.randrange(-(1 << sign_bit) + 1, 1 << sign_bit) for _ in range(200)]:
        raw = fp.encode_sign_magnitude(value, sign_bit)
        assert 0 <= raw < 1 << (8 * size)
        assert bool(raw >> sign_bit & 1) == (value < 0)
        assert fp.decode_sign_magnitude(raw, sign_bit) == value


def test_cycle_wire_bytes_counts_the_packets_of_a_sync_cycle():
    ids = bytes(range(1, 7))
    sync_read = fp.instruction_packet(fp.BROADCAST_ID, fp.INST_SYNC_READ, bytes((56, 2)) + ids)
    replies = b"".join(fp.status_packet(i, 0, b"\x00\x08") for i in ids)
    goals = b"".join(bytes((i, 0x00, 0x08)) for i in ids)
    sync_write = fp.instruction_packet(fp.BROADCAST_ID, fp.INST_SYNC_WRITE, bytes((42, 2)) + goals)
    assert fp.cycle_wire_bytes(6) == len(sync_read) + len(replies) + len(sync_write)


def test_control_table_registers_do_not_overlap():
    spans = sorted((addr, addr + size, name) for name, (addr, size) in fp.ADDR.items())
    for (_, end, name), (start, _, following) in zip(spans, spans[1:], strict=False):
        assert end <= start, f"{name} overlaps {following}"


def test_present_registers_are_read_only_and_in_ram():
    for name, (addr, size) in fp.ADDR.items():
        if name.startswith("Present_"):
            assert set(range(addr, addr + size)) <= fp.READ_ONLY, name
            assert addr >= fp.EEPROM_END, name


# The STS3215 memory table (Feetech's STS3215 documentation), written here and not taken from
# the code: register -> (address, size [bytes], sign bit of its sign-magnitude encoding or None).
STS3215_TABLE = {
    "Model_Number": (3, 2, None), "ID": (5, 1, None), "Baud_Rate": (6, 1, None),
    "Min_Position_Limit": (9, 2, None), "Max_Position_Limit": (11, 2, None),
    "Homing_Offset": (31, 2, 11),  # "Ofs": -2047..2047, direction at bit 11
    "Operating_Mode": (33, 1, None), "Torque_Enable": (40, 1, None), "Acceleration": (41, 1, None),
    "Goal_Position": (42, 2, 15), "Goal_Time": (44, 2, None), "Goal_Velocity": (46, 2, 15),
    "Torque_Limit": (48, 2, None), "Lock": (55, 1, None), "Present_Position": (56, 2, 15),
    "Present_Velocity": (58, 2, 15), "Present_Load": (60, 2, 10),
    "Present_Voltage": (62, 1, None), "Present_Temperature": (63, 1, None),
    "Status": (65, 1, None), "Moving": (66, 1, None),
}


@pytest.mark.parametrize("register", sorted(STS3215_TABLE))
def test_control_table_matches_the_sts3215_memory_table(register):
    address, size, sign_bit = STS3215_TABLE[register]
    assert fp.ADDR[register] == (address, size)
    assert fp.SIGN_BITS.get(register) == sign_bit


def test_homing_offset_encoding_by_hand():
    """-300 ticks: magnitude 300 = 0x12C, direction bit 11 (0x800): 0x92C on the wire."""
    bit = fp.SIGN_BITS["Homing_Offset"]
    assert fp.encode_sign_magnitude(-300, bit) == 0x092C
    assert fp.encode_sign_magnitude(300, bit) == 0x012C
    assert fp.decode_sign_magnitude(0x092C, bit) == -300
    assert fp.decode_sign_magnitude(0x0FFF, bit) == -2047  # the register's extreme
    load = fp.SIGN_BITS["Present_Load"]  # Present_Load: direction at bit 10 (0x400)
    assert fp.decode_sign_magnitude(0x0400 | 500, load) == -500


def test_checksum_by_hand():
    """READ servo 3, 2 bytes at 56: ~(3 + 4 + 2 + 56 + 2) & 0xFF = ~67 & 0xFF = 0xBC."""
    assert READ_3 == bytes.fromhex("ffff0304023802bc")
    assert fp.checksum(bytes((3, 4, 2, 56, 2))) == 0xBC

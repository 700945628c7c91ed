"""Feetech protocol 0 and the STS3215 control table: packets, encodings, wire time.

Pure facts and arithmetic, no I/O: what :mod:`so101_kinematics.virtual.emulator` speaks
on its pty, and what tests use to build raw packets.

- Instruction packet ``FF FF ID LEN INST P.. CHK``, status packet
  ``FF FF ID LEN ERR P.. CHK``; LEN counts INST/ERR, the parameters and CHK;
  CHK is the low byte of the bitwise not of the sum of ID .. the last parameter.
- A receiver resynchronises on the next ``FF FF``: a packet with a bad
  checksum or a LEN below 2 is dropped by skipping its header, and a run of
  ``FF`` bytes before the id is a longer preamble.
- Signed registers are sign-magnitude, the sign at a register-specific bit.
- On the wire a byte takes 10 bits (start, 8 data, stop).

Example (PING servo 1)::

    >>> instruction_packet(1, INST_PING).hex(" ")
    'ff ff 01 02 01 fb'
    >>> decode_sign_magnitude(encode_sign_magnitude(-300, 15), 15)
    -300
"""

from __future__ import annotations

__all__ = [
    "ADDR", "BAUD_RATES", "BITS_PER_BYTE", "BROADCAST_ID", "EEPROM_END", "ERROR_BITS",
    "ERR_OVERHEAT", "ERR_OVERLOAD", "ERR_VOLTAGE", "FIRMWARE", "INST_ACTION", "INST_BACKUP",
    "INST_CALIBRATE", "INST_PING", "INST_READ", "INST_REG_WRITE", "INST_RESET",
    "INST_RESET_TURNS", "INST_RESTART", "INST_SYNC_READ", "INST_SYNC_WRITE", "INST_WRITE",
    "MAX_SERVO_ID", "MODEL_NUMBER", "READ_ONLY", "REGISTERED", "SIGN_BITS",
    "checksum", "collide", "cycle_wire_bytes", "decode_sign_magnitude",
    "encode_sign_magnitude", "instruction_packet", "status_packet", "take_packets",
]

# --- STS3215 facts -------------------------------------------------------------------------------
MODEL_NUMBER = 777
FIRMWARE = (3, 10)
# Baud_Rate register value -> [bit/s], as Feetech's memory table (ftservo/ftservo-wiki,
# docs/en/reference/parameter/memory-sts.md, address 6) and its SDK headers (SMS_STS.h) give them.
# lerobot's STS_SMS_SERIES_BAUDRATE_TABLE says 57 600 / 38 400 / 19 200 for codes 5-7: a servo
# follows Feetech's (lerobot itself only ever writes code 0).
BAUD_RATES = {0: 1_000_000, 1: 500_000, 2: 250_000, 3: 128_000, 4: 115_200, 5: 76_800,
              6: 57_600, 7: 38_400}
BITS_PER_BYTE = 10  # on the wire: start bit, 8 data bits, stop bit

# --- protocol 0 ----------------------------------------------------------------------------------
INST_PING, INST_READ, INST_WRITE = 0x01, 0x02, 0x03
INST_REG_WRITE, INST_ACTION = 0x04, 0x05  # a write held until ACTION (Registered flag, addr 64)
INST_RESET = 0x06  # Feetech's "parameter recovery": every parameter but the ID restored
INST_RESTART, INST_BACKUP = 0x08, 0x09  # restart the servo; back up the parameters for 0x06
INST_RESET_TURNS, INST_CALIBRATE = 0x0A, 0x0B  # clear the turn count; present := middle / value
INST_SYNC_READ, INST_SYNC_WRITE = 0x82, 0x83
BROADCAST_ID = 0xFE
MAX_SERVO_ID = 253  # memory table: ID 0-253; 254 is the broadcast ID
ERR_VOLTAGE = 0x01  # status error bits (the status packet's error byte and the Status register)
ERR_OVERHEAT = 0x04
ERR_OVERLOAD = 0x20
ERROR_BITS = {"voltage": ERR_VOLTAGE, "overheat": ERR_OVERHEAT, "overload": ERR_OVERLOAD}
"""Fault name -> status error bit (the bits lerobot's SDK names in its error messages)."""

# --- control table: name -> (address, size [bytes]) (lerobot's STS_SMS_SERIES_CONTROL_TABLE) ---
ADDR = {
    "Firmware_Major_Version": (0, 1), "Firmware_Minor_Version": (1, 1), "Model_Number": (3, 2),
    "ID": (5, 1), "Baud_Rate": (6, 1), "Return_Delay_Time": (7, 1),
    "Response_Status_Level": (8, 1), "Min_Position_Limit": (9, 2), "Max_Position_Limit": (11, 2),
    "Max_Temperature_Limit": (13, 1), "Max_Voltage_Limit": (14, 1), "Min_Voltage_Limit": (15, 1),
    "Max_Torque_Limit": (16, 2), "Phase": (18, 1), "Unloading_Condition": (19, 1),
    "LED_Alarm_Condition": (20, 1), "P_Coefficient": (21, 1), "D_Coefficient": (22, 1),
    "I_Coefficient": (23, 1), "Minimum_Startup_Force": (24, 2), "CW_Dead_Zone": (26, 1),
    "CCW_Dead_Zone": (27, 1), "Protection_Current": (28, 2), "Angular_Resolution": (30, 1),
    "Homing_Offset": (31, 2), "Operating_Mode": (33, 1), "Protective_Torque": (34, 1),
    "Protection_Time": (35, 1), "Overload_Torque": (36, 1),
    "Velocity_closed_loop_P_proportional_coefficient": (37, 1),
    "Over_Current_Protection_Time": (38, 1),
    "Velocity_closed_loop_I_integral_coefficient": (39, 1), "Torque_Enable": (40, 1),
    "Acceleration": (41, 1), "Goal_Position": (42, 2), "Goal_Time": (44, 2),
    "Goal_Velocity": (46, 2), "Torque_Limit": (48, 2), "Lock": (55, 1),
    "Present_Position": (56, 2), "Present_Velocity": (58, 2), "Present_Load": (60, 2),
    "Present_Voltage": (62, 1), "Present_Temperature": (63, 1), "Status": (65, 1),
    "Moving": (66, 1), "Present_Current": (69, 2), "Maximum_Acceleration": (85, 1),
}
SIGN_BITS = {"Homing_Offset": 11, "Goal_Position": 15, "Goal_Velocity": 15,
             "Present_Position": 15, "Present_Velocity": 15, "Present_Load": 10}
EEPROM_END = 40  # addresses below are EEPROM (saved when Lock = 0)
READ_ONLY = set(range(0, 5)) | set(range(56, 80))
REGISTERED = 64  # the Registered (asynchronous write) flag: 1 from REG_WRITE until ACTION


# --- sign-magnitude ------------------------------------------------------------------------------
def encode_sign_magnitude(value: int, sign_bit: int) -> int:
    """Signed integer -> sign-magnitude register value (sign at ``sign_bit``)."""
    return (-value) | (1 << sign_bit) if value < 0 else value


def decode_sign_magnitude(raw: int, sign_bit: int) -> int:
    """Sign-magnitude register value -> signed integer."""
    return -(raw & ~(1 << sign_bit)) if raw & (1 << sign_bit) else raw


# --- packets -------------------------------------------------------------------------------------
def checksum(body: bytes | bytearray) -> int:
    """Feetech checksum of ID, LEN, INST/ERR and parameters: low byte of the bitwise not."""
    return ~sum(body) & 0xFF


def status_packet(servo_id: int, error: int, params: bytes = b"") -> bytes:
    """A status packet ``FF FF ID LEN ERR P.. CHK``."""
    body = bytes((servo_id, len(params) + 2, error)) + params
    return b"\xff\xff" + body + bytes((checksum(body),))


def instruction_packet(servo_id: int, instruction: int, params: bytes = b"") -> bytes:
    """An instruction packet ``FF FF ID LEN INST P.. CHK`` (for tests and tools)."""
    body = bytes((servo_id, len(params) + 2, instruction)) + params
    return b"\xff\xff" + body + bytes((checksum(body),))


def take_packets(rx: bytearray) -> list[bytes]:
    """Remove every complete packet from the front of ``rx``, as a servo's receiver does.

    Bytes before a header are discarded (a trailing lone ``FF`` is kept: it may
    start the next header); packets with a bad checksum or a LEN below 2 are
    skipped by their header; an incomplete packet stays in ``rx``.

    Args:
        rx: received bytes; consumed in place.

    Returns:
        The complete packets with a valid checksum, in order (header to CHK).
    """
    packets = []
    while True:
        start = rx.find(b"\xff\xff")
        if start < 0:
            del rx[:-1 if rx.endswith(b"\xff") else len(rx)]
            break
        del rx[:start]
        if len(rx) >= 3 and rx[2] == 0xFF:
            del rx[0]
            continue
        if len(rx) < 4:
            break
        total = rx[3] + 4
        if rx[3] < 2:
            del rx[:2]
            continue
        if len(rx) < total:
            break
        packet = bytes(rx[:total])
        if packet[-1] != checksum(packet[2:-1]):
            del rx[:2]  # corrupt instruction: ignored, as a servo does
            continue
        del rx[:total]
        packets.append(packet)
    return packets


# --- a shared half-duplex line --------------------------------------------------------------------
UART_OVERSAMPLING = 16  # samples per bit of a UART receiver (the usual 16x clock)


def collide(packets: list[bytes], baud: int, skew_s: float) -> bytes:
    """What a receiver decodes when several transmitters answer on one line at once.

    Each packet is sent as 8N1 frames (start 0, 8 data bits LSB first, stop 1, idle 1),
    the k-th one ``k * skew_s`` later; a driven 0 wins (the line is the AND of the
    transmitters). The receiver samples each bit in its middle; a frame whose stop
    bit reads 0 is a framing error, delivered as a 0 byte (termios without IGNPAR or
    PARMRK). Equal packets with no skew come through intact; anything else is garbled.

    Args:
        packets: the packets, in the order their transmitters start.
        baud: the line's rate [bit/s].
        skew_s: [s] the delay between one transmitter's start and the next one's.

    Returns:
        The bytes the receiver delivers.

    Example (two servos answer a PING to ID 1 at 1 Mbit/s, 2 us apart)::

        >>> ping = status_packet(1, 0)
        >>> collide([ping, ping], 1_000_000, 0.0) == ping
        True
        >>> collide([ping, ping], 1_000_000, 2e-6) == ping
        False
    """
    n = UART_OVERSAMPLING
    shift = round(skew_s * baud * n)
    length = max(len(p) * BITS_PER_BYTE * n + k * shift for k, p in enumerate(packets)) + n
    line = [1] * length
    for k, packet in enumerate(packets):
        start = k * shift
        for i, byte in enumerate(packet):
            bits = [0] + [byte >> b & 1 for b in range(8)] + [1]
            for j, bit in enumerate(bits):
                if not bit:
                    at = start + (i * BITS_PER_BYTE + j) * n
                    line[at:at + n] = [0] * n
    out = bytearray()
    t, previous = 0, 1
    while t < length:
        if previous == 1 and line[t] == 0 and t + (BITS_PER_BYTE - 1) * n + n // 2 < length:
            mid = t + n // 2
            if line[mid] == 0:  # a start bit, not a glitch
                data = sum(line[mid + b * n] << (b - 1) for b in range(1, 9))
                stop = mid + 9 * n
                out.append(data if line[stop] else 0)
                t, previous = stop, line[stop]
                continue
        previous = line[t]
        t += 1
    return bytes(out)


# --- wire time -----------------------------------------------------------------------------------
def cycle_wire_bytes(n_motors: int = 6) -> int:
    """Bytes on the wire for one sync_read(Present_Position) + sync_write(Goal_Position) cycle."""
    sync_read = (8 + n_motors) + n_motors * (6 + 2)
    sync_write = 8 + n_motors * (1 + 2)
    return sync_read + sync_write

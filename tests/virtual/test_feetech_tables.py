"""The emulator's STS3215 facts (virtual/protocol.py) against the installed lerobot's tables.

The emulator keeps its own control table, so that it cannot take its truth
from the client it is meant to test; these tests make sure the two do not
drift apart unnoticed, under every lerobot line CI runs (0.4.x and 0.6.x).
"""

from __future__ import annotations

import pytest

from so101_kinematics.servo import COUNTS_PER_TURN
from so101_kinematics.virtual.protocol import (
    ADDR,
    BAUD_RATES,
    MODEL_NUMBER,
    SIGN_BITS,
    decode_sign_magnitude,
    encode_sign_magnitude,
)

pytestmark = pytest.mark.hw
tables = pytest.importorskip("lerobot.motors.feetech.tables")
MODEL = "sts3215"


def test_every_emulated_register_has_lerobots_address_and_size():
    theirs = tables.MODEL_CONTROL_TABLE[MODEL]
    different = {name: (ours, theirs.get(name)) for name, ours in ADDR.items()
                 if theirs.get(name) != ours}
    assert not different


def test_the_registers_lerobot_drives_the_so101_with_are_all_emulated():
    used = {"ID", "Baud_Rate", "Return_Delay_Time", "Min_Position_Limit", "Max_Position_Limit",
            "Homing_Offset", "Operating_Mode", "P_Coefficient", "I_Coefficient", "D_Coefficient",
            "Max_Torque_Limit", "Protection_Current", "Overload_Torque", "Torque_Enable", "Lock",
            "Acceleration", "Maximum_Acceleration", "Goal_Position", "Present_Position",
            "Model_Number", "Firmware_Major_Version", "Firmware_Minor_Version"}
    assert used <= set(ADDR) and used <= set(tables.MODEL_CONTROL_TABLE[MODEL])


def test_sign_magnitude_bits_match_lerobots_encoding_table():
    theirs = tables.MODEL_ENCODING_TABLE[MODEL]
    assert {name: bit for name, bit in theirs.items() if name in ADDR} == SIGN_BITS


def test_sign_magnitude_round_trips_with_lerobots_own_encoder():
    encoding = pytest.importorskip("lerobot.motors.encoding_utils")
    for name, bit in SIGN_BITS.items():
        for value in (-2047 if bit == 11 else -1000, -1, 0, 1, 300):
            raw = encode_sign_magnitude(value, bit)
            assert raw == encoding.encode_sign_magnitude(value, bit), name
            assert decode_sign_magnitude(raw, bit) == encoding.decode_sign_magnitude(raw, bit)


def test_model_number_and_resolution_match():
    assert tables.MODEL_NUMBER_TABLE[MODEL] == MODEL_NUMBER
    assert tables.MODEL_RESOLUTION[MODEL] == COUNTS_PER_TURN


# Baud_Rate codes 5-7 of the STS3215 per Feetech (its memory table, address 6, and its SDK's
# SMS_STS.h: SMS_STS_76800 5, SMS_STS_57600 6, SMS_STS_38400 7), written here by hand.
FEETECH_CODES_5_TO_7 = {5: 76_800, 6: 57_600, 7: 38_400}


def test_baud_rates_are_feetechs_where_lerobots_table_disagrees():
    """lerobot's table shifts codes 5-7 one rate down (57 600 / 38 400 / 19 200).

    A servo obeys Feetech's firmware, not lerobot's table; lerobot itself only ever
    writes code 0 (1 Mbit/s), so its table's error never reaches a SO-101. The
    emulator follows the servo: codes 0-4 agree, 5-7 are Feetech's.
    """
    theirs = {code: rate for rate, code in tables.MODEL_BAUDRATE_TABLE[MODEL].items()}
    assert {c: BAUD_RATES[c] for c in range(5)} == {c: theirs[c] for c in range(5)}
    assert {c: BAUD_RATES[c] for c in range(5, 8)} == FEETECH_CODES_5_TO_7
    if theirs[5] == 57_600:  # lerobot still has its own table: say so if it is ever fixed
        assert {c: theirs[c] for c in range(5, 8)} == {5: 57_600, 6: 38_400, 7: 19_200}

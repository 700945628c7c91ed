"""Feetech's own SDK (``feetech-servo-sdk``, module ``scservo_sdk``) drives the virtual arm.

A second client, independent of lerobot (which sits on the same SDK but never sends
REG_WRITE, ACTION or RESET, nor changes the baud rate to anything but 1 Mbit/s).
Expected values are Feetech's (protocol page and STS3215 memory table; see
tests/test_virtual_protocol.py, which sends the same requests as raw packets).
"""

from __future__ import annotations

import time

import pytest
from test_virtual_so101 import HOME

from so101_kinematics.virtual.arm import DEFAULT_CALIBRATION_PATH, VirtualSO101

sdk = pytest.importorskip("scservo_sdk")
MODEL_NUMBER = 777  # STS3215
RESET = 0x06  # parameter recovery; the SDK on PyPI has no call for it: sent through txRxPacket


@pytest.fixture
def arm():
    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH) as virtual_arm:
        virtual_arm.set_pose(HOME)
        yield virtual_arm


@pytest.fixture
def client(arm):
    """(port, packet handler) of Feetech's SDK, at 1 Mbit/s."""
    port = sdk.PortHandler(arm.port)
    assert port.openPort()
    yield port, sdk.PacketHandler(0)  # protocol end 0: little-endian, the STS series
    port.closePort()


def test_scan_reads_model_number_of_six_servos(client):
    port, handler = client
    for servo_id in range(1, 7):
        model, result, error = handler.ping(port, servo_id)
        assert (model, result, error) == (MODEL_NUMBER, sdk.COMM_SUCCESS, 0), servo_id
    assert handler.ping(port, 7)[1] == sdk.COMM_RX_TIMEOUT


def test_reg_write_then_broadcast_action_moves_servos_together(client):
    port, handler = client
    starts = {i: handler.read2ByteTxRx(port, i, 56)[0] for i in (1, 5)}
    for servo_id in (1, 5):
        goal = starts[servo_id] + 250
        result, error = handler.regWriteTxRx(port, servo_id, 42, 2, [goal & 0xFF, goal >> 8])
        assert (result, error) == (sdk.COMM_SUCCESS, 0)
        assert handler.read1ByteTxRx(port, servo_id, 64)[0] == 1  # Registered
    time.sleep(0.3)
    assert abs(handler.read2ByteTxRx(port, 1, 56)[0] - starts[1]) <= 3  # held, not applied
    assert handler.action(port, sdk.BROADCAST_ID) == sdk.COMM_SUCCESS
    assert [handler.read1ByteTxRx(port, i, 64)[0] for i in (1, 5)] == [0, 0]
    time.sleep(1.5)
    for servo_id in (1, 5):
        present = handler.read2ByteTxRx(port, servo_id, 56)[0]
        assert abs(present - (starts[servo_id] + 250)) <= 10, servo_id


def test_reset_restores_p_coefficient_and_keeps_the_id(client, arm):
    port, handler = client
    assert handler.write1ByteTxRx(port, 3, 21, 20) == (sdk.COMM_SUCCESS, 0)
    packet = [0xFF, 0xFF, 3, 2, RESET, 0]  # the SDK adds the checksum
    _, result, error = handler.txRxPacket(port, packet)
    assert (result, error) == (sdk.COMM_SUCCESS, 0)
    assert handler.read1ByteTxRx(port, 3, 21)[:2] == (32, sdk.COMM_SUCCESS)  # factory P
    assert arm.registers("elbow_flex")["ID"] == 3


@pytest.mark.parametrize(("code", "rate"), [(6, 57_600), (7, 38_400)])
def test_baud_change_then_the_servo_answers_at_feetechs_rate(client, code, rate):
    """Codes 6 and 7 (code 5, 76 800, is one the SDK's PortHandler refuses to open)."""
    port, handler = client
    assert handler.write1ByteTxRx(port, 3, 6, code) == (sdk.COMM_SUCCESS, 0)
    assert handler.ping(port, 3)[1] == sdk.COMM_RX_TIMEOUT
    assert port.setBaudRate(rate)
    assert handler.ping(port, 3)[:2] == (MODEL_NUMBER, sdk.COMM_SUCCESS)
    assert handler.ping(port, 2)[1] == sdk.COMM_RX_TIMEOUT  # the others are still at 1 Mbit/s


def test_sync_read_and_sync_write_through_the_sdk_groups(client):
    port, handler = client
    reader = sdk.GroupSyncRead(port, handler, 56, 2)
    for servo_id in range(1, 7):
        assert reader.addParam(servo_id)
    assert reader.txRxPacket() == sdk.COMM_SUCCESS
    present = {i: reader.getData(i, 56, 2) for i in range(1, 7)}
    writer = sdk.GroupSyncWrite(port, handler, 41, 1)  # Acceleration, every servo
    for servo_id in range(1, 7):
        assert writer.addParam(servo_id, [servo_id * 10])
    assert writer.txPacket() == sdk.COMM_SUCCESS
    assert [handler.read1ByteTxRx(port, i, 41)[0] for i in range(1, 7)] == \
        [10, 20, 30, 40, 50, 60]
    assert all(0 < value < 4096 for value in present.values())


def test_two_servos_with_one_id_fail_the_sdks_transactions_but_both_obey(client, arm):
    port, handler = client
    assert handler.write1ByteTxRx(port, 2, 5, 1) == (sdk.COMM_SUCCESS, 0)  # now two ID 1
    assert handler.ping(port, 1)[1] != sdk.COMM_SUCCESS  # collided replies
    assert handler.read2ByteTxRx(port, 1, 56)[1] != sdk.COMM_SUCCESS
    handler.write1ByteTxRx(port, 1, 41, 77)
    assert [arm.registers(j)["Acceleration"] for j in ("shoulder_pan", "shoulder_lift")] == \
        [77, 77]

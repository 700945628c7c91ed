"""Issue 14, protocol fidelity and the shell: replies from the addressed ID, baud rates, model."""

from __future__ import annotations

import math
import time

import pytest

from so101_kinematics.virtual import electrical, shell
from so101_kinematics.virtual.arm import VirtualSO101
from so101_kinematics.virtual.protocol import INST_PING, INST_WRITE, instruction_packet


def test_current_temperature_voltage_model_by_hand():
    assert electrical.current_units(1000) == round(2700 / 6.5)  # stall: 2.7 A in 6.5 mA units
    assert electrical.current_units(0) == 0
    # first order: after one time constant at stall, 25 + 80 * (1 - 1/e)
    assert electrical.next_temperature(25.0, 1000, 120.0, 120.0) == pytest.approx(
        25 + 80 * (1 - math.exp(-1)))
    assert electrical.next_temperature(70.0, 0, 1e6, 120.0) == pytest.approx(25.0)  # cools
    assert electrical.voltage_units(12.0, [1000] * 6) == round(10 * (12 - 0.1 * 6 * 2.7))
    assert electrical.status_bits(71, 120, False, 70, (40, 140)) == 0x04
    assert electrical.status_bits(30, 39, True, 70, (40, 140)) == 0x01 | 0x20


def open_link(port: str, baud: int):
    """A raw serial link to the virtual arm (pyserial comes with the hw extra)."""
    serial = pytest.importorskip("serial")
    return serial.Serial(port, baud, timeout=0.2)


def ping(port, servo_id, baud):
    with open_link(port, baud) as link:
        link.reset_input_buffer()
        link.write(instruction_packet(servo_id, INST_PING))
        return link.read(6)


@pytest.fixture(scope="module")
def arm():
    with VirtualSO101(supply=3.5) as virtual_arm:
        yield virtual_arm


def test_servos_answer_only_at_their_configured_rate(arm):
    for baud in (4800, 9600, 14400, 57600, 115200, 128000, 250000, 500000):
        assert ping(arm.port, 1, baud) == b"", baud
    assert ping(arm.port, 1, 1_000_000)[:3] == b"\xff\xff\x01"


def test_a_write_of_the_id_answers_from_the_addressed_id(arm):
    with open_link(arm.port, 1_000_000) as link:
        link.write(instruction_packet(1, INST_WRITE, bytes((5, 7))))  # servo 1: ID := 7
        reply = link.read(6)
        link.write(instruction_packet(7, INST_WRITE, bytes((5, 1))))  # and back
        back = link.read(6)
    assert reply[:3] == b"\xff\xff\x01" and back[:3] == b"\xff\xff\x07"


def test_low_supply_sets_the_voltage_bit_and_register(arm):
    registers = arm.registers("elbow_flex")
    assert registers["Present_Voltage"] <= 35  # 3.5 V supply (below Min_Voltage_Limit 4.0 V)
    assert registers["Status"] & 0x01
    arm.set_supply(12.0)
    time.sleep(0.1)
    registers = arm.registers("elbow_flex")
    assert registers["Present_Voltage"] > 110 and not registers["Status"] & 0x01


def test_shell_dispatch_table_and_errors(arm):
    assert {"pose", "sweep", "middle", "play", "demo", "limp", "quit"} <= set(shell.COMMANDS)
    assert shell.run_line(arm, "fly").startswith("error unknown command")
    assert shell.run_line(arm, "pose elbow_flex=500").startswith("error pose: elbow_flex = 500")
    arm.set_torque(True)
    assert "torqued" in shell.run_line(arm, "pose elbow_flex=10")
    assert shell.run_line(arm, "limp") == "ok limp"
    answer = shell.run_line(arm, "pose elbow_flex=60 wrist_flex=20")
    assert answer.startswith("ok") and abs(arm.joint_positions()["elbow_flex"] - 60) < 1.0
    time.sleep(0.5)  # a limp arm stays limp, the hand holds it there
    assert not any(arm.torque_enabled().values())
    assert arm.joint_positions()["elbow_flex"] == pytest.approx(60, abs=1.0)

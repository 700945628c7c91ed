"""The virtual arm's STS3215 instruction set and memory table, through raw packets (issue 26).

Each test starts its own virtual arm (they renumber, reset and re-baud servos). Expected
values come from Feetech's documents, written here by hand: the protocol page
(ftservo/ftservo-wiki docs/en/reference/protocol/ft-scs.md) and the STS3215 memory table
(the spreadsheet's "Initial value" column; memory-sts.md on the same wiki). The same
requests through Feetech's own SDK are in tests/virtual/test_virtual_feetech_sdk.py.
"""

from __future__ import annotations

import time

import pytest
from test_virtual_so101 import HOME, RawPort, split_status

import so101_kinematics.virtual.protocol as fp
from so101_kinematics.servo import KIT_SUPPLY_V
from so101_kinematics.virtual.arm import VirtualSO101
from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH

REG_WRITE, ACTION, RESET, UNKNOWN = 0x04, 0x05, 0x06, 0x07  # Feetech's instruction codes
REGISTERED, P_COEFFICIENT, GOAL, PRESENT = 64, 21, 42, 56  # memory table addresses
TICK_DEG = 360.0 / 4095.0


@pytest.fixture
def arm():
    # the figures below (the current at rest, the duty) are the kit's 5 V C001's, by hand
    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH, supply=KIT_SUPPLY_V) as virtual_arm:
        virtual_arm.set_pose(HOME)
        yield virtual_arm


@pytest.fixture
def raw(arm):
    port = RawPort(arm.port)
    yield port
    port.close()


def ask(raw, servo_id, instruction, params=b"", n_bytes=64, timeout=0.2):
    """Send one instruction; the status packets that come back as (id, error, params)."""
    raw.send(servo_id, instruction, params)
    return split_status(raw.receive(n_bytes, timeout=timeout))


def read(raw, servo_id, addr, size=1):
    (reply,) = ask(raw, servo_id, fp.INST_READ, [addr, size], n_bytes=6 + size)
    return int.from_bytes(reply[2], "little")


def goal_bytes(ticks):
    return [ticks & 0xFF, ticks >> 8]


# --- REG_WRITE + ACTION -----------------------------------------------------------------------
def test_reg_write_is_held_with_the_registered_flag_until_a_broadcast_action(raw, arm):
    start = read(raw, 1, PRESENT, 2)
    goal = start + 300  # about 26 deg of shoulder_pan
    assert ask(raw, 1, REG_WRITE, [GOAL, *goal_bytes(goal)]) == [(1, 0, b"")]
    assert read(raw, 1, REGISTERED) == 1
    assert read(raw, 1, GOAL, 2) != goal  # stored, not applied
    time.sleep(0.5)
    assert abs(read(raw, 1, PRESENT, 2) - start) <= 3  # it has not moved
    raw.send(fp.BROADCAST_ID, ACTION)
    assert raw.receive(1, timeout=0.1) == b""  # a broadcast is never answered
    assert read(raw, 1, REGISTERED) == 0
    assert read(raw, 1, GOAL, 2) == goal
    time.sleep(1.5)
    assert abs(read(raw, 1, PRESENT, 2) - goal) <= 10


def test_unicast_action_is_answered_and_moves_only_that_servo(raw):
    starts = {i: read(raw, i, PRESENT, 2) for i in (1, 5)}
    for servo_id in (1, 5):
        ask(raw, servo_id, REG_WRITE, [GOAL, *goal_bytes(starts[servo_id] + 200)])
    assert ask(raw, 5, ACTION) == [(5, 0, b"")]
    assert (read(raw, 5, REGISTERED), read(raw, 1, REGISTERED)) == (0, 1)
    assert read(raw, 5, GOAL, 2) == starts[5] + 200
    assert read(raw, 1, GOAL, 2) != starts[1] + 200


# --- RESET ------------------------------------------------------------------------------------
def test_reset_restores_the_factory_parameters_but_keeps_the_id(raw, arm):
    assert ask(raw, 3, fp.INST_WRITE, [P_COEFFICIENT, 20]) == [(3, 0, b"")]
    assert read(raw, 3, P_COEFFICIENT) == 20
    assert ask(raw, 3, RESET) == [(3, 0, b"")]  # Feetech: FF FF 01 02 00 FC for ID 1
    registers = arm.registers("elbow_flex")
    assert registers["P_Coefficient"] == 32  # the memory table's initial values
    assert registers["ID"] == 3  # "restore all servo parameters except the ID"
    assert (registers["Homing_Offset"], registers["Min_Position_Limit"],
            registers["Max_Position_Limit"]) == (0, 0, 4095)
    assert registers["Return_Delay_Time"] == 250  # a new servo's 500 us
    before = arm.joint_positions()["elbow_flex"]
    time.sleep(0.3)  # torque on, offset changed: the servo holds where it is
    assert abs(arm.joint_positions()["elbow_flex"] - before) < 1.0


# --- the memory table ---------------------------------------------------------------------
@pytest.mark.parametrize(("code", "rate"), [(6, 57_600), (7, 38_400), (5, 76_800)])
def test_baud_rate_codes_are_feetechs(arm, code, rate):
    serial = pytest.importorskip("serial")
    raw = RawPort(arm.port)
    try:
        assert ask(raw, 4, fp.INST_WRITE, [6, code]) == [(4, 0, b"")]  # answered at the old rate
        assert ask(raw, 4, fp.INST_PING) == []  # no longer at 1 Mbit/s
    finally:
        raw.close()
    with serial.Serial(arm.port, rate, timeout=0.2) as port:  # pyserial sets any rate
        port.reset_input_buffer()
        port.write(fp.instruction_packet(4, fp.INST_PING))
        assert port.read(6) == fp.status_packet(4, 0)


def test_torque_enable_128_makes_the_present_position_2048(raw, arm):
    time.sleep(1.5)  # at rest: the servo at P = 32 has settled into its sag after set_pose
    before = arm.joint_positions()["wrist_flex"]
    assert read(raw, 4, PRESENT, 2) != 2048
    assert ask(raw, 4, fp.INST_WRITE, [40, 128]) == [(4, 0, b"")]
    assert abs(read(raw, 4, PRESENT, 2) - 2048) <= 2  # the encoder reads a count off at times
    assert read(raw, 4, 40) == 1  # reads back 0/1: torque stays on
    time.sleep(0.3)
    assert abs(arm.joint_positions()["wrist_flex"] - before) < 1.0  # it did not jump


def test_factory_image_has_the_memory_tables_values(raw):
    # velocity-loop P, over-current protection time [10 ms], velocity-loop I
    assert [read(raw, 2, addr) for addr in (37, 38, 39)] == [10, 200, 10]
    assert read(raw, 2, 48, 2) == 1000  # Torque_Limit from Max_Torque_Limit (1000)
    assert read(raw, 2, 44, 2) == 1000  # Goal_Time, the PWM mode's duty: initial value 1000


def test_torque_limit_is_loaded_from_max_torque_limit_at_power_up(raw, arm):
    ask(raw, 6, fp.INST_WRITE, [55, 0])  # unlock: EEPROM writes survive the power cycle
    ask(raw, 6, fp.INST_WRITE, [16, *goal_bytes(500)])  # Max_Torque_Limit, as lerobot's gripper
    assert read(raw, 6, 48, 2) == 1000  # Torque_Limit changes only at power-up
    arm.power_cycle()
    assert read(raw, 6, 48, 2) == 500


# --- who answers --------------------------------------------------------------------------
def test_response_status_level_0_answers_only_ping_and_read(raw):
    assert ask(raw, 2, fp.INST_WRITE, [8, 0]) == [(2, 0, b"")]  # judged on arrival: answered
    assert ask(raw, 2, fp.INST_WRITE, [41, 100]) == []
    assert ask(raw, 2, REG_WRITE, [41, 50]) == []
    assert ask(raw, 2, ACTION) == []
    assert ask(raw, 2, fp.INST_PING) == [(2, 0, b"")]
    assert read(raw, 2, 41) == 50  # the writes acted all the same
    assert ask(raw, 2, fp.INST_WRITE, [8, 1]) == []
    assert ask(raw, 2, fp.INST_WRITE, [41, 0]) == [(2, 0, b"")]


def test_an_unknown_instruction_is_ignored_without_a_reply(raw):
    assert ask(raw, 1, UNKNOWN, [1, 2]) == []
    assert ask(raw, 1, fp.INST_PING) == [(1, 0, b"")]  # and the bus goes on


# --- two servos with one ID ---------------------------------------------------------------
@pytest.mark.slow
def test_two_servos_with_one_id_both_answer_garbled_and_both_obey(raw, arm):
    assert ask(raw, 2, fp.INST_WRITE, [5, 1]) == [(2, 0, b"")]  # shoulder_lift becomes ID 1
    assert {arm.registers(j)["ID"] for j in ("shoulder_pan", "shoulder_lift")} == {1}
    garbled = 0
    for _ in range(20):  # identical replies garble about 4 in 10 times (servolab, issue 34)
        raw.send(1, fp.INST_PING)
        data = raw.receive(64, timeout=0.2)
        assert data  # both answered
        garbled += data != fp.status_packet(1, 0)
    assert 3 <= garbled <= 13  # by hand: 8 of 20, standard deviation 2.2
    raw.send(1, fp.INST_READ, [PRESENT, 2])
    data = raw.receive(64, timeout=0.2)
    assert not (len(data) == 8 and data[-1] == fp.checksum(data[2:-1]))  # no clean reply
    raw.send(1, fp.INST_WRITE, [41, 77])  # both take a write
    raw.receive(64, timeout=0.1)
    assert [arm.registers(j)["Acceleration"] for j in ("shoulder_pan", "shoulder_lift")] == [77, 77]


def test_two_factory_servos_on_one_bus_collide():
    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH, factory=True) as arm:
        raw = RawPort(arm.port)
        try:
            assert ask(raw, 1, fp.INST_PING) == [(1, 0, b"")]  # one new servo: a clean reply
            arm.plug()  # a second new one, also ID 1, elsewhere: their positions differ
            raw.send(1, fp.INST_READ, [PRESENT, 2])
            data = raw.receive(64, timeout=0.2)
            assert data and not (len(data) == 8 and data[-1] == fp.checksum(data[2:-1]))
        finally:
            raw.close()


# --- the servo model's rows of the issue (the model: so101_kinematics/sim/sts3215.py) ---------
def test_acceleration_and_goal_velocity_shape_a_position_move(raw):
    """Acceleration 10 (1000 counts/s^2), Goal_Velocity 100 counts/s: 400 counts take ~4 s."""
    start = read(raw, 1, PRESENT, 2)
    ask(raw, 1, fp.INST_WRITE, [41, 10])
    ask(raw, 1, fp.INST_WRITE, [46, *goal_bytes(100)])
    ask(raw, 1, fp.INST_WRITE, [GOAL, *goal_bytes(start + 400)])
    time.sleep(1.5)  # by hand: 0.1 s ramp (5 counts) + 1.4 s at 100 counts/s = 145 counts
    assert abs(read(raw, 1, PRESENT, 2) - start) < 250


def test_wheel_mode_spins_at_goal_velocity(raw):
    ask(raw, 5, fp.INST_WRITE, [33, 1])  # Operating_Mode 1: constant speed (wrist_roll)
    start = read(raw, 5, PRESENT, 2)  # the bare encoder in this mode
    ask(raw, 5, fp.INST_WRITE, [46, *goal_bytes(300)])  # 300 counts/s
    time.sleep(1.0)
    assert abs(read(raw, 5, PRESENT, 2) - start) > 150


def test_a_reading_at_rest_moves_by_a_count_or_two(raw):
    readings = {read(raw, 2, PRESENT, 2) for _ in range(50)}
    assert 1 < len(readings) and max(readings) - min(readings) <= 4


def test_present_current_follows_the_load(raw, arm):
    # At rest the current is the duty's: V duty / R (BAM: R = 2.676 ohm, kt/R = 0.4528 N m/V).
    # The shoulder holds 0.26 N m of the arm's weight here (gravity.py): 0.26 / (0.4528 x 5 V)
    # = 11.4 % duty, plus P/4 x 3.5 counts = 2.8 % across half the gear play (P = 32): 14.2 %,
    # 5 V x 0.142 / 2.676 ohm = 0.265 A = 41 units of 6.5 mA (static friction, 0.05 N m, may
    # carry up to 8 of them). The unloaded wrist_roll draws none. The voltage's sag under a
    # stall: tests/virtual/test_virtual_feetech_sdk.py.
    arm.set_pose(dict(HOME, shoulder_lift=-30.0, elbow_flex=0.0, wrist_flex=0.0))
    time.sleep(0.5)
    assert 33 <= read(raw, 2, 69, 2) <= 45
    assert read(raw, 5, 69, 2) <= 2


def test_torque_limit_caps_the_duty_and_the_shoulder_no_longer_lifts(raw, arm):
    # Torque_Limit (48) [MEM: "controls the stall torque output"]: 3 % of 5 V's stall torque,
    # 0.068 N m, is under the 0.26 N m the arm's weight needs about the shoulder here
    arm.set_pose(dict(HOME, shoulder_lift=-30.0, elbow_flex=0.0, wrist_flex=0.0))
    start = read(raw, 2, PRESENT, 2)
    assert ask(raw, 2, fp.INST_WRITE, [48, *goal_bytes(30)]) == [(2, 0, b"")]
    ask(raw, 2, fp.INST_WRITE, [GOAL, *goal_bytes(start - 300)])  # lift by 26 deg
    time.sleep(1.0)
    assert start - read(raw, 2, PRESENT, 2) < 5  # not lifted
    assert read(raw, 2, 60, 2) == 30 | 0x400  # Present_Load: 3 %, the lifting way (bit 10)


def test_goal_time_is_not_a_moves_duration_in_position_mode(raw):
    # The STS moves at Goal_Velocity and Acceleration; Feetech's SMS_STS driver writes a
    # time of 0 with every position, and the memory table makes 44 the PWM mode's duty
    start = read(raw, 1, PRESENT, 2)
    params = [GOAL, *goal_bytes(start + 400), *goal_bytes(2000), 0, 0]  # 2000 ms, as SCS
    assert ask(raw, 1, fp.INST_WRITE, params) == [(1, 0, b"")]
    time.sleep(1.0)  # half of the 2 s: an SCS servo would be 200 counts short
    assert abs(read(raw, 1, PRESENT, 2) - (start + 400)) <= 10


def test_step_mode_moves_by_the_counts_written(raw):
    # Operating_Mode 3 [MEM]: Goal_Position is a relative step (sign bit 15), from the goal
    ask(raw, 5, fp.INST_WRITE, [33, 3])
    start = read(raw, 5, PRESENT, 2)  # wrist_roll, no gravity load; the bare encoder
    ask(raw, 5, fp.INST_WRITE, [GOAL, *goal_bytes(200)])
    time.sleep(0.6)
    assert abs(read(raw, 5, PRESENT, 2) - (start + 200)) <= 8  # dead zone, play, friction
    ask(raw, 5, fp.INST_WRITE, [GOAL, *goal_bytes(200 | 0x8000)])  # -200: sign-magnitude
    time.sleep(0.6)
    assert abs(read(raw, 5, PRESENT, 2) - start) <= 8


def test_pwm_mode_drives_open_loop_with_the_duty_written(raw):
    # Operating_Mode 2 [MEM]: Goal_Time holds the duty (0.1 %), bit 10 its direction; a
    # positive duty counts Present_Position down (lerobot PR #4547's bench check; servolab)
    ask(raw, 5, fp.INST_WRITE, [44, *goal_bytes(0)])
    ask(raw, 5, fp.INST_WRITE, [33, 2])
    start = read(raw, 5, PRESENT, 2)
    ask(raw, 5, fp.INST_WRITE, [44, *goal_bytes(300)])  # 30 % one way
    time.sleep(0.3)
    forward = read(raw, 5, PRESENT, 2) - start
    ask(raw, 5, fp.INST_WRITE, [44, *goal_bytes(300 | 0x400)])  # the other way
    time.sleep(0.6)
    back = read(raw, 5, PRESENT, 2) - start
    assert forward < -50 and back > forward  # it turned down, then back up

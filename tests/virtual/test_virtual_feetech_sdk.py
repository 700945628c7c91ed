"""Feetech's own SDK (``feetech-servo-sdk``, module ``scservo_sdk``) drives the virtual arm.

A second client, independent of lerobot (which sits on the same SDK but never sends
REG_WRITE, ACTION or RESET, nor changes the baud rate to anything but 1 Mbit/s).
Expected values are Feetech's (protocol page and STS3215 memory table; see
tests/virtual/test_virtual_protocol.py, which sends the same requests as raw packets), or computed
by hand below from the memory table's units and the servo's measured motor ([BAM] in
``so101_kinematics/servo.py`` ([BAM]): kt/R = 0.4528 N m/V, kt^2/R = 0.549 N m s/rad, R = 2.676 ohm,
Coulomb 0.0524 N m, viscous 0.0591 N m s/rad, for the kit's C001 at its 5 V supply).
Durations are measured on the simulation's clock (``reply_stats()["sim_time_s"]``), which
slips behind the wall clock on a busy machine.
"""

from __future__ import annotations

import math
import statistics
import time

import pytest
from test_virtual_so101 import HOME

from so101_kinematics.servo import KIT_SUPPLY_V
from so101_kinematics.virtual.arm import VirtualSO101
from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH

sdk = pytest.importorskip("scservo_sdk")
MODEL_NUMBER = 777  # STS3215
RESET = 0x06  # parameter recovery; the SDK on PyPI has no call for it: sent through txRxPacket
# memory table addresses
OPERATING_MODE, TORQUE_ENABLE, ACCELERATION, GOAL, GOAL_TIME, GOAL_VELOCITY = 33, 40, 41, 42, 44, 46
TORQUE_LIMIT, PRESENT, PRESENT_VELOCITY, PRESENT_LOAD, PRESENT_VOLTAGE, PRESENT_CURRENT = \
    48, 56, 58, 60, 62, 69
COUNTS_PER_DEG = 4096 / 360.0  # 4096 counts a turn [memory table: 0.087 deg a count]


@pytest.fixture
def arm():
    # the figures below are the kit's 5 V C001's (by hand, module docstring): its arm, pinned
    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH, supply=KIT_SUPPLY_V) as virtual_arm:
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
    """Identical replies (PING's) garble about 4 in 10 times, as servolab measured on a real bus
    (issue 34): 20 PINGs, by hand 8 expected (binomial, standard deviation 2.2). Replies that
    differ (the two joints' positions) collide every time."""
    port, handler = client
    assert handler.write1ByteTxRx(port, 2, 5, 1) == (sdk.COMM_SUCCESS, 0)  # now two ID 1
    ping = [0xFF, 0xFF, 1, 2, 0x01, 0]  # the SDK's ping() also reads the model: one reply here
    garbled = sum(handler.txRxPacket(port, ping)[1] != sdk.COMM_SUCCESS for _ in range(20))
    assert 3 <= garbled <= 13
    assert all(handler.read2ByteTxRx(port, 1, 56)[1] != sdk.COMM_SUCCESS for _ in range(5))
    handler.write1ByteTxRx(port, 1, 41, 77)
    assert [arm.registers(j)["Acceleration"] for j in ("shoulder_pan", "shoulder_lift")] == \
        [77, 77]


# --- the servo and its modes, through the SDK (issue 26's table) ----------------------------
def sim_time(arm) -> float:
    """The simulation's clock [s]."""
    return arm.reply_stats()["sim_time_s"]


def wait_sim(arm, seconds: float) -> None:
    """Wait until ``seconds`` [s] of simulated time have passed."""
    end = sim_time(arm) + seconds
    while sim_time(arm) < end:
        time.sleep(0.02)


def signed(raw: int, sign_bit: int) -> int:
    """A sign-magnitude register's value (the memory table's "BITn is the direction bit")."""
    magnitude = raw & ((1 << sign_bit) - 1)
    return -magnitude if raw & (1 << sign_bit) else magnitude


def joint_reading(arm, joint: str) -> tuple[float, float]:
    """(simulated time [s], the joint's angle [deg]): the time taken on either side."""
    before = sim_time(arm)
    angle = arm.joint_positions()[joint]
    return (before + sim_time(arm)) / 2, angle


def joint_speed(arm, joint: str, seconds: float = 0.3) -> float:
    """The joint's mean speed over ``seconds`` of simulated time [counts/s]."""
    t0, start = joint_reading(arm, joint)
    wait_sim(arm, seconds)
    t1, end = joint_reading(arm, joint)
    return (end - start) * COUNTS_PER_DEG / (t1 - t0)


def transact(client, call, *args) -> tuple[int, int]:
    """(result, error byte) of one SDK call; one that times out is sent again, as ``read``
    does (a busy machine can keep the emulator off the CPU past the SDK's deadline). Only for
    transactions that may be repeated (writes of a value, RESTART)."""
    port, _ = client
    for _ in range(3):
        *_, result, error = call(port, *args)
        if result != sdk.COMM_RX_TIMEOUT:
            break
        time.sleep(0.05)  # the late reply arrives, and is thrown away
        port.clearPort()
    return result, error


def write2(client, servo_id: int, addr: int, value: int) -> None:
    assert transact(client, client[1].write2ByteTxRx, servo_id, addr, value) == \
        (sdk.COMM_SUCCESS, 0)


def write1(client, servo_id: int, addr: int, value: int) -> None:
    assert transact(client, client[1].write1ByteTxRx, servo_id, addr, value) == \
        (sdk.COMM_SUCCESS, 0)


def read(client, servo_id: int, addr: int, size: int) -> int:
    """A register's raw value; a read that times out is tried again, as lerobot 0.6's reads
    are (a busy machine can keep the emulator off the CPU past the SDK's ~34 ms deadline)."""
    port, handler = client
    call = handler.read2ByteTxRx if size == 2 else handler.read1ByteTxRx
    for _ in range(3):
        value, result, error = call(port, servo_id, addr)
        if result != sdk.COMM_RX_TIMEOUT:
            break
        time.sleep(0.05)  # the late reply arrives, and is thrown away: it would answer the
        port.clearPort()  # next read (FEETECH_NOTES.md, "Traps seen" 1)
    assert (result, error) == (sdk.COMM_SUCCESS, 0)
    return value


def read2(client, servo_id: int, addr: int) -> int:
    return read(client, servo_id, addr, 2)


def read1(client, servo_id: int, addr: int) -> int:
    return read(client, servo_id, addr, 1)


def time_to_reach(client, arm, servo_id: int, goal: int, within: int = 10,
                  timeout: float = 8.0) -> float:
    """Simulated time [s] until Present_Position is ``within`` counts of ``goal``."""
    t0 = sim_time(arm)
    while sim_time(arm) - t0 < timeout:
        if abs(read2(client, servo_id, PRESENT) - goal) <= within:
            return sim_time(arm) - t0
        time.sleep(0.01)
    return math.inf


def test_torque_limit_30_and_the_shoulder_no_longer_lifts(client, arm):
    """Torque_Limit caps the duty [memory table: "controls the stall torque output"].

    By hand: 3 % duty at 5 V gives 0.4528 x 5 x 0.03 = 0.068 N m; the arm's weight about
    the shoulder in this pose needs 0.26 N m (the model's holding torque, gravity.py).
    """
    arm.set_pose(dict(HOME, shoulder_lift=-30.0, elbow_flex=0.0, wrist_flex=0.0))
    start = read2(client, 2, PRESENT)
    write2(client, 2, TORQUE_LIMIT, 30)
    write2(client, 2, GOAL, start - 300)  # lift (against gravity) by 26 deg
    wait_sim(arm, 1.0)
    assert start - read2(client, 2, PRESENT) < 5  # not lifted (it sank)
    assert signed(read2(client, 2, PRESENT_LOAD), 10) == -30  # pushing at the cap
    write2(client, 2, TORQUE_LIMIT, 1000)
    wait_sim(arm, 1.0)
    assert abs(read2(client, 2, PRESENT) - (start - 300)) <= 15  # the same goal, reached


@pytest.mark.slow
def test_acceleration_and_goal_velocity_make_a_400_count_move_last_4_s(client, arm):
    """Acceleration 10, Goal_Velocity 100 on shoulder_pan (no gravity about its axis).

    By hand, from the memory table's units: a = 10 x 8.7 deg/s^2 = 990 counts/s^2;
    v = 100 x 0.0146 rpm = 99.7 counts/s (Phase 12 sets bit 2: that unit). A trapezoid:
    0.1 s ramps (5 counts each), 390 counts at v: 3.9 s; 4.1 s in all. The joint
    follows a few counts behind the profile's target.
    """
    start = read2(client, 1, PRESENT)
    write1(client, 1, ACCELERATION, 10)
    write2(client, 1, GOAL_VELOCITY, 100)
    write2(client, 1, GOAL, start + 400)
    halfway = time_to_reach(client, arm, 1, start + 200, within=3)
    cruise = read2(client, 1, PRESENT_VELOCITY)
    duration = halfway + time_to_reach(client, arm, 1, start + 400)
    assert 1.8 <= halfway <= 2.3  # 0.1 + 195 / 99.7 = 2.06 s
    assert cruise == 100  # in 50 counts/s steps [TEL]
    assert 3.8 <= duration <= 4.4


def test_goal_time_does_not_set_a_position_moves_duration(client, arm):
    """An SCS-style write (position, time 2000 ms, speed 0) moves as fast as time 0 does.

    STS firmware uses speed and acceleration (Feetech's SMS_STS driver writes time 0 with
    every position; the memory table makes address 44 the PWM mode's duty).
    """
    port, handler = client
    durations = []
    for goal_time in (0, 2000):
        start = read2(client, 1, PRESENT)
        goal = start - 400
        data = [goal & 0xFF, goal >> 8, goal_time & 0xFF, goal_time >> 8, 0, 0]
        assert handler.writeTxRx(port, 1, GOAL, 6, data) == (sdk.COMM_SUCCESS, 0)
        assert read2(client, 1, GOAL_TIME) == goal_time  # stored
        durations.append(time_to_reach(client, arm, 1, goal))
        write2(client, 1, GOAL, start)
        wait_sim(arm, 0.5)
    assert durations[1] < 1.0  # under half the 2 s an SCS servo would take
    assert abs(durations[1] - durations[0]) < 0.1


def test_wheel_mode_spins_at_goal_velocity_either_way(client, arm):
    """Operating_Mode 1: "constant-speed motor mode", Goal_Velocity signed by bit 15."""
    write1(client, 5, OPERATING_MODE, 1)
    write2(client, 5, GOAL_VELOCITY, 300)  # 300 counts/s (Phase 12's unit)
    wait_sim(arm, 0.2)
    assert joint_speed(arm, "wrist_roll") == pytest.approx(300, rel=0.05)
    assert signed(read2(client, 5, PRESENT_VELOCITY), 15) == 300
    write2(client, 5, GOAL_VELOCITY, 300 | 0x8000)
    wait_sim(arm, 0.2)
    assert joint_speed(arm, "wrist_roll") == pytest.approx(-300, rel=0.05)


def test_pwm_mode_runs_open_loop_at_the_duty_written(client, arm):
    """Operating_Mode 2: Goal_Time is the duty [0.1 %], bit 10 its direction; a positive duty
    turns the way Present_Position counts down (lerobot PR #4547's bench check; servolab).

    By hand, the unloaded wrist_roll's steady speed at duty u and 5 V:
    (0.4528 x 5 u - 0.0524) / (0.549 + 0.0591) rad/s: 1.031 rad/s = 672 counts/s at 30 %,
    2.148 rad/s = 1400 counts/s at 60 %.
    """
    write1(client, 5, OPERATING_MODE, 2)
    for duty, speed in ((300, -672), (600, -1400), (300 | 0x400, 672)):  # PWM_DIRECTION
        write2(client, 5, GOAL_TIME, duty)
        wait_sim(arm, 0.25)  # the motor's time constant: 0.0284 / 0.608 = 0.05 s
        assert joint_speed(arm, "wrist_roll", 0.2) == pytest.approx(speed, rel=0.1), duty
        assert signed(read2(client, 5, PRESENT_LOAD), 10) == signed(duty, 10)  # the duty
    write2(client, 5, GOAL_TIME, 0)


def test_step_mode_moves_by_the_counts_written_from_where_the_joint_is(client, arm):
    """Operating_Mode 3: each Goal_Position is a relative step (bit 15 its sign).

    Entered from wheel mode, the steps start where the joint stopped (the virtual arm's
    choice: the memory table does not say). Goal_Velocity 0: the profile at full speed.
    """
    write1(client, 5, OPERATING_MODE, 1)
    write2(client, 5, GOAL_VELOCITY, 300)
    wait_sim(arm, 0.3)  # 90 counts away from its goal in position mode
    write2(client, 5, GOAL_VELOCITY, 0)
    wait_sim(arm, 0.1)
    stopped = arm.joint_positions()["wrist_roll"]
    write1(client, 5, OPERATING_MODE, 3)
    wait_sim(arm, 0.3)
    base = arm.joint_positions()["wrist_roll"]
    assert abs(base - stopped) * COUNTS_PER_DEG <= 5  # it stays there
    for step, total in ((200, 200), (200, 400), (400 | 0x8000, 0)):
        write2(client, 5, GOAL, step)
        wait_sim(arm, 0.5)
        moved = (arm.joint_positions()["wrist_roll"] - base) * COUNTS_PER_DEG
        assert moved == pytest.approx(total, abs=10), step  # dead zone, play, friction


def test_torque_enable_128_sets_present_position_2048_and_reads_back_0_or_1(client, arm):
    arm.set_pose(dict(HOME, wrist_roll=-60.0))  # wrist_roll's 2048 is at 0 deg
    arm.set_torque(False, ["wrist_roll"])
    for servo_id, torque in ((4, 1), (5, 0)):
        assert read2(client, servo_id, PRESENT) not in range(2040, 2057)
        write1(client, servo_id, TORQUE_ENABLE, 128)
        assert abs(read2(client, servo_id, PRESENT) - 2048) <= 2  # a count of noise
        assert read1(client, servo_id, TORQUE_ENABLE) == torque


def test_readings_move_like_a_sensors(client, arm):
    """Encoder noise at rest; current and bus voltage that follow the load.

    By hand: wrist_roll stalled against its end stop at full duty (97 %, the firmware's
    cap) draws 5 V x 0.97 / 2.676 ohm = 1.81 A = 279 units of 6.5 mA; through the supply's
    0.1 ohm that is 0.18 V of sag (Present_Voltage in 0.1 V: about 2 units).
    """
    readings = {read2(client, 2, PRESENT) for _ in range(50)}
    assert len(readings) > 1 and max(readings) - min(readings) <= 4
    wait_sim(arm, 0.5)  # the arm settled after set_pose: no servo still pulling current
    rest_volts = volts(client, 5)
    assert read2(client, 5, PRESENT_CURRENT) <= 2  # holding an unloaded joint
    write1(client, 5, OPERATING_MODE, 2)
    write2(client, 5, GOAL_TIME, 1000)
    wait_sim(arm, 1.0)  # at 1.4k counts/s it reaches the stop within 0.6 s
    assert read2(client, 5, PRESENT_CURRENT) == pytest.approx(279, rel=0.1)
    assert 1 <= rest_volts - volts(client, 5) <= 3
    write2(client, 5, GOAL_TIME, 0)
    wait_sim(arm, 0.2)
    assert read2(client, 5, PRESENT_CURRENT) <= 2 and volts(client, 5) >= rest_volts - 1


def volts(client, servo_id: int) -> int:
    """Present_Voltage [0.1 V], the median of 9 readings (it flickers by a unit)."""
    return statistics.median_low(read1(client, servo_id, PRESENT_VOLTAGE) for _ in range(9))


def test_unused_registers_read_the_factory_values(client):
    """The memory table's initial values: velocity-loop P 10, over-current time 200 (10 ms),
    velocity-loop I 10; PWM duty (Goal_Time) 1000; Torque_Limit from Max_Torque_Limit 1000."""
    assert [read1(client, 2, addr) for addr in (37, 38, 39)] == [10, 200, 10]
    assert read2(client, 2, GOAL_TIME) == 1000
    assert read2(client, 2, TORQUE_LIMIT) == read2(client, 2, 16) == 1000


# --- readings that live, and the rest of the table (issue 34) --------------------------------
def test_load_current_and_voltage_at_rest_live_within_a_sensors_band(client, arm):
    """50 reads of a servo holding the arm's weight: each reading moves, within a sensor's band.

    The shoulder holds about 0.26 N m here (gravity.py): a steady duty well inside 5-97 %.
    Present_Load: the loop reads the same encoder as Present_Position, which is a count off
    now and then, so the duty steps by P/4 = 8 (factory P 32) either way; the joint itself
    rests between two adjacent counts (as a real one: roboninecom's 2346/2347): a band of
    at most 4 counts of 8.
    Present_Current: its mean plus up to a unit either way (roboninecom's telemetry: 0-2 units
    at a steady duty), the mean following the duty's band: 32 x 0.29 units (5 V / 2.676 ohm /
    6.5 mA per 0.1 % of duty) = 9 units, plus a unit either way. Present_Voltage: a unit
    (0.1 V) of flicker about the supply's less the bus's sag (most readings: the sag follows
    every servo's current, and one run on a machine at load 13 saw a 0.8 V dip mid-read).
    """
    arm.set_pose(dict(HOME, shoulder_lift=-30.0, elbow_flex=0.0, wrist_flex=0.0))
    wait_sim(arm, 0.5)
    loads = [signed(read2(client, 2, PRESENT_LOAD), 10) for _ in range(50)]
    currents = [read2(client, 2, PRESENT_CURRENT) for _ in range(50)]
    voltages = [read1(client, 2, PRESENT_VOLTAGE) for _ in range(50)]
    assert len(set(loads)) > 1 and max(loads) - min(loads) <= 32
    assert all(50 <= abs(load) <= 970 for load in loads) and len({x > 0 for x in loads}) == 1
    assert len(set(currents)) > 1 and max(currents) - min(currents) <= 11
    assert min(currents) > 0
    middle = statistics.median(voltages)
    assert len(set(voltages)) > 1 and sum(abs(v - middle) <= 1 for v in voltages) >= 40
    assert abs(middle - 10 * KIT_SUPPLY_V) <= 3  # 0.1 V units: the kit's 5 V supply's


def test_overload_drops_the_output_to_protective_torque_and_says_so(client, arm):
    """wrist_roll pushed against its end stop at full duty (PWM mode, -97 %: the firmware's cap).

    Memory table: after Protection_Time (35, here 150 = 1.5 s) above Overload_Torque (36, 80 %)
    the output drops to Protective_Torque (34, 20 %) and the status byte's overload bit (0x20)
    is set; a Torque_Enable write (or a new goal) clears it. By hand: 20 % at 5 V through
    2.676 ohm is 0.37 A = 57 units of 6.5 mA, against 279 at 97 %.
    """
    port, handler = client
    write1(client, 5, 35, 150)
    write2(client, 5, GOAL_TIME, 0)
    write1(client, 5, OPERATING_MODE, 2)
    write2(client, 5, GOAL_TIME, 1000 | 0x400)  # counts up, to its stop
    wait_sim(arm, 2.0)  # the stop within 0.6 s; 1.5 s over 80 %
    load, result, error = handler.read2ByteTxRx(port, 5, PRESENT_LOAD)
    assert result == sdk.COMM_SUCCESS and error & 0x20  # overloaded
    assert signed(load, 10) == -200  # the output at Protective_Torque
    assert 40 <= handler.read2ByteTxRx(port, 5, PRESENT_CURRENT)[0] <= 75
    assert transact(client, handler.write1ByteTxRx, 5, 35, 250) == (sdk.COMM_SUCCESS, 0x20)
    write1(client, 5, TORQUE_ENABLE, 1)  # clears the protection (and 2.5 s to trip again)
    wait_sim(arm, 0.1)  # a physics step at the restored cap
    load, result, error = handler.read2ByteTxRx(port, 5, PRESENT_LOAD)
    assert (result, error & 0x20) == (sdk.COMM_SUCCESS, 0) and signed(load, 10) == -970
    handler.write2ByteTxRx(port, 5, GOAL_TIME, 0)


def test_overload_protection_off_in_unloading_condition_keeps_the_output(client, arm):
    """Unloading_Condition (19) without bit 5: no overload protection [memory table]."""
    port, handler = client
    write1(client, 5, 19, 44 & ~0x20)
    write1(client, 5, 35, 50)
    write2(client, 5, GOAL_TIME, 0)
    write1(client, 5, OPERATING_MODE, 2)
    write2(client, 5, GOAL_TIME, 1000 | 0x400)
    wait_sim(arm, 2.0)
    assert signed(handler.read2ByteTxRx(port, 5, PRESENT_LOAD)[0], 10) == -970
    handler.write2ByteTxRx(port, 5, GOAL_TIME, 0)


@pytest.mark.parametrize("new_id", [254, 255])
def test_an_id_above_253_is_refused(client, arm, new_id):
    """Memory table: ID 0-253 (254 is the broadcast ID). The servo keeps its ID, and a READ
    sent to 254 stays unanswered (a broadcast is never answered but PING)."""
    port, handler = client
    write1(client, 3, 5, new_id)
    assert handler.ping(port, 3)[:2] == (MODEL_NUMBER, sdk.COMM_SUCCESS)
    assert arm.registers("elbow_flex")["ID"] == 3
    port.clearPort()
    assert handler.txPacket(port, [0xFF, 0xFF, 0xFE, 4, 0x02, PRESENT, 2, 0]) == sdk.COMM_SUCCESS
    time.sleep(0.1)  # lerobot's whole transaction budget is 50 ms
    assert not port.readPort(64)  # nobody answers a READ to the broadcast ID


def test_a_limp_falling_joint_draws_no_current(client, arm):
    """Torque off: the driver's bridge is open, the falling joint back-drives an open circuit
    (its EMF, kt w = 1.21 N m/A x under 1.5 rad/s, is far below the 5 V supply plus two body
    diodes): Present_Current reads 0 while Present_Velocity shows the fall."""
    arm.set_pose(dict(HOME, shoulder_lift=-30.0, elbow_flex=0.0, wrist_flex=0.0))
    write1(client, 2, TORQUE_ENABLE, 0)
    speeds, currents = [], []
    for _ in range(30):
        speeds.append(abs(signed(read2(client, 2, PRESENT_VELOCITY), 15)))
        currents.append(read2(client, 2, PRESENT_CURRENT))
        time.sleep(0.01)
    assert max(speeds) >= 100  # counts/s: it falls
    assert currents == [0] * 30


@pytest.mark.parametrize("mode", [1, 2, 3])
def test_present_position_is_the_bare_encoder_outside_position_mode(client, arm, mode):
    """In wheel, PWM and step modes Present_Position does not subtract Homing_Offset (servolab's
    client, issue 34); back in position mode it does again. The joint stands still throughout
    (speed 0, duty 0, no step), so the readings differ by the offset, within the noise."""
    offset = signed(read2(client, 5, 31), 11)
    assert offset != 0
    before = read2(client, 5, PRESENT)
    write2(client, 5, GOAL_TIME, 0)
    write1(client, 5, OPERATING_MODE, mode)
    wait_sim(arm, 0.2)
    bare = read2(client, 5, PRESENT)
    assert abs((bare - before - offset + 2048) % 4096 - 2048) <= 3
    write1(client, 5, OPERATING_MODE, 0)
    wait_sim(arm, 0.2)
    assert abs(read2(client, 5, PRESENT) - before) <= 3


# --- where the sources disagree: the default, and the other choice as a rule (rules.py) -------
@pytest.fixture
def ruled():
    """``ruled(**rules)``: (port, handler, arm) of a virtual arm with those rules."""
    opened = []

    def start(**rules):
        arm = VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH, rules=rules,
                           supply=KIT_SUPPLY_V)  # the kit's 5 V C001, as ``arm`` above
        arm.set_pose(HOME)
        port = sdk.PortHandler(arm.port)
        assert port.openPort()
        opened.append((port, arm))
        return port, sdk.PacketHandler(0), arm

    yield start
    for port, arm in opened:
        port.closePort()
        arm.close()


@pytest.mark.parametrize(("rule", "seconds"), [("ignored", (0.0, 1.0)), ("move_time", (1.8, 2.5))])
def test_goal_time_rule(ruled, rule, seconds):
    """An SCS-style write (position, time 2000 ms, speed 0): the STS ignores the time (default);
    under ``goal_time = "move_time"`` the 400 counts take the 2 s (speed 200 counts/s)."""
    port, handler, arm = ruled(goal_time=rule)
    start = read2((port, handler), 1, PRESENT)
    goal = start - 400
    data = [goal & 0xFF, goal >> 8, 2000 & 0xFF, 2000 >> 8, 0, 0]
    assert handler.writeTxRx(port, 1, GOAL, 6, data) == (sdk.COMM_SUCCESS, 0)
    duration = time_to_reach((port, handler), arm, 1, goal)
    assert seconds[0] <= duration <= seconds[1]


@pytest.mark.parametrize(("rule", "moved"), [("follows", 0), ("kept", 300)])
def test_limp_goal_rule(ruled, rule, moved):
    """A goal written with torque off: it follows Present_Position (default), so torque on holds
    where the joint is; under ``limp_goal = "kept"`` torque on moves to it (shoulder_pan: no
    gravity about its axis, so the limp joint stays put)."""
    port, handler, arm = ruled(limp_goal=rule)
    client = (port, handler)
    write1(client, 1, TORQUE_ENABLE, 0)
    start = read2(client, 1, PRESENT)
    write2(client, 1, GOAL, start + 300)
    wait_sim(arm, 0.3)
    read2(client, 1, PRESENT)  # a read while limp (the default copies the position to the goal)
    write1(client, 1, TORQUE_ENABLE, 1)
    wait_sim(arm, 1.0)
    assert abs(read2(client, 1, PRESENT) - (start + moved)) <= 10


@pytest.mark.parametrize(("rule", "stored"), [("acts", 300), ("refused", None)])
def test_locked_eeprom_rule(ruled, rule, stored):
    """With Lock = 1 (the factory value) an EEPROM write acts until the next power cycle
    (default), or under ``locked_eeprom = "refused"`` is ignored."""
    port, handler, arm = ruled(locked_eeprom=rule)
    client = (port, handler)
    write1(client, 3, 55, 1)
    before = read2(client, 3, 9)  # Min_Position_Limit
    write2(client, 3, 9, 300)
    assert read2(client, 3, 9) == (before if stored is None else stored)


@pytest.mark.parametrize(("rule", "answered"), [("none", False), ("status", True)])
def test_restart_reply_rule(ruled, rule, answered):
    """RESTART (0x08): no reply (default), or under ``restart_reply = "status"`` a status."""
    port, handler, arm = ruled(restart_reply=rule)
    restart = [0xFF, 0xFF, 3, 2, 0x08, 0]
    result = transact((port, handler), handler.txRxPacket, restart)[0] if answered else \
        handler.txRxPacket(port, restart)[1]
    assert (result == sdk.COMM_SUCCESS) == answered
    time.sleep(0.1)
    assert read1((port, handler), 3, 5) == 3  # it came back, as ID 3


# --- the default arm: the course's follower -------------------------------------------------
C018_STALL_MA = 2700.0  # Feetech's C018 datasheet: 2.7 A at stall on 12 V (docs/servo_model.md)
CURRENT_UNIT_MA = 6.5  # one unit of Present_Current (memory table)


def test_a_leader_arm_runs_on_the_courses_5_v_by_default():
    """The course's leader runs on the kit's 5 V supply (ECE4560 assignment 2), not the
    follower's 12 V: Present_Voltage about 50 (0.1 V) with no supply given."""
    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH, leader=True) as arm:
        port = sdk.PortHandler(arm.port)
        assert port.openPort()
        try:
            client = (port, sdk.PacketHandler(0))
            voltage = statistics.median(read1(client, 2, PRESENT_VOLTAGE) for _ in range(15))
        finally:
            port.closePort()
    assert abs(voltage - 50) <= 2, voltage  # 0.1 V units; a limp leader draws nothing


def test_the_default_virtual_arm_is_the_courses_12_v_c018_follower():
    """No supply given: the course's follower (ECE4560 assignment 3: "use the 12V power supply
    with the follower arm"; its servos are 12 V C018s, docs/servo_model.md).

    Present_Voltage reads the 12 V supply, about 120 (0.1 V), less the bus's sag (a unit or
    two). The servo bank is the C018: holding the arm's weight at a steady duty, its current
    is the duty's share of its stall current, 2.7 A at 12 V (the C018's datasheet), so
    Present_Current / |Present_Load| = 2700 mA / 6.5 mA / 1000 = 0.415 units per 0.1 % of
    duty. A C001 (BAM's kt/R) on 12 V would draw 12 V x 0.4528 / 1.2116 = 4.48 A at stall
    (0.69), the C001 by its datasheet 1.97 A (0.30): neither within 12 %.
    """
    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH) as arm:
        arm.set_pose(dict(HOME, shoulder_lift=-30.0, elbow_flex=0.0, wrist_flex=0.0))
        port = sdk.PortHandler(arm.port)
        assert port.openPort()
        try:
            client = (port, sdk.PacketHandler(0))
            wait_sim(arm, 0.5)
            voltage = statistics.median(read1(client, 2, PRESENT_VOLTAGE) for _ in range(15))
            snapshots = []  # Present_Load .. Present_Current in one read: the same instant
            for _ in range(40):
                data, result, error = client[1].readTxRx(port, 2, PRESENT_LOAD, 11)
                if result == sdk.COMM_SUCCESS and error == 0:
                    load = signed(data[0] | data[1] << 8, 10)
                    snapshots.append((abs(load), data[9] | data[10] << 8))
        finally:
            port.closePort()
    assert abs(voltage - 120) <= 3, voltage  # 0.1 V units
    assert len(snapshots) >= 30
    load = statistics.median(s[0] for s in snapshots)
    current = statistics.median(s[1] for s in snapshots)
    assert load >= 50, load  # well above the current's one-unit flicker
    assert current / load == pytest.approx(C018_STALL_MA / CURRENT_UNIT_MA / 1000.0, rel=0.12)

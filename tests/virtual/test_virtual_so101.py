"""The virtual SO-101: Feetech protocol, registers, physics behind them, faults, timing.

Tests marked ``hw`` drive the emulator with lerobot's own, unmodified
FeetechMotorsBus / SO101Follower (the ``hw`` extra); the others speak the
protocol through a raw file descriptor on the pty.
"""

from __future__ import annotations

import os
import select
import subprocess
import sys
import termios
import time
import tty

import numpy as np
import pytest

import so101_kinematics.virtual.protocol as fp
import so101_kinematics.virtual.shipped_calibration as vcal
import so101_mujoco_utils as smu
from benchmarks.bench_hw import measure_cycle, virtual_arm_bus
from so101_forward_kinematics import JOINTS
from so101_kinematics import servo
from so101_kinematics.errors import CalibrationError, FaultSpecError, JointLimitError
from so101_kinematics.gravity import feedforward
from so101_kinematics.paths import REPO
from so101_kinematics.virtual.arm import VirtualSO101
from so101_kinematics.virtual.electrical import SUPPLY_V
from so101_kinematics.virtual.faults import parse_faults
from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH

TICK_DEG = 360.0 / 4095.0  # one encoder tick [deg]
GRIPPER_TICK = 100.0 / 1251.0  # one gripper tick in [0, 100] units (shipped calibration)
HOME = {"shoulder_pan": 0.0, "shoulder_lift": -90.0, "elbow_flex": 90.0, "wrist_flex": 30.0,
        "wrist_roll": 0.0, "gripper": 9.0}
POSE = {"shoulder_pan": 25.0, "shoulder_lift": -40.0, "elbow_flex": 50.0, "wrist_flex": 15.0,
        "wrist_roll": -60.0, "gripper": 40.0}


# --- fixtures and helpers ------------------------------------------------------------------------
@pytest.fixture(scope="module")
def arm():
    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH) as virtual_arm:
        yield virtual_arm


@pytest.fixture
def fresh_arm(arm):
    """The shared arm, back at HOME with torque on, no faults, empty goal log."""
    arm.clear_faults()
    arm.set_wire_timing(False)
    arm.set_torque(True)
    arm.set_pose(HOME)
    arm.clear_goal_log()
    arm.clear_stats()
    yield arm
    arm.clear_faults()
    arm.set_wire_timing(False)


@pytest.fixture(scope="module")
def lerobot_bus_factory():
    pytest.importorskip("lerobot")
    buses = []

    def make(virtual_arm, connect=True):
        bus = virtual_arm_bus(virtual_arm)
        if connect:
            bus.connect()
        buses.append(bus)
        return bus

    yield make
    for bus in buses:
        if bus.is_connected:
            bus.disconnect(disable_torque=False)


@pytest.fixture
def bus(fresh_arm, lerobot_bus_factory):
    bus = lerobot_bus_factory(fresh_arm)
    bus.enable_torque()
    yield bus
    if bus.is_connected:
        bus.disconnect(disable_torque=False)


def resting(goal, p=32, volts=5.0):
    """Where the virtual servos hold ``goal`` at rest: less the sag gravity causes there.

    The STS3215 at P (factory 32, lerobot 16) on the arm's 5 V holds a load only by being
    off its goal (so101_kinematics.gravity: the model's masses over the servo's static law).
    """
    settings = servo.FACTORY.with_(p=p)
    offsets = feedforward(dict(HOME, **goal), settings, volts)
    return {j: goal[j] - offsets[j] for j in goal}


def wait_until_reached(bus, goal, tol=1.0, timeout=4.0):
    """Poll Present_Position until every joint is within tol of goal; return the last reading."""
    deadline = time.monotonic() + timeout
    while True:
        present = bus.sync_read("Present_Position")
        if all(abs(present[j] - goal[j]) <= tol for j in goal) or time.monotonic() > deadline:
            return present
        time.sleep(0.05)


class RawPort:
    """The host end of the pty without lerobot: raw mode, 1 Mbaud like the SO-101's bus."""

    def __init__(self, path, baud=termios.B1000000):
        self.fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(self.fd)
        attrs = termios.tcgetattr(self.fd)
        attrs[4] = attrs[5] = baud
        termios.tcsetattr(self.fd, termios.TCSANOW, attrs)
        termios.tcflush(self.fd, termios.TCIFLUSH)

    def send(self, servo_id, instruction, params=b""):
        os.write(self.fd, fp.instruction_packet(servo_id, instruction, bytes(params)))

    def receive(self, n_bytes, timeout=0.2):
        """Up to n_bytes, waiting at most timeout [s] in total."""
        data = b""
        deadline = time.monotonic() + timeout
        while len(data) < n_bytes:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([self.fd], [], [], left)[0]:
                break
            data += os.read(self.fd, n_bytes - len(data))
        return data

    def close(self):
        os.close(self.fd)


@pytest.fixture
def raw(fresh_arm):
    port = RawPort(fresh_arm.port)
    yield port
    port.close()


def split_status(data):
    """Status packets -> list of (id, error, params), checking each checksum."""
    packets = []
    while data:
        assert data[:2] == b"\xff\xff", data
        length = data[3]
        packet, data = data[:length + 4], data[length + 4:]
        assert packet[-1] == fp.checksum(packet[2:-1]), f"bad checksum in {packet.hex()}"
        packets.append((packet[2], packet[4], packet[5:-1]))
    return packets


# --- calibration and mapping (no lerobot needed) --------------------------------------------
def test_shipped_calibration_is_derived_from_the_model(model):
    shipped = vcal.load_calibration(DEFAULT_CALIBRATION_PATH)
    assert shipped == vcal.make_default_calibration(model)
    for joint, entry in shipped.items():
        assert entry["drive_mode"] == 0
        if joint not in ("gripper", "wrist_roll"):
            # zero of the joint at the middle of the calibrated range
            assert (entry["range_min"] + entry["range_max"]) / 2 == 2047


def test_calibrated_ranges_cover_the_model_joint_limits(model):
    calibration = vcal.load_calibration(DEFAULT_CALIBRATION_PATH)
    limits = smu.joint_limits(model)
    for joint, (lower, upper) in limits.items():
        entry = calibration[joint]
        low_ticks, high_ticks = (
            vcal.radians_to_present(model, entry, joint, smu.to_radians(model, {joint: v})[joint])
            for v in (lower, upper))
        assert entry["range_min"] <= low_ticks + 1e-9, joint
        assert high_ticks <= entry["range_max"] + 1e-9, joint


def test_tick_mapping_agrees_with_the_simulator_units(model):
    """Ticks -> lerobot's DEGREES / RANGE_0_100 formulas == so101_mujoco_utils' user units."""
    calibration = vcal.load_calibration(DEFAULT_CALIBRATION_PATH)
    limits = smu.joint_limits(model)
    rng = np.random.default_rng(4)
    for _ in range(200):
        cfg = {j: float(rng.uniform(*limits[j])) for j in JOINTS}
        angles = smu.to_radians(model, cfg)
        for joint in JOINTS:
            entry = calibration[joint]
            ticks = vcal.radians_to_present(model, entry, joint, angles[joint])
            lo, hi = entry["range_min"], entry["range_max"]
            if joint == "gripper":
                user = (ticks - lo) / (hi - lo) * 100.0  # lerobot RANGE_0_100
            else:
                user = (ticks - (lo + hi) / 2) * 360.0 / 4095.0  # lerobot DEGREES
            assert user == pytest.approx(cfg[joint], abs=1e-9), joint
            back = vcal.present_to_radians(model, entry, joint, ticks)
            assert back == pytest.approx(angles[joint], abs=1e-12)


def test_bad_calibration_is_refused_with_the_fix():
    calibration = vcal.load_calibration(DEFAULT_CALIBRATION_PATH)
    broken = {j: dict(e) for j, e in calibration.items()}
    broken["gripper"]["drive_mode"] = 1
    with pytest.raises(CalibrationError, match="gripper.drive_mode.*drive_mode 0"):
        vcal.load_calibration(broken)
    del broken["elbow_flex"]
    with pytest.raises(CalibrationError, match="elbow_flex"):
        vcal.load_calibration(broken)
    with pytest.raises(CalibrationError, match="does not exist"):
        vcal.load_calibration("/nonexistent/calibration.json")


def test_fault_grammar():
    calibration = vcal.load_calibration(DEFAULT_CALIBRATION_PATH)
    faults = parse_faults("drop:3:5, corrupt:2,remove:wrist_flex,stall:elbow_flex,"
                              "firmware:3.9,firmware:6:3.8", calibration)
    assert faults == [("drop", 3, 5), ("corrupt", 2, 1), ("remove", 4, None), ("stall", 3, None),
                      ("firmware", 1, (3, 9)), ("firmware", 6, (3, 8))]
    with pytest.raises(FaultSpecError, match="unknown servo '9'"):
        parse_faults("drop:9", calibration)
    with pytest.raises(FaultSpecError, match="Grammar"):
        parse_faults("explode:1", calibration)
    with pytest.raises(FaultSpecError, match="Grammar"):
        parse_faults("drop:1:0", calibration)


# --- the protocol on the wire (no lerobot needed) -------------------------------------------
def test_ping_read_and_broadcast_ping(raw):
    raw.send(1, fp.INST_PING)
    assert split_status(raw.receive(6)) == [(1, 0, b"")]
    raw.send(2, fp.INST_READ, [3, 2])  # Model_Number
    assert split_status(raw.receive(8)) == [(2, 0, (777).to_bytes(2, "little"))]
    raw.send(4, fp.INST_READ, [0, 2])  # firmware major, minor
    assert split_status(raw.receive(8)) == [(4, 0, bytes([3, 10]))]
    raw.send(fp.BROADCAST_ID, fp.INST_PING)
    replies = split_status(raw.receive(36))
    assert [r[0] for r in replies] == [1, 2, 3, 4, 5, 6]


def test_broadcasts_are_never_answered(raw):
    goal = [42, 2] + [b for i in range(1, 7) for b in (i, 0x00, 0x08)]
    raw.send(fp.BROADCAST_ID, fp.INST_SYNC_WRITE, goal)
    raw.send(fp.BROADCAST_ID, fp.INST_WRITE, [41, 254])  # Acceleration on every servo
    raw.send(fp.BROADCAST_ID, fp.INST_READ, [56, 2])
    assert raw.receive(1, timeout=0.15) == b""
    raw.send(3, fp.INST_READ, [41, 1])
    assert split_status(raw.receive(7)) == [(3, 0, bytes([254]))]  # the broadcast WRITE acted


def test_sync_read_answers_in_request_order(raw):
    raw.send(fp.BROADCAST_ID, fp.INST_SYNC_READ, [56, 2, 5, 1, 3])
    replies = split_status(raw.receive(3 * 8))
    assert [r[0] for r in replies] == [5, 1, 3]


def test_corrupt_instruction_is_ignored(raw):
    packet = bytearray(fp.instruction_packet(1, fp.INST_PING))
    packet[-1] ^= 0xFF
    os.write(raw.fd, bytes(packet))
    assert raw.receive(1, timeout=0.1) == b""
    raw.send(1, fp.INST_PING)  # the bus resynchronises on the next packet
    assert split_status(raw.receive(6)) == [(1, 0, b"")]


def test_servos_only_hear_their_baud_rate(fresh_arm):
    slow = RawPort(fresh_arm.port, baud=termios.B57600)
    try:
        slow.send(1, fp.INST_PING)
        assert slow.receive(1, timeout=0.1) == b""
    finally:
        slow.close()


def test_wire_timing_reply_never_precedes_the_wire(raw, fresh_arm):
    """With wire timing the 6 replies of a SYNC_READ cannot all arrive before the bytes' time."""
    fresh_arm.set_wire_timing(True)
    wire_s = (8 + 6 + 6 * 8) * 10 / 1_000_000  # request + six 8-byte replies at 1 Mbaud
    for _ in range(20):
        t0 = time.perf_counter()
        raw.send(fp.BROADCAST_ID, fp.INST_SYNC_READ, [56, 2, 1, 2, 3, 4, 5, 6])
        data = raw.receive(48, timeout=0.2)
        elapsed = time.perf_counter() - t0
        assert len(split_status(data)) == 6
        assert elapsed >= wire_s


def test_set_pose_rejects_configurations_outside_the_limits(fresh_arm):
    with pytest.raises(JointLimitError, match="elbow_flex"):
        fresh_arm.set_pose(HOME | {"elbow_flex": 120.0})


def test_command_line_refuses_the_viewer_without_a_display():
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    result = subprocess.run([sys.executable, str(REPO / "virtual_so101.py"), "--viewer"],
                            env=env, capture_output=True, text=True, timeout=60)
    assert result.returncode != 0
    assert "display" in result.stderr


# --- lerobot's bus against the virtual arm ---------------------------------------------------
@pytest.mark.hw
def test_connect_handshake_configure_and_torque(fresh_arm, lerobot_bus_factory):
    bus = lerobot_bus_factory(fresh_arm)  # connect() pings, checks model 777 and firmware
    assert bus.is_calibrated  # registers seeded from the calibration
    bus.configure_motors()
    for joint in JOINTS:
        registers = fresh_arm.registers(joint)
        assert (registers["Return_Delay_Time"], registers["Maximum_Acceleration"],
                registers["Acceleration"]) == (0, 254, 254)
    bus.disable_torque()
    assert not any(fresh_arm.torque_enabled().values())
    assert fresh_arm.registers("gripper")["Lock"] == 0
    bus.enable_torque()
    assert all(fresh_arm.torque_enabled().values())
    assert fresh_arm.registers("gripper")["Lock"] == 1
    bus.disconnect()  # disables torque, as on a real arm
    assert not any(fresh_arm.torque_enabled().values())


@pytest.mark.hw
def test_sync_read_reports_the_simulated_pose(bus, fresh_arm):
    fresh_arm.set_pose(POSE)
    present = bus.sync_read("Present_Position")
    for joint in JOINTS:
        tol = GRIPPER_TICK if joint == "gripper" else TICK_DEG
        # within a tick, and the count the encoder reads off at times (ENCODER_NOISE)
        assert present[joint] == pytest.approx(POSE[joint], abs=2 * tol), joint


@pytest.mark.hw
def test_commanded_pose_is_reached_and_matches_the_simulator(bus, fresh_arm, model):
    bus.sync_write("Goal_Position", POSE)
    # The goals went through lerobot's own unnormalisation, in one SYNC_WRITE, in order.
    expected_raw = bus._unnormalize({bus.motors[j].id: v for j, v in POSE.items()})
    log = fresh_arm.goal_log()
    assert [(servo_id, raw) for _, servo_id, raw in log] == list(expected_raw.items())
    # The actuator targets are the commanded user units, through the calibration (<= 1 tick).
    commanded = fresh_arm.commanded_positions()
    for joint in JOINTS:
        tol = GRIPPER_TICK if joint == "gripper" else TICK_DEG
        assert commanded[joint] == pytest.approx(POSE[joint], abs=tol), joint
    rest = resting(POSE)  # raw goals, no feed-forward: the arm sags (the gripper squeezes none)
    present = wait_until_reached(bus, rest, tol=1.0)
    assert all(abs(present[j] - rest[j]) <= 1.0 for j in JOINTS), present
    time.sleep(0.5)
    measured = fresh_arm.joint_positions()
    for joint in JOINTS:
        assert measured[joint] == pytest.approx(rest[joint], abs=1.0), joint
    # The same dict sent to the plain simulator, on the same servo, lands at the same place.
    import mujoco

    from so101_kinematics.sim import actuation

    sim = smu.load_model()
    actuation.use_servo(sim, volts=SUPPLY_V, p=32, feedforward=False)  # the virtual arm's 5 V
    d = mujoco.MjData(sim)
    smu.set_initial_pose(d, HOME)
    smu.send_position_command(d, POSE)
    smu.hold_position(sim, d, None, 3.0)
    simulated = smu.get_configuration(sim, d)
    for joint in JOINTS:
        assert measured[joint] == pytest.approx(simulated[joint], abs=0.5), joint
    # Goal_Position reads back as commanded (lerobot's truncation loses at most one tick).
    goal = bus.sync_read("Goal_Position")
    for joint in JOINTS:
        tol = GRIPPER_TICK if joint == "gripper" else TICK_DEG
        assert goal[joint] == pytest.approx(POSE[joint], abs=tol + 1e-9), joint


@pytest.mark.hw
def test_gripper_range_0_100_round_trip(bus, fresh_arm):
    for opening in (0.0, 55.0, 100.0):
        bus.write("Goal_Position", "gripper", opening)
        present = wait_until_reached(bus, {"gripper": opening}, tol=0.5)
        assert present["gripper"] == pytest.approx(opening, abs=0.5)
        time.sleep(0.3)  # settle (the jaw overshoots its soft joint limit while moving)
        assert fresh_arm.joint_positions()["gripper"] == pytest.approx(opening, abs=1.0)


@pytest.mark.hw
def test_homing_offset_shifts_present_position(bus, fresh_arm):
    # As in a calibration: torque off, and the joint held still (blocked) while we look.
    bus.disable_torque("wrist_flex")
    fresh_arm.inject("stall:wrist_flex")
    before = bus.read("Present_Position", "wrist_flex", normalize=False)
    offset = bus.read("Homing_Offset", "wrist_flex", normalize=False)
    bus.write("Homing_Offset", "wrist_flex", offset + 100, normalize=False)
    try:
        after = bus.read("Present_Position", "wrist_flex", normalize=False)
        # Present_Position = encoder - Homing_Offset, give or take the encoder's noise (a
        # count either way on some reads: virtual.registers, SERVO_NOTES.md).
        assert abs(after - (before - 100)) <= 2
        assert not bus.is_calibrated  # lerobot now sees a mismatch with its file
    finally:
        bus.write("Homing_Offset", "wrist_flex", offset, normalize=False)
    assert bus.is_calibrated


@pytest.mark.hw
def test_goals_are_clamped_to_the_position_limits(bus, fresh_arm):
    limit = bus.read("Max_Position_Limit", "shoulder_pan", normalize=False)
    bus.write("Max_Position_Limit", "shoulder_pan", 2047 + 200, normalize=False)  # 17.6 deg
    try:
        bus.write("Goal_Position", "shoulder_pan", 40.0)
        assert fresh_arm.commanded_positions()["shoulder_pan"] == pytest.approx(200 * TICK_DEG)
    finally:
        bus.write("Max_Position_Limit", "shoulder_pan", limit, normalize=False)


@pytest.mark.hw
def test_torque_off_makes_the_joint_limp(bus, fresh_arm):
    fresh_arm.set_pose(HOME | {"shoulder_lift": 0.0, "elbow_flex": 0.0})  # arm stretched out
    bus.disable_torque("shoulder_lift")
    time.sleep(0.6)
    sagged = fresh_arm.joint_positions()["shoulder_lift"]
    assert abs(sagged) > 5.0, "gravity should move a limp joint"
    # The limp servo's goal follows its position, so enabling torque does not jump.
    # (It may still be swinging: the goal read lies between two position reads.)
    before = bus.read("Present_Position", "shoulder_lift", normalize=False)
    goal = bus.read("Goal_Position", "shoulder_lift", normalize=False)
    after = bus.read("Present_Position", "shoulder_lift", normalize=False)
    assert min(before, after) - 1 <= goal <= max(before, after) + 1


@pytest.mark.hw
def test_no_late_or_extra_bytes_after_transactions(bus, fresh_arm):
    for i in range(50):
        target = HOME | {"wrist_roll": float(i % 10)}
        bus.sync_write("Goal_Position", target)
        present = bus.sync_read("Present_Position")  # right after a broadcast: no stray reply
        assert present["elbow_flex"] == pytest.approx(HOME["elbow_flex"], abs=2.0)
    bus.read("Present_Load", "gripper")
    time.sleep(0.1)
    assert bus.port_handler.ser.in_waiting == 0
    stats = fresh_arm.reply_stats()
    assert stats["replies"] >= 50 * 6 and stats["late_replies"] == 0


@pytest.mark.hw
def test_so101_follower_connects_without_prompting_and_moves(fresh_arm, monkeypatch):
    pytest.importorskip("lerobot")
    from lerobot.robots.so_follower import SO101Follower, SO101FollowerConfig

    def no_prompt(*args, **kwargs):
        raise AssertionError(f"SO101Follower prompted: {args}")

    monkeypatch.setattr("builtins.input", no_prompt)
    config = SO101FollowerConfig(port=fresh_arm.port, id=DEFAULT_CALIBRATION_PATH.stem,
                                 calibration_dir=DEFAULT_CALIBRATION_PATH.parent)
    robot = SO101Follower(config)
    robot.connect()
    try:
        assert robot.is_calibrated
        assert all(fresh_arm.torque_enabled().values())
        assert fresh_arm.registers("gripper")["Max_Torque_Limit"] == 500
        observation = robot.get_observation()
        # lerobot's configure lets the arm go limp for a moment (torque off, the registers,
        # torque on where it then is): the elbow may have sagged, by how much depends on the
        # bus's timing. What lerobot reports must be where the arm is, within a degree.
        truth = fresh_arm.joint_positions()["elbow_flex"]
        assert observation["elbow_flex.pos"] == pytest.approx(truth, abs=1.0)
        assert abs(truth - HOME["elbow_flex"]) < 15.0  # seen: 4.7 deg on a loaded machine
        robot.send_action({f"{j}.pos": v for j, v in POSE.items()})
        rest = resting(POSE, p=16)  # lerobot's P = 16, no feed-forward: the arm sags
        present = wait_until_reached(robot.bus, rest, tol=1.5)
        assert all(abs(present[j] - rest[j]) <= 1.5 for j in JOINTS), present
    finally:
        robot.disconnect()
    assert not any(fresh_arm.torque_enabled().values())


# --- faults give lerobot's own errors --------------------------------------------------------
@pytest.mark.hw
def test_dropped_reply_is_a_timeout(bus, fresh_arm):
    fresh_arm.inject("drop:3")
    with pytest.raises(ConnectionError, match="There is no status packet"):
        bus.read("Present_Position", "elbow_flex")
    assert bus.read("Present_Position", "elbow_flex") == pytest.approx(90.0, abs=1.0)  # 1 dropped
    fresh_arm.inject("drop:elbow_flex:2")
    for _ in range(2):
        with pytest.raises(ConnectionError, match="Failed to sync read.*There is no status packet"):
            bus.sync_read("Present_Position")
    assert bus.sync_read("Present_Position")["elbow_flex"] == pytest.approx(90.0, abs=1.0)


@pytest.mark.hw
def test_corrupt_reply_is_an_incorrect_status_packet(bus, fresh_arm):
    fresh_arm.inject("corrupt:2")
    with pytest.raises(ConnectionError, match="Incorrect status packet"):
        bus.read("Present_Position", "shoulder_lift")
    fresh_arm.inject("corrupt:shoulder_lift")
    with pytest.raises(ConnectionError, match="Failed to sync read.*Incorrect status packet"):
        bus.sync_read("Present_Position")


@pytest.mark.hw
def test_removed_servo_is_missing_at_connect(fresh_arm, lerobot_bus_factory):
    fresh_arm.inject("remove:4")
    bus = lerobot_bus_factory(fresh_arm, connect=False)
    with pytest.raises(RuntimeError, match=r"Missing motor IDs:\n  - 4 \(expected model: 777\)"):
        bus.connect()
    bus.port_handler.closePort()


@pytest.mark.hw
def test_wrong_firmware_fails_the_handshake(fresh_arm, lerobot_bus_factory):
    fresh_arm.inject("firmware:6:3.9")
    bus = lerobot_bus_factory(fresh_arm, connect=False)
    with pytest.raises(RuntimeError, match="Some Motors use different firmware versions"):
        bus.connect()
    bus.port_handler.closePort()


@pytest.mark.hw
def test_stalled_joint_misses_its_goal_with_rising_load_and_overload(bus, fresh_arm):
    fresh_arm.inject("stall:elbow_flex")
    bus.sync_write("Goal_Position", HOME | {"elbow_flex": 60.0, "wrist_flex": 10.0})
    time.sleep(0.1)
    first = abs(bus.sync_read("Present_Load", normalize=False)["elbow_flex"])
    time.sleep(0.15)
    second = abs(bus.sync_read("Present_Load", normalize=False)["elbow_flex"])
    assert 0 < first < second, (first, second)
    time.sleep(0.5)
    present = bus.sync_read("Present_Position")  # sync_read ignores status bits
    assert present["elbow_flex"] == pytest.approx(90.0, abs=0.5)  # blocked, off its goal
    p = fresh_arm.registers("wrist_flex")["P_Coefficient"]  # 32, or lerobot's 16 if it wrote it
    # the others still move: to the goal less the sag, within the friction band on the
    # approach side (0.5 deg at P = 16 on 5 V) and what is left to settle after 0.75 s: the
    # D term fitted to real arms (docs/servo_model.md) brakes the approach, so more is left
    # (measured here: 1.58 deg short, where the old D left less than 1.5; the simulator
    # without the stalled elbow: 0.56 deg at 0.75 s, 0.34 at 3 s)
    assert present["wrist_flex"] == pytest.approx(
        resting(HOME | {"wrist_flex": 10.0}, p=p)["wrist_flex"], abs=2.0)
    with pytest.raises(RuntimeError, match="Overload error"):
        bus.read("Present_Position", "elbow_flex")
    fresh_arm.clear_faults()
    expected = resting(HOME | {"elbow_flex": 60.0, "wrist_flex": 10.0}, p=p)["elbow_flex"]
    assert wait_until_reached(bus, {"elbow_flex": expected})["elbow_flex"] == pytest.approx(
        expected, abs=1)


@pytest.mark.hw
def test_command_line_serves_with_faults_from_power_up(lerobot_bus_factory):
    process = subprocess.Popen([sys.executable, str(REPO / "virtual_so101.py"),
                                "--faults", "remove:wrist_flex"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        port = process.stdout.readline().strip()
        assert port.startswith("/dev/")

        class Port:  # enough of VirtualSO101 for make_bus
            calibration = vcal.load_calibration(DEFAULT_CALIBRATION_PATH)

        Port.port = port
        bus = lerobot_bus_factory(Port, connect=False)
        with pytest.raises(RuntimeError, match=r"Missing motor IDs:\n  - 4 "):
            bus.connect()
        bus.port_handler.closePort()
    finally:
        process.send_signal(2)  # Ctrl-C
        assert process.wait(timeout=20) == 0


@pytest.mark.hw
def test_lock_decides_which_eeprom_writes_survive_a_power_cycle(bus, fresh_arm):
    bus.disable_torque("wrist_roll")  # lerobot: Torque_Enable = 0, then Lock = 0
    bus.write("P_Coefficient", "wrist_roll", 16)  # saved (unlocked)
    bus.enable_torque("wrist_roll")  # Torque_Enable = 1, Lock = 1
    bus.write("D_Coefficient", "wrist_roll", 10)  # acts now, not saved (locked)
    assert fresh_arm.registers("wrist_roll")["D_Coefficient"] == 10
    fresh_arm.set_torque(False, ["wrist_roll"])  # (Lock stays 1)
    fresh_arm.power_cycle()
    registers = fresh_arm.registers("wrist_roll")
    assert (registers["P_Coefficient"], registers["D_Coefficient"]) == (16, 32)
    assert registers["Torque_Enable"] == 0  # a servo powers up limp
    assert bus.is_calibrated  # calibration registers were saved with the arm
    bus.enable_torque()  # and the servos work again after the power cycle
    bus.write("Goal_Position", "wrist_roll", 30.0)
    assert wait_until_reached(bus, {"wrist_roll": 30.0})["wrist_roll"] == pytest.approx(30, abs=1)


@pytest.mark.hw
def test_measure_cycle_reports_wire_time_and_no_late_replies(fresh_arm):
    pytest.importorskip("lerobot")
    result = measure_cycle(n=100, wire_timing=True, arm=fresh_arm, warmup=10)
    assert result["wire_ms"] == pytest.approx(0.88)  # 88 bytes at 1 Mbaud, 10 bits a byte
    assert result["cycle_median_ms"] >= result["wire_ms"]  # replies wait for their bytes' time
    assert result["late_replies"] == 0
    assert result["host_median_ms"] > 0  # lerobot's own cost, timed on the loopback port


@pytest.mark.hw
def test_lerobot_broadcast_ping_finds_six_sts3215(bus):
    assert bus.broadcast_ping() == dict.fromkeys(range(1, 7), 777)

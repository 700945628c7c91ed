"""The virtual arm's servos against the STS3215's measurements, through lerobot's bus.

The virtual arm runs the simulator's servo model (so101_kinematics/sim/sts3215.py) driven by
the registers a client writes. Expected values come from the measurements quoted in
so101_kinematics/servo.py's sources ([TEL] roboninecom's telemetry, [BAM] Rhoban's identification)
and from the hand calculation gravity torque / stiffness; the windows are the issue's.
"""

from __future__ import annotations

import math
import time

import pytest

pytest.importorskip("lerobot")
pytestmark = pytest.mark.hw

from so101_forward_kinematics import ARM_JOINTS, get_forward_kinematics  # noqa: E402
from so101_kinematics.calibration import load_calibration  # noqa: E402
from so101_kinematics.hw import run as hw  # noqa: E402
from so101_kinematics.hw.bus import (  # noqa: E402
    configure,
    connect,
    disconnect,
    enable_torque_in_place,
)
from so101_kinematics.planning.plans import default_plan, pick_and_place_steps  # noqa: E402
from so101_kinematics.servo import KIT_SUPPLY_V  # noqa: E402
from so101_kinematics.virtual.arm import VirtualSO101  # noqa: E402
from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH  # noqa: E402

CALIBRATION = load_calibration(DEFAULT_CALIBRATION_PATH)
ZERO = dict.fromkeys(ARM_JOINTS, 0.0) | {"gripper": 50.0}
COUNTS_PER_DEG = 4096 / 360


def law(error_counts: float, p: int) -> float:
    """[TEL]: Present_Load = Minimum_Startup_Force + (P/4)(|e| - dead zone), defaults 16, 1."""
    return 16 + p / 4 * (abs(error_counts) - 1)


def rest_at_zero(bus, seconds: float = 3.0) -> tuple[float, int]:
    """Command the all-zero pose, wait; shoulder_lift's (error [deg], Present_Load)."""
    bus.sync_write("Goal_Position", ZERO)
    time.sleep(seconds)
    position = bus.sync_read("Present_Position")["shoulder_lift"]
    load = bus.read("Present_Load", "shoulder_lift", normalize=False)
    return position - ZERO["shoulder_lift"], load


@pytest.mark.slow
def test_at_lerobots_settings_the_shoulder_sags_and_its_load_follows_the_law():
    # the sag window is the kit's 5 V C001's (the issue's 5.3 deg): its arm, pinned
    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH, initial=ZERO,
                      supply=KIT_SUPPLY_V) as arm:
        bus = connect(arm.port, CALIBRATION)
        try:
            configure(bus)  # what lerobot's follower writes: P 16, D 32, I 0
            enable_torque_in_place(bus)
            error, load = rest_at_zero(bus)
            assert 2.0 <= abs(error) <= 9.0  # the window around 5.3 deg (5 V)
            magnitude = abs(load) if load < 0 else load & 0x3FF  # sign bit 10 [MEM]
            expected = law(error * COUNTS_PER_DEG, 16)
            assert magnitude == pytest.approx(expected, rel=0.3)
            bus.write("P_Coefficient", "shoulder_lift", 32)  # stiffer, as measured
            stiffer, _ = rest_at_zero(bus)
            assert 0.35 <= abs(stiffer) / abs(error) <= 0.7
        finally:
            disconnect(bus)


@pytest.mark.slow
def test_acceleration_20_and_goal_velocity_1000_make_a_triangle_of_about_450_counts_per_s():
    # [TEL]: a 100-count move peaks near 450 counts/s and takes 0.4-0.5 s; the wrist_roll
    # joint carries no gravity load (the arm at rest, the roll axis vertical).
    initial = dict(ZERO, wrist_flex=90.0)
    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH, initial=initial) as arm:
        bus = connect(arm.port, CALIBRATION)
        try:
            enable_torque_in_place(bus)
            bus.write("Acceleration", "wrist_roll", 20)
            bus.write("Goal_Velocity", "wrist_roll", 1000)
            time.sleep(0.5)
            start = bus.read("Present_Position", "wrist_roll", normalize=False)
            bus.write("Goal_Position", "wrist_roll", start + 100, normalize=False)
            t0, seen = time.perf_counter(), []
            while time.perf_counter() - t0 < 1.2:
                speed = bus.read("Present_Velocity", "wrist_roll", normalize=False)
                seen.append((time.perf_counter() - t0, speed))
            speeds = [abs(v) if v < 0 else v & 0x7FFF for _, v in seen]  # sign bit 15
            assert all(v % 50 == 0 for v in speeds)  # Present_Velocity in 50 counts/s steps
            assert 380 <= max(speeds) <= 520
            moving = [t for t, v in seen if v]
            assert 0.35 <= moving[-1] - moving[0] <= 0.6
        finally:
            disconnect(bus)


def place_error_mm(gravity_ff: bool) -> float:
    """The course's default plan through the hardware path, the cube where the FK picks it."""
    (pick, rotation), (place, _) = (get_forward_kinematics({j: s.configuration[j]
                                                            for j in ARM_JOINTS})
                                    for s in pick_and_place_steps(default_plan()))
    yaw = math.degrees(math.atan2(rotation[1, 0], rotation[0, 0]))  # as the jaws meet it
    # the kit's 5 V C001 arm: the figures below (14 mm without, README's 14.3) are its
    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH, cube=(pick[0], pick[1], yaw),
                      supply=KIT_SUPPLY_V) as arm:
        result = hw.run_on_arm(arm.port, CALIBRATION, default_plan(), gravity_ff=gravity_ff)
        assert result.aborted is None and result.torque_released
        x, y, _ = arm.cube().position_m
    return 1000 * math.hypot(x - place[0], y - place[1])


@pytest.mark.slow
def test_the_feedforward_places_the_cube_within_5_mm_where_the_sag_misses_it():
    # The simulator, on the same servo model, says 14 mm without and 1.3 mm with it.
    assert place_error_mm(gravity_ff=False) > 10.0
    assert place_error_mm(gravity_ff=True) <= 5.0


@pytest.mark.slow
def test_through_the_course_helpers_the_start_pose_rests_within_half_a_degree(course_arm):
    # so101_utils on the virtual arm at lerobot's P = 16 on the kit's 5 V: with the
    # feed-forward (the default) the course's start configuration holds within 0.5 deg a
    # joint; without it the shoulder sags degrees.
    import so101_kinematics.hw.course_helpers as course
    import so101_utils
    from so101_kinematics.planning.plans import STARTING_CONFIGURATION

    def rest(gravity_ff: bool) -> float:
        bus = so101_utils.setup_motors(so101_utils.load_calibration(str(DEFAULT_CALIBRATION_PATH)),
                                       course_arm.port, gravity_ff=gravity_ff)
        so101_utils.move_to_pose(bus, STARTING_CONFIGURATION, 2.5)
        so101_utils.hold_position(bus, 1.5)
        measured = bus.sync_read("Present_Position")
        for run in list(course._RUNS.values()):
            course.end_at_start(run, "measured")
        return max(abs(measured[j] - STARTING_CONFIGURATION[j]) for j in ARM_JOINTS)

    assert rest(gravity_ff=True) <= 0.5
    assert rest(gravity_ff=False) > 1.5

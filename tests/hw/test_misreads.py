"""A reading no servo could give is refused (hw/misreads.py), and the loop never acts on it."""

from __future__ import annotations

import pytest
from hw_fakes import HOME, make_session

from so101_forward_kinematics import JOINTS
from so101_kinematics.hw.misreads import Misread, ReadingCheck

LIMITS = {joint: (-110.0, 110.0) for joint in JOINTS} | {"gripper": (0.0, 100.0)}
POSE = {"shoulder_pan": 0.0, "shoulder_lift": -90.0, "elbow_flex": 90.0, "wrist_flex": 30.0,
        "wrist_roll": 0.0, "gripper": 10.0}
# The misread seen on the virtual arm through lerobot 0.4.4 (a cubic run's log, one cycle):
# the arm joints 256 counts (22.5 deg) apart, about -2900 deg.
GARBLED = {"shoulder_pan": -2925.7, "shoulder_lift": -2903.2, "elbow_flex": -2880.7,
           "wrist_flex": -2858.2, "wrist_roll": -2835.7, "gripper": 0.0}


def test_the_garbled_reading_seen_on_the_bus_is_refused():
    check = ReadingCheck(LIMITS)
    with pytest.raises(Misread, match="shoulder_pan read -2925.7, outside its calibrated range"):
        check(GARBLED, 0.0)
    assert check.refused == 1


def test_a_reading_a_few_degrees_past_the_calibrated_stops_is_a_pose():
    check = ReadingCheck(LIMITS)
    assert check(POSE | {"elbow_flex": 115.0}, 0.0)["elbow_flex"] == 115.0


def test_a_joint_at_the_fastest_servos_speed_is_accepted_and_a_jump_is_not():
    # 312 deg/s is the C001 datasheet's 52 rpm: in a 10 ms cycle 3.1 deg.
    check = ReadingCheck(LIMITS)
    check(POSE, 0.0)
    check(POSE | {"shoulder_pan": 3.1}, 0.010)
    with pytest.raises(Misread, match="shoulder_pan read 40.0, 36.9 deg from 10 ms before"):
        check(POSE | {"shoulder_pan": 40.0}, 0.020)


def test_the_time_between_samples_runs_from_the_last_reads_start_to_this_ones_end():
    # CI's slow leg: two reads' ends 1 ms apart, the first stamped late (the machine loaded);
    # their samples were further apart, and the ends' 1 ms (2.6 deg allowed) called the
    # swinging shoulder_pan's 2.8 deg a misread. Here the first read took 20 ms.
    check = ReadingCheck(LIMITS)
    check(POSE, 1.000, started=0.980)
    assert check(POSE | {"shoulder_pan": 2.8}, 1.001, started=1.0005)["shoulder_pan"] == 2.8
    # the window is the longest the samples can be apart, and no longer: 312 x 2 deg/s x
    # (1.010 - 1.0005) s + 2 deg = 7.9 deg
    with pytest.raises(Misread, match="shoulder_pan read 11.0, 8.2 deg from 10 ms before"):
        check(POSE | {"shoulder_pan": 11.0}, 1.010, started=1.009)


def test_after_a_jump_the_next_reading_is_judged_by_the_range_alone():
    # One of two readings was wrong; which is unknown: a bad pose must not lock out the rest.
    check = ReadingCheck(LIMITS)
    check(POSE | {"shoulder_pan": 60.0}, 0.0)  # a misread inside the range, accepted
    with pytest.raises(Misread):
        check(POSE, 0.010)  # the true pose, refused once as a jump from it
    assert check(POSE, 0.020) == POSE


def test_after_a_long_silence_any_pose_in_the_range_is_accepted():
    check = ReadingCheck(LIMITS)
    check(POSE, 0.0)
    assert check(POSE | {"shoulder_pan": 90.0}, 1.0)["shoulder_pan"] == 90.0


# --- the control loop never acts on a misread -----------------------------------------------
def test_a_garbled_reading_mid_move_is_a_failed_read_and_the_move_completes(calibration, clock):
    def garble(session, cycle):
        if len(session.cycles) == 30:
            session.bus.garbled_reads = 1

    session, bus = make_session(calibration, clock, on_cycle=garble)
    goal = dict(HOME, wrist_flex=0.0)
    session.move(goal, 1.0)
    measured = [c.measured for c in session.cycles]
    assert sum(m is None for m in measured) == 1  # one cycle unobserved, none acted on
    assert all(m["shoulder_pan"] > -200 for m in measured if m is not None)
    assert bus.pose == pytest.approx(goal) and session.readings.refused == 1


def test_a_controlled_stop_on_a_garbled_reading_never_commands_it(calibration, clock):
    # Clamped to the calibrated range, the misread would send every joint to its lower limit.
    session, bus = make_session(calibration, clock)
    session.move(dict(HOME, wrist_flex=40.0), 0.5)
    sent = len(bus.goals)
    bus.garbled_reads = 1
    assert session.stop_here() is None  # unobserved: the servos hold their last goals
    assert len(bus.goals) == sent
    pose = session.wait_for_arm()  # the next reading is the arm's
    assert pose["wrist_flex"] == pytest.approx(40.0) and bus.goals[-1] == pytest.approx(pose)

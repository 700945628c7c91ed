"""The bus setup_motors hands out (hw/guarded.py), against the virtual SO-101 via lerobot's bus.

A student's own ``bus.sync_write("Goal_Position", ...)`` is ramped at the speed cap and
checked as ``move_to_pose`` is (issue 28, Deliver 2); after a goal written on the bus, guarded
or raw, the next ``move_to_pose`` starts from where the arm is (issue 29, Deliver 5).
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from so101_kinematics.calibration import load_calibration
from so101_kinematics.constants import HOME_POSE
from so101_kinematics.hw.course_calibration import ScriptEnded
from so101_kinematics.hw.timing import MAX_JOINT_SPEED_DEG_S
from so101_kinematics.planning.plans import STARTING_CONFIGURATION

pytestmark = pytest.mark.hw
CALIBRATION_PATH = Path(__file__).resolve().parents[2] / "calibration" / "virtual_so101.json"
TICKS_PER_DEG = 4095 / 360.0  # lerobot's DEGREES normalisation (FEETECH_NOTES.md)
PAN = 1  # shoulder_pan's servo id


def pan_goals(arm, since=0):
    return [ticks for _, servo, ticks in arm.goal_log()[since:] if servo == PAN]


def setup(arm):
    from so101_utils import load_calibration as course_load
    from so101_utils import setup_motors
    return setup_motors(course_load(str(CALIBRATION_PATH)), arm.port)


@pytest.mark.slow
@pytest.mark.newest_lerobot
def test_a_students_goal_write_is_ramped_at_the_speed_cap_not_jumped(course_arm, caplog):
    bus = setup(course_arm)
    start = bus.sync_read("Present_Position")
    sent = len(course_arm.goal_log())
    target = dict(start, shoulder_pan=start["shoulder_pan"] + 40.0)
    began = time.perf_counter()
    bus.sync_write("Goal_Position", target)
    took = time.perf_counter() - began
    goals = pan_goals(course_arm, sent)
    steps = [abs(b - a) for a, b in zip(goals, goals[1:], strict=False)]
    # 40 deg at the cap: minimum jerk's peak 1.875 x the mean speed, ~100 Hz cycles
    assert took >= 40.0 * 1.875 / MAX_JOINT_SPEED_DEG_S * 0.9
    assert len(goals) > 20 and max(steps) <= MAX_JOINT_SPEED_DEG_S * 0.05 * TICKS_PER_DEG
    # The ramp's last goal is sent at its end; the servo settles after it (its lag at P = 16,
    # 0.1 s: servo.lag): give it 0.5 s, then within 1.5 deg (measured 1.51 deg at once, once).
    settle = time.perf_counter() + 0.5
    while (abs(course_arm.joint_positions()["shoulder_pan"] - target["shoulder_pan"]) >= 1.5
           and time.perf_counter() < settle):
        time.sleep(0.02)
    assert abs(course_arm.joint_positions()["shoulder_pan"] - target["shoulder_pan"]) < 1.5
    assert "ramped at the speed cap" in caplog.text
    bus.disable_torque()
    assert not any(course_arm.torque_enabled().values())


@pytest.mark.slow
@pytest.mark.newest_lerobot
def test_a_goal_write_into_the_table_is_refused_and_ends_at_the_start(course_arm, capsys):
    from so101_utils import move_to_pose

    bus = setup(course_arm)
    move_to_pose(bus, STARTING_CONFIGURATION, 1.5)
    with pytest.raises(ScriptEnded) as ended:
        bus.sync_write("Goal_Position", dict(STARTING_CONFIGURATION, shoulder_lift=53.0))
    err = capsys.readouterr().err
    assert ended.value.code == 1 and "into the table" in err
    assert err.strip().splitlines()[-1] == "Back at the starting pose, torque off."


@pytest.mark.slow
@pytest.mark.newest_lerobot
def test_a_goal_outside_the_calibration_is_refused(course_arm, capsys):
    bus = setup(course_arm)
    from so101_kinematics.calibration import calibrated_limits
    upper = calibrated_limits(load_calibration(CALIBRATION_PATH))["elbow_flex"][1]
    with pytest.raises(ScriptEnded):
        bus.write("Goal_Position", "elbow_flex", upper + 10.0)
    err = capsys.readouterr().err
    assert f"elbow_flex = {upper + 10.0:.5f} deg is outside" in err and "calibrated range" in err
    assert "ramped" not in err


def test_raw_ticks_are_refused_in_one_line_and_raw_lerobot_is_bus_raw(course_arm, capsys):
    from lerobot.motors.feetech import FeetechMotorsBus

    bus = setup(course_arm)
    assert isinstance(bus.raw, FeetechMotorsBus)
    with pytest.raises(ScriptEnded) as ended:
        bus.sync_write("Goal_Position", {"shoulder_pan": 2047}, normalize=False)
    assert ended.value.code == 2
    assert "normalize=False" in capsys.readouterr().err and "bus.raw" in str(ended.value.line)


@pytest.mark.slow
@pytest.mark.newest_lerobot
@pytest.mark.parametrize("how", ["guarded", "raw"])
def test_move_to_pose_after_a_students_own_write_starts_where_the_arm_is(course_arm, capsys,
                                                                          how):
    """Week 8's ``bus.sync_write("Goal_Position", offset_config(cfg))``, wait, then
    ``move_to_pose(bus, starting_pose, 2.0)``: it must not abort on tracking."""
    from so101_utils import move_to_pose

    bus = setup(course_arm)
    starting_pose = bus.sync_read("Present_Position")
    cfg = dict(HOME_POSE, shoulder_pan=25.0, shoulder_lift=-70.0, elbow_flex=70.0)
    (bus if how == "guarded" else bus.raw).sync_write("Goal_Position", cfg)
    time.sleep(2.0)
    assert abs(course_arm.joint_positions()["shoulder_pan"] - 25.0) < 1.5
    written = pan_goals(course_arm)[-1]  # the goal the arm holds [ticks]
    sent = len(course_arm.goal_log())
    move_to_pose(bus, starting_pose, 2.0)
    first = pan_goals(course_arm, sent)[0]
    assert abs(first - written) <= 2.0 * TICKS_PER_DEG, "the move starts where the arm is"
    assert abs(course_arm.joint_positions()["shoulder_pan"] - starting_pose["shoulder_pan"]) < 1.5
    bus.disable_torque()
    out = capsys.readouterr()
    assert "ABORTED" not in out.err
    assert out.out.strip().splitlines()[-1] == "Done: back at the starting pose, torque off."

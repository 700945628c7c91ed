"""Two arms in one program through the course's helpers (so101_utils): each its own bus and run.

The two-arm final projects (issue 38) set up two arms in one script. Each
``setup_motors`` hands out its own guarded bus, on its own port; a move on one
leaves the other where it is, and ending one leaves the other set up: torqued,
its script's SIGTERM still a controlled stop, Python's full garbage collection
still kept out of its moves (hw/course_helpers.py keeps those process-wide
settings until the last arm ends).
"""

from __future__ import annotations

import gc
import signal

import pytest

pytest.importorskip("lerobot")
pytestmark = [pytest.mark.hw, pytest.mark.slow]

from so101_kinematics.servo import KIT_SUPPLY_V  # noqa: E402
from so101_kinematics.virtual.arm import VirtualSO101  # noqa: E402
from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH  # noqa: E402


def test_two_arms_set_up_in_one_program_move_and_end_each_on_its_own():
    import so101_kinematics.hw.course_helpers as course
    import so101_utils

    calibration = so101_utils.load_calibration(str(DEFAULT_CALIBRATION_PATH))
    original = signal.getsignal(signal.SIGTERM)
    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH, supply=KIT_SUPPLY_V) as left_arm, \
            VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH, supply=KIT_SUPPLY_V) as right_arm:
        try:
            left = so101_utils.setup_motors(calibration, left_arm.port)
            right = so101_utils.setup_motors(calibration, right_arm.port)
            assert left is not right and left.raw is not right.raw
            still, goals = right_arm.joint_positions(), right_arm.commanded_positions()
            start = left.sync_read("Present_Position")
            goal = dict(start, shoulder_pan=start["shoulder_pan"] + 15.0)
            so101_utils.move_to_pose(left, goal, 1.5)
            assert left_arm.joint_positions()["shoulder_pan"] == pytest.approx(
                goal["shoulder_pan"], abs=2.0)
            assert right_arm.commanded_positions() == goals  # no goal reached the other arm
            assert right_arm.joint_positions()["shoulder_pan"] == pytest.approx(
                still["shoulder_pan"], abs=0.1)  # and it stayed (its pan bears no weight)

            left.disable_torque()  # the left arm's ending: back to its start, released there
            assert not any(left_arm.torque_enabled().values())
            assert all(right_arm.torque_enabled().values())  # the right one still holds
            assert signal.getsignal(signal.SIGTERM) is not original  # still a controlled stop
            assert gc.get_freeze_count() > 0  # still no full collection during its moves

            so101_utils.move_to_pose(right, dict(still, shoulder_pan=still["shoulder_pan"] - 15),
                                     1.5)  # the right arm still moves after the left one ended
            assert right_arm.joint_positions()["shoulder_pan"] == pytest.approx(
                still["shoulder_pan"] - 15.0, abs=2.0)
            right.disable_torque()
            assert not any(right_arm.torque_enabled().values())
            assert signal.getsignal(signal.SIGTERM) is original  # the last run put it back
            assert gc.get_freeze_count() == 0
        finally:
            for run in list(course._RUNS.values()):
                course.end_at_start(run, "test teardown")

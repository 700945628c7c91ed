"""register_page.py --port: the marks touched by a hand on the limp virtual arm, then fitted."""

from __future__ import annotations

import time

import numpy as np
import pytest

pytest.importorskip("lerobot")
pytestmark = pytest.mark.hw

from so101_kinematics.drawing.page import PAGE_THICKNESS, PAGES, Page, page_to_base  # noqa: E402
from so101_kinematics.drawing.pen import PenPose, pen_configuration  # noqa: E402
from so101_kinematics.drawing.registration import check_fit, fit_page, page_marks  # noqa: E402
from so101_kinematics.frames import ARM_JOINTS  # noqa: E402
from so101_kinematics.lab.page_touch import touch_marks  # noqa: E402
from so101_kinematics.virtual.arm import VirtualSO101  # noqa: E402


def test_marks_touched_by_hand_on_the_limp_arm_give_the_page_pose(calibration):
    page = Page("a5", PAGES["a5"], (0.21, -0.02), -8.0)  # [m], [deg]
    marks = page_marks("a5", 3)
    tips = page_to_base(page, marks, PAGE_THICKNESS)
    prompts = []
    with VirtualSO101() as arm:
        def hand_on_mark(prompt: str) -> None:
            # a student's hand puts the pen's tip on the mark the prompt names
            prompts.append(prompt)
            cfg = pen_configuration(tips[len(prompts) - 1], PenPose(10.0))  # any tilt
            arm.hand_move([cfg])
            arm.hand_wait()
            # and until the joints are there (CI's loaded quick tier once read every mark
            # 20-100 mm off: the hand's motion had not reached it when "Enter" came)
            deadline = time.monotonic() + 10.0
            while time.monotonic() < deadline and any(
                    abs(arm.joint_positions()[j] - cfg[j]) > 0.5 for j in ARM_JOINTS):
                time.sleep(0.05)

        touched = touch_marks(arm.port, calibration, 3, hand_on_mark)
        limp = not any(arm.torque_enabled().values())
    assert limp and len(prompts) == 3 and "mark 2 (bottom-right)" in prompts[1]
    fit = fit_page(marks, touched)
    # the servos read in 0.088 deg steps (0.3 mm at the page), the hand holds within them
    assert fit.rms_mm < 1.0 and np.hypot(*np.subtract(fit.centre, page.centre)) < 1e-3
    assert fit.yaw == pytest.approx(-8.0, abs=0.5)
    check_fit(fit, marks, touched)

"""The whole calibration in the simulator, graded against the model: the issue's acceptance.

Focal lengths within 1 % of the model's; the wrist camera in the gripper and the overhead
camera in the base within 2 mm and 0.5 deg. The expected poses are also read off the MJCF by
hand: the wrist camera's lens at (-0.050, 0, -0.040) m in the gripper body, the overhead
camera's at (0.20, 0, 0.55) m above the base (model/so101.xml, model/table.xml).
"""

from __future__ import annotations

import numpy as np
import pytest

from so101_kinematics.vision.calibration_grades import passes, run_calibration

pytestmark = pytest.mark.vision


@pytest.fixture(scope="module")
def report():
    return run_calibration(views=6, seed=3)


def test_focal_lengths_within_one_percent(report):
    for camera in ("overhead", "wrist"):
        grade = report["intrinsics"][camera]
        assert abs(grade["fx_error_pct"]) < 1.0 and abs(grade["fy_error_pct"]) < 1.0, camera
        assert grade["rms_px"] < 0.5
    assert abs(report["intrinsics"]["fx_error_pct"]) < 1.0


@pytest.mark.parametrize("key", ["wrist", "fixed"])
def test_hand_eye_and_eye_to_hand_within_2_mm_and_half_a_degree(report, key):
    grade = report["hand_eye"][key]
    assert grade["translation_mm"] < 2.0 and grade["rotation_deg"] < 0.5
    assert grade["residual_mm"] < 2.0 and grade["views_used"] >= 3


def test_the_poses_are_where_the_mjcf_puts_the_cameras(report):
    in_gripper = np.array(report["hand_eye"]["wrist"]["camera_in_gripper"])
    assert in_gripper[:3, 3] == pytest.approx([-0.050, 0.0, -0.040], abs=0.002)
    in_base = np.array(report["hand_eye"]["fixed"]["camera_in_base"])
    assert in_base[:3, 3] == pytest.approx([0.20, 0.0, 0.55], abs=0.002)
    assert in_base[:3, 2] == pytest.approx([0.0, 0.0, -1.0], abs=0.01)  # looking straight down
    assert passes(report)


def test_a_grade_out_of_the_acceptance_fails(report):
    worse = {**report, "hand_eye": {**report["hand_eye"], "fixed": {
        **report["hand_eye"]["fixed"], "translation_mm": 2.5}}}
    assert not passes(worse)

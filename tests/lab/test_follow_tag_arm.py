"""The follower on an arm sees through the wrist camera it is given: the model's or a calibration's.

A hand-eye calibration (``calibrate_camera.py --photos DIR --mount wrist``) gives the camera in
the gripper frame (frame 5); the follower needs it in the FK's object frame: the same camera,
carried by the fixed transform between the two frames. Expected values from the model: its
wrist camera in its ``gripper`` body, and where the camera sits in the FK's object frame.
"""

from __future__ import annotations

import json

import mujoco
import numpy as np
import pytest

from so101_kinematics.errors import VisionError
from so101_kinematics.lab.follow_tag_arm import wrist_view
from so101_kinematics.sim.cube import build_model
from so101_kinematics.vision.camera_model import get_camera_pose_base

pytestmark = pytest.mark.vision


def wrist_report(path, K, g_gc=None, size=(640, 480)):
    """A report as calibrate_camera.py --photos DIR --mount wrist --json writes it."""
    data = {"intrinsics": {"K": np.asarray(K).tolist(), "distortion": [0.0] * 5, "rms_px": 0.1,
                           "views_used": 12, "image_size": list(size)}}
    if g_gc is not None:
        data["hand_eye"] = {"wrist": {"camera_in_gripper": np.asarray(g_gc).tolist(),
                                      "residual_mm": 0.1, "residual_deg": 0.05}}
    path.write_text(json.dumps(data))
    return path


def model_camera_in_gripper() -> np.ndarray:
    """The model's wrist camera in its ``gripper`` body (the MJCF's, not the FK's)."""
    m = build_model()
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    def g_w(body):
        g = np.eye(4)
        g[:3, :3], g[:3, 3] = d.body(body).xmat.reshape(3, 3), d.body(body).xpos
        return g

    g_bg = np.linalg.inv(g_w("base")) @ g_w("gripper")
    return np.linalg.inv(g_bg) @ get_camera_pose_base(m, d, "wrist")


def test_a_wrist_calibration_is_the_camera_the_follower_steers(tmp_path):
    K, dist, g_tc = wrist_view()
    assert dist is None
    # the model's camera, as a hand-eye calibration would report it: the same mount
    K2, dist2, g_tc2 = wrist_view(camera_calibration=wrist_report(
        tmp_path / "same.json", K, model_camera_in_gripper()))
    np.testing.assert_allclose(K2, K)
    np.testing.assert_allclose(dist2, np.zeros(5))
    np.testing.assert_allclose(g_tc2[:3, 3], g_tc[:3, 3], atol=1e-5)  # 0.01 mm
    np.testing.assert_allclose(g_tc2[:3, :3], g_tc[:3, :3], atol=1e-5)
    # the calibrated camera 5 mm further along the gripper's x: 5 mm further in the object frame
    moved = model_camera_in_gripper()
    moved[0, 3] += 0.005
    _, _, g_tc3 = wrist_view(camera_calibration=wrist_report(tmp_path / "moved.json", K, moved))
    assert np.linalg.norm(g_tc3[:3, 3] - g_tc[:3, 3]) == pytest.approx(0.005, abs=1e-5)


def test_a_calibration_without_the_wrist_cameras_pose_is_one_line(tmp_path):
    K, _, _ = wrist_view()
    with pytest.raises(VisionError) as error:
        wrist_view(camera_calibration=wrist_report(tmp_path / "intrinsics.json", K))
    message = str(error.value)
    assert "\n" not in message and "--mount wrist" in message

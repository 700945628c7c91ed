"""The real-camera path (lerobot's OpenCVCamera) on a video recorded at test time.

The video is the simulator's angled view of the target tag, written as MJPG; read back
through :class:`Webcam` it must be RGB, close to the render, and give the tag's pose
within the issue's 2 mm / 1 deg.
"""

from __future__ import annotations

import json
import logging
import threading
import time

import mujoco
import numpy as np
import pytest

from so101_kinematics.errors import VisionError
from so101_kinematics.opencv_import import require_opencv
from so101_kinematics.sim.tag_textures import TARGET_TAG
from so101_kinematics.vision.detect import find_tag
from so101_kinematics.vision.sim_camera import SimCamera
from so101_kinematics.vision.tagged_scene import build_tagged_model, tagged_spec
from so101_kinematics.vision.tags import get_tag_pose_base
from so101_kinematics.vision.webcam import Webcam

pytest.importorskip("lerobot")
pytestmark = [pytest.mark.hw, pytest.mark.vision]

TARGET_AT = (0.25, -0.12, -20.0)


def report_of_intrinsics(K, size):
    """The ``intrinsics`` part of the report calibrate_camera.py --photos writes (no lens
    distortion: the simulator's pinhole)."""
    return {"intrinsics": {"K": np.asarray(K).tolist(), "distortion": [0.0] * 5,
                           "rms_px": 0.1, "views_used": 6, "image_size": list(size)}}
PROBE = (0.10, -0.12, 0.26)  # 30 cm from the tag, 30 deg off its normal
PROBE_AXES = [0, -1, 0, 0.866025, 0, 0.5]
RED_PATCH = (0.20, -0.06, 0.002)  # [m] a red square on the table, in view


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """30 frames of the probe's view as an MJPG .avi; the render, K and the truth."""
    cv2 = require_opencv()
    spec = tagged_spec(None, TARGET_AT)
    spec.worldbody.add_camera(name="probe", pos=list(PROBE), xyaxes=PROBE_AXES, fovy=58.0)
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, pos=list(RED_PATCH),
                            size=[0.015, 0.015, 0.001], rgba=[0.9, 0.05, 0.05, 1],
                            contype=0, conaffinity=0)
    m = build_tagged_model(spec=spec)
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_forward(m, d)
    with SimCamera(m, d, "probe") as cam:
        image, K, g_bc = cam.read(), cam.intrinsics(), cam.pose()
    path = tmp_path_factory.mktemp("video") / "probe.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 30.0, (640, 480))
    for _ in range(30):
        writer.write(cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
    writer.release()
    calibration = path.with_suffix(".json")
    calibration.write_text(json.dumps(report_of_intrinsics(K, (640, 480))))
    red_px = np.rint(cam_project(K, g_bc, RED_PATCH)).astype(int)
    return path, calibration, image, g_bc, get_tag_pose_base(m, d, "target_tag"), red_px


def cam_project(K, g_bc, point):
    """A base-frame point's pixel (u, v) in a camera at ``g_bc`` (OpenCV axes)."""
    p = np.linalg.inv(g_bc) @ [*point, 1.0]
    uvw = K @ p[:3]
    return uvw[:2] / uvw[2]


def test_the_video_comes_back_rgb_and_close_to_the_render(recorded):
    path, calibration, render, _, _, (u, v) = recorded
    with Webcam(path, calibration=calibration) as cam:
        frame = cam.read()
    assert frame.shape == (480, 640, 3) and frame.dtype == np.uint8
    assert np.abs(frame.astype(float) - render).mean() < 4.0, "MJPG is lossy, not different"
    r, g, b = frame[v, u].astype(int)
    assert r > 150 and g < 80 and b < 80, ("the red patch must stay red", (r, g, b))


def test_the_tags_pose_from_the_video_is_within_2_mm_and_1_deg(recorded):
    path, calibration, _, g_bc, truth, _ = recorded
    with Webcam(path, calibration=calibration) as cam:
        seen = find_tag(cam.read(), cam.intrinsics(), TARGET_TAG, cam.dist, g_bc=g_bc)
    relative = seen.g_bt[:3, :3].T @ truth[:3, :3]
    angle = np.degrees(np.arccos(np.clip((np.trace(relative) - 1) / 2, -1.0, 1.0)))
    assert np.linalg.norm(seen.g_bt[:3, 3] - truth[:3, 3]) * 1000 <= 2.0
    assert angle <= 1.0


def test_the_end_of_the_video_is_a_stale_frame_in_one_line_and_no_thread_traceback(
        recorded, monkeypatch, caplog):
    # the 30 frames are read in well under a second on an idle machine, then the newest ages;
    # read until it has (a loaded host took more than the 0.3 s this test once waited). A read
    # thread that fails at the end does so at once (11 reads, no wait), before the frame ages.
    raised = []  # what Python would print as "Exception in thread ..." (lerobot's read loop)
    monkeypatch.setattr(threading, "excepthook", raised.append)
    path = recorded[0]
    deadline = time.monotonic() + 30.0
    with Webcam(path, max_age=0.2) as cam, pytest.raises(VisionError, match="stale") as err:
        while time.monotonic() < deadline:
            cam.read()
            time.sleep(0.05)
    assert "\n" not in str(err.value)
    assert [r.exc_value for r in raised] == []
    assert [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING] == []


def test_a_calibration_for_another_size_is_refused_in_one_line(recorded, tmp_path):
    other = tmp_path / "other.json"
    K = [[900.0, 0.0, 640.0], [0.0, 900.0, 360.0], [0.0, 0.0, 1.0]]
    other.write_text(json.dumps(report_of_intrinsics(np.array(K), (1280, 720))))
    with pytest.raises(VisionError, match="another camera") as err:
        Webcam(recorded[0], calibration=other)
    assert "\n" not in str(err.value) and "1280x720" in str(err.value)


def test_a_video_of_another_size_is_a_wrong_resolution(recorded):
    with pytest.raises(VisionError, match="wrong resolution.*640x480") as err:
        Webcam(recorded[0], width=1280, height=720)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("source", ["/dev/video97", 97])
def test_no_camera_there_is_one_line(source, tmp_path):
    with pytest.raises(VisionError, match=f"camera {source}") as err:
        Webcam(source)
    assert "\n" not in str(err.value)


def test_no_calibration_or_a_broken_one_is_one_line(recorded, tmp_path):
    with Webcam(recorded[0]) as cam, pytest.raises(VisionError, match="no calibration") as err:
        cam.intrinsics()
    assert "\n" not in str(err.value)
    broken = tmp_path / "broken.json"
    broken.write_text(json.dumps({"intrinsics": {"K": [[500.0]], "image_size": [640, 480]}}))
    with pytest.raises(VisionError, match="calibrate_camera.py --photos") as err:
        Webcam(recorded[0], calibration=broken)
    assert "\n" not in str(err.value)

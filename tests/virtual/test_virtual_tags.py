"""The virtual arm's served cameras see the tags (``sim/tag_textures.py`` in the emulator's scene).

A virtual arm with a cube and the target tag serves its overhead camera; a frame read with a
student's ``cv2.VideoCapture`` goes through the one detection path (``vision/detect.py``):
the cube tag's position within 2 mm of where the emulator's physics has the cube
(``VirtualSO101.cube()``, which reports no yaw: the cube may turn a little as it settles),
the target tag within 2 mm and 1 deg of where it was laid.
"""

from __future__ import annotations

import math
import subprocess
import sys
import time

import numpy as np
import pytest

pytest.importorskip("lerobot")
cv2 = pytest.importorskip("cv2")
pytestmark = [pytest.mark.hw, pytest.mark.vision]

import mujoco  # noqa: E402

from so101_kinematics.constants import CUBE_HALF_SIZE  # noqa: E402
from so101_kinematics.errors import CubePositionError  # noqa: E402
from so101_kinematics.paths import REPO  # noqa: E402
from so101_kinematics.sim.cube import build_model  # noqa: E402
from so101_kinematics.sim.tag_textures import CUBE_TAG, TAG_THICKNESS, TARGET_TAG  # noqa: E402
from so101_kinematics.virtual.arm import VirtualSO101  # noqa: E402
from so101_kinematics.vision.camera_model import (  # noqa: E402
    camera_intrinsics,
    get_camera_pose_base,
)
from so101_kinematics.vision.detect import find_tag, flat_pose  # noqa: E402

CUBE_AT = (0.20, 0.08, 20.0)  # [m, m, deg] on the table, in the overhead camera's view
TARGET_AT = (0.22, -0.10, -15.0)
SIZE = (640, 480)
TOLERANCE_M = 0.002  # issue 36: a tag's position within 2 mm
TOLERANCE_DEG = 1.0


def overhead_camera() -> tuple[np.ndarray, np.ndarray]:
    """K and g_bc of the model's fixed overhead camera (the model's own numbers)."""
    m = build_model(render_meshes=True)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    return camera_intrinsics(m, "overhead", *SIZE), get_camera_pose_base(m, d, "overhead")


def read_frame(address: str, seconds: float = 0.5) -> np.ndarray:
    capture = cv2.VideoCapture(address)
    try:
        assert capture.isOpened(), address
        frame, end = None, time.monotonic() + seconds
        while time.monotonic() < end or frame is None:
            ok, image = capture.read()
            assert ok, "the stream ended"
            frame = image
        return frame
    finally:
        capture.release()


def yaw_error_deg(g_bt: np.ndarray, yaw_deg: float) -> float:
    seen = math.degrees(math.atan2(g_bt[1, 0], g_bt[0, 0]))
    return abs((seen - yaw_deg + 180.0) % 360.0 - 180.0)


def test_the_served_overhead_camera_sees_the_cube_tag_and_the_target_tag_where_they_are():
    K, g_bc = overhead_camera()
    with VirtualSO101(cube=CUBE_AT, target=TARGET_AT, cameras=["overhead"],
                      camera_size=SIZE) as arm:
        frame = read_frame(arm.camera_addresses["overhead"])
        cube = arm.cube()
    rgb = cv2.cvtColor(frame, cv2.COLOR_BGR2RGB)
    centre = np.asarray(cube.position_m)
    seen = find_tag(rgb, K, CUBE_TAG)
    assert seen is not None, "the cube tag is not in the served frame"
    g_bt = flat_pose(seen, K, g_bc, centre[2] + CUBE_HALF_SIZE + TAG_THICKNESS)
    assert np.linalg.norm(g_bt[:2, 3] - centre[:2]) < TOLERANCE_M  # (its yaw: not reported)
    target = find_tag(rgb, K, TARGET_TAG)
    assert target is not None, "the target tag is not in the served frame"
    g_bt = flat_pose(target, K, g_bc, TAG_THICKNESS)  # on the table top, the base's z = 0
    assert np.linalg.norm(g_bt[:2, 3] - TARGET_AT[:2]) < TOLERANCE_M
    assert yaw_error_deg(g_bt, TARGET_AT[2]) < TOLERANCE_DEG


def test_a_target_off_the_table_is_one_line():
    with pytest.raises(CubePositionError, match="target x"):
        VirtualSO101(target=(0.9, 0.0), cameras=["overhead"])


def test_the_command_line_asks_for_a_camera_with_the_target():
    done = subprocess.run([sys.executable, str(REPO / "virtual_so101.py"), "--target", "0.2",
                           "0.0"], capture_output=True, text=True, timeout=30, cwd=REPO)
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and "--camera" in done.stderr

"""See and pick on the virtual arm: lerobot's camera class finds the cube, lerobot's bus moves it.

The whole hardware path with the camera in it: the virtual arm serves its overhead camera
(the cube and the target tag drawn, ``sim/tag_textures.py``); lerobot opens it with its own
camera class (``lerobot_camera_so101_virtual``, an ``OpenCVCamera``); the one detection path
(``vision/detect.py``) gives the cube's and the target's positions; the course's Cartesian
plan (``cartesian_plan``, as ``pick_place_hw.py --pick/--place``) runs through lerobot's
``FeetechMotorsBus`` (``hw/run.py``'s ``run_on_arm``). The expected end: the cube resting on
the target tag, within the 10 mm the course's pick-and-place asks of the arm.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("lerobot")
pytest.importorskip("cv2")
pytestmark = [pytest.mark.hw, pytest.mark.vision]

import mujoco  # noqa: E402

from so101_kinematics.calibration import load_calibration  # noqa: E402
from so101_kinematics.constants import CUBE_HALF_SIZE  # noqa: E402
from so101_kinematics.hw.run import run_on_arm  # noqa: E402
from so101_kinematics.planning.cartesian_plan import cartesian_plan  # noqa: E402
from so101_kinematics.sim.cube import build_model  # noqa: E402
from so101_kinematics.sim.tag_textures import CUBE_TAG, TAG_THICKNESS, TARGET_TAG  # noqa: E402
from so101_kinematics.virtual.arm import VirtualSO101  # noqa: E402
from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH  # noqa: E402
from so101_kinematics.vision.camera_model import (  # noqa: E402
    camera_intrinsics,
    get_camera_pose_base,
)
from so101_kinematics.vision.detect import find_tag, flat_pose  # noqa: E402

CUBE_AT = (0.20, 0.08, 20.0)  # [m, m, deg]
TARGET_AT = (0.22, -0.10, -15.0)
SIZE = (640, 480)
PLACE_TOLERANCE_M = 0.010  # the course's pick-and-place on the arm: 10 mm


def lerobot_frame(address: str) -> np.ndarray:
    """One RGB frame read by lerobot's camera class (as a robot's ``cameras`` config does)."""
    from lerobot.cameras.utils import make_cameras_from_configs

    import lerobot_camera_so101_virtual  # noqa: F401 - registers the camera type
    from lerobot_camera_so101_virtual import SO101VirtualCameraConfig

    config = SO101VirtualCameraConfig(address=address, width=SIZE[0], height=SIZE[1], fps=30)
    camera = make_cameras_from_configs({"overhead": config})["overhead"]
    camera.connect()
    try:
        return camera.read()
    finally:
        camera.disconnect()


def seen_on_table(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The cube tag's and the target tag's poses in the base frame from one overhead image."""
    m = build_model(render_meshes=True)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    K, g_bc = camera_intrinsics(m, "overhead", *SIZE), get_camera_pose_base(m, d, "overhead")
    cube, target = find_tag(image, K, CUBE_TAG), find_tag(image, K, TARGET_TAG)
    assert cube is not None and target is not None, "a tag is not in the served frame"
    cube_top = 2 * CUBE_HALF_SIZE + TAG_THICKNESS  # the table top is the base's z = 0
    return flat_pose(cube, K, g_bc, cube_top), flat_pose(target, K, g_bc, TAG_THICKNESS)


@pytest.mark.slow
def test_the_virtual_arm_puts_the_cube_it_saw_on_the_target_it_saw():
    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH, cube=CUBE_AT, target=TARGET_AT,
                      cameras=["overhead"], camera_size=SIZE) as arm:
        g_cube, g_target = seen_on_table(lerobot_frame(arm.camera_addresses["overhead"]))
        yaw = math.degrees(math.atan2(g_cube[1, 0], g_cube[0, 0]))
        plan = cartesian_plan((*g_cube[:2, 3], CUBE_HALF_SIZE), (*g_target[:2, 3], CUBE_HALF_SIZE),
                              cube_yaw_deg=yaw)
        result = run_on_arm(arm.port, load_calibration(DEFAULT_CALIBRATION_PATH), plan)
        cube = arm.cube()
    assert result.aborted is None and result.torque_released
    x, y, _ = cube.position_m
    assert math.hypot(x - TARGET_AT[0], y - TARGET_AT[1]) <= PLACE_TOLERANCE_M
    assert cube.tilt_deg <= 10.0 and not cube.held

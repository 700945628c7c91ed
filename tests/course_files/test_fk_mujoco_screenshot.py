"""The headless FK test's screenshot shows the red cylinder where the FK says the object is."""

from __future__ import annotations

import math

import imageio.v3 as iio
import mujoco
import numpy as np
import pytest

import test_fk_mujoco as script
from so101_forward_kinematics import get_forward_kinematics

WINDOW = 4  # [px] half-size of the patch checked around a projected point


def project(model, camera: str, size, point) -> tuple[float, float]:
    """Pixel (column, row) of a world point for a model camera (pinhole, MuJoCo conventions)."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)  # camera poses come from mj_camlight
    cam = data.camera(camera)
    rotation = cam.xmat.reshape(3, 3)  # columns: camera x (right), y (up), z (backward)
    local = rotation.T @ (np.asarray(point) - cam.xpos)
    depth = -local[2]
    assert depth > 0, "point is behind the camera"
    width, height = size
    focal = 0.5 * height / math.tan(math.radians(model.camera(camera).fovy[0]) / 2.0)  # [px]
    return 0.5 * width + focal * local[0] / depth, 0.5 * height - focal * local[1] / depth


def red_fraction(image, column: float, row: float) -> float:
    r0, c0 = round(row), round(column)
    assert WINDOW <= r0 < image.shape[0] - WINDOW and WINDOW <= c0 < image.shape[1] - WINDOW
    patch = image[r0 - WINDOW:r0 + WINDOW + 1, c0 - WINDOW:c0 + WINDOW + 1, :3].astype(int)
    red = (patch[..., 0] > 120) & (patch[..., 1] < 60) & (patch[..., 2] < 60)
    return float(red.mean())


@pytest.fixture(scope="module")
def screenshot(tmp_path_factory, model):
    path = tmp_path_factory.mktemp("fk") / "fk_test.png"
    assert script.main(["--headless", "--screenshot", str(path), "--seconds", "0.2"]) == 0
    return iio.imread(path)


def test_screenshot_has_the_configured_size(screenshot):
    width, height = script.SCREENSHOT_SIZE
    assert screenshot.shape[:2] == (height, width)


def test_cylinder_is_drawn_where_fk_puts_the_object(model, screenshot):
    position, rotation = get_forward_kinematics(script.TEST_CONFIGURATION)
    size = script.SCREENSHOT_SIZE
    # The centre and a point up the axis (toward the wrist; the part below the table is hidden).
    for point in (position, position + 0.03 * rotation[:, 2]):
        column, row = project(model, script.SCREENSHOT_CAMERA, size, point)
        assert red_fraction(screenshot, column, row) > 0.9, (point, column, row)


def test_a_wrong_pose_would_not_pass(model, screenshot):
    size = script.SCREENSHOT_SIZE
    position, rotation = get_forward_kinematics(script.TEST_CONFIGURATION)
    # 6 cm sideways (across the view) of the object, beyond the 2.45 cm radius ...
    aside = position + 0.06 * rotation[:, 0] + 0.02 * rotation[:, 2]
    # ... and the object of a configuration 10 deg off in shoulder_pan.
    wrong, _ = get_forward_kinematics(dict(script.TEST_CONFIGURATION, shoulder_pan=-30.0))
    for point in (aside, wrong):
        column, row = project(model, script.SCREENSHOT_CAMERA, size, point)
        assert red_fraction(screenshot, column, row) < 0.1, (point, column, row)


def test_only_the_cylinder_is_red(screenshot):
    # No other red in the scene: the red pixels form one blob around the projected centre.
    pixels = screenshot[..., :3].astype(int)
    red = (pixels[..., 0] > 120) & (pixels[..., 1] < 60) & (pixels[..., 2] < 60)
    rows, columns = np.nonzero(red)
    assert red.sum() > 1000
    assert np.ptp(columns) < screenshot.shape[1] / 2 and np.ptp(rows) < screenshot.shape[0] / 2


def test_committed_fk_table_is_up_to_date():
    committed = (script.TABLE_PATH).read_text()
    assert committed == script.fk_table_markdown(), "regenerate: python test_fk_mujoco.py --table"
    assert committed.count("| `get_g") == 6


def test_frames_picture_renders(tmp_path):
    path = script.render_frames(tmp_path / "frames.png", size=(400, 300))
    image = iio.imread(path)
    assert image.shape[:2] == (300, 400)
    assert np.ptp(image[..., :3]) > 100  # not a blank image
    # The frames' axes are drawn: x red, y green, z blue (pixels where that channel dominates
    # by 60 of 255; the scene itself has none of these colours, measured 50-70 px each).
    pixels = image[..., :3].astype(int)
    for channel, colour in enumerate(("red", "green", "blue")):
        others = [pixels[..., k] for k in range(3) if k != channel]
        strong = (pixels[..., channel] > others[0] + 60) & (pixels[..., channel] > others[1] + 60)
        assert strong.sum() > 20, f"no {colour} axis in the frames picture"

"""The real camera's path on recorded pictures: the simulator's images written to a folder, as
a student's photos and read_position.py's angles would be, calibrated by
``calibrate_camera.py --photos`` and checked against the model (the wrist camera's lens at
(-0.050, 0, -0.040) m in the gripper body, model/so101.xml)."""

from __future__ import annotations

import json

import mujoco
import numpy as np
import pytest

import calibrate_camera
from so101_kinematics.errors import InputError
from so101_kinematics.frames import ARM_JOINTS
from so101_kinematics.vision.boards import set_board_pose
from so101_kinematics.vision.calibration_grades import WRIST_INTRINSICS_POSE
from so101_kinematics.vision.calibration_photos import calibrate_from_photos
from so101_kinematics.vision.calibration_views import (
    board_views,
    calibration_model,
    set_arm,
    table_board_pose,
    wrist_views,
)
from so101_kinematics.vision.sim_camera import WEBCAM, SimCamera

pytestmark = pytest.mark.vision


def _snap(m, d, camera, angles, g_b_board, path) -> None:
    import cv2

    set_arm(m, d, angles)
    set_board_pose(m, d, g_b_board)
    mujoco.mj_forward(m, d)
    cv2.imwrite(str(path), camera.read()[:, :, ::-1])


@pytest.fixture(scope="module")
def photos(tmp_path_factory):
    """A student's folder: 6 board pictures for the intrinsics, 6 arm poses over the board."""
    folder = tmp_path_factory.mktemp("photos")
    (folder / "intrinsics").mkdir()
    m = calibration_model()
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_forward(m, d)
    rng = np.random.default_rng(5)
    lines = [f"image,{','.join(ARM_JOINTS)}"]
    with SimCamera(m, d, "wrist", size=(640, 480), effects=WEBCAM) as camera:
        set_arm(m, d, WRIST_INTRINSICS_POSE)
        for i, g in enumerate(board_views(rng, 6, camera.pose(), camera.intrinsics(),
                                          (640, 480))):
            _snap(m, d, camera, WRIST_INTRINSICS_POSE, g, folder / "intrinsics" / f"{i}.png")
        board = table_board_pose()
        for i, angles in enumerate(wrist_views(m, d, rng, 6, board, camera.intrinsics(),
                                               (640, 480))):
            _snap(m, d, camera, angles, board, folder / f"pose_{i}.png")
            lines.append(f"pose_{i}.png," + ",".join(f"{a:.4f}" for a in angles))
    (folder / "poses.csv").write_text("\n".join(lines) + "\n")
    return folder


def test_the_wrist_camera_from_recorded_pictures(photos, tmp_path, capsys):
    path = tmp_path / "wrist.json"
    assert calibrate_camera.main(["--photos", str(photos), "--mount", "wrist",
                                  "--json", str(path)]) == 0
    report = json.loads(path.read_text())
    K = np.array(report["intrinsics"]["K"])
    focal = 240.0 / np.tan(np.radians(30.0))  # the wrist camera's fovy 60 deg, by hand
    assert K[0, 0] == pytest.approx(focal, rel=0.01) and K[1, 1] == pytest.approx(focal, rel=0.01)
    in_gripper = np.array(report["hand_eye"]["wrist"]["camera_in_gripper"])
    assert in_gripper[:3, 3] == pytest.approx([-0.050, 0.0, -0.040], abs=0.002)
    assert report["hand_eye"]["wrist"]["residual_mm"] < 2.0
    assert "camera_in_gripper: at (-50" in capsys.readouterr().out


def test_the_report_is_the_webcams_calibration(photos, tmp_path):
    # the file calibrate_camera.py writes is the one vision/webcam.py reads: no second format
    from so101_kinematics.vision.webcam import load_calibration

    path = tmp_path / "wrist.json"
    assert calibrate_camera.main(["--photos", str(photos), "--mount", "wrist",
                                  "--json", str(path)]) == 0
    K, dist = load_calibration(path, 640, 480)
    focal = 240.0 / np.tan(np.radians(30.0))  # the wrist camera's fovy 60 deg, by hand
    assert K[0, 0] == pytest.approx(focal, rel=0.01) and K[1, 1] == pytest.approx(focal, rel=0.01)
    assert (K[0, 2], K[1, 2]) == pytest.approx((320.0, 240.0), abs=3.0)  # the image's middle
    assert dist.shape == (5,) and np.all(np.abs(dist) < 0.1)  # a pinhole: next to no distortion


def test_bad_folders_are_one_line(photos, tmp_path):
    with pytest.raises(InputError, match="no such folder"):
        calibrate_from_photos(tmp_path / "nowhere", "wrist")
    (tmp_path / "intrinsics").mkdir()
    with pytest.raises(InputError, match="no pictures"):
        calibrate_from_photos(tmp_path, "wrist")
    (tmp_path / "intrinsics" / "0.png").write_bytes((photos / "intrinsics" / "0.png").read_bytes())
    (tmp_path / "intrinsics" / "1.png").write_text("not an image")
    with pytest.raises(InputError, match="not a readable image") as error:
        calibrate_from_photos(tmp_path, "wrist")
    assert "\n" not in str(error.value)


def test_a_bad_poses_line_and_another_resolution_are_one_line(photos, tmp_path):
    import cv2

    folder = tmp_path / "copy"
    (folder / "intrinsics").mkdir(parents=True)
    for picture in (photos / "intrinsics").glob("*.png"):
        (folder / "intrinsics" / picture.name).write_bytes(picture.read_bytes())
    (folder / "poses.csv").write_text(f"image,{','.join(ARM_JOINTS)}\npose_0.png,0,zero,0,0,0\n")
    assert calibrate_camera.main(["--photos", str(folder)]) == 2
    cv2.imwrite(str(folder / "intrinsics" / "small.png"), np.zeros((240, 320, 3), np.uint8))
    with pytest.raises(InputError, match="320x240 px, the others 640x480 px"):
        calibrate_from_photos(folder, "wrist")

"""The ChArUco board: one image for the simulator's texture and the printed page, true to size.

Expected values from the board's specification (docs/final_project.md: 5 x 7 squares of
32 mm, markers of 24 mm, ids from 10, on A4) and hand arithmetic.
"""

from __future__ import annotations

import re

import mujoco
import numpy as np
import pytest

from so101_kinematics.markers import pdf_ours
from so101_kinematics.sim.tag_textures import TAGS
from so101_kinematics.vision.boards import (
    BOARD_BODY,
    CALIBRATION_BOARD,
    board_face_image,
    board_page,
    charuco_board,
    get_board_pose_base,
    set_board_pose,
    write_board_sheet,
)
from so101_kinematics.vision.camera_model import camera_intrinsics, get_camera_pose_base
from so101_kinematics.vision.charuco import board_pose, find_board
from so101_kinematics.vision.hand_eye import pose_error
from so101_kinematics.vision.sim_camera import SimCamera
from so101_kinematics.vision.tagged_scene import build_tagged_model, tagged_spec

pytestmark = pytest.mark.vision


def test_the_board_fits_an_a4_page_and_its_markers_are_not_the_tags():
    width, height = CALIBRATION_BOARD.face
    assert (width * 1000, height * 1000) == pytest.approx((5 * 32 + 16, 7 * 32 + 16))
    assert width <= 0.210 - 2 * 0.010 and height <= 0.297 - 0.050  # printer margins, text
    ids = set(np.asarray(charuco_board().getIds()).ravel().tolist())
    assert ids == set(range(10, 10 + 17))  # 35 squares, 17 white ones carry a marker
    assert not ids & set(TAGS)
    cell = 0.024 / 6  # a 4 x 4 marker with its border is 6 cells
    assert (CALIBRATION_BOARD.square - CALIBRATION_BOARD.marker) / 2 >= 0.99 * cell


def test_the_face_image_is_the_board_in_its_white_margin():
    face = board_face_image(px_per_mm=4.0)
    assert face.shape == (4 * 240, 4 * 176)
    margin = 4 * 8
    assert np.all(face[:margin] == 255) and np.all(face[:, -margin:] == 255)
    assert np.all(face[margin:margin + 4 * 32, margin:margin + 4 * 32] == 0)  # top-left: black


def test_the_printed_sheet_is_an_a4_pdf_of_ours(tmp_path):
    path = write_board_sheet(tmp_path / "board.pdf")
    assert pdf_ours(path)
    box = re.search(rb"/MediaBox \[\s*0 0 ([\d.]+) ([\d.]+)\s*\]", path.read_bytes())
    assert (float(box[1]), float(box[2])) == pytest.approx((595.28, 841.89), abs=0.01)


def test_the_printed_board_is_true_to_size_and_readable(tmp_path):
    """The page rastered at 10 px/mm: every inner corner found, 32 mm apart."""
    import cv2

    board_page().savefig(tmp_path / "page.png", dpi=254)  # 254 dpi = 10 px/mm
    page = cv2.imread(str(tmp_path / "page.png"))[:, :, ::-1].copy()
    seen = find_board(page)
    assert seen is not None and len(seen.ids) == 4 * 6
    by_id = dict(zip(seen.ids.tolist(), seen.corners, strict=True))
    assert np.linalg.norm(by_id[1] - by_id[0]) / 10.0 == pytest.approx(32.0, abs=0.2)  # a row
    assert np.linalg.norm(by_id[4] - by_id[0]) / 10.0 == pytest.approx(32.0, abs=0.2)  # down


@pytest.fixture(scope="module")
def scene():
    import so101_kinematics.vision.boards as boards

    spec = tagged_spec()
    boards.add_board(spec)
    m = build_tagged_model(spec=spec)
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_forward(m, d)
    return m, d


def test_the_simulators_board_is_seen_where_it_is(scene):
    """Under the overhead camera, turned and tilted: its pose from the image (exact
    intrinsics, no noise) is the simulator's, which is where it was put."""
    m, d = scene
    turn, tilt = np.radians(20.0), np.radians(25.0)
    rotation = np.array([[np.cos(turn), -np.sin(turn), 0.0], [np.sin(turn), np.cos(turn), 0.0],
                         [0.0, 0.0, 1.0]]) @ np.array([[1.0, 0.0, 0.0],
                                                       [0.0, np.cos(tilt), -np.sin(tilt)],
                                                       [0.0, np.sin(tilt), np.cos(tilt)]])
    g_b_board = np.eye(4)
    g_b_board[:3, :3] = rotation @ np.diag([1.0, -1.0, -1.0])  # face up: its z into the board
    g_b_board[:3, 3] = (0.12, 0.08, 0.20)
    set_board_pose(m, d, g_b_board)
    mujoco.mj_forward(m, d)
    assert np.allclose(get_board_pose_base(d, BOARD_BODY), g_b_board, atol=1e-9)
    with SimCamera(m, d, "overhead", size=(640, 480)) as camera:
        seen = find_board(camera.read())
    assert seen is not None and len(seen.ids) == 24
    K = camera_intrinsics(m, "overhead", 640, 480)
    g_c_board, rms = board_pose(seen, K)
    g_bc = get_camera_pose_base(m, d, "overhead")
    position_mm, angle_deg = pose_error(g_bc @ g_c_board, g_b_board)
    assert rms < 0.3
    assert position_mm < 1.0 and angle_deg < 0.3

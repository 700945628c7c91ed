"""Hand-eye and eye-to-hand on exact synthetic poses: the transform built in comes back.

No rendering: the poses are made by hand (a camera 5 cm behind and 4 cm below the gripper's
origin, as the model's wrist camera is; a fixed camera 55 cm above the table), so the only
error is the solver's.
"""

from __future__ import annotations

import numpy as np
import pytest

from so101_kinematics.errors import VisionError
from so101_kinematics.vision.hand_eye import (
    HandEye,
    pose_error,
    refine_on_corners,
    solve_eye_to_hand,
    solve_hand_eye,
)

pytestmark = pytest.mark.vision


def pose(rotation_vector, translation) -> np.ndarray:
    """Rodrigues by hand: a 4x4 pose from a rotation vector [rad] and a translation [m]."""
    v = np.asarray(rotation_vector, dtype=float)
    angle = np.linalg.norm(v)
    k = v / angle if angle else np.zeros(3)
    cross = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    g = np.eye(4)
    g[:3, :3] = np.eye(3) + np.sin(angle) * cross + (1 - np.cos(angle)) * cross @ cross
    g[:3, 3] = translation
    return g


def gripper_poses(n: int, seed: int = 0) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [pose(rng.uniform(-0.8, 0.8, 3), rng.uniform([0.1, -0.15, 0.1], [0.3, 0.15, 0.3]))
            for _ in range(n)]


def test_pose_error_by_hand():
    assert pose_error(pose([0, 0, np.radians(30)], [0.003, 0.004, 0]), np.eye(4)) == \
        pytest.approx((5.0, 30.0))


def test_hand_eye_finds_the_camera_in_the_gripper():
    x_true = pose([0.3, -0.2, 1.4], [-0.05, 0.0, -0.04])
    g_b_board = pose([np.pi, 0, 0], [0.24, 0.0, 0.003])
    grippers = gripper_poses(8)
    boards = [np.linalg.inv(g @ x_true) @ g_b_board for g in grippers]
    result = solve_hand_eye(grippers, boards)
    assert pose_error(result.pose, x_true) == pytest.approx((0.0, 0.0), abs=1e-4)
    assert result.spread_mm < 1e-4 and result.views == 8


def test_eye_to_hand_finds_the_camera_in_the_base():
    y_true = pose([np.pi, 0, np.pi / 2], [0.2, 0.0, 0.55])
    g_g_board = pose([0, np.pi / 2, 0], [0.0, 0.0, -0.23])
    grippers = gripper_poses(8, seed=1)
    boards = [np.linalg.inv(y_true) @ g @ g_g_board for g in grippers]
    result = solve_eye_to_hand(grippers, boards)
    assert pose_error(result.pose, y_true) == pytest.approx((0.0, 0.0), abs=1e-4)


def test_too_few_poses_is_one_line():
    with pytest.raises(VisionError) as error:
        solve_hand_eye(gripper_poses(2), gripper_poses(2))
    assert "\n" not in str(error.value) and "at least 3" in str(error.value)


def test_the_corners_pull_a_wrong_start_back_to_the_truth():
    """Exact pixels of a 4 x 6 grid of 32 mm through the eye-to-hand chain; a start 3 mm and
    1 deg off comes back, the corners then landing where they were seen."""
    y_true = pose([np.pi, 0, np.pi / 2], [0.2, 0.0, 0.55])
    g_g_board = pose([0, np.pi / 2, 0], [0.0, 0.0, -0.23])
    K = np.array([[433.0, 0, 319.5], [0, 433.0, 239.5], [0, 0, 1]])
    grid = np.array([[0.032 * i, 0.032 * j, 0.0] for j in range(1, 7) for i in range(1, 5)])
    grippers = gripper_poses(5, seed=2)
    boards = [np.linalg.inv(y_true) @ g @ g_g_board for g in grippers]
    views = []
    for g in boards:
        points = grid @ g[:3, :3].T + g[:3, 3]
        views.append((grid, (points[:, :2] / points[:, 2:]) @ K[:2, :2].T + K[:2, 2]))
    start = HandEye(y_true @ pose([0, 0, np.radians(1.0)], [0.003, 0, 0]), 0.0, 0.0, "tsai", 5)
    refined = refine_on_corners(start, grippers, boards, views, K, eye_in_hand=False)
    assert pose_error(refined.pose, y_true) == pytest.approx((0.0, 0.0), abs=1e-3)
    assert refined.rms_px < 1e-3 and refined.method == "tsai+corners"


def test_without_opencvs_solver_park_and_martin_in_numpy(monkeypatch):
    """OpenCV 5.0's Python module has no calibrateHandEye: the numpy method alone finds X."""
    from so101_kinematics.vision import hand_eye

    monkeypatch.setattr(hand_eye, "_opencv_candidates", lambda a, b: {})
    x_true = pose([0.3, -0.2, 1.4], [-0.05, 0.0, -0.04])
    g_b_board = pose([np.pi, 0, 0], [0.24, 0.0, 0.003])
    grippers = gripper_poses(6, seed=3)
    boards = [np.linalg.inv(g @ x_true) @ g_b_board for g in grippers]
    result = solve_hand_eye(grippers, boards)
    assert result.method == "park-procrustes"
    assert pose_error(result.pose, x_true) == pytest.approx((0.0, 0.0), abs=1e-4)

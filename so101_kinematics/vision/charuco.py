"""The ChArUco board in an image: its corners, its pose, and a camera's intrinsics from views of it.

The same for the simulator's images and a real camera's:

1. **find** (:func:`find_board`): ``cv2.aruco.CharucoDetector`` (OpenCV 4.7 and newer, 5.0
   too; never the old ``interpolateCornersCharuco`` / ``calibrateCameraCharuco``, gone from
   the main package) finds the markers, then the chessboard's inner corners between them,
   each refined to a fraction of a pixel; ``board.matchImagePoints`` pairs each corner with
   its point in the board frame (``boards.py``). Fewer than :data:`MIN_CORNERS`, or all on
   one line: not a view (None);
2. **pose** (:func:`board_pose`): ``cv2.solvePnP`` (``SOLVEPNP_IPPE``, for points on a plane)
   refined by Levenberg-Marquardt: ``g_c_board``, the board frame in the camera's OpenCV frame;
3. **intrinsics** (:func:`calibrate_intrinsics`): ``cv2.calibrateCamera`` on several views
   (Zhang's method): the camera matrix, the distortion (k1, k2, p1, p2; k3 held at 0, as for
   a webcam's modest lens) and the RMS reprojection error [px].
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from so101_kinematics.errors import OpenCVMissing, VisionError
from so101_kinematics.opencv_import import OPENCV_FIX, require_opencv
from so101_kinematics.vision.boards import CALIBRATION_BOARD, Board, charuco_board
from so101_kinematics.vision.detect import grey_image

__all__ = ["BoardSighting", "Intrinsics", "MIN_CORNERS", "MIN_INTRINSIC_VIEWS", "board_pose",
           "calibrate_intrinsics", "find_board", "no_board_message"]

MIN_CORNERS = 6
"""A view with fewer of the board's inner corners does not count (a pose needs 4 off a line)."""
MIN_INTRINSIC_VIEWS = 4
"""Views of the board ``calibrate_intrinsics`` needs at the least (each tilted differently)."""


@dataclass(frozen=True)
class BoardSighting:
    """The board's inner corners found in one image.

    Attributes:
        corners: N x 2 pixels (u right, v down) [px].
        ids: N corner ids (OpenCV's numbering of the inner corners, row by row).
        object_points: N x 3 the same corners in the board frame [m] (z = 0).
    """

    corners: np.ndarray
    ids: np.ndarray
    object_points: np.ndarray


@dataclass(frozen=True)
class Intrinsics:
    """A camera's calibrated numbers.

    Attributes:
        K: 3x3 camera matrix [px].
        dist: OpenCV's distortion coefficients (k1, k2, p1, p2, k3).
        rms_px: RMS reprojection error over every corner of every view [px].
        views: the views used.
        image_size: (width, height) [px].
    """

    K: np.ndarray
    dist: np.ndarray
    rms_px: float
    views: int
    image_size: tuple[int, int]


@functools.lru_cache(maxsize=4)
def _detector(board: Board):
    cv2 = require_opencv()
    if not hasattr(cv2.aruco, "CharucoDetector"):
        raise OpenCVMissing(f"OpenCV {cv2.__version__} has no cv2.aruco.CharucoDetector (needs "
                            f"4.7 or newer). {OPENCV_FIX}")
    return cv2.aruco.CharucoDetector(charuco_board(board))


def find_board(image: np.ndarray, board: Board = CALIBRATION_BOARD,
               min_corners: int = MIN_CORNERS) -> BoardSighting | None:
    """The board's inner corners in ``image``, or None when too few of them are in view.

    Args:
        image: H x W x 3 uint8 RGB (``interfaces.Camera.read()``), or H x W grey.
        board: which board.
        min_corners: the fewest corners that make a view; they must not lie on one line.
    """
    corners, ids, _, _ = _detector(board).detectBoard(grey_image(image))
    if ids is None or len(ids) < min_corners:
        return None
    object_points, image_points = charuco_board(board).matchImagePoints(corners, ids)
    object_points = np.asarray(object_points, dtype=float).reshape(-1, 3)
    spread = np.linalg.svd(object_points[:, :2] - object_points[:, :2].mean(axis=0),
                           compute_uv=False)
    if spread[-1] < 1e-6:  # all on one row or one column: no pose, no calibration
        return None
    return BoardSighting(np.asarray(image_points, dtype=float).reshape(-1, 2),
                         np.asarray(ids).ravel(), object_points)


def board_pose(sighting: BoardSighting, K: np.ndarray, dist=None) -> tuple[np.ndarray, float]:
    """``g_c_board`` (4x4) [m] and the RMS reprojection error [px] of one view."""
    cv2 = require_opencv()
    K = np.asarray(K, dtype=float)
    dist = np.zeros(5) if dist is None else np.asarray(dist, dtype=float)
    obj, img = sighting.object_points, sighting.corners
    ok, rvec, tvec = cv2.solvePnP(obj, img, K, dist, flags=cv2.SOLVEPNP_IPPE)
    if not ok:
        raise VisionError(f"solvePnP found no pose for {len(obj)} board corners.")
    rvec, tvec = cv2.solvePnPRefineLM(obj, img, K, dist, rvec, tvec)
    g = np.eye(4)
    g[:3, :3] = cv2.Rodrigues(rvec)[0]
    g[:3, 3] = tvec.ravel()
    projected = cv2.projectPoints(obj, rvec, tvec, K, dist)[0].reshape(-1, 2)
    return g, float(np.sqrt(np.mean(np.sum((projected - img) ** 2, axis=1))))


def calibrate_intrinsics(sightings: Sequence[BoardSighting], image_size: Sequence[int],
                         camera: str = "camera") -> Intrinsics:
    """Zhang's calibration (``cv2.calibrateCamera``) from views of the board.

    Args:
        sightings: the views (:func:`find_board`'s), the board tilted differently in each.
        image_size: (width, height) [px].
        camera: its name, for the message.

    Raises:
        VisionError: fewer than :data:`MIN_INTRINSIC_VIEWS` views (one line with the fix).
    """
    if len(sightings) < MIN_INTRINSIC_VIEWS:
        raise VisionError(f"The {camera} camera saw the ChArUco board in {len(sightings)} views; "
                          f"calibrating it needs at least {MIN_INTRINSIC_VIEWS}. Fix: show the "
                          "whole board, tilted a different way each time, in more views.")
    cv2 = require_opencv()
    width, height = (int(v) for v in image_size)
    objects = [s.object_points.astype(np.float32) for s in sightings]
    images = [s.corners.astype(np.float32) for s in sightings]
    rms, K, dist, _, _ = cv2.calibrateCamera(objects, images, (width, height), None, None,
                                             flags=cv2.CALIB_FIX_K3)
    return Intrinsics(np.asarray(K, dtype=float), np.asarray(dist, dtype=float).ravel(),
                      float(rms), len(sightings), (width, height))


def no_board_message(camera: str, seen: int, needed: int, views: int) -> str:
    """One line for a board seen in too few views, ending with what to do."""
    return (f"The ChArUco board (so101 tags --board) was found in {seen} of the {camera} "
            f"camera's {views} views; this calibration needs {needed}. Fix: bring at least "
            f"{MIN_CORNERS} of its inner corners into each view (move the arm or the board), "
            "and check the light and the focus.")

"""Calibration from a folder of real pictures: the printed board, a real camera, the arm by hand.

``calibrate_camera.py --photos DIR --mount wrist|fixed`` reads what a student took on the
real rig (docs/final_project.md, "On the real arm")::

    DIR/intrinsics/*.png|jpg     the board held in front of the camera, tilted each time
    DIR/poses.csv                image,shoulder_pan,shoulder_lift,elbow_flex,wrist_flex,wrist_roll
    DIR/<image>                  one picture per arm pose (angles [deg], as read_position.py
                                 prints them)

and runs the same calibrations as the simulator's (``charuco.py``, ``hand_eye.py``), with
no truth to grade against: the residuals are the grade.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from so101_kinematics.errors import InputError, VisionError
from so101_kinematics.frames import ARM_JOINTS
from so101_kinematics.opencv_import import require_opencv
from so101_kinematics.vision.calibration_views import gripper_pose
from so101_kinematics.vision.charuco import (
    Intrinsics,
    board_pose,
    calibrate_intrinsics,
    find_board,
    no_board_message,
)
from so101_kinematics.vision.hand_eye import (
    MIN_HAND_EYE_VIEWS,
    refine_on_corners,
    solve_eye_to_hand,
    solve_hand_eye,
)

__all__ = ["IMAGE_SUFFIXES", "MOUNTS", "POSES_FILE", "calibrate_from_photos", "read_photo"]

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")
POSES_FILE = "poses.csv"
MOUNTS = {"wrist": "camera_in_gripper", "fixed": "camera_in_base"}
"""Where the camera is -> what the hand-eye calibration gives (its JSON key)."""


def read_photo(path: Path, size: tuple[int, int] | None = None) -> np.ndarray:
    """A picture as H x W x 3 RGB; all of one calibration must have one size.

    Raises:
        InputError: not a readable image, or another size than ``size`` (one line).
    """
    image = require_opencv().imread(str(path))
    if image is None:
        raise InputError(f"--photos: {path} is not a readable image. Fix: give PNG or JPEG "
                         "pictures of the board.")
    if size is not None and (image.shape[1], image.shape[0]) != tuple(size):
        raise InputError(f"--photos: {path} is {image.shape[1]}x{image.shape[0]} px, the "
                         f"others {size[0]}x{size[1]} px: a calibration holds for one "
                         "resolution. Fix: take every picture at the same resolution.")
    return image[:, :, ::-1].copy()


def _intrinsics(folder: Path, camera: str) -> Intrinsics:
    paths = sorted(p for p in (folder / "intrinsics").glob("*") if p.suffix.lower()
                   in IMAGE_SUFFIXES)
    if not paths:
        raise InputError(f"--photos {folder}: no pictures in {folder / 'intrinsics'}. Fix: "
                         "put the board's pictures (PNG or JPEG) there.")
    first = read_photo(paths[0])
    size = (first.shape[1], first.shape[0])
    seen = [s for p in paths if (s := find_board(read_photo(p, size))) is not None]
    return calibrate_intrinsics(seen, size, camera)


def _poses(folder: Path) -> list[tuple[np.ndarray, Path]]:
    path = folder / POSES_FILE
    try:
        with path.open(newline="", encoding="utf-8") as handle:
            rows = list(csv.DictReader(handle))
    except OSError as error:
        raise InputError(f"--photos: cannot read {path} ({error.strerror}). Fix: write one "
                         f"line per arm pose: image,{','.join(ARM_JOINTS)}.") from None
    poses = []
    for number, row in enumerate(rows, start=2):
        try:
            angles = np.array([float(row[joint]) for joint in ARM_JOINTS])
            image = folder / row["image"]
        except (KeyError, TypeError, ValueError):
            raise InputError(f"--photos: {path} line {number} is not image,"
                             f"{','.join(ARM_JOINTS)} with angles in deg. Fix: e.g. "
                             "pose_01.png,0,-60,30,70,0.") from None
        poses.append((angles, image))
    return poses


def calibrate_from_photos(folder: str | Path, mount: str) -> dict:
    """The camera's intrinsics and, with ``poses.csv``, its pose (on the gripper or the base).

    Args:
        folder: the pictures' folder (see the module's docstring).
        mount: "wrist" (hand-eye: the board fixed, the camera on the gripper) or "fixed"
            (eye to hand: the board in the jaws, the camera over the table).

    Returns:
        The report: ``intrinsics`` (camera matrix, distortion, RMS) and ``hand_eye.<mount>``
        (the pose and its residuals) when there are poses.

    Raises:
        InputError: a missing folder, file or picture, or a malformed line (one line).
        VisionError: the board seen in too few pictures (one line).
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"--photos {folder}: no such folder. Fix: give the folder with "
                         "intrinsics/ and poses.csv.")
    intrinsics = _intrinsics(folder, mount)
    report = {"intrinsics": {"K": intrinsics.K.tolist(), "distortion": intrinsics.dist.tolist(),
                             "rms_px": intrinsics.rms_px, "views_used": intrinsics.views,
                             "image_size": list(intrinsics.image_size)}}
    if not (folder / POSES_FILE).exists():
        return report
    poses = _poses(folder)
    found = [(angles, s) for angles, path in poses
             if (s := find_board(read_photo(path, intrinsics.image_size))) is not None]
    if len(found) < MIN_HAND_EYE_VIEWS:
        raise VisionError(no_board_message(mount, len(found), MIN_HAND_EYE_VIEWS, len(poses)))
    grippers = [gripper_pose(angles) for angles, _ in found]
    boards = [board_pose(s, intrinsics.K, intrinsics.dist)[0] for _, s in found]
    solve = solve_hand_eye if mount == "wrist" else solve_eye_to_hand
    result = refine_on_corners(solve(grippers, boards), grippers, boards,
                               [(s.object_points, s.corners) for _, s in found], intrinsics.K,
                               intrinsics.dist, eye_in_hand=mount == "wrist")
    report["hand_eye"] = {mount: {MOUNTS[mount]: result.pose.tolist(),
                                  "residual_mm": result.spread_mm,
                                  "residual_deg": result.spread_deg,
                                  "chain_rms_px": result.rms_px, "method": result.method,
                                  "views_used": result.views, "views": len(poses)}}
    return report

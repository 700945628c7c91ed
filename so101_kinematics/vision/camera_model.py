"""A camera's numbers: intrinsics from MuJoCo's fovy, its pose in the base frame, projection.

Two conventions meet here, and only here:

- **Intrinsics.** MuJoCo's ``fovy`` is the *vertical* field of view [deg] of a pinhole
  with square pixels whose optical axis goes through the middle of the image. The
  OpenCV camera matrix of a ``width`` x ``height`` image is then
  ``fy = fx = (height / 2) / tan(fovy / 2)`` [px] and the principal point
  ``cx = (width - 1) / 2``, ``cy = (height - 1) / 2`` [px]: OpenCV puts pixel ``(u, v)``'s
  *centre* at integer coordinates, so the image's middle is half a pixel short of
  ``width / 2`` (``tests/vision/test_camera_model.py`` checks it against what MuJoCo draws).
- **Camera axes.** A MuJoCo camera looks along its own -z with +y up and +x right
  (OpenGL's); OpenCV's camera frame has x right, y *down*, z *forward*. The OpenCV frame
  is the MuJoCo frame turned 180 deg about its x axis: ``R_mujoco_opencv = diag(1, -1, -1)``
  (:data:`R_MUJOCO_OPENCV`). Every pose this package hands out is of the OpenCV frame.

Frames follow the FK's convention: ``g_ab`` is the pose (4x4) of frame b in frame a;
``b`` is the robot's base (the model's ``base`` body), ``c`` the camera (OpenCV axes).

Example:
    >>> K = intrinsics_from_fovy(90.0, 640, 480)
    >>> round(float(K[1, 1]), 9), float(K[0, 2]), float(K[1, 2])  # fy = 240 / tan(45 deg)
    (240.0, 319.5, 239.5)
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from so101_kinematics.errors import VisionError
from so101_kinematics.sim.render import check_camera

__all__ = [
    "BASE_BODY", "R_MUJOCO_OPENCV", "camera_intrinsics", "get_camera_pose_base",
    "intrinsics_from_fovy", "project_points",
]

R_MUJOCO_OPENCV = np.diag([1.0, -1.0, -1.0])
"""The OpenCV camera frame in the MuJoCo camera frame: a turn of 180 deg about x (its own
inverse). ``R_w_opencv = R_w_mujoco @ R_MUJOCO_OPENCV``."""

BASE_BODY = "base"
"""The model's body whose frame is the robot's base frame (the FK's, ``model/so101.xml``)."""


def intrinsics_from_fovy(fovy_deg: float, width: int, height: int) -> np.ndarray:
    """OpenCV's camera matrix of a MuJoCo camera.

    Args:
        fovy_deg: vertical field of view [deg] (MuJoCo's ``fovy``).
        width: image width [px].
        height: image height [px].

    Returns:
        3x3 ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`` [px].
    """
    if not 0.0 < fovy_deg < 180.0:
        raise VisionError(f"fovy {fovy_deg!r} deg is not a field of view. Fix: give one in "
                          "(0, 180) deg.")
    focal = (height / 2.0) / math.tan(math.radians(fovy_deg) / 2.0)
    return np.array([[focal, 0.0, (width - 1) / 2.0],
                     [0.0, focal, (height - 1) / 2.0],
                     [0.0, 0.0, 1.0]])


def camera_intrinsics(m: mujoco.MjModel, camera: str, width: int, height: int) -> np.ndarray:
    """The camera matrix [px] of the model's camera ``camera`` rendered at ``width`` x ``height``.

    Raises:
        RenderSettingError: no such camera (naming those the model has).
        VisionError: a camera given by a sensor size (MuJoCo's ``sensorsize``/``focal``), whose
            intrinsics are not its ``fovy``'s.
    """
    check_camera(m, camera)
    cam_id = m.camera(camera).id
    if np.any(m.cam_sensorsize[cam_id] > 0):
        raise VisionError(f"Camera {camera!r} is given by its sensor size, not fovy. Fix: give "
                          "it a fovy in the MJCF (the vision tools read that).")
    return intrinsics_from_fovy(float(m.cam_fovy[cam_id]), width, height)


def _pose(position, rotation) -> np.ndarray:
    g = np.eye(4)
    g[:3, :3] = np.asarray(rotation, dtype=float).reshape(3, 3)
    g[:3, 3] = position
    return g


def get_camera_pose_base(m: mujoco.MjModel, d: mujoco.MjData, camera: str) -> np.ndarray:
    """``g_bc``: the camera's OpenCV frame in the robot's base frame, where the simulator has it.

    Reads ``d`` as the last ``mj_forward``/``mj_kinematics`` left it (a wrist camera moves).

    Returns:
        4x4 pose [m].
    """
    check_camera(m, camera)
    g_wc = _pose(d.cam(camera).xpos, np.asarray(d.cam(camera).xmat).reshape(3, 3)
                 @ R_MUJOCO_OPENCV)
    g_wb = _pose(d.body(BASE_BODY).xpos, d.body(BASE_BODY).xmat)
    return np.linalg.inv(g_wb) @ g_wc


def project_points(K: np.ndarray, g_bc: np.ndarray, points_b) -> np.ndarray:
    """Pixels where points of the base frame appear: the pinhole model, no distortion.

    Args:
        K: camera matrix [px].
        g_bc: the camera (OpenCV axes) in the base frame.
        points_b: N x 3 points in the base frame [m].

    Returns:
        N x 2 pixel coordinates (u right, v down) [px]; NaN for a point behind the camera.
    """
    points_b = np.atleast_2d(np.asarray(points_b, dtype=float))
    g_cb = np.linalg.inv(g_bc)
    points_c = points_b @ g_cb[:3, :3].T + g_cb[:3, 3]
    uvw = points_c @ np.asarray(K, dtype=float).T
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = uvw[:, :2] / uvw[:, 2:3]
    uv[points_c[:, 2] <= 0.0] = np.nan
    return uv

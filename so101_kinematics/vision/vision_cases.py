"""``so101-check-vision``'s cases: camera poses around the target tag, and the simulator's truth.

The course's scene with the target tag (``tag_textures.TARGET_TAG``: 40 mm on a 52 mm square) at
(0.22, 0.05) m turned 25 deg, and :data:`VIEWS` cameras looking at it from 25 to 35 cm,
straight down (rolled) and from the side. For each: the rendered 640x480 image (a webcam's
blur and noise) through ``detect.py`` gives the tag's corners (the input a student's
``tag_pose_in_base`` gets); MuJoCo's ``d.cam_xpos`` / ``d.cam_xmat`` are the camera's pose
as the student reads it; the truth is the model's: the tag's pose (``tags.get_tag_pose_base``)
and, for ``camera_to_base``, points in front of the camera expressed in its OpenCV frame.
"""

from __future__ import annotations

import functools
import math

import mujoco
import numpy as np

from so101_kinematics.errors import VisionError
from so101_kinematics.opencv_import import require_opencv
from so101_kinematics.sim.tag_textures import TARGET_TAG, tag_geom_name
from so101_kinematics.vision.camera_model import R_MUJOCO_OPENCV, get_camera_pose_base
from so101_kinematics.vision.detect import find_tag, tag_corners
from so101_kinematics.vision.sim_camera import WEBCAM, SimCamera
from so101_kinematics.vision.tagged_scene import build_tagged_model, tagged_spec
from so101_kinematics.vision.tags import get_tag_pose_base

__all__ = ["TAG_AT", "VIEWS", "look_at", "vision_cases"]

TAG_AT = (0.22, 0.05, 25.0)
"""The target tag: x [m], y [m], yaw [deg] on the table."""
VIEWS = ((0.26, 90.0, 0.0, 30.0), (0.30, 60.0, 20.0, 0.0), (0.33, 45.0, 150.0, -15.0),
         (0.28, 55.0, 80.0, 10.0), (0.35, 70.0, -30.0, 170.0))
"""Each camera: (distance [m], elevation [deg] above the table, azimuth [deg] from +x, roll
[deg] about its optical axis), looking at the tag's centre."""
POINTS = ((0.0, 0.0, 0.3), (0.05, -0.03, 0.25), (-0.08, 0.06, 0.4))
"""[m] Points in each camera's OpenCV frame given to ``camera_to_base`` (the tag's centre too)."""


def look_at(target, distance: float, elevation: float, azimuth: float, roll: float):
    """MuJoCo's ``pos`` and ``xyaxes`` of a camera looking at ``target`` (angles [deg])."""
    e, a, r = (math.radians(v) for v in (elevation, azimuth, roll))
    back = np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])
    forward = -back
    right = np.cross(forward, [0.0, 0.0, 1.0]) if abs(forward[2]) < 0.999 else \
        np.array([-math.sin(a), math.cos(a), 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    x = math.cos(r) * right + math.sin(r) * up
    y = -math.sin(r) * right + math.cos(r) * up
    return np.asarray(target, dtype=float) + distance * back, np.concatenate([x, y])


@functools.lru_cache(maxsize=1)
def vision_cases() -> tuple[dict, ...]:
    """The cases (JSON-ready lists): inputs and the simulator's truth, rendered once.

    Raises:
        VisionError: a view in which the tag is not found (a broken scene).
    """
    cv2 = require_opencv()
    spec = tagged_spec(target_at=TAG_AT)
    table_z = float(spec.geom("table").pos[2])
    centre = (TAG_AT[0], TAG_AT[1], table_z)
    for index, view in enumerate(VIEWS):
        pos, xyaxes = look_at(centre, *view)
        spec.worldbody.add_camera(name=f"check_{index}", pos=pos.tolist(),
                                  xyaxes=xyaxes.tolist(), fovy=50.0)
    m = build_tagged_model(spec=spec)
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_forward(m, d)
    truth_tag = get_tag_pose_base(m, d, tag_geom_name(TARGET_TAG))
    cases = []
    for index in range(len(VIEWS)):
        name = f"check_{index}"
        with SimCamera(m, d, name, effects=WEBCAM) as camera:
            image, K = camera.read(), camera.intrinsics()
        seen = find_tag(image, K, TARGET_TAG)
        if seen is None:
            raise VisionError(f"The checker's camera {name} does not see the target tag.")
        g_bc = get_camera_pose_base(m, d, name)
        points = [np.linalg.inv(g_bc) @ truth_tag[:, 3], *(np.append(p, 1.0) for p in POINTS)]
        ok, rvec, tvec = cv2.solvePnP(tag_corners(TARGET_TAG.size), seen.corners, K, None,
                                      flags=cv2.SOLVEPNP_IPPE_SQUARE)
        cases.append({
            "camera": name, "cam_pos": g_bc[:3, 3].tolist(),  # d.cam_xpos, in the base frame
            "cam_xmat": (g_bc[:3, :3] @ R_MUJOCO_OPENCV).ravel().tolist(), "K": K.tolist(),
            "corners": seen.corners.tolist(), "points": [p[:3].tolist() for p in points],
            "truth_points": [(g_bc @ p)[:3].tolist() for p in points],
            "truth_tag": truth_tag.tolist(), "t_cam": tvec.ravel().tolist()})
    return tuple(cases)

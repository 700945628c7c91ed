"""Render the final-project page's picture: each camera's view with the tags it finds drawn."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

_HERE = Path(__file__).resolve().parent
REPO = _HERE.parent
sys.path.insert(0, str(REPO))

import so101_kinematics.display as so101_display  # noqa: E402, F401  (before mujoco: EGL when there is no display)

# isort: split
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from so101_kinematics.constants import CUBE_HALF_SIZE  # noqa: E402
from so101_kinematics.errors import SO101Error  # noqa: E402
from so101_kinematics.fast_fk import forward_kinematics  # noqa: E402
from so101_kinematics.ik.call_shapes import get_inverse_kinematics  # noqa: E402
from so101_kinematics.opencv_import import require_opencv  # noqa: E402
from so101_kinematics.outputs import (  # noqa: E402
    PNG,
    add_overwrite_argument,
    check_output_path,
    write_png_atomic,
)
from so101_kinematics.planning.plans import (  # noqa: E402
    FINAL_CONFIGURATION,
    STARTING_CONFIGURATION,
)
from so101_kinematics.sim.scene import to_radians  # noqa: E402
from so101_kinematics.vision.detect import detect_tags  # noqa: E402
from so101_kinematics.vision.sim_camera import WEBCAM, ImageEffects, SimCamera  # noqa: E402
from so101_kinematics.vision.tagged_scene import build_tagged_model  # noqa: E402

PNG_PATH = REPO / "docs" / "final_project_cameras.png"
SIZE = (640, 480)  # [px] each camera's image
CAMERAS = ("overhead", "wrist")
WRIST_VIEW_HEIGHT = 0.15  # [m] the object frame above the table for the wrist's picture
WRIST_VIEW_BACK = 0.08  # [m] the object frame this far short of the cube (towards the base)
WRIST_VIEW_PITCH = 60.0  # [deg] the fingers' angle below the horizontal (90: straight down)
PICTURE_EFFECTS = ImageEffects(blur_px=WEBCAM.blur_px)  # the webcam's blur; its noise would
# triple the PNG (the tests and benchmarks run with the noise)
AXIS_LENGTH = 0.02  # [m] the drawn tag axes


def tagged_scene() -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The course's cube (tagged) at its pick position, the target tag at the place position."""
    pick, _ = forward_kinematics(STARTING_CONFIGURATION)
    place, _ = forward_kinematics(FINAL_CONFIGURATION)
    m = build_tagged_model((pick[0], pick[1]), (place[0], place[1]))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    cube = np.array([pick[0], pick[1], CUBE_HALF_SIZE])
    direction = cube[:2] / np.linalg.norm(cube[:2])
    above = [*(cube[:2] - WRIST_VIEW_BACK * direction), WRIST_VIEW_HEIGHT]
    for joint, angle in to_radians(m, get_inverse_kinematics(
            above, approach="pitch", pitch_deg=WRIST_VIEW_PITCH, yaw_deg=None)).items():
        d.qpos[m.joint(joint).qposadr[0]] = angle
    mujoco.mj_forward(m, d)
    return m, d


def annotated(camera: SimCamera) -> np.ndarray:
    """The camera's image with each tag found outlined and its axes drawn (x red, y green)."""
    cv2 = require_opencv()
    image = camera.read()
    K = camera.intrinsics()
    out = image.copy()
    for seen in detect_tags(image, K, g_bc=camera.pose()):
        cv2.polylines(out, [seen.corners.astype(np.int32).reshape(-1, 1, 2)], True,
                      (255, 200, 0), 2)
        rvec = cv2.Rodrigues(seen.g_ct[:3, :3])[0]
        cv2.drawFrameAxes(out, K, np.zeros(5), rvec, seen.g_ct[:3, 3], AXIS_LENGTH, 2)
        x, y, z = seen.g_bt[:3, 3] * 1000
        cv2.putText(out, f"{seen.tag.name} ({x:.0f}, {y:.0f}, {z:.0f}) mm",
                    tuple(int(v) for v in seen.corners[3] + (-60, 18)),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.45, (20, 20, 20), 1, cv2.LINE_AA)
    cv2.putText(out, camera.name, (10, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.7, (20, 20, 20), 2,
                cv2.LINE_AA)
    return out


def main() -> int:
    """Write the PNG: both cameras side by side (the printable tags: ``so101 tags PATH.pdf``)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_overwrite_argument(parser)
    args = parser.parse_args()
    try:  # replaces only a PNG of ours (its Software chunk), or with --overwrite
        check_output_path(PNG_PATH, "the picture", overwrite=args.overwrite, kind=PNG)
        m, d = tagged_scene()
        views = []
        for name in CAMERAS:
            with SimCamera(m, d, name, SIZE, effects=PICTURE_EFFECTS) as cam:
                views.append(annotated(cam))
    except SO101Error as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    write_png_atomic(PNG_PATH, np.hstack(views), "scripts/make_vision_pictures.py")
    print(f"Wrote {PNG_PATH.relative_to(REPO)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

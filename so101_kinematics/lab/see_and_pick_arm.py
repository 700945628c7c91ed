"""See and pick on an arm through lerobot: a camera opened by lerobot's camera class, its bus.

The hardware half of ``see_and_pick.py --port PORT --camera ADDRESS``:

1. **look**: one frame read by lerobot's own camera class (``lerobot_camera_so101_virtual``,
   an ``OpenCVCamera`` for the virtual arm's served stream, and lerobot's ``OpenCVCamera`` for
   a device, ``/dev/videoN`` or an index, both as ``vision/webcam.py``'s ``Webcam``), the
   tags found by the one detection path (``vision/detect.py``) and laid on the table by
   ``detect.flat_pose`` with the camera's ``K``, distortion and pose. Those are the model's
   camera (``camera_model``, default ``overhead``: exact for the virtual arm, whose camera is
   the model's), or a real camera's from the report
   ``calibrate_camera.py --photos DIR --mount fixed --json PATH`` wrote (``camera_calibration``);
2. **plan**: the course's Cartesian pick-and-place (``cartesian_plan``, what
   ``pick_place_hw.py --pick/--place`` runs) from the cube's seen position and yaw to the
   target tag's;
3. **move**: ``hw/run.py``'s ``run_on_arm`` through lerobot's ``FeetechMotorsBus``, the
   checks before torque on and the fault policy as ``pick_place_hw.py``'s: a fault, a refused
   goal or a stop signal ends as every run does, and the run's result (``hw/run.ending``: the
   last line, from the servos' read-back) comes back completed or aborted alike;
4. **score**: the camera looks again; the cube tag's centre against the target's first seen
   (the camera alone), or the bus's cube sensor when the tag is hidden or the camera is gone
   (the virtual arm).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import mujoco
import numpy as np

from so101_kinematics.constants import CUBE_HALF_SIZE
from so101_kinematics.errors import TagNotInView, VisionError
from so101_kinematics.hw.run import MotionAborted, RunResult, run_on_arm
from so101_kinematics.hw.teach import grasp_outcome
from so101_kinematics.planning.cartesian_plan import cartesian_plan
from so101_kinematics.sim.cube import build_model
from so101_kinematics.sim.tag_textures import CUBE_TAG, TAG_THICKNESS, TARGET_TAG
from so101_kinematics.vision.camera_model import camera_intrinsics, get_camera_pose_base
from so101_kinematics.vision.detect import find_tag, flat_pose, no_tag_message
from so101_kinematics.vision.webcam import load_calibration, load_camera_in_base, open_camera

__all__ = ["ARM_PLACE_TOLERANCE", "camera_view", "look_through_lerobot",
           "read_lerobot_frame", "see_and_pick_on_arm", "tag_height"]

ARM_PLACE_TOLERANCE = 0.010
"""[m] placed: the cube's centre this near the target tag's (the course's arm figure)."""
TABLE_TOP_Z = 0.0  # [m] the table top in the base frame (the lab's mount: --base-height)


def tag_height(tag) -> float:
    """[m] The height of ``tag``'s face, lying flat, in the base frame.

    The cube's tag on the top of a cube resting on the table, the target's on the table.
    """
    cube_top = 2 * CUBE_HALF_SIZE if tag.name == CUBE_TAG.name else 0.0
    return TABLE_TOP_Z + cube_top + TAG_THICKNESS


def read_lerobot_frame(address: str, size: Sequence[int] = (640, 480)) -> np.ndarray:
    """One RGB frame of the camera at ``address``, read by lerobot's own camera class."""
    with open_camera(address, *size) as camera:
        return camera.read()


def camera_view(camera: str = "overhead", size: Sequence[int] = (640, 480),
                camera_calibration=None) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """``(K, dist, g_bc)``: a calibrated camera's, or the model's camera ``camera``.

    With ``camera_calibration`` (calibrate_camera.py's report) the real camera's; without,
    the model's (no distortion; exact for the virtual arm).

    Raises:
        VisionError: a report that is not calibrate_camera.py's, or for another size (one line).
    """
    if camera_calibration is not None:
        K, dist = load_calibration(camera_calibration, *size)
        return K, dist, load_camera_in_base(camera_calibration)
    m = build_model(render_meshes=True)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    return camera_intrinsics(m, camera, *size), None, get_camera_pose_base(m, d, camera)


def look_through_lerobot(address: str, camera: str = "overhead",
                         size: Sequence[int] = (640, 480),
                         tags=(CUBE_TAG, TARGET_TAG),
                         camera_calibration=None) -> dict[str, np.ndarray]:
    """The tags' poses ``g_bt`` in the base frame from one frame, by tag name.

    Raises:
        TagNotInView: a tag is not in the frame (one line).
        VisionError: a bad camera calibration, no camera at ``address`` (one line).
    """
    K, dist, g_bc = camera_view(camera, size, camera_calibration)
    image = read_lerobot_frame(address, size)
    poses = {}
    for tag in tags:
        seen = find_tag(image, K, tag, dist)
        if seen is None:
            raise TagNotInView(no_tag_message(tag, camera))
        poses[tag.name] = flat_pose(seen, K, g_bc, tag_height(tag), dist)
    return poses


def see_and_pick_on_arm(port: str, address: str, calibration: Mapping[str, Any], *,
                        camera: str = "overhead", size: Sequence[int] = (640, 480),
                        camera_calibration=None, **run_options) -> tuple[dict, RunResult]:
    """Look, plan, run on the arm at ``port``, look again: the report of one trial, the run.

    Returns:
        The report: ``success_rate``, ``trials`` (one: ``picked``, ``placed``,
        ``placed_error_mm``, ``aborted``, ...), ``cube_seen`` and ``target_seen`` (x, y [m],
        yaw [deg]); and ``run_on_arm``'s result, completed or aborted (its ``ending`` is the
        run's last line).

    Raises:
        TagNotInView: no tag before the run (nothing moved).
        VisionError, PlanError, HardwareError: refused before anything moved (one line).
    """
    seen = look_through_lerobot(address, camera, size, camera_calibration=camera_calibration)
    cube, target = seen[CUBE_TAG.name], seen[TARGET_TAG.name]
    yaw = float(np.degrees(np.arctan2(cube[1, 0], cube[0, 0])))
    plan = cartesian_plan((*cube[:2, 3], CUBE_HALF_SIZE), (*target[:2, 3], CUBE_HALF_SIZE),
                          cube_yaw_deg=yaw)
    try:
        result = run_on_arm(port, calibration, plan, **run_options)
    except MotionAborted as error:  # ended by the fault policy: scored and reported all the same
        result = error.result
    try:
        after, by = look_through_lerobot(address, camera, size, tags=(CUBE_TAG,),
                                         camera_calibration=camera_calibration)[
            CUBE_TAG.name][:2, 3], "camera"
    except VisionError:  # the tag hidden, or the camera gone: the arm has moved, its end stands
        after, by = (None, None) if result.cube is None else (
            np.asarray(result.cube.position_m[:2]), "cube sensor")
    error = None if after is None else float(np.hypot(*(after - target[:2, 3])))
    grasp = grasp_outcome(plan, result.cycles) or ""
    picked = result.aborted is None and "closed on the cube" in grasp
    placed = picked and error is not None and error <= ARM_PLACE_TOLERANCE
    trial = {"picked": picked, "placed": placed,
             "placed_error_mm": None if error is None else 1000.0 * error,
             "placed_measured_by": by, "aborted": None if result.aborted is None else
             str(result.aborted), "grasp": grasp}
    return {"success_rate": 1.0 if placed else 0.0, "trials": [trial],
            "cube_seen": [*map(float, cube[:2, 3]), yaw],
            "target_seen": [*map(float, target[:2, 3]),
                            float(np.degrees(np.arctan2(target[1, 0], target[0, 0])))]}, result

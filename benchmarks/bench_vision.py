"""Benchmark group "vision": the simulator's cameras and the detection path, per frame (issue 36).

Figures (medians over repeats, with spread):
  - render_fps_640x480: frames per second of ``SimCamera.read()`` at 640x480 from the
    ``overhead`` camera, headless, the arm moving between frames (goal >= 30, the issue's);
    render_fps_640x480_wrist: the same from the ``wrist`` camera;
  - render_fps_640x480_webcam: the overhead camera with the webcam-like effects
    (``sim_camera.WEBCAM``: blur and noise), and webcam_effects_ms, their cost per frame;
  - render_reference_fps_640x480: reference, ``sim/render.py``'s ``FrameRenderer`` on the
    course's ``pick_place`` camera in the same run (what the videos render), and
    render_vs_reference, the ratio (load on a shared machine slows both alike);
  - detect_pose_ms: detection and pose of every tag in one 640x480 frame (``detect_tags``:
    both tags, seen from a camera 30 cm away, with the webcam effects), and
    detect_reference_ms, OpenCV's
    ``ArucoDetector.detectMarkers`` alone on the same frame; detect_pose_vs_detector, the
    ratio (what the corner refinement and ``solvePnP`` add). Left out, with a note, when
    OpenCV is missing;
  - see_and_pick_cycle_s: the wall time of one see-and-pick trial (``see_and_pick.run_trial``:
    the scene built, the arm out of the camera's way, the overhead camera's image with the
    webcam's effects, both tags' poses, the plan by the IK, 21 s of simulated motion with the
    STS3215 servos), the cube at (0.20, 0.10) m turned 30 deg, the target at the course's
    place; see_and_pick_reference_s, reference: the same scene, moves and plan from the
    cube's true pose, no camera, in the same run; see_and_pick_vs_reference, the ratio (what
    seeing adds to a pick-and-place cycle).
"""

from __future__ import annotations

import sys
import time


def _fps(camera, m, d, frames: int, repeats: int) -> list[float]:
    import mujoco

    camera.read()  # warm-up
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        for i in range(frames):
            d.qpos[m.joint("shoulder_pan").qposadr[0]] = -0.8 + 1.6 * i / frames
            mujoco.mj_kinematics(m, d)
            camera.read()
        samples.append(frames / (time.perf_counter() - start))
    return samples


def _scene():
    """The course's scene with the tagged cube, the target tag and a camera 30 cm away."""
    import mujoco

    from so101_kinematics.vision.tagged_scene import build_tagged_model, tagged_spec

    spec = tagged_spec((0.25, 0.10, 30.0), (0.25, -0.12, -20.0))
    spec.worldbody.add_camera(name="probe", pos=[0.10, -0.01, 0.27],
                              xyaxes=[0, -1, 0, 0.866025, 0, 0.5], fovy=58.0)
    m = build_tagged_model(spec=spec)
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_forward(m, d)
    return m, d


def _detection(m, d, repeats: int) -> dict:
    import numpy as np

    from benchmarks.common import per_call_us, summarize
    from so101_kinematics.opencv_import import require_opencv
    from so101_kinematics.sim.tag_textures import CUBE_TAG, TAG_DICTIONARY, TARGET_TAG
    from so101_kinematics.vision.detect import detect_tags, find_tag
    from so101_kinematics.vision.sim_camera import WEBCAM, SimCamera

    cv2 = require_opencv()
    with SimCamera(m, d, "probe", effects=WEBCAM) as camera:
        image, K, g_bc = camera.read(), camera.intrinsics(), camera.pose()
    # the tagged scene's two tags (the throw's cup mat, TAGS' third, is not in it)
    found = [find_tag(image, K, tag, g_bc=g_bc) for tag in (CUBE_TAG, TARGET_TAG)]
    if any(seen is None for seen in found):
        raise RuntimeError("the benchmark's frame lost a tag: the measurement would be wrong")
    grey = cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
    detector = cv2.aruco.ArucoDetector(
        cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, TAG_DICTIONARY)),
        cv2.aruco.DetectorParameters())
    pose = per_call_us(lambda: detect_tags(image, K, g_bc=g_bc), 10, repeats)
    reference = per_call_us(lambda: detector.detectMarkers(grey), 10, repeats)
    out = {"detect_pose_ms": summarize([us / 1000 for us in pose]),
           "detect_reference_ms": summarize([us / 1000 for us in reference])}
    out["detect_pose_vs_detector"] = float(np.median(pose) / np.median(reference))
    return out


CUBE_AT = (0.20, 0.10, 30.0)
"""The benchmark's cube: x [m], y [m], yaw [deg] (in reach, off the target)."""


def _pick_without_camera(cube_at, target_at) -> None:
    """The reference: one see-and-pick's scene, moves and plan from the true poses, no camera."""
    import mujoco

    from so101_kinematics.planning.motion import run_plan
    from so101_kinematics.sim import scene, stepping
    from so101_kinematics.sim.pick_place import INITIAL_KEYFRAME
    from so101_kinematics.sim.tag_textures import CUBE_TAG, TARGET_TAG, tag_geom_name
    from so101_kinematics.vision.see_and_pick import (
        LOOK_MOVE,
        LOOK_POSE,
        Sighting,
        plan_from_sighting,
    )
    from so101_kinematics.vision.tagged_scene import build_tagged_model
    from so101_kinematics.vision.tags import get_tag_pose_base

    m = build_tagged_model(cube_at, target_at)
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key(INITIAL_KEYFRAME).id)
    mujoco.mj_forward(m, d)
    rest = scene.get_configuration(m, d)
    stepping.move_to_pose(m, d, None, dict(rest, **LOOK_POSE), LOOK_MOVE[0])
    stepping.hold_position(m, d, None, LOOK_MOVE[1])
    truth = Sighting(get_tag_pose_base(m, d, tag_geom_name(CUBE_TAG, "cube")),
                     get_tag_pose_base(m, d, tag_geom_name(TARGET_TAG)), d.time)
    plan = plan_from_sighting(truth, rest)
    run_plan(plan, lambda cfg, duration: stepping.move_to_pose(m, d, None, cfg, duration),
             lambda duration: stepping.hold_position(m, d, None, duration), rest)


def _see_and_pick(repeats: int) -> dict:
    from benchmarks.common import summarize
    from so101_kinematics.vision.see_and_pick import course_target, run_trial

    target = course_target()
    trial, reference = [], []
    for _ in range(repeats):
        start = time.perf_counter()
        result = run_trial(CUBE_AT, target)
        trial.append(time.perf_counter() - start)
        if not result.success:
            raise RuntimeError(f"the benchmark's see-and-pick failed: {result.reason}")
        start = time.perf_counter()
        _pick_without_camera(CUBE_AT, target)
        reference.append(time.perf_counter() - start)
    out = {"see_and_pick_cycle_s": summarize(trial),
           "see_and_pick_reference_s": summarize(reference)}
    out["see_and_pick_vs_reference"] = (out["see_and_pick_cycle_s"]["median"]
                                        / out["see_and_pick_reference_s"]["median"])
    return out


def bench_vision(quick: bool) -> dict:
    """Run the group; ``quick`` uses fewer repeats."""
    from benchmarks.common import summarize
    from so101_kinematics.errors import OpenCVMissing
    from so101_kinematics.sim.render import FrameRenderer
    from so101_kinematics.vision.sim_camera import WEBCAM, SimCamera

    m, d = _scene()
    frames, repeats = (30, 3) if quick else (90, 5)
    out: dict = {}
    for key, camera, effects in (("render_fps_640x480", "overhead", None),
                                 ("render_fps_640x480_wrist", "wrist", None),
                                 ("render_fps_640x480_webcam", "overhead", WEBCAM)):
        with SimCamera(m, d, camera, effects=effects) as cam:
            out[key] = summarize(_fps(cam, m, d, frames, repeats))
    reference = FrameRenderer(m, d, (640, 480))
    reference.read = reference.render
    out["render_reference_fps_640x480"] = summarize(_fps(reference, m, d, frames, repeats))
    reference.close()
    out["render_vs_reference"] = (out["render_fps_640x480"]["median"]
                                  / out["render_reference_fps_640x480"]["median"])
    out["webcam_effects_ms"] = 1000.0 * (1.0 / out["render_fps_640x480_webcam"]["median"]
                                         - 1.0 / out["render_fps_640x480"]["median"])
    try:
        out.update(_detection(m, d, repeats))
        out.update(_see_and_pick(2 if quick else 5))
    except OpenCVMissing as error:
        print(f"vision: detection not measured: {error}", file=sys.stderr)
    return out

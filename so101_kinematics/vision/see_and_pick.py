"""See and pick: the fixed camera finds the tagged cube and the target, the arm carries it there.

One trial (:func:`run_trial`) in the simulator, with the measured STS3215 servos:

1. **look**: the arm turns its gripper up, out of the camera's way (:data:`LOOK_POSE`); the
   ``overhead`` camera's image (webcam-like: blur and noise) goes through ``detect.py``'s
   one path; each tag lies flat at a known height (the cube's on the top of a cube resting
   on the table, the target's on the table), so :func:`look` takes its pose from
   ``detect.flat_pose`` (the full 6-D pose of a 20 mm tag 55 cm away is centimetres off;
   its corners' rays met with the known plane are within 2 mm). The result is a
   :class:`Sighting` stamped with the clock of its image; no tag in
   :data:`LOOK_FRAMES` frames, no sighting (``TagNotInView``, one line);
2. **plan**: ``cartesian_plan``, the course's pick-and-place waypoints solved by the IK,
   with the cube's yaw from its tag (a cube repeats every 90 deg: the IK picks the wrist
   roll) and the target tag's yaw at the place;
3. **move**, only on a fresh sighting: the plan starts only if its sighting is at most
   :data:`MAX_POSE_AGE` old (``StalePoseError`` otherwise: look again);
4. **score** from the simulator's truth, never used before: was the cube lifted and held,
   how far its centre ended from the target tag's centre (:data:`PLACE_TOLERANCE`).

The camera's pose in the base frame is the mount's (``model/table.xml``), as a
calibration would give it on the real rig; the cube's pose comes from the image alone.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import mujoco
import numpy as np

from so101_kinematics.constants import CUBE_HALF_SIZE, CUBE_SIZE
from so101_kinematics.errors import StalePoseError, TagNotInView, UnreachableError
from so101_kinematics.fast_fk import forward_kinematics
from so101_kinematics.frames import ARM_JOINTS
from so101_kinematics.ik.geometry import PAN_AXIS_POINT
from so101_kinematics.planning.cartesian_plan import cartesian_plan
from so101_kinematics.planning.motion import Plan, Step, run_plan
from so101_kinematics.planning.plans import default_plan, pick_and_place_steps, validate_plan
from so101_kinematics.sim import scene, stepping
from so101_kinematics.sim.cube import CubeMonitor, cube_state, scene_limits
from so101_kinematics.sim.pick_place import INITIAL_KEYFRAME, MIN_LIFT, TILT_TOLERANCE
from so101_kinematics.sim.tag_textures import CUBE_TAG, TAG_THICKNESS, TARGET_TAG, tag_geom_name
from so101_kinematics.vision.detect import find_tag, flat_pose, no_tag_message
from so101_kinematics.vision.see_and_pick_video import inset_recorder
from so101_kinematics.vision.sim_camera import WEBCAM, ImageEffects, SimCamera
from so101_kinematics.vision.tagged_scene import build_tagged_model
from so101_kinematics.vision.tags import get_tag_pose_base

__all__ = [
    "CAMERA", "FRAME_RATE", "LOOK_FRAMES", "LOOK_MOVE", "LOOK_POSE", "MAX_POSE_AGE",
    "PICK_BEARING", "PICK_RADIUS", "PLACE_TOLERANCE", "Sighting", "TrialResult",
    "check_pose_age", "course_target", "look", "look_in_sim", "plan_from_sighting",
    "random_cube", "run_trial", "run_trials",
]

CAMERA = "overhead"
"""The fixed camera the program looks with (``model/table.xml``)."""
LOOK_POSE = {"shoulder_pan": 0.0, "shoulder_lift": -90.0, "elbow_flex": 90.0,
             "wrist_flex": -90.0, "wrist_roll": 0.0}
"""[deg] Where the arm waits while the camera looks: the rest pose (``home``) with the
gripper turned up (wrist_flex -90 deg, not 30). At rest the gripper hides the table around
(0.20, 0) m from the overhead camera; turned up, the arm's whole outline falls within 0.09 m
of the pan axis or behind it (the camera's segmentation image, projected on the table), and
the way there keeps every part of the arm 5 cm above the table (folding the wrist down
instead, to +90 deg, sweeps the jaws through a cube at (0.21, 0) m)."""
LOOK_MOVE = (1.0, 0.3)
"""[s] The move to :data:`LOOK_POSE` and the hold after it (the arm still when it is seen)."""
LOOK_FRAMES = 5
"""Frames the camera is read at most (at :data:`FRAME_RATE`) until both tags are found."""
FRAME_RATE = 30.0
"""[frames/s] The simulated camera's rate while it looks."""
MAX_POSE_AGE = 0.5
"""[s] The oldest sighting the arm starts a plan on (its image's clock to the first move's)."""
PLACE_TOLERANCE = 0.005
"""[m] Placed: the cube's centre this close (horizontally) to the target tag's centre."""
PICK_RADIUS = (0.14, 0.25)
"""[m] Random cubes: distance from the shoulder_pan axis. The course's plan (approach, slide,
lift) solves top-down for every yaw from 0.12 to 0.27 m; 2 cm kept off each end."""
PICK_BEARING = (-80.0, 80.0)
"""[deg] Random cubes: bearing from the pan axis (0: straight ahead, +x)."""
MIN_TARGET_DISTANCE = 0.08
"""[m] Random cubes: at least this far from the target tag (its 52 mm square stays clear)."""


def course_target() -> tuple[float, float, float]:
    """Where the course's plan puts the cube: (x [m], y [m], yaw 0 [deg]), its place's FK."""
    _, place = pick_and_place_steps(default_plan())
    position, _ = forward_kinematics({j: place.configuration[j] for j in ARM_JOINTS})
    return float(position[0]), float(position[1]), 0.0


def random_cube(rng: np.random.Generator, target_xy) -> tuple[float, float, float]:
    """A cube pose (x [m], y [m], yaw [deg]) in the reach (:data:`PICK_RADIUS`), off the target."""
    while True:
        radius = rng.uniform(*PICK_RADIUS)
        bearing = math.radians(rng.uniform(*PICK_BEARING))
        x = PAN_AXIS_POINT[0] + radius * math.cos(bearing)
        y = PAN_AXIS_POINT[1] + radius * math.sin(bearing)
        yaw = float(rng.uniform(-180.0, 180.0))
        if math.dist((x, y), target_xy[:2]) >= MIN_TARGET_DISTANCE:
            return float(x), float(y), yaw


@dataclass(frozen=True)
class Sighting:
    """The cube and the target as one image showed them (poses in the base frame).

    Attributes:
        cube: the cube tag's pose (4x4) [m], z up (it lies flat on the cube's top).
        target: the target tag's pose [m].
        time: the clock of the image [s] (the simulator's time; a real camera's timestamp).
        corners: the tags' corner pixels, by tag name (for drawing).
    """

    cube: np.ndarray
    target: np.ndarray
    time: float
    corners: dict = field(default_factory=dict)

    def yaw_deg(self, which: str) -> float:
        """The yaw [deg] of ``"cube"`` or ``"target"`` in (-180, 180]."""
        g = self.cube if which == "cube" else self.target
        return math.degrees(math.atan2(g[1, 0], g[0, 0]))


def look(image: np.ndarray, K: np.ndarray, g_bc: np.ndarray, stamp: float,
         camera: str = CAMERA) -> Sighting:
    """Find the cube and the target in one image: :class:`Sighting`.

    Args:
        image: the camera's H x W x 3 RGB image.
        K: its camera matrix [px].
        g_bc: the camera's OpenCV frame in the base frame [m] (the mount or a calibration).
        stamp: the image's time [s].
        camera: the camera's name, for the message.

    Raises:
        TagNotInView: a tag not wholly in the image (``detect.no_tag_message``).
    """
    heights = {CUBE_TAG.name: CUBE_SIZE + TAG_THICKNESS, TARGET_TAG.name: TAG_THICKNESS}
    poses, corners = {}, {}
    for tag in (CUBE_TAG, TARGET_TAG):
        seen = find_tag(image, K, tag)
        if seen is None:
            raise TagNotInView(no_tag_message(tag, camera))
        poses[tag.name] = flat_pose(seen, K, g_bc, heights[tag.name])
        corners[tag.name] = seen.corners
    return Sighting(poses[CUBE_TAG.name], poses[TARGET_TAG.name], float(stamp), corners)


def look_in_sim(m: mujoco.MjModel, d: mujoco.MjData, camera: SimCamera,
                frames: int = LOOK_FRAMES) -> Sighting:
    """:func:`look` at up to ``frames`` frames of ``camera``, the arm holding; the first seen.

    A webcam's noise makes a small tag drop out of an odd frame: the simulation runs one
    frame period (:data:`FRAME_RATE`) between the frames, so the sighting's stamp is its own
    frame's time.

    Raises:
        TagNotInView: a tag missing from every frame.
    """
    K, g_bc = camera.intrinsics(), camera.pose()
    for frame in range(frames):
        if frame:
            stepping.hold_position(m, d, None, 1.0 / FRAME_RATE)
        try:
            return look(camera.read(), K, g_bc, d.time, camera.name)
        except TagNotInView:
            if frame == frames - 1:
                raise
    raise TagNotInView("no frame was read")  # frames < 1


def plan_from_sighting(sighting: Sighting, rest=None) -> Plan:
    """The course's pick-and-place from the sighting: the cube to the target, by the IK.

    Args:
        sighting: where the cube and the target are.
        rest: a configuration [deg] to go to first (the rest pose, from
            :data:`LOOK_POSE`), in ``LOOK_MOVE[0]`` s; the plan ends there.

    Raises:
        UnreachableError: a waypoint the arm cannot reach (the message names it).
    """
    pick = (*sighting.cube[:2, 3], CUBE_HALF_SIZE)
    place = (*sighting.target[:2, 3], CUBE_HALF_SIZE)
    plan = cartesian_plan(pick, place, cube_yaw_deg=sighting.yaw_deg("cube"),
                          place_yaw_deg=sighting.yaw_deg("target"))
    if rest is not None:
        plan.steps.insert(0, Step("rest", dict(rest), LOOK_MOVE[0], 0.0))
    return validate_plan(plan, scene_limits())


def check_pose_age(sighting: Sighting, now: float, max_age: float = MAX_POSE_AGE) -> float:
    """The sighting's age at ``now`` [s]; ``StalePoseError`` past ``max_age``."""
    age = now - sighting.time
    if age > max_age:
        raise StalePoseError(f"The cube's pose is {age:.2f} s old, more than the "
                             f"{max_age:g} s the arm moves on. Fix: look again (a new image) "
                             "and plan from that.")
    return age


@dataclass
class TrialResult:
    """One trial's outcome; the JSON's ``trials`` items (lengths [mm], angles [deg]).

    ``placed_error_mm`` is always measured (from the simulator's truth): a cube never
    moved is as far from the target as it started. ``refused``: nothing moved (no tag in
    view, or the cube out of reach; ``reason`` says which).
    """

    picked: bool
    placed_error_mm: float
    success: bool
    reason: str | None
    refused: bool
    cube_true: list[float]
    target_true: list[float]
    cube_seen_error_mm: float | None = None
    cube_seen_yaw_error_deg: float | None = None
    target_seen_error_mm: float | None = None
    pose_age_s: float | None = None
    tilt_deg: float = 0.0
    wall_time_s: float = 0.0

    def as_dict(self) -> dict:
        """The JSON item: numbers rounded to what they mean."""
        return {key: round(value, 3) if isinstance(value, float) else value
                for key, value in asdict(self).items()}


def _yaw_error(seen_deg: float, true_deg: float, period: float) -> float:
    return abs((seen_deg - true_deg + period / 2) % period - period / 2)


def _seen_errors(m, d, sighting: Sighting) -> dict:
    """How far the sighting is from the truth (scored after the plan is made)."""
    cube = get_tag_pose_base(m, d, tag_geom_name(CUBE_TAG, "cube"))
    target = get_tag_pose_base(m, d, tag_geom_name(TARGET_TAG))
    true_yaw = math.degrees(math.atan2(cube[1, 0], cube[0, 0]))
    return dict(cube_seen_error_mm=1000 * math.dist(sighting.cube[:2, 3], cube[:2, 3]),
                cube_seen_yaw_error_deg=_yaw_error(sighting.yaw_deg("cube"), true_yaw, 360.0),
                target_seen_error_mm=1000 * math.dist(sighting.target[:2, 3], target[:2, 3]))


def _target_centre(m, d) -> np.ndarray:
    return get_tag_pose_base(m, d, tag_geom_name(TARGET_TAG))[:2, 3]


def run_trial(cube_at, target_at, *, effects: ImageEffects | None = WEBCAM,
              video: str | Path | None = None, progress: bool = False) -> TrialResult:
    """One see-and-pick in the simulator: look, plan, move, score (see the module).

    Args:
        cube_at: the tagged cube's (x [m], y [m], yaw [deg]) on the table: the truth the
            program does not read until it scores.
        target_at: the target tag's (x [m], y [m], yaw [deg]).
        effects: the overhead camera's webcam effects (None: the image as rendered).
        video: an MP4 path: the run, with the camera's view inset (``see_and_pick_video``).
        progress: a progress bar while recording.

    Returns:
        The result; a trial that cannot start (no tag, out of reach) is a failed one,
        with the one-line reason.
    """
    wall0 = time.perf_counter()
    m = build_tagged_model(cube_at, target_at)
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key(INITIAL_KEYFRAME).id)
    mujoco.mj_forward(m, d)
    rest = scene.get_configuration(m, d)
    stepping.move_to_pose(m, d, None, dict(rest, **LOOK_POSE), LOOK_MOVE[0])
    stepping.hold_position(m, d, None, LOOK_MOVE[1])
    truth = dict(cube_true=[float(v) for v in cube_at], target_true=[float(v) for v in target_at])
    with SimCamera(m, d, CAMERA, effects=effects) as camera:
        try:
            sighting = look_in_sim(m, d, camera)
            plan = plan_from_sighting(sighting, rest)
        except (TagNotInView, UnreachableError) as error:  # nothing moved: score it as it is
            start_error = 1000 * math.dist(d.body("cube").xpos[:2], _target_centre(m, d))
            return TrialResult(False, start_error, False, str(error), True, **truth,
                               wall_time_s=time.perf_counter() - wall0)
    seen = _seen_errors(m, d, sighting)
    age = check_pose_age(sighting, d.time)  # the plan starts now: its pose is this old
    monitor = _execute(m, d, plan, sighting, video, progress, rest)
    centre, tilt, _ = cube_state(m, d)
    error = float(np.linalg.norm(centre[:2] - _target_centre(m, d)))
    picked = monitor.max_lift >= MIN_LIFT and not monitor.dropped
    success = picked and error <= PLACE_TOLERANCE and tilt <= TILT_TOLERANCE
    reason = None if success else _failure(monitor, error, tilt)
    return TrialResult(picked, 1000 * error, success, reason, False, **truth, **seen,
                       pose_age_s=age,
                       tilt_deg=tilt, wall_time_s=time.perf_counter() - wall0)


def _failure(monitor: CubeMonitor, error: float, tilt: float) -> str:
    if monitor.max_lift < MIN_LIFT:
        return f"never lifted {MIN_LIFT * 1000:.0f} mm (the grasp failed)"
    if monitor.dropped:
        return "it fell out of the gripper"
    if tilt > TILT_TOLERANCE:
        return f"it ended tilted {tilt:.0f} deg"
    return (f"placed {error * 1000:.1f} mm from the target tag's centre (tolerance "
            f"{PLACE_TOLERANCE * 1000:.0f} mm)")


def _execute(m, d, plan: Plan, sighting: Sighting, video, progress: bool,
             initial) -> CubeMonitor:
    """Run the plan on ``d`` (from its state now, ending at ``initial``), into a video if asked.

    Returns:
        The cube's monitor (lifted, dropped).
    """
    recorder = None if video is None else inset_recorder(m, d, video, plan, sighting, progress)
    finished = False
    try:
        monitor = CubeMonitor(m, d, recorder)
        run_plan(plan, lambda cfg, duration: stepping.move_to_pose(m, d, monitor, cfg, duration),
                 lambda duration: stepping.hold_position(m, d, monitor, duration), initial)
        monitor.check()
        finished = True
    finally:
        if recorder is not None:
            recorder.close(complete=finished)
    return monitor


def _stats(values) -> dict | None:
    values = [v for v in values if v is not None]
    if not values:
        return None
    return {"mean": round(float(np.mean(values)), 3), "worst": round(float(np.max(values)), 3)}


def run_trials(trials: int, seed: int, *, cube_at=None, target_at=None,
               random_target: bool = False,
               effects: ImageEffects | None = WEBCAM, video: str | Path | None = None,
               progress: bool = False, on_trial=None) -> dict:
    """``trials`` see-and-picks, each cube at a seeded random pose (or at ``cube_at``).

    Args:
        trials: how many (at least 1).
        seed: the random poses' and the camera noise's seed.
        cube_at: every trial's cube (x [m], y [m], yaw [deg]) instead of random ones.
        target_at: the target tag's (x, y, yaw); default :func:`course_target`.
        random_target: each trial's target at a seeded random pose in the reach too
            (:func:`random_cube`'s region; the cube then at least 8 cm from it).
        effects: the camera's webcam effects (each trial's noise seeded from ``seed``).
        video: an MP4 of the first trial (the camera's view inset).
        progress: a progress bar while recording.
        on_trial: called with (index, :class:`TrialResult`) after each trial.

    Returns:
        The report: ``success_rate``, ``trials`` (each :meth:`TrialResult.as_dict`), and
        the placement and sighting errors' mean and worst [mm].
    """
    fixed_target = tuple(target_at) if target_at is not None else course_target()
    rng = np.random.default_rng(seed)
    results = []
    for index in range(trials):
        target_at = random_cube(rng, (math.inf, math.inf)) if random_target else fixed_target
        cube = tuple(cube_at) if cube_at is not None else random_cube(rng, target_at)
        noise = None if effects is None else replace(effects, seed=seed * 1000 + index)
        result = run_trial(cube, target_at, effects=noise,
                           video=video if index == 0 else None, progress=progress)
        results.append(result)
        if on_trial is not None:
            on_trial(index, result)
    picked = [r for r in results if r.picked]
    return {
        "success_rate": sum(r.success for r in results) / trials,
        "trials": [r.as_dict() for r in results],
        "seed": seed,
        "random_target": random_target,
        "picked": len(picked),
        "placed": sum(r.success for r in results),
        "place_tolerance_mm": PLACE_TOLERANCE * 1000,
        "placed_error_mm": _stats([r.placed_error_mm for r in picked]),
        "cube_seen_error_mm": _stats([r.cube_seen_error_mm for r in results]),
        "cube_seen_yaw_error_deg": _stats([r.cube_seen_yaw_error_deg for r in results]),
        "target_seen_error_mm": _stats([r.target_seen_error_mm for r in results]),
        "max_pose_age_s": MAX_POSE_AGE,
        "camera": CAMERA,
        "webcam_effects": None if effects is None else asdict(effects),
        "wall_time_s": round(sum(r.wall_time_s for r in results), 2),
    }

"""The tag follower: the wrist camera keeps a moving tag centred, by the course's resolved rate.

The target tag (``tag_textures.TARGET_TAG``, 40 mm) is a mocap body sliding on the table along a
circle or a line (:class:`TagPath`) at a stated speed. Each control cycle (one camera frame,
:data:`FOLLOW_RATE`):

1. **see**: the ``wrist`` camera's image (a webcam's blur and noise) through ``detect.py``'s
   one path; the tag lies flat on the table, so its position in the base frame comes from
   ``detect.flat_pose`` with the camera's pose from the FK of the *measured* joints and the
   camera's mount on the gripper (:func:`camera_in_tool`, as a hand-eye calibration gives it);
2. **want**: the camera :data:`HEIGHT` above the tag, looking straight down (then the tag
   is at the image's centre), the tag's velocity (from the last sightings, smoothed) fed
   forward and predicted to the image's age;
3. **step**: resolved-rate control with the course's analytic Jacobian
   (``ik.geometry.get_jacobian``, the object frame's; moved to the camera):
   ``dq = J^T (J J^T + lambda^2 I)^-1 (v + K e) dt`` on 5 rows, the camera's position (3)
   and the turn of its optical axis (2; the turn about the axis is free), as
   ``planning/straight_line.py``'s resolved rate; integrated on the commanded joints, the
   error measured on the real ones (so the servos' sag is taken out too), sent to the
   measured STS3215 servos (``stepping.move_to_pose``, linear over the cycle).

**Lost tag.** A frame without the tag keeps the last sighting; once it is older than
:data:`FOLLOW_POSE_AGE` the arm holds (no new command: the servos keep the last one) until
the tag is seen again, and the report counts the frames lost and held.

Scored from the simulator's truth (never read by the controller): where the tag's true
centre falls in the true camera's image, from the image's centre [px], and how far the
optical axis meets the table from the tag's centre [mm].
"""

from __future__ import annotations

import functools
import math
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from so101_kinematics.constants import HOME_POSE
from so101_kinematics.errors import VisionError
from so101_kinematics.fast_fk import forward_kinematics
from so101_kinematics.frames import ARM_JOINTS, JOINT_RANGES_RAD
from so101_kinematics.ik.geometry import PAN_AXIS_POINT, get_jacobian
from so101_kinematics.opencv_import import require_opencv
from so101_kinematics.sim import actuation, scene, stepping
from so101_kinematics.sim.pick_place import INITIAL_KEYFRAME
from so101_kinematics.sim.tag_textures import TAG_THICKNESS, TARGET_TAG, tag_geom_name
from so101_kinematics.sim.video import VideoRecorder
from so101_kinematics.vision.camera_model import get_camera_pose_base, project_points
from so101_kinematics.vision.detect import find_tag, flat_pose
from so101_kinematics.vision.sim_camera import WEBCAM, ImageEffects, SimCamera
from so101_kinematics.vision.tagged_scene import build_tagged_model, tagged_spec
from so101_kinematics.vision.tags import get_tag_pose_base

__all__ = [
    "DAMPING", "FOLLOW_CAMERA", "FOLLOW_POSE_AGE", "FOLLOW_RATE", "GAIN", "HEIGHT", "LOOK_TILT",
    "PATHS", "REACH_MARGIN", "SPEED_RANGE", "TagPath", "TagTracker", "camera_goal",
    "camera_in_tool", "camera_task", "follow", "follow_reach", "follower_model",
    "look_configuration", "out_of_reach", "resolved_rate_step",
]

FOLLOW_CAMERA = "wrist"
"""The camera the follower looks with (``model/so101.xml``, on the gripper)."""
FOLLOW_RATE = 30.0
"""[frames/s] The camera's rate, and the control loop's: one step per frame."""
HEIGHT = 0.15
"""[m] The camera's height above the tag it keeps (17 cm from it along the axis: the 40 mm
tag about 95 px wide at 640x480)."""
LOOK_TILT = 30.0
"""[deg] The optical axis's tilt from straight down, out along the arm's plane."""
GAIN = 6.0
"""[1/s] K, the error's feedback (a time constant of 5 frames)."""
DAMPING = 1e-3
"""lambda of the damped least squares (``straight_line.py``'s resolved rate's)."""
FOLLOW_POSE_AGE = 0.2
"""[s] The oldest sighting the arm moves on (6 frames); older: it holds."""
VELOCITY_SMOOTHING = 0.25
"""Weight of the newest sighting in the tag's smoothed velocity (exponential)."""
PATHS = ("circle", "line")
SPEED_RANGE = (0.0, 0.08)
"""[m/s] Speeds a tag may slide at (the lab's 2 to 5 cm/s, and some margin)."""
REACH_MARGIN = 0.01
"""[m] A tag is followed only this far inside the reach (:func:`follow_reach`): never on the
arm's stretched or folded edge, where a step turns the joints fast."""
HIDDEN_Z = -0.5
"""[m] Where a hidden tag goes: under the table, out of every camera's view."""
DOWN = np.array([0.0, 0.0, -1.0])


@dataclass(frozen=True)
class TagPath:
    """Where the tag is at each time: a circle or a back-and-forth line on the table.

    Attributes:
        kind: "circle" (counter-clockwise from ``centre + (radius, 0)``) or "line" (along y,
            from ``centre``, out to ``radius`` each side and back).
        centre: (x, y) [m] in the base frame.
        radius: the circle's radius or the line's half-length [m].
        speed: along the path [m/s].
        hide: (start, end) [s] when the tag is hidden (under the table), or None.
    """

    kind: str = "circle"
    centre: tuple[float, float] = (0.24, 0.0)
    radius: float = 0.04
    speed: float = 0.03
    hide: tuple[float, float] | None = None

    def position(self, t: float) -> np.ndarray:
        """The tag's centre (x, y) [m] at time ``t`` [s]."""
        s = self.speed * t
        c = np.asarray(self.centre, dtype=float)
        if self.kind == "circle":
            angle = s / self.radius
            return c + self.radius * np.array([math.cos(angle), math.sin(angle)])
        phase = (s / self.radius) % 4.0  # out, back, out the other side, back
        y = phase if phase < 1 else 2 - phase if phase < 3 else phase - 4
        return c + np.array([0.0, self.radius * y])

    def hidden(self, t: float) -> bool:
        """Whether the tag is hidden at ``t`` [s]."""
        return self.hide is not None and self.hide[0] <= t < self.hide[1]


def follower_model(path: TagPath) -> mujoco.MjModel:
    """The course's scene with the target tag on a mocap body (moved by :class:`TagPath`)."""
    spec = tagged_spec(target_at=(*path.centre, 0.0))
    spec.body(tag_geom_name(TARGET_TAG)).mocap = True
    return build_tagged_model(spec=spec)


def _pose(position, rotation) -> np.ndarray:
    g = np.eye(4)
    g[:3, :3], g[:3, 3] = rotation, position
    return g


def camera_in_tool(m: mujoco.MjModel, d: mujoco.MjData, camera: str = FOLLOW_CAMERA) -> np.ndarray:
    """``g_tc``: the camera (OpenCV axes) in the FK's object frame, the mount's (fixed) [m].

    From the model at ``d``'s configuration (any: the camera rides on the gripper), as a
    hand-eye calibration would give it on the real arm.
    """
    g_bt = _pose(*forward_kinematics(scene.get_configuration(m, d)))
    return np.linalg.inv(g_bt) @ get_camera_pose_base(m, d, camera)


def camera_task(cfg, g_tc: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The camera's position [m], optical axis and their (6, 5) Jacobian at ``cfg`` [deg].

    The course's Jacobian of the object frame (rows: linear, angular; world frame) moved
    to the camera: ``v_c = v_t + w x (p_c - p_t)``.
    """
    position, rotation = forward_kinematics(cfg)
    g_bc = _pose(position, rotation) @ g_tc
    jac = get_jacobian(cfg)
    r = g_bc[:3, 3] - position
    skew = np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])
    return g_bc[:3, 3], g_bc[:3, 2], np.vstack([jac[:3] - skew @ jac[3:], jac[3:]])


def resolved_rate_step(cfg, g_tc: np.ndarray, goal: tuple[np.ndarray, np.ndarray],
                       velocity: np.ndarray, error: np.ndarray | None = None,
                       dt: float = 1.0 / FOLLOW_RATE, gain: float = GAIN) -> dict[str, float]:
    """One resolved-rate step: the configuration [deg] after ``dt`` towards ``goal``.

    Args:
        cfg: the commanded configuration [deg] (the Jacobian's, and what is integrated).
        g_tc: the camera in the object frame (:func:`camera_in_tool`).
        goal: where the camera should be [m] and its optical axis there (:func:`camera_goal`).
        velocity: the goal's velocity [m/s], fed forward.
        error: the camera's position error [m] as measured (default: ``goal`` minus the
            commanded camera's position).
        dt: the cycle [s].
        gain: K [1/s].

    Returns:
        The new arm configuration [deg], clipped to the joints' ranges.
    """
    position, axis, jac = camera_task(cfg, g_tc)
    error = goal[0] - position if error is None else error
    # The axis's turn about the two directions across it (its turn about itself is free).
    across = np.linalg.svd(axis.reshape(1, 3))[2][1:]
    rows = np.vstack([jac[:3], across @ jac[3:]])
    wanted = np.concatenate([velocity + gain * error, across @ (gain * np.cross(axis, goal[1]))])
    dq = rows.T @ np.linalg.solve(rows @ rows.T + DAMPING**2 * np.eye(5), wanted)
    theta = np.radians([cfg[j] for j in ARM_JOINTS]) + dq * dt
    lower, upper = (np.array([JOINT_RANGES_RAD[j][k] for j in ARM_JOINTS]) for k in (0, 1))
    return dict(zip(ARM_JOINTS, np.degrees(np.clip(theta, lower, upper)).tolist(), strict=True))


def camera_goal(tag: np.ndarray, g_tc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where the camera sees ``tag`` [m] at its image's centre from :data:`HEIGHT` above.

    The gripper top-down (the course's grasp), its jaws across the arm's plane (wrist_roll
    near 0): the camera, tilted from the fingers by its mount (15 deg), then looks out along
    the arm's plane, and sits on the line through the tag along its optical axis.

    Returns:
        The camera's position [m] and its optical axis (a unit vector).
    """
    tilt = math.radians(LOOK_TILT)
    out = np.append(tag[:2] - np.asarray(PAN_AXIS_POINT[:2]), 0.0)
    out /= max(float(np.linalg.norm(out)), 1e-9)
    axis = math.cos(tilt) * DOWN + math.sin(tilt) * out
    return tag - axis * HEIGHT / math.cos(tilt), axis


def look_configuration(cfg, g_tc: np.ndarray, tag: np.ndarray,
                       cycles: int = 300) -> dict[str, float]:
    """The configuration [deg] that sees ``tag`` [m] as :func:`camera_goal` says.

    The resolved-rate step iterated from ``cfg`` turned top-down (on the jaws-across branch).

    Raises:
        VisionError: the camera cannot get there (the tag is out of the follower's reach).
    """
    cfg = dict(cfg, wrist_flex=90.0, wrist_roll=0.0)  # top-down, on the jaws-across branch
    goal = camera_goal(tag, g_tc)
    for _ in range(cycles):
        cfg.update(resolved_rate_step(cfg, g_tc, goal, np.zeros(3), dt=0.05, gain=8.0))
    position, axis, _ = camera_task(cfg, g_tc)
    if np.linalg.norm(position - goal[0]) > 1e-4 or axis @ goal[1] < math.cos(1e-3):
        raise VisionError(f"The wrist camera cannot see the tag at ({tag[0]:.3f}, {tag[1]:.3f}) "
                          f"m from {HEIGHT * 100:.0f} cm above. Fix: a tag path nearer the "
                          "middle of the reach, e.g. centre (0.24, 0).")
    return cfg


def _reaches(g_tc: np.ndarray, radius: float, height: float) -> bool:
    try:
        look_configuration(HOME_POSE, g_tc, np.array([PAN_AXIS_POINT[0] + radius, 0.0,
                                                         height]))
    except VisionError:
        return False
    return True


@functools.lru_cache(maxsize=8)
def _reach(mount: bytes, height: float) -> tuple[float, float]:
    g_tc = np.frombuffer(mount).reshape(4, 4)
    inner = (0.05, 0.24)  # [m] from the pan axis: out of reach, then in (bisected)
    outer = (0.24, 0.45)  # in reach, then out
    for _ in range(12):  # to 0.05 mm
        middle = sum(inner) / 2
        inner = (middle, inner[1]) if not _reaches(g_tc, middle, height) else (inner[0], middle)
        middle = sum(outer) / 2
        outer = (middle, outer[1]) if _reaches(g_tc, middle, height) else (outer[0], middle)
    return inner[1] + REACH_MARGIN, outer[0] - REACH_MARGIN


def follow_reach(g_tc: np.ndarray, height: float = TAG_THICKNESS) -> tuple[float, float]:
    """The tag's distance from the pan axis [m] the follower follows at: (nearest, farthest).

    Where :func:`look_configuration` gets the camera to its goal (bisected along the arm's
    plane; the goal turns with the pan, so every bearing alike), :data:`REACH_MARGIN` inside.

    Args:
        g_tc: the camera in the object frame (:func:`camera_in_tool`, or a calibration's).
        height: the tag's face above the base frame [m] (on the table by default).
    """
    return _reach(np.ascontiguousarray(g_tc, dtype=float).tobytes(), float(height))


def out_of_reach(tag: np.ndarray, g_tc: np.ndarray, height: float = TAG_THICKNESS) -> str | None:
    """Why the follower does not follow ``tag`` [m] (one line), or None when it does.

    ``height``: the tag's face above the base frame [m], the one its reach was found at.
    """
    near, far = follow_reach(g_tc, height)
    offset = np.asarray(tag[:2]) - np.asarray(PAN_AXIS_POINT[:2])
    radius = float(np.hypot(*offset))
    bearing = math.degrees(math.atan2(offset[1], offset[0]))
    pan = [math.degrees(v) for v in JOINT_RANGES_RAD["shoulder_pan"]]
    if near <= radius <= far and pan[0] <= bearing <= pan[1]:
        return None
    return (f"the tag at ({tag[0]:.3f}, {tag[1]:.3f}) m is {radius * 100:.1f} cm from the "
            f"shoulder_pan axis at {bearing:.0f} deg: the follower follows from {near * 100:.1f} "
            f"to {far * 100:.1f} cm, at {pan[0]:.0f} to {pan[1]:.0f} deg; the arm holds. Fix: "
            "move the tag nearer the middle of the reach, e.g. (0.24, 0) m.")


@dataclass
class TagTracker:
    """The last sighting and the tag's smoothed velocity (what the controller knows)."""

    position: np.ndarray | None = None
    stamp: float = -math.inf
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def update(self, position: np.ndarray, stamp: float) -> None:
        """A sighting: the tag at ``position`` [m] in an image taken at ``stamp`` [s]."""
        if self.position is not None and 0.0 < stamp - self.stamp <= FOLLOW_POSE_AGE:
            seen = (position - self.position) / (stamp - self.stamp)
            self.velocity = (1 - VELOCITY_SMOOTHING) * self.velocity + VELOCITY_SMOOTHING * seen
        else:
            self.velocity = np.zeros(3)
        self.position, self.stamp = position, stamp

    def age(self, now: float) -> float:
        """[s] How old the last sighting is at ``now``."""
        return now - self.stamp

    def predicted(self, now: float) -> np.ndarray:
        """[m] Where the tag is at ``now``: the last sighting moved on at the smoothed velocity."""
        return self.position + self.velocity * self.age(now)


def _truth(m, d, K) -> tuple[float, float]:
    """The tag's offset from the image's centre [px] and the axis's miss on the table [m]."""
    g_bc = get_camera_pose_base(m, d, FOLLOW_CAMERA)
    tag = get_tag_pose_base(m, d, tag_geom_name(TARGET_TAG))[:3, 3]
    pixel = project_points(K, g_bc, tag)[0]
    axis = g_bc[:3, 2]
    meet = g_bc[:3, 3] + axis * (tag[2] - g_bc[2, 3]) / axis[2]
    return float(np.hypot(*(pixel - K[:2, 2]))), float(np.linalg.norm(meet[:2] - tag[:2]))


def _stats(values) -> dict | None:
    if not values:
        return None
    return {"mean": round(float(np.mean(values)), 3), "worst": round(float(np.max(values)), 3)}


def _start(path: TagPath):
    """The scene, the arm settled over the tag's start, the camera's mount."""
    m = follower_model(path)
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key(INITIAL_KEYFRAME).id)
    body = m.body(tag_geom_name(TARGET_TAG)).mocapid[0]
    d.mocap_pos[body, :2] = path.position(0.0)
    mujoco.mj_forward(m, d)
    g_tc = camera_in_tool(m, d)
    rest = scene.get_configuration(m, d)
    tag = np.array([*path.position(0.0), TAG_THICKNESS])
    scene.set_initial_pose(d, dict(rest, **look_configuration(rest, g_tc, tag)))
    stepping.hold_position(m, d, None, 0.5)  # the servos settle (their sag)
    return m, d, body, g_tc


class _WristInset:
    """The video's inset: the wrist camera's last image, the tag outlined, the centre marked."""

    def __init__(self):
        self.image, self.corners = None, None

    def see(self, image: np.ndarray, sighting) -> None:
        self.image, self.corners = image, None if sighting is None else sighting.corners

    def __call__(self, frame: np.ndarray) -> np.ndarray:
        if self.image is None:
            return frame
        cv2 = require_opencv()
        view = np.ascontiguousarray(self.image)
        centre = (view.shape[1] // 2, view.shape[0] // 2)
        cv2.drawMarker(view, centre, (255, 0, 255), cv2.MARKER_CROSS, 60, 3)
        if self.corners is not None:
            cv2.polylines(view, [np.round(self.corners).astype(np.int32).reshape(-1, 1, 2)],
                          True, (255, 150, 0), 2, cv2.LINE_AA)
        else:
            cv2.putText(view, "tag lost", (10, 40), cv2.FONT_HERSHEY_SIMPLEX, 1.2,
                        (255, 40, 40), 2, cv2.LINE_AA)
        width = frame.shape[1] // 3
        height = round(width * view.shape[0] / view.shape[1])
        view = cv2.resize(view, (width, height), interpolation=cv2.INTER_AREA)
        frame = frame.copy()
        frame[:height + 4, :width + 4] = 255
        frame[2:2 + height, 2:2 + width] = view
        return frame


def follow(path: TagPath, duration: float, *, effects: ImageEffects | None = WEBCAM,
           video: str | Path | None = None) -> dict:
    """Follow the tag along ``path`` for ``duration`` [s] of simulated time; the report.

    Args:
        path: the tag's motion (and when it is hidden).
        duration: [s] of simulated time, one control cycle per camera frame.
        effects: the wrist camera's webcam effects (None: the images as rendered).
        video: an MP4 path: the run from the front, the wrist camera's view inset.

    Returns:
        The report (see ``docs/final_project.md``): ``tracking_error_px`` and
        ``tracking_error_mm`` (mean, worst), ``frames``, ``lost_frames``, ``held_frames``...
    """
    wall0 = time.perf_counter()
    m, d, body, g_tc = _start(path)
    inset = _WristInset()
    recorder = None if video is None else VideoRecorder(
        m, d, video, compose=inset, total_time=duration, progress=False)
    finished = False
    try:
        with SimCamera(m, d, FOLLOW_CAMERA, effects=effects) as camera:
            log = _loop(m, d, body, g_tc, camera, path, duration, recorder, inset)
        finished = True
    finally:
        if recorder is not None:
            recorder.close(complete=finished)
    return {
        "tracking_error_px": _stats(log["px"]), "tracking_error_mm": _stats(log["mm"]),
        "frames": log["frames"], "lost_frames": log["lost"], "hidden_frames": log["hidden"],
        "held_frames": log["held"], "first_held_s": log["first_held"],
        "held_command_change_deg": log["held_change"],
        "max_pose_age_s": FOLLOW_POSE_AGE, "path": asdict(path), "duration_s": duration,
        "height_m": HEIGHT, "look_tilt_deg": LOOK_TILT, "frame_rate": FOLLOW_RATE,
        "gain_per_s": GAIN, "damping": DAMPING, "camera": FOLLOW_CAMERA,
        "servo": actuation.servo_spec(m).describe(),
        "webcam_effects": None if effects is None else asdict(effects),
        "wall_time_s": round(time.perf_counter() - wall0, 2),
    }


def _loop(m, d, body, g_tc, camera, path: TagPath, duration: float, viewer, inset) -> dict:
    """The control loop: see, want, step (or hold), one camera frame at a time; the log."""
    tracker, t0, K = TagTracker(), d.time, camera.intrinsics()
    log = {"px": [], "mm": [], "lost": 0, "hidden": 0, "held": 0, "frames": 0,
           "first_held": None, "held_change": 0.0}
    held_at = None
    for frame in range(int(round(duration * FOLLOW_RATE))):
        t = d.time - t0
        dt = t0 + (frame + 1) / FOLLOW_RATE - d.time  # to the next frame (whole physics steps)
        hidden = path.hidden(t)
        d.mocap_pos[body] = [*path.position(t), HIDDEN_Z if hidden else 0.0]
        mujoco.mj_forward(m, d)
        g_bc = _pose(*forward_kinematics(scene.get_configuration(m, d))) @ g_tc  # measured
        image = camera.read()
        seen = find_tag(image, K, TARGET_TAG)
        if seen is not None:
            tracker.update(flat_pose(seen, K, g_bc, TAG_THICKNESS)[:3, 3], d.time)
        inset.see(image, seen)
        log["frames"] += 1
        log["hidden"] += hidden
        log["lost"] += seen is None
        if not hidden:
            px, miss = _truth(m, d, K)
            log["px"].append(px)
            log["mm"].append(1000 * miss)
        command = scene.get_command(m, d)
        if tracker.age(d.time) > FOLLOW_POSE_AGE:  # lost: hold, no motion on an old pose
            log["held"] += 1
            if log["first_held"] is None:
                log["first_held"] = round(t, 3)
            held_at = held_at or command  # the command when this hold began
            log["held_change"] = max(log["held_change"], max(
                abs(command[j] - held_at[j]) for j in ARM_JOINTS))
            stepping.hold_position(m, d, viewer, dt)
            continue
        held_at = None
        goal = camera_goal(tracker.predicted(d.time), g_tc)
        cfg = resolved_rate_step(command, g_tc, goal, tracker.velocity,
                                 error=goal[0] - g_bc[:3, 3], dt=dt)
        stepping.move_to_pose(m, d, viewer, dict(command, **cfg), dt, profile="linear")
    return log

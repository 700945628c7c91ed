"""The tag follower on an arm through lerobot: the wrist camera keeps the tag centred, on the bus.

The hardware half of ``follow_tag.py --port PORT --camera ADDRESS``, the simulator's follower
(``vision/tag_follower.py``) on ``hw/run.py``'s ``run_on_arm``:

1. **look**: the arm goes from where it stands to look at :data:`LOOK_AT` (the simulator's
   tag path's centre) from the follower's height, a plan step checked as every plan is;
2. **follow** (``run_on_arm``'s closed loop, ``then``), for ``seconds``: each new frame of the
   wrist camera (lerobot's camera class, ``vision/webcam.py``'s ``open_camera``) through the
   one detection path; the target tag laid on the table (``detect.flat_pose``) through the
   camera's pose from the FK of the joints read from the servos and its mount on the gripper
   (the model's, exact for the virtual arm, or a hand-eye calibration's); the goal from the
   tag's predicted position (``camera_goal``) and one resolved-rate step of the course's
   Jacobian (``resolved_rate_step``), sent by ``ArmSession.move``: the calibrated range, the
   table's clearance (``clearance.check_path``) and the speed cap, as every move;
3. **hold, never release**: a sighting older than ``FOLLOW_POSE_AGE``, a tag out of the
   follower's reach (``out_of_reach``) or a goal the guards refuse: the arm keeps its last
   goal (``ArmSession.hold``, still reading and checking every cycle);
4. **the end**: after ``seconds`` the plan's return to the starting pose and the torque
   released there; a stop signal, a stale camera or a fault end as every run does
   (``hw/run.py``'s fault policy), and ``hw/run.ending`` says how from the servos' read-back.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping, Sequence
from typing import Any

import mujoco
import numpy as np

from so101_kinematics.constants import HOME_POSE
from so101_kinematics.errors import ClearanceError, JointLimitError, StopRequested
from so101_kinematics.fast_fk import forward_kinematics
from so101_kinematics.frames import ARM_JOINTS
from so101_kinematics.hw.run import MotionAborted, RunResult, run_on_arm
from so101_kinematics.lab.see_and_pick_arm import tag_height
from so101_kinematics.planning.motion import Plan, Step
from so101_kinematics.planning.plans import GRIPPER_CLOSED
from so101_kinematics.sim.cube import build_model
from so101_kinematics.sim.tag_textures import TARGET_TAG
from so101_kinematics.vision.calibration_views import gripper_pose
from so101_kinematics.vision.camera_model import camera_intrinsics
from so101_kinematics.vision.detect import find_tag, flat_pose
from so101_kinematics.vision.tag_follower import (
    FOLLOW_CAMERA,
    FOLLOW_POSE_AGE,
    FOLLOW_RATE,
    TagPath,
    TagTracker,
    camera_goal,
    camera_in_tool,
    follow_reach,
    look_configuration,
    out_of_reach,
    resolved_rate_step,
)
from so101_kinematics.vision.webcam import (
    load_calibration,
    load_camera_in_gripper,
    open_camera,
)

__all__ = ["LOOK_MOVE_S", "FOLLOW_STEP", "LOOK_AT", "follow_on_arm", "look_plan", "wrist_view"]

logger = logging.getLogger(__name__)

LOOK_AT = TagPath().centre
"""(x, y) [m] where the arm first looks for the tag: the simulator's tag path's centre."""
LOOK_MOVE_S = 3.0
"""[s] The move to the look pose and the return from it (the speed cap may stretch them)."""
FOLLOW_STEP = "follow"
"""The cycles' step name while following (and holding) in the run's log."""
MAX_STEP_S = 0.1
"""[s] The longest cycle a resolved-rate step integrates (a slow frame is not a big jump)."""


def _pose(position, rotation) -> np.ndarray:
    g = np.eye(4)
    g[:3, :3], g[:3, 3] = rotation, position
    return g


def wrist_view(size: Sequence[int] = (640, 480), camera_calibration=None
               ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """``(K, dist, g_tc)``: the wrist camera's matrix, distortion and pose in the object frame.

    With ``camera_calibration`` (``calibrate_camera.py --photos DIR --mount wrist``'s report)
    the real camera's, its pose in the gripper frame carried to the FK's object frame (a fixed
    transform: taken at the home pose); without, the model's (exact for the virtual arm).

    Raises:
        VisionError: a report that is not calibrate_camera.py's, without the wrist camera's
            pose, or for another size (one line).
    """
    if camera_calibration is not None:
        K, dist = load_calibration(camera_calibration, *size)
        g_gc = load_camera_in_gripper(camera_calibration)
        home = {j: HOME_POSE[j] for j in ARM_JOINTS}
        g_tc = np.linalg.inv(_pose(*forward_kinematics(home))) @ gripper_pose(
            [home[j] for j in ARM_JOINTS]) @ g_gc
        return K, dist, g_tc
    m = build_model(render_meshes=True)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    return camera_intrinsics(m, FOLLOW_CAMERA, *size), None, camera_in_tool(m, d)


def look_plan(g_tc: np.ndarray, height: float) -> Plan:
    """To the pose that sees :data:`LOOK_AT` at the image's centre, then back at the end."""
    cfg = look_configuration(HOME_POSE, g_tc, np.array([*LOOK_AT, height]))
    return Plan([Step("look", {**cfg, "gripper": GRIPPER_CLOSED}, LOOK_MOVE_S, 0.5)],
                return_to_start=True, return_duration=LOOK_MOVE_S)


class _Follower:
    """The closed loop ``run_on_arm`` runs after the look step (the module's doc, 2 and 3)."""

    def __init__(self, camera, K, dist, g_tc, seconds: float, tag=TARGET_TAG):
        self.camera, self.K, self.dist, self.g_tc = camera, K, dist, g_tc
        self.seconds, self.tag, self.height = seconds, tag, tag_height(tag)
        self.refusing = False
        self.log = {"frames": 0, "seen_frames": 0, "held_frames": 0, "refused_frames": 0,
                    "stretched_frames": 0, "offset_px": [], "miss_mm": [], "refused": None}

    def _see(self, session, tracker: TagTracker, stamp: float | None) -> float:
        """A new frame; the tag's sighting (if any) given to ``tracker``; its stamp [s]."""
        image, stamp = self.camera.read_stamped(newer_than=stamp)
        measured = session.read_pose()
        g_bc = _pose(*forward_kinematics({j: measured[j] for j in ARM_JOINTS})) @ self.g_tc
        seen = find_tag(image, self.K, self.tag, self.dist)
        self.log["frames"] += 1
        if seen is not None:
            tag = flat_pose(seen, self.K, g_bc, self.height, self.dist)[:3, 3]
            tracker.update(tag, stamp)
            axis = g_bc[:3, 2]
            meet = g_bc[:3, 3] + axis * (tag[2] - g_bc[2, 3]) / axis[2]
            centre = np.asarray(seen.corners, dtype=float).reshape(-1, 2).mean(axis=0)
            self.log["seen_frames"] += 1
            self.log["offset_px"].append(float(np.hypot(*(centre - self.K[:2, 2]))))
            self.log["miss_mm"].append(1000.0 * float(np.linalg.norm(meet[:2] - tag[:2])))
        return stamp

    def _refuse(self, session, why: str) -> None:
        if not self.refusing:  # once a refusal begins
            logger.warning("Not following: %s", why)
        self.refusing = True
        self.log["refused"] = why
        self.log["refused_frames"] += 1
        session.hold(1.0 / FOLLOW_RATE, step=FOLLOW_STEP)

    def __call__(self, session) -> None:
        tracker, stamp, clock = TagTracker(), None, time.perf_counter
        end = last = clock()
        end += self.seconds
        while clock() < end:
            if session.stop_reason is not None:
                raise StopRequested(session.stop_reason)
            stamp = self._see(session, tracker, stamp)
            now = clock()
            dt, last = min(now - last, MAX_STEP_S), now
            if tracker.age(now) > FOLLOW_POSE_AGE:  # lost: hold, no motion on an old pose
                self.log["held_frames"] += 1
                session.hold(1.0 / FOLLOW_RATE, step=FOLLOW_STEP)
                continue
            tag = tracker.predicted(now)
            why = out_of_reach(tag, self.g_tc, self.height)
            if why is not None:
                self._refuse(session, why)
                continue
            goal = camera_goal(tag, self.g_tc)
            g_bc = _pose(*forward_kinematics({j: session.command[j] for j in ARM_JOINTS}))
            cfg = resolved_rate_step(session.command, self.g_tc, goal, tracker.velocity,
                                     error=goal[0] - (g_bc @ self.g_tc)[:3, 3], dt=dt)
            try:
                move = session.move({**session.command, **cfg}, 1.0 / FOLLOW_RATE,
                                    step=FOLLOW_STEP, max_speed=session.max_speed,
                                    profile="linear")
            except (JointLimitError, ClearanceError) as error:  # refused before anything sent
                self._refuse(session, str(error))
                continue
            self.refusing = False
            self.log["stretched_frames"] += move.duration > move.requested + 1e-9


def _stats(values) -> dict | None:
    if not values:
        return None
    return {"mean": round(float(np.mean(values)), 3), "worst": round(float(np.max(values)), 3)}


def follow_on_arm(port: str, address: str, calibration: Mapping[str, Any], seconds: float, *,
                  size: Sequence[int] = (640, 480), camera_calibration=None,
                  **run_options) -> tuple[dict, RunResult]:
    """Follow the target tag with the arm at ``port`` for ``seconds`` [s]; the report, the run.

    Args:
        port: the arm's serial port.
        address: the wrist camera (``open_camera``'s: a virtual arm's stream, a device).
        calibration: the arm's lerobot calibration (``calibration.load_calibration``).
        seconds: [s] how long to follow, after the look step.
        size: the camera's frames (width, height) [px].
        camera_calibration: calibrate_camera.py's ``--mount wrist`` report (None: the model's).
        **run_options: ``run_on_arm``'s options (``confirm``, ``trims``, ...).

    Returns:
        The report (``frames``, ``seen_frames``, ``held_frames``, ``refused_frames``, the
        camera's own following figures ``offset_px`` and ``miss_mm``, mean and worst, ``aborted``)
        and ``run_on_arm``'s result (its ``ending`` is the run's last line).

    Raises:
        VisionError: a bad camera calibration, no camera at ``address`` (nothing moved).
    """
    K, dist, g_tc = wrist_view(size, camera_calibration)
    height = tag_height(TARGET_TAG)
    near, far = follow_reach(g_tc, height)
    plan = look_plan(g_tc, height)
    with open_camera(address, *size, max_age=max(0.5, 2 * FOLLOW_POSE_AGE)) as camera:
        follower = _Follower(camera, K, dist, g_tc, seconds)
        try:
            result = run_on_arm(port, calibration, plan, then=follower, **run_options)
        except MotionAborted as error:
            result = error.result
    log = follower.log
    report = {key: log[key] for key in ("frames", "seen_frames", "held_frames",
                                        "refused_frames", "stretched_frames")}
    report.update(offset_px=_stats(log["offset_px"]), miss_mm=_stats(log["miss_mm"]),
                  refused=log["refused"], aborted=result.aborted, seconds=seconds,
                  reach_m=[round(near, 4), round(far, 4)], look_at_m=list(LOOK_AT),
                  frame_rate=round(log["frames"] / seconds, 1),
                  max_pose_age_s=FOLLOW_POSE_AGE, tag=TARGET_TAG.name)
    return report, result

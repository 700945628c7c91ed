"""The simulated pick-and-place, run and judged: the plan on the scene, where the cube went.

:func:`run_pick_place` runs a plan headless, in the viewer or into a video,
watching the cube; :class:`RunReport` says whether it was picked, carried and
placed within tolerance.
"""

from __future__ import annotations

import logging
import math
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from so101_kinematics import display
from so101_kinematics.errors import PlanError, RenderSettingError, ViewerClosed
from so101_kinematics.fast_fk import forward_kinematics as get_forward_kinematics
from so101_kinematics.frames import ARM_JOINTS, TOOL_SITE
from so101_kinematics.inputs import check_number
from so101_kinematics.paths import REPO
from so101_kinematics.planning import straight_line
from so101_kinematics.planning.motion import Plan, Step, run_plan
from so101_kinematics.planning.plans import default_plan, pick_and_place_steps, validate_plan
from so101_kinematics.sim import actuation, scene, stepping
from so101_kinematics.sim.cube import (
    CubeMonitor,
    CubeStart,
    build_model,
    check_cube_start,
    scene_limits,
    scene_model,
)
from so101_kinematics.sim.render import (
    DEFAULT_CAMERA,
    DEFAULT_FPS,
    DEFAULT_SIZE,
    QUALITY,
    add_overlays,
    check_fps,
    check_frame_size,
    target_cubes,
)
from so101_kinematics.sim.video import VideoRecorder

__all__ = [
    "DEFAULT_VIDEO", "INITIAL_KEYFRAME", "MIN_LIFT", "PLACEMENT_TOLERANCE", "RunReport",
    "TILT_TOLERANCE", "TIMESTEP_RANGE", "_report", "choose_mode", "execute_plan", "run_pick_place",
    "total_duration",
]

DEFAULT_VIDEO = REPO / "out" / "pick_place.mp4"
INITIAL_KEYFRAME = "home"  # the arm's initial pose, returned to at the end

# What counts as a successful pick-and-place.
PLACEMENT_TOLERANCE = 0.010  # [m] horizontal distance from the FK final position
TILT_TOLERANCE = 10.0  # [deg] angle of the cube's up axis from the vertical
MIN_LIFT = 0.020  # [m] the cube must rise at least this much to count as carried

# Ranges of the command line's numbers (the --help text shows them).
TIMESTEP_RANGE = (0.0, 0.01)  # [s] run_pick_place's timestep, lower end excluded

log = logging.getLogger("pick_place_sim")


@dataclass
class RunReport:
    """Outcome of a run; the JSON report has these keys.

    Positions in the world (base) frame [m]; cube fields are ``None`` without a cube.
    """

    cube_final_position_m: list[float] | None
    cube_target_position_m: list[float] | None
    placement_error_m: float | None
    tilt_deg: float | None
    dropped: bool | None
    max_lift_m: float | None
    sim_time_s: float
    wall_time_s: float
    realtime_factor: float
    frames_written: int
    success: bool
    completed: bool = True
    waypoint_errors_deg: dict[str, float] = field(default_factory=dict)
    video: str | None = None
    servo: str = ""
    straight_path_deviation_mm: dict[str, float] = field(default_factory=dict)

    def summary(self) -> str:
        """Human-readable lines for stdout."""
        factor = f"{self.realtime_factor:.0f}" if self.realtime_factor >= 10 else \
            f"{self.realtime_factor:.2f}"
        lines = [f"Simulated {self.sim_time_s:.2f} s in {self.wall_time_s:.2f} s wall time "
                 f"({factor}x real time)"]
        if self.servo:
            lines.append(f"Servo: {self.servo}")
        if self.video:
            lines[0] += f"; {self.frames_written} frames written to {self.video}"
        if not self.completed:
            lines.append("The viewer was closed before the end: partial run.")
        if self.cube_final_position_m is None:
            lines.append("No cube (--no-cube).")
            return "\n".join(lines)
        final, target = self.cube_final_position_m, self.cube_target_position_m
        lines += [
            f"Cube final position:  ({final[0]:.4f}, {final[1]:.4f}, {final[2]:.4f}) m",
            f"Cube target (FK):     ({target[0]:.4f}, {target[1]:.4f}, {target[2]:.4f}) m",
            f"Placement error:      {self.placement_error_m * 1000:.1f} mm "
            f"(tolerance {PLACEMENT_TOLERANCE * 1000:.0f} mm)",
            f"Tilt:                 {self.tilt_deg:.1f} deg (tolerance {TILT_TOLERANCE:.0f} deg)",
            f"Max lift:             {self.max_lift_m * 1000:.0f} mm; dropped: "
            f"{'yes' if self.dropped else 'no'}",
        ]
        if self.success:
            lines.append("Result: SUCCESS - the cube was picked by friction, carried and placed.")
        else:
            reasons = []
            if self.max_lift_m < MIN_LIFT:
                reasons.append(f"it was never lifted {MIN_LIFT * 1000:.0f} mm (grasp failed)")
            if self.dropped:
                reasons.append("it fell out of the gripper")
            if self.placement_error_m > PLACEMENT_TOLERANCE:
                reasons.append("it ended too far from the target")
            if self.tilt_deg > TILT_TOLERANCE:
                reasons.append("it ended tilted")
            lines.append("Result: FAILED - " + "; ".join(reasons or ["incomplete run"]) + ".")
        if self.straight_path_deviation_mm:
            lines.append(straight_line.describe(self.straight_path_deviation_mm, "measured"))
        return "\n".join(lines)


def total_duration(plan: Plan) -> float:
    """Simulated duration of a plan [s], including the return to the initial pose."""
    return sum(s.duration + s.hold for s in plan.steps) + (plan.return_duration
                                                           if plan.return_to_start else 0.0)


def run_pick_place(
    plan: Plan | None = None,
    *,
    cube: CubeStart | None = CubeStart(),  # noqa: B008 - immutable use
    mode: str = "headless",
    video: str | Path | None = None,
    fps: float = DEFAULT_FPS,
    size: Sequence[int] = DEFAULT_SIZE,
    camera: str = DEFAULT_CAMERA,
    quality: str = "fast",
    progress: bool = True,
    timestep: float | None = None,
    show_ui: bool = False,
    base_height: float = 0.0,
    servo: dict | None = None,
) -> RunReport:
    """Run a pick-and-place plan in simulation and measure what happened to the cube.

    Args:
        plan: the plan (default: ``so101_kinematics.planning.plans.default_plan()``); validated
            against the joint limits before anything moves.
        cube: where the free cube starts, or ``None`` for no cube.
        mode: "headless" (as fast as possible), "viewer" (interactive, real
            time) or "record" (offscreen, to ``video``).
        video: MP4 path for mode "record".
        fps: video frames per second of simulated time.
        size: video (width, height) [px].
        camera: camera name for the video.
        quality: a ``so101_kinematics.sim.render.QUALITY`` preset name.
        progress: progress bar while recording.
        timestep: physics step [s] instead of the model's 4 ms (to check
            that a result does not depend on it).
        show_ui: mode "viewer": show MuJoCo's side panels from the start.
        base_height: the table is this far below the base frame [m] (the cube
            rests on it).
        servo: keywords of ``so101_kinematics.sim.actuation.use_servo`` (default:
            the measured STS3215 at lerobot's settings, 5 V, gravity feed-forward).

    Returns:
        The run report.

    Raises:
        so101_kinematics.planning.motion.PlanError: the plan is invalid (nothing moved).
        so101_kinematics.sim.render.RenderError: the video cannot be written as asked.
    """
    if mode not in ("headless", "viewer", "record"):
        raise PlanError(f"mode must be 'headless', 'viewer' or 'record', got {mode!r}.")
    if quality not in QUALITY:
        raise RenderSettingError(f"Unknown quality {quality!r}; choose one of "
                                 f"{', '.join(QUALITY)}.")
    if timestep is not None:
        timestep = check_number(timestep, "timestep", *TIMESTEP_RANGE, "s", low_open=True)
    plan = validate_plan(plan or default_plan(), scene_limits(), base_height=base_height)
    if cube is not None:
        check_cube_start(plan, cube)
    if mode == "record":
        check_fps(fps, 1.0 / (timestep or scene_model().opt.timestep))
        check_frame_size(size, "Video size")
    # Visual meshes have no mass and no contact: the physics is bit for bit the
    # same with the render-only meshes, which compile 4x faster and draw 3x
    # faster, and without any (headless). Only the interactive viewer shows
    # the upstream meshes.
    light = mode == "record" and QUALITY[quality].light_meshes
    m = build_model(plan, cube, render_meshes=light, physics_only=mode == "headless",
                    base_height=base_height, servo=servo)
    if timestep is not None:
        m.opt.timestep = timestep
    pick, place = pick_and_place_steps(plan)
    return execute_plan(
        m, plan, lambda run: _report(m, run.d, plan, run.monitor, run.wall, run.frames,
                                     run.completed, run.errors, run.video, run.positions),
        mode=mode, video=video, fps=fps, size=size, camera=camera, quality=quality,
        progress=progress, show_ui=show_ui,
        overlays=target_cubes(pick.configuration, place.configuration))


@dataclass
class Execution:
    """A plan run on a scene, as the report needs it (see :func:`execute_plan`)."""

    d: mujoco.MjData
    monitor: CubeMonitor
    wall: float  # [s] wall time of the plan
    frames: int  # video frames written
    completed: bool  # False: the viewer was closed before the end
    errors: dict[str, float]  # step name -> largest joint error when it ended [deg]
    video: str | None  # the video written, in mode "record"
    positions: list = field(default_factory=list)  # (step, object frame [m]) at each step's end


def execute_plan(m: mujoco.MjModel, plan: Plan, report: Callable[[Execution], object], *,
                 mode: str, video, fps: float, size, camera: str, quality: str, progress: bool,
                 show_ui: bool, overlays=()):
    """Run a checked plan on the model ``m`` from its initial keyframe; return ``report(run)``.

    The one run loop of the pick-and-place and the stacking: headless, in the
    viewer (which then keeps holding the pose until it is closed; the report is
    taken before) or into a video (renamed over its target only when complete).

    Args:
        m: the scene (its cubes are watched by a :class:`CubeMonitor` on "cube").
        plan: the validated plan.
        report: makes the report from the finished run.
        mode: "headless", "viewer" or "record".
        video: MP4 path for mode "record".
        fps: video frames per second of simulated time.
        size: video (width, height) [px].
        camera: camera name for the video.
        quality: a ``so101_kinematics.sim.render.QUALITY`` preset name.
        progress: progress bar while recording.
        show_ui: mode "viewer": show MuJoCo's side panels from the start.
        overlays: translucent target cubes drawn into the video or viewer.
    """
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key(INITIAL_KEYFRAME).id)
    mujoco.mj_forward(m, d)
    initial = scene.get_configuration(m, d)
    overlays = list(overlays)

    errors: dict[str, float] = {}
    positions: list[tuple[str, list[float]]] = []
    current: list[Step] = []

    def note_reached(step: Step | None) -> None:
        # Called when a step ends: how far the arm is from that step's target.
        if current:
            done = current.pop()
            positions.append((done.name, d.site(TOOL_SITE).xpos.tolist()))
            if not straight_line.is_path_sample(done.name):  # a line's samples: its deviation
                measured = scene.get_configuration(m, d)
                errors[done.name] = max(abs(measured[j] - done.configuration[j])
                                        for j in ARM_JOINTS)
        if step is not None:
            current.append(step)

    inner, frames, completed, finished = None, 0, True, False
    wall0 = time.perf_counter()
    try:
        if mode == "record":
            inner = VideoRecorder(m, d, video or DEFAULT_VIDEO, fps=fps, size=size, camera=camera,
                                  overlays=overlays, quality=QUALITY[quality],
                                  total_time=total_duration(plan), progress=progress)
        elif mode == "viewer":
            inner = display.launch_viewer(m, d, show_ui=show_ui)
            with inner.lock():
                inner.user_scn.ngeom = 0
                add_overlays(inner.user_scn, overlays)
        monitor = CubeMonitor(m, d, inner)
        try:
            run_plan(plan,
                     lambda cfg, duration: stepping.move_to_pose(m, d, monitor, cfg, duration,
                                                                 raise_if_closed=True),
                     lambda duration: stepping.hold_position(m, d, monitor, duration,
                                                             raise_if_closed=True), initial,
                     on_step=note_reached)
            note_reached(None)
        except ViewerClosed:
            completed = False
        if mode == "record":
            frames = inner.frames_written
        wall = time.perf_counter() - wall0
        if monitor.has_cube:
            monitor.check()
        result = report(Execution(d, monitor, wall, frames, completed, errors,
                                  str(video or DEFAULT_VIDEO) if mode == "record" else None,
                                  positions))
        if mode == "viewer" and completed:
            print("Done: close the viewer window to see the report.", file=sys.stderr)
            try:
                while True:  # the arm keeps holding its pose, in real time
                    stepping.hold_position(m, d, monitor, 0.1, raise_if_closed=True)
            except ViewerClosed:
                pass
        finished = True
    finally:
        if mode == "viewer" and inner is not None:
            display.close_viewer(inner)  # and wait for its render thread: no crash at exit
        elif isinstance(inner, VideoRecorder):
            inner.close(complete=finished)  # renamed over the target only when complete
        elif inner is not None:
            inner.close()
    return result


def _report(m, d, plan, monitor, wall, frames, completed, errors, video,
            positions=()) -> RunReport:
    """Assemble the run report from the final state."""
    cube_keys = dict.fromkeys(("cube_final_position_m", "cube_target_position_m",
                               "placement_error_m", "tilt_deg", "dropped", "max_lift_m"))
    success = completed
    if monitor.has_cube:
        _, place = pick_and_place_steps(plan)
        target, _ = get_forward_kinematics({j: place.configuration[j] for j in ARM_JOINTS})
        final = d.body("cube").xpos.copy()
        up = d.body("cube").xmat.reshape(3, 3)[:, 2]
        error = float(np.linalg.norm(final[:2] - target[:2]))
        tilt = math.degrees(math.acos(min(1.0, max(-1.0, float(up[2])))))
        cube_keys = dict(cube_final_position_m=[float(v) for v in final],
                         cube_target_position_m=[float(v) for v in target],
                         placement_error_m=error, tilt_deg=tilt, dropped=monitor.dropped,
                         max_lift_m=monitor.max_lift)
        success = (completed and not monitor.dropped and monitor.max_lift >= MIN_LIFT
                   and error <= PLACEMENT_TOLERANCE and tilt <= TILT_TOLERANCE)
    spec = actuation.servo_spec(m)
    return RunReport(**cube_keys, sim_time_s=float(d.time), wall_time_s=wall,
                     realtime_factor=float(d.time) / wall if wall > 0 else float("inf"),
                     frames_written=frames, success=success, completed=completed,
                     waypoint_errors_deg=errors, video=video,
                     servo=spec.describe() if spec else "",
                     straight_path_deviation_mm=straight_line.path_deviations(plan, positions))


def choose_mode(headless: bool, record: Path | None, display: bool) -> tuple[str, Path | None]:
    """The run mode from the options and the display (see ``--help``).

    Returns:
        (mode, video path or None): "record" if a video is asked for, or if
        nothing is asked and there is no display (then to ``DEFAULT_VIDEO``);
        "headless" with ``--headless``; else "viewer".
    """
    if record is not None:
        return "record", record
    if headless:
        return "headless", None
    if display:
        return "viewer", None
    return "record", DEFAULT_VIDEO


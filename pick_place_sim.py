"""Run the course's pick-and-place on the simulated SO-101: viewer, headless or MP4 video."""

from __future__ import annotations

import so101_kinematics.display as so101_display  # first: EGL when there is no display

# isort: split
import argparse
import functools
import json
import logging
import math
import sys
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import mujoco
import numpy as np

import so101_mujoco_utils as utils
from so101_forward_kinematics import (
    ARM_JOINTS,
    TOOL_SITE,
    KinematicsInputError,
    get_forward_kinematics,
)
from so101_inverse_kinematics import get_inverse_kinematics
from so101_kinematics.cartesian_plan import (
    CUBE_YAW_RANGE,
    add_cartesian_arguments,
    plan_from_arguments,
)
from so101_kinematics.cli import (
    EXIT_BAD_INPUT,
    EXIT_INTERRUPTED,
    ArgumentParser,
    number,
    range_help,
    report_unexpected,
)
from so101_kinematics.motion import MAX_DURATION, Plan, PlanError, Step, check_number, run_plan
from so101_kinematics.outputs import OutputPathError, check_output_path, write_text_atomic
from so101_kinematics.plans import default_plan, load_plan, pick_and_place_steps, validate_plan
from so101_kinematics.sim.contact_pairs import use_explicit_contact_pairs
from so101_kinematics.sim.meshes import ensure_meshes
from so101_kinematics.sim.render import (
    DEFAULT_CAMERA,
    DEFAULT_FPS,
    DEFAULT_SIZE,
    FRAME_EDGE_RANGE,
    MIN_FPS,
    QUALITY,
    RenderError,
    RenderSettingError,
    VideoRecorder,
    add_overlays,
    check_fps,
    check_frame_size,
    max_fps,
    target_cubes,
    use_render_meshes,
)

_HERE = Path(__file__).resolve().parent
DEFAULT_VIDEO = _HERE / "out" / "pick_place.mp4"
INITIAL_KEYFRAME = "home"  # the arm's initial pose, returned to at the end

# The free cube: a 26 mm hardwood cube (17.6 cm^3 at ~0.7 g/cm^3 = 12 g).
# Sliding friction 0.5 is wood on wood or on PLA; where it touches a jaw pad,
# the pad's own contact parameters apply (model/so101.xml, class jaw_pad).
CUBE_EDGE = 0.026  # [m]
CUBE_MASS = 0.012  # [kg]
CUBE_FRICTION = (0.5, 0.005, 0.0001)  # sliding [-], torsional [m], rolling [m]
CUBE_RGBA = (0.25, 0.45, 0.85, 1.0)

# What counts as a successful pick-and-place.
PLACEMENT_TOLERANCE = 0.010  # [m] horizontal distance from the FK final position
TILT_TOLERANCE = 10.0  # [deg] angle of the cube's up axis from the vertical
MIN_LIFT = 0.020  # [m] the cube must rise at least this much to count as carried
HELD_DISTANCE = 0.015  # [m] cube centre this close to the object frame = in the grip
# A cube whose centre is this high above its start and not in the grip is
# falling (a cube tipping over on the table rises at most 5.4 mm).
AIRBORNE_HEIGHT = 0.010  # [m]
MONITOR_PERIOD = 0.01  # [s] of simulation time between checks of the cube

# Ranges of the command line's numbers (the --help text shows them).
CUBE_OFFSET_RANGE_MM = (-100.0, 100.0)  # [mm] each of --cube-offset DX DY: a perturbation
TIMESTEP_RANGE = (0.0, 0.01)  # [s] run_pick_place's timestep, lower end excluded

log = logging.getLogger("pick_place_sim")


@dataclass
class CubeStart:
    """Where the free cube starts: the pick position's FK, plus a perturbation.

    Attributes:
        offset: horizontal displacement (x, y) in the world frame [m].
        yaw: extra rotation about the vertical [deg].
    """

    offset: tuple[float, float] = (0.0, 0.0)
    yaw: float = 0.0

    def pose(self, pick: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
        """Cube centre [m] and quaternion (w, x, y, z) for the pick configuration ``pick``.

        The cube stands on the table, turned about z as the FK object frame
        (so its faces are parallel to the jaws), then by ``yaw``.
        """
        position, rotation = get_forward_kinematics({j: pick[j] for j in ARM_JOINTS})
        centre = np.array([position[0] + self.offset[0], position[1] + self.offset[1],
                           0.5 * CUBE_EDGE])
        angle = math.atan2(rotation[1, 0], rotation[0, 0]) + math.radians(self.yaw)
        return centre, np.array([math.cos(angle / 2), 0.0, 0.0, math.sin(angle / 2)])


def build_model(plan: Plan | None = None, cube: CubeStart | None = None,
                render_meshes: bool = False, physics_only: bool = False,
                explicit_pairs: bool = True) -> mujoco.MjModel:
    """Compile the course scene, optionally with a free cube at the plan's pick position.

    Args:
        plan: gives the pick configuration (default: the built-in plan).
        cube: the cube's start; ``None`` for no cube.
        render_meshes: use the decimated render-only meshes (for a model that
            is only drawn; see ``so101_render.use_render_meshes``).
        physics_only: leave out the visual geoms and their meshes (for a run
            that is never drawn). They have no mass and no contact, so the
            physics is bit for bit the same; each step skips their poses.
        explicit_pairs: list the geom pairs that can touch instead of finding
            them every step (``so101_contact_pairs``; the same contacts, 6 %
            less work per step).

    Returns:
        The model. Sleeping is enabled: a cube at rest on the table costs no
        contact computation until the arm touches it.
    """
    ensure_meshes()
    spec = mujoco.MjSpec.from_file(str(utils.SCENE_PATH))
    if physics_only:
        _remove_visuals(spec)
    elif render_meshes:
        use_render_meshes(spec)
    if cube is not None:
        pick, _ = pick_and_place_steps(plan or default_plan())
        centre, quat = cube.pose(pick.configuration)
        body = spec.worldbody.add_body(name="cube", pos=centre, quat=quat)
        body.add_freejoint(name="cube")
        body.add_geom(name="cube", type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.5 * CUBE_EDGE] * 3,
                      mass=CUBE_MASS, friction=list(CUBE_FRICTION), condim=3, rgba=list(CUBE_RGBA))
        spec.option.enableflags |= mujoco.mjtEnableBit.mjENBL_SLEEP
    if explicit_pairs:
        use_explicit_contact_pairs(spec)
    return spec.compile()


def _remove_visuals(spec: mujoco.MjSpec) -> None:
    """Delete the arm's visual geoms (class "visual": no contact, no mass) and the meshes."""
    for geom in list(spec.geoms):
        massless = geom.density == 0 and not geom.mass > 0  # mass is NaN when not given
        if (geom.type == mujoco.mjtGeom.mjGEOM_MESH and geom.contype == 0
                and geom.conaffinity == 0 and massless):
            spec.delete(geom)
    for mesh in list(spec.meshes):
        spec.delete(mesh)


@functools.lru_cache(maxsize=1)
def _scene_model() -> mujoco.MjModel:
    """The scene without cube and visual meshes (for its limits, table and timestep)."""
    return build_model(physics_only=True)


def scene_limits() -> dict[str, tuple[float, float]]:
    """Joint limits of the scene's arm in user units ([deg], gripper [0, 100])."""
    return utils.joint_limits(_scene_model())


def table_extent() -> tuple[tuple[float, float], tuple[float, float]]:
    """The table top's x and y ranges [m] in the world (the scene's geom "table")."""
    m = _scene_model()
    centre, half = m.geom("table").pos, m.geom("table").size
    return ((float(centre[0] - half[0]), float(centre[0] + half[0])),
            (float(centre[1] - half[1]), float(centre[1] + half[1])))


def check_cube_start(plan: Plan, cube: CubeStart) -> np.ndarray:
    """Refuse a cube start that is off the table or out of the arm's reach, before the run.

    Args:
        plan: the plan (its pick step gives the nominal position).
        cube: the perturbation.

    Returns:
        The cube's start centre [m].

    Raises:
        so101_motion.PlanError: naming the position, the table or the reach, and the fix.
    """
    for axis, value in zip("xy", cube.offset, strict=True):
        check_number(value, f"cube offset {axis}", CUBE_OFFSET_RANGE_MM[0] / 1000.0,
                      CUBE_OFFSET_RANGE_MM[1] / 1000.0, "m")
    check_number(cube.yaw, "cube turn", *CUBE_YAW_RANGE, "deg")
    pick, _ = pick_and_place_steps(plan)
    centre, _ = cube.pose(pick.configuration)
    (x_low, x_high), (y_low, y_high) = table_extent()
    half = 0.5 * CUBE_EDGE
    where = (f"The cube would start at ({centre[0]:.3f}, {centre[1]:.3f}) m (waypoint "
             f"'{pick.name}' plus the offset ({cube.offset[0] * 1e3:g}, "
             f"{cube.offset[1] * 1e3:g}) mm)")
    if not (x_low + half <= centre[0] <= x_high - half and y_low + half <= centre[1] <= y_high
            - half):
        raise PlanError(f"{where}: off the table, which spans x in [{x_low:g}, {x_high:g}] m "
                        f"and y in [{y_low:g}, {y_high:g}] m. Fix: a smaller --cube-offset, or "
                        "a pick position on the table.")
    try:
        get_inverse_kinematics(centre, approach=None)
    except PlanError as error:
        reason = str(error).split(" Fix:")[0]
        raise PlanError(f"{where}: out of the arm's reach ({reason}). Fix: a smaller "
                        "--cube-offset, or a pick position the arm reaches.") from None
    return centre


class CubeMonitor:
    """Watches the cube during the run; a viewer wrapper for move_to_pose.

    It forwards ``sync()`` / ``is_running()`` to an inner viewer (passive
    viewer or video recorder) if there is one and takes its pacing flags.

    Args:
        m: the model (with a body "cube", or without: then it only forwards).
        d: the data.
        inner: the viewer to forward to, or ``None`` (headless).
    """

    def __init__(self, m: mujoco.MjModel, d: mujoco.MjData, inner=None):
        self.d, self.inner = d, inner
        self.offscreen = inner is None or getattr(inner, "offscreen", False)
        self.sync_every_step = inner is not None and getattr(inner, "sync_every_step", False)
        cube = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "cube")
        self.has_cube = cube >= 0
        self._next = d.time
        if self.has_cube:
            # Views into d (rows of its arrays): they follow the simulation.
            self._cube = d.xpos[cube]
            self._site = d.site_xpos[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, TOOL_SITE)]
            self.start_height = float(self._cube[2])
        self.max_lift = 0.0  # [m]
        self.dropped = False

    def is_running(self) -> bool:
        """The inner viewer's state (always true headless)."""
        return self.inner is None or self.inner.is_running()

    def sync(self) -> None:
        """Check the cube (every MONITOR_PERIOD [s]), then forward."""
        if self.has_cube and self.d.time >= self._next - 1e-9:
            self._next = self.d.time + MONITOR_PERIOD
            self.check()
        if self.inner is not None:
            self.inner.sync()

    def check(self) -> None:
        """Update the lift height and note a drop: the cube in the air, out of the grip."""
        lift = float(self._cube[2]) - self.start_height
        self.max_lift = max(self.max_lift, lift)
        if lift > AIRBORNE_HEIGHT and math.dist(self._cube, self._site) > HELD_DISTANCE:
            self.dropped = True


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

    def summary(self) -> str:
        """Human-readable lines for stdout."""
        factor = f"{self.realtime_factor:.0f}" if self.realtime_factor >= 10 else \
            f"{self.realtime_factor:.2f}"
        lines = [f"Simulated {self.sim_time_s:.2f} s in {self.wall_time_s:.2f} s wall time "
                 f"({factor}x real time)"]
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
) -> RunReport:
    """Run a pick-and-place plan in simulation and measure what happened to the cube.

    Args:
        plan: the plan (default: ``so101_motion.default_plan()``); validated
            against the joint limits before anything moves.
        cube: where the free cube starts, or ``None`` for no cube.
        mode: "headless" (as fast as possible), "viewer" (interactive, real
            time) or "record" (offscreen, to ``video``).
        video: MP4 path for mode "record".
        fps: video frames per second of simulated time.
        size: video (width, height) [px].
        camera: camera name for the video.
        quality: a ``so101_render.QUALITY`` preset name.
        progress: progress bar while recording.
        timestep: physics step [s] instead of the model's 4 ms (to check
            that a result does not depend on it).
        show_ui: mode "viewer": show MuJoCo's side panels from the start.

    Returns:
        The run report.

    Raises:
        so101_motion.PlanError: the plan is invalid (nothing moved).
        so101_render.RenderError: the video cannot be written as asked.
    """
    if mode not in ("headless", "viewer", "record"):
        raise PlanError(f"mode must be 'headless', 'viewer' or 'record', got {mode!r}.")
    if quality not in QUALITY:
        raise RenderSettingError(f"Unknown quality {quality!r}; choose one of "
                                 f"{', '.join(QUALITY)}.")
    if timestep is not None:
        timestep = check_number(timestep, "timestep", *TIMESTEP_RANGE, "s", low_open=True)
    plan = validate_plan(plan or default_plan(), scene_limits())
    if cube is not None:
        check_cube_start(plan, cube)
    if mode == "record":
        check_fps(fps, 1.0 / (timestep or _scene_model().opt.timestep))
        check_frame_size(size, "Video size")
    # Visual meshes have no mass and no contact: the physics is bit for bit the
    # same with the render-only meshes, which compile 4x faster and draw 3x
    # faster, and without any (headless). Only the interactive viewer shows
    # the upstream meshes.
    light = mode == "record" and QUALITY[quality].light_meshes
    m = build_model(plan, cube, render_meshes=light, physics_only=mode == "headless")
    if timestep is not None:
        m.opt.timestep = timestep
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key(INITIAL_KEYFRAME).id)
    mujoco.mj_forward(m, d)
    initial = utils.get_configuration(m, d)
    pick, place = pick_and_place_steps(plan)
    overlays = target_cubes(pick.configuration, place.configuration)

    errors: dict[str, float] = {}
    current: list[Step] = []

    def note_reached(step: Step | None) -> None:
        # Called when a step ends: how far the arm is from that step's target.
        if current:
            done = current.pop()
            measured = utils.get_configuration(m, d)
            errors[done.name] = max(abs(measured[j] - done.configuration[j]) for j in ARM_JOINTS)
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
            inner = so101_display.launch_viewer(m, d, show_ui=show_ui)
            with inner.lock():
                inner.user_scn.ngeom = 0
                add_overlays(inner.user_scn, overlays)
        monitor = CubeMonitor(m, d, inner)
        try:
            run_plan(plan, lambda cfg, duration: utils.move_to_pose(m, d, monitor, cfg, duration),
                     lambda duration: utils.hold_position(m, d, monitor, duration), initial,
                     on_step=note_reached)
            note_reached(None)
        except utils.ViewerClosed:
            completed = False
        if mode == "record":
            frames = inner.frames_written
        wall = time.perf_counter() - wall0
        if monitor.has_cube:
            monitor.check()
        report = _report(m, d, plan, monitor, wall, frames, completed, errors,
                         str(video or DEFAULT_VIDEO) if mode == "record" else None)
        if mode == "viewer" and completed:
            print("Done: close the viewer window to see the report.", file=sys.stderr)
            try:
                while True:  # the arm keeps holding its pose, in real time
                    utils.hold_position(m, d, monitor, 0.1)
            except utils.ViewerClosed:
                pass
        finished = True
    finally:
        if mode == "viewer" and inner is not None:
            so101_display.close_viewer(inner)  # and wait for its render thread: no crash at exit
        elif isinstance(inner, VideoRecorder):
            inner.close(complete=finished)  # renamed over the target only when complete
        elif inner is not None:
            inner.close()
    return report


def _report(m, d, plan, monitor, wall, frames, completed, errors, video) -> RunReport:
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
    return RunReport(**cube_keys, sim_time_s=float(d.time), wall_time_s=wall,
                     realtime_factor=float(d.time) / wall if wall > 0 else float("inf"),
                     frames_written=frames, success=success, completed=completed,
                     waypoint_errors_deg=errors, video=video)


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


def _size(text: str) -> tuple[int, int]:
    low, high = FRAME_EDGE_RANGE
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a size; give WIDTHxHEIGHT in px, each even and in "
            f"[{low}, {high}]. Fix: e.g. --size 640x480.") from None
    try:
        return check_frame_size((width, height), "size")
    except RenderSettingError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def main(argv: Sequence[str] | None = None) -> int:
    """Parse the command line, run, print the summary; returns the exit code."""
    duration = (0.0, MAX_DURATION, "s")
    parser = ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=f"""Modes:
  with a display, no options   interactive viewer, paced to real time
  without a display (DISPLAY / WAYLAND_DISPLAY unset), no options
                               headless, and the video is recorded to
                               {DEFAULT_VIDEO.relative_to(_HERE)} (as ./dev.sh sim does)
  --headless                   no viewer, as fast as possible; no video
                               unless --record is given
  --record PATH.mp4            offscreen video (any machine; MUJOCO_GL=egl)

Output files (--record, --json) are checked before the run and written beside
the target, then renamed over it when complete: an interrupted run (Ctrl-C)
leaves an existing file as it was.

Exit code: 0 done (even if the grasp failed, unless --strict), 1 the cube was
not placed (with --strict) or an unexpected error (rerun with -v for the
traceback), 2 bad input (plan file, options), 130 interrupted.""")
    parser.add_argument("--plan", type=Path, help="waypoint file (.json or .toml, UTF-8) "
                        "replacing the built-in plan; see waypoints/")
    parser.add_argument("--headless", action="store_true", help="no viewer (default when there "
                        "is no display)")
    parser.add_argument("--record", type=Path, metavar="PATH.mp4", help="record a video")
    parser.add_argument("--ui", action="store_true", help="viewer: show MuJoCo's side panels "
                        "(Tab / Shift+Tab toggle them)")
    parser.add_argument("--fps", type=number(MIN_FPS, math.inf, "frames/s"), default=DEFAULT_FPS,
                        help=f"video frame rate [frames/s], from {MIN_FPS:g} up to one frame per "
                        "physics step (1 / timestep) (default %(default)g)")
    parser.add_argument("--size", type=_size, default=DEFAULT_SIZE, metavar="WxH",
                        help="video size [px], each edge even and in "
                        f"[{FRAME_EDGE_RANGE[0]}, {FRAME_EDGE_RANGE[1]}] (default 640x480)")
    parser.add_argument("--camera", default=DEFAULT_CAMERA, help="camera (default %(default)s)")
    parser.add_argument("--quality", choices=sorted(QUALITY), default="fast",
                        help="video quality preset (default %(default)s)")
    parser.add_argument("--cube", action=argparse.BooleanOptionalAction, default=True,
                        help="put a free 26 mm cube at the pick position (default on)")
    parser.add_argument("--cube-offset", type=number(*CUBE_OFFSET_RANGE_MM, "mm"), nargs=2,
                        default=(0.0, 0.0), metavar=("DX", "DY"),
                        help="displace the cube's start [mm], world x, y, each "
                        f"{range_help(*CUBE_OFFSET_RANGE_MM, 'mm')}; it must stay on the table "
                        "and within reach")
    parser.add_argument("--cube-turn", type=number(*CUBE_YAW_RANGE, "deg"), default=0.0,
                        metavar="DEG",
                        help="turn the cube's start about z [deg] away from where the plan "
                        f"expects it, {range_help(*CUBE_YAW_RANGE, 'deg')} (a perturbation; for "
                        "--pick/--place see --cube-yaw)")
    parser.add_argument("--move-duration", type=number(*duration), default=2.0,
                        help="built-in plan: seconds per main move, "
                        f"{range_help(*duration)} (default %(default)g)")
    parser.add_argument("--hold", type=number(*duration), default=0.5,
                        help="built-in plan: seconds held at each course configuration, "
                        f"{range_help(*duration)} (default %(default)g)")
    add_cartesian_arguments(parser)
    parser.add_argument("--json", type=Path, metavar="PATH", help="write the run report as JSON")
    parser.add_argument("--strict", action="store_true", help="exit 1 unless the cube is placed "
                        "within tolerance")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("-v", "--verbose", action="store_true", help="log details (and show "
                        "the traceback of an unexpected error)")
    try:
        args = parser.parse_args(argv)
    except SystemExit as stop:  # bad options (one line printed) or --help: the exit code
        return stop.code
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    try:
        return _run(parser, args)
    except KeyboardInterrupt:
        print("Interrupted (Ctrl-C): nothing was written; existing output files are as they "
              "were.", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as error:
        return report_unexpected(error, args.verbose)


def _run(parser: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    """Check the outputs and the plan, run, report (see :func:`main`)."""
    mode, video = choose_mode(args.headless, args.record, so101_display.has_display())
    try:
        json_path = None
        check_fps(args.fps, max_fps(_scene_model()), "--fps")
        if mode == "record":
            video = check_output_path(video, "--record", inputs=[args.plan], suffixes=(".mp4",))
        if args.json is not None:
            json_path = check_output_path(args.json, "--json", inputs=[args.plan])
            if video is not None and json_path == video:
                raise OutputPathError(f"--json {args.json}: is the --record file too. Fix: "
                                      "give the report its own name, e.g. report.json.")
        if mode == "record" and args.record is None:
            print(f"No display: running headless and recording {video}", file=sys.stderr)
        plan = plan_from_arguments(args)
        if plan is None:
            if args.cube_yaw is not None:
                raise PlanError("--cube-yaw sets the cube's yaw for a Cartesian plan: give "
                                "--pick and --place too (--cube-turn perturbs any plan's cube).")
            plan = load_plan(args.plan, scene_limits()) if args.plan else default_plan(
                args.move_duration, args.hold)
        cube = CubeStart((args.cube_offset[0] / 1000.0, args.cube_offset[1] / 1000.0),
                         args.cube_turn) if args.cube else None
        report = run_pick_place(plan, cube=cube, mode=mode, video=video, fps=args.fps,
                                size=args.size, camera=args.camera, quality=args.quality,
                                progress=not args.no_progress, show_ui=args.ui)
    except (PlanError, RenderError, OutputPathError, KinematicsInputError) as error:
        print(f"error: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT
    print(report.summary())
    if json_path is not None:
        write_text_atomic(json_path, json.dumps(asdict(report), indent=2) + "\n")
    if args.strict and not report.success:
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())

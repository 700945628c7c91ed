"""Assignment 7's IK test, done properly: reachable targets, the cube shown, the arm measured.

The course's test sends the simulated arm to random top-down grasps of a cube
lying on the table, showing each target as a translucent cube. This module
owns what ``test_ik_mujoco.py`` needs around that loop:

- :func:`random_targets`: targets drawn from the top-down workspace at the
  course's height (``TARGET_HEIGHT``): positions of random in-limit top-down
  grasps (``so101_inverse_kinematics.sample_top_down_targets``) within
  ``SAMPLE_SLAB`` of that height, moved onto it, yaw in [0, 90) deg (a
  cube's yaw repeats every 90 deg), each kept only if the IK solves it;
  :func:`check_target` for a target the user gives;
- :func:`show_cube`: the course's helper, for MuJoCo's passive viewer (its
  ``user_scn``), the video recorder (drawn into every frame) or ``None``;
- :func:`measure_target`: where the object frame (site ``object_frame``)
  ended, against the target itself: position error [mm] and yaw error [deg]
  modulo 90 (the tool frame's x axis against the cube's; the z axis's sign
  is not compared);
- :func:`open_scene`: the model, its data and the viewer for a mode
  ("viewer", "headless", "record"), closed properly however the run ends.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from so101_kinematics import display
from so101_kinematics.constants import CUBE_HALF_SIZE
from so101_kinematics.errors import KinematicsInputError, PlanError, UnreachableError
from so101_kinematics.frames import TOOL_SITE, Rz, check_angle
from so101_kinematics.ik.call_shapes import get_inverse_kinematics
from so101_kinematics.ik.solver import sample_top_down_targets
from so101_kinematics.sim import actuation
from so101_kinematics.sim.cube import build_model
from so101_kinematics.sim.render import (
    DEFAULT_CAMERA,
    DEFAULT_FPS,
    DEFAULT_SIZE,
    QUALITY,
    START_RGBA,
    Overlay,
    add_overlays,
)
from so101_kinematics.sim.video import VideoRecorder

__all__ = [
    "CUBE_SYMMETRY", "DemoReport", "POSITION_TOLERANCE", "SERVO_POSITION_TOLERANCE",
    "SERVO_YAW_TOLERANCE", "TARGET_HEIGHT", "Target", "YAW_TOLERANCE", "check_target",
    "measure_target", "open_scene", "random_targets", "show_cube", "tolerances",
    "yaw_difference",
]

TARGET_HEIGHT = 0.014  # [m] the course's targets: a cube's centre on the table, 1 mm clearance
CUBE_SYMMETRY = 90.0  # [deg] a cube looks the same turned by this about the vertical
POSITION_TOLERANCE = 0.002  # [m] object frame to target: "reached" (an ideal servo)
YAW_TOLERANCE = 1.0  # [deg] tool x axis to the cube's, modulo CUBE_SYMMETRY: "reached"
# The STS3215 at P = 16 with the gravity feed-forward rests anywhere in its friction band:
# +-0.5 deg a joint on 5 V (BAM's Coulomb 0.052 N m over 5.9 N m/rad), less what the
# feed-forward takes out: up to 5.3 mm and 1.4 deg at the object frame over 50 random
# targets (2026-12-02). What the arm you get reaches; a wrong IK branch, a dropped link
# offset (18 mm) or a wrong yaw still misses by more.
SERVO_POSITION_TOLERANCE = 0.007  # [m]
SERVO_YAW_TOLERANCE = 2.0  # [deg]


def tolerances(m: mujoco.MjModel) -> tuple[float, float]:
    """What "reached" means on ``m``'s servo: (position [m], yaw [deg])."""
    spec = actuation.servo_spec(m)
    if spec is None or spec.mode == "ideal":
        return POSITION_TOLERANCE, YAW_TOLERANCE
    return SERVO_POSITION_TOLERANCE, SERVO_YAW_TOLERANCE
TARGET_RGBA = START_RGBA  # translucent red, as the course draws its target cube
SAMPLE_SLAB = 0.002  # [m] sampled top-down grasps kept within this of TARGET_HEIGHT
SAMPLE_BATCH = 4000  # random configurations drawn per batch (about 9 % land in the slab)
MAX_BATCHES = 50


@dataclass(frozen=True)
class Target:
    """A top-down grasp of a cube on the table.

    Attributes:
        position: the cube's centre (x, y, z) [m] in the base frame.
        yaw_deg: the cube's turn about the vertical [deg].
    """

    position: tuple[float, float, float]
    yaw_deg: float

    @property
    def rotation(self) -> np.ndarray:
        """The cube's orientation in the world: Rz(yaw) (3, 3)."""
        return Rz(self.yaw_deg)


def yaw_difference(a_deg: float, b_deg: float) -> float:
    """Smallest difference [deg] between two cube yaws, modulo ``CUBE_SYMMETRY``, in [-45, 45).

    Example:
        >>> yaw_difference(89.0, 1.0), yaw_difference(10.0, 190.5)
        (-2.0, -0.5)
    """
    half = CUBE_SYMMETRY / 2.0
    return (a_deg - b_deg + half) % CUBE_SYMMETRY - half


def check_target(x: float, y: float, yaw_deg: float, name: str = "target") -> Target:
    """A target at the course's height, refused before anything runs if the IK cannot reach it.

    Raises:
        UnreachableError: one line: ``name``, the target, why and by how much, the fix.
        KinematicsInputError: a coordinate or yaw that is not a finite number in range.
    """
    try:
        # The course's call, as the run makes it: the position and the cube's Rz(yaw).
        get_inverse_kinematics((x, y, TARGET_HEIGHT), Rz(check_angle(yaw_deg, "yaw_deg")))
    except UnreachableError as error:
        raise UnreachableError(f"{name} ({x:g}, {y:g}) m, yaw {yaw_deg:g} deg: {error}",
                               error.reason, error.distance, error.joint) from None
    except KinematicsInputError as error:
        raise type(error)(f"{name}: {error}") from None
    return Target((float(x), float(y), TARGET_HEIGHT), float(yaw_deg))


def random_targets(n: int, seed: int = 0) -> list[Target]:
    """``n`` reachable top-down targets at ``TARGET_HEIGHT``, the same for the same seed.

    Args:
        n: how many, >= 1.
        seed: random seed.

    Returns:
        The targets, in the order drawn; yaws in [0, ``CUBE_SYMMETRY``) deg.

    Raises:
        PlanError: fewer than ``n`` found in ``MAX_BATCHES`` batches (not seen in practice).
    """
    rng = np.random.default_rng(seed)
    targets: list[Target] = []
    for _ in range(MAX_BATCHES):
        _, positions, yaws = sample_top_down_targets(SAMPLE_BATCH, seed=int(rng.integers(2**32)),
                                                     min_height=TARGET_HEIGHT - SAMPLE_SLAB)
        near = np.abs(positions[:, 2] - TARGET_HEIGHT) <= SAMPLE_SLAB
        for (x, y, _), yaw in zip(positions[near], yaws[near], strict=True):
            try:
                targets.append(check_target(round(float(x), 4), round(float(y), 4),
                                            round(float(yaw) % CUBE_SYMMETRY, 1)))
            except UnreachableError:  # reachable 2 mm higher or lower, not at the height
                continue
            if len(targets) == n:
                return targets
    raise PlanError(f"only {len(targets)} of {n} reachable targets found. Fix: ask for fewer.")


def show_cube(viewer, position, orientation, halfwidth: float = CUBE_HALF_SIZE,
              rgba: Sequence[float] = TARGET_RGBA) -> None:
    """Show the target cube (and only it): the course's helper, for any kind of viewer.

    Args:
        viewer: MuJoCo's passive viewer (drawn in its ``user_scn``), a
            :class:`VideoRecorder` (drawn into the frames from now on) or
            ``None`` (headless: nothing to draw).
        position: the cube's centre [m].
        orientation: its rotation (3, 3).
        halfwidth: half its edge [m].
        rgba: colour and opacity, each in [0, 1].
    """
    cube = Overlay(np.asarray(position, dtype=float), np.asarray(orientation, dtype=float),
                   halfwidth, tuple(rgba))
    if isinstance(viewer, VideoRecorder):
        viewer.set_overlays([cube])
    elif viewer is not None:
        with viewer.lock():
            viewer.user_scn.ngeom = 0
            add_overlays(viewer.user_scn, [cube])
        viewer.sync()


@dataclass
class TargetResult:
    """How close the object frame came to one target, after the move and the hold."""

    target_position_m: list[float]
    target_yaw_deg: float
    final_position_m: list[float]
    final_yaw_deg: float
    position_error_mm: float
    yaw_error_deg: float  # modulo CUBE_SYMMETRY
    reached: bool


def measure_target(m: mujoco.MjModel, d: mujoco.MjData, target: Target,
                   position_tolerance: float | None = None,
                   yaw_tolerance: float | None = None) -> TargetResult:
    """Compare the simulated object frame (site ``object_frame``) with ``target`` itself.

    The tolerances default to what the model's servo can reach (:func:`tolerances`).
    """
    default_position, default_yaw = tolerances(m)
    position_tolerance = default_position if position_tolerance is None else position_tolerance
    yaw_tolerance = default_yaw if yaw_tolerance is None else yaw_tolerance
    site = d.site(TOOL_SITE)
    position, rotation = site.xpos.copy(), site.xmat.reshape(3, 3)
    yaw = math.degrees(math.atan2(rotation[1, 0], rotation[0, 0]))  # the tool x axis's heading
    error = float(np.linalg.norm(position - np.asarray(target.position)))
    yaw_error = yaw_difference(yaw, target.yaw_deg)
    return TargetResult([float(v) for v in target.position], target.yaw_deg,
                        [float(v) for v in position], yaw, error * 1e3, yaw_error,
                        error <= position_tolerance and abs(yaw_error) <= yaw_tolerance)


@dataclass
class DemoReport:
    """The run: each target's result, the tolerances, the times, the video."""

    results: list[TargetResult] = field(default_factory=list)
    targets_asked: int = 0
    seed: int | None = None
    position_tolerance_mm: float = POSITION_TOLERANCE * 1e3
    yaw_tolerance_deg: float = YAW_TOLERANCE
    sim_time_s: float = 0.0
    wall_time_s: float = 0.0
    video: str | None = None
    frames_written: int = 0
    servo: str = ""

    @property
    def success(self) -> bool:
        """Every target asked for was run and reached."""
        return len(self.results) == self.targets_asked and all(r.reached for r in self.results)

    def misses(self) -> list[str]:
        """One line per target missed: which, by how much."""
        return [f"target {i} at ({r.target_position_m[0]:.4f}, {r.target_position_m[1]:.4f}, "
                f"{r.target_position_m[2]:.4f}) m, yaw {r.target_yaw_deg:.1f} deg: missed by "
                f"{r.position_error_mm:.2f} mm (tolerance {self.position_tolerance_mm:g}) and "
                f"{abs(r.yaw_error_deg):.2f} deg of yaw (tolerance {self.yaw_tolerance_deg:g})"
                for i, r in enumerate(self.results, 1) if not r.reached]

    def summary(self) -> str:
        """The lines a user reads: each target, then the verdict."""
        lines = [f"target {i}: ({r.target_position_m[0]:+.4f}, {r.target_position_m[1]:+.4f}, "
                 f"{r.target_position_m[2]:.4f}) m, yaw {r.target_yaw_deg:5.1f} deg -> off by "
                 f"{r.position_error_mm:.2f} mm, {r.yaw_error_deg:+.2f} deg"
                 f"{'' if r.reached else '  MISSED'}" for i, r in enumerate(self.results, 1)]
        worst = max((r.position_error_mm for r in self.results), default=0.0)
        worst_yaw = max((abs(r.yaw_error_deg) for r in self.results), default=0.0)
        reached = sum(r.reached for r in self.results)
        lines.append(f"{reached} of {self.targets_asked} targets reached within "
                     f"{self.position_tolerance_mm:g} mm and {self.yaw_tolerance_deg:g} deg "
                     f"(worst {worst:.2f} mm, {worst_yaw:.2f} deg); {self.sim_time_s:.1f} s "
                     f"simulated in {self.wall_time_s:.1f} s"
                     + (f"; video {self.video} ({self.frames_written} frames)" if self.video
                        else ""))
        if self.servo:
            lines.append(f"Servo: {self.servo}")
        return "\n".join(lines)

    def as_json(self) -> dict:
        """The report as plain data (``--json``)."""
        return dict(asdict(self), success=self.success)


@contextlib.contextmanager
def open_scene(mode: str, video: str | Path | None = None, *, fps: float = DEFAULT_FPS,
               size: Sequence[int] = DEFAULT_SIZE, camera: str = DEFAULT_CAMERA,
               quality: str = "fast", total_time: float | None = None, progress: bool = True,
               show_ui: bool = False,
               servo: dict | None = None) -> Iterator[tuple[mujoco.MjModel, mujoco.MjData, object]]:
    """The course scene and a viewer for ``mode``; the viewer is closed however the block ends.

    Args:
        mode: "viewer" (MuJoCo's passive viewer), "headless" (``viewer`` is
            ``None``) or "record" (a :class:`VideoRecorder` to ``video``,
            renamed over it only if the block ends without an exception).
        video: the MP4 path for "record".
        fps: video frame rate [frames/s].
        size: video (width, height) [px].
        camera: the video's camera.
        quality: a ``QUALITY`` preset name for the video.
        total_time: the run's expected simulated time [s] (the progress bar).
        progress: show a progress bar while recording.
        show_ui: "viewer": MuJoCo's side panels.
        servo: keywords of ``actuation.use_servo`` (default: its defaults).

    Yields:
        ``(m, d, viewer)``.
    """
    if mode not in ("viewer", "headless", "record"):
        raise PlanError(f"mode must be 'viewer', 'headless' or 'record', got {mode!r}.")
    # Visual geoms have no mass and no contact: the physics is the same with
    # the light render meshes (video) or none at all (headless).
    m = build_model(render_meshes=mode == "record" and QUALITY[quality].light_meshes,
                    physics_only=mode == "headless", servo=servo)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    if mode == "headless":
        yield m, d, None
        return
    if mode == "viewer":
        viewer = display.launch_viewer(m, d, show_ui=show_ui)
        try:
            yield m, d, viewer
        finally:
            display.close_viewer(viewer)  # and wait for its render thread: no crash at exit
        return
    recorder = VideoRecorder(m, d, video, fps=fps, size=size, camera=camera,
                             quality=QUALITY[quality], total_time=total_time, progress=progress)
    finished = False
    try:
        yield m, d, recorder
        finished = True
    finally:
        recorder.close(complete=finished)


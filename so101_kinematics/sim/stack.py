"""Stacking in simulation: the stacking plan on a scene with N free cubes, and how the stack stands.

:func:`run_stack` builds the scene with one free cube per block at its start
(the same cube as the pick-and-place's: friction alone holds it, no weld),
runs ``so101_kinematics.planning.stacking``'s plan through the pick-and-place's run
loop, and reports each block's final pose (:class:`StackReport`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from so101_kinematics.constants import CUBE_SIZE
from so101_kinematics.errors import PlanError, RenderSettingError
from so101_kinematics.planning.plans import validate_plan
from so101_kinematics.planning.stack_report import (
    STACK_TILT_TOLERANCE,
    STACK_TOLERANCE,
    measure_stack,
)
from so101_kinematics.planning.stacking import StackPlan
from so101_kinematics.sim.cube import build_model, cube_names, scene_limits, scene_model
from so101_kinematics.sim.pick_place import execute_plan
from so101_kinematics.sim.render import (
    DEFAULT_CAMERA,
    DEFAULT_FPS,
    DEFAULT_SIZE,
    FINAL_RGBA,
    QUALITY,
    check_fps,
    check_frame_size,
)
from so101_kinematics.sim.render import Overlay as _Overlay

__all__ = ["run_stack", "stack_report"]


@dataclass
class StackReport:
    """Outcome of a stacking run; the JSON report has these keys (positions [m], angles [deg])."""

    blocks_final_position_m: list[list[float]]
    blocks_target_position_m: list[list[float]]
    blocks_tilt_deg: list[float]
    blocks_offset_m: list[float]  # horizontal: the bottom block from the target, each other
    # block from the one below it
    lean_deg: float  # the line from the bottom block's centre to the top one's, from vertical
    base_height_m: float
    sim_time_s: float
    wall_time_s: float
    frames_written: int
    success: bool
    completed: bool = True
    waypoint_errors_deg: dict[str, float] = field(default_factory=dict)
    video: str | None = None

    def summary(self) -> str:
        """Human-readable lines for stdout."""
        lines = [f"Simulated {self.sim_time_s:.2f} s in {self.wall_time_s:.2f} s wall time"]
        if self.video:
            lines[0] += f"; {self.frames_written} frames written to {self.video}"
        if not self.completed:
            lines.append("The viewer was closed before the end: partial run.")
        for i, (final, target, tilt, offset) in enumerate(zip(
                self.blocks_final_position_m, self.blocks_target_position_m,
                self.blocks_tilt_deg, self.blocks_offset_m, strict=True)):
            below = "the stack's spot" if i == 0 else f"block {i}"
            lines.append(f"Block {i + 1}: ({final[0]:.4f}, {final[1]:.4f}, {final[2]:.4f}) m, "
                         f"target z {target[2]:.4f} m; {offset * 1e3:.1f} mm from {below}, "
                         f"tilt {tilt:.1f} deg")
        lines.append(f"Stack lean: {self.lean_deg:.1f} deg (bottom to top centre from vertical)")
        lines.append("Result: SUCCESS - the blocks stand stacked." if self.success else
                     f"Result: FAILED - a block is more than {STACK_TOLERANCE * 1e3:.0f} mm off "
                     f"its place or tilted beyond {STACK_TILT_TOLERANCE:.0f} deg.")
        return "\n".join(lines)


def stack_report(positions: Sequence[Sequence[float]], rotations: Sequence[np.ndarray],
                 stack: StackPlan) -> dict:
    """Offsets, tilts, lean and success of blocks at ``positions`` turned by ``rotations``.

    Args:
        positions: each block's centre [m], bottom block first.
        rotations: each block's 3x3 orientation in the world. Its tilt is the
            angle from the vertical to the nearest face normal: a cube is
            square, whichever face it stands on.
        stack: the plan's blocks and targets.

    Returns:
        The geometric keys of :class:`StackReport`.
    """
    tilts = [math.degrees(math.acos(min(1.0, float(np.max(np.abs(np.asarray(r)[2, :]))))))
             for r in rotations]
    return measure_stack(positions, tilts, stack)


def run_stack(
    stack: StackPlan,
    *,
    mode: str = "headless",
    video: str | Path | None = None,
    fps: float = DEFAULT_FPS,
    size: Sequence[int] = DEFAULT_SIZE,
    camera: str = DEFAULT_CAMERA,
    quality: str = "fast",
    progress: bool = True,
    show_ui: bool = False,
    servo: dict | None = None,
) -> StackReport:
    """Run a stacking plan in simulation, the blocks on the table at their starts.

    Args:
        stack: the plan and blocks (``so101_kinematics.planning.stacking.stack_plan``).
        mode: "headless", "viewer" or "record" (see ``run_pick_place``).
        video: MP4 path for mode "record".
        fps: video frames per second of simulated time.
        size: video (width, height) [px].
        camera: camera name for the video.
        quality: a ``so101_kinematics.sim.render.QUALITY`` preset name.
        progress: progress bar while recording.
        show_ui: mode "viewer": show MuJoCo's side panels from the start.
        servo: keywords of ``so101_kinematics.sim.actuation.use_servo``.

    Returns:
        The report: where each block ended, bottom block first.

    Raises:
        so101_kinematics.planning.motion.PlanError: the plan is invalid (nothing moved).
        so101_kinematics.sim.render.RenderError: the video cannot be written as asked.
    """
    if mode not in ("headless", "viewer", "record"):
        raise PlanError(f"mode must be 'headless', 'viewer' or 'record', got {mode!r}.")
    if quality not in QUALITY:
        raise RenderSettingError(f"Unknown quality {quality!r}; choose one of "
                                 f"{', '.join(QUALITY)}.")
    plan = validate_plan(stack.plan, scene_limits(), base_height=stack.base_height)
    if mode == "record":
        check_fps(fps, 1.0 / scene_model().opt.timestep)
        check_frame_size(size, "Video size")
    m = build_model(render_meshes=mode == "record" and QUALITY[quality].light_meshes,
                    physics_only=mode == "headless", base_height=stack.base_height,
                    cubes_at=[(*b.start[:2], b.start_yaw_deg) for b in stack.blocks],
                    servo=servo)
    names = cube_names(m)
    overlays = [_Overlay(np.array(b.target), np.eye(3), 0.5 * CUBE_SIZE, FINAL_RGBA)
                for b in stack.blocks]

    def report(run) -> StackReport:
        geometry = stack_report([run.d.body(n).xpos for n in names],
                                [run.d.body(n).xmat.reshape(3, 3) for n in names], stack)
        geometry["success"] = geometry["success"] and run.completed
        return StackReport(**geometry, sim_time_s=float(run.d.time), wall_time_s=run.wall,
                           frames_written=run.frames, completed=run.completed,
                           waypoint_errors_deg=run.errors, video=run.video)

    return execute_plan(m, plan, report, mode=mode, video=video, fps=fps, size=size,
                        camera=camera, quality=quality, progress=progress, show_ui=show_ui,
                        overlays=overlays)

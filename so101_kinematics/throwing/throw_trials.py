"""Throws at seeded cups, their summary, and a picture or a video of one throw.

:func:`cup_positions` draws the cups (a seeded generator: the same seed, the same cups);
:func:`run_throws` throws at each (``throw_run.throw_at``) and sums up; :func:`save_picture`
and :func:`save_video` show one throw from the side camera of the throwing scene.
"""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np

from so101_kinematics import servo
from so101_kinematics.errors import PlanError
from so101_kinematics.throwing.ball import Ball
from so101_kinematics.throwing.throw_run import ThrowRun, throw_at
from so101_kinematics.throwing.throw_scene import SIDE_CAMERA

__all__ = [
    "AZIMUTH_RANGE_DEG", "CUP_DISTANCES", "cup_positions", "run_throws",
    "save_picture", "save_video",
]

CUP_DISTANCES = (0.3, 0.6)
"""The seeded cups' distances from the base [m] (issue 38's acceptance)."""
AZIMUTH_RANGE_DEG = (-40.0, 40.0)
"""The seeded cups' directions from the base's forward axis [deg]."""


def cup_positions(count: int, seed: int) -> list[tuple[float, float]]:
    """``count`` cup positions (x, y) [m] on the table, drawn with ``seed``.

    Example:
        >>> [round(math.hypot(*p), 3) for p in cup_positions(2, 0)]  # distance, azimuth per cup
        [0.491, 0.312]
    """
    rng = np.random.default_rng(seed)
    cups = []
    for _ in range(count):
        distance = rng.uniform(*CUP_DISTANCES)
        azimuth = math.radians(rng.uniform(*AZIMUTH_RANGE_DEG))
        cups.append((distance * math.cos(azimuth), distance * math.sin(azimuth)))
    return cups


def run_throws(m: mujoco.MjModel, ball: Ball, cups, volts: float = servo.DEFAULT_SUPPLY_V,
               variant: str = servo.DEFAULT_VARIANT, aims=None) -> dict:
    """Throw at each cup; the report (``hits``, ``trials``, the worst model error, the speeds).

    ``aims``: where each throw aims (x, y) [m], when not at the cup itself (where a camera
    saw it: ``cup_camera.py``); the cups stand at ``cups`` all the same.
    """
    aims = cups if aims is None else aims
    trials = [throw_at(m, ball, aim, volts, variant, cup=cup)
              for aim, cup in zip(aims, cups, strict=True)]
    errors = [t["model_error_m"] for t in trials if t["model_error_m"] is not None]
    speeds = [t["release_speed_m_s"] for t in trials if "release_speed_m_s" in t]
    return {"hits": sum(t["in_cup"] for t in trials), "throws": len(trials),
            "worst_model_error_m": max(errors) if errors else None,
            "release_speed_m_s": [min(speeds), max(speeds)] if speeds else None,
            "ball": ball.report(),
            "trials": trials}


def save_video(path: Path, m: mujoco.MjModel, ball: Ball, cup,
               volts: float = servo.DEFAULT_SUPPLY_V, variant: str = servo.DEFAULT_VARIANT,
               aim=None) -> dict:
    """Record one throw at ``cup`` to an MP4 (the side camera); the trial.

    ``aim``: where the throw aims (x, y) [m], when not at the cup (``run_throws``'s ``aims``).
    """
    from so101_kinematics.sim.video import VideoRecorder

    recorders: dict = {}

    def on_step(run: ThrowRun) -> None:
        if run.d not in recorders:
            recorders.clear()
            recorders[run.d] = VideoRecorder(m, run.d, path, camera=SIDE_CAMERA, progress=False)
        recorders[run.d].sync()

    trial = throw_at(m, ball, cup if aim is None else aim, volts, variant, record=on_step,
                     cup=cup)
    for recorder in recorders.values():
        recorder.close()
    return trial


def save_picture(path: Path, m: mujoco.MjModel, ball: Ball, cup,
                 volts: float = servo.DEFAULT_SUPPLY_V,
                 variant: str = servo.DEFAULT_VARIANT, aim=None) -> dict:
    """A PNG of one throw at ``cup``: the side camera at the first touch, the ball's path drawn.

    ``aim``: where the throw aims (x, y) [m], when not at the cup (``run_throws``'s ``aims``).
    """
    from matplotlib.figure import Figure

    from so101_kinematics.markers import png_metadata
    from so101_kinematics.outputs import atomic_output
    from so101_kinematics.sim.render import FrameRenderer, Overlay

    path_points: list[np.ndarray] = []
    frames: dict = {}

    def on_step(run: ThrowRun) -> None:
        flight = run.flight
        if flight is None or flight.release is None:
            return
        if flight.touch is None:
            path_points.append(flight.ball_state()[0])
        elif "image" not in frames:
            overlays = [Overlay(p, np.eye(3), 0.003, (0.1, 0.2, 0.9, 0.8))
                        for p in path_points[::3]]
            renderer = FrameRenderer(m, run.d, (800, 600), SIDE_CAMERA, overlays)
            frames["image"] = renderer.render()
            renderer.close()

    trial = throw_at(m, ball, cup if aim is None else aim, volts, variant, record=on_step,
                     cup=cup)
    if "image" not in frames:
        raise PlanError("the ball never came down, so there is no picture of its landing. "
                        "Fix: throw at a cup in range (see --help).")
    figure = Figure(figsize=(8, 6.6), dpi=100)
    axes = figure.add_axes((0.0, 0.09, 1.0, 0.91))
    axes.imshow(frames["image"])
    axes.axis("off")
    error = trial["model_error_m"] or 0.0
    verdict = "in the cup" if trial["in_cup"] else "missed"
    figure.text(0.5, 0.045, f"{ball.name} ball at {trial['release_speed_m_s']:.2f} m/s to a cup "
                f"{trial['cup_distance_m']:.2f} m away: {verdict}; forward model "
                f"{1000 * error:.1f} mm from the first touch (path: blue)",
                ha="center", va="center", fontsize=9)
    with atomic_output(Path(path)) as temporary:
        figure.savefig(temporary, format="png", metadata=png_metadata("throw.py"))
    return trial


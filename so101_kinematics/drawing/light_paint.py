"""Light painting: strokes in a vertical plane, a light switched with the motion, a long exposure.

The light (an LED in the pen's holder, where the pen's tip would be) traces the strokes on a
vertical board in front of the arm: the board's frame has its centre ``BOARD_CENTRE`` in the
base frame, u to the board's right as the camera sees it (the base's +y) and v up (the
base's +z); the holder points straight ahead (``LIGHT_TILT_DEG``: the approach horizontal).
The path is the drawing's (``pen_plan``: constant speed between corners, stops at corners,
each command leading by the servo's lag), with no pen to lower: between strokes the light is
off. While on, its brightness follows the light's speed read back one control period before
(:func:`measured_brightness`: ``v / speed``, a PWM duty): the exposure per millimetre of the
path is the same at full speed, in the ramps and where the servos lag, and a stop leaves no
blot.

The exposure: after every control period the simulated arm's light (the tip's position) is
projected through the fixed ``pick_place`` camera (``vision/camera_model.py``) and added to
a long-exposure image, weighted by its brightness and the time. Scored: ``mean_mm`` (the
light's path, while on, from the strokes, in the board's plane) and
``brightness_spread_pct`` (the exposure per millimetre of the light's own path, in pieces
of ``SPREAD_PIECE_MM``: (largest - smallest) / mean).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import mujoco
import numpy as np

from so101_kinematics.drawing.ink import build_drawing_model
from so101_kinematics.drawing.ink_score import distances_to_strokes
from so101_kinematics.drawing.page import Page
from so101_kinematics.drawing.pen import PenPose, pen_configuration
from so101_kinematics.drawing.pen_plan import (
    DEFAULT_SPEED_MM_S,
    DWELL_S,
    SPEED_RAMP_S,
    TRAVEL_SPEED_MM_S,
    corner_runs,
    lag_seconds,
    lead_commands,
    points_along,
    trapezoid,
    with_pen_load,
)
from so101_kinematics.drawing.strokes import prepare
from so101_kinematics.markers import png_metadata
from so101_kinematics.outputs import atomic_output
from so101_kinematics.planning.plans import GRIPPER_CLOSED
from so101_kinematics.servo import DEFAULT_SUPPLY_V
from so101_kinematics.sim import actuation
from so101_kinematics.sim.scene import send_position_command, set_initial_pose
from so101_kinematics.sim.straight import control_period
from so101_kinematics.vision.camera_model import (
    camera_intrinsics,
    get_camera_pose_base,
    project_points,
)

__all__ = [
    "BOARD_CENTRE", "EXPOSURE_CAMERA", "EXPOSURE_SIZE", "LIGHT_TILT_DEG", "SPREAD_PIECE_MM",
    "base_to_board", "board_to_base", "light_configurations", "light_path", "measured_brightness",
    "paint", "save_exposure", "score_exposure",
]

BOARD_CENTRE = (0.26, 0.0, 0.165)
"""The board's centre [m] in the base frame: 26 cm ahead of the base, 16.5 cm above the table
(a 120 mm star in reach at the light's tilt)."""
LIGHT_TILT_DEG = 60.0
"""The holder's approach, from the vertical [deg] (90: straight ahead): leaning forward, the
light faces the camera in front of the arm; upright the arm cannot reach the board's height."""
EXPOSURE_CAMERA = "pick_place"
"""The fixed camera that takes the long exposure (``model/table.xml``: in front of the arm)."""
EXPOSURE_SIZE = (640, 480)  # [px]
SPREAD_PIECE_MM = 5.0  # [mm]: the pieces of a stroke whose exposures are compared
SPLAT_PX = 1.5  # [px]: the light's blur in the picture (its glow)
HEADROOM = 2.0
"""The light's brightest over its brightness at the asked speed: the PWM's nominal duty is
half its full one, so a light catching up after a corner is not dimmed."""


def board_to_base(points_mm: np.ndarray, centre=BOARD_CENTRE) -> np.ndarray:
    """Board points (n, 2) [mm] (u right as the camera sees it, v up) to base points [m].

    Example:
        >>> board_to_base(np.array([[10.0, 20.0]])).round(3).tolist()
        [[0.26, 0.01, 0.185]]
    """
    points = np.asarray(points_mm, dtype=float).reshape(-1, 2) / 1000.0
    return np.column_stack([np.full(len(points), centre[0]), centre[1] + points[:, 0],
                            centre[2] + points[:, 1]])


def base_to_board(points: np.ndarray, centre=BOARD_CENTRE) -> np.ndarray:
    """Base points (n, 3) [m] to the board's (u, v) [mm] (:func:`board_to_base`'s inverse)."""
    return np.column_stack([points[:, 1] - centre[1], points[:, 2] - centre[2]]) * 1000.0


def light_path(strokes: Sequence[np.ndarray], speed: float, dt: float):
    """The light's samples: positions (n, 3) [m] and brightness (n,) in [0, 1] (0: off).

    Between strokes the light is off and travels at ``TRAVEL_SPEED_MM_S``; along a stroke
    its brightness is the planned speed over ``speed``.
    """
    parts: list[tuple[np.ndarray, np.ndarray]] = []
    here = None
    for stroke in strokes:
        start = board_to_base(stroke[:1])[0]
        if here is not None and np.linalg.norm(start - here) > 0.0:
            way = float(np.linalg.norm(start - here)) * 1000.0
            moved = points_along(np.vstack([here, start]), trapezoid(
                way, TRAVEL_SPEED_MM_S, TRAVEL_SPEED_MM_S / SPEED_RAMP_S, dt) / 1000.0)
            parts.append((moved, np.zeros(len(moved))))
        hold = np.repeat(start[None], max(1, round(DWELL_S / dt)), axis=0)
        parts.append((hold, np.zeros(len(hold))))
        for run in corner_runs(stroke):
            length = float(np.linalg.norm(np.diff(run, axis=0), axis=1).sum())
            s = trapezoid(length, speed, speed / SPEED_RAMP_S, dt)
            rate = np.diff(np.concatenate([[0.0], s])) / dt / speed  # planned speed / speed
            parts.append((points_along(board_to_base(run), s / 1000.0), np.clip(rate, 0, 1)))
        here = board_to_base(stroke[-1:])[0]
        parts.append((np.repeat(here[None], max(1, round(DWELL_S / dt)), axis=0),
                      np.zeros(max(1, round(DWELL_S / dt)))))
    return np.vstack([p for p, _ in parts]), np.concatenate([b for _, b in parts])


def light_configurations(strokes: Sequence[np.ndarray], speed: float, dt: float):
    """The arm's configurations along :func:`light_path`, the light at ``LIGHT_TILT_DEG``.

    Returns:
        ``(configurations, brightness)``: one configuration per sample (each solved from the
        one before, so the wrist does not flip between samples) and its brightness (n,).

    Raises:
        UnreachableError: a point of the board the light cannot reach straight ahead.
    """
    points, brightness = light_path(strokes, speed, dt)
    pose, configurations, cfg = PenPose(LIGHT_TILT_DEG), [], None
    for point in points:
        cfg = pen_configuration(point, pose, cfg)
        configurations.append(cfg)
    return configurations, brightness


def measured_brightness(light: np.ndarray, lit: np.ndarray, speed: float,
                        dt: float) -> np.ndarray:
    """The light's brightness in each period, from its speed read back in the period before.

    That speed over the asked ``speed``, at most ``HEADROOM``; 0 where the plan has it off.

    On the arm the same comes from the servos' present positions at each control cycle (the
    FK of the light, as ``draw.py --port`` reads the tip): one period late, as here.

    Example:
        >>> light = np.array([[0.0, 0, 0], [0.0001, 0, 0], [0.0003, 0, 0], [0.0006, 0, 0]])
        >>> measured_brightness(light, np.ones(4, bool), 15.0, 0.01).round(3).tolist()
        [0.0, 0.0, 0.667, 1.333]
    """
    moved = np.linalg.norm(np.diff(light, axis=0), axis=1) * 1000.0 / dt  # [mm/s]
    before = np.concatenate([[0.0, 0.0], moved[:-1]])  # the period before each period
    return np.where(lit, np.clip(before / speed, 0.0, HEADROOM), 0.0)


def _simulate(commands: list[dict], dt: float, m) -> np.ndarray:
    """Run ``commands`` one per ``dt``; the light's position [m] after each."""
    d = mujoco.MjData(m)
    steps = max(1, round(dt / m.opt.timestep))
    set_initial_pose(d, {**commands[0], "gripper": GRIPPER_CLOSED})
    for _ in range(round(1.0 / dt)):  # a second to settle at the start
        send_position_command(d, commands[0])
        actuation.step(m, d, steps)
    light = np.empty((len(commands), 3))
    for k, cfg in enumerate(commands):
        send_position_command(d, cfg)
        actuation.step(m, d, steps)
        light[k] = d.geom("pen_tip").xpos
    return light, d


def score_exposure(strokes: Sequence[np.ndarray], light: np.ndarray,
                   brightness: np.ndarray, dt: float) -> dict:
    """The light's figures while on: distances [mm] and the exposure's evenness.

    ``mean_mm``/``worst_mm``: the light's path (in the board's plane) from the strokes.
    ``brightness_spread_pct``: the light's own path cut into pieces of ``SPREAD_PIECE_MM``
    (each lit stretch, its last partial piece aside); each piece's exposure is its periods'
    brightness times time over the way they covered; (largest - smallest) / mean of them. A light
    that lags or jerks where its brightness assumed the plan's speed shows here.
    """
    on = brightness > 0.0
    distance = distances_to_strokes(base_to_board(light[on]), strokes)
    exposures = []
    lit = np.flatnonzero(on)
    for stretch in np.split(lit, np.flatnonzero(np.diff(lit) > 1) + 1):
        if len(stretch) < 2:
            continue
        steps = np.linalg.norm(np.diff(light[stretch], axis=0), axis=1) * 1000.0  # [mm]
        way = np.cumsum(steps)  # at the end of each period after the first
        pieces = int(way[-1] // SPREAD_PIECE_MM)
        if pieces < 1:
            continue
        piece = np.minimum((way // SPREAD_PIECE_MM).astype(int), pieces)
        energy = np.bincount(piece, weights=brightness[stretch][1:] * dt, minlength=pieces + 1)
        length = np.bincount(piece, weights=steps, minlength=pieces + 1)
        exposures.extend(energy[:pieces] / np.maximum(length[:pieces], 1e-12))
    exposures = np.array(exposures)
    spread = (100.0 * (exposures.max() - exposures.min()) / exposures.mean()
              if len(exposures) else 0.0)
    return {"mean_mm": round(float(distance.mean()), 3),
            "worst_mm": round(float(distance.max()), 3),
            "brightness_spread_pct": round(float(spread), 1), "pieces": int(len(exposures))}


def paint(strokes: Sequence[np.ndarray], speed: float = DEFAULT_SPEED_MM_S,
          volts: float = DEFAULT_SUPPLY_V) -> tuple[dict, np.ndarray]:
    """Paint ``strokes`` (board millimetres) with the simulated arm; the report and the image.

    Returns:
        ``(report, exposure)``: the report (``exposure``: :func:`score_exposure`'s figures)
        and the long exposure, (height, width), its brightest pixel 1.

    Raises:
        UnreachableError: a point of the board the light cannot reach straight ahead.
    """
    prepared = prepare(strokes)
    m = build_drawing_model(Page())  # the page lies on the table, far below the light
    dt = control_period(m)
    plan, brightness = light_configurations(prepared, speed, dt)
    commands = with_pen_load(lead_commands(plan, dt, lag_seconds(volts)),
                             np.zeros(len(plan), dtype=bool), volts, None, None)
    light, d = _simulate(commands, dt, m)
    brightness = measured_brightness(light, brightness > 0.0, speed, dt)
    width, height = EXPOSURE_SIZE
    pixels = project_points(camera_intrinsics(m, EXPOSURE_CAMERA, width, height),
                            get_camera_pose_base(m, d, EXPOSURE_CAMERA), light)
    image = np.zeros((height, width))
    grid_y, grid_x = np.mgrid[0:height, 0:width]
    for (u, v), weight in zip(pixels[brightness > 0], brightness[brightness > 0] * dt,
                              strict=True):
        x0, y0 = int(round(u)), int(round(v))
        if 3 <= x0 < width - 3 and 3 <= y0 < height - 3:
            box = np.s_[y0 - 3:y0 + 4, x0 - 3:x0 + 4]
            image[box] += weight * np.exp(-((grid_x[box] - u) ** 2 + (grid_y[box] - v) ** 2)
                                          / (2 * SPLAT_PX ** 2))
    report = {"exposure": score_exposure(prepared, light, brightness, dt),
              "duration_s": round(len(light) * dt, 2), "speed_mm_s": speed,
              "camera": EXPOSURE_CAMERA, "board_centre_m": list(BOARD_CENTRE)}
    return report, image / max(float(image.max()), 1e-12)


def save_exposure(path: str | Path, image: np.ndarray, caption: str,
                  program: str = "light_paint.py") -> Path:
    """Write the long exposure as a PNG (the light's glow on black), with a caption."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    height, width = image.shape
    band = 0.4  # [in]: the caption's two lines
    figure = Figure(figsize=(width / 100.0, height / 100.0 + band), dpi=100)
    axes = figure.add_axes((0.0, band / (height / 100.0 + band), 1.0,
                            (height / 100.0) / (height / 100.0 + band)))
    axes.imshow(np.sqrt(image), cmap="inferno", vmin=0.0, vmax=1.0)
    axes.axis("off")
    figure.text(0.5, 0.5 * band / (height / 100.0 + band), caption, ha="center",
                va="center", fontsize=8)
    target = Path(path)
    with atomic_output(target) as temporary:
        figure.savefig(temporary, format="png", metadata=png_metadata(program))
    return target

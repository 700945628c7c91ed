"""One drawing in the simulator: strokes from text, a picture or a shape, drawn, inked, scored.

:func:`drawing_strokes` makes the target (page millimetres, centred on the page) and checks
it fits the page; :func:`run_drawing` orders and resamples it, checks the reach, plans the
pen's path (``pen_plan``), runs it on the simulated arm with the pen that leaves ink
(``ink``) and scores the ink (``ink_score``). ``draw.py`` at the root is its command line.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Mapping, Sequence

import mujoco
import numpy as np

from so101_kinematics.drawing.glyphs import DEFAULT_FONT, shape_strokes, text_strokes
from so101_kinematics.drawing.ink import INK_FORCE_N, InkRecorder, build_drawing_model
from so101_kinematics.drawing.ink_score import score_ink
from so101_kinematics.drawing.page import Page, check_reach
from so101_kinematics.drawing.pen import PenPose
from so101_kinematics.drawing.pen_plan import DEFAULT_SPEED_MM_S, lag_seconds, plan_drawing
from so101_kinematics.drawing.strokes import (
    MIN_STROKE_MM,
    bounds,
    fit_to_height,
    ink_length,
    pen_up_travel,
    prepare,
    stroke_length,
)
from so101_kinematics.drawing.svg_paths import svg_strokes
from so101_kinematics.errors import PlanError
from so101_kinematics.planning.plans import GRIPPER_CLOSED
from so101_kinematics.servo import DEFAULT_SUPPLY_V
from so101_kinematics.sim import actuation
from so101_kinematics.sim.scene import set_initial_pose
from so101_kinematics.sim.straight import control_period

__all__ = ["PAGE_MARGIN_MM", "SETTLE_S", "drawing_strokes", "ready_strokes", "run_drawing"]

PAGE_MARGIN_MM = 5.0
"""The drawing keeps this far from the page's edges [mm]."""
SETTLE_S = 1.0
"""The arm rests at the first pen-up point this long before it draws [s]."""

logger = logging.getLogger(__name__)


def drawing_strokes(height: float, page: Page, text: str | None = None,
                    svg: str | None = None, shape: str | None = None,
                    font: str = DEFAULT_FONT) -> list[np.ndarray]:
    """The target strokes [mm], centred on the page, ``height`` [mm] high.

    Args:
        height: text: the font's line height (``glyphs``); a picture or a shape: its height.
        page: the page it must fit on (inside ``PAGE_MARGIN_MM``).
        text: a line of text to draw, or None.
        svg: an SVG file whose paths to draw, or None.
        shape: one of ``glyphs.SHAPES``, or None.
        font: the Hershey font of a text.

    Raises:
        PlanError: nothing or more than one thing to draw, an empty text, an unknown glyph,
            an SVG without paths or whose curves are all too small to draw, a drawing
            larger than the page.
    """
    given = [name for name, value in (("--text", text), ("--svg", svg), ("--shape", shape))
             if value is not None]
    if len(given) != 1:
        raise PlanError(f"give one thing to draw, not {len(given)} ({', '.join(given) or 'none'})"
                        ". Fix: --text \"ECE 4560\", --svg FILE.svg or --shape star.")
    if text is not None:
        raw, lines = text_strokes(text, font)
        strokes = fit_to_height(raw, height, lines)
    elif shape is not None:
        strokes = fit_to_height(shape_strokes(shape), height)
    else:
        strokes = _svg_to_page(svg, height)
    low, high = bounds(strokes)
    size = high - low
    room = np.asarray(page.size) - 2.0 * PAGE_MARGIN_MM
    if (size > room + 1e-9).any():
        fits = math.floor(height * float(min(room / np.maximum(size, 1e-9))))
        fix = (f"--height-mm {fits:g} or less, or a larger page (--page a4)" if fits >= 1 else
               "crop the picture to what should be drawn (it is far wider than high)")
        raise PlanError(f"the drawing is {size[0]:.0f} x {size[1]:.0f} mm; the {page.name} page "
                        f"holds {room[0]:.0f} x {room[1]:.0f} mm inside its {PAGE_MARGIN_MM:g} mm "
                        f"margins. Fix: {fix}.")
    return strokes


def _svg_to_page(svg: str, height: float) -> list[np.ndarray]:
    """An SVG's strokes scaled to ``height`` [mm]; curves too small to draw dropped (warned)."""
    strokes = fit_to_height(svg_strokes(svg), height)
    small = [s for s in strokes if stroke_length(s) < MIN_STROKE_MM]
    if len(small) == len(strokes):
        raise PlanError(f"--svg {svg}: at --height-mm {height:g} every path is shorter than "
                        f"{MIN_STROKE_MM:g} mm, too small for a pen to draw. Fix: draw it larger "
                        "(--height-mm) or simplify the picture.")
    if small:
        logger.warning("warning: --svg %s: %d of %d paths are shorter than %g mm and are left "
                       "out (a pen's dot). Fix: --height-mm larger to keep them.", svg,
                       len(small), len(strokes), MIN_STROKE_MM)
    return [s for s in strokes if stroke_length(s) >= MIN_STROKE_MM]


def ready_strokes(strokes: Sequence[np.ndarray], page: Page,
                  pose: PenPose) -> tuple[list[np.ndarray], tuple[float, float]]:
    """The strokes as drawn: ordered from the drawing's left end, resampled, checked in reach.

    Returns:
        ``(prepared, start)``: the strokes and the point [mm] the ordering started from.

    Raises:
        PlanError: strokes out of reach (``page.check_reach``).
    """
    low, _ = bounds(strokes)
    start = (float(low[0]), 0.0)
    prepared = prepare(strokes, start=start)
    check_reach(page, prepared, pose)
    return prepared, start


def _run_in_simulator(m: mujoco.MjModel, path) -> InkRecorder:
    """Put the arm at the path's start, let it settle, run the path; the recorder."""
    d = mujoco.MjData(m)
    steps = max(1, round(path.dt / m.opt.timestep))
    set_initial_pose(d, {**path.plan[0], "gripper": GRIPPER_CLOSED})
    recorder = InkRecorder(m, d)
    recorder.run([path.commands[0]] * max(1, round(SETTLE_S / path.dt)), steps)
    recorder.run(path.commands, steps)
    return recorder


def run_drawing(strokes: Sequence[np.ndarray], page: Page, pose: PenPose | None = None,
                speed: float = DEFAULT_SPEED_MM_S, servo: Mapping | None = None,
                lead: bool = True) -> tuple[dict, np.ndarray, list[np.ndarray]]:
    """Draw ``strokes`` on ``page`` in the simulator and score the ink.

    Args:
        strokes: the target [mm] (:func:`drawing_strokes`).
        page: where the page lies.
        pose: the pen's tilt and roll (default upright).
        speed: the pen's speed on the paper [mm/s].
        servo: ``actuation.use_servo``'s keywords (default: the faithful STS3215, 12 V).
        lead: lead each command by the servo's lag (``pen_plan``; none for the ideal servo).

    Returns:
        ``(report, ink, prepared)``: the report (``ink``: the figures of ``ink_score``),
        the ink's touches and the strokes as drawn (ordered, resampled).

    Raises:
        PlanError: strokes out of reach, a speed the servos cannot hold.
    """
    pose = pose or PenPose()
    servo = dict(servo or {})
    prepared, start = ready_strokes(strokes, page, pose)
    volts, variant = float(servo.get("volts", DEFAULT_SUPPLY_V)), servo.get("variant")
    faithful = servo.get("mode", "sts3215") != "ideal"
    lag = lag_seconds(volts, variant, servo.get("p")) if lead and faithful else 0.0
    load = faithful and servo.get("feedforward", True)
    m = build_drawing_model(page, servo)
    started = time.perf_counter()
    path = plan_drawing(page, prepared, pose, speed, control_period(m), volts, variant, lag,
                        load, servo.get("p"))
    planned = time.perf_counter()
    recorder = _run_in_simulator(m, path)
    ink = recorder.ink()
    score = score_ink(page, prepared, ink)
    forces = ink[:, 3] if len(ink) else np.zeros(1)
    report = {
        "ink": score,
        "page": {"name": page.name, "size_mm": list(page.size), "centre_m": list(page.centre),
                 "yaw_deg": page.yaw},
        "pen": {"tilt_deg": math.degrees(pose.tilt), "speed_mm_s": speed,
                "force_n": {"mean": round(float(forces.mean()), 3),
                            "max": round(float(forces.max()), 3), "ink_at_least": INK_FORCE_N}},
        "strokes": len(prepared), "target_mm": round(ink_length(prepared), 1),
        "pen_up_travel_mm": round(pen_up_travel(prepared, start), 1),
        "drawing_s": round(path.duration, 2),
        "servo": actuation.servo_spec(m).describe(),
        "lag_lead_s": round(lag, 4),
        "plan_s": round(planned - started, 2),
        "simulation_s": round(time.perf_counter() - planned, 2),
    }
    return report, ink, prepared

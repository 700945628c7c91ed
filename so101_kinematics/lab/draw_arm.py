"""A drawing on an arm through lerobot: the simulator's pen path run by the hardware path.

The half of ``draw.py --port PORT`` that moves an arm (the virtual arm or the real one):
the strokes are ordered, checked in reach and planned as in the simulator
(``drawing/pen_plan.py``: one configuration per 10 ms control cycle, offset by the pen's
load), then run by ``hw/run.py``'s ``run_on_arm`` with its checks, its gravity feed-forward
and its velocity lead (``hw/lead.py``: the servo's lag, led on the wire). The arm has no
page that records ink: the figures are the tip's path as the servos read it back (the FK of
each cycle's present positions, ``pen.tip_position``) against the strokes, on the pen-down
cycles: how far the pen would have drawn from them, its spring's travel aside.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from so101_kinematics.drawing.draw_run import ready_strokes
from so101_kinematics.drawing.ink_score import COVER_MM, distances_to_strokes
from so101_kinematics.drawing.page import Page, base_to_page
from so101_kinematics.drawing.pen import PenPose, tip_position
from so101_kinematics.drawing.pen_plan import DEFAULT_SPEED_MM_S, plan_drawing
from so101_kinematics.drawing.strokes import resample
from so101_kinematics.hw.run import run_on_arm
from so101_kinematics.planning.motion import Plan, Step
from so101_kinematics.planning.plans import GRIPPER_CLOSED
from so101_kinematics.planning.straight_line import CONTROL_DT

__all__ = ["APPROACH_S", "draw_on_arm", "drawing_plan"]

APPROACH_S = 3.0
"""The move from where the arm is to the first pen-up point [s] (the speed cap may stretch it)."""
SAMPLE = "draw~"  # the drawing's steps: draw~00001, ...


def drawing_plan(path) -> Plan:
    """The pen's path as a plan: the approach, then one step per control cycle."""
    commands = [{**cfg, "gripper": GRIPPER_CLOSED} for cfg in path.commands]
    steps = [Step("approach", commands[0], APPROACH_S, 1.0)]
    steps += [Step(f"{SAMPLE}{k:05d}", cfg, path.dt, 0.0) for k, cfg in enumerate(commands)]
    return Plan(steps, return_to_start=True, return_duration=APPROACH_S)


def _coverage(strokes: Sequence[np.ndarray], tips: np.ndarray, samples: list[int]) -> float:
    """The share [%] of the strokes with the read-back tip within ``COVER_MM``, as for ink.

    The pen-down tips (n, 2) [mm] are one line per run of consecutive plan samples.
    """
    breaks = np.flatnonzero(np.diff(samples) > 1) + 1
    lines = [np.vstack([part, part[-1:]]) for part in np.split(tips, breaks)]
    targets = np.vstack([resample(s) for s in strokes])
    return round(100.0 * float((distances_to_strokes(targets, lines) <= COVER_MM).mean()), 1)


def draw_on_arm(port: str, calibration: Mapping[str, Any], strokes: Sequence[np.ndarray],
                page: Page, pose: PenPose | None = None, speed: float = DEFAULT_SPEED_MM_S,
                load: bool = True, **run_options) -> dict:
    """Draw ``strokes`` on the arm at ``port``; the tip's measured path scored.

    Args:
        port: the arm's serial port.
        calibration: its lerobot calibration (``calibration.load_calibration``).
        strokes: the target [mm] (``draw_run.drawing_strokes``).
        page: where the page lies.
        pose: the pen's tilt and roll (default upright).
        speed: the pen's speed [mm/s].
        load: offset the goals by the pen's load (``pen_plan``): an arm that holds the pen
            on a page; ``False`` for one without (the virtual arm has neither).
        **run_options: ``run_on_arm``'s options (``confirm``, ``trims``, ...).

    Returns:
        The report: ``arm_tip`` (``mean_mm``, ``worst_mm``: the read-back tip's distance from
        the strokes on the pen-down cycles; ``coverage_pct``: the share of the strokes it
        passed within ``COVER_MM``, as the ink's; ``cycles``), ``aborted`` (None, or why).

    Raises:
        PlanError: strokes out of reach, a speed the servos cannot hold (nothing moved).
    """
    pose = pose or PenPose()
    prepared, _ = ready_strokes(strokes, page, pose)
    path = plan_drawing(page, prepared, pose, speed, CONTROL_DT, load=load)
    options = {"profile": "linear", "velocity_ff": True, "gravity_ff": True, **run_options}
    result = run_on_arm(port, calibration, drawing_plan(path), **options)
    down = [(int(c.step[len(SAMPLE):]), tip_position(c.measured)[:2]) for c in result.cycles
            if c.measured is not None and c.step.startswith(SAMPLE)
            and path.down[int(c.step[len(SAMPLE):])]]
    figures = {"mean_mm": None, "worst_mm": None, "coverage_pct": 0.0, "cycles": len(down)}
    if down:
        tips = base_to_page(page, np.array([tip for _, tip in down]))
        distance = distances_to_strokes(tips, prepared)
        figures.update(mean_mm=round(float(distance.mean()), 3),
                       worst_mm=round(float(distance.max()), 3),
                       coverage_pct=_coverage(prepared, tips, [k for k, _ in down]))
    return {"arm_tip": figures, "strokes": len(prepared), "drawing_s": round(path.duration, 2),
            "aborted": None if result.aborted is None else str(result.aborted)}

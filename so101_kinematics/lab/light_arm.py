"""A light painting on an arm through lerobot: a torch switched by the gripper, led in time.

The half of ``light_paint.py --port PORT`` that moves an arm. The arm has no output of its
own, so the light is a torch with a momentary push button, tied to the gripper's fixed jaw
with its lens where the pen's tip would be and its button facing the moving jaw
(``docs/final_project_drawing.md`` has the mount): the gripper's goal closes past the
button's click to light it and opens to let it go, each press and release led by the
jaw's lag (``drawing/light_switch.py``).

The light's path is the simulator's (``drawing/light_paint.py``: the board, the constant
speed, the light off between strokes), one configuration per 10 ms control cycle, run by
``hw/run.py``'s ``run_on_arm`` with its checks, gravity feed-forward and velocity lead.
The report gives the light's planned on/off times and the ones measured, where the
gripper's read-back position crossed the click: their difference is the lead to correct.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from so101_kinematics.drawing.ink_score import distances_to_strokes
from so101_kinematics.drawing.light_paint import (
    LIGHT_TILT_DEG,
    base_to_board,
    light_configurations,
)
from so101_kinematics.drawing.light_switch import (
    TorchSwitch,
    gripper_goals,
    switch_times,
)
from so101_kinematics.drawing.pen import tip_position
from so101_kinematics.drawing.pen_plan import DEFAULT_SPEED_MM_S
from so101_kinematics.drawing.strokes import prepare
from so101_kinematics.hw.run import run_on_arm
from so101_kinematics.hw.timing import MAX_GRIPPER_SPEED_PCT_S
from so101_kinematics.planning.motion import Plan, Step
from so101_kinematics.planning.straight_line import CONTROL_DT

__all__ = ["paint_on_arm"]

SAMPLE = "light~"  # the painting's steps: light~00001, ...
APPROACH_S = 3.0  # [s]: from where the arm is to the light's first point


def _plan(commands: list[dict], goals: np.ndarray, dt: float, switch: TorchSwitch) -> Plan:
    """The approach (released), then one step per control cycle."""
    steps = [Step("approach", {**commands[0], "gripper": switch.released}, APPROACH_S, 1.0)]
    steps += [Step(f"{SAMPLE}{k:05d}", {**cfg, "gripper": float(g)}, dt, 0.0)
              for k, (cfg, g) in enumerate(zip(commands, goals, strict=True))]
    return Plan(steps, return_to_start=True, return_duration=APPROACH_S)


def _measured_switching(cycles, switch: TorchSwitch, n: int, dt: float):
    """The measured light (the jaw at or past the click) per sample, and the light's tips."""
    lit = np.zeros(n, dtype=bool)
    tips = np.full((n, 3), np.nan)
    for c in cycles:
        if c.measured is None or not c.step.startswith(SAMPLE):
            continue
        k = int(c.step[len(SAMPLE):])
        lit[k] = c.measured["gripper"] <= switch.click
        tips[k] = tip_position(c.measured)
    return lit, tips


def paint_on_arm(port: str, calibration: Mapping[str, Any], strokes: Sequence[np.ndarray],
                 speed: float = DEFAULT_SPEED_MM_S, switch: TorchSwitch | None = None,
                 **run_options) -> dict:
    """Paint ``strokes`` (board [mm]) on the arm at ``port``, the torch switched by the gripper.

    Returns:
        The report: ``light`` (``planned`` and ``measured`` [[on, off], ...] [s] from the
        painting's start; ``switch``: the measured minus planned times, ``on_ms`` and
        ``off_ms`` (mean), ``worst_ms``; ``mean_mm``/``worst_mm``: the read-back light,
        while measured on, from the strokes in the board's plane), ``aborted``.

    Raises:
        PlanError: the board out of reach, a bad switch (nothing moved).
    """
    switch = switch or TorchSwitch()
    switch.check()
    prepared = prepare(strokes)
    commands, brightness = light_configurations(prepared, speed, CONTROL_DT)
    planned_lit = brightness > 0.0
    goals = gripper_goals(planned_lit, CONTROL_DT, switch, MAX_GRIPPER_SPEED_PCT_S)
    options = {"profile": "linear", "velocity_ff": True, "gravity_ff": True, **run_options}
    result = run_on_arm(port, calibration, _plan(commands, goals, CONTROL_DT, switch),
                        **options)
    lit, tips = _measured_switching(result.cycles, switch, len(commands), CONTROL_DT)
    planned, measured = switch_times(planned_lit, CONTROL_DT), switch_times(lit, CONTROL_DT)
    light = {"planned": [list(p) for p in planned], "measured": [list(m) for m in measured],
             "switch": None, "mean_mm": None, "worst_mm": None}
    if len(planned) == len(measured) and planned:
        errors = np.array(measured) - np.array(planned)  # [s]
        light["switch"] = {"on_ms": round(1e3 * float(errors[:, 0].mean()), 1),
                           "off_ms": round(1e3 * float(errors[:, 1].mean()), 1),
                           "worst_ms": round(1e3 * float(np.abs(errors).max()), 1)}
    if lit.any() and not np.isnan(tips[lit]).any():
        distance = distances_to_strokes(base_to_board(tips[lit]), prepared)
        light.update(mean_mm=round(float(distance.mean()), 3),
                     worst_mm=round(float(distance.max()), 3))
    return {"light": light, "strokes": len(prepared),
            "duration_s": round(len(commands) * CONTROL_DT, 2),
            "switch_gripper": [switch.released, switch.click, switch.pressed],
            "switch_lead_s": [switch.lead_on_s, switch.lead_off_s], "tilt_deg": LIGHT_TILT_DEG,
            "aborted": None if result.aborted is None else str(result.aborted),
            "speed_mm_s": speed}

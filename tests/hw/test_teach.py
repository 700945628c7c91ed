"""Teach mode and the plan table."""

from __future__ import annotations

import json
from pathlib import Path

from hw_fakes import HOME, FakeBus, FakeClock, make_session  # noqa: F401

import so101_kinematics.hw.teach as teaching
from so101_forward_kinematics import get_forward_kinematics
from so101_kinematics.hw.timing import speed_caps
from so101_kinematics.planning.plans import default_plan, pick_and_place_steps

REPO = Path(__file__).resolve().parents[2]
VIRTUAL_CALIBRATION = REPO / "calibration" / "virtual_so101.json"


def test_pick_and_place_waypoints_and_their_cube_positions(calibration):
    plan = default_plan()
    pick, place = pick_and_place_steps(plan)  # shared with the simulator
    assert (pick.name, place.name) == ("start_open", "final_open")
    text = teaching.format_plan(plan, rate_hz=100.0, profile="minimum_jerk", max_speed=speed_caps())
    for label, step in (("pick ", pick), ("place", place)):
        x, y, _ = get_forward_kinematics(step.configuration)[0] * 100.0
        assert f"{label} ({step.name}): x = {x:.1f} cm, y = {y:.1f} cm" in text


def test_teach_prints_pasteable_configurations(calibration):
    bus = FakeBus(calibration, dict(HOME, wrist_flex=42.0))
    import io

    out = io.StringIO()
    last = teaching.teach(bus, rate_hz=50.0, duration=0.1, out=out)
    assert not any(bus.torque.values())  # torque off: moved by hand
    lines = out.getvalue().splitlines()
    pasted = json.loads(lines[-1].split(": ", 1)[1])
    assert pasted["wrist_flex"] == 42.0 and last["wrist_flex"] == 42.0
    x, y, z = get_forward_kinematics(last)[0] * 100.0
    assert f"object x={x:.1f} y={y:.1f} z={z:.1f} cm" in lines[1]

"""The pen's path in time: constant speed on the paper, lifts, the contact height, the lead."""

from __future__ import annotations

import math

import numpy as np
import pytest

from so101_kinematics import servo
from so101_kinematics.drawing.page import PAGE_THICKNESS, Page, base_to_page
from so101_kinematics.drawing.pen import PEN_PRESS_M, PenPose
from so101_kinematics.drawing.pen_plan import (
    LIFT_M,
    SPEED_RAMP_S,
    check_joint_speeds,
    lag_seconds,
    plan_drawing,
    trapezoid,
)
from so101_kinematics.errors import PlanError
from so101_kinematics.frames import ARM_JOINTS

DT = 0.01


def test_the_trapezoid_by_hand():
    # 20 mm at 10 mm/s with 100 mm/s^2: 0.1 s ramps of 0.5 mm, 19 mm at speed: 2.1 s
    s = trapezoid(20.0, 10.0, 100.0, DT)
    assert len(s) == 210 and s[-1] == 20.0
    assert s[9] == pytest.approx(0.5)  # the end of the ramp, t = 0.1 s
    assert np.diff(s)[20:190] == pytest.approx(np.full(170, 0.1))  # 10 mm/s x 10 ms
    # too short to reach the speed: a triangle, 0.2 mm at 100 mm/s^2 is 2 x 0.0447 s
    assert len(trapezoid(0.2, 10.0, 100.0, DT)) == math.ceil(2 * math.sqrt(0.002) / DT)


@pytest.fixture(scope="module")
def drawn():
    """A 40 mm line across an L's corner: two runs, one stroke."""
    stroke = np.vstack([np.column_stack([np.linspace(-20.0, 0.0, 41), np.zeros(41)]),
                        np.column_stack([np.zeros(40), np.linspace(0.5, 20.0, 40)])])
    page = Page()
    return page, stroke, plan_drawing(page, [stroke], PenPose(), 15.0, DT, lag=0.05)


def test_the_pen_draws_at_the_speed_on_the_paper_at_the_contact_height(drawn):
    page, stroke, path = drawn
    on_paper = path.tips[path.down]
    assert on_paper[:, 2] == pytest.approx(PAGE_THICKNESS - PEN_PRESS_M)
    speeds = np.linalg.norm(np.diff(path.tips[:, :2], axis=0), axis=1) * 1000.0 / DT
    drawing = speeds[path.down[1:] & path.down[:-1]]
    assert drawing.max() == pytest.approx(15.0, rel=1e-6)
    ramp = SPEED_RAMP_S / DT  # samples in one ramp
    cruising = np.isclose(drawing, 15.0).sum()
    assert cruising >= (40.0 / 15.0) / DT - 4 * ramp - 2  # all but the four ramps


def test_the_pen_stops_at_the_corner_and_lifts_at_the_end(drawn):
    page, stroke, path = drawn
    points = base_to_page(page, path.tips[:, :2])
    at_corner = np.linalg.norm(points, axis=1) < 1e-9
    assert at_corner.any() and path.down[at_corner].all()  # it stands at (0, 0), pen down
    assert path.tips[-1, 2] == pytest.approx(PAGE_THICKNESS + LIFT_M)
    assert path.tips[0, 2] == pytest.approx(PAGE_THICKNESS + LIFT_M)
    assert points[-1] == pytest.approx(stroke[-1])


def test_each_command_leads_the_plan_by_the_lag_times_its_velocity(drawn):
    _, _, path = drawn
    q = np.array([[c[j] for j in ARM_JOINTS] for c in path.plan])
    sent = np.array([[c[j] for j in ARM_JOINTS] for c in path.commands])
    rates = (q[2:] - q[:-2]) / (2 * DT)  # central differences [deg/s]
    k = 1 + int(np.argmax(np.abs(rates).max(axis=1)))  # the fastest sample: a lead to see
    velocity = rates[k - 1]
    assert np.abs(velocity).max() > 1.0
    assert sent[k] - q[k] == pytest.approx(0.05 * velocity, abs=1e-9)
    assert sent[-1] == pytest.approx(q[-1])  # at rest at the end: no lead


def test_the_lag_is_the_servo_models():
    settings = servo.LEROBOT
    chosen = servo.VARIANTS["C018"]
    by_hand = (chosen.emf_damping + chosen.viscous) / (
        chosen.torque_per_volt * 12.0 * settings.p / 4000.0 * 4096 / (2 * math.pi))
    assert lag_seconds(12.0, "C018") == pytest.approx(by_hand)


def test_a_speed_the_servos_cannot_hold_is_refused_with_one_that_fits():
    turn = [{j: 0.0 for j in ARM_JOINTS}, {j: 0.0 for j in ARM_JOINTS}]
    turn[1]["shoulder_pan"] = 2.0  # 200 deg/s in 10 ms
    with pytest.raises(PlanError, match=r"shoulder_pan at up to 200 deg/s.*Fix: --speed-mm-s"):
        check_joint_speeds(turn, DT, 100.0, 5.0, "C001")
    turn[1]["shoulder_pan"] = 0.2  # 20 deg/s: well within
    check_joint_speeds(turn, DT, 100.0, 5.0, "C001")


def test_a_speed_that_is_not_positive_is_refused():
    with pytest.raises(PlanError, match="not positive"):
        plan_drawing(Page(), [np.array([[0.0, 0.0], [1.0, 0.0]])], PenPose(), 0.0)

"""The throw's inverse: the release that lands the model in the cup, within the servos' speed."""

from __future__ import annotations

import math

import numpy as np
import pytest

from so101_kinematics import servo
from so101_kinematics.errors import PlanError
from so101_kinematics.throwing.ball import BALLS, flight
from so101_kinematics.throwing.throw_plan import (
    RELEASE_DEG,
    SPEED_MARGIN,
    SWING_DEG,
    SWING_JOINTS,
    joint_speed_limits,
    plan_throw,
    release_state,
    throwing_range,
)
from so101_kinematics.throwing.throw_scene import CUP_HEIGHT, build_throw_model

BALL = BALLS["pingpong"]


@pytest.fixture(scope="module")
def model():
    return build_throw_model(BALL)


@pytest.mark.parametrize("cup", [(0.3, 0.0), (0.42, 0.25), (0.45, -0.35)])
def test_the_planned_release_lands_the_model_at_the_cups_rim(model, cup):
    plan = plan_throw(model, cup, BALL)
    landing = flight(plan.release_point, plan.release_velocity, BALL, CUP_HEIGHT)[0]
    assert np.hypot(*(landing[:2] - np.asarray(cup))) < 0.003


def test_the_ball_leaves_towards_the_cup(model):
    plan = plan_throw(model, (0.3, 0.3), BALL)
    v, p = plan.release_velocity, plan.release_point
    # the velocity's line, seen from above, passes over the cup
    across = (0.3 - p[0]) * v[1] - (0.3 - p[1]) * v[0]
    assert abs(across) / math.hypot(v[0], v[1]) < 0.001
    assert plan.pan_deg == pytest.approx(-45.0, abs=5.0)  # a positive pan turns the arm to -y


def test_the_release_is_the_middle_of_one_cubic_swing(model):
    plan = plan_throw(model, (0.5, 0.0), BALL)
    middle = plan.configuration(0.5)
    assert {j: middle[j] for j in RELEASE_DEG} == pytest.approx(RELEASE_DEG)
    # the cubic's peak speed, 3/2 of the mean, is the planned rate
    assert plan.rates_deg(0.5)["elbow_flex"] == pytest.approx(math.degrees(plan.rate))
    assert plan.rates_deg(0.5)["elbow_flex"] == pytest.approx(1.5 * SWING_DEG / plan.duration)
    start, end = plan.configuration(0.0), plan.configuration(1.0)
    for joint in SWING_JOINTS:
        assert end[joint] - start[joint] == pytest.approx(SWING_DEG)


def test_the_ball_speed_is_the_jacobian_times_the_rate(model):
    point, per_rate = release_state(model, 0.0, 1.0)
    _, doubled = release_state(model, 0.0, 2.0)
    assert doubled == pytest.approx(2.0 * per_rate)
    assert point[2] > 0.35  # released high, behind the base
    assert point[0] < 0.0


def test_the_servos_top_speed_is_under_the_no_load_speed_and_falls_with_the_supply(model):
    no_load = servo.VARIANTS["C018"].no_load_speed(12.0)  # 45 rpm less friction: 4.71 rad/s
    at_12 = joint_speed_limits(model, 0.0, 12.0, "C018")
    at_10 = joint_speed_limits(model, 0.0, 10.0, "C018")
    for joint in SWING_JOINTS:
        assert 0.5 * no_load < at_12[joint] < no_load
        assert at_10[joint] < at_12[joint]
    assert at_12["shoulder_lift"] < at_12["wrist_flex"]  # the shoulder lifts the most


def test_the_range_ends_where_the_servos_top_speed_does(model):
    nearest, farthest, top = throwing_range(model, BALL)
    _, per_rate = release_state(model, 0.0)
    rate = SPEED_MARGIN * min(joint_speed_limits(model).values())
    assert top == pytest.approx(rate * np.linalg.norm(per_rate))
    assert nearest < 0.3 and 0.6 < farthest < 1.0
    assert throwing_range(model, BALL, 10.0)[1] < farthest


@pytest.mark.parametrize(("cup", "said"), [((0.95, 0.0), "needs a release faster than"),
                                           ((0.1, 0.1), "against the arm's base")])
def test_a_cup_out_of_range_is_refused_with_the_range(model, cup, said):
    with pytest.raises(PlanError) as error:
        plan_throw(model, cup, BALL)
    message = str(error.value)
    assert said in message and "throwing range 0.25-0.90 m" in message and "Fix:" in message


@pytest.mark.parametrize("cup", [(0.3, 0.0), (0.5, 0.3), (0.8, -0.2)])
def test_the_whole_swing_stays_above_the_table(model, cup):
    # the clearance check of the arm's runs (clearance.lowest_point: the arm's parts, the table
    # at the base frame's z = 0): the 70 deg swing's wind-up put the moving jaw 54 mm into it
    from so101_kinematics.clearance import lowest_point

    plan = plan_throw(model, cup, BALL)
    heights = [lowest_point(plan.configuration(f), 0.0)[0] for f in np.linspace(0, 1, 21)]
    assert min(heights) > 0.01

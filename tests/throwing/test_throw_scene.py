"""The throwing scene: the ball held at the object frame, the cup, the drag the model has."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from so101_kinematics.frames import TOOL_SITE
from so101_kinematics.sim.scene import set_initial_pose
from so101_kinematics.throwing.ball import BALLS, flight
from so101_kinematics.throwing.throw_scene import (
    BALL_CONTACT,
    CUP_HEIGHT,
    CUP_INNER_DIAMETER,
    Flight,
    build_throw_model,
    in_cup,
    place_cup,
)

BALL = BALLS["pingpong"]


@pytest.fixture(scope="module")
def model():
    return build_throw_model(BALL)


def _held(m):
    d = mujoco.MjData(m)
    set_initial_pose(d, {"shoulder_pan": 20.0, "shoulder_lift": -60.0, "elbow_flex": -60.0,
                         "wrist_flex": -15.0, "wrist_roll": 0.0, "gripper": 20.0})
    adr = m.joint("ball").qposadr[0]
    d.qpos[adr:adr + 3] = d.site(TOOL_SITE).xpos
    mujoco.mj_forward(m, d)
    return d


def test_the_ball_is_held_at_the_object_frame(model):
    d = _held(model)
    flight_ = Flight(model, d, BALL, float(d.qpos[model.joint("gripper").qposadr[0]]))
    for _ in range(250):  # 1 s
        flight_.step()
    assert flight_.release is None
    assert np.linalg.norm(d.body("ball").xpos - d.site(TOOL_SITE).xpos) < 0.001


def test_the_ball_touches_the_table_and_the_cup_but_not_the_arm(model):
    ball = model.geom("ball")
    for i in range(model.ngeom):
        geom = model.geom(i)
        touches = bool(ball.contype & geom.conaffinity) or bool(geom.contype & ball.conaffinity)
        name = geom.name
        if name == "table" or name.startswith("cup"):
            assert touches, name
        elif name != "ball":
            assert not touches, name
    assert ball.contype == BALL_CONTACT


def test_a_ball_in_the_cup_is_one_inside_its_wall_below_its_rim():
    inner = CUP_INNER_DIAMETER / 2
    assert in_cup([0.5 + inner - 0.001, 0.0, 0.02], (0.5, 0.0), BALL)
    assert not in_cup([0.5 + inner + 0.001, 0.0, 0.02], (0.5, 0.0), BALL)
    assert not in_cup([0.5, 0.0, CUP_HEIGHT + 0.001], (0.5, 0.0), BALL)


def test_the_simulated_flight_has_the_models_drag(model):
    """Launched free, the ball comes down where the model with drag says, not the vacuum's."""
    d = _held(model)
    place_cup(model, d, 0.9, 0.9)  # out of the way
    flight_ = Flight(model, d, BALL, -math.inf)  # free at once
    dof = model.joint("ball").dofadr[0]
    flight_.step()
    d.qvel[dof:dof + 3] = [1.8, 0.0, 1.6]
    d.qvel[dof + 3:dof + 6] = 0.0
    start = flight_.ball_state()
    while flight_.touch is None and d.time < 3.0:
        flight_.step()
    _, touch, touched = flight_.touch
    assert touched == "table"
    dragged = flight(*start, BALL, touch[2])[0]
    vacuum = flight(*start, BALL, touch[2], drag=False)[0]
    assert np.hypot(*(dragged[:2] - touch[:2])) < 0.005
    assert np.hypot(*(vacuum[:2] - touch[:2])) > 0.03

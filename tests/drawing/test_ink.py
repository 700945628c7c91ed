"""The simulator's pen: its tip where the IK puts it, ink only where it presses on the page."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from so101_kinematics.drawing.ink import PEN_TIP_RADIUS, InkRecorder, build_drawing_model
from so101_kinematics.drawing.page import PAGE_THICKNESS, Page, base_to_page
from so101_kinematics.drawing.pen import (
    PEN_MASS,
    PEN_PRELOAD_M,
    PEN_PRESS_M,
    PEN_SPRING,
    PenPose,
    pen_configuration,
    tip_position,
)
from so101_kinematics.drawing.pen_plan import LIFT_M
from so101_kinematics.planning.plans import GRIPPER_CLOSED
from so101_kinematics.sim.scene import set_initial_pose

PAGE = Page()
GRAVITY = 9.81  # [m/s^2]


@pytest.fixture(scope="module")
def model():
    return build_drawing_model(PAGE)


def _arm_at(model, tip):
    d = mujoco.MjData(model)
    cfg = pen_configuration(tip, PenPose())
    set_initial_pose(d, {**cfg, "gripper": GRIPPER_CLOSED})
    return d, cfg


def test_the_models_pen_tip_is_where_the_ik_puts_it(model):
    """MuJoCo's own kinematics of the compiled model against the course's FK."""
    d, cfg = _arm_at(model, (0.22, 0.04, 0.02))
    approach = -d.site("object_frame").xmat.reshape(3, 3)[:, 2]
    lowest = d.geom("pen_tip").xpos + PEN_TIP_RADIUS * approach
    assert lowest == pytest.approx(tip_position(cfg), abs=2e-5)
    assert lowest == pytest.approx([0.22, 0.04, 0.02], abs=2e-5)


def test_the_pen_inks_where_it_presses_with_the_springs_force(model):
    target = np.array([0.2, -0.03, PAGE_THICKNESS - PEN_PRESS_M])
    d, cfg = _arm_at(model, target + [0.0, 0.0, PEN_PRESS_M + LIFT_M])
    recorder = InkRecorder(model, d)
    recorder.run([cfg] * 25, 2)  # 0.2 s lifted above the page: no ink
    assert recorder.touches == []
    pressed = pen_configuration(target, PenPose(), cfg)
    recorder.run([pressed] * 150, 2)  # 1.2 s pressed 2 mm into the page
    ink = recorder.ink()
    assert len(ink) > 100
    # under the tip, within the servos' rest band (a count, 0.088 deg, is 0.4 mm at 0.25 m)
    assert np.abs(ink[-50:, 1:3] - target[:2]).max() < 1.0e-3
    # by hand: the page carries the pen's weight and the spring's push: off its stop (pressed),
    # at least the preload's, at most the preload's and the whole press's
    weight = PEN_MASS * GRAVITY
    low = PEN_SPRING * PEN_PRELOAD_M + weight
    high = PEN_SPRING * (PEN_PRELOAD_M + PEN_PRESS_M) + weight * 1.1  # the tip's 0.5 g too
    assert low < ink[-50:, 3].mean() < high


def test_the_models_page_is_the_page_turned_as_it_lies():
    """The page's box in the compiled model: its corners are the page's, in page millimetres."""
    page = Page("a5", (210.0, 148.0), centre=(0.21, 0.03), yaw=30.0)
    m = build_drawing_model(page)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    geom = d.geom("page")
    half = m.geom("page").size
    corners = [geom.xpos + geom.xmat.reshape(3, 3) @ [sx * half[0], sy * half[1], half[2]]
               for sx in (-1, 1) for sy in (-1, 1)]
    on_page = np.abs(base_to_page(page, np.array(corners)[:, :2]))
    assert on_page == pytest.approx(np.tile([105.0, 74.0], (4, 1)), abs=1e-9)
    assert corners[0][2] == pytest.approx(PAGE_THICKNESS)  # the paper's top

"""Each arm of the two-arm model, driven with the course helpers' call shapes."""

from __future__ import annotations

import inspect

import mujoco
import pytest

import so101_mujoco_utils
from so101_kinematics.constants import HOME_POSE
from so101_kinematics.sim.scene import load_model
from so101_kinematics.two_arms.scene_arm import SceneArm
from so101_kinematics.two_arms.two_arm_scene import arm_bases, build_two_arm_model

START = dict(HOME_POSE, gripper=0.0)
GOAL = {"shoulder_pan": 30.0, "shoulder_lift": -40.0, "elbow_flex": 50.0, "wrist_flex": 60.0,
        "wrist_roll": 10.0, "gripper": 40.0}


@pytest.fixture(scope="module")
def model():
    return build_two_arm_model(arm_bases("facing", 0.46))


@pytest.fixture
def arms(model):
    d = mujoco.MjData(model)
    left, right = (SceneArm(model, base) for base in arm_bases("facing", 0.46))
    left.set_initial_pose(d, START)
    right.set_initial_pose(d, START)
    return d, left, right


def test_an_arm_takes_the_course_scripts_calls_as_they_are_written(model, arms):
    """so101_mujoco_utils' positional calls, with the arm object in place of the module."""
    d, left, _ = arms
    viewer = None
    left.set_initial_pose(d, START)
    left.send_position_command(d, START)
    left.move_to_pose(model, d, viewer, GOAL, 0.5)
    left.hold_position(model, d, viewer, 0.1)
    assert set(left.get_configuration(model, d)) == set(GOAL)
    for name in ("move_to_pose", "hold_position", "get_configuration", "pick_up_block"):
        ours = list(inspect.signature(getattr(SceneArm, name)).parameters)[1:4]
        course = list(inspect.signature(getattr(so101_mujoco_utils, name)).parameters)[:3]
        assert ours[:len(course)] == course[:len(ours)], name


def test_moving_one_arm_leaves_the_other_still(model, arms):
    d, left, right = arms
    still = mujoco.MjData(model)  # the same start, the left arm holding
    for arm in (left, right):
        arm.set_initial_pose(still, START)
    left.move_to_pose(model, d, None, GOAL, 1.0)
    left.hold_position(model, d, None, 0.5)
    left.hold_position(model, still, None, 1.5)
    moved, held = right.get_configuration(model, d), right.get_configuration(model, still)
    assert max(abs(moved[j] - held[j]) for j in held) < 1e-6  # [deg]
    reached = left.get_configuration(model, d)
    assert max(abs(reached[j] - GOAL[j]) for j in GOAL if j != "gripper") < 1.0  # [deg]


def test_an_arm_in_the_two_arm_model_moves_as_the_courses_one_arm(model, arms):
    """The same servo model per arm: the same move ends at the same angles."""
    d, left, _ = arms
    left.move_to_pose(model, d, None, GOAL, 1.0)
    left.hold_position(model, d, None, 0.5)
    one = load_model()
    d_one = mujoco.MjData(one)
    so101_mujoco_utils.set_initial_pose(d_one, START)
    so101_mujoco_utils.move_to_pose(one, d_one, None, GOAL, 1.0)
    so101_mujoco_utils.hold_position(one, d_one, None, 0.5)
    ours = left.get_configuration(model, d)
    course = so101_mujoco_utils.get_configuration(one, d_one)
    assert max(abs(ours[j] - course[j]) for j in GOAL) < 0.05  # [deg]


def test_the_command_is_the_configuration_sent(model, arms):
    d, left, right = arms
    left.send_position_command(d, GOAL)
    command = left.get_command(model, d)
    assert all(command[j] == pytest.approx(GOAL[j]) for j in GOAL)
    assert right.get_command(model, d) == pytest.approx(START)

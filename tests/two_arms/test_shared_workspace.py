"""The shared workspace: every planned path checked, the arms' distance watched in the run."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from so101_kinematics.errors import ClearanceError
from so101_kinematics.ik.call_shapes import get_inverse_kinematics
from so101_kinematics.two_arms.game_board import GameBoard
from so101_kinematics.two_arms.scene_arm import SceneArm
from so101_kinematics.two_arms.shared_workspace import (
    MIN_ARM_DISTANCE,
    ArmDistanceWatch,
    arm_distance,
    check_shared_path,
)
from so101_kinematics.two_arms.two_arm_game import board_zone, park_pose
from so101_kinematics.two_arms.two_arm_scene import (
    arm_bases,
    base_from_world,
    build_two_arm_model,
)

BASES = arm_bases("facing", 0.46)
ZONE = board_zone(GameBoard())
NOWHERE = (5.0, 6.0, 5.0, 6.0)  # a board's area no arm reaches: only the distance rule


@pytest.fixture(scope="module")
def scene():
    m = build_two_arm_model(BASES)
    return m, SceneArm(m, BASES[0]), SceneArm(m, BASES[1])


def _reaching(arm: SceneArm, world_xyz) -> dict[str, float]:
    """The arm's top-down configuration with its object frame at a world point."""
    return dict(get_inverse_kinematics(base_from_world(arm.base, world_xyz)), gripper=0.0)


def _goals(arm: SceneArm, d, cfg) -> np.ndarray:
    arm.send_position_command(d, cfg)
    return d.ctrl[arm.actuators].copy()


def _path_to(m, d, arm: SceneArm, cfg) -> np.ndarray:
    return arm.path(m, d, cfg, 1.0)


def test_a_path_into_the_board_while_the_other_arm_is_there_is_refused(scene):
    m, left, right = scene
    d = mujoco.MjData(m)
    left.set_initial_pose(d, park_pose(left.base))
    other = _goals(right, d, _reaching(right, (0.055, -0.055, 0.05)))  # over square 8
    rows = _path_to(m, d, left, _reaching(left, (-0.055, 0.055, 0.05)))  # to square 0
    with pytest.raises(ClearanceError) as error:
        check_shared_path(m, mujoco.MjData(m), left, right, rows, other, ZONE, "left arm: test")
    message = str(error.value)
    assert "\n" not in message and "both arms would be in the board's area" in message
    assert "Fix: move the right arm out of the board's area first" in message


def test_a_path_that_brings_the_arms_too_close_is_refused(scene):
    m, left, right = scene
    d = mujoco.MjData(m)
    left.set_initial_pose(d, park_pose(left.base))
    other = _goals(right, d, _reaching(right, (0.03, 0.0, 0.05)))
    rows = _path_to(m, d, left, _reaching(left, (-0.01, 0.0, 0.05)))
    with pytest.raises(ClearanceError, match=r"would come -?[\d.]+ mm apart \(at least 20 mm\)"):
        check_shared_path(m, mujoco.MjData(m), left, right, rows, other, NOWHERE, "left arm")


def test_a_path_with_the_other_arm_parked_passes_and_says_how_close(scene):
    m, left, right = scene
    d = mujoco.MjData(m)
    left.set_initial_pose(d, park_pose(left.base))
    other = _goals(right, d, park_pose(right.base))
    rows = _path_to(m, d, left, _reaching(left, (0.055, 0.0, 0.05)))  # the far middle square
    least = check_shared_path(m, mujoco.MjData(m), left, right, rows, other, ZONE, "left arm")
    assert MIN_ARM_DISTANCE <= least


def test_the_distance_is_the_least_over_every_pair_of_the_arms_boxes(scene):
    """The bounding-sphere filter never hides a nearer pair (seeded configurations)."""
    m, left, right = scene
    d = mujoco.MjData(m)
    rng = np.random.default_rng(1)
    for _ in range(10):
        for arm in (left, right):
            d.qpos[arm.qpos_addresses] = rng.uniform(-1.0, 1.0, 6)
        mujoco.mj_kinematics(m, d)
        brute = min(mujoco.mj_geomDistance(m, d, int(a), int(b), 0.1, None)
                    for a in left.geoms for b in right.geoms)
        assert arm_distance(m, d, left.geoms, right.geoms) == pytest.approx(min(brute, 0.1))


def test_the_watch_counts_each_time_the_arms_come_to_touch(scene):
    m, left, right = scene
    d = mujoco.MjData(m)
    watch = ArmDistanceWatch(m, d, (left, right))
    apart = {arm: park_pose(arm.base) for arm in (left, right)}
    touching = {left: _reaching(left, (0.0, 0.0, 0.05)), right: _reaching(right, (0.0, 0.0, 0.05))}
    for poses in (apart, touching, touching, apart, touching):
        for arm, cfg in poses.items():
            arm.set_initial_pose(d, cfg)
        watch.sync()
    assert watch.collisions == 2
    assert watch.least_distance < 0.0

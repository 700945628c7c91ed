"""Assignment 8's ``pick_up_block`` and ``place_block`` as moves, for either backend to run.

The course's recipe, top-down at yaw 0 (``get_inverse_kinematics(position)``):

- picking: above the block (``BLOCK_CLEARANCE`` higher) with the gripper open
  (``BLOCK_GRIPPER_OPEN``) in ``move_to_duration``; down to the block in
  ``BLOCK_STEP_S``; close (``BLOCK_GRIPPER_CLOSED``) in ``BLOCK_STEP_S``; lift
  back above it in ``BLOCK_STEP_S``;
- placing mirrors it: above the target closed, down, open, back up.

Every configuration is solved and the duration checked before the first
move, so a block out of reach or a bad duration stops the call before the arm
moves. The backends (``so101_mujoco_utils.py``, ``so101_utils.py``) run the
moves through their own ``move_to_pose``, with its checks and fault policy.

Example::

    >>> moves = pick_up_moves([0.2, 0.0, 0.014], 2.0)
    >>> [(round(cfg["gripper"]), duration) for cfg, duration in moves]
    [(50, 2.0), (50, 1.0), (5, 1.0), (5, 1.0)]
"""

from __future__ import annotations

from so101_kinematics.ik.call_shapes import get_inverse_kinematics
from so101_kinematics.ik.solver import as_position
from so101_kinematics.inputs import Configuration, check_duration

__all__ = ["pick_up_moves", "place_moves"]

BLOCK_CLEARANCE = 0.03  # [m] above the block (or the target) before going down and after
BLOCK_GRIPPER_OPEN = 50.0  # [0, 100] the opening that clears a 26-28 mm block
BLOCK_GRIPPER_CLOSED = 5.0  # [0, 100] squeezing the block
BLOCK_STEP_S = 1.0  # [s] each of the short moves: down, close or open, up

Move = tuple[Configuration, float]  # (configuration [deg], gripper [0, 100]; duration [s])


def _above_and_at(position) -> tuple[Configuration, Configuration]:
    """(configuration above ``position``, configuration at it), both top-down at yaw 0."""
    x, y, z = as_position(position)
    at = get_inverse_kinematics((x, y, z))
    above = get_inverse_kinematics((x, y, z + BLOCK_CLEARANCE), initial=at)
    return above, at


def _with_gripper(cfg: Configuration, opening: float) -> Configuration:
    """``cfg`` with the gripper at ``opening`` [0, 100]."""
    return dict(cfg, gripper=opening)


def pick_up_moves(block_position, move_to_duration) -> list[Move]:
    """The moves of the course's ``pick_up_block``: above open, down, close, lift.

    Args:
        block_position: the block's centre (x, y, z) [m] in the base frame.
        move_to_duration: [s] of the first move (from wherever the arm is to above the block).

    Returns:
        Four (configuration, duration [s]) pairs.

    Raises:
        UnreachableError: the block, or the point above it, is out of reach.
        KinematicsInputError: a position that is not three numbers [m].
        PlanError: a duration that is not a number of seconds in [0, 600].
    """
    duration = check_duration(move_to_duration, "pick_up_block move_to_duration")
    above, at = _above_and_at(block_position)
    return [(_with_gripper(above, BLOCK_GRIPPER_OPEN), duration),
            (_with_gripper(at, BLOCK_GRIPPER_OPEN), BLOCK_STEP_S),
            (_with_gripper(at, BLOCK_GRIPPER_CLOSED), BLOCK_STEP_S),
            (_with_gripper(above, BLOCK_GRIPPER_CLOSED), BLOCK_STEP_S)]


def place_moves(target_position, move_to_duration) -> list[Move]:
    """The moves of the course's ``place_block``: above closed, down, open, back up.

    Args:
        target_position: where the block's centre goes (x, y, z) [m] in the base frame.
        move_to_duration: [s] of the first move (to above the target).

    Returns:
        Four (configuration, duration [s]) pairs.

    Raises:
        UnreachableError, KinematicsInputError, PlanError: as :func:`pick_up_moves`.
    """
    duration = check_duration(move_to_duration, "place_block move_to_duration")
    above, at = _above_and_at(target_position)
    return [(_with_gripper(above, BLOCK_GRIPPER_CLOSED), duration),
            (_with_gripper(at, BLOCK_GRIPPER_CLOSED), BLOCK_STEP_S),
            (_with_gripper(at, BLOCK_GRIPPER_OPEN), BLOCK_STEP_S),
            (_with_gripper(above, BLOCK_GRIPPER_OPEN), BLOCK_STEP_S)]

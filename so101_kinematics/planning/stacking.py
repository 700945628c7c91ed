"""Stacking blocks (the course's assignment 8): N cubes picked top-down by IK, stacked at one spot.

:func:`stack_plan` turns the blocks' start positions and the stack's (x, y)
into one plan for any backend: for each block in turn the waypoints of
``cartesian_plan`` (approach, grasp, lift, carry, release, retreat, depart),
placed one cube edge higher than the block before; then the open gripper
rises clear of the stack (``clear``) and the arm returns to its initial pose.
Reachability is checked up front (:func:`check_stack_reach`): every level of
the stack and every start must take a top-down grasp.

Heights. Block ``k`` (0 = the bottom one) of the stack has its centre at
``-base_height + (k + 1/2) * CUBE_SIZE`` in the base frame: the table is
``base_height`` below the base frame (the lab's arms stand on a 15 mm mount).
With the model's 26 mm cubes on the table (``base_height`` 0) that is
0.013, 0.039, 0.065 and 0.091 m; the course quotes 0.014, 0.043, 0.071 and
0.100 m (``COURSE_BLOCK_HEIGHTS``: a pitch of about 28.7 mm, where the model's
cube gives 26 mm). The model's wrist_flex limit (95 deg) ends top-down grasps
at about z = 0.08 m in the base frame, so three blocks stack on the table and
four on the 15 mm mount. From the third block on, the approach to a block
comes in higher than ``cartesian_plan``'s 5 cm, so that the open jaws pass
over the stack on their way from the last depart.

Default starts (:data:`DEFAULT_STARTS`, in this order, skipping any closer
than ``CLEARANCE`` to the stack or to a block already chosen): the course's
start and final cube positions (the FK of its two configurations, y = +-0.19
m), then 0.15 m out at +-0.22 m to the side, then on the x axis at 0.28 and
0.14 m. Each block starts turned as its top-down grasp with ``wrist_roll``
near 0 finds it, so its faces are parallel to the jaws.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from so101_kinematics.cli import number, range_help
from so101_kinematics.constants import CUBE_HALF_SIZE, CUBE_SIZE, HOME_POSE
from so101_kinematics.errors import PlanError, UnreachableError
from so101_kinematics.fast_fk import forward_kinematics
from so101_kinematics.frames import ARM_JOINTS
from so101_kinematics.ik.call_shapes import get_inverse_kinematics
from so101_kinematics.ik.geometry import MIN_HEIGHT, POSITION_LIMIT
from so101_kinematics.inputs import check_number
from so101_kinematics.planning.cartesian_plan import (
    APPROACH_HEIGHT,
    CUBE_YAW_RANGE,
    DEFAULT_LIFT_HEIGHT,
    cartesian_plan,
)
from so101_kinematics.planning.motion import Plan, Step

__all__ = [
    "CLEARANCE", "COURSE_BLOCK_HEIGHTS", "LAB_BASE_HEIGHT", "StackPlan", "add_stack_arguments",
    "block_height", "default_starts", "min_target_height", "stack_from_arguments",
    "stack_plan",
]

COURSE_BLOCK_HEIGHTS = (0.014, 0.043, 0.071, 0.100)
"""The course's block centres [m] for the 1st..4th block of a stack (its lab blocks)."""

DEFAULT_BLOCKS = 2
MAX_BLOCKS = 4
"""Most blocks asked for at all; the reach decides how many stack (3 on the table)."""

BASE_HEIGHT_RANGE = (0.0, 0.05)
"""Allowed --base-height [m]: the table from level with the base frame to 5 cm below it."""

LAB_BASE_HEIGHT = 0.015
"""The lab's mount [m]: its arms' base frame is this far above the table."""

CLEARANCE = 0.080
"""Least horizontal distance between two blocks' starts, or a start and the stack [m]:
room for the gripper (about 50 mm wide) coming down beside a stack of four."""

DEFAULT_STARTS = ((0.230, 0.190), (0.229, -0.191), (0.150, 0.220), (0.150, -0.220),
                  (0.280, 0.000), (0.140, 0.000))
"""Candidate default starts (x, y) [m], in order of use (see the module docstring)."""


def table_height(base_height: float = 0.0) -> float:
    """The table top's z in the base frame [m]: ``-base_height``."""
    return -float(base_height)


def resting_height(base_height: float = 0.0) -> float:
    """The centre z [m] of a cube resting on the table, in the base frame."""
    return table_height(base_height) + CUBE_HALF_SIZE


def min_target_height(base_height: float = 0.0) -> float:
    """The IK's lowest accepted target [m] over a table ``base_height`` below the base.

    1 mm under a resting cube's centre: the IK's own default for ``base_height`` 0.
    """
    return MIN_HEIGHT - float(base_height)


def block_height(level: int, base_height: float = 0.0) -> float:
    """Centre z [m] of the stack's block ``level`` (0 = on the table) in the base frame."""
    return table_height(base_height) + (level + 0.5) * CUBE_SIZE


@dataclass
class Block:
    """One block of the stack: where it starts and where it goes.

    Attributes:
        start: centre at the start (x, y, z) [m], resting on the table.
        start_yaw_deg: its turn about the vertical at the start [deg].
        target: centre in the stack (x, y, z) [m].
    """

    start: tuple[float, float, float]
    start_yaw_deg: float
    target: tuple[float, float, float]


@dataclass
class StackPlan:
    """The stacking plan and the blocks it moves (bottom block first)."""

    plan: Plan
    blocks: list[Block] = field(default_factory=list)
    base_height: float = 0.0

    def describe(self) -> str:
        """Where to put the blocks and where they go, for the student [cm]."""
        x, y, _ = self.blocks[0].target
        lines = [f"Stack of {len(self.blocks)} blocks at x = {100 * x:.1f} cm, y = "
                 f"{100 * y:.1f} cm (the table {100 * self.base_height:.1f} cm below the base "
                 "frame). Put the blocks here:"]
        lines += [f"  block {i + 1}: x = {100 * b.start[0]:.1f} cm, y = {100 * b.start[1]:.1f} "
                  f"cm, turned {b.start_yaw_deg:.0f} deg; stacked with its centre at z = "
                  f"{100 * b.target[2]:.1f} cm" for i, b in enumerate(self.blocks)]
        return "\n".join(lines)


def _grasp_yaw(cfg) -> float:
    """The cube yaw [deg] a top-down grasp ``cfg`` takes: the tool x axis's azimuth.

    Only the x axis is read, so the answer does not depend on which way the
    tool frame's z axis points (a cube repeats every 90 deg anyway).
    """
    _, rotation = forward_kinematics({j: cfg[j] for j in ARM_JOINTS})
    return math.degrees(math.atan2(rotation[1, 0], rotation[0, 0]))


def _top_down(position, yaw_deg, base_height):
    """A top-down grasp at ``position`` [m] over a table ``base_height`` [m] below the base."""
    return get_inverse_kinematics(position, approach="down", yaw_deg=yaw_deg,
                                  min_height=min_target_height(base_height))


def check_stack_reach(stack_xy: Sequence[float], blocks: int, base_height: float = 0.0) -> None:
    """Refuse a stack whose levels the arm cannot reach from above, naming the first height.

    Raises:
        PlanError: naming the block, its centre height, the reason and the fix.
    """
    x, y = stack_xy
    for level in range(blocks):
        z = block_height(level, base_height)
        try:
            _top_down((x, y, z), None, base_height)
        except UnreachableError as error:
            reason = str(error).split(" Fix:")[0].rstrip(".")
            most = f"at most {level} block(s) here" if level else "another spot"
            raise PlanError(
                f"--stack {x:g} {y:g} with {blocks} blocks: block {level + 1}'s centre at "
                f"z = {z:.3f} m cannot be reached top-down ({reason}). Fix: {most}, or a "
                "stack nearer the middle of the workspace (docs/workspace.png).") from None


# The arm's rest pose (HOME_POSE: the model's "home" keyframe, where the simulator and the
# virtual arm start and every run returns) holds the gripper forward and down, in front of the
# base: measured from the model's collision boxes there, the gripper and jaws fill the space
# from its object frame back 0.10 m towards the base, 0.035 m to either side, from 0.02 m
# below the object frame up. A stack reaching into it would be knocked over by the return.
REST_GRIPPER_LENGTH = 0.10  # [m] from the rest pose's object frame back towards the base
REST_GRIPPER_HALF_WIDTH = 0.035  # [m]
REST_GRIPPER_BELOW = 0.020  # [m] the jaws' lowest point below the rest pose's object frame
JAW_MARGIN = 0.010  # [m] the open jaws' tips pass this far over the stack's top


def check_rest_pose_clear(stack_xy: Sequence[float], blocks: int,
                          base_height: float = 0.0) -> None:
    """Refuse a stack that reaches into the gripper of the arm's rest pose (see above).

    Raises:
        PlanError: naming the stack's top, the rest pose's gripper and the fix.
    """
    (rx, ry, rz), _ = forward_kinematics({j: HOME_POSE[j] for j in ARM_JOINTS})
    top = table_height(base_height) + blocks * CUBE_SIZE
    if top <= rz - REST_GRIPPER_BELOW:
        return
    radial = np.array([rx, ry]) / math.hypot(rx, ry)
    rel = np.asarray(stack_xy, dtype=float) - [rx, ry]
    along = min(0.0, max(-REST_GRIPPER_LENGTH, float(rel @ radial)))
    distance = float(np.linalg.norm(rel - along * radial))
    if distance < REST_GRIPPER_HALF_WIDTH + CUBE_HALF_SIZE * math.sqrt(2):
        raise PlanError(
            f"--stack {stack_xy[0]:g} {stack_xy[1]:g} with {blocks} blocks: its top at "
            f"z = {top:.3f} m reaches into the gripper of the arm's rest pose (the jaws at "
            f"({rx:.2f}, {ry:.2f}) m, down to z = {rz - REST_GRIPPER_BELOW:.3f} m), where "
            "the run returns at the end. Fix: stack at least 6 cm to the side of the x axis "
            "(e.g. --stack 0.15 0.1), or fewer blocks.")


def default_starts(stack_xy: Sequence[float], blocks: int) -> list[tuple[float, float]]:
    """The first ``blocks`` of ``DEFAULT_STARTS`` ``CLEARANCE`` clear of the stack and each other.

    Raises:
        PlanError: not enough of them are clear of the stack (give --block).
    """
    chosen: list[tuple[float, float]] = []
    for xy in DEFAULT_STARTS:
        if all(math.dist(xy, other) >= CLEARANCE for other in [tuple(stack_xy), *chosen]):
            chosen.append(xy)
        if len(chosen) == blocks:
            return chosen
    raise PlanError(f"--stack {stack_xy[0]:g} {stack_xy[1]:g}: only {len(chosen)} of the "
                    f"default starts are {CLEARANCE * 1e3:.0f} mm clear of it, {blocks} "
                    "needed. Fix: give each block's start with --block X Y.")


def stack_plan(
    stack_xy: Sequence[float],
    blocks: int = DEFAULT_BLOCKS,
    starts: Sequence[Sequence[float]] | None = None,
    *,
    base_height: float = 0.0,
    lift_height: float = DEFAULT_LIFT_HEIGHT,
    move_duration: float = 2.0,
    hold_duration: float = 0.5,
) -> StackPlan:
    """The plan that stacks ``blocks`` cubes at ``stack_xy``, bottom block first.

    Args:
        stack_xy: the stack's centre (x, y) [m] in the base frame.
        blocks: how many (1 to ``MAX_BLOCKS``; the reach decides how many fit).
        starts: each block's start (x, y[, yaw]) [m, deg], resting on the table;
            default :func:`default_starts`, each turned as its grasp finds it.
        base_height: how far the table is below the base frame [m].
        lift_height: lift and carry this high above each pick and place [m].
        move_duration: time of each main move [s] (``cartesian_plan``'s).
        hold_duration: pause after each of the course's configurations [s].

    Returns:
        The plan (steps named ``block1_approach`` ... ``blockN_depart``) and the blocks.

    Raises:
        PlanError: a bad count, height or start; a start too close to another or
            to the stack; a level or waypoint out of reach (UnreachableError).
    """
    if isinstance(blocks, bool) or not isinstance(blocks, int) or not 1 <= blocks <= MAX_BLOCKS:
        raise PlanError(f"--blocks {blocks!r}: give a whole number from 1 to {MAX_BLOCKS}.")
    base_height = check_number(base_height, "--base-height", *BASE_HEIGHT_RANGE, "m")
    x, y = (check_number(v, f"stack {axis}", -POSITION_LIMIT, POSITION_LIMIT, "m")
            for axis, v in zip("xy", stack_xy, strict=True))
    check_stack_reach((x, y), blocks, base_height)
    check_rest_pose_clear((x, y), blocks, base_height)
    if starts is None:
        starts = [(sx, sy, None) for sx, sy in default_starts((x, y), blocks)]
    elif len(starts) != blocks:
        raise PlanError(f"--block was given {len(starts)} time(s) for {blocks} blocks. Fix: one "
                        "--block X Y [YAW] per block, or none for the default starts.")
    checked = _check_starts(starts, (x, y))
    result = StackPlan(Plan(), base_height=base_height)
    stack_yaw = None
    for index, (sx, sy, yaw) in enumerate(checked):
        pick = (sx, sy, resting_height(base_height))
        place = (x, y, block_height(index, base_height))
        try:
            if yaw is None:
                yaw = _grasp_yaw(_top_down(pick, None, base_height))
            part = cartesian_plan(pick, place, cube_yaw_deg=yaw, place_yaw_deg=stack_yaw,
                                  lift_height=lift_height, move_duration=move_duration,
                                  hold_duration=hold_duration,
                                  approach_height=_approach_height(index),
                                  min_height=min_target_height(base_height))
        except UnreachableError as error:
            raise PlanError(f"--stack {x:g} {y:g}, block {index + 1} (start ({sx:g}, {sy:g}) "
                            f"m, stack level z = {place[2]:.3f} m): {error}") from None
        if stack_yaw is None:  # the blocks above turn as the bottom one: a square stack
            stack_yaw = _grasp_yaw(part.configurations()["final_open"])
        result.plan.steps += [Step(f"block{index + 1}_{step.name}", step.configuration,
                                   step.duration, step.hold) for step in part.steps]
        result.plan.return_duration = part.return_duration
        result.blocks.append(Block(pick, float(yaw), place))
    result.plan.steps.append(_clear_step(result, lift_height, move_duration))
    return result


def _approach_height(level: int) -> float:
    """How high above a block's pick the approach comes in [m], with ``level`` blocks stacked.

    ``cartesian_plan``'s 5 cm, or higher: the open jaws (their tips
    ``REST_GRIPPER_BELOW`` under the object frame) pass ``JAW_MARGIN`` over the
    stack's top on the way from the last depart, even from a start near it.
    """
    stack_top_over_pick = level * CUBE_SIZE - CUBE_HALF_SIZE
    return max(APPROACH_HEIGHT, stack_top_over_pick + REST_GRIPPER_BELOW + JAW_MARGIN)


def _clear_step(stack: StackPlan, lift_height: float, move_duration: float) -> Step:
    """The open gripper ``lift_height`` above the top block, before the return to the start.

    The return is a joint-space move to the arm's initial (folded) pose; from
    the last depart (5 cm above the top block) it would sweep the jaws through
    the stack. From this high it passes over it.
    """
    last = stack.plan.steps[-1]
    x, y, z = stack.blocks[-1].target
    try:
        cfg = get_inverse_kinematics((x, y, z + max(lift_height, CUBE_SIZE)), approach=None,
                                     initial=last.configuration,
                                     min_height=min_target_height(stack.base_height))
    except UnreachableError as error:
        raise PlanError(f"Waypoint 'clear' above the stack: {error}") from None
    return Step("clear", cfg, 0.5 * move_duration, 0.0)


def _check_starts(starts, stack_xy) -> list[tuple[float, float, float | None]]:
    """Each start as (x, y, yaw or None), checked: numbers, clear of the stack and each other."""
    checked: list[tuple[float, float, float | None]] = []
    for i, start in enumerate(starts):
        name = f"--block {i + 1}"
        if len(start) not in (2, 3):
            raise PlanError(f"{name}: give X Y [YAW] ([m], [m], [deg]), got {list(start)}.")
        sx, sy = (check_number(v, f"{name} {axis}", -POSITION_LIMIT, POSITION_LIMIT, "m")
                  for axis, v in zip("xy", start[:2], strict=True))
        yaw = start[2] if len(start) == 3 else None
        if yaw is not None:
            yaw = check_number(yaw, f"{name} yaw", *CUBE_YAW_RANGE, "deg")
        for other, what in [(stack_xy, "the stack"),
                            *[(c[:2], f"block {j + 1}") for j, c in enumerate(checked)]]:
            gap = math.dist((sx, sy), other)
            if gap < CLEARANCE:
                raise PlanError(f"{name} ({sx:g}, {sy:g}) m is {gap * 1e3:.0f} mm from {what}; "
                                f"at least {CLEARANCE * 1e3:.0f} mm are needed for the jaws. "
                                "Fix: move it further away.")
        checked.append((sx, sy, yaw))
    return checked


def add_stack_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``--stack X Y``, ``--blocks N``, ``--block X Y [YAW]`` (repeated), ``--base-height``."""
    group = parser.add_argument_group(
        "Stacking (assignment 8)", "stack blocks at one spot, each picked top-down by IK")
    coordinate = (-POSITION_LIMIT, POSITION_LIMIT, "m")
    group.add_argument("--stack", type=number(*coordinate), nargs=2, metavar=("X", "Y"),
                       help="stack the blocks with their centres over (X, Y) [m] in the base "
                       "frame")
    group.add_argument("--blocks", type=int, default=None, metavar="N",
                       help=f"how many blocks, 1 to {MAX_BLOCKS} (default {DEFAULT_BLOCKS}, or "
                       "as many as --block); the reach at each level is checked first")
    group.add_argument("--block", action="append", type=float, nargs="+",
                       metavar="X Y [YAW]", help="a block's start on the table (centre [m], "
                       "yaw [deg]), once per block, bottom block first (default: "
                       "so101_kinematics/planning/stacking.py's DEFAULT_STARTS)")
    low, high = BASE_HEIGHT_RANGE
    group.add_argument("--base-height", type=number(low, high, "m"), default=0.0, metavar="M",
                       help="the table is M below the robot's base frame [m], "
                       f"{range_help(low, high, 'm')} (default 0; the lab's mount: "
                       f"{LAB_BASE_HEIGHT:g})")


def stack_from_arguments(args: argparse.Namespace) -> StackPlan | None:
    """The stacking plan if ``--stack`` was given, else None (see :func:`add_stack_arguments`).

    Raises:
        PlanError: --blocks/--block without --stack, together with another plan, or a
            bad stack (see :func:`stack_plan`).
    """
    blocks, starts = getattr(args, "blocks", None), getattr(args, "block", None)
    if args.stack is None:
        if blocks is not None or starts:
            raise PlanError("--blocks and --block need --stack X Y (where to stack them).")
        return None
    for option in ("plan", "pick", "place"):
        if getattr(args, option, None):
            raise PlanError(f"--stack and --{option} both define the plan; give one of them.")
    if blocks is None:
        blocks = len(starts) if starts else DEFAULT_BLOCKS
    return stack_plan(args.stack, blocks, starts, base_height=args.base_height,
                      lift_height=getattr(args, "lift_height", DEFAULT_LIFT_HEIGHT),
                      move_duration=getattr(args, "move_duration", 2.0),
                      hold_duration=getattr(args, "hold", 0.5))

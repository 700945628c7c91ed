"""The course's pick-and-place from Cartesian cube positions, planned by inverse kinematics.

:func:`cartesian_plan` turns a pick and a place position (and the cube's yaw)
into the same waypoints as ``plans.default_plan()``, each solved by
``so101_inverse_kinematics`` with a top-down grasp; :func:`add_cartesian_arguments`
and :func:`plan_from_arguments` give ``pick_place_sim.py`` and
``pick_place_hw.py`` the same ``--pick/--place`` options.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Mapping

import numpy as np

from so101_kinematics.cli import number, range_help
from so101_kinematics.errors import PlanError, UnreachableError
from so101_kinematics.fast_fk import forward_kinematics
from so101_kinematics.ik.call_shapes import get_inverse_kinematics
from so101_kinematics.ik.geometry import GRIPPER_OPEN, MIN_HEIGHT, POSITION_LIMIT
from so101_kinematics.ik.solver import as_position
from so101_kinematics.inputs import check_number
from so101_kinematics.planning.motion import Plan
from so101_kinematics.planning.plans import (
    FINAL_CONFIGURATION,
    STARTING_CONFIGURATION,
    pick_and_place_plan,
)

__all__ = [
    "APPROACH_HEIGHT", "CUBE_YAW_RANGE", "DEFAULT_LIFT_HEIGHT", "PRE_GRASP_SLIDE",
    "add_cartesian_arguments", "cartesian_plan", "plan_from_arguments",
]

DEFAULT_LIFT_HEIGHT = 0.10
"""Height of the lift and carry waypoints above the pick and place positions [m]."""

LIFT_HEIGHT_RANGE = (0.0, 0.30)
"""Allowed lift height [m]: from none up to 30 cm (the arm's reach decides what is reachable)."""

APPROACH_HEIGHT_RANGE = (0.0, 0.30)
"""Allowed height of approach and depart above pre_grasp and retreat [m]."""

SLIDE_RANGE = (0.0, 0.05)
"""Allowed slide of pre_grasp and retreat off the grasps [m]."""

CUBE_YAW_RANGE = (-180.0, 180.0)
"""Allowed cube yaw [deg] (a cube repeats every 90 deg)."""

APPROACH_HEIGHT = 0.05
"""Height of the approach waypoint above pre_grasp [m]."""

PRE_GRASP_SLIDE = 0.012
"""Offset of pre_grasp and retreat from the grasps along the jaw axis, towards the fixed jaw [m]."""

def _jaw_axis_and_yaw(cfg: Mapping[str, float]) -> tuple[np.ndarray, float]:
    """Jaw-closing axis (the tool's -x: towards the fixed jaw) and its yaw [deg] at a grasp."""
    _, rotation = forward_kinematics(cfg)
    axis = -rotation[:, 0]
    return axis, math.degrees(math.atan2(axis[1], axis[0]))


def cartesian_plan(
    pick_xyz,
    place_xyz,
    cube_yaw_deg: float | None = None,
    lift_height: float = DEFAULT_LIFT_HEIGHT,
    move_duration: float = 2.0,
    hold_duration: float = 0.5,
    place_yaw_deg: float | None = None,
    *,
    approach_height: float = APPROACH_HEIGHT,
    slide: float = PRE_GRASP_SLIDE,
    min_height: float = MIN_HEIGHT,
) -> Plan:
    """The course's pick-and-place plan from the Cartesian pick and place positions.

    The waypoints and timing of ``plans.default_plan()``, each solved
    by IK from the one before it (so the arm stays on one branch):

    - start_open / final_open: top-down grasps at the pick and place positions;
      start_closed / final_closed: the same with the gripper closed;
    - pre_grasp / retreat: the open gripper ``slide`` [m] off the grasp along
      the jaw axis, towards the fixed jaw's side, at the same height: the
      fixed jaw slides onto the cube and backs off it horizontally;
    - approach / depart: ``approach_height`` above pre_grasp / retreat;
    - lift / carry: ``lift_height`` above the pick and place positions.

    Approach, lift, carry and depart are top-down when the arm can reach them so,
    otherwise as close to top-down as it can (position-only IK).

    Args:
        pick_xyz: centre of the cube to pick, (x, y, z) [m] in the base frame.
        place_xyz: where the cube's centre goes [m].
        cube_yaw_deg: the cube's yaw at the pick [deg] (see
            :func:`get_inverse_kinematics`); None keeps wrist_roll near 0, the
            course's grasp.
        lift_height: height of lift and carry above pick and place [m].
        move_duration: time for each main move [s]; the short moves near the
            cube (pre_grasp, start_open, start_closed, final_open, retreat,
            depart) take half of it.
        hold_duration: pause after each of the course's six configurations [s].
        place_yaw_deg: the cube's yaw at the place [deg]; default ``cube_yaw_deg``.
        approach_height: height of approach and depart above pre_grasp and retreat [m].
        slide: horizontal offset of pre_grasp and retreat from the grasps [m].
        min_height: the IK's lowest accepted target [m] (lower it by the mount's
            height when the table is below the base frame: ``stacking.min_target_height``).

    Returns:
        The plan; configurations [deg], gripper [0, 100].

    Raises:
        UnreachableError: a waypoint cannot be reached (the message names it).
        PlanError: a height, slide, yaw or duration outside its
            range (``LIFT_HEIGHT_RANGE``, ``APPROACH_HEIGHT_RANGE``,
            ``SLIDE_RANGE``, ``CUBE_YAW_RANGE``, ``so101_kinematics.inputs.MAX_DURATION``).
        so101_forward_kinematics.KinematicsInputError: a malformed position.

    Example (the FK positions of the course's configurations give its grasps back)::

        >>> plan = cartesian_plan((0.230054, 0.190308, 0.013), (0.229144, -0.191219, 0.013))
        >>> [step.name for step in plan.steps]  # doctest: +NORMALIZE_WHITESPACE
        ['approach', 'pre_grasp', 'start_open', 'start_closed', 'lift', 'carry',
         'final_closed', 'final_open', 'retreat', 'depart']
        >>> {joint: round(value, 2) for joint, value in plan.configurations()["start_open"].items()}
        {'shoulder_pan': -45.0, 'shoulder_lift': 45.0, 'elbow_flex': -45.0, 'wrist_flex': 90.0, \
'wrist_roll': 0.0, 'gripper': 50.0}
    """
    lift_height = check_number(lift_height, "lift_height", *LIFT_HEIGHT_RANGE, "m")
    approach_height = check_number(approach_height, "approach_height", *APPROACH_HEIGHT_RANGE,
                                   "m")
    slide = check_number(slide, "slide", *SLIDE_RANGE, "m")
    for name, value in (("cube_yaw_deg", cube_yaw_deg), ("place_yaw_deg", place_yaw_deg)):
        if value is not None:
            check_number(value, name, *CUBE_YAW_RANGE, "deg")
    if place_yaw_deg is None:
        place_yaw_deg = cube_yaw_deg
    pick = np.array(as_position(pick_xyz))
    place = np.array(as_position(place_xyz))
    up = np.array([0.0, 0.0, 1.0])

    def solve(name, target, yaw, initial, top_down_only=True):
        try:
            try:
                return get_inverse_kinematics(target, approach="down", yaw_deg=yaw, initial=initial,
                                              gripper=GRIPPER_OPEN, min_height=min_height)
            except UnreachableError:
                if top_down_only:
                    raise
                return get_inverse_kinematics(target, approach=None, initial=initial,
                                              gripper=GRIPPER_OPEN, min_height=min_height)
        except UnreachableError as error:
            raise UnreachableError(f"Waypoint '{name}': {error}", error.reason, error.distance,
                                   error.joint) from None

    start_open = solve("start_open", pick, cube_yaw_deg, STARTING_CONFIGURATION)
    final_open = solve("final_open", place, place_yaw_deg,
                       dict(FINAL_CONFIGURATION, wrist_roll=start_open["wrist_roll"]))
    pick_jaw, pick_yaw = _jaw_axis_and_yaw(start_open)
    place_jaw, place_yaw = _jaw_axis_and_yaw(final_open)
    pre_grasp = solve("pre_grasp", pick + slide * pick_jaw, pick_yaw, start_open)
    approach = solve("approach", pick + slide * pick_jaw + approach_height * up, pick_yaw,
                     pre_grasp, top_down_only=False)
    retreat = solve("retreat", place + slide * place_jaw, place_yaw, final_open)
    depart = solve("depart", place + slide * place_jaw + approach_height * up, place_yaw,
                   retreat, top_down_only=False)
    lift = solve("lift", pick + lift_height * up, pick_yaw, start_open, top_down_only=False)
    carry = solve("carry", place + lift_height * up, place_yaw, final_open, top_down_only=False)
    return pick_and_place_plan(approach, pre_grasp, start_open, lift, carry, final_open, retreat,
                               depart, move_duration, hold_duration)


def add_cartesian_arguments(parser: argparse.ArgumentParser, cube_yaw: bool = True) -> None:
    """Add ``--pick X Y Z``, ``--place X Y Z``, ``--lift-height M`` (and ``--cube-yaw DEG``).

    Args:
        parser: the script's parser.
        cube_yaw: also add ``--cube-yaw`` (leave it out if the script has its own,
            with ``default=None``).
    """
    group = parser.add_argument_group(
        "Cartesian pick-and-place", "give the cube's positions instead of joint angles; the "
        "waypoints are computed by inverse kinematics (top-down grasps)")
    coordinate = (-POSITION_LIMIT, POSITION_LIMIT, "m")
    group.add_argument("--pick", type=number(*coordinate), nargs=3, metavar=("X", "Y", "Z"),
                       help="centre of the cube to pick [m] in the base frame (z = 0.013 on "
                       f"the table), each {range_help(*coordinate)}; needs --place")
    group.add_argument("--place", type=number(*coordinate), nargs=3, metavar=("X", "Y", "Z"),
                       help="where to put the cube's centre [m]; needs --pick")
    if cube_yaw:
        group.add_argument("--cube-yaw", type=number(*CUBE_YAW_RANGE, "deg"), default=None,
                           metavar="DEG",
                           help="the cube's yaw in the world [deg], "
                           f"{range_help(*CUBE_YAW_RANGE, 'deg')}; the wrist turns to it "
                           "(default: wrist_roll stays near 0, as in the course's plan)")
    group.add_argument("--lift-height", type=number(*LIFT_HEIGHT_RANGE, "m"),
                       default=DEFAULT_LIFT_HEIGHT, metavar="M",
                       help="lift and carry this high above pick and place [m], "
                       f"{range_help(*LIFT_HEIGHT_RANGE, 'm')} (default %(default)g)")


def plan_from_arguments(args: argparse.Namespace) -> Plan | None:
    """The Cartesian plan if ``--pick`` and ``--place`` were given, else None.

    Reads ``pick``, ``place``, ``cube_yaw``, ``lift_height``, ``move_duration``,
    ``hold`` and ``base_height`` (the table below the base frame [m]: the IK's lowest
    target follows it) from ``args`` (see :func:`add_cartesian_arguments`).

    Raises:
        PlanError: only one of --pick/--place, or together with --plan.
        UnreachableError: a waypoint is out of reach (a PlanError too).
    """
    pick, place = getattr(args, "pick", None), getattr(args, "place", None)
    if pick is None and place is None:
        return None
    if pick is None or place is None:
        raise PlanError("--pick and --place go together: give both cube positions "
                        "(X Y Z [m] each).")
    if getattr(args, "plan", None):
        raise PlanError("--plan and --pick/--place both define the plan; give one of them.")
    return cartesian_plan(pick, place, cube_yaw_deg=getattr(args, "cube_yaw", None),
                          lift_height=getattr(args, "lift_height", DEFAULT_LIFT_HEIGHT),
                          move_duration=getattr(args, "move_duration", 2.0),
                          hold_duration=getattr(args, "hold", 0.5),
                          min_height=MIN_HEIGHT - getattr(args, "base_height", 0.0))

"""The virtual arm's cubes, checked on the parent's side: where each rests, how low the table is."""

from __future__ import annotations

import math

from so101_kinematics.constants import CUBE_SIZE
from so101_kinematics.errors import CubePositionError
from so101_kinematics.inputs import check_number
from so101_kinematics.sensors.cube_wire import MAX_CUBES

__all__ = ["CUBE_REACH_M", "check_base_height", "check_cube_position", "check_cubes",
           "check_target_position"]

CUBE_REACH_M = 0.5  # a cube is placed within this of the base, on the table [m]
BASE_HEIGHT_RANGE_M = (0.0, 0.05)  # the table below the base frame [m] (the lab's mount: 0.015)


def check_cube_position(cube) -> tuple[float, float, float]:
    """(x, y[, yaw]) of a cube on the table, checked: on the table top, finite numbers.

    Raises:
        CubePositionError: naming the value, the allowed range and the fix.
    """
    if len(cube) not in (2, 3):
        raise CubePositionError(f"A cube position is X Y [YAW], got {cube!r}.")
    x = check_number(cube[0], "cube x", -CUBE_REACH_M, CUBE_REACH_M, "m", error=CubePositionError)
    y = check_number(cube[1], "cube y", -CUBE_REACH_M, CUBE_REACH_M, "m", error=CubePositionError)
    yaw = check_number(cube[2] if len(cube) == 3 else 0.0, "cube yaw", -180.0, 180.0, "deg",
                       error=CubePositionError)
    return x, y, yaw


def check_target_position(target) -> tuple[float, float, float]:
    """(x, y[, yaw]) of the target tag on the table, checked as a cube's (``--target``).

    Raises:
        CubePositionError: naming the value, the allowed range and the fix.
    """
    if len(target) not in (2, 3):
        raise CubePositionError(f"The target tag's position is X Y [YAW], got {target!r}.")
    x = check_number(target[0], "target x", -CUBE_REACH_M, CUBE_REACH_M, "m",
                     error=CubePositionError)
    y = check_number(target[1], "target y", -CUBE_REACH_M, CUBE_REACH_M, "m",
                     error=CubePositionError)
    yaw = check_number(target[2] if len(target) == 3 else 0.0, "target yaw", -180.0, 180.0,
                       "deg", error=CubePositionError)
    return x, y, yaw


def check_cubes(cube) -> list[tuple[float, float, float]]:
    """One cube (x, y[, yaw]) or a list of them, each checked; at most ``MAX_CUBES``.

    Raises:
        CubePositionError: a bad position, too many cubes, or two cubes whose centres
            are closer than a cube's size (they would overlap: the physics pushes them apart).
    """
    if cube is None:
        return []
    cubes = [cube] if len(cube) and not hasattr(cube[0], "__len__") else list(cube)
    if len(cubes) > MAX_CUBES:
        raise CubePositionError(f"{len(cubes)} cubes: the virtual table takes at most "
                                f"{MAX_CUBES}. Fix: give fewer --cube options.")
    checked = [check_cube_position(c) for c in cubes]
    for second, (x2, y2, _) in enumerate(checked):
        for first, (x1, y1, _) in enumerate(checked[:second]):
            apart = math.hypot(x2 - x1, y2 - y1)
            if apart < CUBE_SIZE:
                raise CubePositionError(
                    f"cube {second + 1} at ({x2:g}, {y2:g}) m is {apart * 1e3:.1f} mm from cube "
                    f"{first + 1} at ({x1:g}, {y1:g}) m: cubes closer than their size "
                    f"({CUBE_SIZE * 1e3:g} mm) overlap. Fix: put their centres at least "
                    f"{CUBE_SIZE * 1e3:g} mm apart.")
    return checked


def check_base_height(value) -> float:
    """The table's depth below the base frame [m], checked (``BASE_HEIGHT_RANGE_M``)."""
    return check_number(value, "--base-height", *BASE_HEIGHT_RANGE_M, "m",
                        error=CubePositionError)

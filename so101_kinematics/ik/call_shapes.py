"""The IK's public entry point: the course's call shapes and the package's keywords.

The course's assignments call the IK three ways, all accepted here:

- ``get_inverse_kinematics(position)``: a top-down grasp at yaw 0 (its
  hardware example);
- ``get_inverse_kinematics(position, orientation)``: a 3x3 rotation of the
  object frame, ``np.eye(3)`` for a top-down grasp at yaw 0 (its IK test);
- ``get_inverse_kinematics(position, yaw, pitch)``: angles in radians, as the
  course draws them (``yaw`` in [0, pi/2]).

In the course's convention (``so101_forward_kinematics``) a top-down grasp
has the object frame ``Rz(yaw)``, z up; ``wrist_roll = shoulder_pan`` gives
yaw 0 up to the gripper mount's tilt: ``yaw = wrist_roll - shoulder_pan +
GRIPPER_MOUNT_TILT_DEG`` (-2.79 deg). These shapes ask for the frame's yaw
itself: the grasp with exactly that yaw is tried first, the cube's other
three grasps (90 deg apart, the same cube) only if its wrist_roll is beyond
the joint's limits. The keywords (``approach``, ``yaw_deg``, ``pitch_deg``)
are the package's, in degrees; ``yaw_deg`` there is the cube's yaw (any of
the four grasps, the wrist_roll nearest the reference's first).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping

import numpy as np

from so101_kinematics.errors import KinematicsInputError, KinematicsTypeError, UnreachableError
from so101_kinematics.fast_fk import forward_kinematics
from so101_kinematics.ik.geometry import MIN_HEIGHT
from so101_kinematics.ik.solver import solve_keywords
from so101_kinematics.inputs import describe_value

__all__ = ["_as_rotation", "get_inverse_kinematics"]

TOP_DOWN_TOL_DEG = 0.5
"""Largest tilt of an orientation's z axis from the vertical still taken as top-down [deg]."""

ORIENTATION_TOL_DEG = 1.0
"""Largest angle between an asked and a reached non-top-down orientation [deg]."""

_UNSET = object()


def get_inverse_kinematics(position, orientation=None, pitch=None, *, approach=_UNSET,
                           yaw_deg=_UNSET, pitch_deg=None,
                           initial: Mapping[str, float] | None = None,
                           gripper: float | None = None, min_height: float = MIN_HEIGHT,
                           viewer=None) -> dict[str, float]:
    """Joint configuration [deg] that puts the object frame at ``position``.

    Args:
        position: the object frame's (the held cube's centre) target (x, y, z)
            [m] in the base frame; a cube resting on the table has z = 0.013
            (the course's examples use 0.014).
        orientation: the course's second argument: a 3x3 rotation of the
            object frame (top-down: ``Rz(yaw)``; a tilted one only if the arm
            can reach it, see below), or the yaw [rad] with ``pitch``. None: a
            top-down grasp at yaw 0 (unless keywords say otherwise).
        pitch: with a yaw, the approach's tilt from the vertical [rad]: 0 is
            top-down, pi/2 horizontal, positive tilting the fingertips away
            from the base.
        approach: keyword form: "down", "pitch" (with ``pitch_deg``: the
            approach's angle below the horizontal, 90 = top-down) or None
            (position only).
        yaw_deg: keyword form: the cube's yaw [deg] (every 90 deg the same
            cube); None: any yaw.
        pitch_deg: keyword form, with ``approach="pitch"`` [deg].
        initial: a configuration [deg] to stay near (picks the branch).
        gripper: the result's gripper opening [0, 100].
        min_height: lowest target z accepted [m].
        viewer: accepted for the course's scripts, which pass theirs; unused.

    Returns:
        The five arm joints [deg] and ``gripper`` [0, 100].

    Raises:
        UnreachableError: out of reach or beyond a joint limit (says which and how far);
            an orientation the five joints cannot take (says how far the nearest is).
        KinematicsInputError: malformed arguments (one line: which, the value, the fix);
            :class:`KinematicsTypeError` for text, None or booleans where numbers belong.

    Examples (the course's targets; a cube on the table has its centre 14 mm up)::

        >>> import numpy as np
        >>> cfg = get_inverse_kinematics([0.2, 0.2, 0.014], np.eye(3))
        >>> round(cfg["wrist_roll"] - cfg["shoulder_pan"], 2)  # yaw 0: roll = pan + 2.79 deg tilt
        2.79
        >>> cfg = get_inverse_kinematics([0.2, 0.0, 0.014])  # position alone: top-down, yaw 0
        >>> round(cfg["wrist_flex"] + cfg["shoulder_lift"] + cfg["elbow_flex"], 6)  # vertical
        90.0
        >>> cfg = get_inverse_kinematics([0.2, 0.1, 0.014], np.pi / 4, 0.0)  # yaw [rad], pitch
        >>> _, rotation = forward_kinematics(cfg)  # Rz(45 deg), z up
        >>> rotation.round(4) + 0.0
        array([[ 0.7071, -0.7071,  0.    ],
               [ 0.7071,  0.7071,  0.    ],
               [ 0.    ,  0.    ,  1.    ]])
    """
    del viewer
    if orientation is not None and hasattr(orientation, "user_scn"):
        orientation = None  # the course's first IK stub passes its viewer second
    keywords = approach is not _UNSET or yaw_deg is not _UNSET or pitch_deg is not None
    if orientation is None and pitch is None:
        if not keywords:
            return solve_keywords(position, "down", 0.0, initial=initial, gripper=gripper,
                                  min_height=min_height, exact_yaw=True)
        return solve_keywords(position, "down" if approach is _UNSET else approach,
                              0.0 if yaw_deg is _UNSET else yaw_deg, pitch_deg, initial,
                              gripper=gripper, min_height=min_height)
    if keywords:
        raise KinematicsInputError(
            "get_inverse_kinematics got an orientation both positionally and by keyword "
            "(approach, yaw_deg or pitch_deg). Fix: use one form: (position, orientation) or "
            "(position, yaw, pitch) as the course does, or the keywords.")
    if isinstance(orientation, str):
        fix = (f"pass the approach by keyword: approach={orientation!r}"
               if orientation in ("down", "pitch") else "pass a rotation or a yaw [rad], or the "
               "approach by keyword: approach='down' (with yaw_deg) or approach='pitch' (with "
               "pitch_deg)")
        raise KinematicsTypeError(
            f"The second argument is the object frame's orientation (a 3x3 rotation) or its yaw "
            f"[rad], got {orientation!r}. Fix: {fix}.")
    solve = dict(initial=initial, gripper=gripper, min_height=min_height)
    if _is_matrix(orientation):
        if pitch is not None:
            raise KinematicsInputError(
                f"pitch = {describe_value(pitch)} given with a rotation matrix, which already "
                "fixes the pitch. Fix: pass (position, rotation) or (position, yaw, pitch).")
        return _solve_rotation(position, _as_rotation(orientation), solve)
    yaw = _as_radians("yaw", 0.0 if orientation is None else orientation, math.tau)
    tilt = _as_radians("pitch", 0.0 if pitch is None else pitch, math.pi / 2)
    if tilt == 0.0:
        return solve_keywords(position, "down", math.degrees(yaw), exact_yaw=True, **solve)
    return solve_keywords(position, "pitch", math.degrees(yaw), 90.0 - math.degrees(tilt),
                          exact_yaw=True, **solve)


def _is_matrix(value) -> bool:
    """Whether ``value`` looks like a matrix (anything with rows), not a number."""
    if isinstance(value, (numbers.Real, np.generic)) or value is None:
        return False
    return np.ndim(np.asarray(value, dtype=object)) >= 1


def _as_rotation(value) -> np.ndarray:
    """``value`` as a (3, 3) rotation matrix (orthonormal to 1e-6, determinant +1)."""
    try:
        rotation = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise KinematicsTypeError(
            f"orientation must be a 3x3 rotation matrix of numbers, got "
            f"{describe_value(value)}. Fix: pass e.g. np.eye(3).") from None
    if rotation.shape != (3, 3):
        raise KinematicsInputError(
            f"orientation must be a 3x3 rotation matrix, got shape {rotation.shape}. Fix: pass "
            "e.g. np.eye(3) (a top-down grasp at yaw 0) or Rz(yaw).")
    if not np.isfinite(rotation).all():
        raise KinematicsInputError("orientation holds NaN or an infinity. Fix: pass a finite "
                                   "3x3 rotation matrix.")
    error = float(np.abs(rotation.T @ rotation - np.eye(3)).max())
    if error > 1e-6 or np.linalg.det(rotation) < 0.0:
        raise KinematicsInputError(
            f"orientation is not a rotation matrix (R^T R differs from I by {error:.2g}, "
            f"det = {np.linalg.det(rotation):.3g}; allowed 1e-6 and +1). Fix: build it from "
            "rotations, e.g. Rz(yaw), or orthonormalise it.")
    return rotation


def _as_radians(name: str, value, limit: float) -> float:
    """A positional angle [rad] of the course's shape, within +-``limit``."""
    if isinstance(value, (str, bytes, bool, np.bool_)) or not isinstance(
            value, (numbers.Real, np.generic)):
        raise KinematicsTypeError(
            f"{name} must be a number of radians, got {describe_value(value)}. Fix: pass a "
            f"float, e.g. np.pi / 4, or {name}_deg= in degrees.")
    value = float(value)
    if not -limit <= value <= limit:  # also false for NaN
        raise KinematicsInputError(
            f"{name} = {value:g} rad is outside [{-limit:.4g}, {limit:.4g}] rad (the course's "
            f"positional angles are radians). Fix: convert degrees with np.radians, or pass "
            f"{name}_deg= by keyword.")
    return value


def _solve_rotation(position, rotation: np.ndarray, solve: dict) -> dict[str, float]:
    """Solve for a rotation: top-down by its yaw, else by its pitch, then checked whole."""
    z_axis = rotation[:, 2]
    tilt = math.degrees(math.acos(min(1.0, max(-1.0, float(z_axis[2])))))
    if tilt <= TOP_DOWN_TOL_DEG:
        # The yaw of the frame's x axis about the vertical (exact when z is vertical).
        x_axis = rotation[:, 0] - rotation[2, 0] * z_axis
        yaw = math.degrees(math.atan2(x_axis[1], x_axis[0]))
        return solve_keywords(position, "down", yaw, exact_yaw=True, **solve)
    # The approach (the frame's -z) points 90 - tilt below the horizontal.
    pitch_deg = 90.0 - tilt
    # The pitch mode's yaw is that of the top-down grasp it tilts: start from the x axis's
    # level direction and correct by the remaining turn about the tool's z (converges in 2-3).
    yaw = math.degrees(math.atan2(rotation[1, 0], rotation[0, 0]))
    for _ in range(6):
        try:
            cfg = solve_keywords(position, "pitch", math.remainder(yaw, 360.0), pitch_deg,
                                 exact_yaw=True, **solve)
        except UnreachableError as error:
            raise UnreachableError(
                f"orientation tilts the approach {tilt:.1f} deg from the vertical "
                f"({pitch_deg:.1f} deg below the horizontal): {error}", error.reason,
                error.distance, error.joint) from None
        _, reached = forward_kinematics(cfg)
        relative = reached.T @ rotation
        cos = (float(np.trace(relative)) - 1.0) / 2.0
        off = math.degrees(math.acos(min(1.0, max(-1.0, cos))))
        turn = math.degrees(math.atan2(relative[1, 0], relative[0, 0]))
        if off < 1e-7 or abs(turn) < 1e-9:
            break
        yaw += turn
    if off > ORIENTATION_TOL_DEG:
        raise UnreachableError(
            f"orientation is not one the arm's five joints can take at {list(position)}: the "
            f"nearest reachable with its pitch ({pitch_deg:.1f} deg below the horizontal) is "
            f"{off:.1f} deg away (allowed {ORIENTATION_TOL_DEG:g}); a tilted approach must lie "
            "in the arm's vertical plane. Fix: pass a top-down orientation Rz(yaw), or "
            "(position, yaw, pitch).", "orientation", off)
    return cfg

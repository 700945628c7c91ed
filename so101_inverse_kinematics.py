"""Inverse kinematics of the SO-101 arm for the object frame of the FK module.

The SO-101 has five arm joints, so a full 6-D pose of the object frame ``t``
(the centre of a held 26 mm cube; at a top-down grasp ``Rz(yaw)``, z up, as
the course draws it; see ``so101_forward_kinematics``) is reachable only on a
5-D subset. :func:`get_inverse_kinematics` takes the course's call shapes:

- ``get_inverse_kinematics(position)``: a top-down grasp at yaw 0;
- ``get_inverse_kinematics(position, orientation)``: a 3x3 rotation,
  ``np.eye(3)`` for a top-down grasp at yaw 0, ``Rz(yaw)`` for another yaw (a
  tilted orientation only where the five joints can take it);
- ``get_inverse_kinematics(position, yaw, pitch)``: radians, as the course
  passes them; pitch is the approach's tilt from the vertical (0 top-down);

and the package's keywords (degrees): ``approach="down"`` with ``yaw_deg``
(the cube's yaw, any of its four grasps), ``approach="pitch"`` with
``pitch_deg`` (below the horizontal, 90 top-down), ``approach=None``
(position only: the wrist keeps its roll, the pitch stays near the
reference's), plus ``initial``, ``gripper`` and ``min_height``.

At a top-down grasp the frame's yaw is ``wrist_roll - shoulder_pan +
GRIPPER_MOUNT_TILT_DEG``: the course's ``wrist_roll = shoulder_pan`` for yaw 0
is right up to the gripper mount's -2.79 deg tilt, which this IK includes
(``wrist_roll = shoulder_pan + 2.79 deg``).

Closed form, derived from the exact model numbers of ``so101_kinematics/frames.py``.
Shoulder_lift, elbow_flex and wrist_flex turn about parallel horizontal
axes, so after shoulder_pan the arm is a planar three-link chain, offset
sideways from the pan axis:

- sideways (along the lift axis) the object frame sits
  ``L = -0.0182778 + 0.0181 + 0.0051 sin(alpha) - 0.000218 cos(alpha)`` [m]
  from the pan axis (shoulder and wrist offsets, and the part of the tool
  offset that turns with the roll), ``alpha = wrist_roll +
  GRIPPER_MOUNT_TILT_DEG``. So ``shoulder_pan = asin(L / r) - azimuth``, r the
  horizontal distance of the target from the pan axis; the mirrored
  solution ``pi - asin(L / r) - azimuth`` reaches backwards over the base;
- the approach pitch below the horizontal is ``psi = shoulder_lift +
  elbow_flex + wrist_flex``; with ``psi = 90 deg`` the frame's yaw is
  ``alpha - shoulder_pan`` (a cube repeats every 90 deg);
- in the arm's plane the object frame is the wrist_flex axis plus
  ``0.0611 + 0.1075`` m along the approach and ``-(0.0051 cos(alpha) +
  0.000218 sin(alpha))`` m across it; the wrist_flex axis is reached by two
  kinked links (``(-0.11257, -0.028)`` and ``(-0.1349, 0.0052)`` m in their
  joint frames): the law of cosines, elbow-up and elbow-down branches.

A given yaw ties ``alpha`` to ``shoulder_pan`` and ``L`` to ``alpha``: a scalar
equation solved by Newton's method in two or three steps. Every result is
checked with the FK; if it is off by more than ``REFINE_TOL`` (it is
normally off by ~1e-16) it is refined by damped least squares on the
analytic Jacobian (:func:`get_jacobian`), which also finishes position-only
targets the closed-form search misses. The solver lives in
``so101_kinematics/ik/`` (geometry, the closed-form search, refinement, the
course's call shapes); this file is what the course's scripts import.

Angles are degrees at this module's boundary (configuration dicts, as the
course's), radians inside. Example (the course's starting position)::

    >>> cfg = get_inverse_kinematics((0.230054, 0.190308, 0.013), yaw_deg=None)
    >>> {joint: round(value, 2) for joint, value in cfg.items()}  # [deg], gripper [0, 100]
    {'shoulder_pan': -45.0, 'shoulder_lift': 45.0, 'elbow_flex': -45.0, 'wrist_flex': 90.0, \
'wrist_roll': 0.0, 'gripper': 50.0}
"""


from __future__ import annotations

import numpy as np

from so101_forward_kinematics import get_g5t, get_g45
from so101_kinematics.constants import CUBE_HALF_SIZE  # noqa: F401 - the course's names
from so101_kinematics.errors import UnreachableError  # noqa: F401
from so101_kinematics.frames import (  # noqa: F401
    GRIPPER_MOUNT_TILT_DEG,
    JOINT_LIMITS,
    JOINT_RANGES_RAD,
)
from so101_kinematics.ik.call_shapes import _as_rotation as as_rotation
from so101_kinematics.ik.call_shapes import get_inverse_kinematics  # noqa: F401
from so101_kinematics.ik.geometry import (  # noqa: F401
    GRIPPER_OPEN,
    MIN_HEIGHT,
    PAN_AXIS_POINT,
    POSITION_LIMIT,
    REFERENCE_CONFIGURATION,
    REFINE_TOL,
    SOLVE_TOL,
    get_jacobian,
)
from so101_kinematics.ik.solver import as_position, sample_top_down_targets  # noqa: F401


def get_wrist_flex_position(target_position, target_orientation=None):
    """Assignment 7's step 1c: the wrist_flex frame (4) that puts the object frame at the target.

    ``g_w4 = g_wt g_4t^-1`` with ``g_4t = g_45(0) g_5t`` (wrist_roll at 0), the
    factors of ``so101_forward_kinematics``: frame 4 sits on the wrist_flex
    axis, so its position is the wrist point the shoulder and elbow must reach.

    Args:
        target_position: the object frame's position (x, y, z) [m] in the base frame.
        target_orientation: its 3x3 rotation; None: top-down at yaw 0 (the identity).

    Returns:
        (position (3,) [m], rotation (3, 3)) of frame 4 in the world frame.

    Example (top-down: the wrist_flex axis 0.0611 + 0.1075 m above the target,
    frame 4's origin on it, 18 mm to the side of the object frame)::

        >>> position, rotation = get_wrist_flex_position([0.2, 0.0, 0.014])
        >>> [round(float(v), 4) for v in position]  # [m]
        [0.1958, -0.0179, 0.1826]
    """
    g_wt = np.eye(4)
    g_wt[:3, 3] = as_position(target_position)
    if target_orientation is not None:
        g_wt[:3, :3] = as_rotation(target_orientation)
    g_4t = get_g45(0.0) @ get_g5t()
    g_w4 = g_wt @ np.linalg.inv(g_4t)
    return g_w4[:3, 3].copy(), g_w4[:3, :3].copy()

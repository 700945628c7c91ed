"""Inverse kinematics of the SO-101 arm for the object frame of the FK module (assignment 7).

The course's files at the root are the project's one facade; ``so101_kinematics`` does the work.

Five arm joints reach a full 6-D pose of the object frame ``t`` only on a 5-D subset.
:func:`get_inverse_kinematics` takes the course's call shapes: ``(position)`` (top-down, yaw
0), ``(position, orientation)`` (a 3x3 rotation, ``Rz(yaw)`` for a top-down grasp) and
``(position, yaw, pitch)`` (radians, pitch 0 top-down); and the package's keywords in degrees
(``approach="down"`` with ``yaw_deg``, ``approach="pitch"`` with ``pitch_deg``, ``approach=None``
for position only, ``initial``, ``gripper``, ``min_height``).

The geometric steps, closed form on the model's numbers (``so101_kinematics/ik/``):

1. shoulder_lift, elbow_flex and wrist_flex turn about parallel horizontal axes, so after
   shoulder_pan the arm is a planar three-link chain, offset sideways from the pan axis by
   ``L = -0.0182778 + 0.0181 + 0.0051 sin(alpha) - 0.000218 cos(alpha)`` [m], ``alpha =
   wrist_roll + GRIPPER_MOUNT_TILT_DEG``: ``shoulder_pan = asin(L / r) - azimuth`` (r the
   target's horizontal distance from the pan axis; ``pi - asin(L / r) - azimuth`` reaches
   backwards over the base);
2. the approach pitch below the horizontal is ``psi = shoulder_lift + elbow_flex +
   wrist_flex``; top-down (``psi = 90 deg``) the frame's yaw is ``alpha - shoulder_pan``;
3. in the arm's plane the wrist_flex axis (:func:`get_wrist_flex_position`) is ``0.0611 +
   0.1075`` m back along the approach from the target and ``0.0051 cos(alpha) + 0.000218
   sin(alpha)`` m across it; two kinked links (``(-0.11257, -0.028)`` and ``(-0.1349,
   0.0052)`` m in their joint frames) reach it by the law of cosines, elbow up or down;
4. a given yaw ties ``alpha`` to ``shoulder_pan``: a scalar equation, two or three Newton steps.
   Every result is checked with the FK and, if off by more than ``REFINE_TOL``, refined by
   damped least squares on the analytic Jacobian.

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
from so101_kinematics.errors import UnreachableError  # noqa: F401 - what the IK raises
from so101_kinematics.ik.call_shapes import _as_rotation as as_rotation
from so101_kinematics.ik.call_shapes import get_inverse_kinematics  # noqa: F401 - the course's
from so101_kinematics.ik.geometry import GRIPPER_OPEN  # noqa: F401 - the course's 50
from so101_kinematics.ik.solver import as_position


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

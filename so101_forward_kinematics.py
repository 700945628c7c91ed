"""Forward kinematics of the SO-101 arm as a product of rigid transforms (the course's part 1a).

The course's files at the root are the project's one facade; ``so101_kinematics`` does the work.

``g_ab`` is the pose of frame ``b`` in frame ``a`` (a 4x4 homogeneous matrix); poses chain by
multiplication, ``g_ac = g_ab @ g_bc``. Frames: ``w`` the world (the base, z up), ``1`` to ``5``
the bodies turned by shoulder_pan, shoulder_lift, elbow_flex, wrist_flex and wrist_roll (each
about its local z), ``t`` the object frame: the centre of a 26 mm cube held between the jaws
(site ``object_frame`` in ``model/so101.xml``). Each ``get_gxx`` is the upstream model's fixed
displacement and rotation (``so101_kinematics/frames.py``) times the joint's ``Rz(theta)``,
angles in degrees. At a top-down grasp ``g_wt`` is ``Rz(yaw)``, z up, with ``yaw = wrist_roll -
shoulder_pan + GRIPPER_MOUNT_TILT_DEG`` (the model's gripper mount is turned -2.79 deg).

Example (the course's test configuration)::

    >>> position, rotation = get_forward_kinematics({
    ...     "shoulder_pan": -45.0, "shoulder_lift": 45.0, "elbow_flex": -45.0,
    ...     "wrist_flex": 90.0, "wrist_roll": 0.0})
    >>> position.round(4)  # [m]; the cube centre, 13 mm above the table
    array([0.2301, 0.1903, 0.013 ])
    >>> rotation.round(4) + 0.0  # Rz(42.21 deg): yaw = wrist_roll - shoulder_pan - 2.79 deg
    array([[ 0.7407, -0.6719,  0.    ],
           [ 0.6719,  0.7407,  0.    ],
           [ 0.    ,  0.    ,  1.    ]])
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from so101_kinematics.errors import KinematicsInputError  # noqa: F401 - what the getters raise
from so101_kinematics.fast_fk import forward_kinematics_batch
from so101_kinematics.frames import (  # noqa: F401 - JOINTS, ARM_JOINTS, TOOL_SITE: the course's
    ARM_JOINTS,
    JOINTS,
    TOOL_SITE,
    check_angle,
    joint_transform,
    read_angles,
)


def get_gw1(theta1_deg: float) -> np.ndarray:
    """Pose of frame 1 (shoulder) in the world, shoulder_pan = ``theta1_deg`` [deg].

    Raises:
        KinematicsInputError: the angle is not a finite number in ``ANGLE_RANGE_DEG``
            (a :class:`KinematicsTypeError` for text, None or a boolean).
    """
    return joint_transform("w1", check_angle(theta1_deg, "shoulder_pan"))


def get_g12(theta2_deg: float) -> np.ndarray:
    """Pose of frame 2 (upper arm) in frame 1, shoulder_lift = ``theta2_deg`` [deg]."""
    return joint_transform("12", check_angle(theta2_deg, "shoulder_lift"))


def get_g23(theta3_deg: float) -> np.ndarray:
    """Pose of frame 3 (lower arm) in frame 2, elbow_flex = ``theta3_deg`` [deg]."""
    return joint_transform("23", check_angle(theta3_deg, "elbow_flex"))


def get_g34(theta4_deg: float) -> np.ndarray:
    """Pose of frame 4 (wrist) in frame 3, wrist_flex = ``theta4_deg`` [deg]."""
    return joint_transform("34", check_angle(theta4_deg, "wrist_flex"))


def get_g45(theta5_deg: float) -> np.ndarray:
    """Pose of frame 5 (gripper) in frame 4, wrist_roll = ``theta5_deg`` [deg].

    The fixed rotation keeps the gripper mount's tilt of about -2.79 deg
    (``GRIPPER_MOUNT_TILT_DEG``) exactly as the upstream model has it.
    """
    return joint_transform("45", check_angle(theta5_deg, "wrist_roll"))


def get_g5t() -> np.ndarray:
    """Pose of the object frame t in frame 5 (fixed: the gripper joint does not move it)."""
    return joint_transform("5t", 0.0)


def get_forward_kinematics(position_dict: Mapping[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """Object-frame pose in the world: the product of the six factors, as the course writes it.

    Args:
        position_dict: joint name -> angle [deg]. The five arm joints are
            required; ``gripper`` (and any other key) is ignored.

    Returns:
        ``(position, rotation)``: (3,) position [m] and (3, 3) rotation of the
        object frame in the world (``g_wt``).

    Raises:
        KinematicsInputError: a joint is missing or not a finite number in
            ``ANGLE_RANGE_DEG`` (see :func:`joint_angles`).
    """
    read_angles(position_dict)  # a clear error for a missing or malformed joint
    gw1 = get_gw1(position_dict['shoulder_pan'])
    g12 = get_g12(position_dict['shoulder_lift'])
    g23 = get_g23(position_dict['elbow_flex'])
    g34 = get_g34(position_dict['wrist_flex'])
    g45 = get_g45(position_dict['wrist_roll'])
    g5t = get_g5t()
    gwt = gw1 @ g12 @ g23 @ g34 @ g45 @ g5t
    position = gwt[0:3, 3]
    rotation = gwt[0:3, 0:3]
    return position, rotation


def get_forward_kinematics_batch(angles_deg, chunk: int = 8192) -> tuple[np.ndarray, np.ndarray]:
    """Object-frame poses of many configurations at once (see ``fast_fk.forward_kinematics_batch``).

    Args:
        angles_deg: (N, 5) joint angles [deg] in ``ARM_JOINTS`` order.
        chunk: configurations per vectorised block.

    Returns:
        ``(positions, rotations)``: (N, 3) [m] and (N, 3, 3).
    """
    return forward_kinematics_batch(angles_deg, chunk)

"""Forward kinematics of the SO-101 arm as a product of rigid transforms.

Frame convention, used in every name of this module:
    ``g_ab`` is the pose of frame ``b`` expressed in frame ``a``: a 4x4
    homogeneous matrix ``[[R_ab, p_ab], [0, 0, 0, 1]]`` that maps coordinates
    in ``b`` to coordinates in ``a``. Poses chain by multiplication:
    ``g_ac = g_ab @ g_bc``.

Frames: ``w`` is the world (the base, origin on the table, z up), ``1`` to
``5`` are the bodies moved by shoulder_pan, shoulder_lift, elbow_flex,
wrist_flex and wrist_roll (each joint turns about its frame's local z axis),
and ``t`` is the object (tool) frame: the centre of a 26 mm cube held between
the jaws, z along the approach direction, x along the jaw-closing direction
(site ``object_frame`` in ``model/so101.xml``). The gripper joint moves only
the moving jaw, so it does not enter the object pose.

Each ``get_gxx`` is a fixed displacement and rotation taken from the
upstream SO-101 model (``so101_new_calib``), followed by the joint rotation
``Rz(theta)``. Angles are in degrees at this module's boundary.

Example (the course's test configuration)::

    >>> position, rotation = get_forward_kinematics({
    ...     "shoulder_pan": -45.0, "shoulder_lift": 45.0, "elbow_flex": -45.0,
    ...     "wrist_flex": 90.0, "wrist_roll": 0.0})
    >>> position.round(4)  # [m]; the cube centre, 13 mm above the table
    array([0.2301, 0.1903, 0.013 ])
    >>> rotation[:, 2].round(6) + 0.0  # the approach axis points straight down
    array([ 0.,  0., -1.])
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

ARM_JOINTS = ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll")
"""Joints that move the object frame, base to tip."""

JOINTS = ARM_JOINTS + ("gripper",)
"""All six joints (and actuators) of the SO-101, as named by lerobot and the model."""

FRAMES = ("w", "1", "2", "3", "4", "5", "t")
"""FK frame names, base to tool."""

BODY_OF_FRAME = {
    "1": "shoulder",
    "2": "upper_arm",
    "3": "lower_arm",
    "4": "wrist",
    "5": "gripper",
}
"""The MuJoCo body carrying each joint frame (the tool frame is a site)."""

TOOL_SITE = "object_frame"

# The gripper mount's small tilt about the wrist_roll axis, exactly as the
# upstream quaternion (0.0172091, -0.0172091, 0.706897, 0.706897) encodes it:
# that quaternion is Rz(180) Rx(90) Rz(phi) with phi = 2 atan2(-0.0172091, 0.706897).
GRIPPER_MOUNT_TILT_DEG = math.degrees(2.0 * math.atan2(-0.0172091, 0.706897))  # about -2.789

# Fixed part of each transform: displacement [m] and rotation as a sequence of
# (axis, angle [deg]) applied left to right. Numbers from so101_new_calib.
_FIXED = {
    "w1": ((0.0388353, -8.97657e-09, 0.0624), (("z", 180.0), ("x", 180.0))),
    "12": ((-0.0303992, -0.0182778, -0.0542), (("x", -90.0), ("z", -90.0))),
    "23": ((-0.11257, -0.028, 0.0), (("z", 90.0),)),
    "34": ((-0.1349, 0.0052, 0.0), (("z", -90.0),)),
    "45": ((0.0, -0.0611, 0.0181), (("z", 180.0), ("x", 90.0), ("z", GRIPPER_MOUNT_TILT_DEG))),
    # Tool: centre of the held cube (derivation in model/so101.xml), 180 deg about y.
    "5t": ((0.0051, -0.000218, -0.1075), (("y", 180.0),)),
}


def Rx(thetadeg: float) -> np.ndarray:
    """Rotation matrix about x by ``thetadeg`` [deg]."""
    c, s = _cos_sin(thetadeg)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def Ry(thetadeg: float) -> np.ndarray:
    """Rotation matrix about y by ``thetadeg`` [deg]."""
    c, s = _cos_sin(thetadeg)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def Rz(thetadeg: float) -> np.ndarray:
    """Rotation matrix about z by ``thetadeg`` [deg]."""
    c, s = _cos_sin(thetadeg)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _cos_sin(thetadeg: float) -> tuple[float, float]:
    """Cosine and sine of an angle in degrees, exact at multiples of 90."""
    quarter_turns, rest = divmod(thetadeg, 90.0)
    if rest == 0.0:
        return ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))[int(quarter_turns) % 4]
    rad = math.radians(thetadeg)
    return math.cos(rad), math.sin(rad)


_AXIS_ROTATION = {"x": Rx, "y": Ry, "z": Rz}


def pose(rotation: np.ndarray, displacement) -> np.ndarray:
    """Assemble a 4x4 homogeneous transform.

    Args:
        rotation: (3, 3) rotation matrix.
        displacement: (3,) translation [m].

    Returns:
        The (4, 4) transform ``[[rotation, displacement], [0, 0, 0, 1]]``.
    """
    g = np.eye(4)
    g[:3, :3] = rotation
    g[:3, 3] = displacement
    return g


def _fixed_rotation(name: str) -> np.ndarray:
    rotation = np.eye(3)
    for axis, angle in _FIXED[name][1]:
        rotation = rotation @ _AXIS_ROTATION[axis](angle)
    return rotation


def _joint_transform(name: str, theta_deg: float) -> np.ndarray:
    return pose(_fixed_rotation(name) @ Rz(theta_deg), _FIXED[name][0])


def get_gw1(theta1_deg: float) -> np.ndarray:
    """Pose of frame 1 (shoulder) in the world, shoulder_pan = ``theta1_deg`` [deg]."""
    return _joint_transform("w1", theta1_deg)


def get_g12(theta2_deg: float) -> np.ndarray:
    """Pose of frame 2 (upper arm) in frame 1, shoulder_lift = ``theta2_deg`` [deg]."""
    return _joint_transform("12", theta2_deg)


def get_g23(theta3_deg: float) -> np.ndarray:
    """Pose of frame 3 (lower arm) in frame 2, elbow_flex = ``theta3_deg`` [deg]."""
    return _joint_transform("23", theta3_deg)


def get_g34(theta4_deg: float) -> np.ndarray:
    """Pose of frame 4 (wrist) in frame 3, wrist_flex = ``theta4_deg`` [deg]."""
    return _joint_transform("34", theta4_deg)


def get_g45(theta5_deg: float) -> np.ndarray:
    """Pose of frame 5 (gripper) in frame 4, wrist_roll = ``theta5_deg`` [deg].

    The fixed rotation keeps the gripper mount's tilt of about -2.79 deg
    (``GRIPPER_MOUNT_TILT_DEG``) exactly as the upstream model has it.
    """
    return _joint_transform("45", theta5_deg)


def get_g5t() -> np.ndarray:
    """Pose of the object frame t in frame 5 (fixed: the gripper joint does not move it)."""
    return pose(_fixed_rotation("5t"), _FIXED["5t"][0])


def joint_angles(position_dict: Mapping[str, float]) -> np.ndarray:
    """Read the five arm joint angles from a configuration dict.

    Args:
        position_dict: joint name -> angle [deg]; extra keys (``gripper``) are ignored.

    Returns:
        (5,) angles [deg] in ``ARM_JOINTS`` order.

    Raises:
        ValueError: a joint is missing, or its value is not a finite number.
    """
    angles = np.empty(len(ARM_JOINTS))
    for i, joint in enumerate(ARM_JOINTS):
        if joint not in position_dict:
            raise ValueError(
                f"Configuration has no '{joint}' angle; expected keys {', '.join(ARM_JOINTS)} "
                f"(degrees), got {sorted(position_dict)}."
            )
        value = position_dict[joint]
        try:
            angles[i] = value
        except (TypeError, ValueError):
            raise ValueError(
                f"Joint '{joint}' must be a number of degrees, got {value!r}."
            ) from None
        if not math.isfinite(angles[i]):
            raise ValueError(f"Joint '{joint}' must be finite, got {value!r} degrees.")
    return angles


def get_frame_chain(position_dict: Mapping[str, float]) -> dict[str, np.ndarray]:
    """Pose in the world of every FK frame, built from the ``get_gxx`` factors.

    Args:
        position_dict: joint name -> angle [deg].

    Returns:
        Frame name (``FRAMES``: "w", "1".."5", "t") -> ``g_w<frame>`` (4, 4).
    """
    theta = joint_angles(position_dict)
    factors = (get_gw1(theta[0]), get_g12(theta[1]), get_g23(theta[2]),
               get_g34(theta[3]), get_g45(theta[4]), get_g5t())
    chain = {"w": np.eye(4)}
    g_w = chain["w"]
    for frame, factor in zip(FRAMES[1:], factors):
        g_w = g_w @ factor
        chain[frame] = g_w
    return chain


# Fast path. Each factor g(theta) = fixed @ Rz(theta) is linear in
# (cos theta, sin theta): g = K0 + cos * Kc + sin * Ks. The constant tool
# transform is folded into the last factor.
def _linear_factors() -> np.ndarray:
    names = ("w1", "12", "23", "34", "45")
    factors = np.zeros((len(names), 3, 4, 4))
    for i, name in enumerate(names):
        at_0 = _joint_transform(name, 0.0)
        at_90 = _joint_transform(name, 90.0)
        constant = at_0.copy()
        constant[:, :2] = 0.0  # columns 0, 1 are the only ones theta touches
        factors[i, 0] = constant
        factors[i, 1] = at_0 - constant   # multiplies cos(theta)
        factors[i, 2] = at_90 - constant  # multiplies sin(theta)
    factors[-1] = factors[-1] @ get_g5t()
    return factors


_K = _linear_factors()  # (joint, {constant, cos, sin}, 4, 4)
_K_WIDE = _K.transpose(0, 2, 1, 3).reshape(len(_K), 4, 12)  # [K0 | Kc | Ks] side by side


def get_forward_kinematics(position_dict: Mapping[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """Object-frame pose in the world for one configuration.

    Args:
        position_dict: joint name -> angle [deg]. The five arm joints are
            required; ``gripper`` is ignored.

    Returns:
        ``(position, rotation)``: (3,) position [m] and (3, 3) rotation of the
        object frame in the world (``g_wt``).

    Raises:
        ValueError: a joint is missing or not a finite number.
    """
    theta = np.radians(joint_angles(position_dict))
    g = _K[:, 0] + np.cos(theta)[:, None, None] * _K[:, 1] + np.sin(theta)[:, None, None] * _K[:, 2]
    g_wt = g[0] @ g[1] @ g[2] @ g[3] @ g[4]
    return g_wt[:3, 3].copy(), g_wt[:3, :3].copy()


def get_forward_kinematics_batch(angles_deg, chunk: int = 16384) -> tuple[np.ndarray, np.ndarray]:
    """Object-frame poses for many configurations at once.

    Args:
        angles_deg: (N, 5) arm joint angles [deg], columns in ``ARM_JOINTS`` order.
        chunk: configurations processed per block (keeps the work in cache).

    Returns:
        ``(positions, rotations)``: (N, 3) [m] and (N, 3, 3).

    Raises:
        ValueError: wrong shape or non-finite angles.
    """
    theta = np.radians(np.asarray(angles_deg, dtype=float))
    if theta.ndim != 2 or theta.shape[1] != len(ARM_JOINTS):
        raise ValueError(
            f"angles_deg must have shape (N, {len(ARM_JOINTS)}) with columns "
            f"{', '.join(ARM_JOINTS)}; got {np.shape(angles_deg)}."
        )
    if not np.all(np.isfinite(theta)):
        row, col = np.argwhere(~np.isfinite(theta))[0]
        raise ValueError(f"Joint '{ARM_JOINTS[col]}' of configuration {row} is not finite.")
    n = theta.shape[0]
    positions = np.empty((n, 3))
    rotations = np.empty((n, 3, 3))
    cos, sin = np.cos(theta), np.sin(theta)
    for start in range(0, n, chunk):
        stop = min(start + chunk, n)
        c, s = cos[start:stop, :, None], sin[start:stop, :, None]
        # Rows of the accumulated top block [R | p] of g_w<i>, stacked: (3m, 4).
        g = (_K[0, 0, :3] + c[:, 0, :, None] * _K[0, 1, :3] + s[:, 0, :, None] * _K[0, 2, :3])
        g = g.reshape(-1, 4)
        for j in range(1, len(ARM_JOINTS)):
            # g @ (K0 + c Kc + s Ks), the three products in one matrix product.
            parts = (g @ _K_WIDE[j]).reshape(stop - start, 3, 3, 4)
            g = (parts[:, :, 0] + c[:, j, :, None] * parts[:, :, 1]
                 + s[:, j, :, None] * parts[:, :, 2]).reshape(-1, 4)
        g = g.reshape(stop - start, 3, 4)
        positions[start:stop] = g[:, :, 3]
        rotations[start:stop] = g[:, :, :3]
    return positions, rotations

"""The SO-101's kinematic facts and the building blocks of its forward kinematics.

The frame convention is written once, at the top of ``so101_forward_kinematics.py``:
``g_ab`` is the pose of frame ``b`` in frame ``a``; frames ``w``, ``1`` ... ``5``, ``t``.

Each joint's transform is a fixed displacement and rotation read from the arm's
model, ``model/so101.xml`` (upstream ``so101_new_calib``; :data:`FIXED_TRANSFORMS`,
via :mod:`so101_kinematics.model_facts`),
followed by the joint rotation ``Rz(theta)``: :func:`joint_transform`. The
course's factors ``get_gw1`` ... ``get_g5t`` (``so101_forward_kinematics.py``)
are these; :mod:`so101_kinematics.fast_fk` evaluates their product in closed form.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from so101_kinematics import model_facts
from so101_kinematics.errors import KinematicsInputError, KinematicsTypeError

__all__ = [
    "ANGLE_RANGE_DEG", "ARM_JOINTS", "BODY_OF_FRAME", "FIXED_ROTATION", "FIXED_TRANSFORMS",
    "FRAMES", "GRIPPER_MOUNT_TILT_DEG", "GRIPPER_RANGE", "JOINTS", "JOINT_LIMITS",
    "MOVING_JAW_BODY", "JOINT_RANGES_RAD", "Rx", "Ry", "Rz", "TOOL_SITE", "_as_degrees",
    "check_angle",
    "get_frame_chain", "rigid_fit_2d", "joint_angles", "joint_transform", "pose", "read_angles",
]

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

MOVING_JAW_BODY = "moving_jaw_so101_v1"
"""The MuJoCo body of the moving jaw (turned by the gripper joint, carried by frame 5)."""

TOOL_SITE = "object_frame"

ANGLE_RANGE_DEG = (-360.0, 360.0)
"""Joint angles the FK accepts [deg]: one turn either way.

Every pose is reached within it; a larger angle is almost surely a mistake
(radians summed as degrees, an angle never wrapped) and loses precision
(at 1e12 deg a float resolves only 1e-4 deg). The arm's own joint limits are
narrower (:data:`JOINT_LIMITS`).
"""

JOINT_RANGES_RAD = {joint: model_facts.joint_range(joint) for joint in JOINTS}
"""Joint ranges [rad]: the ``range`` attributes of ``model/so101.xml`` (upstream
``so101_new_calib``), read without MuJoCo so that the IK and the real-arm path know them
(``tests/sim/test_model.py`` checks them against the compiled model)."""

GRIPPER_RANGE = (0.0, 100.0)
"""The gripper's user range [%]: 0 at its lower joint limit (closed), 100 at the upper (open)."""

JOINT_LIMITS = {joint: (math.degrees(lower), math.degrees(upper))
                for joint, (lower, upper) in JOINT_RANGES_RAD.items() if joint != "gripper"}
JOINT_LIMITS["gripper"] = GRIPPER_RANGE
"""Joint limits in user units: [deg] for the arm joints, [0, 100] for the gripper."""

# The gripper mount's small tilt about the wrist_roll axis, exactly as the upstream
# quaternion of the ``gripper`` body in model/so101.xml, (0.0172091, -0.0172091, 0.706897,
# 0.706897), encodes it: that quaternion is Rz(180) Rx(90) Rz(phi) with
# phi = 2 atan2(q_x, q_y) (quat = w x y z).
_GRIPPER_QUAT = model_facts.body_quaternion("gripper")
GRIPPER_MOUNT_TILT_DEG = math.degrees(2.0 * math.atan2(_GRIPPER_QUAT[1], _GRIPPER_QUAT[2]))
"""[deg] about -2.789."""

# Fixed part of each transform: displacement [m] (the child body's ``pos`` in
# model/so101.xml) and rotation as a sequence of (axis, angle [deg]) applied left to right:
# the body's ``quat`` in the course's factors (tests/core/test_facts.py checks they agree).
FIXED_TRANSFORMS = {
    "w1": (model_facts.body_position("shoulder"), (("z", 180.0), ("x", 180.0))),
    "12": (model_facts.body_position("upper_arm"), (("x", -90.0), ("z", -90.0))),
    "23": (model_facts.body_position("lower_arm"), (("z", 90.0),)),
    "34": (model_facts.body_position("wrist"), (("z", -90.0),)),
    "45": (model_facts.body_position("gripper"),
           (("z", 180.0), ("x", 90.0), ("z", GRIPPER_MOUNT_TILT_DEG))),
    # Tool: centre of the held cube (the object_frame site; derivation in model/so101.xml),
    # axes those of frame 5: at a top-down grasp z points up and the frame is Rz(yaw).
    "5t": (model_facts.site_position("object_frame"), ()),
}


def Rx(thetadeg: float) -> np.ndarray:
    """Rotation matrix about x by ``thetadeg`` [deg] (in ``ANGLE_RANGE_DEG``)."""
    c, s = _cos_sin(check_angle(thetadeg, "thetadeg"))
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def Ry(thetadeg: float) -> np.ndarray:
    """Rotation matrix about y by ``thetadeg`` [deg] (in ``ANGLE_RANGE_DEG``)."""
    c, s = _cos_sin(check_angle(thetadeg, "thetadeg"))
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def Rz(thetadeg: float) -> np.ndarray:
    """Rotation matrix about z by ``thetadeg`` [deg] (in ``ANGLE_RANGE_DEG``)."""
    c, s = _cos_sin(check_angle(thetadeg, "thetadeg"))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def check_angle(value, name: str) -> float:
    """``value`` as a float if it is a number of degrees in ``ANGLE_RANGE_DEG``.

    Args:
        value: the angle [deg].
        name: what to call it in the message, e.g. ``"wrist_roll"``.

    Raises:
        KinematicsTypeError: text, None, a boolean or another non-number.
        KinematicsInputError: NaN, an infinity, or outside the range.
    """
    if type(value) is not float:  # ints, numpy scalars; rejects text and booleans
        value = _as_degrees(name, value)
    if not ANGLE_RANGE_DEG[0] <= value <= ANGLE_RANGE_DEG[1]:  # also false for NaN
        low, high = ANGLE_RANGE_DEG
        if not math.isfinite(value):
            raise KinematicsInputError(
                f"{name} must be a finite number of degrees in [{low:g}, {high:g}], got "
                f"{value!r}. Fix: give a finite angle.")
        raise KinematicsInputError(
            f"{name} = {value:g} deg is outside [{low:g}, {high:g}] deg (the FK takes each angle "
            "within one turn). Fix: wrap it into [-180, 180] deg (and check it is not in "
            "radians or a sum of angles).")
    return value


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
    """The fixed rotation of transform ``name``, composed left to right."""
    rotation = np.eye(3)
    for axis, angle in FIXED_TRANSFORMS[name][1]:
        rotation = rotation @ _AXIS_ROTATION[axis](angle)
    return rotation


FIXED_ROTATION = {name: _fixed_rotation(name) for name in FIXED_TRANSFORMS}


def joint_transform(name: str, theta_deg: float) -> np.ndarray:
    """``g`` of one joint: its fixed transform ``name`` ("w1", ..., "45") then ``Rz(theta_deg)``."""
    return pose(FIXED_ROTATION[name] @ Rz(theta_deg), FIXED_TRANSFORMS[name][0])


def read_angles(position_dict: Mapping[str, float]) -> list[float]:
    """The five arm joint angles [deg] of a configuration, validated (see :func:`joint_angles`)."""
    angles = []
    low, high = ANGLE_RANGE_DEG
    for joint in ARM_JOINTS:
        try:
            value = position_dict[joint]
        except (KeyError, TypeError, IndexError):
            error = KinematicsInputError if isinstance(position_dict, Mapping) else \
                KinematicsTypeError
            raise error(
                f"Configuration has no '{joint}' angle; expected a dict with keys "
                f"{', '.join(ARM_JOINTS)} (degrees), got {_describe_keys(position_dict)}. "
                "Fix: give all five arm joints."
            ) from None
        if type(value) is not float or not low <= value <= high:
            value = check_angle(value, f"Joint '{joint}'")
        angles.append(value)
    return angles


def _as_degrees(name: str, value) -> float:
    """``float(value)`` for a number; KinematicsTypeError for text, None, booleans and the rest."""
    if isinstance(value, (str, bytes, bool, np.bool_)) or value is None:
        raise KinematicsTypeError(f"{name} must be a number of degrees, got {value!r} "
                                  f"({type(value).__name__}). Fix: pass a number"
                                  + (" without quotes." if isinstance(value, str) else "."))
    try:
        return float(value)
    except OverflowError:
        raise KinematicsInputError(f"{name} must be a finite number of degrees, got an "
                                   "integer too large for a float. Fix: give a finite "
                                   "angle.") from None
    except (TypeError, ValueError):
        raise KinematicsTypeError(f"{name} must be a number of degrees, got "
                                  f"{type(value).__name__}. Fix: pass a number.") from None


def _describe_keys(position_dict) -> str:
    try:
        return repr(sorted(map(str, position_dict.keys())))
    except Exception:  # not a mapping: say what it is instead
        return f"a {type(position_dict).__name__}"


def joint_angles(position_dict: Mapping[str, float]) -> np.ndarray:
    """Read the five arm joint angles from a configuration dict.

    Args:
        position_dict: joint name -> angle [deg]; extra keys (``gripper``) are ignored.

    Returns:
        (5,) angles [deg] in ``ARM_JOINTS`` order.

    Raises:
        KinematicsInputError: a joint is missing, or its value is not a finite
            number in ``ANGLE_RANGE_DEG`` (a ValueError; text, None and
            booleans raise its subclass :class:`KinematicsTypeError`, also a TypeError).
    """
    return np.array(read_angles(position_dict))




def get_frame_chain(position_dict: Mapping[str, float]) -> dict[str, np.ndarray]:
    """Pose in the world of every FK frame: the course's factors multiplied one by one.

    Args:
        position_dict: joint name -> angle [deg].

    Returns:
        Frame name (``FRAMES``: "w", "1".."5", "t") -> ``g_w<frame>`` (4, 4).

    Raises:
        KinematicsInputError: a joint is missing or not a finite number in
            ``ANGLE_RANGE_DEG`` (see :func:`joint_angles`).
    """
    theta = read_angles(position_dict) + [0.0]  # g_5t has no joint
    chain = {"w": np.eye(4)}
    g_w = chain["w"]
    for frame, name, angle in zip(FRAMES[1:], ("w1", "12", "23", "34", "45", "5t"), theta,
                                  strict=True):
        g_w = g_w @ joint_transform(name, angle)
        chain[frame] = g_w
    return chain


def rigid_fit_2d(points, targets) -> tuple[float, np.ndarray, np.ndarray]:
    """The turn about the vertical and the shift that take ``points`` nearest ``targets``.

    Least squares, Kabsch's method in the plane, no scale: ``targets ~ R(angle) points +
    shift``. The one rigid fit of the project (the page's and the chess board's
    registrations from touched points).

    Args:
        points: (n, 2) points [m] in their own frame (a page's marks, a board's squares).
        targets: (n, 2) where each was touched [m], in the arm's base frame.

    Returns:
        ``(angle, shift, residuals)``: the angle [rad], the shift (2,) [m] and each point's
        distance from its target after the fit (n,) [m].

    Example:
        >>> angle, shift, residuals = rigid_fit_2d([[0, 0], [1, 0], [0, 1]],
        ...                                        [[2, 3], [2, 4], [1, 3]])
        >>> round(math.degrees(angle), 6), shift.round(6).tolist(), residuals.round(9).tolist()
        (90.0, [2.0, 3.0], [0.0, 0.0, 0.0])
    """
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    q = np.asarray(targets, dtype=float).reshape(-1, 2)
    p0, q0 = p.mean(axis=0), q.mean(axis=0)
    a, b = p - p0, q - q0
    angle = math.atan2(float((a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]).sum()),
                       float((a * b).sum()))
    c, s = math.cos(angle), math.sin(angle)
    rotation = np.array([[c, -s], [s, c]])
    shift = q0 - rotation @ p0
    return angle, shift, np.linalg.norm(p @ rotation.T + shift - q, axis=1)

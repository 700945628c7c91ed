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
:func:`get_frame_chain` multiplies the ``get_gxx`` factors as the assignment
does; :func:`get_forward_kinematics` and :func:`get_forward_kinematics_batch`
evaluate the same product in closed form, for speed (derivation above
``_closed_form_assumptions``). All three agree with MuJoCo to ~1e-15.

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
import numbers
import operator
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from so101_kinematics.errors import (
    KinematicsInputError as KinematicsInputError,
)
from so101_kinematics.errors import (
    KinematicsTypeError as KinematicsTypeError,
)

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

ANGLE_RANGE_DEG = (-360.0, 360.0)
"""Joint angles the FK accepts [deg]: one turn either way.

Every pose is reached within it; a larger angle is almost surely a mistake
(radians summed as degrees, an angle never wrapped) and loses precision
(at 1e12 deg a float resolves only 1e-4 deg). The arm's own joint limits are
narrower (``so101_mujoco_utils.joint_limits``).
"""


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
    rotation = np.eye(3)
    for axis, angle in _FIXED[name][1]:
        rotation = rotation @ _AXIS_ROTATION[axis](angle)
    return rotation


_FIXED_ROTATION = {name: _fixed_rotation(name) for name in _FIXED}


def _joint_transform(name: str, theta_deg: float) -> np.ndarray:
    return pose(_FIXED_ROTATION[name] @ Rz(theta_deg), _FIXED[name][0])


def get_gw1(theta1_deg: float) -> np.ndarray:
    """Pose of frame 1 (shoulder) in the world, shoulder_pan = ``theta1_deg`` [deg].

    Raises:
        KinematicsInputError: the angle is not a finite number in ``ANGLE_RANGE_DEG``
            (a :class:`KinematicsTypeError` for text, None or a boolean).
    """
    return _joint_transform("w1", check_angle(theta1_deg, "shoulder_pan"))


def get_g12(theta2_deg: float) -> np.ndarray:
    """Pose of frame 2 (upper arm) in frame 1, shoulder_lift = ``theta2_deg`` [deg]."""
    return _joint_transform("12", check_angle(theta2_deg, "shoulder_lift"))


def get_g23(theta3_deg: float) -> np.ndarray:
    """Pose of frame 3 (lower arm) in frame 2, elbow_flex = ``theta3_deg`` [deg]."""
    return _joint_transform("23", check_angle(theta3_deg, "elbow_flex"))


def get_g34(theta4_deg: float) -> np.ndarray:
    """Pose of frame 4 (wrist) in frame 3, wrist_flex = ``theta4_deg`` [deg]."""
    return _joint_transform("34", check_angle(theta4_deg, "wrist_flex"))


def get_g45(theta5_deg: float) -> np.ndarray:
    """Pose of frame 5 (gripper) in frame 4, wrist_roll = ``theta5_deg`` [deg].

    The fixed rotation keeps the gripper mount's tilt of about -2.79 deg
    (``GRIPPER_MOUNT_TILT_DEG``) exactly as the upstream model has it.
    """
    return _joint_transform("45", check_angle(theta5_deg, "wrist_roll"))


def get_g5t() -> np.ndarray:
    """Pose of the object frame t in frame 5 (fixed: the gripper joint does not move it)."""
    return pose(_FIXED_ROTATION["5t"], _FIXED["5t"][0])


def _read_angles(position_dict: Mapping[str, float]) -> list[float]:
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
    return np.array(_read_angles(position_dict))


def get_frame_chain(position_dict: Mapping[str, float]) -> dict[str, np.ndarray]:
    """Pose in the world of every FK frame, built from the ``get_gxx`` factors.

    Args:
        position_dict: joint name -> angle [deg].

    Returns:
        Frame name (``FRAMES``: "w", "1".."5", "t") -> ``g_w<frame>`` (4, 4).

    Raises:
        KinematicsInputError: a joint is missing or not a finite number in
            ``ANGLE_RANGE_DEG`` (see :func:`joint_angles`).
    """
    theta = _read_angles(position_dict)
    factors = (get_gw1(theta[0]), get_g12(theta[1]), get_g23(theta[2]),
               get_g34(theta[3]), get_g45(theta[4]), get_g5t())
    chain = {"w": np.eye(4)}
    g_w = chain["w"]
    for frame, factor in zip(FRAMES[1:], factors, strict=True):
        g_w = g_w @ factor
        chain[frame] = g_w
    return chain


# ---------------------------------------------------------------------------
# Closed form of g_wt, used by get_forward_kinematics and the batch form.
#
# The product gw1 @ g12 @ g23 @ g34 @ g45 @ g5t simplifies because of two
# facts about the SO-101 (checked below at import, and against MuJoCo and the
# product itself in tests/test_forward_kinematics.py):
#   1. shoulder_lift, elbow_flex and wrist_flex turn about parallel axes: the
#      fixed rotations of g23 and g34 are Rz(+90) and Rz(-90), so
#      Rz(th2) Rz(90) Rz(th3) Rz(-90) Rz(th4) = Rz(phi), phi = th2 + th3 + th4.
#   2. the other fixed rotations are signed permutations:
#      R_w1 = diag(-1, 1, -1), R_12 = P (rows e_y, e_z, e_x), R_5t = diag(-1, 1, -1),
#      and R_45 = D Rz(tilt) with D = Rz(180) Rx(90); the tilt adds to wrist_roll:
#      psi = th5 + GRIPPER_MOUNT_TILT_DEG.
# Then R_wt = diag(-1, 1, -1) Rz(th1) P Rz(phi) D Rz(psi) diag(-1, 1, -1), whose
# entries are the short products written out in get_forward_kinematics, and
#   p_wt = p_w1 + diag(-1, 1, -1) Rz(th1) (p_12 + P r), with
#   r = Rz(th2) p_23 + Rz(th2 + th3 + 90) p_34 + Rz(phi) (p_45 + D Rz(psi) p_5t).
_P_W1, _P_12, _P_23, _P_34, _P_45, _P_5T = (
    tuple(map(float, _FIXED[name][0])) for name in ("w1", "12", "23", "34", "45", "5t")
)
_V_X = _P_45[0]                             # p_45 + D Rz(psi) p_5t = (V_X - c5 a + s5 b,
_V_Y = _P_45[1] + _P_5T[2]                  #                          V_Y,
_V_Z = _P_45[2] + _P_12[1] + _P_23[2] + _P_34[2]  # V_Z + s5 a + c5 b), plus p_12,y and r_z
_TOOL_A, _TOOL_B = _P_5T[0], _P_5T[1]       # a, b
_DEG = math.pi / 180.0
_HALF_DEG = math.pi / 360.0
_TILT_DEG = GRIPPER_MOUNT_TILT_DEG


def _closed_form_assumptions() -> None:
    """Fail loudly if ``_FIXED`` no longer has the structure the closed form assumes."""
    flip = np.diag([1.0, -1.0, 1.0]) * -1.0  # diag(-1, 1, -1)
    expected = {
        "w1": flip,
        "12": np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]),
        "23": Rz(90.0),
        "34": Rz(-90.0),
        "45": Rz(180.0) @ Rx(90.0) @ Rz(_TILT_DEG),
        "5t": flip,
    }
    for name, rotation in expected.items():
        if not np.allclose(_FIXED_ROTATION[name], rotation, rtol=0.0, atol=1e-15):
            raise RuntimeError(
                f"The fixed rotation of g_{name} changed; update the closed form in "
                f"{Path(__file__).name} (get_forward_kinematics and the batch form) to match."
            )


_closed_form_assumptions()


def get_forward_kinematics(position_dict: Mapping[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """Object-frame pose in the world for one configuration.

    Equal (to rounding, ~1e-16) to ``get_gw1 @ get_g12 @ ... @ get_g5t`` as the
    assignment composes it, evaluated in closed form for speed.

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
    th1, th2, th3, th4, th5 = _read_angles(position_dict)
    cos, sin = math.cos, math.sin
    a = th1 * _DEG
    c1, s1 = cos(a), sin(a)
    a = th2 * _DEG
    c2, s2 = cos(a), sin(a)
    a = (th2 + th3) * _DEG
    c23, s23 = cos(a), sin(a)
    a = (th2 + th3 + th4) * _DEG
    cp, sp = cos(a), sin(a)
    a = (th5 + _TILT_DEG) * _DEG
    c5, s5 = cos(a), sin(a)
    v_x = _V_X - c5 * _TOOL_A + s5 * _TOOL_B
    h_1 = _V_Z + s5 * _TOOL_A + c5 * _TOOL_B
    r_x = (c2 * _P_23[0] - s2 * _P_23[1] - s23 * _P_34[0] - c23 * _P_34[1]
           + cp * v_x - sp * _V_Y)
    h_0 = (_P_12[0] + s2 * _P_23[0] + c2 * _P_23[1] + c23 * _P_34[0] - s23 * _P_34[1]
           + sp * v_x + cp * _V_Y)
    spc5, sps5 = sp * c5, sp * s5
    position = np.array((_P_W1[0] - c1 * h_0 + s1 * h_1,
                         _P_W1[1] + s1 * h_0 + c1 * h_1,
                         _P_W1[2] - _P_12[2] - r_x))
    rotation = np.array(((-c1 * spc5 - s1 * s5, s1 * c5 - c1 * sps5, c1 * cp),
                         (s1 * spc5 - c1 * s5, s1 * sps5 + c1 * c5, -s1 * cp),
                         (-cp * c5, -cp * s5, -sp)))
    return position, rotation


def _cos_sin_from_half(half: np.ndarray, cos: np.ndarray, sin: np.ndarray,
                       scratch: np.ndarray) -> None:
    """Cosine and sine of ``2 * half`` [rad], in place, from t = tan(half).

    cos = 2 / (1 + t^2) - 1 and sin = t * 2 / (1 + t^2): one vectorised tan
    (fast in numpy) instead of a sin and a cos (much slower), exact to a few
    1e-16 for every angle (t is at most ~1.6e16 at half = 90 deg).
    """
    np.tan(half, out=sin)
    np.multiply(sin, sin, out=scratch)
    scratch += 1.0
    np.divide(2.0, scratch, out=scratch)
    np.subtract(scratch, 1.0, out=cos)
    sin *= scratch


def _batch_angles(angles_deg) -> np.ndarray:
    """The (N, 5) float array of a batch, checked (see :func:`get_forward_kinematics_batch`)."""
    shape_text = f"an (N, {len(ARM_JOINTS)}) array with columns {', '.join(ARM_JOINTS)}"
    try:
        raw = np.asarray(angles_deg)
    except (TypeError, ValueError):  # ragged nested lists
        raise KinematicsInputError(f"angles_deg must be {shape_text} [deg]; got a ragged or "
                                   f"malformed {type(angles_deg).__name__}.") from None
    if raw.ndim != 2 or raw.shape[1] != len(ARM_JOINTS):
        raise KinematicsInputError(f"angles_deg must be {shape_text}; got shape {raw.shape}.")
    if raw.dtype.kind == "O":
        for (row, col), value in np.ndenumerate(raw):
            if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
                _as_degrees(f"Joint '{ARM_JOINTS[col]}' of configuration {row}", value)
                raise KinematicsTypeError(  # pragma: no cover - _as_degrees raised
                    f"Joint '{ARM_JOINTS[col]}' of configuration {row} is not a number.")
        try:
            raw = raw.astype(float)
        except OverflowError:
            raise KinematicsInputError("angles_deg holds an integer too large for a float. "
                                       "Fix: give finite angles [deg].") from None
    elif raw.dtype.kind not in "iuf":
        raise KinematicsTypeError(f"angles_deg must hold numbers [deg], got an array of "
                                  f"{raw.dtype} (kind '{raw.dtype.kind}'). Fix: pass floats, "
                                  "e.g. np.asarray(angles, dtype=float) of numbers, not text.")
    theta = np.asarray(raw, dtype=float)
    low, high = ANGLE_RANGE_DEG
    bad = ~((theta >= low) & (theta <= high))  # NaN fails both comparisons
    if bad.any():
        row, col = np.argwhere(bad)[0]
        value = theta[row, col]
        problem = "is not finite" if not math.isfinite(value) else \
            f"= {value:g} deg is outside [{low:g}, {high:g}] deg"
        raise KinematicsInputError(
            f"Joint '{ARM_JOINTS[col]}' of configuration {row} {problem} (the FK takes each "
            "angle within one turn). Fix: give finite angles wrapped into [-180, 180] deg.")
    return theta


def get_forward_kinematics_batch(angles_deg, chunk: int = 8192) -> tuple[np.ndarray, np.ndarray]:
    """Object-frame poses for many configurations at once.

    The closed form of :func:`get_forward_kinematics`, evaluated on columns of
    ``chunk`` configurations at a time with preallocated buffers.

    Args:
        angles_deg: (N, 5) arm joint angles [deg], columns in ``ARM_JOINTS`` order.
        chunk: configurations processed per block (keeps the work in cache).

    Returns:
        ``(positions, rotations)``: (N, 3) [m] and (N, 3, 3).

    Raises:
        KinematicsInputError: wrong shape, angles that are not finite or outside
            ``ANGLE_RANGE_DEG`` (naming the joint and the row), or chunk < 1;
            :class:`KinematicsTypeError` for text, booleans or other
            non-numbers, and a chunk that is not a whole number.
    """
    theta = _batch_angles(angles_deg)
    if isinstance(chunk, (bool, np.bool_)):
        raise KinematicsTypeError(f"chunk must be a whole number >= 1, got {chunk!r}. "
                                  "Fix: pass an int such as 8192.")
    try:
        chunk = operator.index(chunk)
    except TypeError:
        raise KinematicsTypeError(f"chunk must be a whole number >= 1, got {chunk!r} "
                                  f"({type(chunk).__name__}). Fix: pass an int such as "
                                  "8192.") from None
    if chunk < 1:
        raise KinematicsInputError(f"chunk must be a whole number >= 1, got {chunk!r}. "
                                   "Fix: pass an int such as 8192.")
    n = theta.shape[0]
    positions = np.empty((n, 3))
    rotations = np.empty((n, 3, 3))
    buffers = np.empty((16, min(chunk, n)))
    mul, add, sub, neg = np.multiply, np.add, np.subtract, np.negative
    for start in range(0, n, chunk):
        stop = min(start + chunk, n)
        th = theta[start:stop]
        p, R = positions[start:stop], rotations[start:stop]
        (c1, s1, c2, s2, c23, s23, cp, sp, c5, s5,
         x, y, z, u, w, tmp) = buffers[:, : stop - start]
        # cos and sin of th1, th2, th2 + th3, phi and psi, from half angles [rad].
        mul(th[:, 0], _HALF_DEG, out=x)
        _cos_sin_from_half(x, c1, s1, tmp)
        mul(th[:, 1], _HALF_DEG, out=y)
        _cos_sin_from_half(y, c2, s2, tmp)
        mul(th[:, 2], _HALF_DEG, out=z)
        z += y
        _cos_sin_from_half(z, c23, s23, tmp)
        mul(th[:, 3], _HALF_DEG, out=x)
        x += z
        _cos_sin_from_half(x, cp, sp, tmp)
        add(th[:, 4], _TILT_DEG, out=x)
        x *= _HALF_DEG
        _cos_sin_from_half(x, c5, s5, tmp)
        # x = v_x, y = h_1 (as in get_forward_kinematics).
        mul(c5, -_TOOL_A, out=x)
        mul(s5, _TOOL_B, out=tmp)
        x += tmp
        x += _V_X
        mul(s5, _TOOL_A, out=y)
        mul(c5, _TOOL_B, out=tmp)
        y += tmp
        y += _V_Z
        # z = r_x, u = h_0.
        mul(cp, x, out=z)
        for column, factor in ((sp, -_V_Y), (c2, _P_23[0]), (s2, -_P_23[1]),
                               (s23, -_P_34[0]), (c23, -_P_34[1])):
            mul(column, factor, out=tmp)
            z += tmp
        mul(sp, x, out=u)
        for column, factor in ((cp, _V_Y), (s2, _P_23[0]), (c2, _P_23[1]),
                               (c23, _P_34[0]), (s23, -_P_34[1])):
            mul(column, factor, out=tmp)
            u += tmp
        u += _P_12[0]
        mul(c1, u, out=tmp)
        mul(s1, y, out=w)
        w -= tmp
        add(w, _P_W1[0], out=p[:, 0])
        mul(s1, u, out=tmp)
        mul(c1, y, out=w)
        w += tmp
        add(w, _P_W1[1], out=p[:, 1])
        sub(_P_W1[2] - _P_12[2], z, out=p[:, 2])
        # Rotation; x = sin(phi) cos(psi), y = sin(phi) sin(psi).
        mul(sp, c5, out=x)
        mul(sp, s5, out=y)
        mul(c1, x, out=tmp)
        mul(s1, s5, out=w)
        w += tmp
        neg(w, out=R[:, 0, 0])
        mul(s1, c5, out=tmp)
        mul(c1, y, out=w)
        sub(tmp, w, out=R[:, 0, 1])
        mul(c1, cp, out=R[:, 0, 2])
        mul(s1, x, out=tmp)
        mul(c1, s5, out=w)
        sub(tmp, w, out=R[:, 1, 0])
        mul(s1, y, out=tmp)
        mul(c1, c5, out=w)
        add(tmp, w, out=R[:, 1, 1])
        mul(s1, cp, out=tmp)
        neg(tmp, out=R[:, 1, 2])
        mul(cp, c5, out=tmp)
        neg(tmp, out=R[:, 2, 0])
        mul(cp, s5, out=tmp)
        neg(tmp, out=R[:, 2, 1])
        neg(sp, out=R[:, 2, 2])
    return positions, rotations

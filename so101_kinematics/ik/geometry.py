"""The arm's geometry for the IK: link vectors, tolerances, the FK chain and the Jacobian."""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence

import numpy as np

from so101_kinematics.constants import CUBE_HALF_SIZE
from so101_kinematics.frames import (
    ARM_JOINTS,
    FIXED_TRANSFORMS,
    GRIPPER_MOUNT_TILT_DEG,
    JOINT_RANGES_RAD,
    joint_angles,
    joint_transform,
)
from so101_kinematics.planning.plans import STARTING_CONFIGURATION

__all__ = [
    "GRIPPER_OPEN", "MIN_HEIGHT", "PAN_AXIS_POINT", "POSITION_LIMIT",
    "REFERENCE_CONFIGURATION", "REFINE_TOL", "SOLVE_TOL", "_A", "_ACROSS0", "_ALONG", "_B",
    "_C", "_DEFAULT_REFERENCE", "_H0", "_KINK", "_LATERAL0", "_LEN_A", "_LEN_B", "_LIMITS",
    "_LIMIT_SLACK", "_PAN", "_QUARTER", "_REACH_MAX", "_REACH_MIN", "_ROLL", "_T", "_TILT",
    "_Z0", "chain_from_radians", "jacobian_from_chain", "_wrap", "get_jacobian", "log",
]

MIN_HEIGHT = CUBE_HALF_SIZE - 0.001
"""Lowest object-frame height accepted by default [m]: a cube centre at most 1 mm into the table."""

GRIPPER_OPEN = float(STARTING_CONFIGURATION["gripper"])
"""Gripper opening of the course's open configurations [0, 100]."""

POSITION_LIMIT = 10.0
"""Largest coordinate of a target accepted as input [m]; the arm reaches about 0.5 m.

A target further out is refused as malformed (a position in millimetres?)
before any arithmetic that could overflow.
"""

REFINE_TOL = 1e-12
"""FK residual [m] or [rad] above which a closed-form result is refined numerically."""

SOLVE_TOL = 1e-9
"""Largest residual [m] or [rad] a returned solution may have."""

REFERENCE_CONFIGURATION = dict(STARTING_CONFIGURATION)
"""Configuration [deg] the solver stays closest to when no ``initial`` is given."""

log = logging.getLogger(__name__)

_LIMIT_SLACK = 1e-9  # [rad]: a solution this close outside a limit is clipped onto it
_DEFAULT_REFERENCE = [math.radians(REFERENCE_CONFIGURATION[joint]) for joint in ARM_JOINTS]


# ---------------------------------------------------------------------------
# Geometry, read from the FK module's fixed transforms (see the module doc).
# "Plane" coordinates are those of frame 2 at shoulder_lift = 0: x2 points
# down, y2 backwards and z2 sideways along the lift axis (for pan = 0); the
# world before the pan is (forward, sideways, up) = (-y2, z2, -x2) from _C.
_C = tuple(float(v) for v in FIXED_TRANSFORMS["w1"][0])        # a point on the pan axis [m]
PAN_AXIS_POINT = _C
"""A point of the shoulder_pan axis (vertical) in the base frame [m]: where the arm turns."""
_D12 = FIXED_TRANSFORMS["12"][0]
_H0 = -_D12[0]                                       # lift axis: forward of the pan axis [m]
_Z0 = -_D12[2]                                       # lift axis: above _C [m]
_A = (FIXED_TRANSFORMS["23"][0][0], FIXED_TRANSFORMS["23"][0][1])  # upper arm in frame 2 [m]
_B = (-FIXED_TRANSFORMS["34"][0][1], FIXED_TRANSFORMS["34"][0][0])  # forearm, Rz(90) p_34, frame 2
_T = FIXED_TRANSFORMS["5t"][0]                                 # object frame in frame 5 [m]
_D45 = FIXED_TRANSFORMS["45"][0]
_LATERAL0 = _D12[1] + FIXED_TRANSFORMS["23"][0][2] + FIXED_TRANSFORMS["34"][0][2] + _D45[2]  # [m]
_ALONG = _D45[1] + _T[2]           # object frame along frame 4's y (minus the approach) [m]
_ACROSS0 = _D45[0]                 # and along its x, before the roll's share [m]
_LEN_A = math.hypot(*_A)
_LEN_B = math.hypot(*_B)
_KINK = math.atan2(_B[1], _B[0]) - math.atan2(_A[1], _A[0])
_REACH_MAX = _LEN_A + _LEN_B       # shoulder_lift axis to wrist_flex axis [m]
_REACH_MIN = abs(_LEN_A - _LEN_B)
_TILT = math.radians(GRIPPER_MOUNT_TILT_DEG)
_LIMITS = tuple(JOINT_RANGES_RAD[joint] for joint in ARM_JOINTS)
_PAN, _ROLL = 0, 4                 # positions in ARM_JOINTS order
_TWO_PI = 2.0 * math.pi
_QUARTER = 0.5 * math.pi


def _wrap(angle: float) -> float:
    """Angle [rad] wrapped into [-pi, pi)."""
    return (angle + math.pi) % _TWO_PI - math.pi


# ---------------------------------------------------------------------------
# Frames and Jacobian.
def chain_from_radians(theta: Sequence[float]) -> np.ndarray:
    """World poses of frames 1..5 (after their joints) and of the object frame: (6, 4, 4).

    Args:
        theta: arm angles [rad] in ``ARM_JOINTS`` order.
    """
    degrees = [math.degrees(v) for v in theta] + [0.0]
    factors = [joint_transform(name, angle)
               for name, angle in zip(("w1", "12", "23", "34", "45", "5t"), degrees, strict=True)]
    out = np.empty((6, 4, 4))
    g_w = np.eye(4)
    for i, factor in enumerate(factors):
        g_w = g_w @ factor
        out[i] = g_w
    return out


def jacobian_from_chain(chain: np.ndarray) -> np.ndarray:
    """(6, 5) world-frame Jacobian [linear; angular] of the object frame.

    Args:
        chain: :func:`chain_from_radians`'s frames (the Jacobian reuses them).
    """
    axes = chain[:5, :3, 2]      # joint i turns about the z axis of its frame ...
    origins = chain[:5, :3, 3]   # ... which passes through the frame's origin
    jac = np.empty((6, 5))
    jac[:3] = np.cross(axes, chain[5, :3, 3] - origins).T
    jac[3:] = axes.T
    return jac


def get_jacobian(position_dict: Mapping[str, float]) -> np.ndarray:
    """Analytic Jacobian of the object frame, in the world frame.

    Column j is the object frame's velocity per unit speed of joint
    ``ARM_JOINTS[j]`` [rad/s]: rows 0-2 linear [m/rad], rows 3-5 angular
    [rad/rad], in world coordinates (the convention of MuJoCo's ``mj_jacSite``).

    Args:
        position_dict: joint name -> angle [deg] (``gripper`` ignored).

    Returns:
        (6, 5) Jacobian.

    Example:
        >>> jac = get_jacobian({"shoulder_pan": 0.0, "shoulder_lift": 0.0, "elbow_flex": 0.0,
        ...                     "wrist_flex": 0.0, "wrist_roll": 0.0})
        >>> jac[3:, 0] + 0.0  # shoulder_pan turns about the world's -z axis
        array([ 0.,  0., -1.])
    """
    return jacobian_from_chain(chain_from_radians(np.radians(joint_angles(position_dict))))



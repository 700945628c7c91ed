"""Inverse kinematics of the SO-101 arm for the object frame of the FK module.

The SO-101 has five arm joints, so a full 6-D pose of the object frame ``t``
(the centre of a held 26 mm cube, z = approach, x = jaw closing; see
``so101_forward_kinematics``) is reachable only on a 5-D subset. This module
solves the three useful cases:

- ``approach="down"``: position plus a top-down approach (tool z pointing
  straight down) and the cube's yaw about the vertical;
- ``approach="pitch"``: position plus the approach's pitch below the
  horizontal (90 deg is top-down);
- ``approach=None``: position only; the wrist keeps its roll and the approach
  stays as close to the reference pitch as reach and limits allow.

Closed form, derived from the exact ``_FIXED`` numbers of the FK module.
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
  elbow_flex + wrist_flex``; with ``psi = 90 deg`` the cube's yaw in the world
  is ``180 deg - shoulder_pan + alpha`` (and repeats every 90 deg);
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
targets the closed-form search misses.

Angles are degrees at this module's boundary (configuration dicts, as the
course's), radians inside. Example (the course's starting position)::

    >>> cfg = get_inverse_kinematics((0.230054, 0.190308, 0.013), yaw_deg=None)
    >>> {joint: round(value, 2) for joint, value in cfg.items()}  # [deg], gripper [0, 100]
    {'shoulder_pan': -45.0, 'shoulder_lift': 45.0, 'elbow_flex': -45.0, 'wrist_flex': 90.0, \
'wrist_roll': 0.0, 'gripper': 50.0}
"""

from __future__ import annotations

import logging
import math
import numbers
from collections.abc import Mapping, Sequence

import numpy as np

from so101_forward_kinematics import (
    _FIXED,
    ARM_JOINTS,
    GRIPPER_MOUNT_TILT_DEG,
    KinematicsInputError,
    KinematicsTypeError,
    check_angle,
    get_forward_kinematics,
    get_forward_kinematics_batch,
    get_g5t,
    get_g12,
    get_g23,
    get_g34,
    get_g45,
    get_gw1,
    joint_angles,
)
from so101_kinematics.errors import UnreachableError as UnreachableError
from so101_kinematics.motion import (
    GRIPPER_RANGE,
    STARTING_CONFIGURATION,
    check_number,
    describe_value,
    is_finite_number,
)

# Joint limits [rad]: the ``range`` attributes of model/so101.xml (upstream
# so101_new_calib). Kept here so that a solve needs no MuJoCo; a test checks
# that they equal the model's.
JOINT_LIMITS_RAD = {
    "shoulder_pan": (-1.9198621771937616, 1.9198621771937634),
    "shoulder_lift": (-1.7453292519943224, 1.7453292519943366),
    "elbow_flex": (-1.69, 1.69),
    "wrist_flex": (-1.6580628494556928, 1.6580627293335335),
    "wrist_roll": (-2.7438472969992493, 2.841206309382605),
}
JOINT_LIMITS = {joint: (math.degrees(lower), math.degrees(upper))
                for joint, (lower, upper) in JOINT_LIMITS_RAD.items()}
"""Arm joint limits [deg] (the gripper's are (0, 100) by definition)."""

CUBE_HALF_SIZE = 0.013
"""Half the edge of the course's cube [m]: the height of its centre on the table."""

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
_C = tuple(float(v) for v in _FIXED["w1"][0])        # a point on the pan axis [m]
PAN_AXIS_POINT = _C
"""A point of the shoulder_pan axis (vertical) in the base frame [m]: where the arm turns."""
_D12 = _FIXED["12"][0]
_H0 = -_D12[0]                                       # lift axis: forward of the pan axis [m]
_Z0 = -_D12[2]                                       # lift axis: above _C [m]
_A = (_FIXED["23"][0][0], _FIXED["23"][0][1])        # upper arm in frame 2 [m]
_B = (-_FIXED["34"][0][1], _FIXED["34"][0][0])       # forearm, Rz(90) p_34, in frame 2 [m]
_T = _FIXED["5t"][0]                                 # object frame in frame 5 [m]
_D45 = _FIXED["45"][0]
_LATERAL0 = _D12[1] + _FIXED["23"][0][2] + _FIXED["34"][0][2] + _D45[2]  # [m]
_ALONG = _D45[1] + _T[2]           # object frame along frame 4's y (minus the approach) [m]
_ACROSS0 = _D45[0]                 # and along its x, before the roll's share [m]
_LEN_A = math.hypot(*_A)
_LEN_B = math.hypot(*_B)
_KINK = math.atan2(_B[1], _B[0]) - math.atan2(_A[1], _A[0])
_REACH_MAX = _LEN_A + _LEN_B       # shoulder_lift axis to wrist_flex axis [m]
_REACH_MIN = abs(_LEN_A - _LEN_B)
_TILT = math.radians(GRIPPER_MOUNT_TILT_DEG)
_LIMITS = tuple(JOINT_LIMITS_RAD[joint] for joint in ARM_JOINTS)
_PAN, _ROLL = 0, 4                 # positions in ARM_JOINTS order
_TWO_PI = 2.0 * math.pi
_QUARTER = 0.5 * math.pi


def _wrap(angle: float) -> float:
    """Angle [rad] wrapped into [-pi, pi)."""
    return (angle + math.pi) % _TWO_PI - math.pi


# ---------------------------------------------------------------------------
# Frames and Jacobian.
def _chain(theta: Sequence[float]) -> np.ndarray:
    """World poses of frames 1..5 (after their joints) and of the object frame: (6, 4, 4).

    Args:
        theta: arm angles [rad] in ``ARM_JOINTS`` order.
    """
    th1, th2, th3, th4, th5 = (math.degrees(v) for v in theta)
    factors = (get_gw1(th1), get_g12(th2), get_g23(th3), get_g34(th4), get_g45(th5), get_g5t())
    out = np.empty((6, 4, 4))
    g_w = np.eye(4)
    for i, factor in enumerate(factors):
        g_w = g_w @ factor
        out[i] = g_w
    return out


def _jacobian_from_chain(chain: np.ndarray) -> np.ndarray:
    """(6, 5) world-frame Jacobian [linear; angular] of the object frame, from :func:`_chain`."""
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
    return _jacobian_from_chain(_chain(np.radians(joint_angles(position_dict))))


# ---------------------------------------------------------------------------
# Closed form. Targets are tuples of floats relative to _C (plain floats are
# several times faster than numpy scalars here).
def _pan(rel: tuple, alpha0: float, yaw_tied: bool, backwards: bool):
    """Shoulder_pan and roll angle alpha [rad], or why the target is too near the pan axis.

    Args:
        rel: target minus ``_C`` [m].
        alpha0: wrist_roll + tilt [rad] if not ``yaw_tied``, else the constant
            in ``alpha = alpha0 + shoulder_pan`` (a given cube yaw).
        yaw_tied: whether alpha follows shoulder_pan.
        backwards: the solution reaching backwards over the base.

    Returns:
        ``(theta1, alpha, None)`` or ``(None, None, ("too_close", shortfall [m]))``.
    """
    r = math.hypot(rel[0], rel[1])
    azimuth = math.atan2(rel[1], rel[0])
    theta1 = math.pi - azimuth if backwards else -azimuth
    if r < 1e-9 and not yaw_tied and abs(_LATERAL0 + _T[0] * math.sin(alpha0)
                                         + _T[1] * math.cos(alpha0)) < 1e-9:
        return _wrap(theta1), alpha0, None  # on the pan axis: any pan will do
    # theta1 = beta(L(alpha(theta1))) - azimuth, by Newton's method.
    for _ in range(12):
        alpha = alpha0 + theta1 if yaw_tied else alpha0
        sa, ca = math.sin(alpha), math.cos(alpha)
        lateral = _LATERAL0 + _T[0] * sa + _T[1] * ca
        if abs(lateral) >= r:
            return None, None, ("too_close", abs(lateral) - r)
        beta = math.asin(lateral / r)
        slope = 0.0
        if yaw_tied:
            slope = (_T[0] * ca - _T[1] * sa) / math.sqrt(r * r - lateral * lateral)
        if backwards:
            beta, slope = math.pi - beta, -slope
        f = _wrap(theta1 - beta + azimuth)
        theta1 -= f / (1.0 - slope)
        if abs(f) < 1e-15:
            break
    theta1 = _wrap(theta1)
    return theta1, (alpha0 + theta1 if yaw_tied else alpha0), None


def _planar(rel: tuple, theta1: float, alpha: float, psi: float, elbow: float):
    """Shoulder_lift, elbow_flex and wrist_flex [rad] in the arm's plane, or why not.

    Args:
        rel: target minus ``_C`` [m].
        theta1: shoulder_pan [rad].
        alpha: wrist_roll + tilt [rad].
        psi: the arm's pitch, shoulder_lift + elbow_flex + wrist_flex [rad].
        elbow: +1.0 or -1.0, the two elbow branches.

    Returns:
        ``((theta2, theta3, theta4), None)`` or ``(None, (reason, excess [m]))``.
    """
    h = math.cos(theta1) * rel[0] - math.sin(theta1) * rel[1]  # forward, in the arm's plane
    across = _ACROSS0 - (_T[0] * math.cos(alpha) - _T[1] * math.sin(alpha))
    cp, sp = math.cos(psi), math.sin(psi)
    # Object frame = wrist_flex axis + Rz(psi) (across, _ALONG), in plane coordinates.
    wx = _Z0 - rel[2] - (cp * across - sp * _ALONG)
    wy = _H0 - h - (sp * across + cp * _ALONG)
    dist2 = wx * wx + wy * wy
    cos_q = (dist2 - _LEN_A * _LEN_A - _LEN_B * _LEN_B) / (2.0 * _LEN_A * _LEN_B)
    if cos_q > 1.0:
        return None, ("too_far", math.sqrt(dist2) - _REACH_MAX)
    if cos_q < -1.0:
        return None, ("too_close", _REACH_MIN - math.sqrt(dist2))
    theta3 = elbow * math.acos(cos_q) - _KINK
    c3, s3 = math.cos(theta3), math.sin(theta3)
    ex = _A[0] + c3 * _B[0] - s3 * _B[1]
    ey = _A[1] + s3 * _B[0] + c3 * _B[1]
    theta2 = _wrap(math.atan2(wy, wx) - math.atan2(ey, ex))
    theta3 = _wrap(theta3)
    return (theta2, theta3, _wrap(psi - theta2 - theta3)), None


def _pitch_windows(rel: tuple, theta1: float, alpha: float):
    """Arm pitches [rad] at which the wrist_flex axis is within the two links' reach.

    The wrist_flex axis lies on a circle of pitches around the target (the
    object frame is the axis plus ``Rz(psi) v``), so it is within reach on at
    most two arcs of ``psi``, kept slightly inside their ends.

    Returns:
        ``(windows, failure)``: (lowest, highest) pitch intervals [rad], and
        the reach failure ("too_far" or "too_close", excess [m]) if there are none.
    """
    h = math.cos(theta1) * rel[0] - math.sin(theta1) * rel[1]
    qx, qy = _Z0 - rel[2], _H0 - h
    vx, vy = _ACROSS0 - (_T[0] * math.cos(alpha) - _T[1] * math.sin(alpha)), _ALONG
    n_q, n_v = math.hypot(qx, qy), math.hypot(vx, vy)
    if n_q < 1e-12:
        return [], ("too_close", _REACH_MIN)
    # |W|^2 = |Q|^2 + |v|^2 - 2 |Q| |v| cos(delta), delta = psi + angle(v) - angle(Q).
    lo_c = (n_q * n_q + n_v * n_v - _REACH_MAX ** 2) / (2.0 * n_q * n_v)
    hi_c = (n_q * n_q + n_v * n_v - _REACH_MIN ** 2) / (2.0 * n_q * n_v)
    if lo_c > 1.0:
        return [], ("too_far", abs(n_q - n_v) - _REACH_MAX)
    if hi_c < -1.0:
        return [], ("too_close", _REACH_MIN - (n_q + n_v))
    d_lo, d_hi = math.acos(min(hi_c, 1.0)), math.acos(max(lo_c, -1.0))
    margin = min(math.radians(0.5), 0.25 * (d_hi - d_lo))
    d_lo, d_hi = d_lo + margin, d_hi - margin
    shift = math.atan2(qy, qx) - math.atan2(vy, vx)
    return [(d_lo + shift, d_hi + shift), (shift - d_hi, shift - d_lo)], None


def _pitch_candidates(windows, psi0: float, step: float = math.radians(2.0)):
    """Pitches inside ``windows`` [rad], nearest ``psi0`` first.

    ``psi0`` itself if a window holds it, then the points of the windows
    nearest to it and a grid over them, sorted by distance.
    """
    nearest = []
    for low, high in windows:
        centre = 0.5 * (low + high)
        psi = centre + _wrap(psi0 - centre)
        if low <= psi <= high:
            yield psi
        nearest.append(min(max(psi, low), high))
    candidates = list(nearest)
    for low, high in windows:
        n = int((high - low) / step) + 1
        candidates += [low + (k + 0.5) * (high - low) / n for k in range(n)]
    yield from sorted(candidates, key=lambda psi: abs(_wrap(psi - psi0)))


class _Search:
    """Collects in-limit solutions (keeping the one nearest the reference) and the failures."""

    def __init__(self, reference: Sequence[float]):
        self.reference = reference
        self.best: list[float] | None = None
        self.best_cost = math.inf
        self.reach_failures: list[tuple[str, float]] = []
        self.axis_failures: list[tuple[str, float]] = []
        self.limit_failures: list[tuple[float, int, float, float, list[float]]] = []

    def try_pitch(self, rel: tuple, theta1: float, alpha: float, psi: float) -> bool:
        """Try both elbow branches at a known pan, roll and arm pitch; True if one fits."""
        found = False
        roll = _wrap(alpha - _TILT)
        reference = self.reference
        for elbow in (1.0, -1.0):
            angles, failure = _planar(rel, theta1, alpha, psi, elbow)
            if failure is not None:
                self.reach_failures.append(failure)
                return False  # both branches fail alike
            theta = [theta1, angles[0], angles[1], angles[2], roll]
            worst = None
            cost = 0.0
            for i in range(5):
                value = theta[i]
                lower, upper = _LIMITS[i]
                if value < lower or value > upper:
                    excess = lower - value if value < lower else value - upper
                    if excess <= _LIMIT_SLACK:
                        value = theta[i] = lower if value < lower else upper
                    elif worst is None or excess > worst[0]:
                        worst = (excess, i, value, lower if value < lower else upper, theta)
                cost += (value - reference[i]) ** 2
            if worst is not None:
                self.limit_failures.append(worst)
                continue
            if cost < self.best_cost:
                self.best, self.best_cost = theta, cost
            found = True
        return found

    def try_approach(self, rel: tuple, alpha0: float, yaw_tied: bool, psi: float,
                     backwards: bool) -> bool:
        """Try a target with a given approach pitch ``psi`` [rad] from the radial direction."""
        theta1, alpha, failure = _pan(rel, alpha0, yaw_tied, backwards)
        if failure is not None:
            self.axis_failures.append(failure)
            return False
        # Reaching backwards, the arm's plane faces away from the target.
        return self.try_pitch(rel, theta1, alpha, math.pi - psi if backwards else psi)

    def error(self, what: str) -> UnreachableError:
        """The most helpful error: the smallest joint-limit excess, else the smallest reach miss."""
        if self.limit_failures:
            excess, i, value, limit, _ = min(self.limit_failures, key=lambda f: f[0])
            joint = ARM_JOINTS[i]
            return UnreachableError(
                f"{what} needs {joint} = {math.degrees(value):.2f} deg, beyond its limit "
                f"{math.degrees(limit):.2f} deg by {math.degrees(excess):.2f} deg (every other "
                "solution is further off). Fix: move the target, or change the approach or yaw.",
                "joint_limit", math.degrees(excess), joint)
        if self.reach_failures:
            reason, excess = min(self.reach_failures, key=lambda failure: failure[1])
            if reason == "too_far":
                return UnreachableError(
                    f"{what} is {excess * 1e3:.1f} mm beyond the arm's reach (the two links span "
                    f"at most {_REACH_MAX * 1e3:.1f} mm from the shoulder_lift axis to the "
                    "wrist_flex axis). Fix: move the target closer to the base.", "too_far", excess)
            excess = max(excess, 0.0)
            return UnreachableError(
                f"{what} is {excess * 1e3:.1f} mm too close to the shoulder for the arm to fold "
                "onto. Fix: move the target away from the base.", "too_close", excess)
        _, excess = min(self.axis_failures, key=lambda failure: failure[1])
        return UnreachableError(
            f"{what} is {excess * 1e3:.3f} mm too close to the shoulder_pan axis: the arm's plane "
            f"passes up to {(abs(_LATERAL0) + math.hypot(_T[0], _T[1])) * 1e3:.1f} mm beside the "
            "axis. Fix: move the target away from the axis.", "too_close", excess)


# ---------------------------------------------------------------------------
# Public solver.
def as_position(position) -> tuple[float, float, float]:
    """A position as three finite floats (x, y, z) [m], each within ``POSITION_LIMIT``.

    Raises:
        KinematicsTypeError: not three numbers (text, None and booleans are refused).
        KinematicsInputError: a coordinate is not finite or beyond ``POSITION_LIMIT``.
    """
    try:
        values = list(position)
    except TypeError:
        values = None
    if isinstance(position, (str, bytes)) or values is None or len(values) != 3:
        raise KinematicsTypeError(
            f"position must be three numbers (x, y, z) [m], got {describe_value(position)}. "
            "Fix: pass a tuple such as (0.2, 0.0, 0.013).")
    out = []
    for axis, value in zip("xyz", values, strict=True):
        if isinstance(value, (str, bytes, bool, np.bool_)) or value is None or not isinstance(
                value, numbers.Real):
            raise KinematicsTypeError(
                f"position {axis} must be a number [m], got {describe_value(value)}. Fix: pass "
                "three numbers (x, y, z) [m] without quotes.")
        if not is_finite_number(value):
            raise KinematicsInputError(
                f"position {axis} must be finite, got {describe_value(value)} (position "
                f"{describe_value(list(values))}). Fix: pass three finite numbers [m].")
        out.append(check_number(value, f"position {axis}", -POSITION_LIMIT, POSITION_LIMIT, "m",
                                error=KinematicsInputError,
                                fix="give the position in metres, in the base frame."))
    return out[0], out[1], out[2]


def _check_gripper(value) -> float:
    """The gripper opening as a float in ``GRIPPER_RANGE``."""
    low, high = GRIPPER_RANGE
    error = KinematicsInputError if is_finite_number(value) or (
        isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))) \
        else KinematicsTypeError
    return check_number(value, "gripper", low, high, "%", error=error,
                        fix=f"give an opening in [{low:g}, {high:g}] (0 closed, 100 open).")


def get_inverse_kinematics(
    position,
    approach: str | None = "down",
    yaw_deg: float | None = 0.0,
    pitch_deg: float | None = None,
    initial: Mapping[str, float] | None = None,
    *,
    gripper: float | None = None,
    min_height: float = MIN_HEIGHT,
) -> dict[str, float]:
    """Joint configuration that puts the object frame at ``position``.

    The solutions within the joint limits differ in shoulder_pan (facing the
    target, or reaching back over the base), elbow (up or down), the grasp
    (the cube's four sides, 90 deg of roll apart) and, when free, the roll or
    pitch. They are tried from the one nearest ``initial`` outwards; of the
    first set that fits (both elbow branches), the one nearest ``initial`` in
    joint space is returned.

    Args:
        position: where the object frame (the held cube's centre) should be,
            (x, y, z) [m] in the base frame.
        approach: "down" (tool z straight down), "pitch" (tool z ``pitch_deg``
            below the horizontal) or None (position only).
        yaw_deg: the cube's yaw [deg]: the angle from the world x axis to one
            of its face normals; the jaws close along one (every 90 deg is the
            same cube). None: any yaw, the wrist_roll nearest the reference's
            first. Ignored when ``approach`` is None.
        pitch_deg: approach pitch [deg] for ``approach="pitch"``: 90 is
            top-down, 0 horizontal pointing away from the base; the jaw axis
            is the top-down grasp's for ``yaw_deg``, tilted about the arm's
            sideways axis.
        initial: configuration [deg] to stay near, e.g. the current one
            (default ``REFERENCE_CONFIGURATION``): it picks the branch, the
            roll when the yaw is free and the pitch for a position-only target.
        gripper: opening in the result [0, 100] (default: the ``initial``'s,
            else ``GRIPPER_OPEN``).
        min_height: lowest accepted target z [m] (default: a cube resting on
            the table, 1 mm of tolerance).

    Returns:
        Configuration: the five arm joints [deg] and ``gripper`` [0, 100].

    Raises:
        UnreachableError: the target is below the table, too far, too close,
            or needs a joint beyond its limit; the message says which and by
            how much.
        so101_forward_kinematics.KinematicsInputError: malformed arguments (a
            ValueError; text, None and booleans where numbers belong raise its
            subclass ``KinematicsTypeError``, also a TypeError): a position
            beyond ``POSITION_LIMIT``, a yaw or pitch outside ``ANGLE_RANGE_DEG``,
            a gripper outside [0, 100].
    """
    p = as_position(position)
    if approach not in ("down", "pitch", None):
        raise KinematicsInputError(f"approach must be 'down', 'pitch' or None, got "
                                   f"{describe_value(approach)}. Fix: use one of those.")
    if approach == "pitch":
        if pitch_deg is None:
            raise KinematicsInputError("approach='pitch' needs a finite pitch_deg (90 = "
                                       "top-down), got None. Fix: pass pitch_deg.")
        pitch_deg = check_angle(pitch_deg, "pitch_deg")
    elif pitch_deg is not None:
        raise KinematicsInputError(f"pitch_deg needs approach='pitch' (got approach="
                                   f"{approach!r}). Fix: pass approach='pitch' or no pitch_deg.")
    if yaw_deg is not None:
        yaw_deg = check_angle(yaw_deg, "yaw_deg")
    min_height = check_number(min_height, "min_height", -POSITION_LIMIT, POSITION_LIMIT, "m",
                              error=KinematicsInputError)
    if gripper is not None:
        gripper = _check_gripper(gripper)
    if p[2] < min_height:
        short = min_height - p[2]
        raise UnreachableError(
            f"Target z = {p[2]:.4f} m is {short * 1e3:.1f} mm below the lowest allowed height "
            f"{min_height:.4f} m (a cube resting on the table has its centre {CUBE_HALF_SIZE} m "
            "up). Fix: raise the target.", "below_table", short)
    reference = _DEFAULT_REFERENCE if initial is None else [
        math.radians(v) for v in joint_angles(initial)]
    if gripper is None:
        gripper = GRIPPER_OPEN if initial is None else _check_gripper(
            initial.get("gripper", GRIPPER_OPEN))
    psi = None if approach is None else math.radians(90.0 if approach == "down" else pitch_deg)
    yaw = None if yaw_deg is None or approach is None else math.radians(yaw_deg)
    theta = _solve(p, psi, yaw, reference)
    cfg = {joint: math.degrees(value) for joint, value in zip(ARM_JOINTS, theta, strict=True)}
    cfg["gripper"] = float(gripper)
    return cfg


def _describe(p, psi) -> str:
    where = f"Target ({p[0]:.4f}, {p[1]:.4f}, {p[2]:.4f}) m"
    if psi is None:
        return where
    if psi == _QUARTER:
        return where + " with a top-down approach"
    return where + f" with a {math.degrees(psi):g} deg approach pitch"


def _solve(p: tuple, psi: float | None, yaw: float | None, reference: list[float]) -> list[float]:
    """Arm angles [rad] for a checked target (see :func:`get_inverse_kinematics`)."""
    rel = (p[0] - _C[0], p[1] - _C[1], p[2] - _C[2])
    search = _Search(reference)
    if psi is None:
        _search_position_only(rel, reference, search)
    elif yaw is None:
        for fine in (False, True):
            if fine and not _worth_fine_search(search):
                break
            for roll in _roll_candidates(reference[_ROLL], rel, fine):
                for backwards in (False, True):
                    if search.try_approach(rel, roll + _TILT, False, psi, backwards):
                        break
                if search.best is not None:
                    break
            if search.best is not None:
                break
    else:
        # Cube yaw = pi - pan + alpha: alpha = (yaw - pi + k pi/2) + pan for the
        # four grasps k. Try them by how near their roll is to the reference's
        # (the pan is about -azimuth), stopping at the first that fits.
        azimuth = math.atan2(rel[1], rel[0])
        base = yaw - math.pi
        k0 = round((reference[_ROLL] + _TILT + azimuth - base) / _QUARTER)
        for backwards in (False, True):
            for k in (k0, k0 + 1, k0 - 1, k0 + 2):
                if search.try_approach(rel, _wrap(base + k * _QUARTER), True, psi, backwards):
                    break
            if search.best is not None:
                break
    theta = search.best
    if theta is None and (psi is None or yaw is None) and search.limit_failures:
        theta = _rescue(p, psi, yaw, search)
    if theta is None:
        raise search.error(_describe(p, psi))
    return _check(theta, p, psi, yaw)


def _roll_candidates(roll0: float, rel: tuple, fine: bool = False) -> list[float]:
    """Wrist_roll values [rad] to try when the roll is free.

    Coarse: ``roll0``, then every 10 deg by distance from it. Fine (for targets
    at the edge of the workspace): every 1 deg and both limits. For a target
    within a few mm of the pan axis, first the two rolls that put the arm's
    plane through the axis (sideways offset ``L = 0``).
    """
    lower, upper = _LIMITS[_ROLL]
    if fine:
        rolls = [math.radians(a) for a in range(-157, 163)] + [lower, upper]
    else:
        grid = [math.radians(a) for a in range(-180, 180, 10)]
        rolls = [roll0] + sorted(grid, key=lambda roll: abs(roll - roll0))
    if math.hypot(rel[0], rel[1]) < 0.006:
        # L = _LATERAL0 + _T[0] sin(alpha) + _T[1] cos(alpha) = 0.
        amplitude, phase = math.hypot(_T[0], _T[1]), math.atan2(_T[1], _T[0])
        beta = math.asin(-_LATERAL0 / amplitude)
        rolls = [_wrap(beta - phase - _TILT), _wrap(math.pi - beta - phase - _TILT)] + rolls
    return [roll for roll in rolls if lower <= roll <= upper]


def _worth_fine_search(search: _Search) -> bool:
    """Whether a finer roll search could succeed: a near miss of the reach or of a limit.

    The roll moves the object frame by at most |(0.0051, -0.000218)| = 5.1 mm
    (a few degrees of joint angle unless the target is near the pan axis).
    """
    return (bool(search.axis_failures)
            or any(excess < 0.006 for _, excess in search.reach_failures)
            or any(failure[0] < math.radians(10.0) for failure in search.limit_failures))


def _search_position_only(rel: tuple, reference: list[float], search: _Search) -> None:
    """Fill ``search`` for a position-only target: wrist_roll and pitch nearest the reference's.

    Rolls every 10 deg, pitches every 2 deg inside the reach windows; targets
    whose in-limit solutions fall between these samples (thin slivers at the
    joint limits) are left to :func:`_rescue`.
    """
    psi0 = reference[1] + reference[2] + reference[3]
    for roll in _roll_candidates(reference[_ROLL], rel):
        alpha = roll + _TILT
        for backwards in (False, True):
            theta1, _, failure = _pan(rel, alpha, False, backwards)
            if failure is not None:
                search.axis_failures.append(failure)
                continue
            windows, failure = _pitch_windows(rel, theta1, alpha)
            if failure is not None:
                search.reach_failures.append(failure)
                continue
            lower, upper = _LIMITS[_PAN]
            if not lower <= theta1 <= upper:
                limit = lower if theta1 < lower else upper
                search.limit_failures.append((abs(theta1 - limit), _PAN, theta1, limit, None))
                continue
            for psi in _pitch_candidates(windows, psi0):
                if search.try_pitch(rel, theta1, alpha, psi):
                    return


def _rescue(p: tuple, psi: float | None, yaw: float | None, search: _Search) -> list[float] | None:
    """Damped least squares from the nearest out-of-limit solutions, limits enforced.

    For a free roll or pitch, in-limit solutions can lie between the samples
    of the closed-form search (near the edges of the workspace).
    """
    near = math.radians(10.0)  # further off, the roll or pitch cannot make up for it
    tried = sorted((f for f in search.limit_failures if f[4] is not None and f[0] < near),
                   key=lambda f: f[0])
    for *_, theta in tried[:3]:
        log.debug("No sampled solution within limits at %s; damped least squares from %s [rad].",
                  p, [round(v, 4) for v in theta])
        start = [min(max(v, lo), hi) for v, (lo, hi) in zip(theta, _LIMITS, strict=True)]
        refined, residual = _refine(start, p, psi, yaw)
        if residual <= SOLVE_TOL:
            return refined
    return None


# ---------------------------------------------------------------------------
# Check against the FK and numerical refinement.
def _approach_direction(theta1: float, p: tuple, psi: float) -> np.ndarray:
    """Wanted approach (tool z) direction, unit (3,), for shoulder_pan ``theta1`` [rad]."""
    # The arm's plane points along Rz(-pan) x; the approach's horizontal part
    # points away from the base, flipped when the arm reaches backwards.
    cx, sy = math.cos(theta1), -math.sin(theta1)
    if cx * (p[0] - _C[0]) + sy * (p[1] - _C[1]) < 0.0:
        cx, sy = -cx, -sy
    return np.array([math.cos(psi) * cx, math.cos(psi) * sy, -math.sin(psi)])


def _task(chain: np.ndarray, p: np.ndarray, psi: float | None, yaw: float | None):
    """Residual and Jacobian of the constraints at a configuration.

    Rows: the position error [m] (3); with a vertical approach, the tilt of
    the approach axis (3: the sine of the angle, about the correcting axis)
    and, with a yaw, the jaw's angle to the nearest face normal [rad] (1);
    with a pitched approach, the error of the approach's vertical component (1).

    Returns:
        ``(error, jacobian)``: (k,) and (k, 5).
    """
    g_wt = chain[5]
    jac = _jacobian_from_chain(chain)
    errors = [p - g_wt[:3, 3]]
    rows = [jac[:3]]
    if psi is not None:
        z_t = g_wt[:3, 2]
        if abs(math.cos(psi)) < 1e-9:
            wanted = np.array([0.0, 0.0, -math.copysign(1.0, math.sin(psi))])
            errors.append(np.cross(z_t, wanted))
            rows.append(jac[3:] - np.outer(wanted, wanted @ jac[3:]))  # tilt only
            if yaw is not None:
                x_t = g_wt[:3, 0]
                jaw = np.array([math.cos(yaw), math.sin(yaw), 0.0])
                angle = math.atan2(float(np.cross(x_t, jaw) @ wanted), float(x_t @ jaw))
                errors.append([(angle + math.pi / 4) % _QUARTER - math.pi / 4])
                rows.append((wanted @ jac[3:])[None])
        else:
            errors.append([-math.sin(psi) - z_t[2]])
            rows.append((np.cross(z_t, [0.0, 0.0, 1.0]) @ jac[3:])[None])
    return np.concatenate(errors), np.vstack(rows)


def _refine(theta: Sequence[float], p: tuple, psi: float | None, yaw: float | None,
            max_iterations: int = 100, damping: float = 1e-5) -> tuple[list[float], float]:
    """Damped least squares on the analytic Jacobian, joint limits enforced by clipping.

    Args:
        theta: start [rad].
        p: target position [m].
        psi: approach pitch [rad] or None (position only).
        yaw: cube yaw [rad] of a vertical approach, or None (free).
        max_iterations: iteration cap.
        damping: lambda of ``dq = J^T (J J^T + lambda^2 I)^-1 e``.

    Returns:
        The refined angles [rad] and the largest remaining residual.
    """
    theta = np.array(theta, dtype=float)
    lower = np.array([lo for lo, _ in _LIMITS])
    upper = np.array([hi for _, hi in _LIMITS])
    target = np.array(p)
    residual = math.inf
    history = []
    for _ in range(max_iterations):
        error, jac = _task(_chain(theta), target, psi, yaw)
        residual = float(np.max(np.abs(error)))
        history.append(residual)
        if residual < REFINE_TOL or (len(history) > 20 and residual > 0.5 * history[-11]):
            break  # converged, or stuck (at a limit, or on an unreachable target)
        # Joints at a limit that the step would push further out leave the
        # task (active set), so the others can slide along the limit.
        free = np.ones(len(theta), dtype=bool)
        for _ in range(len(theta)):
            jac_free = jac * free
            step = jac_free.T @ np.linalg.solve(
                jac_free @ jac_free.T + damping ** 2 * np.eye(len(error)), error)
            pushing = ((theta <= lower) & (step < 0.0)) | ((theta >= upper) & (step > 0.0))
            if not pushing.any():
                break
            free &= ~pushing
        theta = np.clip(theta + step, lower, upper)
    return [float(v) for v in theta], residual


def _check(theta: list[float], p: tuple, psi: float | None, yaw: float | None) -> list[float]:
    """Check a closed-form result with the FK; refine it if it is off by more than REFINE_TOL."""
    cfg = dict(zip(ARM_JOINTS, map(math.degrees, theta), strict=True))
    position, rotation = get_forward_kinematics(cfg)
    x, y, z = position.tolist()
    error = max(abs(x - p[0]), abs(y - p[1]), abs(z - p[2]))
    if psi is not None:
        (xx, _, zx), (xy, _, zy), (xz, _, zz) = rotation.tolist()
        approach_dir = _approach_direction(theta[_PAN], p, psi)
        ax, ay, az = approach_dir.tolist()
        # Angle between the approach axis and the wanted one (from the cross product).
        sin_angle = math.sqrt((zy * az - zz * ay) ** 2 + (zz * ax - zx * az) ** 2
                              + (zx * ay - zy * ax) ** 2)
        error = max(error, sin_angle if zx * ax + zy * ay + zz * az > 0.0 else 1.0)
        if psi == _QUARTER and yaw is not None:
            angle = math.atan2(xx * math.sin(yaw) - xy * math.cos(yaw),
                               xx * math.cos(yaw) + xy * math.sin(yaw))
            error = max(error, abs((angle + math.pi / 4) % _QUARTER - math.pi / 4))
    if error <= REFINE_TOL:
        return theta
    log.debug("Closed form off by %.3g at %s; refining by damped least squares.", error, p)
    refined, norm = _refine(theta, p, psi, yaw)
    if norm > SOLVE_TOL:
        raise UnreachableError(
            f"{_describe(p, psi)}: the solver stopped {norm:.2g} away from it (a degenerate "
            "pose?). Fix: move the target a little.", "no_convergence", norm)
    return refined


# ---------------------------------------------------------------------------
# Sampling (tests, benchmarks, the workspace picture).
def sample_top_down_targets(n: int, seed: int = 0, min_height: float = MIN_HEIGHT):
    """Reachable top-down grasps: FK of random in-limit configurations with a vertical approach.

    Shoulder_pan, shoulder_lift, elbow_flex and wrist_roll are drawn uniformly
    within their limits, wrist_flex = 90 deg - shoulder_lift - elbow_flex
    makes the approach vertical; draws with wrist_flex outside its limits or
    the cube below ``min_height`` are dropped, so fewer than ``n`` may return.

    Args:
        n: configurations to draw.
        seed: random seed.
        min_height: lowest object-frame z kept [m].

    Returns:
        ``(angles, positions, yaws)``: (m, 5) [deg] in ``ARM_JOINTS`` order,
        (m, 3) [m] and (m,) cube yaw [deg].
    """
    rng = np.random.default_rng(seed)
    lower = np.array([JOINT_LIMITS[j][0] for j in ARM_JOINTS])
    upper = np.array([JOINT_LIMITS[j][1] for j in ARM_JOINTS])
    angles = rng.uniform(lower, upper, size=(n, len(ARM_JOINTS)))
    angles[:, 3] = 90.0 - angles[:, 1] - angles[:, 2]
    angles = angles[(angles[:, 3] >= lower[3]) & (angles[:, 3] <= upper[3])]
    positions, rotations = get_forward_kinematics_batch(angles)
    keep = positions[:, 2] >= min_height
    yaws = np.degrees(np.arctan2(rotations[keep, 1, 0], rotations[keep, 0, 0]))
    return angles[keep], positions[keep], yaws

"""The IK's entry point: inputs checked, the closed-form search, refinement, the checked result."""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping

import numpy as np

from so101_kinematics.constants import CUBE_HALF_SIZE
from so101_kinematics.errors import KinematicsInputError, KinematicsTypeError, UnreachableError
from so101_kinematics.fast_fk import forward_kinematics_batch
from so101_kinematics.frames import (
    ARM_JOINTS,
    GRIPPER_RANGE,
    JOINT_LIMITS,
    check_angle,
    joint_angles,
)
from so101_kinematics.ik.geometry import (
    _C,
    _DEFAULT_REFERENCE,
    _LATERAL0,
    _LIMITS,
    _PAN,
    _QUARTER,
    _ROLL,
    _T,
    _TILT,
    GRIPPER_OPEN,
    MIN_HEIGHT,
    POSITION_LIMIT,
    SOLVE_TOL,
    _wrap,
    log,
)
from so101_kinematics.ik.refine import _check, _describe, _refine
from so101_kinematics.ik.search import _pan, _pitch_candidates, _pitch_windows, _Search
from so101_kinematics.inputs import check_number, describe_value, is_finite_number

__all__ = ["as_position", "sample_top_down_targets", "solve_keywords"]


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


def solve_keywords(
    position,
    approach: str | None = "down",
    yaw_deg: float | None = 0.0,
    pitch_deg: float | None = None,
    initial: Mapping[str, float] | None = None,
    *,
    gripper: float | None = None,
    min_height: float = MIN_HEIGHT,
    exact_yaw: bool = False,
) -> dict[str, float]:
    """Joint configuration that puts the object frame at ``position`` (the keyword form).

    ``so101_inverse_kinematics.get_inverse_kinematics`` takes the course's
    positional shapes and these keywords, and calls this.

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
            At a top-down grasp the object frame is ``Rz(yaw)`` for one of the
            four grasps: ``yaw = wrist_roll - shoulder_pan + GRIPPER_MOUNT_TILT_DEG``.
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
        exact_yaw: the object frame's yaw itself (``Rz(yaw_deg)`` first, the
            cube's other three grasps only if it is out of reach); default: the
            grasp whose wrist_roll is nearest the reference's first.

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
    theta = _solve(p, psi, yaw, reference, exact_yaw)
    cfg = {joint: math.degrees(value) for joint, value in zip(ARM_JOINTS, theta, strict=True)}
    cfg["gripper"] = float(gripper)
    return cfg


def _solve(p: tuple, psi: float | None, yaw: float | None, reference: list[float],
           exact_yaw: bool = False) -> list[float]:
    """Arm angles [rad] for a checked target (see :func:`solve_keywords`)."""
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
        # Object-frame yaw = alpha - pan (alpha = roll + tilt): alpha = (yaw + k pi/2)
        # + pan for the cube's four grasps k. Try them from the exact yaw (k = 0)
        # or by how near their roll is to the reference's (the pan is about
        # -azimuth), stopping at the first that fits.
        azimuth = math.atan2(rel[1], rel[0])
        base = yaw
        k0 = 0 if exact_yaw else round((reference[_ROLL] + _TILT + azimuth - base) / _QUARTER)
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
            or any(failure[1] < 0.006 for failure in search.reach_failures)
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
    positions, rotations = forward_kinematics_batch(angles)
    keep = positions[:, 2] >= min_height
    yaws = np.degrees(np.arctan2(rotations[keep, 1, 0], rotations[keep, 0, 0]))
    return angles[keep], positions[keep], yaws


"""The closed-form search of the IK: shoulder_pan, the planar three-link chain, pitch windows."""

from __future__ import annotations

import math
from collections.abc import Sequence

from so101_kinematics.errors import UnreachableError
from so101_kinematics.frames import (
    ARM_JOINTS,
)
from so101_kinematics.ik.geometry import (
    _A,
    _ACROSS0,
    _ALONG,
    _B,
    _H0,
    _KINK,
    _LATERAL0,
    _LEN_A,
    _LEN_B,
    _LIMIT_SLACK,
    _LIMITS,
    _REACH_MAX,
    _REACH_MIN,
    _T,
    _TILT,
    _Z0,
    _wrap,
)
from so101_kinematics.inputs import format_limit

__all__ = ["_Search", "_pan", "_pitch_candidates", "_pitch_windows"]


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
        ``((theta2, theta3, theta4), None)`` or ``(None, (reason, excess [m], (forward,
        up) [m]))``: where the wrist_flex axis would be from the shoulder_lift axis.
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
        return None, ("too_far", math.sqrt(dist2) - _REACH_MAX, (-wy, -wx))
    if cos_q < -1.0:
        return None, ("too_close", _REACH_MIN - math.sqrt(dist2), (-wy, -wx))
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
        the reach failure ("too_far" or "too_close", excess [m], (forward, up) [m] of the
        target from the shoulder_lift axis) if there are none.
    """
    h = math.cos(theta1) * rel[0] - math.sin(theta1) * rel[1]
    qx, qy = _Z0 - rel[2], _H0 - h
    vx, vy = _ACROSS0 - (_T[0] * math.cos(alpha) - _T[1] * math.sin(alpha)), _ALONG
    n_q, n_v = math.hypot(qx, qy), math.hypot(vx, vy)
    if n_q < 1e-12:
        return [], ("too_close", _REACH_MIN, (0.0, 0.0))
    # |W|^2 = |Q|^2 + |v|^2 - 2 |Q| |v| cos(delta), delta = psi + angle(v) - angle(Q).
    lo_c = (n_q * n_q + n_v * n_v - _REACH_MAX ** 2) / (2.0 * n_q * n_v)
    hi_c = (n_q * n_q + n_v * n_v - _REACH_MIN ** 2) / (2.0 * n_q * n_v)
    if lo_c > 1.0:
        return [], ("too_far", abs(n_q - n_v) - _REACH_MAX, (-qy, -qx))
    if hi_c < -1.0:
        return [], ("too_close", _REACH_MIN - (n_q + n_v), (-qy, -qx))
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


def reach_fix(forward: float, up: float, too_far: bool) -> str:
    """Which way to move a target out of reach, from where the wrist would be.

    Args:
        forward: the wrist_flex axis from the shoulder_lift axis, along the arm [m].
        up: the same, upwards [m].
        too_far: beyond the links' reach (move towards the shoulder), else too close.

    Returns:
        e.g. "lower (down)", "closer to the base", "lower and closer to the base".

    Example:
        >>> reach_fix(0.02, 0.5, True), reach_fix(0.4, -0.05, True)
        ('lower (down)', 'closer to the base')
    """
    sign = -1.0 if too_far else 1.0  # too far: towards the shoulder; too close: away
    norm = math.hypot(forward, up) or 1.0
    words = []
    if abs(up) >= 0.4 * norm:
        words.append("higher (up)" if sign * up > 0 else "lower (down)")
    if abs(forward) >= 0.4 * norm:
        words.append("away from the base" if sign * forward > 0 else "closer to the base")
    if len(words) == 2:
        words[0] = words[0].split(" (")[0]
    return " and ".join(words) or ("closer to the base" if too_far else "away from the base")


class _Search:
    """Collects in-limit solutions (keeping the one nearest the reference) and the failures."""

    def __init__(self, reference: Sequence[float]):
        self.reference = reference
        self.best: list[float] | None = None
        self.best_cost = math.inf
        self.reach_failures: list[tuple[str, float, tuple[float, float]]] = []
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
                f"{format_limit(math.degrees(limit))} deg by {math.degrees(excess):.2f} deg "
                "(every other solution is further off). Fix: move the target, or change the "
                "approach or yaw.",
                "joint_limit", math.degrees(excess), joint)
        if self.reach_failures:
            reason, excess, (forward, up) = min(self.reach_failures,
                                                key=lambda failure: failure[1])
            if reason == "too_far":
                return UnreachableError(
                    f"{what} is {excess * 1e3:.1f} mm beyond the arm's reach (the two links span "
                    f"at most {_REACH_MAX * 1e3:.1f} mm from the shoulder_lift axis to the "
                    f"wrist_flex axis). Fix: move the target {reach_fix(forward, up, True)}.",
                    "too_far", excess)
            excess = max(excess, 0.0)
            return UnreachableError(
                f"{what} is {excess * 1e3:.1f} mm too close to the shoulder for the arm to fold "
                f"onto. Fix: move the target {reach_fix(forward, up, False)}.", "too_close",
                excess)
        _, excess = min(self.axis_failures, key=lambda failure: failure[1])
        return UnreachableError(
            f"{what} is {excess * 1e3:.3f} mm too close to the shoulder_pan axis: the arm's plane "
            f"passes up to {(abs(_LATERAL0) + math.hypot(_T[0], _T[1])) * 1e3:.1f} mm beside the "
            "axis. Fix: move the target away from the axis.", "too_close", excess)



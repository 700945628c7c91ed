"""Refinement and checking of IK solutions: damped least squares on the analytic Jacobian."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from so101_kinematics.errors import UnreachableError
from so101_kinematics.fast_fk import forward_kinematics
from so101_kinematics.frames import (
    ARM_JOINTS,
)
from so101_kinematics.ik.geometry import (
    _C,
    _LIMITS,
    _PAN,
    _QUARTER,
    _ROLL,
    REFINE_TOL,
    SOLVE_TOL,
    chain_from_radians,
    jacobian_from_chain,
    log,
)

__all__ = ["_check", "_describe", "_refine", "line_task"]


# ---------------------------------------------------------------------------
# Check against the FK and numerical refinement.
def _describe(p, psi) -> str:
    where = f"Target ({p[0]:.4f}, {p[1]:.4f}, {p[2]:.4f}) m"
    if psi is None:
        return where
    if psi == _QUARTER:
        return where + " with a top-down approach"
    return where + f" with a {math.degrees(psi):g} deg approach pitch"



def _approach_direction(theta1: float, p: tuple, psi: float) -> np.ndarray:
    """Wanted approach direction (tool -z), unit (3,), for shoulder_pan ``theta1`` [rad]."""
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
    jac = jacobian_from_chain(chain)
    errors = [p - g_wt[:3, 3]]
    rows = [jac[:3]]
    if psi is not None:
        z_t = -g_wt[:3, 2]  # the approach axis: wrist to fingertips, the tool's -z
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
        error, jac = _task(chain_from_radians(theta), target, psi, yaw)
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
    position, rotation = forward_kinematics(cfg)
    x, y, z = position.tolist()
    error = max(abs(x - p[0]), abs(y - p[1]), abs(z - p[2]))
    if psi is not None:
        (xx, _, zx), (xy, _, zy), (xz, _, zz) = (-rotation).tolist()  # approach = -z
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




def top_down_task(theta: Sequence[float], p: Sequence[float],
                  yaw: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Residual and analytic Jacobian of a top-down grasp at ``p`` (resolved-rate control).

    Args:
        theta: the arm's five joint angles [rad].
        p: the object frame's wanted position [m].
        yaw: the jaw's yaw [rad] (modulo 90 deg, a cube's faces are alike).

    Returns:
        ``(error, jacobian)``: the position error [m] (3), the approach axis's tilt (3)
        and the jaw's yaw error [rad] (1); and their (7, 5) Jacobian.
    """
    return _task(chain_from_radians(theta), np.asarray(p, dtype=float), _QUARTER, yaw)


def line_task(theta: Sequence[float], p: Sequence[float], approach: Sequence[float],
              roll: float) -> tuple[np.ndarray, np.ndarray]:
    """Residual and analytic Jacobian of a pose on a straight line (``straight_line.py``).

    Args:
        theta: the arm's five joint angles [rad].
        p: the object frame's wanted position [m].
        approach: the wanted approach axis (the tool's -z), a unit vector; (0, 0, -1) is
            top-down.
        roll: the wanted wrist_roll [rad].

    Returns:
        ``(error, jacobian)``: the position error [m] (3), the approach axis's tilt from the
        wanted one (3: the sine of the angle, about the correcting axis) and the wrist_roll
        error [rad] (1); and their (7, 5) Jacobian (as :func:`top_down_task`'s rows).
    """
    chain = chain_from_radians(theta)
    g_wt = chain[5]
    jac = jacobian_from_chain(chain)
    wanted = np.asarray(approach, dtype=float)
    z_t = -g_wt[:3, 2]  # the approach axis: wrist to fingertips
    roll_row = np.zeros((1, len(theta)))
    roll_row[0, _ROLL] = 1.0
    error = np.concatenate([np.asarray(p, dtype=float) - g_wt[:3, 3], np.cross(z_t, wanted),
                            [roll - theta[_ROLL]]])
    return error, np.vstack([jac[:3], jac[3:] - np.outer(wanted, wanted @ jac[3:]), roll_row])

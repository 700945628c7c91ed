"""The pen in its holder, and the IK that puts its tip on a point at a chosen tilt.

The holder is the course's cube (``constants.CUBE_SIZE``) printed with a bore through its
centre along the approach axis; the jaws hold it as they hold the cube (the object frame
is its centre), and the pen slides in the bore against a spring (a pen plotter's holder:
a height error of a few millimetres changes the pen's force, not its line). The stock
jaws do not hold a bare pen: a round pen rolls and slips between two flat pads (the Fall
2025 tic-tac-toe group gave up drawing for that), the cube's flat faces do not.

The tip is ``PEN_TIP_BELOW_CENTRE`` along the approach axis (the tool's -z) from the
object frame, the spring at rest. The IK here holds the tip at a point, the approach at a
tilt from the vertical in the arm's plane (0: the pen upright; positive: the tip leans
away from the base, as :func:`so101_kinematics.ik.call_shapes.get_inverse_kinematics`'s
pitch) and wrist_roll at a fixed angle: five rows for five joints, Newton's method on the
analytic Jacobian (``ik.geometry``'s chain), from the last answer.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from so101_kinematics.constants import CUBE_HALF_SIZE
from so101_kinematics.errors import UnreachableError
from so101_kinematics.frames import ARM_JOINTS, JOINT_RANGES_RAD
from so101_kinematics.ik.call_shapes import get_inverse_kinematics
from so101_kinematics.ik.geometry import chain_from_radians, jacobian_from_chain

__all__ = [
    "GRAVITY", "HOLDER_MASS", "PEN_MASS", "PEN_PRELOAD_M", "PEN_PRESS_M", "PEN_SPRING",
    "PEN_TIP_BELOW_CENTRE", "PenPose", "pen_configuration", "pen_residual", "pressing_force",
    "tip_position",
]

PEN_TIP_BELOW_CENTRE = CUBE_HALF_SIZE + 0.032
"""The pen's tip below the holder's centre (the object frame) [m], the spring at rest: 32 mm
of pen below the holder's bottom face, the fingertips (3 mm above the centre) 48 mm above
the page."""

PEN_PRESS_M = 0.002
"""How far the tip is commanded below the page [m] while drawing: the spring's compression,
whose force holds the pen on the paper (``ink.PEN_SPRING``)."""

PEN_MASS = 0.010
"""A felt-tip pen's mass [kg]."""
HOLDER_MASS = 0.012
"""The printed holder's mass [kg] (the course's cube's size, PLA, hollow): with the pen, a load
at the object frame the gravity feed-forward takes in (``pen_plan``)."""

PEN_SPRING = 150.0
"""The holder's spring [N/m]: 2 mm of press is 0.3 N more on the paper (a felt-tip pen writes
with 0.2-1 N)."""
PEN_PRELOAD_M = 0.0015
"""The spring's compression at the stop [m]: 0.22 N, more than the pen's weight, so the pen
rests on its stop in the air and lifts off it only on the paper."""
GRAVITY = 9.81  # [m/s^2]


def pressing_force(press: float = PEN_PRESS_M) -> float:
    """The tip's force on the paper [N] with the holder ``press`` [m] lower than at a touch.

    The spring's push and the pen's weight: ``k (preload + press) + m g``.

    Example:
        >>> round(pressing_force(), 3)  # 150 N/m x 3.5 mm + 0.010 kg x 9.81 m/s^2
        0.623
    """
    return PEN_SPRING * (PEN_PRELOAD_M + press) + PEN_MASS * GRAVITY


ITERATIONS = 30
TOLERANCE = 1e-7  # [m] and [rad]: the residual of an answer


class PenPose:
    """What the pen holds besides its tip's position: the tilt and the wrist's roll.

    Attributes:
        tilt: the pen's lean from the vertical [rad], in the arm's plane (positive: the tip
            away from the base).
        roll: wrist_roll [rad].
        reach: the tip's distance from the object frame along the approach axis [m].
    """

    def __init__(self, tilt_deg: float = 0.0, roll_deg: float = 0.0,
                 reach: float = PEN_TIP_BELOW_CENTRE):
        self.tilt = math.radians(tilt_deg)
        self.roll = math.radians(roll_deg)
        self.reach = reach


def tip_position(cfg: Mapping[str, float], reach: float = PEN_TIP_BELOW_CENTRE) -> np.ndarray:
    """The pen's tip [m] at configuration ``cfg`` [deg] (the spring at rest)."""
    theta = np.radians([cfg[j] for j in ARM_JOINTS])
    g_wt = chain_from_radians(theta)[5]
    return g_wt[:3, 3] - reach * g_wt[:3, 2]


def pen_residual(theta: np.ndarray, tip: Sequence[float],
                 pose: PenPose) -> tuple[np.ndarray, np.ndarray]:
    """Residual and Jacobian of the pen's task at ``theta`` [rad].

    Rows: the tip's position error [m] (3); the pen's pitch error [rad] (1: the approach's
    angle below the horizontal, in the arm's plane, wanted ``pi/2 - tilt``); the
    wrist_roll error [rad] (1).

    Returns:
        ``(error, jacobian)``: (5,) and (5, 5).
    """
    chain = chain_from_radians(theta)
    jac = jacobian_from_chain(chain)
    g_wt = chain[5]
    a = -g_wt[:3, 2]  # the approach axis: along the pen, towards its tip
    turn = np.cross(jac[3:].T, a).T  # d a / d theta_j = omega_j x a: (3, 5)
    tip_jac = jac[:3] + pose.reach * turn
    pan = theta[0]
    h = np.array([math.cos(pan), -math.sin(pan), 0.0])  # the arm's plane, outwards
    u, v = -a[2], float(a @ h)
    du = -turn[2]
    dv = h @ turn
    dv[0] += a @ np.array([-math.sin(pan), -math.cos(pan), 0.0])
    pitch_row = (v * du - u * dv) / (u * u + v * v)
    roll_row = np.zeros(5)
    roll_row[4] = 1.0
    error = np.concatenate([np.asarray(tip, dtype=float) - (g_wt[:3, 3] + pose.reach * a),
                            [math.pi / 2 - pose.tilt - math.atan2(u, v)],
                            [pose.roll - theta[4]]])
    return error, np.vstack([tip_jac, pitch_row, roll_row])


_LOWER = np.array([JOINT_RANGES_RAD[j][0] for j in ARM_JOINTS])
_UPPER = np.array([JOINT_RANGES_RAD[j][1] for j in ARM_JOINTS])


def _first_guess(tip: Sequence[float], pose: PenPose) -> np.ndarray:
    """The course's IK for the holder's centre above ``tip`` at the pen's tilt [rad]."""
    guess = np.asarray(tip, dtype=float) + [0.0, 0.0, pose.reach * math.cos(pose.tilt)]
    cfg = get_inverse_kinematics(list(guess), approach="pitch",
                                 pitch_deg=90.0 - math.degrees(pose.tilt), min_height=-1.0)
    return np.radians([cfg[j] for j in ARM_JOINTS])


def pen_configuration(tip: Sequence[float], pose: PenPose,
                      initial: Mapping[str, float] | None = None) -> dict[str, float]:
    """The arm's configuration [deg] that puts the pen's tip at ``tip`` [m] as ``pose`` says.

    Args:
        tip: where the tip goes (x, y, z) [m] in the base frame.
        pose: the pen's tilt, the wrist's roll and the tip's reach.
        initial: the last answer [deg] (a path stays on its branch); None: the course's
            IK gives the first guess.

    Returns:
        The five arm joints [deg].

    Raises:
        UnreachableError: the tip cannot be there at that tilt within the joint limits.
    """
    theta = (_first_guess(tip, pose) if initial is None
             else np.radians([initial[j] for j in ARM_JOINTS]))
    for _ in range(ITERATIONS):
        error, jac = pen_residual(theta, tip, pose)
        if float(np.max(np.abs(error))) < TOLERANCE:
            return dict(zip(ARM_JOINTS, np.degrees(theta).tolist(), strict=True))
        step = np.linalg.solve(jac.T @ jac + 1e-10 * np.eye(5), jac.T @ error)
        theta = np.clip(theta + step, _LOWER, _UPPER)
    raise UnreachableError(
        f"the pen's tip cannot reach ({', '.join(f'{1e3 * v:.0f}' for v in tip)}) mm at a "
        f"{math.degrees(pose.tilt):g} deg tilt (residual {np.max(np.abs(error)):.2g}). Fix: "
        "move the page closer to the arm.", "no_convergence", float(np.max(np.abs(error))))

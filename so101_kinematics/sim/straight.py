"""A straight line in task space, two ways (assignment 9's optional part), in simulation.

The object frame goes from ``p0`` to ``pf`` along the segment with the cubic time
scaling ``s(t)`` (``p = (1 - s) p0 + s pf``), held top-down at yaw 0, the commands
computed every ``CONTROL_DT`` as a control loop would:

- ``"ik"``: the IK at every cycle (``get_inverse_kinematics`` from the last answer);
- ``"resolved_rate"``: resolved-rate control with the analytic Jacobian
  (``ik.refine.top_down_task``): ``dq = J^T (J J^T + lambda^2 I)^-1 (v + K e) dt``, the
  segment's velocity ``v`` fed forward and the task error ``e`` fed back, joint limits
  enforced by clipping.

:func:`max_path_deviation_mm` measures the object frame's largest distance from the
segment over the move and a short settle.
"""

from __future__ import annotations

import math

import numpy as np

from so101_kinematics.fast_fk import forward_kinematics
from so101_kinematics.frames import ARM_JOINTS, JOINT_RANGES_RAD, TOOL_SITE
from so101_kinematics.ik.course import get_inverse_kinematics
from so101_kinematics.ik.refine import top_down_task
from so101_kinematics.profiles import PROFILES
from so101_kinematics.sim import stepping
from so101_kinematics.sim.scene import set_initial_pose
from so101_kinematics.sim.tracking import StepLog

METHODS = ("ik", "resolved_rate")
FROM = (0.25, 0.1, 0.04425)  # [m]: 3 cm above the page's first block
TO = (0.25, -0.1, 0.04425)  # [m]: 3 cm above its second
DURATION_S = 2.0  # [s], the page's move
CONTROL_DT = 0.01  # [s]: a 100 Hz loop, as the real arm's (rounded to whole physics steps)
SETTLE_S = 1.0  # [s] at the start before the line, and measured after it
RATE_GAIN = 20.0  # [1/s]: K, the task error's feedback
DAMPING = 1e-3  # lambda of the damped least squares
GRIPPER = 0.0  # closed


class SiteLog(StepLog):
    """A :class:`StepLog` that also records the object frame's position [m] each step."""

    def __init__(self, m, d, viewer=None):
        super().__init__(m, d, viewer)
        self.positions: list[np.ndarray] = []

    def sync(self) -> None:
        """Record the step and the object frame's position; pass frames on."""
        self.positions.append(self.d.site(TOOL_SITE).xpos.copy())
        super().sync()


def run_straight(m, d, method: str, viewer=None, p0=FROM, pf=TO,
                 duration: float = DURATION_S) -> SiteLog:
    """Place the arm at ``p0`` (top-down), settle, then run the line by ``method``.

    Returns:
        The log of the line and the settle after it (positions in ``.positions``).
    """
    p0, pf = np.asarray(p0, dtype=float), np.asarray(pf, dtype=float)
    cfg = get_inverse_kinematics(list(p0), gripper=GRIPPER)
    set_initial_pose(d, cfg)
    stepping.hold_position(m, d, viewer, SETTLE_S, raise_if_closed=True)
    log = SiteLog(m, d, viewer)
    theta = np.radians([cfg[j] for j in ARM_JOINTS])
    lower, upper = (np.array([JOINT_RANGES_RAD[j][k] for j in ARM_JOINTS]) for k in (0, 1))
    cubic = PROFILES["cubic"]
    period = max(1, round(CONTROL_DT / m.opt.timestep)) * m.opt.timestep  # [s]
    cycles = max(1, round(duration / period))
    for k in range(1, cycles + 1):
        s = k / cycles
        p = p0 + cubic(s) * (pf - p0)
        if method == "ik":
            cfg = get_inverse_kinematics(list(p), initial=cfg, gripper=GRIPPER)
        else:
            v = cubic.velocity(s) / (cycles * period) * (pf - p0)  # [m/s]
            error, jac = top_down_task(theta, p)
            wanted = RATE_GAIN * error
            wanted[:3] += v
            rate = jac.T @ np.linalg.solve(jac @ jac.T + DAMPING**2 * np.eye(len(error)),
                                           wanted)
            theta = np.clip(theta + rate * period, lower, upper)
            cfg = dict(zip(ARM_JOINTS, map(math.degrees, theta), strict=True),
                       gripper=GRIPPER)
        stepping.hold_position(m, d, log, cfg, period, raise_if_closed=True)
    stepping.hold_position(m, d, log, SETTLE_S, raise_if_closed=True)
    return log


def figures(log: SiteLog, p0=FROM, pf=TO) -> dict[str, float]:
    """The line's figures [mm].

    ``max_path_deviation_mm``: the measured object frame's over the line and the settle
    after it; ``start_offset_mm``: how far from ``p0`` the arm was when the line began
    (its sag); ``command_deviation_mm``: the commands' own (their FK), the method's share.
    """
    start = np.asarray(log.positions[0]) if log.positions else np.asarray(p0, dtype=float)
    commands = log.arrays()["command"]
    commanded = [forward_kinematics(dict(zip(ARM_JOINTS, row[:5], strict=True)))[0]
                 for row in commands.tolist()]
    return {"max_path_deviation_mm": max_path_deviation_mm(log.positions, p0, pf),
            "start_offset_mm": float(np.linalg.norm(start - np.asarray(p0)) * 1e3),
            "command_deviation_mm": max_path_deviation_mm(commanded, p0, pf)}


def max_path_deviation_mm(positions, p0=FROM, pf=TO) -> float:
    """The largest distance [mm] of ``positions`` (n, 3) [m] from the segment ``p0``-``pf``.

    Example:
        >>> max_path_deviation_mm([[0.0, 0.0, 0.001], [0.5, 0.002, 0.0], [1.25, 0.0, 0.0]],
        ...                       (0.0, 0.0, 0.0), (1.0, 0.0, 0.0))  # beyond the end: 0.25 m
        250.0
    """
    p0, pf = np.asarray(p0, dtype=float), np.asarray(pf, dtype=float)
    x = np.asarray(positions, dtype=float).reshape(-1, 3)
    if len(x) == 0:
        return 0.0
    length = float(np.linalg.norm(pf - p0))
    u = (pf - p0) / length if length > 0.0 else np.zeros(3)
    along = np.clip((x - p0) @ u, 0.0, length)
    return float(np.linalg.norm(x - p0 - along[:, None] * u, axis=1).max() * 1e3)

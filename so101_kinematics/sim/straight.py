"""A straight line in task space, two ways (assignment 9's optional part), in simulation.

The path itself (the object frame along the segment with the cubic time scaling, by IK
at every cycle or by resolved-rate control) is planned by
``so101_kinematics.planning.straight_line``, the same code the arm's ``--approach
straight`` runs; here it is executed on MuJoCo, one command per ``CONTROL_DT``, and
:func:`figures` measures MuJoCo's object frame.
"""

from __future__ import annotations

import numpy as np

from so101_kinematics.fast_fk import forward_kinematics
from so101_kinematics.frames import ARM_JOINTS, TOOL_SITE
from so101_kinematics.ik.call_shapes import get_inverse_kinematics
from so101_kinematics.planning.straight_line import CONTROL_DT, max_path_deviation_mm, straight_path
from so101_kinematics.sim import stepping
from so101_kinematics.sim.scene import set_initial_pose
from so101_kinematics.sim.tracking import StepLog

__all__ = ["DURATION_S", "FROM", "SETTLE_S", "TO", "control_period", "figures", "run_straight"]

FROM = (0.25, 0.1, 0.04425)  # [m]: 3 cm above the page's first block
TO = (0.25, -0.1, 0.04425)  # [m]: 3 cm above its second
DURATION_S = 2.0  # [s], the page's move
SETTLE_S = 1.0  # [s] at the start before the line, and measured after it
APPROACH_S = 2.0  # [s]: the page's move, from its all-zero start to the line's start
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


def control_period(m) -> float:
    """``CONTROL_DT`` [s] rounded to whole physics steps of ``m`` (at least one)."""
    return max(1, round(CONTROL_DT / m.opt.timestep)) * m.opt.timestep


def run_straight(m, d, method: str, viewer=None, p0=FROM, pf=TO,
                 duration: float = DURATION_S) -> SiteLog:
    """Move the arm to ``p0`` (top-down) as a run does, settle, then run the line by ``method``.

    The arm starts at the page's all-zero pose and reaches ``p0`` by a cubic move, so
    every joint arrives from a known side: a servo stops within its friction band of its
    goal, and the gravity feed-forward takes that band out only when it knows the side
    (``gravity.Feedforward``). Put down at ``p0`` instead, the arm rests up to 2.8 mm
    from it (0.5 deg at the shoulder on 5 V), more than the line's own error.

    Returns:
        The log of the line and the settle after it (positions in ``.positions``).
    """
    cfg = get_inverse_kinematics(list(p0), gripper=GRIPPER)
    set_initial_pose(d, {name: 0.0 for name in cfg})  # the page's start: all zero
    stepping.move_to_pose(m, d, viewer, cfg, APPROACH_S, profile="cubic", raise_if_closed=True)
    stepping.hold_position(m, d, viewer, SETTLE_S, raise_if_closed=True)
    log = SiteLog(m, d, viewer)
    period = control_period(m)
    goal = get_inverse_kinematics(list(pf), initial=cfg, gripper=GRIPPER)
    for sample in straight_path(cfg, goal, duration, method, period):
        stepping.hold_position(m, d, log, sample, period, raise_if_closed=True)
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


"""From a planned command to the Goal_Position written: the last checks and the offsets.

The control loop (``hw/control.py``) plans in the model's angles; what reaches the
servos is, in this order: the plan (refused outside the calibrated range,
:func:`guard`), plus the velocity lead (``hw/lead.py``, during a move), plus the
gravity feed-forward (``gravity.Feedforward``), clamped into the calibrated range,
plus the trims (``trims.Trims``). Only the first is what the checks judge.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping

from so101_kinematics.errors import JointLimitError, PortLost
from so101_kinematics.frames import JOINTS
from so101_kinematics.gravity import Feedforward
from so101_kinematics.hw.bus import clamp_to_limits, port_lost
from so101_kinematics.inputs import (
    LIMIT_TOLERANCE,
    Configuration,
    Limits,
    limit_excess,
    limit_message,
)
from so101_kinematics.trims import Trims

__all__ = ["goal_for", "guard", "send_goal"]

logger = logging.getLogger(__name__)


def guard(command: Mapping[str, float], limits: Limits) -> Configuration:
    """Last line of defence: refuse a command outside the calibrated range (nothing sent).

    Raises:
        JointLimitError: a joint beyond its range by more than ``checks.LIMIT_TOLERANCE``.
    """
    out = {}
    for joint in JOINTS:
        lower, upper = limits[joint]
        value = command[joint]
        if limit_excess(value, lower, upper) > LIMIT_TOLERANCE:
            message = limit_message(joint, value, lower, upper, "the calibrated range")
            raise JointLimitError(f"Command {message}; nothing was sent.")
        out[joint] = min(upper, max(lower, value))
    return out


def goal_for(command: Mapping[str, float], feedforward: Feedforward | None, limits: Limits,
             led: Mapping[str, float] | None = None) -> Configuration:
    """The goal written for ``command`` (or its ``led`` goal): plus gravity, in the range."""
    goal = dict(led if led is not None else command)
    if feedforward is None or not feedforward.enabled:
        return clamp_to_limits(goal, limits) if led is not None else goal
    return clamp_to_limits(feedforward.apply(goal), limits)


def send_goal(bus, trims: Trims, goal: Mapping[str, float]) -> None:
    """Write ``goal`` (the model's angles) plus the trims; a lost port raises, else a warning."""
    try:
        bus.sync_write("Goal_Position", trims.to_wire(goal))
    except Exception as error:  # noqa: BLE001 - a broadcast gets no reply: only the port fails
        if port_lost(bus):
            raise PortLost.during("sending Goal_Position") from error
        logger.warning("Goal_Position write failed: %s", error)

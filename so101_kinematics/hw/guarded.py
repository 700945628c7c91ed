"""The bus ``setup_motors`` hands a student: lerobot's bus, its goal writes guarded.

The course's scripts write goals themselves (``bus.sync_write("Goal_Position",
offset_config(cfg))``); on a bare lerobot bus that jumps the arm at the
servos' full speed, past every check the helpers make. :class:`GuardedBus`
is lerobot's ``FeetechMotorsBus`` in every other respect (each attribute and
method is the bus's own), except:

- ``sync_write("Goal_Position", values)`` and ``write("Goal_Position", motor,
  value)`` go through the helpers' control loop: the values (lerobot's units,
  what the servos receive: [deg], gripper [0, 100]) are checked against the
  calibrated range and the table (``clearance.py``), and the arm is *ramped*
  there at the speed cap, never jumped; the call returns when it arrived. A
  refusal ends the script as a fault in ``move_to_pose`` does (the policy of
  docs/hardware_safety.md). Raw ticks (``normalize=False``) are refused.
- ``disable_torque()`` is the helpers' ending: released at the starting pose,
  returning there first if away.

Raw lerobot, unguarded, is ``bus.raw`` (the ``FeetechMotorsBus`` itself): for
those who ask for it explicitly, knowing that a goal written there moves the
arm at full speed; the next ``move_to_pose`` or ``hold_position`` then starts
from where the arm stands (:func:`resync`). Only its ``disable_torque`` stays
the helpers' ending (lerobot's ``disconnect()`` calls it), as it always was.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from typing import Any

from so101_kinematics.checks import START_MISMATCH, check_configuration, is_finite_number
from so101_kinematics.errors import BusError, PlanError
from so101_kinematics.frames import ARM_JOINTS, JOINTS
from so101_kinematics.hw.control import ArmSession
from so101_kinematics.hw.feedforward import tracking_allowance
from so101_kinematics.hw.timing import capped_duration

logger = logging.getLogger("so101_utils")

GOAL = "Goal_Position"
RAW_TICKS = ("with normalize=False writes raw ticks, which skip the calibration, the limits and "
             "the speed cap. Fix: write degrees (gripper 0-100) with normalize=True, or use "
             "bus.raw if you really mean raw ticks (the arm then jumps at full speed).")
"""The refusal of a raw-tick goal write (after the call's name)."""


class GuardedBus:
    """lerobot's bus with ``Goal_Position`` writes ramped and checked (see the module).

    Args:
        raw: the connected lerobot ``FeetechMotorsBus`` (``bus.raw``).
        write_goal: ``write_goal(values, what, normalize)``: the helpers' ramped, checked
            move (it refuses ``normalize=False``: :data:`RAW_TICKS`).
        disable_torque: the helpers' ending (release at the starting pose).
    """

    def __init__(self, raw, write_goal: Callable[[dict[str, Any], str, bool], None],
                 disable_torque: Callable[..., None]):
        object.__setattr__(self, "raw", raw)
        object.__setattr__(self, "_write_goal", write_goal)
        object.__setattr__(self, "_disable_torque", disable_torque)

    def __getattr__(self, name: str):
        return getattr(self.raw, name)

    def __setattr__(self, name: str, value) -> None:
        setattr(self.raw, name, value)

    def __repr__(self) -> str:
        return f"GuardedBus({self.raw!r}) (raw lerobot: bus.raw)"

    def sync_write(self, data_name: str, values, normalize: bool = True,
                   num_retry: int = 0) -> None:
        """The bus's ``sync_write``; a ``Goal_Position`` is ramped there at the speed cap."""
        if data_name != GOAL:
            return self.raw.sync_write(data_name, values, normalize=normalize,
                                       num_retry=num_retry)
        what = 'bus.sync_write("Goal_Position", ...)'
        if not isinstance(values, Mapping):  # lerobot: one value for every motor
            values = dict.fromkeys(self.raw.motors, values)
        self._write_goal(dict(values), what, normalize)
        return None

    def write(self, data_name: str, motor: str, value, normalize: bool = True,
              num_retry: int = 0) -> None:
        """The bus's ``write``; a ``Goal_Position`` is ramped there at the speed cap."""
        if data_name != GOAL:
            return self.raw.write(data_name, motor, value, normalize=normalize,
                                  num_retry=num_retry)
        self._write_goal({motor: value}, f'bus.write("Goal_Position", {motor!r}, ...)',
                         normalize)
        return None

    def disable_torque(self, motors=None, num_retry: int = 0) -> None:
        """The course's last call: the arm is released at its starting pose (returning first)."""
        self._disable_torque(motors, num_retry)


def ramp_to_goal(session: ArmSession, values: Mapping[str, Any], what: str) -> None:
    """Move to a goal a student wrote, at the speed cap; returns when the arm is there.

    Args:
        session: the helpers' session.
        values: joint -> lerobot's value (what the servos receive, trims included: the
            course's ``offset_config(cfg)``); joints left out keep their goal.
        what: the call, for messages.

    Raises:
        PlanError: an unknown motor or a value that is not a number; and whatever
            ``ArmSession.move`` raises (the calibrated range, the table, a fault).
    """
    unknown = [j for j in values if j not in JOINTS]
    if unknown:
        raise PlanError(f"{what}: unknown motor {unknown[0]!r}; the motors are "
                        f"{', '.join(JOINTS)}.")
    bad = [j for j in values if not is_finite_number(values[j])]
    if bad:
        raise PlanError(f"{what}: {bad[0]} = {values[bad[0]]!r} is not a finite number of "
                        "degrees (gripper 0-100). Fix: write numbers.")
    resync(session)
    start = session.command
    goal = dict(start, **session.trims.from_wire({j: float(v) for j, v in values.items()}))
    check_configuration(goal, session.limits, f"{what} (calibrated range)")  # before the log
    seconds = max(capped_duration(start, goal, 0.0, session.profile, session.max_speed),
                  session.loop.period)
    joint = max(goal, key=lambda j: abs(goal[j] - start[j]))
    step = abs(goal[joint] - start[joint])
    (logger.warning if step > START_MISMATCH else logger.debug)(
        "%s: ramped at the speed cap (%s moves %.1f, over %.2f s), not jumped at the servos' "
        "full speed; the call returns when the arm is there (bus.raw writes unguarded).",
        what, joint, step, seconds)
    session.move(goal, seconds)


def resync(session: ArmSession) -> None:
    """Start from where the arm stands if it is elsewhere than the last command.

    A goal written on ``bus.raw`` (or by another program) moved the arm outside the
    loop: each arm joint more than ``START_MISMATCH`` (plus the sag the servo has there
    without the feed-forward) from its last command starts the next move or hold from its
    measured position, never jumping back to the stale command.
    """
    try:
        measured = session.read_pose()
    except BusError:  # a glitch: the loop itself rides it through (or ends by the policy)
        return
    allowed = tracking_allowance(session.feedforward, dict.fromkeys(ARM_JOINTS, START_MISMATCH),
                                 session.command, session.command, 1.0)  # plus the sag at rest
    moved = [j for j in ARM_JOINTS if abs(measured[j] - session.command[j]) > allowed[j]]
    if moved:
        logger.warning("The arm is not where it was last commanded (%s; a goal written on "
                       "bus.raw?): the move starts from where it stands.",
                       ", ".join(f"{j} {measured[j]:.1f} vs {session.command[j]:.1f} deg"
                                 for j in moved))
        limits = session.limits
        session.command = dict(session.command, **{
            j: min(limits[j][1], max(limits[j][0], measured[j])) for j in moved})

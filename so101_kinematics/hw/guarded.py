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
  returning there first if away; so is a write of ``Torque_Enable`` 0 (on any motor:
  the whole arm is released there, as ``disable_torque``).
- every other write that can drop, spin or weaken the arm is refused in one line
  with the fix and the way around (:data:`REFUSED`, :func:`register_refusal`): the
  motion registers (Torque_Limit, Max_Torque_Limit, P/I/D, Operating_Mode,
  Goal_Velocity, Acceleration) unless written to the course's own value
  (``hw/servo_settings.py``: a no-op, as lerobot's configuration writes them);
  the servo's identity, bus and calibration (ID, Baud_Rate, Lock, Homing_Offset,
  Min/Max_Position_Limit) and any other register, always; and lerobot's calls that
  write those (:data:`REFUSED_CALLS`). The refusal ends the script as a refused
  raw-tick goal does (exit status 2), the arm returned to its start and released.

Raw lerobot, unguarded, is ``bus.raw`` (the ``FeetechMotorsBus`` itself): for
those who ask for it explicitly, knowing that a goal written there moves the
arm at full speed and a register written there may drop or spin it (the last
line then names each servo that cannot hold, read back); the next
``move_to_pose`` or ``hold_position`` then starts from where the arm stands
(:func:`resync`). Only its ``disable_torque`` stays the helpers' ending
(lerobot's ``disconnect()`` calls it), as it always was.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from typing import Any

from so101_kinematics.errors import BusError, PlanError
from so101_kinematics.frames import ARM_JOINTS, JOINTS
from so101_kinematics.hw.control import ArmSession
from so101_kinematics.hw.feedforward import tracking_allowance
from so101_kinematics.hw.servo_settings import COURSE, course_value
from so101_kinematics.hw.timing import capped_duration
from so101_kinematics.inputs import START_MISMATCH, check_configuration, is_finite_number

__all__ = ["GuardedBus", "RAW_TICKS", "ramp_to_goal", "resync"]

logger = logging.getLogger("so101_utils")

GOAL = "Goal_Position"
RAW_TICKS = ("with normalize=False writes raw ticks, which skip the calibration, the limits and "
             "the speed cap. Fix: write degrees (gripper 0-100) with normalize=True, or use "
             "bus.raw if you really mean raw ticks (the arm then jumps at full speed).")
"""The refusal of a raw-tick goal write (after the call's name)."""

TORQUE = "Torque_Enable"
_DROPS = "below what the arm's weight needs, the arm drops with torque on"
_GAINS = "is a gain of the servo's loop: other values make it creep, overshoot or shake"
REFUSED = {
    "Torque_Limit": f"caps the servo's push: {_DROPS}",
    "Max_Torque_Limit": f"caps Torque_Limit: {_DROPS}",
    "P_Coefficient": "is the servo's stiffness: a low P lets the arm sag and drop with torque on",
    "I_Coefficient": _GAINS,
    "D_Coefficient": _GAINS,
    "Operating_Mode": ("takes the servo out of position control (1: a wheel that spins at "
                       "Goal_Velocity into its stop, still driven after the script ends)"),
    "Goal_Velocity": ("caps the servo's speed below the helpers' moves (the next move then "
                      "aborts as a stall); in wheel mode it spins the joint"),
    "Acceleration": "is the servo's own ramp: other values lag or jerk the helpers' moves",
    "ID": "is the servo's address: this program loses it (lerobot-setup-motors sets the ids)",
    "Baud_Rate": ("is the servo's bus speed: it stops answering this program "
                  "(lerobot-setup-motors sets it)"),
    "Lock": "unlocks the servo's EEPROM: every later write there becomes permanent",
    "Homing_Offset": "is the calibration: every angle and limit moves (lerobot-calibrate)",
    "Min_Position_Limit": "is the calibration: the servo's own limit (lerobot-calibrate)",
    "Max_Position_Limit": "is the calibration: the servo's own limit (lerobot-calibrate)",
}
"""Register -> what a write does to the arm; those in ``servo_settings.COURSE`` pass when
written to the course's own value. A register in neither is refused too."""
SLOWER = "for a slower move pass a longer duration to move_to_pose (the helpers cap the speed)"
REFUSED_CALLS = {
    "torque_disabled": ("releases the torque wherever the arm is (it falls)",
                        "bus.disable_torque() releases it at the starting pose"),
    "write_calibration": ("rewrites the servos' calibration", "run lerobot-calibrate"),
    "reset_calibration": ("rewrites the servos' calibration", "run lerobot-calibrate"),
    "set_half_turn_homings": ("rewrites the servos' calibration", "run lerobot-calibrate"),
    "setup_motor": ("rewrites a servo's id and bus speed", "run lerobot-setup-motors"),
    "set_baudrate": ("changes the bus speed", "run lerobot-setup-motors"),
}
"""lerobot's own calls that write those registers: refused on the guarded bus (on bus.raw not)."""


def _same(value, target: int) -> bool:
    try:
        return float(value) == target
    except (TypeError, ValueError):
        return False


def register_refusal(register: str, values: Mapping[str, Any], what: str,
                     how: str) -> str | None:
    """The one-line refusal of a register write, or None when it is the course's own value.

    Args:
        register: the register (lerobot's name).
        values: motor -> value written.
        what: the call as written, for the message.
        how: the same call on the raw bus (the way around).
    """
    if register in COURSE and all(_same(v, course_value(register, j)) for j, v in values.items()):
        return None
    does = REFUSED.get(register, "is not one the course's helpers let a script write: it can "
                                 "change how the servo moves or answers")
    if register in ("Goal_Velocity", "Acceleration"):
        fix = SLOWER
    elif register in COURSE:
        course = sorted({course_value(register, j) for j in values} or {COURSE[register][0]})
        fix = (f"leave it at the course's {'/'.join(map(str, course))} "
               "(setup_motors puts it back)")
    else:
        fix = "leave it to lerobot's setup tools, with no script running"
    return (f"Refused: {what}: {register} {does}. Fix: {fix}; to write it anyway, support the "
            f"arm and use {how} (lerobot's bus, unguarded).")


class GuardedBus:
    """lerobot's bus with ``Goal_Position`` writes ramped and checked (see the module).

    Args:
        raw: the connected lerobot ``FeetechMotorsBus`` (``bus.raw``).
        write_goal: ``write_goal(values, what, normalize)``: the helpers' ramped, checked
            move (it refuses ``normalize=False``: :data:`RAW_TICKS`).
        disable_torque: the helpers' ending (release at the starting pose).
        refuse: ``refuse(line)``: prints the refusal and ends the script (never returns).
    """

    def __init__(self, raw, write_goal: Callable[[dict[str, Any], str, bool], None],
                 disable_torque: Callable[..., None], refuse: Callable[[str], None]):
        object.__setattr__(self, "raw", raw)
        object.__setattr__(self, "_write_goal", write_goal)
        object.__setattr__(self, "_disable_torque", disable_torque)
        object.__setattr__(self, "_refuse", refuse)

    def __getattr__(self, name: str):
        if name in REFUSED_CALLS:
            does, fix = REFUSED_CALLS[name]

            def refused(*_args, **_kwargs) -> None:
                self._refuse(f"Refused: bus.{name}(...) {does}. Fix: {fix}; to call it anyway, "
                             f"support the arm and use bus.raw.{name}(...) (lerobot's bus, "
                             "unguarded).")
            return refused
        return getattr(self.raw, name)

    def __setattr__(self, name: str, value) -> None:
        setattr(self.raw, name, value)

    def __repr__(self) -> str:
        return f"GuardedBus({self.raw!r}) (raw lerobot: bus.raw)"

    def sync_write(self, data_name: str, values, normalize: bool = True,
                   num_retry: int = 0) -> None:
        """The bus's ``sync_write``: a goal ramped, ``Torque_Enable`` 0 released (the module)."""
        written = (values if isinstance(values, Mapping)  # lerobot: one value for every motor
                   else dict.fromkeys(self.raw.motors, values))
        if data_name == GOAL:
            self._write_goal(dict(written), 'bus.sync_write("Goal_Position", ...)', normalize)
            return None
        what = f"bus.sync_write({data_name!r}, {values!r})"
        return self._register(data_name, dict(written), what,
                              what.replace("bus.", "bus.raw.", 1),
                              lambda: self.raw.sync_write(data_name, values, normalize=normalize,
                                                          num_retry=num_retry))

    def write(self, data_name: str, motor: str, value, normalize: bool = True,
              num_retry: int = 0) -> None:
        """The bus's ``write``: a goal ramped, ``Torque_Enable`` 0 released (the module)."""
        if data_name == GOAL:
            self._write_goal({motor: value}, f'bus.write("Goal_Position", {motor!r}, ...)',
                             normalize)
            return None
        what = f"bus.write({data_name!r}, {motor!r}, {value!r})"
        return self._register(data_name, {motor: value}, what,
                              what.replace("bus.", "bus.raw.", 1),
                              lambda: self.raw.write(data_name, motor, value, normalize=normalize,
                                                     num_retry=num_retry))

    def _register(self, data_name: str, values: dict[str, Any], what: str, how: str,
                  write: Callable[[], None]) -> None:
        """A write of another register than the goal: through, released, or refused."""
        if data_name == TORQUE and any(_same(v, 0) for v in values.values()):
            logger.warning("%s: released as bus.disable_torque() releases the arm: at the "
                           "starting pose, returning there slowly first (never dropped where it "
                           "is; %s does that).", what, how)
            self._disable_torque(None, 0)
            return None
        if data_name == TORQUE and all(_same(v, 1) for v in values.values()):
            return write()  # torque on holds the goal register: the helpers' last goal
        refusal = register_refusal(data_name, values, what, how)
        if refusal is not None:
            self._refuse(refusal)
            return None
        return write()

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

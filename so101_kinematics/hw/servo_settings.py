"""The registers that decide how a servo moves: the course's values, put back and read back.

A register an earlier program left (a ``Goal_Velocity`` that slows every move, a
``Torque_Limit`` that lets the arm drop with torque on, a joint left in wheel
mode) survives a power-on of the program but not :func:`restore_course_values`,
which ``setup_motors`` runs with lerobot's configuration and which says what it
changed. At the end of a run :func:`unable_to_hold` reads the servos again and
names each one that cannot hold the pose it is at, and why: the last line is
then what the servos say, never what was commanded.

The course's values (:data:`COURSE`), their sources:

- [LR] lerobot 0.4.4, ``robots/so_follower/so_follower.py`` ``configure()``:
  Operating_Mode 0 (position), P_Coefficient 16, I_Coefficient 0, D_Coefficient 32
  on every joint; the gripper's Max_Torque_Limit 500; and
  ``motors/feetech/feetech.py`` ``configure_motors()``: Acceleration 254.
- [MEM] Feetech's STS memory table: Torque_Limit (48) is loaded from
  Max_Torque_Limit (16) at power-up (so lerobot's arm runs at 1000 on the arm
  joints, the factory Max_Torque_Limit, and 500 on the gripper); Goal_Velocity 0
  is the fastest (lerobot never writes it: a servo after power-up).

``servo.LEROBOT`` and ``servo.LEROBOT_GRIPPER`` hold the same numbers for the models.
"""

from __future__ import annotations

import logging
import math
import statistics
from collections.abc import Mapping

from so101_kinematics import servo
from so101_kinematics.frames import ARM_JOINTS, JOINTS
from so101_kinematics.gravity import holding_torques
from so101_kinematics.hw.bus import configure, discard_stale_input, recover_port, with_retries
from so101_kinematics.hw.cycle_checks import GRIPPER_OVERLOAD, STATUS_BITS
from so101_kinematics.hw.timing import TRACKING_TOLERANCE_DEG

__all__ = [
    "COURSE", "HOLD_REGISTERS", "configure_as_course", "course_value", "describe_unable",
    "describe_unread", "read_back",
    "read_registers", "unable_to_hold",
]

logger = logging.getLogger(__name__)

_ARM, _GRIP = servo.LEROBOT, servo.LEROBOT_GRIPPER
COURSE: dict[str, tuple[int, int]] = {
    "Operating_Mode": (0, 0),
    "P_Coefficient": (_ARM.p, _GRIP.p),
    "I_Coefficient": (_ARM.i, _GRIP.i),
    "D_Coefficient": (_ARM.d, _GRIP.d),
    "Acceleration": (_ARM.acceleration, _GRIP.acceleration),
    "Goal_Velocity": (_ARM.goal_velocity, _GRIP.goal_velocity),
    "Max_Torque_Limit": (_ARM.torque_limit, _GRIP.torque_limit),
    "Torque_Limit": (_ARM.torque_limit, _GRIP.torque_limit),
}
"""Register -> (the arm joints' value, the gripper's): what the course's arm runs at [LR, MEM]."""

_NEW = servo.FACTORY
FACTORY = {"Operating_Mode": 0, "P_Coefficient": _NEW.p, "I_Coefficient": _NEW.i,
           "D_Coefficient": _NEW.d, "Acceleration": _NEW.acceleration,
           "Goal_Velocity": _NEW.goal_velocity, "Max_Torque_Limit": _NEW.torque_limit,
           "Torque_Limit": _NEW.torque_limit}
"""A servo as shipped, or its RAM after power-up [MEM] (``servo.FACTORY``): setting these to
the course's is lerobot's configuration; any other value was left by an earlier program."""

LEFT_BY_CONFIGURE = ("Max_Torque_Limit", "Torque_Limit", "Goal_Velocity")
"""What lerobot's configuration does not write on every joint: :func:`restore_course_values`
writes these (Max_Torque_Limit first: it caps Torque_Limit)."""

MODES = {0: "position", 1: "wheel", 2: "PWM", 3: "step"}
"""Operating_Mode's values [MEM]."""

HOLD_REGISTERS = ("Torque_Enable", "Operating_Mode", "Torque_Limit", "Max_Torque_Limit",
                  "P_Coefficient", "Status", "Present_Voltage")
"""What the ending reads back from every servo (raw values)."""

CONFIRMED = HOLD_REGISTERS[:-1]
"""What the last line names: each read twice and believed only when two reads agree
(``Present_Voltage`` flickers by itself: a reading outside the servo's range is dropped, and
an unread supply is guessed low, :func:`unable_to_hold`)."""

_MAX_VOLTS = max(variant.max_volts for variant in servo.VARIANTS.values())

SAG_LIMIT_DEG = TRACKING_TOLERANCE_DEG
"""A joint that would sag farther than this under the arm's weight [deg] cannot hold: the
loop's stall check calls that much error a stall (``hw/timing.py``)."""


def course_value(register: str, joint: str) -> int:
    """The course's value of ``register`` on ``joint`` (:data:`COURSE`)."""
    arm, gripper = COURSE[register]
    return gripper if joint == "gripper" else arm


def read_registers(bus, registers, confirm: tuple[str, ...] = (), attempts: int = 3
                   ) -> dict[str, dict[str, int]]:
    """Register -> joint -> raw value, for each register that could be read (others left out).

    The port is settled first and after a failed read: a late reply to an earlier read
    (one byte, as most of these) would otherwise be taken for the next register's. A
    register in ``confirm`` counts only when two reads agree, so that a late reply that
    slips past the settling (a loaded host, a slow bus) is never reported as the servo's
    setting. Each register gets ``attempts`` reads (one more when confirmed).
    """
    values = {}
    recover_port(bus)
    for register in registers:
        seen: list[dict[str, int]] = []
        for _ in range(attempts + (register in confirm)):
            try:
                discard_stale_input(bus)
                value = {j: int(v) for j, v in
                         bus.sync_read(register, normalize=False, num_retry=1).items()}
            except Exception as error:  # noqa: BLE001 - unread: the caller says what it does not know
                recover_port(bus, settle=isinstance(error, ConnectionError))  # a timeout: settle
                continue
            if register not in confirm or value in seen:
                values[register] = value
                break
            seen.append(value)
    return values


def configure_as_course(bus, who: str) -> None:
    """Lerobot's configure, then the course's values it leaves; each change logged, torque off.

    One path for every program that arms the servos (``setup_motors`` and
    ``pick_place_hw.py``): a Torque_Limit, Goal_Velocity or gain left by an
    earlier program is put back and named, never kept silently.

    Args:
        bus: the connected lerobot bus.
        who: the program, for the log lines (``"setup_motors"``, ``"pick_place_hw"``).
    """
    before = read_registers(bus, COURSE)  # what an earlier program left
    with_retries(configure, bus)
    changed = with_retries(lambda b: restore_course_values(b, before), bus)
    for leftover, line in changed:  # an earlier program's values: a warning each
        (logger.warning if leftover else logger.info)(
            "%s: %s%s.", who, line, " (left by an earlier program)" * leftover)


def restore_course_values(bus, before: Mapping[str, Mapping[str, int]]
                          ) -> list[tuple[bool, str]]:
    """Write what lerobot's configuration leaves; say which course values were not there.

    Call it after ``hw/bus.py``'s ``configure`` (which writes Operating_Mode, the
    gains and Acceleration), torque off. Each register of :data:`LEFT_BY_CONFIGURE`
    is written where ``before`` differs from the course (every joint when unread).

    Args:
        bus: the connected lerobot bus, torque off.
        before: :func:`read_registers` of :data:`COURSE` before ``configure``.

    Returns:
        (leftover, line) per register that was not the course's value on some joint, e.g.
        ``(True, "Torque_Limit was 0 on shoulder_lift, elbow_flex: set back to the course's
        1000")``; ``leftover``: a value neither the course's nor the factory's (:data:`FACTORY`):
        an earlier program's.
    """
    for register in LEFT_BY_CONFIGURE:
        found = before.get(register, {})
        wrong = {j: course_value(register, j) for j in JOINTS
                 if found.get(j) != course_value(register, j)}
        if wrong:
            bus.sync_write(register, wrong, normalize=False)
    changed = []
    for register, found in before.items():
        for leftover in (True, False):
            wrong = [j for j in JOINTS if j in found and found[j] != course_value(register, j)
                     and (found[j] != FACTORY[register]) == leftover]
            if not wrong:
                continue
            was = sorted({found[j] for j in wrong})
            now = sorted({course_value(register, j) for j in wrong})
            changed.append((leftover, f"{register} was {'/'.join(map(str, was))} on "
                                      f"{', '.join(wrong)}: set back to the course's "
                                      f"{'/'.join(map(str, now))}"))
    return changed


def unable_to_hold(state: Mapping[str, Mapping[str, int]],
                   pose: Mapping[str, float] | None) -> dict[str, str]:
    """The torqued servos that cannot hold the pose they are at, read back, and why.

    A servo cannot hold when it is not in position mode, its duty cap
    (min(Torque_Limit, Max_Torque_Limit)) or its P is 0, a Status bit that stops
    the motion is set (the gripper's overload excepted: squeezing is what it is
    for), or the servo's static law (``servo.holding_error``, at the supply it
    reports) says gravity at ``pose`` needs more than its cap or sags it more than
    :data:`SAG_LIMIT_DEG`. Servos read with torque off are left to the torque's own
    words (limp); registers that were not read decide nothing.

    Args:
        state: :func:`read_registers` of :data:`HOLD_REGISTERS`.
        pose: where the arm is (the model's angles), or None if unread.

    Returns:
        joint -> the reason, naming the register and its value.
    """
    def reg(name: str, joint: str) -> int | None:
        return state.get(name, {}).get(joint)

    # a reading outside every STS3215's range is no supply (a late reply of another register)
    volts = [v / 10.0 for v in state.get("Present_Voltage", {}).values()
             if servo.MIN_VOLTS <= v / 10.0 <= _MAX_VOLTS]
    # unread: the kit's 5 V C001s, the weaker servo (less stiff, less torque than the
    # course's 12 V C018s), so that a guess never claims a hold the arm may not make
    supply = statistics.median(volts) if volts else servo.KIT_SUPPLY_V
    torques = holding_torques(pose) if pose is not None else {}
    reasons = {}
    for joint in JOINTS:
        if reg("Torque_Enable", joint) == 0:
            continue
        mode, p = reg("Operating_Mode", joint), reg("P_Coefficient", joint)
        caps = [c for c in (reg("Torque_Limit", joint), reg("Max_Torque_Limit", joint))
                if c is not None]
        cap = min(caps) if caps else None
        bits = (reg("Status", joint) or 0) & ~(GRIPPER_OVERLOAD if joint == "gripper" else 0)
        faults = [text for bit, text in STATUS_BITS.items() if bits & bit]
        if mode not in (None, 0):
            reasons[joint] = f"Operating_Mode {mode}: {MODES.get(mode, 'unknown')} mode"
        elif cap == 0:
            reasons[joint] = "Torque_Limit 0"
        elif p == 0:
            reasons[joint] = "P_Coefficient 0"
        elif faults:
            reasons[joint] = f"status: {', '.join(faults)}"
        elif joint in ARM_JOINTS and joint in torques and cap is not None and p is not None:
            settings = servo.Settings(p=p, torque_limit=cap)
            error = servo.holding_error(torques[joint], settings, supply,
                                        servo.default_variant(supply))
            if error is None:
                reasons[joint] = f"Torque_Limit {cap}: less than gravity needs here"
            elif abs(math.degrees(error)) > SAG_LIMIT_DEG:
                reasons[joint] = (f"P_Coefficient {p}: it would sag "
                                  f"{abs(math.degrees(error)):.0f} deg under the arm's weight")
    return reasons


def read_back(bus, pose: Mapping[str, float] | None, torque: dict[str, bool] | None
              ) -> tuple[dict[str, bool] | None, dict[str, str], list[str]]:
    """What the servos say now, for a last line.

    Returns (Torque_Enable, :func:`unable_to_hold`, the registers that could not be read):
    the line says what it does not know.

    Args:
        bus: the raw lerobot bus.
        pose: where the arm is (the model's angles), or None if unread.
        torque: Torque_Enable as read just before (``hw/cycle_checks.py``), or None: then this
            read's, if it got one.
    """
    state = read_registers(bus, HOLD_REGISTERS, confirm=CONFIRMED)
    read = state.get("Torque_Enable")
    if torque is None and read and set(read.values()) <= {0, 1}:
        torque = {j: bool(v) for j, v in read.items()}
    unread = [r for r in CONFIRMED  # Torque_Enable: known when read just before
              if r not in state and not (r == "Torque_Enable" and torque is not None)]
    return torque, unable_to_hold(state, pose), unread


def describe_unread(unread: list[str]) -> str:
    """``"P_Coefficient not read back: whether each servo can hold here is unknown"``."""
    return (f"{', '.join(unread)} not read back: whether each servo can hold here is unknown "
            "(a noisy bus; setup_motors puts the course's servo settings back)")


def describe_unable(unable: Mapping[str, str]) -> str:
    """``"UNABLE TO HOLD (read back): shoulder_lift, elbow_flex (Torque_Limit 0) ..."``."""
    groups: dict[str, list[str]] = {}
    for joint, why in unable.items():
        groups.setdefault(why, []).append(joint)
    return "UNABLE TO HOLD (read back): " + "; ".join(
        f"{', '.join(joints)} ({why})" for why, joints in groups.items()) + (
        " (setup_motors puts the course's servo settings back)")

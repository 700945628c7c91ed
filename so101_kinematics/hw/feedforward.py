"""The gravity feed-forward on the real arm: read what the servos run at, then offset each goal.

At connection the servos are asked for what decides their sag: P_Coefficient,
Minimum_Startup_Force, the dead zones, Torque_Limit and Present_Voltage (the
supply as the servos see it). ``gravity.Feedforward`` then offsets each goal by the
error the servo will need to hold gravity there (``ArmSession`` adds it to every
goal written, after the plan and before the trims).
"""

from __future__ import annotations

import logging
import statistics
import time
from collections.abc import Callable

from so101_kinematics import servo
from so101_kinematics.calibration import calibrated_limits
from so101_kinematics.frames import ARM_JOINTS, JOINTS
from so101_kinematics.gravity import Feedforward
from so101_kinematics.hw.bus import clamp_to_limits, enable_torque_in_place, read_pose

__all__ = [
    "RAMP_PERIOD_S", "RAMP_S", "read_feedforward", "sag_allowance", "torque_on_in_place",
    "tracking_allowance",
]

logger = logging.getLogger(__name__)

SETTLE_TIMEOUT_S = 1.0
"""How long torque-on waits for the arm to come back to where it stood [s] (lerobot's
configuration lets it go limp for a moment; at P = 16 it settles in about 0.3 s)."""

RAMP_S, RAMP_PERIOD_S = 0.3, 0.02
"""The goals ramp to the held pose over this [s], one write each period [s]."""

SETTLED_DEG = 1.0
"""Back where it stood: every arm joint within this [deg]."""

REGISTERS = ("P_Coefficient", "Minimum_Startup_Force", "CW_Dead_Zone", "CCW_Dead_Zone",
             "Torque_Limit", "Present_Voltage")
"""What the feed-forward reads from each servo (raw values)."""


def read_feedforward(bus, enabled: bool = True) -> Feedforward:
    """The arm's feed-forward from its servos' registers (offsets only when ``enabled``).

    A register that cannot be read is taken at lerobot's value (and the supply at the
    course's follower's 12 V, ``servo.DEFAULT_SUPPLY_V``: C018s), with a warning: the
    offsets are then only as good as that guess.

    Args:
        bus: a connected lerobot ``FeetechMotorsBus``.
        enabled: ``--gravity-ff`` (``False``: no offsets, the raw sag; the tracking
            check still learns from it how far the arm will sag and lag).
    """
    values: dict[str, dict[str, int]] = {}
    for register in REGISTERS:
        try:
            values[register] = {j: int(v) for j, v in
                                bus.sync_read(register, normalize=False).items()}
        except Exception as error:  # noqa: BLE001 - lerobot raises ConnectionError/RuntimeError
            logger.warning("Cannot read %s for the gravity feed-forward (%s): using lerobot's "
                           "value.", register, error)
            values[register] = {}
    settings = {}
    for joint in JOINTS:
        default = servo.LEROBOT_GRIPPER if joint == "gripper" else servo.LEROBOT

        def value(register: str, fallback: int, joint=joint) -> int:
            return values[register].get(joint, fallback)

        settings[joint] = servo.Settings(
            p=value("P_Coefficient", default.p) or default.p, d=default.d, i=default.i,
            min_startup=value("Minimum_Startup_Force", default.min_startup),
            dead_zone=(value("CW_Dead_Zone", 1) + value("CCW_Dead_Zone", 1)) / 2,
            torque_limit=value("Torque_Limit", default.torque_limit) or default.torque_limit)
    volts = [v / 10.0 for v in values["Present_Voltage"].values() if v > 0]
    supply = statistics.median(volts) if volts else servo.DEFAULT_SUPPLY_V
    if not volts:
        logger.warning("No Present_Voltage read: the gravity feed-forward assumes the course's "
                       "follower's %g V supply (%s servos).", supply,
                       servo.default_variant(supply))
    feedforward = Feedforward(settings, supply, enabled=enabled)
    logger.info("%s", describe_at_pose(bus, feedforward))
    return feedforward


def describe_at_pose(bus, feedforward: Feedforward) -> str:
    """The feed-forward's line, its offsets at the arm's pose as read now, and saying so.

    The offsets change with the pose (gravity's arm): at the all-zero pose (the arm
    stretched up) they are not the arm's, so a pose that cannot be read is named as such.
    """
    if not feedforward.enabled:
        return feedforward.describe(dict.fromkeys(JOINTS, 0.0))
    try:
        pose, where = read_pose(bus), "the arm's pose as read now"
    except Exception:  # noqa: BLE001 - a silent bus: the line still says what it shows
        pose, where = dict.fromkeys(JOINTS, 0.0), "the all-zero pose (the arm's was not read)"
    return f"{feedforward.describe(pose)}; offsets at {where}"


def torque_on_in_place(bus, feedforward: Feedforward | None, start=None, *,
                       clock: Callable[[], float] = time.monotonic,
                       sleep: Callable[[float], None] = time.sleep) -> None:
    """Torque on where the arm stands; with the feed-forward, held there without its sag.

    ``hw/bus.py``'s ``enable_torque_in_place`` sets each goal to the present position
    and turns torque on. With an enabled ``feedforward`` the goals then ramp, over
    ``RAMP_S``, to ``start`` (the pose measured before lerobot's configuration let the
    arm go limp for a moment; default: the present one) plus the offsets, so the arm
    comes back to where it stood and holds there instead of sagging from it by several
    degrees at P = 16. (A servo keeps its goal on its present position while limp: a
    goal written before torque on would be lost.)

    Args:
        bus: the connected bus.
        feedforward: the arm's feed-forward, or None.
        start: joint -> position as written on the wire ([deg], gripper [0, 100]).
        clock: the run's clock [s] (the wall's, or the virtual arm's simulated one).
        sleep: the run's sleep [s], on the same clock.
    """
    enable_torque_in_place(bus)
    if feedforward is None or not feedforward.enabled:
        return
    here = read_pose(bus)
    target = dict(start) if start is not None else dict(here)
    goal = clamp_to_limits(feedforward.apply(target), calibrated_limits(bus.calibration))
    steps = max(1, round(RAMP_S / RAMP_PERIOD_S))
    for k in range(1, steps + 1):
        s = k / steps
        bus.sync_write("Goal_Position", {j: here[j] + s * (goal[j] - here[j]) for j in goal})
        sleep(RAMP_PERIOD_S)
    deadline = clock() + SETTLE_TIMEOUT_S  # back where it stood, then go on
    while clock() < deadline:
        try:
            pose = read_pose(bus)
        except Exception:  # noqa: BLE001 - the control loop's own checks deal with a silent bus
            return
        if all(abs(pose[j] - target[j]) <= SETTLED_DEG for j in ARM_JOINTS):
            return
        sleep(0.02)


def tracking_allowance(feedforward: Feedforward | None, tolerance: dict, previous: dict,
                       command: dict, period: float) -> dict:
    """Tracking tolerances for one cycle: each joint's margin plus the lag and sag it will have.

    Args:
        feedforward: the arm's feed-forward (None: the margins alone).
        tolerance: joint -> margin [deg] (None: unchecked).
        previous: the command before [deg].
        command: this cycle's command [deg].
        period: the loop's period [s] (the commands' change over it is their speed).
    """
    if feedforward is None:
        return tolerance
    speeds = {j: (command[j] - previous[j]) / period for j in command}
    expected = feedforward.expected_errors(previous, speeds)
    return {j: None if allowed is None else allowed + expected.get(j, 0.0)
            for j, allowed in tolerance.items()}


def sag_allowance(feedforward: Feedforward | None, command: dict) -> dict:
    """How far [deg] each joint rests from ``command``: its sag without the feed-forward.

    Nothing with it. A measured start that far off is no mistake.
    """
    if feedforward is None:
        return {}
    return feedforward.expected_errors(command, {})

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

from so101_kinematics import servo
from so101_kinematics.frames import JOINTS
from so101_kinematics.gravity import Feedforward

logger = logging.getLogger(__name__)

REGISTERS = ("P_Coefficient", "Minimum_Startup_Force", "CW_Dead_Zone", "CCW_Dead_Zone",
             "Torque_Limit", "Present_Voltage")
"""What the feed-forward reads from each servo (raw values)."""


def read_feedforward(bus, enabled: bool = True) -> Feedforward:
    """The arm's feed-forward from its servos' registers (offsets only when ``enabled``).

    A register that cannot be read is taken at lerobot's value (and the supply at the
    kit's 5 V), with a warning: the offsets are then only as good as that guess.

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
    supply = statistics.median(volts) if volts else servo.KIT_SUPPLY_V
    if not volts:
        logger.warning("No Present_Voltage read: the gravity feed-forward assumes the kit's "
                       "%g V supply.", supply)
    feedforward = Feedforward(settings, supply, enabled=enabled)
    logger.info("%s", feedforward.describe(dict.fromkeys(JOINTS, 0.0)))
    return feedforward

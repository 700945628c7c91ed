"""The virtual SO-101's lerobot calibration: the shipped one and what only the virtual arm needs.

Loading, checking and lerobot's normalisation live in :mod:`so101_kinematics.calibration`
(one implementation for the real and the virtual arm); here are the virtual
arm's additions: the shipped calibration derived from the model, the one
extra constraint (drive_mode 0) and ticks <-> joint angles as the composition
of lerobot's normalisation with the project's one unit conversion:
Present_Position [ticks] -> ``so101_kinematics.calibration.ticks_to_user`` ([deg], lerobot's
DEGREES; gripper [0, 100], lerobot's RANGE_0_100) -> ``so101_mujoco_utils.to_radians``
[rad] (0..100 spans the model's gripper range), and back.

The shipped calibration (:func:`make_default_calibration`) centres each arm
joint's range on the model's zero (2047 +/- the joint's range, rounded up by a
tick so that lerobot's truncation at the exact joint limit stays inside). The
wrist_roll range of the model is asymmetric (-157.2..162.8 deg): its middle is
not its zero, so its calibration is what lerobot-calibrate records for this
full-turn joint, range 0..4095 (middle 2047.5 = 0 deg); the mapping stays exact
and the model's limits stop the joint. Each servo's encoder reading is the
calibration's present value plus the calibration's Homing_Offset (fixed,
plausible offsets), and the registers are seeded from the calibration, so
``SO101Follower.connect()`` finds the arm calibrated and never prompts.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from pathlib import Path

from so101_kinematics.calibration import (
    MOTOR_IDS,
    ServoCalibration,
    calibration_source_name,
    ticks_to_user,
    user_to_ticks,
)
from so101_kinematics.calibration import load_calibration as load_lerobot_calibration
from so101_kinematics.errors import CalibrationError
from so101_kinematics.paths import CALIBRATION_DIR
from so101_kinematics.servo import COUNTS_PER_TURN

__all__ = [
    "DEFAULT_CALIBRATION_PATH", "TICKS_PER_RAD", "load_calibration",
    "make_default_calibration", "present_to_radians", "radians_to_present",
]

DEFAULT_CALIBRATION_PATH = CALIBRATION_DIR / "virtual_so101.json"

TICKS_PER_RAD = (COUNTS_PER_TURN - 1) / (2.0 * math.pi)  # lerobot's scale (360 deg = 4095 ticks)

# Plausible encoder offsets of the virtual arm's servo horns (any |value| <= 2047 works).
DEFAULT_HOMING_OFFSETS = {"shoulder_pan": 143, "shoulder_lift": -612, "elbow_flex": 488,
                          "wrist_flex": -251, "wrist_roll": 97, "gripper": -705}
FULL_TURN_JOINTS = ("wrist_roll",)  # recorded as 0..4095 by lerobot-calibrate


def make_default_calibration(m) -> dict[str, dict[str, int]]:
    """The virtual arm's calibration, derived from the model's joint ranges.

    Arm joints: range centred on 2047 (the model's zero), half-width = the
    joint's largest |limit| in ticks rounded up; full-turn joints (wrist_roll):
    0..4095. Gripper: 2047.5 +/- half its range, so 0..100 spans it.

    Args:
        m: the MuJoCo model (``so101_mujoco_utils.load_model()``).

    Returns:
        Joint name -> {id, drive_mode, homing_offset, range_min, range_max}.
    """
    calibration = {}
    for name, servo_id in MOTOR_IDS.items():
        lower, upper = (float(x) for x in m.joint(name).range)
        if name in FULL_TURN_JOINTS:
            range_min, range_max = 0, COUNTS_PER_TURN - 1
        elif name == "gripper":
            span = round((upper - lower) * TICKS_PER_RAD)
            range_min = COUNTS_PER_TURN // 2 - (span + 1) // 2  # about the encoder's middle
            range_max = range_min + span
        else:
            half = math.ceil(max(abs(lower), abs(upper)) * TICKS_PER_RAD - 1e-9)
            range_min, range_max = 2047 - half, 2047 + half
        calibration[name] = {"id": servo_id, "drive_mode": 0,
                             "homing_offset": DEFAULT_HOMING_OFFSETS[name],
                             "range_min": range_min, "range_max": range_max}
    return calibration


def load_calibration(calibration: str | Path | Mapping) -> dict[str, dict[str, int]]:
    """Read and check a lerobot calibration (JSON path or dict) for the virtual arm.

    The checks are :func:`so101_kinematics.calibration.load_calibration`'s, plus the
    virtual arm's own: its servos are not inverted (drive_mode 0).

    Args:
        calibration: path to a ``lerobot-calibrate`` JSON file, or the dict
            joint name -> {id, drive_mode, homing_offset, range_min, range_max}
            (values may also be objects with those attributes).

    Returns:
        Joint name -> dict of ints, in the six SO-101 joints' order.

    Raises:
        CalibrationError: missing joints or keys, bad values; the message says what to fix.
    """
    servos = load_lerobot_calibration(calibration)
    for name, servo in servos.items():
        if servo.drive_mode != 0:
            raise CalibrationError(
                f"{calibration_source_name(calibration)}: {name}.drive_mode = {servo.drive_mode}; "
                "the virtual arm's servos are not inverted. Fix: use drive_mode 0.")
    return {name: dataclasses.asdict(servo) for name, servo in servos.items()}


def present_to_radians(m, cal: Mapping[str, int], joint: str, present: float) -> float:
    """Present_Position [ticks] -> joint angle [rad]: lerobot's normalisation, then ``to_radians``.

    Args:
        m: the MuJoCo model (its gripper range is what [0, 100] spans).
        cal: the joint's calibration entry.
        joint: joint name.
        present: position in the calibration's frame [ticks] (the gripper's is
            clamped to its calibrated range, as lerobot reads it).
    """
    from so101_kinematics.sim.scene import (  # imports mujoco: only where a model is at hand
        to_radians,
    )

    user = ticks_to_user(joint, present, ServoCalibration(**cal))
    return to_radians(m, {joint: user})[joint]


def radians_to_present(m, cal: Mapping[str, int], joint: str, angle: float) -> float:
    """Joint angle [rad] -> Present_Position [ticks, not rounded]; inverse of present_to_radians."""
    from so101_kinematics.sim.scene import from_radians

    user = from_radians(m, {joint: angle})[joint]
    return user_to_ticks(joint, user, ServoCalibration(**cal))

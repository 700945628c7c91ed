"""The virtual SO-101's lerobot calibration: the shipped one, loading, ticks <-> radians.

Ticks <-> joint angles go through the lerobot calibration, so they agree with
``so101_mujoco_utils.to_radians``:
- arm joints: angle [deg] = (present - (range_min + range_max) / 2) * 360 / 4095,
  lerobot's DEGREES;
- gripper: opening [0, 100] = (present - range_min) / (range_max - range_min) * 100,
  lerobot's RANGE_0_100, and 0..100 spans the model's gripper range.
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

import json
import math
from collections.abc import Mapping
from pathlib import Path

from feetech_protocol import BROADCAST_ID, RESOLUTION

_HERE = Path(__file__).resolve().parent
DEFAULT_CALIBRATION_PATH = _HERE / "calibration" / "virtual_so101.json"

TICKS_PER_RAD = (RESOLUTION - 1) / (2.0 * math.pi)  # lerobot's scale (360 deg = 4095 ticks)

# Plausible encoder offsets of the virtual arm's servo horns (any |value| <= 2047 works).
DEFAULT_HOMING_OFFSETS = {"shoulder_pan": 143, "shoulder_lift": -612, "elbow_flex": 488,
                          "wrist_flex": -251, "wrist_roll": 97, "gripper": -705}
FULL_TURN_JOINTS = ("wrist_roll",)  # recorded as 0..4095 by lerobot-calibrate
JOINT_IDS = {"shoulder_pan": 1, "shoulder_lift": 2, "elbow_flex": 3, "wrist_flex": 4,
             "wrist_roll": 5, "gripper": 6}
CALIBRATION_KEYS = ("id", "drive_mode", "homing_offset", "range_min", "range_max")


class CalibrationError(ValueError):
    """A calibration file or dict is not usable for the virtual arm."""


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
    for name, servo_id in JOINT_IDS.items():
        lower, upper = (float(x) for x in m.joint(name).range)
        if name in FULL_TURN_JOINTS:
            range_min, range_max = 0, RESOLUTION - 1
        elif name == "gripper":
            span = round((upper - lower) * TICKS_PER_RAD)
            range_min, range_max = 2048 - (span + 1) // 2, 2048 - (span + 1) // 2 + span
        else:
            half = math.ceil(max(abs(lower), abs(upper)) * TICKS_PER_RAD - 1e-9)
            range_min, range_max = 2047 - half, 2047 + half
        calibration[name] = {"id": servo_id, "drive_mode": 0,
                             "homing_offset": DEFAULT_HOMING_OFFSETS[name],
                             "range_min": range_min, "range_max": range_max}
    return calibration


def load_calibration(calibration: str | Path | Mapping) -> dict[str, dict[str, int]]:
    """Read and check a lerobot calibration (JSON path or dict) for the virtual arm.

    Args:
        calibration: path to a ``lerobot-calibrate`` JSON file, or the dict
            joint name -> {id, drive_mode, homing_offset, range_min, range_max}
            (values may also be objects with those attributes).

    Returns:
        Joint name -> dict of ints, in the six SO-101 joints' order.

    Raises:
        CalibrationError: missing joints or keys, bad values; the message says what to fix.
    """
    source = "calibration"
    if isinstance(calibration, (str, Path)):
        source = str(calibration)
        try:
            calibration = json.loads(Path(calibration).read_text())
        except FileNotFoundError as exc:
            raise CalibrationError(
                f"Calibration file {source} not found. Fix: pass an existing lerobot calibration "
                f"JSON, e.g. {DEFAULT_CALIBRATION_PATH}.") from exc
        except json.JSONDecodeError as exc:
            raise CalibrationError(f"Calibration file {source} is not valid JSON: {exc}.") from exc
    out = {}
    missing = [name for name in JOINT_IDS if name not in calibration]
    if missing:
        raise CalibrationError(f"{source}: joints {missing} are missing; the virtual SO-101 needs "
                               f"all of {list(JOINT_IDS)}.")
    for name in JOINT_IDS:
        entry = calibration[name]
        get = entry.get if isinstance(entry, Mapping) else lambda k, e=entry: getattr(e, k, None)
        values = {key: get(key) for key in CALIBRATION_KEYS}
        for key, value in values.items():
            if isinstance(value, bool) or not isinstance(value, int):
                raise CalibrationError(f"{source}: {name}.{key} = {value!r} must be an integer.")
        if values["drive_mode"] != 0:
            raise CalibrationError(f"{source}: {name}.drive_mode = {values['drive_mode']}; the "
                                   "virtual arm's servos are not inverted. Fix: use drive_mode 0.")
        if not 0 <= values["range_min"] < values["range_max"] <= RESOLUTION - 1:
            raise CalibrationError(
                f"{source}: {name} range [{values['range_min']}, {values['range_max']}] must "
                f"satisfy 0 <= range_min < range_max <= {RESOLUTION - 1}.")
        if abs(values["homing_offset"]) > 2047:
            raise CalibrationError(f"{source}: {name}.homing_offset = {values['homing_offset']} "
                                   "is beyond +/-2047 (the register's sign-magnitude range).")
        if not 0 < values["id"] < BROADCAST_ID:
            raise CalibrationError(f"{source}: {name}.id = {values['id']} must be in 1..253.")
        out[name] = values
    ids = [v["id"] for v in out.values()]
    if len(set(ids)) != len(ids):
        raise CalibrationError(f"{source}: servo ids {ids} are not unique.")
    return out


def present_to_radians(cal: Mapping[str, int], joint: str, present: float,
                       joint_range: tuple[float, float]) -> float:
    """Present_Position [ticks] -> joint angle [rad] through the calibration (lerobot's mapping).

    Args:
        cal: the joint's calibration entry.
        joint: joint name ("gripper" uses RANGE_0_100 over ``joint_range``).
        present: position in the calibration's frame [ticks].
        joint_range: the model joint's (lower, upper) [rad].
    """
    lo, hi = cal["range_min"], cal["range_max"]
    if joint == "gripper":
        return joint_range[0] + (present - lo) / (hi - lo) * (joint_range[1] - joint_range[0])
    return (present - (lo + hi) / 2.0) / TICKS_PER_RAD


def radians_to_present(cal: Mapping[str, int], joint: str, angle: float,
                       joint_range: tuple[float, float]) -> float:
    """Joint angle [rad] -> Present_Position [ticks, not rounded]; see present_to_radians."""
    lo, hi = cal["range_min"], cal["range_max"]
    if joint == "gripper":
        return lo + (angle - joint_range[0]) / (joint_range[1] - joint_range[0]) * (hi - lo)
    return (lo + hi) / 2.0 + angle * TICKS_PER_RAD

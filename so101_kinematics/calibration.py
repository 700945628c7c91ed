"""lerobot calibration files of the SO-101 follower: where they are, what they hold, their limits.

A calibration (what ``lerobot-calibrate`` writes) gives each servo its id,
drive mode, homing offset and calibrated range in raw encoder ticks. Here it
is found by robot id, loaded and validated from a file or a mapping
(:func:`load_calibration`), and turned into user units exactly as lerobot
normalises: [deg] for the arm joints, [0, 100] for the gripper
(:func:`ticks_to_user`, its inverse :func:`user_to_ticks`,
:func:`calibrated_limits`). The one implementation for both backends: the
real arm (``so101_kinematics.hw.bus``) and the virtual arm
(``so101_kinematics.virtual.shipped_calibration``
adds only what is specific to it).

Also home of :class:`HardwareError`, the base of the hardware error family
(``so101_kinematics.hw.bus`` and ``pick_place_hw`` add the others).
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from so101_kinematics.errors import CalibrationError
from so101_kinematics.frames import JOINTS
from so101_kinematics.servo import COUNTS_PER_TURN

__all__ = [
    "CALIBRATE_HINT", "MOTOR_IDS", "ServoCalibration", "calibrated_limits",
    "calibration_source_name", "find_calibration", "lerobot_calibration_root",
    "load_calibration", "ticks_to_user", "user_to_ticks",
]

# --- Settings ---------------------------------------------------------------
ROBOT_TYPE = "so101_follower"
# lerobot 0.4.x files SO-100/SO-101 calibrations under the robot class name
# "so_follower"; lerobot 0.2-0.3 used the type name "so101_follower".
CALIBRATION_SUBDIRS = ("so_follower", "so101_follower")
MOTOR_IDS = {"shoulder_pan": 1, "shoulder_lift": 2, "elbow_flex": 3, "wrist_flex": 4,
             "wrist_roll": 5, "gripper": 6}
"""Servo id of each joint on the SO-101 follower (lerobot's SOFollower)."""
TICKS_PER_TURN = COUNTS_PER_TURN - 1  # lerobot's max_res for the sts3215: its positions - 1
CALIBRATE_HINT = (f"lerobot-calibrate --robot.type={ROBOT_TYPE} --robot.port={{port}} "
                  "--robot.id={robot_id}")


# --- Errors -----------------------------------------------------------------
# --- Calibration files ---------------------------------------------------------
@dataclass(frozen=True)
class ServoCalibration:
    """One joint's entry of a lerobot calibration file (raw encoder ticks)."""

    id: int
    drive_mode: int
    homing_offset: int
    range_min: int
    range_max: int


CALIBRATION_FIELDS = ("id", "drive_mode", "homing_offset", "range_min", "range_max")
"""The fields of one joint's calibration, in lerobot's order."""


def lerobot_calibration_root() -> Path:
    """Where lerobot keeps calibrations, resolved as lerobot does (without importing it).

    ``HF_LEROBOT_CALIBRATION``, else ``HF_LEROBOT_HOME/calibration``, else
    ``HF_HOME/lerobot/calibration`` (``HF_HOME`` defaults to
    ``$XDG_CACHE_HOME/huggingface`` or ``~/.cache/huggingface``).
    """
    if os.environ.get("HF_LEROBOT_CALIBRATION"):
        return Path(os.environ["HF_LEROBOT_CALIBRATION"]).expanduser()
    if os.environ.get("HF_LEROBOT_HOME"):
        return Path(os.environ["HF_LEROBOT_HOME"]).expanduser() / "calibration"
    hf_home = os.environ.get("HF_HOME")
    if not hf_home:
        cache = os.environ.get("XDG_CACHE_HOME") or str(Path("~/.cache").expanduser())
        hf_home = os.path.join(cache, "huggingface")
    return Path(hf_home).expanduser() / "lerobot" / "calibration"


def calibration_candidates(robot_id: str) -> list[Path]:
    """The files lerobot would use for a follower with this id, newest layout first."""
    root = lerobot_calibration_root() / "robots"
    return [root / sub / f"{robot_id}.json" for sub in CALIBRATION_SUBDIRS]


def find_calibration(robot_id: str, port: str | None = None) -> Path:
    """Locate the calibration file ``lerobot-calibrate`` wrote for ``robot_id``.

    Raises:
        CalibrationError: no file, naming the places searched and the command that writes one.
    """
    candidates = calibration_candidates(robot_id)
    for path in candidates:
        if path.is_file():
            return path
    searched = "\n  ".join(str(p) for p in candidates)
    fix = CALIBRATE_HINT.format(port=port or "PORT", robot_id=robot_id)
    raise CalibrationError(
        f"No calibration for robot id '{robot_id}'. Searched:\n  {searched}\n"
        f"Fix: calibrate the arm with `{fix}`, or pass the file with --calibration PATH."
    )


def calibration_source_name(source: str | Path | Mapping) -> str:
    """How error messages name a calibration: its file, or "The calibration" for a mapping."""
    if isinstance(source, Mapping):
        return "The calibration"
    return f"Calibration file '{Path(source)}'"


def _entry_fields(entry: Any) -> Mapping[str, Any] | None:
    """One joint's entry as a mapping of the calibration fields (None if some are missing)."""
    if isinstance(entry, Mapping):
        return entry if all(k in entry for k in CALIBRATION_FIELDS) else None
    if all(hasattr(entry, k) for k in CALIBRATION_FIELDS):  # ServoCalibration, MotorCalibration
        return {k: getattr(entry, k) for k in CALIBRATION_FIELDS}
    return None


def load_calibration(source: str | Path | Mapping,
                     robot_id: str | None = None) -> dict[str, ServoCalibration]:
    """Read and check a lerobot calibration (the JSON ``lerobot-calibrate`` writes, or its dict).

    Args:
        source: the JSON file, or the mapping joint name -> {id, drive_mode,
            homing_offset, range_min, range_max} (entries may also be objects
            with those attributes, e.g. :class:`ServoCalibration`).
        robot_id: only for the fix suggested in error messages.

    Returns:
        joint name -> :class:`ServoCalibration`, in ``JOINTS`` order.

    Raises:
        CalibrationError: missing file, invalid JSON, missing or unknown joints,
            wrong servo ids, non-integer fields, an empty or out-of-encoder range.
    """
    name = calibration_source_name(source)
    stem = "ROBOT_ID" if isinstance(source, Mapping) else Path(source).stem
    command = CALIBRATE_HINT.format(port="PORT", robot_id=robot_id or stem)
    fix = f"Fix: recalibrate with `{command}` or pass the right file with --calibration."
    if isinstance(source, Mapping):
        data = source
    else:
        try:
            data = json.loads(Path(source).read_text())
        except FileNotFoundError:
            raise CalibrationError(f"{name} does not exist. {fix}") from None
        except OSError as error:
            raise CalibrationError(f"Cannot read {name}: {error.strerror}.") from None
        except ValueError as error:
            raise CalibrationError(f"{name} is not valid JSON ({error}). {fix}") from None
    if not isinstance(data, Mapping):
        raise CalibrationError(f"{name} must map joint names to calibrations. {fix}")
    unknown = sorted(set(data) - set(JOINTS))
    missing = [j for j in JOINTS if j not in data]
    if unknown or missing:
        raise CalibrationError(
            f"{name} is not an SO-101 follower calibration: "
            + (f"missing {missing}" if missing else "")
            + ("; " if missing and unknown else "")
            + (f"unknown {unknown}" if unknown else "")
            + f". Expected exactly: {', '.join(JOINTS)}. {fix}"
        )
    out = {}
    for joint in JOINTS:
        entry = _entry_fields(data[joint])
        fields = CALIBRATION_FIELDS
        if entry is None:
            raise CalibrationError(f"{name}: {joint} needs the fields "
                                   f"{', '.join(fields)}. {fix}")
        for key in fields:
            value = entry[key]
            if isinstance(value, bool) or not isinstance(value, int):
                raise CalibrationError(f"{name}: {joint}.{key} must be an integer, got "
                                       f"{value!r}. {fix}")
        cal = ServoCalibration(*(entry[k] for k in fields))
        if cal.id != MOTOR_IDS[joint]:
            raise CalibrationError(f"{name}: {joint} has servo id {cal.id}; the "
                                   f"SO-101 follower uses id {MOTOR_IDS[joint]} for it. {fix}")
        if cal.drive_mode not in (0, 1):
            raise CalibrationError(f"{name}: {joint}.drive_mode = {cal.drive_mode}; it must be "
                                   f"0 or 1. {fix}")
        if abs(cal.homing_offset) > 2047:
            raise CalibrationError(f"{name}: {joint}.homing_offset = "
                                   f"{cal.homing_offset} is beyond +-2047 ticks. {fix}")
        if not 0 <= cal.range_min < cal.range_max <= TICKS_PER_TURN:
            raise CalibrationError(
                f"{name}: {joint} range [{cal.range_min}, {cal.range_max}] ticks must satisfy "
                f"0 <= range_min < range_max <= {TICKS_PER_TURN} (an empty range means the joint "
                f"was not moved through its range during calibration). {fix}")
        out[joint] = cal
    return out


def ticks_to_user(joint: str, raw: float, cal) -> float:
    """Raw Present/Goal_Position ticks -> [deg] (gripper [0, 100]), exactly as lerobot normalises.

    Args:
        joint: joint name (the gripper uses RANGE_0_100, the others DEGREES).
        raw: encoder ticks.
        cal: the joint's calibration (anything with ``range_min``, ``range_max``, ``drive_mode``).
    """
    lo, hi = cal.range_min, cal.range_max
    if joint == "gripper":
        value = (min(hi, max(lo, raw)) - lo) / (hi - lo) * 100.0
        return 100.0 - value if cal.drive_mode else value
    return (raw - (lo + hi) / 2.0) * 360.0 / TICKS_PER_TURN


def user_to_ticks(joint: str, value: float, cal) -> float:
    """[deg] (gripper [0, 100]) -> raw ticks, not rounded: the inverse of :func:`ticks_to_user`.

    Not clamped (lerobot clamps the gripper to [0, 100] before it writes), so
    the map stays affine beyond the calibrated range.

    Args:
        joint: joint name (the gripper uses RANGE_0_100, the others DEGREES).
        value: joint angle [deg], or gripper opening [0, 100].
        cal: the joint's calibration (anything with ``range_min``, ``range_max``, ``drive_mode``).

    Returns:
        Encoder ticks (a float).
    """
    lo, hi = cal.range_min, cal.range_max
    if joint == "gripper":
        value = 100.0 - value if cal.drive_mode else value
        return lo + value / 100.0 * (hi - lo)
    return (lo + hi) / 2.0 + value * TICKS_PER_TURN / 360.0


def calibrated_limits(calibration: Mapping[str, Any]) -> dict[str, tuple[float, float]]:
    """The calibrated range of each joint: [deg] for the arm, (0, 100) for the gripper."""
    limits = {}
    for joint in JOINTS:
        cal = calibration[joint]
        if joint == "gripper":
            limits[joint] = (0.0, 100.0)
        else:
            limits[joint] = (ticks_to_user(joint, cal.range_min, cal),
                             ticks_to_user(joint, cal.range_max, cal))
    return limits

"""One lerobot calibration for both arms: calibration.py, and the virtual arm's additions.

The virtual arm's ticks <-> radians is the composition of lerobot's
normalisation (``so101_kinematics.calibration.ticks_to_user``) with the project's one unit
conversion (``so101_mujoco_utils.to_radians``); these tests hold it to the
closed-form formulas it replaced, over every joint's whole tick range.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

import so101_kinematics.virtual.shipped_calibration as vcal
from so101_forward_kinematics import JOINTS
from so101_kinematics.calibration import (
    ServoCalibration,
    load_calibration,
    ticks_to_user,
    user_to_ticks,
)
from so101_kinematics.errors import CalibrationError, HardwareError
from so101_kinematics.virtual.servo_memory import VirtualServo

SHIPPED = Path(__file__).resolve().parents[2] / "calibration" / "virtual_so101.json"
TICKS_PER_RAD = 4095 / (2 * math.pi)  # lerobot's DEGREES scale: 360 deg = 4095 ticks


def closed_form_present_to_radians(entry, joint, present, joint_range):
    """The direct ticks -> [rad] formulas (lerobot's DEGREES / RANGE_0_100 in radians)."""
    lo, hi = entry["range_min"], entry["range_max"]
    if joint == "gripper":
        return joint_range[0] + (present - lo) / (hi - lo) * (joint_range[1] - joint_range[0])
    return (present - (lo + hi) / 2.0) / TICKS_PER_RAD


def closed_form_radians_to_present(entry, joint, angle, joint_range):
    """The direct [rad] -> ticks formulas, the inverse of the above."""
    lo, hi = entry["range_min"], entry["range_max"]
    if joint == "gripper":
        return lo + (angle - joint_range[0]) / (joint_range[1] - joint_range[0]) * (hi - lo)
    return (lo + hi) / 2.0 + angle * TICKS_PER_RAD


# --- the virtual arm's ticks <-> radians ------------------------------------------------------
@pytest.mark.parametrize("joint", JOINTS)
def test_composed_mapping_equals_the_closed_form_over_the_whole_tick_range(model, joint):
    entry = vcal.load_calibration(SHIPPED)[joint]
    joint_range = tuple(float(x) for x in model.joint(joint).range)
    # every tick and half tick of the calibrated range; arm joints: the whole encoder turn
    lo, hi = (entry["range_min"], entry["range_max"]) if joint == "gripper" else (0, 4095)
    for present in np.arange(lo, hi + 0.25, 0.5):
        angle = vcal.present_to_radians(model, entry, joint, float(present))
        expected = closed_form_present_to_radians(entry, joint, float(present), joint_range)
        assert abs(angle - expected) <= 1e-12, (joint, present)
        ticks = vcal.radians_to_present(model, entry, joint, angle)
        expected_ticks = closed_form_radians_to_present(entry, joint, angle, joint_range)
        assert abs(ticks - expected_ticks) <= 1e-9, (joint, present)
        assert abs(ticks - present) <= 1e-9, (joint, present)


def test_gripper_ticks_beyond_the_calibration_read_as_its_ends(model):
    entry = vcal.load_calibration(SHIPPED)["gripper"]
    lower, upper = model.joint("gripper").range
    below = vcal.present_to_radians(model, entry, "gripper", entry["range_min"] - 40)
    above = vcal.present_to_radians(model, entry, "gripper", entry["range_max"] + 40)
    assert below == pytest.approx(lower, abs=1e-12)
    assert above == pytest.approx(upper, abs=1e-12)


def test_emulated_servos_keep_the_closed_form_affine_map_bit_for_bit(model):
    """Present_Position on the wire = round(base + scale * angle): same bits as before."""
    for joint, entry in vcal.load_calibration(SHIPPED).items():
        joint_range = tuple(float(x) for x in model.joint(joint).range)
        servo = VirtualServo(joint, entry, model)
        base = closed_form_radians_to_present(entry, joint, 0.0, joint_range)
        scale = closed_form_radians_to_present(entry, joint, 1.0, joint_range) - base
        assert (servo.base, servo.scale) == (base, scale), joint


# --- lerobot's normalisation and its inverse --------------------------------------------------
@pytest.mark.parametrize("joint, drive_mode", [("elbow_flex", 0), ("elbow_flex", 1),
                                               ("gripper", 0), ("gripper", 1)])
def test_user_to_ticks_inverts_ticks_to_user(joint, drive_mode):
    cal = ServoCalibration(3, drive_mode, 0, 1000, 2900)
    rng = np.random.default_rng(7)
    for raw in rng.uniform(cal.range_min, cal.range_max, 200):
        user = ticks_to_user(joint, float(raw), cal)
        assert user_to_ticks(joint, user, cal) == pytest.approx(raw, abs=1e-9)
    if joint == "gripper":
        closed = 100.0 if drive_mode else 0.0
        assert user_to_ticks(joint, closed, cal) == cal.range_min


# --- loading: a file or a mapping, one error class --------------------------------------------
def test_a_mapping_loads_like_its_file():
    from_file = load_calibration(SHIPPED)
    data = json.loads(SHIPPED.read_text())
    assert load_calibration(data) == from_file
    assert load_calibration(from_file) == from_file  # entries as ServoCalibration objects


def test_a_bad_mapping_is_refused_with_joint_value_and_fix():
    data = json.loads(SHIPPED.read_text())
    data["wrist_flex"]["id"] = 9
    with pytest.raises(CalibrationError, match="The calibration: wrist_flex has servo id 9.*"
                                               "uses id 4.*lerobot-calibrate"):
        load_calibration(data)
    del data["wrist_flex"]["id"]
    with pytest.raises(CalibrationError, match="wrist_flex needs the fields id"):
        load_calibration(data)


def test_one_calibration_error_for_both_arms():
    data = json.loads(SHIPPED.read_text())
    data["gripper"]["drive_mode"] = 1
    assert load_calibration(data)["gripper"].drive_mode == 1  # a real arm may be inverted
    with pytest.raises(CalibrationError, match="gripper.drive_mode = 1.*drive_mode 0") as info:
        vcal.load_calibration(data)  # the virtual arm's servos are not
    assert isinstance(info.value, HardwareError) and isinstance(info.value, ValueError)

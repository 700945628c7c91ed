"""lerobot calibration files: loading, refusing, finding, normalising."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hw_fakes import HOME, FakeBus, FakeClock, make_session  # noqa: F401

from so101_forward_kinematics import JOINTS
from so101_kinematics.calibration import (
    MOTOR_IDS,
    ServoCalibration,
    calibrated_limits,
    find_calibration,
    lerobot_calibration_root,
    load_calibration,
    ticks_to_user,
    user_to_ticks,
)
from so101_kinematics.errors import CalibrationError
from so101_kinematics.hw.bus import make_bus

REPO = Path(__file__).resolve().parents[2]
VIRTUAL_CALIBRATION = REPO / "calibration" / "virtual_so101.json"


# --- calibration ---------------------------------------------------------------------
def test_virtual_calibration_loads_in_joint_order(calibration):
    assert list(calibration) == list(JOINTS)
    assert calibration["gripper"].id == 6


@pytest.mark.parametrize("mutate, words", [
    (lambda d: d.pop("wrist_flex"), ["missing", "wrist_flex"]),
    (lambda d: d.update(elbow=d["elbow_flex"]), ["unknown", "elbow"]),
    (lambda d: d["elbow_flex"].update(range_min=2000, range_max=2000),
     ["elbow_flex", "empty range"]),
    (lambda d: d["elbow_flex"].update(range_max=5000), ["elbow_flex", "range_max <= 4095"]),
    (lambda d: d["shoulder_lift"].update(id=7), ["shoulder_lift", "servo id 7", "id 2"]),
    (lambda d: d["gripper"].update(homing_offset=3000), ["gripper", "homing_offset", "2047"]),
    (lambda d: d["gripper"].update(range_min="12"), ["gripper.range_min", "integer"]),
    (lambda d: d["gripper"].pop("drive_mode"), ["gripper", "drive_mode"]),
])
def test_malformed_calibration_is_refused_with_the_fix(tmp_path, mutate, words):
    data = json.loads(VIRTUAL_CALIBRATION.read_text())
    mutate(data)
    with pytest.raises(CalibrationError) as info:
        load_calibration(write_calibration(tmp_path, data), robot_id="lab_arm")
    message = str(info.value)
    for word in words:
        assert word in message
    assert "lerobot-calibrate --robot.type=so101_follower" in message and "lab_arm" in message


def test_missing_and_invalid_calibration_files(tmp_path):
    with pytest.raises(CalibrationError, match="does not exist.*lerobot-calibrate"):
        load_calibration(tmp_path / "nope.json")
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(CalibrationError, match="not valid JSON"):
        load_calibration(bad)


def test_calibration_is_found_where_lerobot_keeps_it(tmp_path, monkeypatch):
    monkeypatch.delenv("HF_LEROBOT_HOME", raising=False)
    monkeypatch.setenv("HF_LEROBOT_CALIBRATION", str(tmp_path))
    with pytest.raises(CalibrationError) as info:
        find_calibration("lab_arm", "/dev/ttyACM0")
    message = str(info.value)
    assert str(tmp_path / "robots" / "so_follower" / "lab_arm.json") in message
    assert str(tmp_path / "robots" / "so101_follower" / "lab_arm.json") in message
    assert "--robot.port=/dev/ttyACM0 --robot.id=lab_arm" in message
    # the older layout (robots/so101_follower) is found too; lerobot 0.4's (so_follower) wins
    older = tmp_path / "robots" / "so101_follower" / "lab_arm.json"
    older.parent.mkdir(parents=True)
    older.write_text(VIRTUAL_CALIBRATION.read_text())
    assert find_calibration("lab_arm") == older
    newer = tmp_path / "robots" / "so_follower" / "lab_arm.json"
    newer.parent.mkdir(parents=True)
    newer.write_text(VIRTUAL_CALIBRATION.read_text())
    assert find_calibration("lab_arm") == newer


def test_calibration_root_follows_lerobot_environment(tmp_path, monkeypatch):
    for name in ("HF_LEROBOT_CALIBRATION", "HF_LEROBOT_HOME", "HF_HOME", "XDG_CACHE_HOME"):
        monkeypatch.delenv(name, raising=False)
    default = Path("~/.cache/huggingface/lerobot/calibration").expanduser()
    assert lerobot_calibration_root() == default
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    xdg = tmp_path / "xdg" / "huggingface" / "lerobot" / "calibration"
    assert lerobot_calibration_root() == xdg
    monkeypatch.setenv("HF_HOME", str(tmp_path / "hf"))
    assert lerobot_calibration_root() == tmp_path / "hf" / "lerobot" / "calibration"
    monkeypatch.setenv("HF_LEROBOT_HOME", str(tmp_path / "home"))
    assert lerobot_calibration_root() == tmp_path / "home" / "calibration"
    monkeypatch.setenv("HF_LEROBOT_CALIBRATION", str(tmp_path / "cal"))
    assert lerobot_calibration_root() == tmp_path / "cal"


def test_calibrated_limits_are_lerobots_normalisation_of_the_range(calibration):
    limits = calibrated_limits(calibration)
    pan = calibration["shoulder_pan"]
    half = (pan.range_max - pan.range_min) / 2 * 360 / 4095
    assert limits["shoulder_pan"] == pytest.approx((-half, half), abs=1e-12)
    assert limits["gripper"] == (0.0, 100.0)


def test_gripper_ticks_by_hand(calibration):
    """lerobot's RANGE_0_100: 0 % at range_min (closed), 100 % at range_max; drive_mode 1 flips.

    The virtual arm's gripper: ticks 1422..2673 (calibration/virtual_so101.json).
    """
    gripper = calibration["gripper"]
    assert ticks_to_user("gripper", 1422, gripper) == 0.0
    assert ticks_to_user("gripper", 2673, gripper) == 100.0
    assert ticks_to_user("gripper", 1422 + 0.25 * 1251, gripper) == pytest.approx(25.0)
    assert user_to_ticks("gripper", 25.0, gripper) == pytest.approx(1422 + 0.25 * 1251)
    flipped = ServoCalibration(6, 1, 0, 1422, 2673)
    assert ticks_to_user("gripper", 1422, flipped) == 100.0
    assert user_to_ticks("gripper", 100.0, flipped) == pytest.approx(1422)


@pytest.mark.hw
def test_ticks_to_user_matches_lerobot_bus_normalisation(calibration):
    pytest.importorskip("lerobot")
    bus = make_bus("/dev/null", calibration)  # constructed, never connected
    rng = np.random.default_rng(5)
    for joint in JOINTS:
        cal = calibration[joint]
        motor_id = MOTOR_IDS[joint]
        for raw in rng.integers(cal.range_min - 50, cal.range_max + 50, 40):
            expected = bus._normalize({motor_id: int(raw)})[motor_id]
            assert ticks_to_user(joint, int(raw), cal) == pytest.approx(expected, abs=1e-9)
    drive = dict(calibration, gripper=ServoCalibration(6, 1, 0, 1000, 2000))
    bus = make_bus("/dev/null", drive)
    assert ticks_to_user("gripper", 1200, drive["gripper"]) == pytest.approx(
        bus._normalize({6: 1200})[6])


def write_calibration(tmp_path, data, name="arm.json") -> Path:
    path = tmp_path / name
    path.write_text(json.dumps(data))
    return path

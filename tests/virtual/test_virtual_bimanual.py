"""lerobot's bimanual robot type against two virtual SO-101s, each on its own port (issue 38).

``bi_so_follower`` (lerobot 0.4 and 0.6 alike) is two SO followers under one robot: the
keys ``left_...``/``right_...``, one calibration per arm (``<id>_left``, ``<id>_right`` in its
``calibration_dir``). Two ``VirtualSO101`` stand in for the arms, with lerobot's own,
unmodified classes driving them: what a student's two-arm project connects to.
"""

from __future__ import annotations

import shutil
import time

import pytest

pytest.importorskip("lerobot")
pytestmark = pytest.mark.hw  # 5 s: the quick tier, on both lerobots

from so101_kinematics.virtual.arm import VirtualSO101  # noqa: E402
from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH  # noqa: E402

JOINTS = ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper")
HOME = {"shoulder_pan": 0.0, "shoulder_lift": -90.0, "elbow_flex": 90.0, "wrist_flex": 30.0,
        "wrist_roll": 0.0, "gripper": 9.0}  # [deg], gripper [0, 100]
TURN = {"shoulder_pan": 25.0, "wrist_roll": -40.0}  # the joints gravity does not load [deg]


def wait_for(robot, goal: dict[str, float], tol: float, timeout: float = 4.0) -> dict:
    """Observations until every key of ``goal`` is within ``tol`` of it (or the timeout)."""
    deadline = time.monotonic() + timeout
    while True:
        seen = robot.get_observation()
        if all(abs(seen[k] - v) <= tol for k, v in goal.items()) or time.monotonic() > deadline:
            return seen
        time.sleep(0.05)


def test_bi_so_follower_drives_two_virtual_arms_each_its_own(tmp_path, monkeypatch):
    from lerobot.robots.bi_so_follower import BiSOFollower, BiSOFollowerConfig
    from lerobot.robots.so_follower import SOFollowerConfig

    def no_prompt(*args, **kwargs):
        raise AssertionError(f"BiSOFollower prompted: {args}")

    monkeypatch.setattr("builtins.input", no_prompt)
    for side in ("left", "right"):  # one calibration per arm, as lerobot names them
        shutil.copy(DEFAULT_CALIBRATION_PATH, tmp_path / f"pair_{side}.json")
    with VirtualSO101() as left, VirtualSO101() as right:
        assert left.port != right.port
        for arm in (left, right):
            arm.set_pose(HOME)
        robot = BiSOFollower(BiSOFollowerConfig(
            id="pair", calibration_dir=tmp_path,
            left_arm_config=SOFollowerConfig(port=left.port),
            right_arm_config=SOFollowerConfig(port=right.port)))
        robot.connect()
        try:
            assert robot.is_calibrated
            assert all(left.torque_enabled().values()) and all(right.torque_enabled().values())
            seen = robot.get_observation()
            assert {k for k in seen if k.endswith(".pos")} == {
                f"{side}_{j}.pos" for side in ("left", "right") for j in JOINTS}
            for side, arm in (("left", left), ("right", right)):  # each key is its own arm
                truth = arm.joint_positions()
                for j in ("shoulder_pan", "wrist_roll"):
                    assert seen[f"{side}_{j}.pos"] == pytest.approx(truth[j], abs=1.0), (side, j)

            # the left arm turns; the right, sent its own pose, stays where it is
            action = {f"left_{j}.pos": TURN.get(j, seen[f"left_{j}.pos"]) for j in JOINTS}
            action |= {f"right_{j}.pos": seen[f"right_{j}.pos"] for j in JOINTS}
            robot.send_action(action)
            goal = {f"left_{j}.pos": v for j, v in TURN.items()}
            moved = wait_for(robot, goal, tol=1.5)
            for j, v in TURN.items():
                assert left.joint_positions()[j] == pytest.approx(v, abs=1.5), j
                assert moved[f"left_{j}.pos"] == pytest.approx(v, abs=1.5), j
                assert right.joint_positions()[j] == pytest.approx(
                    seen[f"right_{j}.pos"], abs=1.0), j

            # back where it started before lerobot's disconnect releases the torque
            robot.send_action({f"{side}_{j}.pos": seen[f"{side}_{j}.pos"]
                               for side in ("left", "right") for j in JOINTS})
            wait_for(robot, {f"left_{j}.pos": seen[f"left_{j}.pos"] for j in TURN}, tol=1.5)
        finally:
            robot.disconnect()
        assert not any(left.torque_enabled().values())
        assert not any(right.torque_enabled().values())

"""Radians given for degrees (issue 28, Deliver 7): warned before a move, refused in a plan file.

The radian configurations are the degree ones converted by hand (math.radians), as a student
copying ``d.qpos`` would pass them.
"""

from __future__ import annotations

import json
import logging
import math
from pathlib import Path

import pytest

import pick_place_hw as cli
from so101_kinematics.constants import HOME_POSE
from so101_kinematics.errors import PlanError
from so101_kinematics.frames import ARM_JOINTS
from so101_kinematics.planning.plans import STARTING_CONFIGURATION, load_plan

CALIBRATION_PATH = Path(__file__).resolve().parents[2] / "calibration" / "virtual_so101.json"


def in_radians(cfg):
    return {j: math.radians(v) if j in ARM_JOINTS else v for j, v in cfg.items()}


def radians_plan(tmp_path) -> Path:
    path = tmp_path / "radians.json"
    steps = [{"name": name, "configuration": in_radians(cfg)}
             for name, cfg in (("grasp", STARTING_CONFIGURATION), ("rest", HOME_POSE))]
    path.write_text(json.dumps({"steps": steps}))
    return path


def test_a_plan_file_in_radians_is_refused(tmp_path):
    with pytest.raises(PlanError, match="radians.*Fix: multiply each angle by 180/pi"):
        load_plan(radians_plan(tmp_path))


def test_dry_run_refuses_a_plan_in_radians_in_one_line(tmp_path, capsys):
    assert cli.main(["--dry-run", "--plan", str(radians_plan(tmp_path))]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "radians" in err[0] and "Fix:" in err[0]


def test_a_plan_near_the_zero_pose_in_degrees_is_not_taken_for_radians(tmp_path):
    path = tmp_path / "zero.json"
    zero = dict.fromkeys(ARM_JOINTS, 0.0) | {"gripper": 50.0}
    path.write_text(json.dumps({"steps": [{"name": "up", "configuration": zero}]}))
    load_plan(path)


def test_the_simulator_s_move_to_pose_warns_before_moving(caplog):
    mujoco = pytest.importorskip("mujoco")
    import so101_mujoco_utils as utils

    m = utils.load_model()
    d = mujoco.MjData(m)
    utils.set_initial_pose(d, HOME_POSE)
    with caplog.at_level(logging.WARNING):
        utils.move_to_pose(m, d, None, in_radians(STARTING_CONFIGURATION), 0.05)
    assert "look like radians" in caplog.text and "math.degrees" in caplog.text
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        utils.move_to_pose(m, d, None, STARTING_CONFIGURATION, 0.05)
    assert "radians" not in caplog.text


@pytest.mark.slow
@pytest.mark.newest_lerobot
@pytest.mark.hw
def test_so101_utils_move_to_pose_warns_before_the_move(course_arm, caplog):
    from so101_utils import load_calibration, move_to_pose, setup_motors

    bus = setup_motors(load_calibration(str(CALIBRATION_PATH)), course_arm.port)
    sent = len(course_arm.goal_log())
    cfg = in_radians(dict(HOME_POSE, shoulder_pan=20.0))
    with caplog.at_level(logging.WARNING):
        move_to_pose(bus, cfg, 2.0)
    assert "look like radians" in caplog.text  # a warning: the move itself is legal and runs
    assert sent < len(course_arm.goal_log())
    bus.disable_torque()

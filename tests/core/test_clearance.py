"""Nothing into the table: the one clearance check (so101_kinematics/clearance.py), everywhere.

Expected values come from the model (MuJoCo's own geom poses and contacts), not from the
check's constants; the plans that must pass are the course's own.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import pick_place_hw as cli
from so101_kinematics import clearance
from so101_kinematics.constants import HOME_POSE
from so101_kinematics.errors import ClearanceError
from so101_kinematics.frames import JOINTS
from so101_kinematics.hw.course_calibration import ScriptEnded
from so101_kinematics.planning.plans import STARTING_CONFIGURATION, default_plan, load_plan
from so101_kinematics.planning.stacking import LAB_BASE_HEIGHT, stack_plan

# The object frame under the table (the case, there 17.6 mm): the course's grasp
# with the shoulder 8 deg further down.
INTO_TABLE = dict(STARTING_CONFIGURATION, shoulder_lift=53.0)
# Both ends clear of the table; the wrist swings through pointing down in between.
SWING_A = {"shoulder_pan": 0.0, "shoulder_lift": 30.0, "elbow_flex": 60.0, "wrist_flex": -90.0,
           "wrist_roll": 0.0, "gripper": 0.0}
SWING_B = dict(SWING_A, wrist_flex=90.0)


def mujoco_lowest(cfg, base_height=0.0):
    """The model's answer: the lowest point of any collision box or the object frame [m]."""
    mujoco = pytest.importorskip("mujoco")
    from so101_kinematics.sim.scene import load_model, to_radians

    m = load_model()
    d = mujoco.MjData(m)
    for joint, value in to_radians(m, cfg).items():
        d.qpos[m.joint(joint).qposadr[0]] = value
    mujoco.mj_kinematics(m, d)
    lowest = d.site("object_frame").xpos[2]
    for g in range(m.ngeom):
        if m.geom_group[g] == 3:  # the collision class
            corners = np.abs(d.geom_xmat[g].reshape(3, 3)[2]) @ m.geom_size[g]
            lowest = min(lowest, d.geom_xpos[g][2] - corners)
    return lowest + base_height


@pytest.mark.slow
def test_the_check_places_every_collision_box_as_the_model_does():
    rng = np.random.default_rng(7)
    from so101_kinematics.frames import JOINT_LIMITS
    for _ in range(50):
        cfg = {j: float(rng.uniform(*JOINT_LIMITS[j])) for j in JOINTS}
        assert clearance.lowest_point(cfg)[0] == pytest.approx(mujoco_lowest(cfg), abs=1e-9)


def test_a_waypoint_under_the_table_is_refused_with_the_model_s_depth():
    depth = -mujoco_lowest(INTO_TABLE)
    assert depth > 0.015  # the model: the jaws under the table
    with pytest.raises(ClearanceError, match=rf"'press'.*{depth * 1000:.1f} mm into the table"
                                             r".*at the waypoint.*Fix:"):
        clearance.check_path([STARTING_CONFIGURATION, INTO_TABLE], ["press"])


def test_a_path_is_checked_between_its_waypoints_not_only_at_them():
    assert mujoco_lowest(SWING_A) > clearance.CLEARANCE_MARGIN_M
    assert mujoco_lowest(SWING_B) > clearance.CLEARANCE_MARGIN_M
    middle = dict(SWING_A, wrist_flex=0.0)
    assert mujoco_lowest(middle) < -0.05  # the model: the jaws 10 cm into the table
    clearance.check_path([SWING_A, SWING_A])
    clearance.check_path([SWING_B, SWING_B])
    with pytest.raises(ClearanceError, match=r"'swing'.*% of the way there.*wrist_flex"):
        clearance.check_path([SWING_A, SWING_B], ["swing"])


def test_the_course_s_plans_and_waypoint_files_clear_the_table():
    clearance.check_plan_clearance(default_plan(), HOME_POSE)
    for path in ("waypoints/example.json", "waypoints/example.toml", "waypoints/course_six.json"):
        clearance.check_plan_clearance(load_plan(path), HOME_POSE)
    for base_height, xy, blocks in ((0.0, (0.15, 0.1), 3), (LAB_BASE_HEIGHT, (0.15, 0.1), 4),
                                    (LAB_BASE_HEIGHT, (0.25, -0.1), 3), (0.0, (0.2, -0.1), 2)):
        plan = stack_plan(xy, blocks, base_height=base_height).plan
        clearance.check_plan_clearance(plan, HOME_POSE, base_height=base_height)


def test_an_arm_starting_low_may_move_up_but_not_down():
    low = dict(STARTING_CONFIGURATION, shoulder_lift=47.0)  # the object frame ~5 mm lower
    start = clearance.lowest_point(low)[0]
    assert 0.0 < start < clearance.CLEARANCE_MARGIN_M
    clearance.check_path([low, STARTING_CONFIGURATION])
    with pytest.raises(ClearanceError):
        clearance.check_path([low, dict(low, shoulder_lift=49.0)])


def test_the_return_may_come_down_to_where_the_arm_stood_no_lower():
    # A released arm slumps: the virtual arm, released at the rest pose after a run, settled
    # with elbow_flex 90 -> 96.9 and wrist_flex 30 -> 40.2 deg, its jaw pad on the table. A
    # second run from there went through its plan and then refused its own return (the
    # soak: every second run ended holding at 'depart').
    rest = {"shoulder_pan": 0.0, "shoulder_lift": -89.5, "elbow_flex": 96.9,
            "wrist_flex": 40.2, "wrist_roll": 0.1, "gripper": 9.5}
    depart = {"shoulder_pan": 45.0, "shoulder_lift": 24.0, "elbow_flex": -32.0,
              "wrist_flex": 93.0, "wrist_roll": 0.0, "gripper": 50.0}
    assert abs(clearance.lowest_point(rest)[0]) < 0.001  # at the table: inside the 5 mm margin
    with pytest.raises(ClearanceError, match="return_to_start"):
        clearance.check_path([depart, rest], ["return_to_start"])
    clearance.check_path([depart, rest], ["return_to_start"], rest=rest)
    deeper = dict(rest, wrist_flex=45.0)  # the jaw pad 7.9 mm into the table (the model)
    with pytest.raises(ClearanceError, match="mm into the table"):
        clearance.check_path([depart, deeper], ["deeper"], rest=rest)


def test_dry_run_refuses_a_plan_into_the_table(tmp_path, capsys):
    path = tmp_path / "press.json"
    steps = [{"name": "above", "configuration": STARTING_CONFIGURATION},
             {"name": "press", "configuration": INTO_TABLE}]
    path.write_text(json.dumps({"steps": steps}))
    rc = cli.main(["--dry-run", "--plan", str(path)])
    captured = capsys.readouterr()
    assert rc == 2
    assert "the plan is valid" not in captured.out
    line = captured.err.strip().splitlines()[-1]
    assert "waypoint 'press'" in line and "mm into the table" in line and "Fix:" in line
    assert "shoulder_lift 53.0" in line


def test_the_stacking_plan_on_the_lab_mount_passes_the_dry_run(capsys):
    rc = cli.main(["--dry-run", "--stack", "0.15", "0.1", "--blocks", "3",
                   "--base-height", str(LAB_BASE_HEIGHT)])
    assert rc == 0, capsys.readouterr().err


def sent_lift(arm, count):
    """How many shoulder_lift goals are among the first ``count`` goals the arm received."""
    return sum(1 for _, servo, _ in arm.goal_log()[:count] if servo == 2)


@pytest.mark.slow
@pytest.mark.newest_lerobot
@pytest.mark.hw
def test_move_to_pose_into_the_table_is_refused_before_anything_moves(course_arm, capsys):
    from so101_utils import load_calibration, move_to_pose, setup_motors

    bus = setup_motors(load_calibration("calibration/virtual_so101.json"), course_arm.port)
    move_to_pose(bus, STARTING_CONFIGURATION, 1.5)
    sent = len(course_arm.goal_log())
    with pytest.raises(ScriptEnded) as ended:
        move_to_pose(bus, INTO_TABLE, 2.0)
    err = capsys.readouterr().err
    assert ended.value.code == 1
    assert "into the table" in err and "Fix:" in err
    lift = [ticks for _, servo, ticks in course_arm.goal_log() if servo == 2]  # shoulder_lift
    home, grasp = lift[0], lift[sent_lift(course_arm, sent) - 1]
    after = lift[sent_lift(course_arm, sent):]
    # goals carry the feed-forward: up to 0.5 deg (6 ticks) of friction push at P = 16 on
    # the virtual arm's 5 V; the refused target is 8 deg (91 ticks) beyond the grasp
    assert all(min(home, grasp) - 10 <= t <= max(home, grasp) + 10 for t in after), \
        "after the refusal, shoulder_lift only went back towards the start"
    assert err.strip().splitlines()[-1] == "Back at the starting pose, torque off."
    bus.disconnect(disable_torque=False)


@pytest.mark.hw
def test_the_virtual_hand_refuses_with_the_same_check():
    pytest.importorskip("lerobot")
    from so101_kinematics.virtual.arm import VirtualSO101

    with VirtualSO101(torque_on_start=False) as virtual:
        with pytest.raises(Exception, match="into the table"):
            virtual.hand_move([SWING_A, SWING_B])


@pytest.mark.hw
def test_the_real_run_refuses_a_plan_into_the_table_before_the_port_opens(tmp_path, capsys):
    pytest.importorskip("lerobot")
    from so101_kinematics.virtual.arm import VirtualSO101

    path = tmp_path / "press.json"
    steps = [{"name": "above", "configuration": STARTING_CONFIGURATION},
             {"name": "press", "configuration": INTO_TABLE}]
    path.write_text(json.dumps({"steps": steps}))
    with VirtualSO101() as arm:
        rc = cli.main(["--port", arm.port, "--calibration", "calibration/virtual_so101.json",
                       "--yes", "--plan", str(path)])
        assert rc == 2
        assert "waypoint 'press'" in capsys.readouterr().err
        assert arm.goal_log() == []  # nothing sent: refused before the port opened

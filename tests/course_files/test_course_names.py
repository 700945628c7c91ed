"""The course's names a student imports: converters, trims, the wrist point, pick and place.

Expected values come from the model's own ranges (MuJoCo), the FK factors'
product (assignment 7's ``g_w4 = g_wt g_4t^-1`` must give back frame 4 of a
configuration), the assignment 8 page (3 cm above, gripper 50 / 5, 1 s
steps) and hand arithmetic on the printed limits.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import so101_mujoco_utils as utils
from so101_forward_kinematics import (
    JOINTS,
    get_forward_kinematics,
    get_g12,
    get_g23,
    get_g34,
    get_gw1,
)
from so101_kinematics.errors import JointLimitError, PlanError, UnreachableError
from so101_kinematics.frames import JOINT_LIMITS
from so101_kinematics.hw.course_calibration import ScriptEnded
from so101_kinematics.inputs import (
    LIMIT_TOLERANCE,
    check_configuration,
    format_limit,
    limit_excess,
)

REPO = Path(__file__).resolve().parents[2]
START = {"shoulder_pan": -45.0, "shoulder_lift": 45.0, "elbow_flex": -45.0, "wrist_flex": 90.0,
         "wrist_roll": 0.0, "gripper": 50.0}


# --- convert_to_dictionary / convert_to_list ------------------------------------------------

def test_convert_to_dictionary_of_qpos_is_the_measured_configuration(model, data):
    utils.set_initial_pose(data, START)
    utils.move_to_pose(model, data, None, dict(START, shoulder_pan=10.0, gripper=20.0), 0.3)
    converted = utils.convert_to_dictionary(data.qpos)
    measured = utils.get_configuration(model, data)
    assert list(converted) == list(JOINTS)
    for joint in JOINTS:
        assert converted[joint] == pytest.approx(measured[joint], abs=1e-9)


def test_convert_to_list_into_ctrl_commands_what_send_position_command_does(model, data):
    cfg = dict(START, gripper=5.0)
    utils.send_position_command(data, cfg)
    expected = data.ctrl.copy()
    data.ctrl[:] = 0.0
    data.ctrl[:] = utils.convert_to_list(cfg)
    np.testing.assert_allclose(data.ctrl, expected, atol=1e-12)


def test_the_gripper_maps_0_100_onto_the_model_s_range(model):
    lower, upper = model.joint("gripper").range  # -10 deg closed, 100 deg open
    at = {g: utils.convert_to_list(dict(START, gripper=g))[5] for g in (0.0, 100.0)}
    assert at[0.0] == pytest.approx(lower, abs=1e-7) and at[100.0] == pytest.approx(upper, abs=1e-7)
    qpos = [0.0] * 5 + [lower]
    assert utils.convert_to_dictionary(qpos)["gripper"] == pytest.approx(0.0, abs=1e-5)


def test_converters_round_trip_and_arm_joints_are_degrees():
    rng = np.random.default_rng(7)
    for _ in range(50):
        angles = rng.uniform(-1.6, 1.6, 6)
        cfg = utils.convert_to_dictionary(angles)
        assert cfg["elbow_flex"] == pytest.approx(math.degrees(angles[2]), abs=1e-12)
        np.testing.assert_allclose(utils.convert_to_list(cfg), angles, atol=1e-12)


def test_a_pose_copied_from_the_viewer_converts_as_printed():
    cfg = utils.convert_to_dictionary(np.array([0.0, -1.75, 0.0, 0.0, 0.0, 0.0, 9.9]))  # + a cube
    assert cfg["shoulder_lift"] == pytest.approx(-100.2676141, abs=1e-6)  # -1.75 * 180 / pi


@pytest.mark.parametrize(("call", "message"), [
    (lambda: utils.convert_to_dictionary([0.0, 1.0]), "six joint angles"),
    (lambda: utils.convert_to_dictionary(None), "six joint angles"),
    (lambda: utils.convert_to_dictionary([0.0] * 5 + [float("nan")]), "'gripper'"),
    (lambda: utils.convert_to_list({"shoulder_pan": 0.0}), "'shoulder_lift' is missing"),
    (lambda: utils.convert_to_list([0.0] * 6), "configuration dict"),
])
def test_converters_refuse_bad_input_in_one_line(call, message):
    with pytest.raises(PlanError, match=message) as error:
        call()
    assert "\n" not in str(error.value)


def test_qpos_passed_as_a_configuration_is_refused_in_one_line_naming_the_converter(model, data):
    for call in (lambda: utils.move_to_pose(model, data, None, data.qpos, 1.0),
                 lambda: utils.set_initial_pose(data, [0.0] * 6),
                 lambda: utils.send_position_command(data, data.qpos)):
        with pytest.raises(PlanError, match=r"must be a dict .*convert_to_dictionary\(d\.qpos\)"):
            call()
    assert data.time == 0.0


# --- limits: accept what they print -----------------------------------------------------------

@pytest.mark.parametrize("joint", JOINTS)
def test_a_limit_as_printed_is_accepted_and_a_refused_value_prints_beyond_it(joint):
    for side, limit in ((-1, JOINT_LIMITS[joint][0]), (1, JOINT_LIMITS[joint][1])):
        printed = float(format_limit(limit))
        accepted = check_configuration({joint: printed}, {joint: JOINT_LIMITS[joint]})[joint]
        assert abs(accepted - printed) <= LIMIT_TOLERANCE / 2  # on the limit, or just inside
        refused = limit + side * 1.01e-5
        with pytest.raises(JointLimitError) as error:
            check_configuration({joint: refused}, {joint: JOINT_LIMITS[joint]})
        assert f"{joint} = {format_limit(refused)} " in str(error.value)
        assert format_limit(refused) != format_limit(limit)


def test_the_issue_s_round_numbers_are_within_the_model_s_limits():
    for joint, value in (("shoulder_lift", -100), ("shoulder_pan", -110), ("wrist_flex", 95)):
        assert limit_excess(value, *JOINT_LIMITS[joint]) <= LIMIT_TOLERANCE
    # and by hand: wrist_flex's 95 deg is 1.65806 rad, 94.9999966 deg: 3.4e-6 deg inside
    assert limit_excess(95.0, *JOINT_LIMITS["wrist_flex"]) == pytest.approx(3.44e-6, abs=1e-8)


def test_limit_messages_print_the_deciding_digits():
    with pytest.raises(JointLimitError, match=r"elbow_flex = 96\.82989 deg is outside its limits "
                                              r"\[-96\.82987, 96\.82987\] deg"):
        check_configuration({"elbow_flex": 96.82989}, {"elbow_flex": JOINT_LIMITS["elbow_flex"]})


# --- get_wrist_flex_position -------------------------------------------------------------------

def test_wrist_flex_position_gives_back_frame_4_of_a_configuration():
    from so101_inverse_kinematics import get_wrist_flex_position

    rng = np.random.default_rng(3)
    for _ in range(20):
        q = {j: float(rng.uniform(-60, 60)) for j in JOINTS}
        q["wrist_roll"] = 0.0  # g_4t = g_45(0) g_5t: the course's step, at wrist_roll 0
        position, rotation = get_forward_kinematics(q)
        g_w4 = (get_gw1(q["shoulder_pan"]) @ get_g12(q["shoulder_lift"])
                @ get_g23(q["elbow_flex"]) @ get_g34(q["wrist_flex"]))
        p_w4, r_w4 = get_wrist_flex_position(position, rotation)
        np.testing.assert_allclose(p_w4, g_w4[:3, 3], atol=1e-12)
        np.testing.assert_allclose(r_w4, g_w4[:3, :3], atol=1e-12)


def test_wrist_flex_position_of_a_top_down_target_is_above_it():
    from so101_inverse_kinematics import get_wrist_flex_position

    position, rotation = get_wrist_flex_position([0.2, 0.1, 0.014])
    assert position[2] == pytest.approx(0.014 + 0.0611 + 0.1075, abs=1e-9)  # gripper + tool [m]
    np.testing.assert_allclose(rotation[:, 1], [0.0, 0.0, 1.0], atol=1e-12)  # y_4: the approach


# --- pick_up_block / place_block ----------------------------------------------------------------

def test_pick_up_block_in_simulation_follows_the_page(model, data):
    """Above the block open (50) in move_to_duration, down, close (5), lift: 1 s each."""
    block = [0.2, 0.1, 0.014]
    utils.set_initial_pose(data, START)
    commands, times = [], []
    real_move = utils.move_to_pose

    def spy(m, d, viewer, cfg, duration):
        real_move(m, d, viewer, cfg, duration)
        commands.append(utils.get_command(m, d))
        times.append(duration)

    utils.move_to_pose, saved = spy, utils.move_to_pose
    try:
        utils.pick_up_block(model, data, None, block, 2.0)
    finally:
        utils.move_to_pose = saved
    assert times == [2.0, 1.0, 1.0, 1.0]
    assert [round(c["gripper"]) for c in commands] == [50, 50, 5, 5]
    heights = [get_forward_kinematics(c)[0] for c in commands]
    np.testing.assert_allclose(heights[0], [0.2, 0.1, 0.044], atol=1e-6)  # 3 cm above
    np.testing.assert_allclose(heights[1], block, atol=1e-6)
    np.testing.assert_allclose(heights[3], [0.2, 0.1, 0.044], atol=1e-6)
    assert data.time == pytest.approx(5.0, abs=2 * model.opt.timestep)


def test_place_block_out_of_reach_stops_before_the_arm_moves(model, data):
    utils.set_initial_pose(data, START)
    with pytest.raises(UnreachableError, match="wrist_flex"):
        utils.place_block(model, data, None, [0.25, -0.1, 0.043], 2.0)  # 3 cm above: too high
    assert data.time == 0.0
    with pytest.raises(PlanError, match="move_to_duration"):
        utils.pick_up_block(model, data, None, [0.2, 0.1, 0.014], "2")
    assert data.time == 0.0


def test_offset_config_without_an_arm_adds_nothing():
    from so101_utils import offset_config

    cfg = {"shoulder_lift": 10.0, "elbow_flex": 20.0}
    out = offset_config(cfg)
    assert out == cfg and out is not cfg


def test_the_course_names_import():
    import so101_utils
    from so101_inverse_kinematics import get_wrist_flex_position  # noqa: F401
    from so101_mujoco_utils import (  # noqa: F401
        convert_to_dictionary,
        convert_to_list,
        pick_up_block,
        place_block,
    )

    for name in ("load_calibration", "setup_motors", "move_to_pose", "hold_position",
                 "offset_config", "pick_up_block", "place_block"):
        assert callable(getattr(so101_utils, name)), name


# --- on the real arm's path (the virtual arm) ---------------------------------------------------

@pytest.mark.slow
@pytest.mark.newest_lerobot
@pytest.mark.hw
def test_offset_config_reads_the_trims_given_to_setup_motors(course_arm):
    import so101_utils

    calibration = so101_utils.load_calibration(str(REPO / "calibration" / "virtual_so101.json"))
    bus = so101_utils.setup_motors(calibration, course_arm.port,
                                   offset_config={"shoulder_lift": 2.0, "elbow_flex": -4.0})
    try:
        cfg = dict(START, shoulder_lift=10.0, elbow_flex=20.0)
        assert so101_utils.offset_config(cfg) == dict(cfg, shoulder_lift=12.0, elbow_flex=16.0)
    finally:
        bus.disable_torque()
        bus.disconnect(disable_torque=False)


@pytest.mark.slow
@pytest.mark.newest_lerobot
@pytest.mark.hw
def test_an_unreachable_block_on_the_arm_ends_the_script_before_it_moves(course_arm, capsys):
    import so101_utils

    calibration = so101_utils.load_calibration(str(REPO / "calibration" / "virtual_so101.json"))
    bus = so101_utils.setup_motors(calibration, course_arm.port)
    before = course_arm.joint_positions()
    with pytest.raises(ScriptEnded) as ended:
        so101_utils.place_block(bus, [0.25, -0.1, 0.043], 2.0)  # 3 cm above it: out of reach
    assert ended.value.code == 1
    err = capsys.readouterr().err
    assert "ABORTED: place_block:" in err and "wrist_flex" in err and "Traceback" not in err
    after = course_arm.joint_positions()
    moved = {j: round(after[j] - before[j], 2) for j in JOINTS}
    assert all(abs(v) < 1.0 for v in moved.values()), moved  # it never moved away
    assert not any(course_arm.torque_enabled().values())
    bus.disconnect(disable_torque=False)

"""MuJoCo utils: the one unit conversion, limit checks before motion, and simulation timing."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

import so101_mujoco_utils as utils
from so101_forward_kinematics import ARM_JOINTS, JOINTS
from so101_kinematics.errors import PlanError

START = {"shoulder_pan": -45.0, "shoulder_lift": 45.0, "elbow_flex": -45.0, "wrist_flex": 90.0,
         "wrist_roll": 0.0, "gripper": 50.0}


def random_configuration(model, rng) -> dict[str, float]:
    limits = utils.joint_limits(model)
    return {j: float(rng.uniform(*limits[j])) for j in JOINTS}


def test_conversion_round_trips(model):
    rng = np.random.default_rng(1)
    for _ in range(200):
        cfg = random_configuration(model, rng)
        back = utils.from_radians(model, utils.to_radians(model, cfg))
        assert back.keys() == cfg.keys()
        for joint in JOINTS:
            assert back[joint] == pytest.approx(cfg[joint], abs=1e-10)
        angles = utils.to_radians(model, cfg)
        for joint in ARM_JOINTS:
            assert angles[joint] == pytest.approx(math.radians(cfg[joint]), abs=1e-15)


def test_gripper_mapping_endpoints_are_the_joint_range(model):
    lower, upper = model.joint("gripper").range
    assert utils.gripper_to_radians(model, 0.0) == pytest.approx(lower, abs=1e-15)
    assert utils.gripper_to_radians(model, 100.0) == pytest.approx(upper, abs=1e-15)
    assert utils.gripper_to_radians(model, 50.0) == pytest.approx((lower + upper) / 2, abs=1e-15)
    assert utils.gripper_from_radians(model, lower) == pytest.approx(0.0, abs=1e-12)
    assert utils.gripper_from_radians(model, upper) == pytest.approx(100.0, abs=1e-12)
    assert utils.joint_limits(model)["gripper"] == (0.0, 100.0)


def test_arm_limits_are_the_model_ranges_in_degrees(model):
    limits = utils.joint_limits(model)
    for joint in ARM_JOINTS:
        np.testing.assert_allclose(limits[joint], np.degrees(model.joint(joint).range))


def test_set_initial_pose_places_and_commands_the_arm(model, data):
    utils.set_initial_pose(data, START)
    measured, commanded = utils.get_configuration(model, data), utils.get_command(model, data)
    for joint in JOINTS:
        assert measured[joint] == pytest.approx(START[joint], abs=1e-9)
        assert commanded[joint] == pytest.approx(START[joint], abs=1e-9)
    assert not np.any(data.qvel)


def state(data):
    return data.time, data.qpos.copy(), data.ctrl.copy()


def assert_untouched(data, before):
    time, qpos, ctrl = before
    assert data.time == time
    np.testing.assert_array_equal(data.qpos, qpos)
    np.testing.assert_array_equal(data.ctrl, ctrl)


@pytest.mark.parametrize("joint", JOINTS)
@pytest.mark.parametrize("side", [-1, 1])
def test_out_of_limit_targets_are_held_at_the_limit_with_one_warning(model, data, joint, side,
                                                                      caplog):
    """The course's utils write qpos/ctrl as given and MuJoCo holds the joint at its range."""
    lower, upper = model.joint(joint).range  # [rad], the model's range
    limit_rad = upper if side > 0 else lower
    limit = utils.joint_limits(model)[joint][1 if side > 0 else 0]
    value = round(limit) + 5.0 * side
    printed_limit = f"{limit:.5f}".rstrip("0").rstrip(".")  # to 1e-5, within the tolerance
    bad = dict(START, **{joint: value})
    calls = {"move_to_pose": lambda: utils.move_to_pose(model, data, None, bad, 0.02),
             "set_initial_pose": lambda: utils.set_initial_pose(data, bad),
             "send_position_command": lambda: utils.send_position_command(data, {joint: value}),
             "hold_position": lambda: utils.hold_position(model, data, None, bad, 0.02)}
    for name, call in calls.items():
        utils.set_initial_pose(data, START)
        caplog.clear()
        call()
        warnings = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
        assert len(warnings) == 1, (name, warnings)
        assert f"{joint} = {value:g} " in warnings[0] and f"limit {printed_limit} " in warnings[0]
        assert "held at the limit" in warnings[0] and "\n" not in warnings[0]
        assert data.ctrl[model.actuator(joint).id] == pytest.approx(limit_rad, abs=1e-12), name


def test_a_pose_copied_from_the_viewer_runs_held_at_the_limit(model, data, caplog):
    """shoulder_lift -1.75 rad (-100.268 deg) and -180: the course's set_initial_pose runs them."""
    for value in (math.degrees(-1.75), -180.0):
        utils.set_initial_pose(data, dict(START, shoulder_lift=value))
        assert data.qpos[model.joint("shoulder_lift").qposadr[0]] == pytest.approx(
            -1.7453292519943, abs=1e-12)  # the model's range, -100 deg
    assert sum("shoulder_lift" in r.getMessage() for r in caplog.records) == 2


@pytest.mark.parametrize(("joint", "value"), [("shoulder_lift", -100), ("shoulder_pan", -110),
                                              ("shoulder_pan", 110), ("wrist_flex", 95),
                                              ("wrist_flex", -95), ("shoulder_lift", 100)])
def test_a_limit_s_round_number_is_within_it(model, data, joint, value, caplog):
    """The issue's moves: on the limit as printed, no error and no warning."""
    utils.set_initial_pose(data, START)
    utils.move_to_pose(model, data, None, dict(START, **{joint: value}), 0.02)
    assert not [r for r in caplog.records if r.levelname == "WARNING"]
    assert utils.get_command(model, data)[joint] == pytest.approx(value, abs=1e-5)


@pytest.mark.parametrize("value", [float("nan"), float("inf"), "10", None])
def test_non_numeric_targets_are_refused_naming_the_joint(model, data, value):
    utils.set_initial_pose(data, START)
    before = state(data)
    with pytest.raises(PlanError, match="'wrist_flex'"):
        utils.move_to_pose(model, data, None, dict(START, wrist_flex=value), 1.0)
    assert_untouched(data, before)


def test_missing_and_unknown_joints_are_refused(model, data):
    incomplete = {k: v for k, v in START.items() if k != "elbow_flex"}
    with pytest.raises(PlanError, match="'elbow_flex'"):
        utils.set_initial_pose(data, incomplete)
    with pytest.raises(PlanError, match="'elbow'.*elbow_flex"):
        utils.move_to_pose(model, data, None, dict(incomplete, elbow=0.0), 1.0)


def test_move_to_pose_is_timed_on_simulation_time_and_ends_at_the_goal(model, data):
    utils.set_initial_pose(data, START)
    goal = dict(START, shoulder_pan=0.0, wrist_roll=30.0, gripper=20.0)
    t0 = data.time
    utils.move_to_pose(model, data, None, goal, 0.5, profile="linear")
    assert data.time == pytest.approx(t0 + 0.5, abs=model.opt.timestep)
    command = utils.get_command(model, data)
    for joint in JOINTS:
        assert command[joint] == pytest.approx(goal[joint], abs=1e-9)
    utils.hold_position(model, data, None, 1.5)
    measured = utils.get_configuration(model, data)
    for joint in ARM_JOINTS:
        assert measured[joint] == pytest.approx(goal[joint], abs=1.0)


class ClosingViewer:
    """A viewer stub whose window closes after a few syncs."""

    offscreen = True

    def __init__(self, open_syncs: int):
        self.syncs, self.open_syncs = 0, open_syncs

    def is_running(self) -> bool:
        return self.syncs < self.open_syncs

    def sync(self) -> None:
        self.syncs += 1


def test_closing_the_viewer_stops_the_motion_and_every_later_call_returns_at_once(model, data):
    """The course's ``while viewer.is_running():`` loop ends: nothing raises, no time passes."""
    utils.set_initial_pose(data, START)
    viewer = ClosingViewer(open_syncs=3)
    loops = 0
    while viewer.is_running():
        loops += 1
        utils.move_to_pose(model, data, viewer, dict(START, shoulder_pan=0.0), 10.0)
        utils.hold_position(model, data, viewer, START, 10.0)
        utils.pick_up_block(model, data, viewer, [0.2, 0.0, 0.014], 2.0)
    assert loops == 1 and viewer.syncs == 3
    assert data.time < 1.0
    t_closed = data.time
    utils.hold_position(model, data, viewer, 10.0)
    assert data.time == t_closed


def test_the_project_s_runners_can_still_stop_on_a_closed_viewer(model, data):
    utils.set_initial_pose(data, START)
    viewer = ClosingViewer(open_syncs=3)
    with pytest.raises(utils.ViewerClosed):
        utils.hold_position(model, data, viewer, 10.0, raise_if_closed=True)
    assert viewer.syncs == 3
    with pytest.raises(utils.ViewerClosed):
        utils.move_to_pose(model, data, viewer, START, 1.0, raise_if_closed=True)


def test_headless_runs_are_deterministic(model):
    finals = []
    for _ in range(2):
        data = mujoco.MjData(model)
        utils.set_initial_pose(data, START)
        utils.move_to_pose(model, data, None, dict(START, shoulder_pan=30.0), 0.4)
        finals.append(data.qpos.copy())
    np.testing.assert_array_equal(finals[0], finals[1])


# --- hold_position: the course's two call shapes --------------------------------------------


def test_hold_position_with_a_configuration_commands_it_then_holds(model, data):
    """Assignment 7's shape: hold_position(m, d, viewer, cfg, duration)."""
    utils.set_initial_pose(data, START)
    goal = dict(START, shoulder_pan=-30.0, elbow_flex=-40.0, gripper=30.0)
    utils.hold_position(model, data, None, goal, 1.5)
    assert data.time == pytest.approx(1.5, abs=model.opt.timestep)
    command, measured = utils.get_command(model, data), utils.get_configuration(model, data)
    for joint in JOINTS:
        assert command[joint] == pytest.approx(goal[joint], abs=1e-9)
    for joint in ARM_JOINTS:  # the servos got there: 5 deg and 15 deg steps, 1.5 s to settle
        assert measured[joint] == pytest.approx(goal[joint], abs=1.0)


def test_hold_position_without_a_configuration_keeps_the_command(model, data):
    """Assignment 6's shape: hold_position(m, d, viewer, duration); keywords work too."""
    utils.set_initial_pose(data, START)
    utils.send_position_command(data, {"shoulder_pan": -40.0})
    utils.hold_position(model, data, None, 0.5)
    utils.hold_position(model, data, None, duration=0.5)
    assert data.time == pytest.approx(1.0, abs=model.opt.timestep)
    assert utils.get_command(model, data)["shoulder_pan"] == pytest.approx(-40.0, abs=1e-9)
    assert utils.get_configuration(model, data)["shoulder_pan"] == pytest.approx(-40.0, abs=1.0)


def test_hold_position_shapes_give_the_same_physics(model):
    """cfg then duration = send_position_command(cfg) then hold(duration), step for step."""
    goal = dict(START, wrist_flex=60.0)
    finals = []
    for call in (lambda m, d: utils.hold_position(m, d, None, goal, 0.6),
                 lambda m, d: utils.hold_position(m, d, None, cfg=goal, duration=0.6),
                 lambda m, d: (utils.send_position_command(d, goal),
                               utils.hold_position(m, d, None, 0.6))):
        data = mujoco.MjData(model)
        utils.set_initial_pose(data, START)
        call(model, data)
        finals.append(data.qpos.copy())
    np.testing.assert_array_equal(finals[0], finals[1])
    np.testing.assert_array_equal(finals[0], finals[2])


@pytest.mark.parametrize("args, kwargs, message", [
    ((START, START), {}, r"got a configuration \(.*\) where the duration \[s\] belongs"),
    ((2.0, START), {}, r"got the duration \(2\) before the configuration"),
    ((START, 2.0, 3.0), {}, r"takes at most 5 arguments, got 6"),
    ((START,), {}, r"needs a duration \[s\] after the configuration"),
    ((), {}, r"needs a duration \[s\] \(how long"),
    (([0.0] * 6, 2.0), {}, r"configuration must be a dict .*got \[0\.0, 0\.0"),
    ((2.0,), {"duration": 2.0}, "got duration both by position and by keyword"),
])
def test_hold_position_refuses_other_shapes_naming_both(model, data, args, kwargs, message):
    utils.set_initial_pose(data, START)
    with pytest.raises(utils.CallShapeError, match=message) as caught:
        utils.hold_position(model, data, None, *args, **kwargs)
    text = str(caught.value)
    assert "\n" not in text
    if "before the configuration" not in text:
        assert utils.HOLD_SHAPES in text
    assert isinstance(caught.value, PlanError) and isinstance(caught.value, TypeError)
    assert data.time == 0.0  # nothing ran


@pytest.mark.parametrize("viewer", [2.0, START])
def test_hold_position_names_a_missing_viewer(model, data, viewer):
    with pytest.raises(utils.CallShapeError, match="third argument is the viewer"):
        utils.hold_position(model, data, viewer, 2.0)


def test_hold_position_checks_its_configuration_before_any_step(model, data):
    utils.set_initial_pose(data, START)
    with pytest.raises(PlanError, match="unknown joint 'elbow'.*Fix: use those names"):
        utils.hold_position(model, data, None, {"elbow": 0.0}, 1.0)
    with pytest.raises(PlanError, match="unknown joint ''.*Fix:"):  # the fuzz test's find
        utils.hold_position(model, data, None, {"": 0}, 1.0)
    assert data.time == 0.0
    assert utils.get_command(model, data) == pytest.approx(START)


# --- move_to_pose: assignment 8's starting configuration --------------------------------------


def run_moves(model, moves) -> np.ndarray:
    """qpos after ``moves`` (each a tuple of move_to_pose's arguments after m, d, viewer)."""
    data = mujoco.MjData(model)
    utils.set_initial_pose(data, START)
    for args in moves:
        utils.move_to_pose(model, data, None, *args)
    return data.qpos.copy()


def test_a_starting_configuration_at_the_last_command_moves_as_the_course_form(model, caplog):
    """Assignment 8's ``move_to_pose(m, d, viewer, starting_cfg, cfg, duration)``: chained
    moves pass the previous target as the start, which is where the command already is."""
    first, second = dict(START, shoulder_pan=20.0), dict(START, elbow_flex=-20.0, gripper=10.0)
    course = run_moves(model, [(first, 0.4), (second, 0.3)])
    with_start = run_moves(model, [(START, first, 0.4), (first, second, 0.3)])
    np.testing.assert_array_equal(with_start, course)
    assert "starting configuration" not in caplog.text
    by_keyword = mujoco.MjData(model)
    utils.set_initial_pose(by_keyword, START)
    utils.move_to_pose(model, by_keyword, None, cfg=first, duration=0.4)
    np.testing.assert_array_equal(by_keyword.qpos, run_moves(model, [(first, 0.4)]))


def test_a_starting_configuration_away_from_the_command_is_named_and_not_jumped_to(model, caplog):
    goal = dict(START, shoulder_pan=0.0)
    elsewhere = dict(START, shoulder_pan=-43.0, wrist_flex=60.0)  # 2 deg and 30 deg off
    np.testing.assert_array_equal(run_moves(model, [(elsewhere, goal, 0.4)]),
                                  run_moves(model, [(goal, 0.4)]))
    assert "starting configuration is 30.0 deg from the last command (wrist_flex: 60 given, " \
           "90 commanded)" in caplog.text


@pytest.mark.parametrize("args, says", [
    ((2.0,), "got one argument (2)"),  # assignment 8's pick_up_block: move_to_pose(bus, time)
    ((START,), "got one argument ({'shoulder_pan'"),
    ((START, START, START), "a configuration ({'shoulder_pan'"),
    ((START, START, 1.0, 2.0), "got 4 arguments"),
    ((3.0, START, 1.0), "starting configuration must be a dict joint name -> value, got 3"),
    (({"elbow": 0.0}, START, 1.0), "unknown joint 'elbow'. Did you mean 'elbow_flex'?"),
    (({"elbow_flex": "0"}, START, 1.0), "'elbow_flex' must be a finite number"),
])
def test_other_move_shapes_name_the_accepted_ones_before_any_step(model, data, args, says):
    utils.set_initial_pose(data, START)
    with pytest.raises(utils.CallShapeError) as error:
        utils.move_to_pose(model, data, None, *args)
    assert says in str(error.value)
    assert "move_to_pose(m, d, viewer, starting_cfg, cfg, duration)" in str(error.value) \
        or "Fix: use those names" in str(error.value) or "Fix: give" in str(error.value)
    assert data.time == 0.0

"""The hardware run's policy without an arm: plan checks, settings, every ending of execute()."""

from __future__ import annotations

from pathlib import Path

import pytest
from hw_fakes import HOME, FakeBus, FakeClock, make_session  # noqa: F401

import so101_kinematics.hw.run as hw
from so101_forward_kinematics import JOINTS
from so101_kinematics.calibration import ServoCalibration
from so101_kinematics.errors import FreezeRequested, JointLimitError, PlanError
from so101_kinematics.hw.preflight import check_run_settings, validate_plan_for_arm
from so101_kinematics.planning.motion import Plan, Step
from so101_kinematics.planning.plans import default_plan

REPO = Path(__file__).resolve().parents[2]
VIRTUAL_CALIBRATION = REPO / "calibration" / "virtual_so101.json"


# --- plan validation -------------------------------------------------------------------
def test_default_plan_passes_both_limit_checks(calibration):
    validate_plan_for_arm(default_plan(), calibration)


def test_waypoint_beyond_the_model_limit_names_joint_value_and_limit(calibration):
    plan = default_plan()
    plan.steps[2].configuration["elbow_flex"] = -100.0
    with pytest.raises(JointLimitError) as info:
        validate_plan_for_arm(plan, calibration)
    message = str(info.value)
    assert "elbow_flex = -100" in message and "model" in message and plan.steps[2].name in message


def test_waypoint_beyond_a_narrow_calibration_is_refused(calibration):
    narrow = dict(calibration, shoulder_lift=ServoCalibration(2, 0, 0, 1600, 2500))
    with pytest.raises(JointLimitError) as info:
        validate_plan_for_arm(default_plan(), narrow, "lab_arm.json")
    message = str(info.value)
    assert "shoulder_lift" in message and "calibrated range" in message
    assert "lab_arm.json" in message


def test_plan_errors_name_the_problem(calibration):
    with pytest.raises(PlanError, match="no steps"):
        validate_plan_for_arm(Plan([]), calibration)
    plan = Plan([Step("a", dict(HOME, wrist_flex="up"))])
    with pytest.raises(PlanError, match="wrist_flex.*finite number"):
        validate_plan_for_arm(plan, calibration)


def at_step(step, action):
    """An on_cycle hook running ``action(session)`` once, at the first cycle of ``step``."""
    def on_cycle(session, cycle):
        if cycle.step == step and not on_cycle.fired:
            on_cycle.fired.append(cycle.t_s)
            action(session)

    on_cycle.fired = []
    return on_cycle


def run(calibration, clock, hook=None, plan=None, **kwargs):
    """execute() of ``plan`` (default: the course's, short) from HOME on a fake arm.

    Returns (result, bus, error): ``error`` is the MotionAborted, or None.
    """
    session, bus = make_session(calibration, clock, on_cycle=hook)
    plan = validate_plan_for_arm(plan or default_plan(0.6, 0.1), calibration)
    try:
        return hw.execute(session, plan, dict(HOME), **kwargs), bus, None
    except hw.MotionAborted as error:
        return error.result, bus, error


def assert_released_only_at_the_start(result, bus):
    """The policy: torque off means the arm is at its starting pose."""
    if not any(bus.torque.values()):
        assert bus.pose == pytest.approx(HOME, abs=1e-6)
        assert result.returned_to_start and result.torque_released


RELEASE = "python pick_place_hw.py --release --port P --id arm"


def test_stop_request_returns_slowly_to_the_start_and_releases(calibration, clock):
    stop = at_step("lift", lambda s: setattr(s, "stop_reason", "Ctrl-C"))
    result, bus, error = run(calibration, clock, stop)
    assert "stopped by Ctrl-C" in str(error) and "'lift'" in str(error)
    assert result.returned_to_start and result.unreleased == []
    assert not any(bus.torque.values())
    assert bus.goals[-1] == pytest.approx(HOME)
    back = [s for s in result.segments if s.step == "abort_return"]
    assert len(back) == 1
    # "slowly": 20 deg/s (README), minimum jerk peaks at 1.875 x the mean speed, >= 1 s
    distance = max(abs(back[0].goal[j] - back[0].start[j]) for j in JOINTS)
    assert back[0].duration == pytest.approx(max(1.0, distance * 1.875 / 20.0), rel=1e-3)
    assert hw.ending(result, RELEASE) == "Back at the starting pose, torque off."


def test_a_servo_that_never_answers_leaves_the_others_holding(calibration, clock):
    def silence_wrist(session):
        session.bus.silent.add("wrist_flex")
        session.bus.fail_until = clock.now + 1e6

    result, bus, error = run(calibration, clock, at_step("carry", silence_wrist))
    assert "did not answer" in str(error)
    assert result.silent == ["wrist_flex"] and not result.returned_to_start
    assert all(bus.torque.values())  # nobody released: the arm is not at its start
    assert not any(s.step == "abort_return" for s in result.segments)  # no half-arm return
    line = hw.ending(result, RELEASE)
    assert "Not answering: wrist_flex (id 4)" in line and "torque ON" in line
    assert line.endswith(RELEASE) and "power" in line


def test_a_servo_answering_with_an_error_bit_is_not_named_silent(calibration, clock):
    def silence_wrist_overload_gripper(session):
        session.bus.silent.add("wrist_flex")
        session.bus.status["gripper"] = 0x20  # overload: it answers, with the bit set
        session.bus.fail_until = clock.now + 1e6

    result, bus, error = run(calibration, clock, at_step("carry", silence_wrist_overload_gripper))
    assert result.silent == ["wrist_flex"] and all(bus.torque.values())
    assert "Not answering: wrist_flex (id 4)" in hw.ending(result, RELEASE)


def test_an_outage_that_recovers_after_the_tolerance_returns_and_releases(calibration, clock):
    down = at_step("carry", lambda s: setattr(s.bus, "fail_until", clock.now + 2.5))
    result, bus, error = run(calibration, clock, down)
    assert "did not answer" in str(error) and "'carry'" in str(error)
    assert result.returned_to_start and not any(bus.torque.values())
    assert_released_only_at_the_start(result, bus)


def test_an_outage_within_the_tolerance_completes_the_run(calibration, clock):
    down = at_step("carry", lambda s: setattr(s.bus, "fail_until", clock.now + 0.5))
    result, bus, error = run(calibration, clock, down)
    assert error is None and result.returned_to_start and not any(bus.torque.values())
    assert [len(result.outages), round(result.outages[0][1], 1)] == [1, 0.5]
    moves = [s.step for s in result.segments if s.kind == "move"]
    assert moves[-1] == "return_to_start" and "carry" in moves


def test_a_plan_without_return_ends_holding_with_torque_on(calibration, clock):
    plan = default_plan(0.6, 0.1)
    plan.return_to_start = False
    result, bus, error = run(calibration, clock, plan=plan)
    assert error is None and not result.returned_to_start
    assert all(bus.torque.values())
    line = hw.ending(result, RELEASE)
    assert line.startswith("Done: holding the final pose 'depart'") and "torque ON" in line
    assert "return_to_start: false" in line and line.endswith(RELEASE)


def test_a_stall_on_the_way_back_holds_where_it_stopped(calibration, clock):
    def stop(session):
        session.stop_reason = "SIGTERM"

    def block_pan(session, cycle):
        stopper(session, cycle)
        if cycle.step == "abort_return":
            session.bus.stalled.add("shoulder_pan")

    stopper = at_step("carry", stop)
    result, bus, error = run(calibration, clock, block_pan)
    assert "stopped by SIGTERM (during 'carry')" in str(error)
    assert not result.returned_to_start and all(bus.torque.values())
    assert bus.goals[-1] == pytest.approx(bus.pose)  # controlled stop: goal = present
    assert hw.ending(result, RELEASE).startswith("The arm is holding where it stopped")


def test_a_second_signal_during_the_return_freezes_with_torque_on(calibration, clock):
    def signals(session, cycle):
        if cycle.step == "lift" and session.stop_reason is None:
            session.stop_reason = "SIGHUP"
        elif cycle.step == "abort_return" and len(signals.back) == 10:
            raise FreezeRequested("SIGHUP")
        if cycle.step == "abort_return":
            signals.back.append(cycle)

    signals.back = []
    result, bus, error = run(calibration, clock, signals)
    assert result.frozen and not result.returned_to_start and all(bus.torque.values())
    assert bus.goals[-1] == pytest.approx(bus.pose)
    assert hw.ending(result, RELEASE).startswith("Frozen where it was by a second stop signal")


def test_a_servo_error_bit_returns_and_releases(calibration, clock):
    hot = at_step("lift", lambda s: s.bus.status.update(elbow_flex=0x04))  # and it stays set
    result, bus, error = run(calibration, clock, hot)
    assert "elbow_flex servo reports: overheated" in str(error)
    assert result.returned_to_start and not any(bus.torque.values())


def test_a_vanished_port_is_reported_as_the_usb_connection(calibration, clock, tmp_path):
    def unplug(session):
        session.bus.port = str(tmp_path / "ttyACM0")  # a path that does not exist
        session.bus.fail_until = clock.now + 1e6

    result, bus, error = run(calibration, clock, at_step("carry", unplug))
    assert "USB connection was lost" in str(error) and result.usb_lost
    assert all(bus.torque.values())
    line = hw.ending(result, RELEASE)
    assert "USB connection was lost" in line and "hold their last goal" in line


@pytest.mark.parametrize("setting, value", [
    ("--rate", 0.0), ("--rate", 19.9), ("--rate", 501.0), ("--rate", float("nan")),
    ("--max-speed", 0.0), ("--max-speed", -5.0), ("--max-speed", 181.0), ("--max-speed", 1e9),
    ("--max-speed", float("inf")), ("--tracking-tolerance", 0.0), ("--tracking-tolerance", 46.0),
])
def test_settings_out_of_range_are_refused_naming_the_range(setting, value):
    settings = {"--rate": 100.0, "--max-speed": 100.0, "--tracking-tolerance": 15.0}
    settings[setting] = value
    with pytest.raises(PlanError) as info:
        check_run_settings(*settings.values())
    message = str(info.value)
    assert message.startswith(f"{setting} ") and "Fix:" in message
    low, high = {"--rate": (20, 500), "--max-speed": (0, 180),
                 "--tracking-tolerance": (0, 45)}[setting]
    assert f"{low}, {high}]" in message  # the allowed range, from the README


def test_settings_at_their_documented_bounds_are_accepted():
    check_run_settings(20.0, 180.0, 45.0)
    check_run_settings(500.0, 1e-3, 1e-3)

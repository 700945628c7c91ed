"""so101_utils.py, the course's hardware helpers, against the virtual SO-101 through lerobot's bus.

The first test replays assignment 8's hardware example call by call (its
imports, ``load_calibration(ROBOT_NAME)``, ``setup_motors(calibration,
PORT_ID)``, ``bus.sync_read("Present_Position")``, ``move_to_pose(bus, cfg,
2.0)``, ``hold_position(bus, hold_time)``, the move back,
``bus.disable_torque()``); the others are the fault policy's endings inside
and between those calls (docs/hardware_safety.md): a fault, a signal, an
exception, a script that forgets ``disable_torque``. Scripts that need real
signals run in their own process, as a student runs them.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

import so101_kinematics.hw.course_helpers as course
from so101_forward_kinematics import ARM_JOINTS, JOINTS
from so101_kinematics.calibration import calibrated_limits, load_calibration
from so101_kinematics.constants import HOME_POSE
from so101_kinematics.fast_fk import forward_kinematics
from so101_kinematics.gravity import feedforward
from so101_kinematics.hw.course_calibration import ScriptEnded
from so101_kinematics.servo import LEROBOT

REPO = Path(__file__).resolve().parents[2]
CALIBRATION_PATH = REPO / "calibration" / "virtual_so101.json"
ROBOT_NAME = "follower-1"
HOME = HOME_POSE  # the virtual arm powers up there
# The goal that holds the arm at HOME: HOME plus the gravity feed-forward's offsets at
# lerobot's P = 16 on the virtual arm's 5 V (the model's masses over the servo's static law;
# the elbow's is about -4 deg); friction's +-0.5 deg comes on top, in the last move's direction.
HOME_GOAL = {j: HOME[j] + v for j, v in feedforward(HOME, LEROBOT, 5.0).items()}
hw = [pytest.mark.hw]


@pytest.fixture
def arm(course_arm):
    """The virtual arm (tests/conftest.py's course_arm)."""
    return course_arm


@pytest.fixture
def lerobot_calibrations(tmp_path, monkeypatch):
    """Where lerobot keeps calibrations, holding the virtual arm's as robot id ROBOT_NAME."""
    folder = tmp_path / "lerobot_calibration" / "robots" / "so_follower"
    folder.mkdir(parents=True)
    shutil.copy(CALIBRATION_PATH, folder / f"{ROBOT_NAME}.json")
    monkeypatch.setenv("HF_LEROBOT_CALIBRATION", str(tmp_path / "lerobot_calibration"))


def assert_near(actual, expected, tol_deg=1.0, tol_gripper=3.0, joints=JOINTS, label=""):
    for joint in joints:
        tol = tol_gripper if joint == "gripper" else tol_deg
        assert abs(actual[joint] - expected[joint]) <= tol, (
            f"{label} {joint}: {actual[joint]:.2f} vs {expected[joint]:.2f} (tol {tol})")


def goals_outside_calibration(goal_log):
    cal = load_calibration(CALIBRATION_PATH)
    by_id = {c.id: c for c in cal.values()}
    return [(servo, ticks) for _, servo, ticks in goal_log
            if not by_id[servo].range_min <= ticks <= by_id[servo].range_max]


def last_line(text: str) -> str:
    return text.strip().splitlines()[-1]


@pytest.mark.slow
@pytest.mark.newest_lerobot
@pytest.mark.hw
def test_assignment_8_example_runs_as_written(arm, lerobot_calibrations, capsys):
    from so101_inverse_kinematics import get_inverse_kinematics
    from so101_utils import hold_position, load_calibration, move_to_pose, setup_motors

    PORT_ID = arm.port  # noqa: N806 - the course's names
    desired_ee = [0.2, 0.0, 0.014]  # the course's x, y [m]; z at a resting cube's centre
    desired_configuration = get_inverse_kinematics(desired_ee)
    move_time = 2.0  # [s], as the course
    hold_time = 1.0  # [s] (the course holds 10 s)

    calibration = load_calibration(ROBOT_NAME)
    bus = setup_motors(calibration, PORT_ID)
    starting_pose = bus.sync_read("Present_Position")
    move_to_pose(bus, desired_configuration, move_time)
    reached = arm.joint_positions()
    hold_position(bus, hold_time)
    held = arm.joint_positions()
    move_to_pose(bus, starting_pose, move_time)
    bus.disable_torque()

    # held where it stood, within the servo's friction band (0.5 deg at P = 16 on 5 V) and
    # a count of the encoder
    assert_near(starting_pose, HOME, tol_deg=0.7, label="start")
    assert_near(reached, desired_configuration, label="after move_to_pose")
    assert_near(held, desired_configuration, label="after hold_position")
    position = forward_kinematics({j: held[j] for j in ARM_JOINTS})[0]
    assert np.linalg.norm(position - desired_ee) < 0.003  # the object frame is where asked [m]
    assert not any(arm.torque_enabled().values())
    assert_near(arm.joint_positions(), starting_pose, label="end")
    assert goals_outside_calibration(arm.goal_log()) == []
    assert last_line(capsys.readouterr().out) == "Done: back at the starting pose, torque off."
    bus.disconnect()  # lerobot's own call after the release: no second release, no error


@pytest.mark.slow
@pytest.mark.newest_lerobot
@pytest.mark.hw
def test_assignment_8_starting_position_form_never_jumps(arm, capsys, caplog):
    """The course's suggested ``move_to_pose(bus, starting_position, desired_position,
    duration)``: chained as the course chains it, then with a start the arm is not at."""
    from so101_utils import load_calibration, move_to_pose, setup_motors

    bus = setup_motors(load_calibration(str(CALIBRATION_PATH)), arm.port)
    session = course._RUNS[id(bus)].session
    starting_pose = bus.sync_read("Present_Position")
    target = dict(HOME, shoulder_pan=30.0, elbow_flex=70.0)
    move_to_pose(bus, starting_pose, target, 1.0)
    move_to_pose(bus, target, starting_pose, 1.0)
    assert "starting configuration" not in caplog.text
    # read as the move ends: the servo still trails its goal there (the simulator on the same
    # servo, the C001 at P = 16 on 5 V with the D term fitted to real arms (docs/servo_model.md),
    # this 1 s minimum-jerk move: 1.1 deg at its end, 0.5 deg 0.1 s later; 0.25 before the fit)
    assert_near(arm.joint_positions(), starting_pose, tol_deg=1.5, label="back")
    elsewhere = dict(starting_pose, shoulder_pan=starting_pose["shoulder_pan"] - 25.0)
    move_to_pose(bus, elsewhere, target, 1.0)
    assert "starting configuration is 25.0 deg from the last command (shoulder_pan" in caplog.text
    assert_near(session.segments[-1].start, starting_pose, tol_deg=1e-6, tol_gripper=1e-6,
                label="the move began at the last goal")
    assert_near(arm.joint_positions(), target, tol_deg=1.5, label="reached")  # as "back"
    bus.disable_torque()
    assert last_line(capsys.readouterr().out) == "Done: back at the starting pose, torque off."
    bus.disconnect(disable_torque=False)


@pytest.mark.slow
@pytest.mark.newest_lerobot
@pytest.mark.hw
def test_assignment_8_pick_up_block_call_without_a_target_ends_at_the_start(arm, capsys):
    """The course's ``pick_up_block`` calls ``move_to_pose(bus, move_to_duration)``."""
    from so101_utils import load_calibration, move_to_pose, setup_motors

    bus = setup_motors(load_calibration(str(CALIBRATION_PATH)), arm.port)
    move_to_pose(bus, dict(HOME, shoulder_pan=20.0), 1.0)
    with pytest.raises(ScriptEnded) as ended:
        move_to_pose(bus, 2.0)
    assert ended.value.code == 1 and ended.value.result.returned_to_start
    err = capsys.readouterr().err
    assert "move_to_pose got one argument (2) after bus" in err
    assert "move_to_pose(bus, starting_position, desired_position, duration)" in err
    assert last_line(err) == "Back at the starting pose, torque off."
    assert not any(arm.torque_enabled().values())
    bus.disconnect(disable_torque=False)


@pytest.mark.slow
@pytest.mark.newest_lerobot
@pytest.mark.hw
def test_disable_torque_away_from_the_start_returns_there_first(arm, capsys, caplog):
    from so101_utils import load_calibration, move_to_pose, setup_motors

    bus = setup_motors(load_calibration(str(CALIBRATION_PATH)), arm.port)
    away = dict(HOME, shoulder_lift=-40.0, elbow_flex=40.0)  # released here, the arm would fall
    move_to_pose(bus, away, 1.0)
    # at the end of a 1 s move the STS3215 at P = 16 still trails by a few degrees (the
    # simulator on the same servo, C001 5 V, D fitted to real arms: shoulder_lift 2.4 deg at
    # the end of this 1 s minimum-jerk move, 1.2 deg 0.1 s later; 0.8 before the fit)
    assert_near(arm.joint_positions(), away, tol_deg=3.0, label="away")
    bus.disable_torque()
    assert not any(arm.torque_enabled().values())
    assert_near(arm.commanded_positions(), HOME_GOAL, tol_deg=2.0, label="last goal before release")
    assert "away from the starting pose (shoulder_lift, elbow_flex)" in caplog.text
    assert last_line(capsys.readouterr().out) == "Done: back at the starting pose, torque off."
    bus.disconnect(disable_torque=False)


@pytest.mark.slow
@pytest.mark.newest_lerobot
@pytest.mark.hw
def test_an_outage_inside_move_to_pose_ends_back_at_the_start_released(arm, capsys):
    from so101_utils import load_calibration, move_to_pose, setup_motors

    bus = setup_motors(load_calibration(str(CALIBRATION_PATH)), arm.port)
    session = course._RUNS[id(bus)].session
    session.on_cycle = lambda s, c: (len(s.cycles) == 40 and arm.inject("outage:2500"))
    with pytest.raises(ScriptEnded) as ended:
        move_to_pose(bus, dict(HOME, shoulder_pan=40.0, elbow_flex=60.0), 1.5)
    result = ended.value.result
    assert ended.value.code == 1 and result.returned_to_start and result.torque_released
    assert "did not answer" in result.aborted and "during 'move_to_pose'" in result.aborted
    assert not any(arm.torque_enabled().values())
    assert_near(arm.commanded_positions(), HOME_GOAL, tol_deg=2.0, label="last goal before release")
    err = capsys.readouterr().err
    assert last_line(err) == "Back at the starting pose, torque off."
    with pytest.raises(ScriptEnded) as again:  # the run is over: nothing moves any more
        move_to_pose(bus, HOME, 1.0)
    assert again.value.code == 2 and "setup_motors" in again.value.line
    bus.disconnect(disable_torque=False)


@pytest.mark.slow
@pytest.mark.newest_lerobot
@pytest.mark.hw
def test_a_short_outage_inside_move_to_pose_is_ridden_through(arm, capsys):
    from so101_utils import hold_position, load_calibration, move_to_pose, setup_motors

    bus = setup_motors(load_calibration(str(CALIBRATION_PATH)), arm.port)
    session = course._RUNS[id(bus)].session
    session.on_cycle = lambda s, c: (len(s.cycles) == 40 and arm.inject("outage:500"))
    target = dict(HOME, shoulder_pan=30.0, elbow_flex=70.0)
    move_to_pose(bus, target, 1.5)
    hold_position(bus, 0.3)
    assert len(session.outages) == 1
    assert_near(arm.joint_positions(), target, label="reached")
    bus.disable_torque()
    assert not any(arm.torque_enabled().values())
    assert last_line(capsys.readouterr().out) == "Done: back at the starting pose, torque off."
    bus.disconnect(disable_torque=False)


@pytest.mark.slow
@pytest.mark.newest_lerobot
@pytest.mark.hw
def test_a_configuration_outside_the_calibration_ends_the_script_released(arm, capsys):
    from so101_utils import load_calibration, move_to_pose, setup_motors

    bus = setup_motors(load_calibration(str(CALIBRATION_PATH)), arm.port)
    upper = calibrated_limits(load_calibration(CALIBRATION_PATH))["elbow_flex"][1]
    with pytest.raises(ScriptEnded) as ended:
        move_to_pose(bus, dict(HOME, elbow_flex=upper + 10.0), 2.0)
    assert ended.value.code == 1
    err = capsys.readouterr().err
    printed = f"{upper + 10.0:.5f}".rstrip("0").rstrip(".")  # limits print to 5 decimals
    assert f"elbow_flex = {printed} deg is outside" in err
    assert last_line(err) == "Back at the starting pose, torque off."
    assert not any(arm.torque_enabled().values())
    bus.disconnect(disable_torque=False)


@pytest.mark.hw
def test_a_second_setup_on_the_same_port_is_refused_in_one_line(arm, capsys):
    from so101_utils import load_calibration, setup_motors

    calibration = load_calibration(str(CALIBRATION_PATH))
    bus = setup_motors(calibration, arm.port)
    with pytest.raises(ScriptEnded) as refused:
        setup_motors(calibration, arm.port)
    assert refused.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("Refused, nothing moved:") and "in use" in err and "\n" not in err
    bus.disable_torque()
    bus.disconnect(disable_torque=False)


def test_an_unknown_robot_is_refused_in_one_line(tmp_path, monkeypatch, capsys):
    from so101_utils import load_calibration

    monkeypatch.setenv("HF_LEROBOT_CALIBRATION", str(tmp_path))
    with pytest.raises(ScriptEnded) as refused:
        load_calibration("no-such-arm")
    err = capsys.readouterr().err.strip()
    assert refused.value.code == 2 and "\n" not in err
    assert "No calibration for robot id 'no-such-arm'" in err and "lerobot-calibrate" in err
    for bad in (None, "", 3):
        with pytest.raises(ScriptEnded) as refused:
            load_calibration(bad)
        assert refused.value.code == 2 and "robot id" in refused.value.line


def test_setup_motors_refuses_what_is_not_a_calibration_in_one_line(capsys):
    from so101_utils import setup_motors

    with pytest.raises(ScriptEnded) as refused:
        setup_motors(None, "/dev/ttyACM0")
    assert refused.value.code == 2 and "load_calibration(ROBOT_NAME)" in refused.value.line
    with pytest.raises(ScriptEnded) as refused:
        setup_motors(load_calibration(CALIBRATION_PATH), "/dev/ttyACM0",
                     offset_config={"elbow_flex": 9.0})  # refused before the port is opened
    assert "elbow_flex = 9 deg is beyond the 5 deg" in refused.value.line
    assert capsys.readouterr().err.count("\n") == 2  # one line each


def test_a_calibration_path_and_a_robot_id_load_the_same(tmp_path, monkeypatch):
    from so101_utils import load_calibration

    folder = tmp_path / "robots" / "so_follower"
    folder.mkdir(parents=True)
    shutil.copy(CALIBRATION_PATH, folder / "arm7.json")
    monkeypatch.setenv("HF_LEROBOT_CALIBRATION", str(tmp_path))
    by_id, by_path = load_calibration("arm7"), load_calibration(CALIBRATION_PATH)
    assert dict(by_id) == dict(by_path) == load_calibration(str(CALIBRATION_PATH))
    assert by_id.robot_id == "arm7" and by_path.robot_id is None


# --- endings between the calls, in the student's own process --------------------------
SCRIPT = """\
import sys
import time

from so101_utils import hold_position, load_calibration, move_to_pose, setup_motors

PORT_ID = sys.argv[1]
calibration = load_calibration(sys.argv[2])
bus = setup_motors(calibration, PORT_ID)
starting_pose = bus.sync_read("Present_Position")
move_to_pose(bus, {cfg!r}, {move_time})
print("moved", flush=True)
{after}
"""
AWAY = dict(HOME, shoulder_lift=-40.0, elbow_flex=40.0)


def run_script(arm, tmp_path, after: str, move_time: float = 1.0) -> subprocess.Popen:
    script = tmp_path / "student.py"
    script.write_text(SCRIPT.format(cfg=AWAY, move_time=move_time,
                                    after=textwrap.dedent(after)))
    return subprocess.Popen([sys.executable, str(script), arm.port, str(CALIBRATION_PATH)],
                            cwd=REPO, env={**os.environ, "PYTHONPATH": str(REPO)},
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def wait_for(condition, timeout=60.0):
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.02)


@pytest.mark.hw
@pytest.mark.slow
@pytest.mark.newest_lerobot  # the course helpers' ending
def test_a_script_that_forgets_disable_torque_ends_back_at_the_start_released(arm, tmp_path):
    run = run_script(arm, tmp_path, "hold_position(bus, 0.2)  # and no bus.disable_torque()")
    out, err = run.communicate(timeout=120)
    assert run.returncode == 0, err
    assert "moved" in out and last_line(out) == "Done: back at the starting pose, torque off."
    assert not any(arm.torque_enabled().values())
    assert_near(arm.commanded_positions(), HOME_GOAL, tol_deg=2.0, joints=ARM_JOINTS,
                label="last goal before release")


@pytest.mark.hw
@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_a_stop_signal_inside_move_to_pose_returns_slowly_and_releases(arm, tmp_path, signum):
    run = run_script(arm, tmp_path, "bus.disable_torque()", move_time=4.0)
    wait_for(lambda: arm.joint_positions()["elbow_flex"] < 70.0)  # on its way to AWAY
    run.send_signal(signum)
    out, err = run.communicate(timeout=120)
    assert run.returncode == 1, err
    name = {signal.SIGINT: "Ctrl-C"}.get(signum, signal.Signals(signum).name)
    assert f"stopped by {name} (during 'move_to_pose')" in err and "Traceback" not in err
    assert last_line(err) == "Back at the starting pose, torque off."
    assert "moved" not in out  # the script ended inside the call
    assert not any(arm.torque_enabled().values())
    assert_near(arm.commanded_positions(), HOME_GOAL, tol_deg=2.0, joints=ARM_JOINTS,
                label="last goal before release")


@pytest.mark.hw
@pytest.mark.slow
def test_sighup_between_the_calls_ends_back_at_the_start_released(arm, tmp_path):
    run = run_script(arm, tmp_path, "time.sleep(60)\nbus.disable_torque()")
    assert run.stdout.readline().strip() == "moved"  # now holding away, in time.sleep
    run.send_signal(signal.SIGHUP)
    out, err = run.communicate(timeout=120)
    assert run.returncode != 0
    assert "KeyboardInterrupt: SIGHUP" in err  # the student's script was interrupted ...
    assert last_line(out) == "Done: back at the starting pose, torque off."  # ... then ended
    assert not any(arm.torque_enabled().values())
    assert_near(arm.commanded_positions(), HOME_GOAL, tol_deg=2.0, joints=ARM_JOINTS,
                label="last goal before release")

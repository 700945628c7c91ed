"""Every way a run on the (virtual) arm ends, from the shell: signals, a kill, a busy or lost port.

pick_place_hw.py runs as a student runs it, in its own process, against a
virtual SO-101 started by the test; signals are real signals.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("lerobot")
pytestmark = [pytest.mark.hw, pytest.mark.slow]

import so101_kinematics.hw.run as hw  # noqa: E402
from so101_forward_kinematics import ARM_JOINTS  # noqa: E402
from so101_kinematics.calibration import load_calibration  # noqa: E402
from so101_kinematics.constants import HOME_POSE  # noqa: E402
from so101_kinematics.hw.bus import connect, disconnect, silent_servos  # noqa: E402
from so101_kinematics.planning.motion import Plan, Step  # noqa: E402
from so101_kinematics.virtual.arm import VirtualSO101  # noqa: E402
from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
CALIBRATION = load_calibration(DEFAULT_CALIBRATION_PATH)
HOME = HOME_POSE  # the virtual arm powers up there
PLAN = {"steps": [
    {"name": "swing_left", "configuration": dict(HOME, shoulder_pan=40.0, elbow_flex=70.0),
     "duration": 1.0, "hold": 0.2},
    {"name": "swing_right", "configuration": dict(HOME, shoulder_pan=-40.0, elbow_flex=70.0),
     "duration": 2.0, "hold": 0.2}], "return_duration": 1.0}


@pytest.fixture
def arm():
    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH) as virtual:
        yield virtual


def start_run(arm, tmp_path, *extra):
    """pick_place_hw.py on the virtual arm in its own process, with --log; returns the Popen."""
    plan = tmp_path / "plan.json"
    plan.write_text(json.dumps(PLAN))
    command = [sys.executable, str(REPO / "pick_place_hw.py"), "--port", arm.port,
               "--calibration", str(DEFAULT_CALIBRATION_PATH), "--yes", "--plan", str(plan),
               "--log", str(tmp_path / "run.csv"), *extra]
    return subprocess.Popen(command, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, stdin=subprocess.DEVNULL)


def wait_for(condition, timeout=60.0):
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.02)


def swinging(arm):
    """True once the arm is well on its way to swing_left (mid-motion)."""
    return lambda: arm.joint_positions()["shoulder_pan"] > 25.0


def near_start(arm, tol=2.0):
    pose = arm.joint_positions()
    return all(abs(pose[j] - HOME[j]) <= tol for j in ARM_JOINTS)


def log_rows(path: Path) -> list[list[str]]:
    rows = [line.split(",") for line in path.read_text().splitlines()]
    assert rows[0][:3] == ["t_s", "wall_s", "step"]
    return rows[1:]


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT])
@pytest.mark.newest_lerobot  # the releasing ending
def test_a_stop_signal_mid_motion_returns_slowly_and_releases_at_the_start(arm, tmp_path, signum):
    run = start_run(arm, tmp_path)
    wait_for(swinging(arm))
    run.send_signal(signum)
    out, err = run.communicate(timeout=60)
    assert run.returncode == 1, err
    name = {signal.SIGINT: "Ctrl-C"}.get(signum, signal.Signals(signum).name)
    assert f"stopped by {name} (during 'swing_left')" in err
    assert err.strip().splitlines()[-1] == "Back at the starting pose, torque off."
    assert not any(arm.torque_enabled().values())
    header = (tmp_path / "run.csv").read_text().splitlines()[0].split(",")
    rows = log_rows(tmp_path / "run.csv")
    assert rows[-1][2] == "abort_return"  # the log holds the return, to its last cycle
    released_at = {j: float(rows[-1][header.index(f"meas_{j}")]) for j in ARM_JOINTS}
    assert all(abs(released_at[j] - HOME[j]) <= 2.0 for j in ARM_JOINTS), released_at
    assert list(tmp_path.glob(".run.csv.*")) == []


@pytest.mark.newest_lerobot  # lerobot's disconnect must not let go
def test_a_second_signal_during_the_return_freezes_with_torque_on(arm, tmp_path):
    run = start_run(arm, tmp_path)
    wait_for(swinging(arm))
    run.send_signal(signal.SIGTERM)
    wait_for(lambda: arm.joint_positions()["shoulder_pan"] < 20.0)  # on its way back
    run.send_signal(signal.SIGTERM)
    out, err = run.communicate(timeout=60)
    assert run.returncode == 1, err
    last = err.strip().splitlines()[-1]
    assert last.startswith("Frozen where it was by a second stop signal") and "--release" in last
    assert all(arm.torque_enabled().values())
    before = arm.joint_positions()
    time.sleep(0.5)
    after = arm.joint_positions()
    assert all(abs(after[j] - before[j]) < 0.5 for j in ARM_JOINTS)  # holding, not falling
    assert not near_start(arm, tol=5.0)
    release = subprocess.run([sys.executable, str(REPO / "pick_place_hw.py"), "--release",
                              "--yes", "--port", arm.port, "--calibration",
                              str(DEFAULT_CALIBRATION_PATH)], cwd=REPO, capture_output=True,
                             text=True, timeout=60)
    assert release.returncode == 0 and "Torque off on every servo" in release.stdout
    assert not any(arm.torque_enabled().values())


def test_a_killed_run_leaves_its_log_up_to_the_last_flush(arm, tmp_path):
    run = start_run(arm, tmp_path)
    wait_for(swinging(arm))
    time.sleep(0.7)
    run.kill()
    run.communicate(timeout=30)
    assert not (tmp_path / "run.csv").exists()
    (partial,) = tmp_path.glob(".run.csv.*.part.csv")
    rows = log_rows(partial)
    assert len(rows) >= 50 and {r[2] for r in rows} >= {"swing_left"}


def test_a_second_program_on_the_port_is_told_it_is_in_use(arm):
    bus = connect(arm.port, CALIBRATION)
    try:
        other = subprocess.run([sys.executable, str(REPO / "read_position.py"), "--port",
                                arm.port, "--calibration", str(DEFAULT_CALIBRATION_PATH),
                                "--duration", "0.5"], cwd=REPO, capture_output=True, text=True,
                               timeout=60)
    finally:
        disconnect(bus)
    assert other.returncode == 2
    assert "is in use by another program" in other.stderr and f"pid {os.getpid()}" in other.stderr
    assert "Traceback" not in other.stderr


@pytest.mark.newest_lerobot  # the holding ending
def test_a_pulled_usb_cable_is_named_and_the_arm_holds(arm):
    def unplug(session, cycle):
        if cycle.step == "swing_right" and not unplug.done:
            unplug.done = True
            arm.inject("unplug")

    unplug.done = False
    plan = Plan([Step(s["name"], s["configuration"], s["duration"], s["hold"])
                    for s in PLAN["steps"]], return_duration=1.0)
    with pytest.raises(hw.MotionAborted, match="USB connection was lost") as info:
        hw.run_on_arm(arm.port, CALIBRATION, plan, on_cycle=unplug)
    assert info.value.result.usb_lost
    assert all(arm.torque_enabled().values())
    before = arm.joint_positions()
    time.sleep(0.5)
    after = arm.joint_positions()
    assert all(abs(after[j] - before[j]) < 0.5 for j in ARM_JOINTS)


def test_read_position_rides_through_a_lost_reply(arm, capsys):
    import threading

    import read_position

    def drop_replies_once_teaching():  # teach mode releases the torque first
        wait_for(lambda: not any(arm.torque_enabled().values()))
        arm.inject("drop:1:4")

    dropper = threading.Thread(target=drop_replies_once_teaching)
    dropper.start()
    try:
        rc = read_position.main(["--port", arm.port, "--calibration",
                                 str(DEFAULT_CALIBRATION_PATH), "--rate", "20", "--duration", "1"])
    finally:
        dropper.join()
    assert rc == 0
    assert "Last pose" in capsys.readouterr().out


def test_a_servo_reporting_an_error_bit_is_not_called_silent(arm):
    """The last line names the servos that do not answer; one that answers with its overload
    bit set (a gripper squeezing a cube for long) is not one of them."""
    bus = connect(arm.port, load_calibration(DEFAULT_CALIBRATION_PATH))
    try:
        arm.inject("overload:gripper,remove:wrist_flex")
        assert silent_servos(bus) == ["wrist_flex"]
    finally:
        disconnect(bus)


def test_compare_marks_a_stopped_run_aborted_and_keeps_it_apart(arm, tmp_path, capsys):
    """Issue 33: a run stopped mid-motion (SIGINT: Ctrl-C) and a complete one, same profile:
    --compare marks the stopped one aborted (the sidecar says why) and does not pool it with
    the complete one as run-to-run variation."""
    from so101_kinematics.commands import so101_command

    stopped_dir, done_dir = tmp_path / "stopped", tmp_path / "done"
    stopped_dir.mkdir()
    done_dir.mkdir()
    run = start_run(arm, stopped_dir)
    wait_for(swinging(arm))
    run.send_signal(signal.SIGINT)
    _, err = run.communicate(timeout=60)
    assert run.returncode == 1, err
    sidecar = json.loads((stopped_dir / "run.run.json").read_text())
    assert sidecar["aborted"].startswith("stopped by Ctrl-C (during 'swing_left')")
    run = start_run(arm, done_dir)
    _, err = run.communicate(timeout=120)
    assert run.returncode == 0, err
    assert json.loads((done_dir / "run.run.json").read_text())["aborted"] is None
    out = tmp_path / "compare.json"
    logs = [str(done_dir / "run.csv"), str(stopped_dir / "run.csv")]
    assert so101_command.main(["compare", *logs, "--report", str(tmp_path / "c.png"),
                               "--json", str(out)]) == 0
    table = capsys.readouterr().out
    (runs,) = json.loads(out.read_text())["profiles"].values()
    assert [run["aborted"] for run in runs][0] is None
    assert runs[1]["aborted"].startswith("stopped by Ctrl-C")
    assert [line.split()[0] for line in table.splitlines() if line.endswith("ABORTED")] == \
        ["run.csv"] and "run-to-run variation" not in table.replace(
            "never counted in the run-to-run variation", "")

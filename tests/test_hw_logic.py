"""The hardware code without an arm: calibration, limits, speed cap, scheduler, session, CLI.

These cover so101_calibration, so101_bus, so101_control and pick_place_hw and
run without lerobot: the session is driven through a small fake bus and a fake
clock, so they are fast and deterministic. The same behaviour against the real
lerobot bus and the virtual SO-101 is in test_pick_place_hw.py.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest

import pick_place_hw as hw
from so101_bus import ConnectionFailed, bus_errors, make_bus
from so101_calibration import (
    MOTOR_IDS,
    CalibrationError,
    ServoCalibration,
    calibrated_limits,
    find_calibration,
    lerobot_calibration_root,
    load_calibration,
    ticks_to_user,
)
from so101_control import (
    MAX_JOINT_SPEED_DEG_S,
    MAX_MISSED_READS,
    RETURN_MIN_DURATION_S,
    RETURN_SPEED_DEG_S,
    TRACKING_TIMEOUT_S,
    ArmSession,
    BusError,
    RateLoop,
    TrackingError,
    capped_duration,
    hold_position,
    loop_timing_stats,
    move_to_pose,
    peak_speed_factor,
    session_for,
    speed_caps,
)
from so101_forward_kinematics import JOINTS, get_forward_kinematics
from so101_motion import JointLimitError, Plan, PlanError, Step, default_plan, pick_and_place_steps

REPO = Path(__file__).resolve().parent.parent
VIRTUAL_CALIBRATION = REPO / "calibration" / "virtual_so101.json"
HOME = {"shoulder_pan": 0.0, "shoulder_lift": -90.0, "elbow_flex": 90.0, "wrist_flex": 30.0,
        "wrist_roll": 0.0, "gripper": 9.0}


# --- helpers -----------------------------------------------------------------------
class FakeClock:
    """Deterministic time: sleep advances it; each read advances 1 us (so spinning ends)."""

    def __init__(self):
        self.now = 1000.0
        self.sleeps = []

    def clock(self) -> float:
        self.now += 1e-6
        return self.now

    def sleep(self, seconds: float) -> None:
        self.sleeps.append(seconds)
        self.now += max(0.0, seconds)


class FakeBus:
    """Enough of lerobot's FeetechMotorsBus for a session: servos follow goals instantly.

    ``stalled`` joints never move; ``fail_reads`` makes the next N sync_reads raise
    ConnectionError as lerobot does when a servo does not answer.
    """

    def __init__(self, calibration, pose, stalled=()):
        self.calibration = calibration
        self.motors = {j: types.SimpleNamespace(id=MOTOR_IDS[j]) for j in JOINTS}
        self.pose = dict(pose)
        self.stalled = set(stalled)
        self.goals: list[dict] = []
        self.torque = dict.fromkeys(JOINTS, True)
        self.fail_reads = 0
        self.silent: set[str] = set()
        self.port_handler = types.SimpleNamespace(clearPort=lambda: None, is_using=False)

    def sync_write(self, name, values, normalize=True):
        assert name == "Goal_Position"
        self.goals.append(dict(values))
        for joint, value in values.items():
            if joint not in self.stalled:
                self.pose[joint] = value

    def sync_read(self, name, motors=None, normalize=True):
        assert name == "Present_Position"
        if self.fail_reads > 0:
            self.fail_reads -= 1
            raise ConnectionError("Failed to sync read 'Present_Position' on ids=[1, 2, 3, 4, 5, "
                                  "6] after 1 tries. [TxRxResult] There is no status packet!")
        return dict(self.pose)

    def disable_torque(self, motors=None, num_retry=0):
        for joint in [motors] if isinstance(motors, str) else (motors or JOINTS):
            self.write("Torque_Enable", joint, 0)

    def write(self, name, motor, value, normalize=True, num_retry=0):
        if motor in self.silent:
            raise ConnectionError(f"{motor}: There is no status packet!")
        if name == "Torque_Enable":
            self.torque[motor] = bool(value)

    def ping(self, motor, num_retry=0):
        return None if motor in self.silent else 777


@pytest.fixture
def calibration():
    return load_calibration(VIRTUAL_CALIBRATION)


@pytest.fixture
def clock():
    return FakeClock()


def make_session(calibration, clock, pose=HOME, stalled=(), **kwargs):
    bus = FakeBus(calibration, pose, stalled)
    return ArmSession(bus, clock=clock.clock, sleep=clock.sleep, **kwargs), bus


def write_calibration(tmp_path, data, name="arm.json") -> Path:
    path = tmp_path / name
    path.write_text(json.dumps(data))
    return path


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


# --- plan validation -------------------------------------------------------------------
def test_default_plan_passes_both_limit_checks(calibration):
    hw.validate_plan_for_arm(default_plan(), calibration)


def test_waypoint_beyond_the_model_limit_names_joint_value_and_limit(calibration):
    plan = default_plan()
    plan.steps[2].configuration["elbow_flex"] = -100.0
    with pytest.raises(JointLimitError) as info:
        hw.validate_plan_for_arm(plan, calibration)
    message = str(info.value)
    assert "elbow_flex = -100" in message and "model" in message and plan.steps[2].name in message


def test_waypoint_beyond_a_narrow_calibration_is_refused(calibration):
    narrow = dict(calibration, shoulder_lift=ServoCalibration(2, 0, 0, 1600, 2500))
    with pytest.raises(JointLimitError) as info:
        hw.validate_plan_for_arm(default_plan(), narrow, "lab_arm.json")
    message = str(info.value)
    assert "shoulder_lift" in message and "calibrated range" in message
    assert "lab_arm.json" in message


def test_plan_errors_name_the_problem(calibration):
    with pytest.raises(PlanError, match="no steps"):
        hw.validate_plan_for_arm(Plan([]), calibration)
    plan = Plan([Step("a", dict(HOME, wrist_flex="up"))])
    with pytest.raises(PlanError, match="wrist_flex.*finite number"):
        hw.validate_plan_for_arm(plan, calibration)


# --- speed cap ---------------------------------------------------------------------------
def test_peak_speed_factors():
    assert peak_speed_factor("linear") == pytest.approx(1.0)
    assert peak_speed_factor("minimum_jerk") == pytest.approx(1.875, rel=1e-4)


def test_capped_duration_stretches_only_when_needed():
    caps = speed_caps(100.0, 50.0)
    start, goal = dict(HOME), dict(HOME, shoulder_pan=90.0)
    assert capped_duration(start, goal, 2.0, "minimum_jerk", caps) == 2.0
    assert capped_duration(start, goal, 1.0, "minimum_jerk", caps) == pytest.approx(1.6875)
    assert capped_duration(start, goal, 0.1, "linear", caps) == pytest.approx(0.9)
    gripper = dict(HOME, gripper=59.0)  # 50 % at 50 %/s
    assert capped_duration(start, gripper, 0.2, "linear", caps) == pytest.approx(1.0)


# --- the deadline scheduler ------------------------------------------------------------
def test_rate_loop_deadlines_do_not_drift_with_varying_work(clock):
    loop = RateLoop(100.0, clock.clock, clock.sleep, spin=0.0005)
    t0 = loop.start()
    rng = np.random.default_rng(1)
    wakes = []
    for _ in range(1000):
        clock.now += rng.uniform(0.0, 0.008)  # work of 0-8 ms inside a 10 ms period
        wakes.append(loop.wait())
    assert wakes[-1] == pytest.approx(t0 + 1000 * 0.01, abs=1e-9)  # no accumulated drift
    assert np.diff(wakes) == pytest.approx(0.01, abs=1e-9)
    assert loop.overruns == 0 and loop.skipped == 0
    assert clock.now - wakes[-1] < 1e-4  # woke at the deadline, not after it
    assert min(clock.sleeps) >= 0.0  # slept up to the spin margin, then spun


def test_rate_loop_counts_overruns_and_skips_missed_deadlines(clock):
    loop = RateLoop(100.0, clock.clock, clock.sleep)
    t0 = loop.start()
    clock.now += 0.013  # 3 ms late: run the next cycle at once, keep the grid
    assert loop.wait() == pytest.approx(t0 + 0.01)
    assert (loop.overruns, loop.skipped) == (1, 0)
    assert loop.wait() == pytest.approx(t0 + 0.02)
    clock.now += 0.035  # 3.5 periods of work: skip the missed deadlines, no burst
    deadline = loop.wait()
    assert (loop.overruns, loop.skipped) == (2, 2)
    assert deadline == pytest.approx(t0 + 0.05)
    assert clock.now - deadline < 0.01
    assert loop.wait() == pytest.approx(t0 + 0.06)


def test_rate_loop_refuses_impossible_rates():
    for rate in (0, -10, 5000, float("nan")):
        with pytest.raises(ValueError, match="rate"):
            RateLoop(rate)


def test_loop_timing_stats():
    times = [0.0, 0.010, 0.020, 0.031, 0.040, 0.050]
    stats = loop_timing_stats(times, 100.0)
    assert stats["period_p50_ms"] == pytest.approx(10.0)
    assert stats["achieved_hz"] == pytest.approx(100.0)
    assert stats["period_max_error_ms"] == pytest.approx(1.0)
    assert stats["cycles"] == 6


# --- the session, on a fake bus ------------------------------------------------------------
def test_first_move_ramps_from_the_measured_pose_within_the_speed_cap(calibration, clock):
    session, bus = make_session(calibration, clock)
    goal = dict(HOME, shoulder_pan=-45.0, shoulder_lift=45.0, elbow_flex=-45.0, wrist_flex=90.0)
    session.move(goal, 0.5)  # far too fast: stretched
    commands = np.array([[g[j] for j in JOINTS] for g in bus.goals])
    first_step = np.abs(commands[0] - [HOME[j] for j in JOINTS])
    assert first_step.max() < 0.5  # no jump: the first command is next to the measured pose
    assert commands[-1] == pytest.approx([goal[j] for j in JOINTS])
    speed = np.abs(np.diff(commands, axis=0)).max(axis=0) * 100.0  # [deg/s] at 100 Hz
    assert speed[:5].max() <= MAX_JOINT_SPEED_DEG_S * 1.01
    assert session.stretched and "stretched" in session.stretched[0]
    assert session.segments[0].duration > session.segments[0].requested == 0.5


def test_move_runs_on_the_rate_grid(calibration, clock):
    session, bus = make_session(calibration, clock, rate_hz=100.0)
    session.move(dict(HOME, wrist_flex=35.0), 1.0)
    session.hold(0.5)
    times = [c.t_s for c in session.cycles]
    assert len(times) == 150
    assert np.diff(times) == pytest.approx(0.01, abs=1e-9)
    assert times[0] == pytest.approx(0.01)  # the command for t = 0 is where the arm already is
    assert [c.step for c in session.cycles] == [""] * 150
    assert all(c.measured is not None for c in session.cycles)


def test_course_call_shape_with_a_plain_bus(calibration, clock):
    bus = FakeBus(calibration, HOME)
    ArmSession(bus, clock=clock.clock, sleep=clock.sleep)  # registered for this bus
    move_to_pose(bus, dict(HOME, gripper=50.0), 1.0)
    hold_position(bus, 0.2)
    assert bus.pose["gripper"] == pytest.approx(50.0)
    assert session_for(bus).segments[-1].kind == "hold"


def test_command_outside_the_calibrated_range_is_never_sent(calibration, clock):
    session, bus = make_session(calibration, clock)
    with pytest.raises(JointLimitError, match="shoulder_pan = 150"):
        session.move(dict(HOME, shoulder_pan=150.0), 5.0)
    assert bus.goals == []


def test_stalled_joint_aborts_after_the_tracking_timeout(calibration, clock):
    session, bus = make_session(calibration, clock, stalled=["elbow_flex"])
    with pytest.raises(TrackingError) as info:
        session.move(dict(HOME, elbow_flex=30.0), 1.5)
    message = str(info.value)
    assert "elbow_flex does not follow" in message and "tolerance 15" in message
    # the error first exceeded 15 deg, then stayed beyond it for the timeout
    cycles = session.cycles
    lag = [abs(now.measured["elbow_flex"] - before.command["elbow_flex"])
           for before, now in zip(cycles, cycles[1:], strict=False)]
    first_beyond = 1 + next(i for i, error in enumerate(lag) if error > 15.0)
    elapsed = cycles[-1].t_s - cycles[first_beyond].t_s
    assert elapsed == pytest.approx(TRACKING_TIMEOUT_S, abs=0.011)
    assert all(c.measured["elbow_flex"] == 90.0 for c in cycles)  # the joint never moved


def test_gripper_squeezing_a_cube_is_not_a_stall(calibration, clock):
    session, bus = make_session(calibration, clock, stalled=["gripper"])
    session.move(dict(HOME, gripper=50.0), 0.5)
    session.hold(1.0)  # no TrackingError: the gripper is not tracked


def test_a_missed_read_is_tolerated_but_a_silent_servo_is_a_bus_error(calibration, clock):
    session, bus = make_session(calibration, clock)
    session.move(dict(HOME, wrist_flex=32.0), 0.2)
    bus.fail_reads = MAX_MISSED_READS
    session.hold(0.1)
    assert sum(c.measured is None for c in session.cycles) == MAX_MISSED_READS
    bus.fail_reads = MAX_MISSED_READS + 1
    with pytest.raises(BusError, match="no status packet"):
        session.hold(0.1)


def test_stop_request_returns_slowly_to_the_start_and_releases(calibration, clock):
    def on_cycle(session, cycle):
        if cycle.step == "lift" and session.stop_reason is None and not stopped:
            stopped.append(cycle.t_s)
            session.stop_reason = "Ctrl-C"

    stopped = []
    session, bus = make_session(calibration, clock, on_cycle=on_cycle)
    start = dict(HOME)
    plan = hw.validate_plan_for_arm(default_plan(), calibration)
    with pytest.raises(hw.MotionAborted) as info:
        hw.execute(session, plan, start)
    result = info.value.result
    assert "stopped by Ctrl-C" in str(info.value) and "'lift'" in str(info.value)
    assert result.returned_to_start and result.unreleased == []
    assert all(not on for on in bus.torque.values())
    assert bus.goals[-1] == pytest.approx(start)
    back = [s for s in result.segments if s.step == "abort_return"]
    assert len(back) == 1
    slow = speed_caps(RETURN_SPEED_DEG_S, RETURN_SPEED_DEG_S)
    distance = max(abs(back[0].goal[j] - back[0].start[j]) / slow[j] for j in JOINTS)
    expected = max(RETURN_MIN_DURATION_S, distance * 1.875)
    assert back[0].duration == pytest.approx(expected, rel=1e-3)


def test_bus_error_releases_without_moving_back(calibration, clock):
    def on_cycle(session, cycle):
        if cycle.step == "carry" and not bus.silent:
            bus.silent.add("wrist_flex")
            bus.fail_reads = 100

    session, bus = make_session(calibration, clock, on_cycle=on_cycle)
    plan = hw.validate_plan_for_arm(default_plan(), calibration)
    with pytest.raises(hw.MotionAborted) as info:
        hw.execute(session, plan, dict(HOME))
    message = str(info.value)
    result = info.value.result
    assert "wrist_flex (id 4)" in message and "switch off its power" in message
    assert not result.returned_to_start and result.unreleased == ["wrist_flex"]
    assert not any(s.step == "abort_return" for s in result.segments)
    assert [j for j, on in bus.torque.items() if on] == ["wrist_flex"]


# --- output ------------------------------------------------------------------------------
def test_pick_and_place_waypoints_and_their_cube_positions(calibration):
    plan = default_plan()
    pick, place = pick_and_place_steps(plan)  # shared with the simulator
    assert (pick.name, place.name) == ("start_open", "final_open")
    text = hw.format_plan(plan, rate_hz=100.0, profile="minimum_jerk", max_speed=speed_caps())
    for label, step in (("pick ", pick), ("place", place)):
        x, y, _ = get_forward_kinematics(step.configuration)[0] * 100.0
        assert f"{label} ({step.name}): x = {x:.1f} cm, y = {y:.1f} cm" in text


def test_log_csv_has_time_command_and_measurement_per_cycle(calibration, clock, tmp_path):
    session, bus = make_session(calibration, clock)
    session.move(dict(HOME, wrist_flex=40.0), 0.3)
    path = hw.write_log_csv(session.cycles, tmp_path / "run.csv")
    rows = path.read_text().splitlines()
    header = rows[0].split(",")
    assert header[:3] == ["t_s", "wall_s", "step"]
    assert header[3:] == [f"cmd_{j}" for j in JOINTS] + [f"meas_{j}" for j in JOINTS]
    assert len(rows) == 1 + len(session.cycles)
    last = dict(zip(header, rows[-1].split(","), strict=True))
    assert float(last["cmd_wrist_flex"]) == pytest.approx(40.0)
    assert float(last["meas_wrist_flex"]) == pytest.approx(40.0)


def test_plot_is_written(calibration, clock, tmp_path):
    session, _ = make_session(calibration, clock)
    session.move(dict(HOME, wrist_flex=40.0), 0.3)
    path = hw.plot_log(session.cycles, tmp_path / "run.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 10_000


def test_teach_prints_pasteable_configurations(calibration):
    bus = FakeBus(calibration, dict(HOME, wrist_flex=42.0))
    import io

    out = io.StringIO()
    last = hw.teach(bus, rate_hz=50.0, duration=0.1, out=out)
    assert not any(bus.torque.values())  # torque off: moved by hand
    lines = out.getvalue().splitlines()
    pasted = json.loads(lines[-1].split(": ", 1)[1])
    assert pasted["wrist_flex"] == 42.0 and last["wrist_flex"] == 42.0
    x, y, z = get_forward_kinematics(last)[0] * 100.0
    assert f"object x={x:.1f} y={y:.1f} z={z:.1f} cm" in lines[1]


# --- prompts and the command line ---------------------------------------------------------
def test_prompt_never_blocks_without_a_terminal():
    class Pipe:
        def isatty(self):
            return False

        def readline(self):
            raise AssertionError("must not read")

    assert hw.ask("Go?", assume_yes=True, stdin=Pipe())
    with pytest.raises(hw.NotConfirmed, match="--yes"):
        hw.ask("Go?", assume_yes=False, stdin=Pipe())

    class Terminal:
        def __init__(self, answer):
            self.answer = answer

        def isatty(self):
            return True

        def readline(self):
            return self.answer

    assert hw.ask("Go?", False, Terminal("y\n"))
    assert not hw.ask("Go?", False, Terminal("\n"))


def test_dry_run_prints_plan_and_cube_positions(capsys):
    assert hw.main(["--dry-run", "--calibration", str(VIRTUAL_CALIBRATION)]) == 0
    out = capsys.readouterr().out
    assert "Dry run: the plan is valid; nothing was sent" in out
    assert "pick  (start_open): x = 23.0 cm, y = 19.0 cm" in out


def test_dry_run_refuses_a_bad_waypoint_file(tmp_path, capsys):
    plan = {"steps": [{"name": "reach", "configuration": dict(HOME, shoulder_lift=120.0)}]}
    path = tmp_path / "plan.json"
    path.write_text(json.dumps(plan))
    args = ["--dry-run", "--calibration", str(VIRTUAL_CALIBRATION), "--plan", str(path)]
    assert hw.main(args) == 2
    err = capsys.readouterr().err
    assert "shoulder_lift = 120" in err and "'reach'" in err and "nothing moved" in err


def test_a_real_run_needs_to_know_which_arm(capsys):
    assert hw.main(["--port", "/dev/ttyACM0", "--yes"]) == 2
    assert "--id ROBOT_ID" in capsys.readouterr().err


def test_bad_rate_is_refused(capsys):
    assert hw.main(["--dry-run", "--rate", "0"]) == 2
    assert "rate" in capsys.readouterr().err


def _run_without_lerobot(args: list[str]) -> subprocess.CompletedProcess:
    code = (f"import sys; sys.modules['lerobot'] = None; sys.path.insert(0, {str(REPO)!r}); "
            f"import pick_place_hw; rc = pick_place_hw.main({args!r}); "
            "assert 'torch' not in sys.modules; sys.exit(rc)")
    env = dict(os.environ, PYTHONPATH=str(REPO))
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                          timeout=120, cwd=REPO)


def test_help_and_dry_run_work_without_lerobot():
    help_run = subprocess.run([sys.executable, str(REPO / "pick_place_hw.py"), "--help"],
                              capture_output=True, text=True, timeout=60, cwd=REPO)
    assert help_run.returncode == 0 and "--dry-run" in help_run.stdout
    dry = _run_without_lerobot(["--dry-run", "--calibration", str(VIRTUAL_CALIBRATION)])
    assert dry.returncode == 0, dry.stderr
    assert "nothing was sent" in dry.stdout


def test_without_lerobot_a_real_run_says_how_to_install_it(tmp_path):
    run = _run_without_lerobot(["--port", str(tmp_path / "ttyACM0"), "--yes",
                                "--calibration", str(VIRTUAL_CALIBRATION)])
    assert run.returncode == 2
    assert "pip install -e '.[hw]'" in run.stderr


def test_bus_failures_while_setting_up_say_what_to_do():
    with pytest.raises(ConnectionFailed) as info:
        with bus_errors("configuring the servos"):
            raise RuntimeError("Failed to write 'P_Coefficient' on id_=3 after 1 tries.")
    assert "configuring the servos" in str(info.value) and "id_=3" in str(info.value)
    assert "power supply" in str(info.value)
    with pytest.raises(CalibrationError):  # our own errors pass through unchanged
        with bus_errors("reading"):
            raise CalibrationError("mismatch")


def test_a_new_segment_continues_the_grid_after_a_late_cycle(clock):
    loop = RateLoop(100.0, clock.clock, clock.sleep)
    t0 = loop.start()
    loop.wait()
    clock.now += 0.025  # the last cycle of a move ran long
    assert loop.resume() == pytest.approx(t0 + 0.03)  # same grid, missed deadlines skipped
    assert loop.skipped == 2
    clock.now += 1.0  # idle (e.g. a prompt): a fresh grid
    assert loop.resume() == pytest.approx(clock.now, abs=1e-5)


def test_garbage_collector_is_frozen_during_the_motion(calibration, clock):
    import gc

    frozen = []
    session, _ = make_session(calibration, clock,
                              on_cycle=lambda s, c: frozen.append(gc.get_freeze_count()))
    plan = hw.validate_plan_for_arm(default_plan(0.2, 0.0), calibration)
    hw.execute(session, plan, dict(HOME))
    assert min(frozen) > 1000  # everything alive before the run is skipped by collections
    assert gc.get_freeze_count() == 0

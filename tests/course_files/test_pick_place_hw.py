"""pick_place_hw and the hw package against the virtual SO-101: lerobot's real bus, a pty.

Each test starts its own virtual arm (a MuJoCo arm stepped in real time in a
subprocess; about 1.5 s to start), so faults and torque states never leak
between tests. The full pick-and-place runs once (module fixture) with the
course's waypoints at shortened durations; the speed cap stretches the moves
that would be too fast, exactly as on the lab arm.
"""

from __future__ import annotations

import json
import os
import signal
import time

import mujoco
import numpy as np
import pytest

pytest.importorskip("lerobot")
pytestmark = pytest.mark.hw

import pick_place_hw as cli  # noqa: E402
import so101_kinematics.hw.run as hw  # noqa: E402
import so101_mujoco_utils as mu  # noqa: E402
from benchmarks.bench_hw import measure_loop_timing  # noqa: E402
from so101_forward_kinematics import ARM_JOINTS, JOINTS  # noqa: E402
from so101_kinematics.calibration import load_calibration  # noqa: E402
from so101_kinematics.constants import HOME_POSE  # noqa: E402
from so101_kinematics.errors import (  # noqa: E402
    CalibrationError,
    ConnectionFailed,
    JointLimitError,
    NotConfirmed,  # noqa: E402
)
from so101_kinematics.hw import feedforward  # noqa: E402
from so101_kinematics.hw.bus import calibration_mismatch, connect, disconnect  # noqa: E402
from so101_kinematics.planning.motion import Plan, Step  # noqa: E402
from so101_kinematics.planning.plans import default_plan  # noqa: E402
from so101_kinematics.sim import actuation  # noqa: E402
from so101_kinematics.virtual.arm import VirtualSO101  # noqa: E402
from so101_kinematics.virtual.electrical import SUPPLY_V  # noqa: E402
from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH  # noqa: E402

CALIBRATION = load_calibration(DEFAULT_CALIBRATION_PATH)
HOME = HOME_POSE  # the virtual arm powers up there


def short_plan() -> Plan:
    """Two quick waypoints near the power-up pose, for the fault tests (about 3 s)."""
    left = dict(HOME, shoulder_pan=30.0, elbow_flex=70.0, gripper=40.0)
    right = dict(left, shoulder_pan=-30.0)
    return Plan([Step("swing_left", left, 0.8, 0.1), Step("swing_right", right, 1.2, 0.1)],
                return_duration=1.0)


def assert_near(actual, expected, tol_deg=1.5, tol_gripper=3.0, label=""):
    for joint in JOINTS:
        tol = tol_gripper if joint == "gripper" else tol_deg
        assert abs(actual[joint] - expected[joint]) <= tol, (
            f"{label} {joint}: {actual[joint]:.2f} vs {expected[joint]:.2f} (tol {tol})")


def goals_outside_calibration(goal_log):
    """Goal_Position writes (servo id, ticks) outside that servo's calibrated range."""
    by_id = {cal.id: cal for cal in CALIBRATION.values()}
    return [(servo, ticks) for _, servo, ticks in goal_log
            if not by_id[servo].range_min <= ticks <= by_id[servo].range_max]


@pytest.fixture
def arm():
    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH) as virtual:
        yield virtual


@pytest.fixture(scope="module")
def full_run():
    """The course's plan, durations shortened, on a fresh virtual arm.

    Each hold lasts 0.5 s: the STS3215 at lerobot's P = 16 trails a fast move by about a
    tenth of a second of its motion and settles in about 0.3 s (a 0.1 s hold ended with
    the shoulder still 4.6 deg short).
    """
    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH) as arm:
        plan = default_plan(move_duration=0.6, hold_duration=0.5)
        before = arm.reply_stats()
        result = hw.run_on_arm(arm.port, CALIBRATION, plan)
        after = arm.reply_stats()
        # real time the emulator's physics could not keep up with (it drops it) [s]
        slip = (after["wall_time_s"] - before["wall_time_s"]) - (
            after["sim_time_s"] - before["sim_time_s"])
        data = {"plan": plan, "result": result, "goals": arm.goal_log(), "slip": slip,
                "final": arm.joint_positions(), "torque": arm.torque_enabled()}
    return data  # the virtual arm is closed: no emulator left running during later tests


# --- the full sequence ------------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.newest_lerobot
def test_full_sequence_completes_and_ends_at_the_starting_pose(full_run):
    result = full_run["result"]
    assert result.aborted is None
    assert_near(result.start_pose, HOME, tol_deg=0.5, tol_gripper=0.5, label="start")
    moves = [s.step for s in result.segments if s.kind == "move"]
    assert moves == [s.name for s in full_run["plan"].steps] + ["return_to_start"]
    assert_near(full_run["final"], result.start_pose, label="end (MuJoCo)")
    assert not any(full_run["torque"].values()), "torque must be off at the end"


@pytest.mark.slow
@pytest.mark.newest_lerobot
def test_every_goal_received_stays_within_the_calibrated_limits(full_run):
    goals = full_run["goals"]
    cycles = full_run["result"].cycles
    # + the in-place goals written before torque on, and the feed-forward's ramp after it
    ramp = round(feedforward.RAMP_S / feedforward.RAMP_PERIOD_S)
    assert len(goals) == 6 * (len(cycles) + 1 + ramp)
    assert goals_outside_calibration(goals) == []


@pytest.mark.slow
@pytest.mark.newest_lerobot
def test_waypoints_are_reached(full_run):
    """Each held waypoint's last measured pose is within 2 deg of it (gripper: no cube, 3 %).

    A waypoint the plan passes through without a hold (approach, pre_grasp, retreat,
    depart) is left while the arm still trails it: the STS3215 at P = 16 lags a move by
    about 0.1 s of its motion (servo.lag), up to 6 deg at these shortened moves' speeds.
    """
    result = full_run["result"]
    for step in full_run["plan"].steps:
        cycles = [c for c in result.cycles if c.step == step.name and c.measured]
        tolerance = 2.0 if step.hold > 0 else 8.0
        assert_near(cycles[-1].measured, step.configuration, tol_deg=tolerance, label=step.name)


@pytest.mark.slow
@pytest.mark.newest_lerobot
def test_the_cycles_are_scheduled_on_the_10_ms_grid(full_run):
    """Every cycle's time is on the 100 Hz grid (a skipped cycle skips a whole period).

    How well the wall clock keeps that rate is a speed, measured by ``benchmarks/bench_hw.py``
    (``hw_loop_hz_100hz``, ``hw_period_p99_error_ms_100hz``) against its goal, not asserted
    here: on CI's loaded slow leg the median period read 10.67 ms.
    """
    scheduled = np.diff([c.t_s for c in full_run["result"].cycles])
    assert len(scheduled) > 100
    assert np.all(np.abs(scheduled / 0.01 - np.round(scheduled / 0.01)) < 1e-6)  # on the grid
    assert np.all(np.round(scheduled / 0.01) >= 1)  # never two cycles in one period


def _simulate_segments(segments, start_pose):
    """Replay the executed moves and holds on the simulator (so101_mujoco_utils), headless.

    Each segment starts at the same time as on the arm, so the two timelines
    line up; returns (times [s], configurations (N, 6)).
    """
    m = mu.load_model()
    # the virtual arm's servos at its default supply (electrical.SUPPLY_V: the course's 12 V C018s)
    actuation.use_servo(m, volts=SUPPLY_V)
    d = mujoco.MjData(m)
    mu.set_initial_pose(d, start_pose)
    times, poses = [], []

    class Recorder:  # a "viewer" called after every physics step, no pacing
        offscreen = True
        sync_every_step = True

        def is_running(self):
            return True

        def sync(self):
            times.append(d.time)
            poses.append([mu.get_configuration(m, d)[j] for j in JOINTS])

    recorder = Recorder()
    for i, segment in enumerate(segments):
        end = segments[i + 1].t_start_s if i + 1 < len(segments) else segment.t_start_s + 1.0
        if segment.kind == "move":
            mu.move_to_pose(m, d, recorder, segment.goal, segment.duration)
        if end - d.time > 0:
            mu.hold_position(m, d, recorder, end - d.time)
    return np.array(times), np.array(poses)


def on_schedule(cycles, period=0.01, late=0.003, window=0.2) -> np.ndarray:
    """Cycles before which the loop kept its schedule for ``window`` [s].

    A cycle is off schedule when it started more than ``late`` [s] after its
    deadline or deadlines before it were skipped (the host did not run us).
    """
    t = np.array([c.t_s for c in cycles])
    wall = np.array([c.wall_s for c in cycles])
    bad = wall - t > late
    bad[1:] |= np.diff(t) > 1.5 * period
    bad_times = t[bad]
    return np.array([not np.any((bad_times <= ti) & (bad_times >= ti - window)) for ti in t])


@pytest.fixture(scope="module")
def sim_comparison(full_run):
    """|measured - simulated| per cycle and joint, and which cycles were on schedule."""
    result = full_run["result"]
    times, poses = _simulate_segments(result.segments, result.start_pose)
    cycles = [c for c in result.cycles if c.measured is not None]
    t = np.array([c.t_s for c in cycles])
    measured = np.array([[c.measured[j] for j in JOINTS] for c in cycles])
    simulated = np.stack([np.interp(t, times, poses[:, k]) for k in range(len(JOINTS))], axis=1)
    return {"error": np.abs(measured - simulated), "measured": measured,
            "on_schedule": on_schedule(cycles)}


@pytest.mark.slow
@pytest.mark.newest_lerobot
def test_measured_trajectory_follows_the_simulator(sim_comparison):
    """Always (even on a loaded host): the median error is below 1.5 deg on every joint.

    A wrong unit, sign, offset or calibration, or a different interpolation,
    gives errors of tens of degrees over most of the run; transient lags when
    the host deschedules the loop or the emulator do not move the median.
    """
    error = sim_comparison["error"]
    assert np.median(error, axis=0).max() <= 1.5, np.median(error, axis=0).round(2)
    pan = sim_comparison["measured"][:, JOINTS.index("shoulder_pan")]
    assert np.ptp(pan) > 80.0  # it really moved


@pytest.mark.slow
@pytest.mark.newest_lerobot
def test_measured_trajectory_matches_the_simulator(full_run, sim_comparison):
    """Sim-to-"real": the virtual arm's measured joints follow the simulator's within 3 deg.

    Tolerance: both are the same MuJoCo model driven along the same path, so
    what separates them is time. The arm receives a new goal every 10 ms and
    holds it in between (a 5 ms lag on average; at the 100 deg/s speed cap
    that is 0.5 deg), its Present_Position is read about 1 ms after the goal
    (0.1 deg), ticks are 0.088 deg, and a cycle up to 3 ms late adds 0.3 deg.
    3 deg peak and 1 deg RMS bound these with margin (measured on a quiet
    host: 1.1 deg peak, 0.2 deg RMS).

    Compared only on cycles where the loop kept its schedule for the 200 ms
    before: when the host does not run the loop (or the emulator) for tens of
    ms, the arm lags by speed x delay, which says nothing about sim-to-real.
    If the host was too loaded to judge (under half the cycles on schedule, or
    the emulator's physics lost more than 20 ms of real time), the test skips.
    """
    error, ok = sim_comparison["error"], sim_comparison["on_schedule"]
    lag = full_run["result"].timing["plan_lag_s"]  # the plan slowed for a stalled host
    if ok.mean() < 0.5 or full_run["slip"] > 0.02 or lag > 0.02:
        pytest.skip(f"host too loaded to compare timing: {ok.mean():.0%} of cycles on schedule, "
                    f"emulator lost {1e3 * full_run['slip']:.0f} ms, the plan "
                    f"{1e3 * lag:.0f} ms")
    error = error[ok]
    worst = {j: round(float(error[:, k].max()), 2) for k, j in enumerate(JOINTS)}
    assert error.max() <= 3.0, worst
    assert np.sqrt((error ** 2).mean(axis=0)).max() <= 1.0, worst


@pytest.mark.slow
@pytest.mark.newest_lerobot
def test_cli_run_writes_log_and_plot(arm, tmp_path, capsys):
    plan = {"steps": [{"name": "nod", "configuration": dict(HOME, wrist_flex=50.0),
                       "duration": 0.5, "hold": 0.1}], "return_duration": 0.5}
    plan_path = tmp_path / "nod.json"
    plan_path.write_text(json.dumps(plan))
    log, plot = tmp_path / "run.csv", tmp_path / "run.png"
    rc = cli.main(["--port", arm.port, "--calibration", str(DEFAULT_CALIBRATION_PATH), "--yes",
                  "--plan", str(plan_path), "--log", str(log), "--plot", str(plot)])
    out = capsys.readouterr().out
    assert rc == 0, out
    assert "Done: back at the starting pose" in out
    rows = log.read_text().splitlines()
    assert len(rows) > 50 and rows[0].startswith("t_s,wall_s,step,cmd_shoulder_pan")
    nod = [r.split(",") for r in rows[1:] if r.split(",")[2] == "nod"]
    header = rows[0].split(",")
    assert float(nod[-1][header.index("meas_wrist_flex")]) == pytest.approx(50.0, abs=2.0)
    assert plot.stat().st_size > 10_000
    assert not any(arm.torque_enabled().values())


# --- aborts --------------------------------------------------------------------------------
def once_in_swing_right(action):
    """An on_cycle hook that runs ``action(session)`` once, at the first cycle of 'swing_right'.

    The hook's ``fired`` list records the cycle time [s] when it ran.
    """
    def on_cycle(session, cycle):
        if cycle.step == "swing_right" and not on_cycle.fired:
            on_cycle.fired.append(cycle.t_s)
            action(session)

    on_cycle.fired = []
    return on_cycle


def slowest_return_s(goal_log, since: float) -> tuple[float, float]:
    """From the virtual arm's own goal log: (duration [s], angle [deg]) of the slowest arm
    joint's return after ``since`` (time.time() [s]): from its last goal at the controlled
    stop's position to its first goal at its final position."""
    worst = (0.0, 0.0)
    for servo in range(1, 6):  # the arm joints, in degrees (not the gripper, in %)
        goals = [(t, ticks) for t, sid, ticks in goal_log if sid == servo and t >= since]
        stop, final = goals[0][1], goals[-1][1]
        begin = max(t for t, ticks in goals if ticks == stop)
        end = min(t for t, ticks in goals if ticks == final and t >= begin)
        angle = abs(final - stop) * 360.0 / 4095.0  # lerobot's DEGREES: 4095 ticks a turn
        worst = max(worst, (end - begin, angle), key=lambda w: w[1])
    return worst


@pytest.mark.slow
@pytest.mark.newest_lerobot
def test_ctrl_c_mid_motion_returns_to_the_start_and_releases(arm):
    # A real Ctrl-C, handled at the cycle boundary.
    def ctrl_c(session):
        ctrl_c.at = time.time()
        os.kill(os.getpid(), signal.SIGINT)

    on_cycle = once_in_swing_right(ctrl_c)
    start = arm.joint_positions()
    handler = signal.getsignal(signal.SIGINT)
    with pytest.raises(hw.MotionAborted) as info:
        hw.run_on_arm(arm.port, CALIBRATION, short_plan(), on_cycle=on_cycle)
    result = info.value.result
    assert "stopped by Ctrl-C (during 'swing_right')" in str(info.value)
    assert result.returned_to_start and result.unreleased == []
    assert hw.ending(result, "") == "Back at the starting pose, torque off."
    assert_near(arm.joint_positions(), start, label="after Ctrl-C")
    assert not any(arm.torque_enabled().values())
    assert goals_outside_calibration(arm.goal_log()) == []
    assert signal.getsignal(signal.SIGINT) is handler  # Ctrl-C handling restored
    # README: "the slow return (20 deg/s)": measured on the arm's clock, at least angle / 20.
    duration, angle = slowest_return_s(arm.goal_log(), ctrl_c.at)
    assert angle > 20.0  # from 'swing_left' (shoulder_pan 30 deg) back to the start
    assert duration >= angle / 20.0, f"{angle:.1f} deg in {duration:.2f} s"


@pytest.mark.slow
def test_a_second_run_from_where_the_released_arm_slumped_ends_as_the_first(arm):
    # Released at its rest pose, the arm slumps onto the table (the virtual arm: elbow_flex
    # 90 -> 97, wrist_flex 30 -> 40 deg, its jaw pad at the table, inside the 5 mm clearance
    # margin). Run again from there, the plan's own return to that pose was refused at the
    # end and the arm held at 'depart' (half the runs of the 20-run soak, 2026-12-02).
    from so101_kinematics.clearance import CLEARANCE_MARGIN_M, lowest_point

    plan = default_plan(move_duration=0.6, hold_duration=0.5)
    first = hw.run_on_arm(arm.port, CALIBRATION, plan)
    assert first.aborted is None and first.torque_released
    deadline = time.monotonic() + 10.0  # limp: the wrist droops onto the table in about 4 s
    while lowest_point(arm.joint_positions())[0] > 0.001 and time.monotonic() < deadline:
        time.sleep(0.2)
    slumped = arm.joint_positions()
    assert lowest_point(slumped)[0] < min(0.001, CLEARANCE_MARGIN_M)
    second = hw.run_on_arm(arm.port, CALIBRATION, plan)
    assert second.aborted is None and second.returned_to_start and second.torque_released
    assert hw.ending(second, "") == "Done: back at the starting pose, torque off."
    assert_near(arm.joint_positions(), slumped, label="back where it slumped")
    assert not any(arm.torque_enabled().values())


@pytest.mark.slow
@pytest.mark.newest_lerobot
def test_interrupt_inside_a_bus_transaction_is_recovered(arm):
    """KeyboardInterrupt with a reply still on the wire: the port is flushed before the return."""
    def interrupt_mid_transaction(session):
        session.bus.sync_reader.txPacket()  # request sent, reply left unread ...
        raise KeyboardInterrupt  # ... as when Ctrl-C lands inside lerobot

    on_cycle = once_in_swing_right(interrupt_mid_transaction)
    start = arm.joint_positions()
    with pytest.raises(hw.MotionAborted, match="Ctrl-C") as info:
        hw.run_on_arm(arm.port, CALIBRATION, short_plan(), on_cycle=on_cycle)
    assert info.value.result.returned_to_start
    assert_near(arm.joint_positions(), start, label="after interrupt")
    assert not any(arm.torque_enabled().values())


@pytest.mark.slow
@pytest.mark.newest_lerobot
def test_a_late_reply_is_dropped_not_taken_for_the_next_one(arm):
    """A reply left on the port (late, as after a timeout) must not poison the next read.

    The late reply is servo 1's Model_Number (777): taken for its
    Present_Position it would read shoulder_pan as -112 deg.
    """
    def leave_a_reply_on_the_port(session):
        bus = session.bus
        bus.packet_handler.readTx(bus.port_handler, 1, 3, 2)  # its reply is never read ...
        bus.port_handler.is_using = False  # ... as after the SDK gave up waiting

    on_cycle = once_in_swing_right(leave_a_reply_on_the_port)
    result = hw.run_on_arm(arm.port, CALIBRATION, short_plan(), on_cycle=on_cycle)
    pan = [c.measured["shoulder_pan"] for c in result.cycles if c.measured is not None]
    assert on_cycle.fired and min(pan) > -32.0 and max(pan) < 32.0
    assert result.stale_bytes == 8  # one status packet with 2 bytes of data
    assert_near(arm.joint_positions(), result.start_pose, label="end")


@pytest.mark.slow
@pytest.mark.newest_lerobot
def test_stalled_joint_aborts_returns_and_releases(arm):
    # Blocked where it stands (90 deg) from the run's first cycle on; swing_left asks for 70.
    # Not before the connect: the powered-up elbow sags 20 ticks under its goal (P 32), so a
    # block then loads it to overload before lerobot's ping, which reads the error bit as a
    # missing servo (an idle machine trips it before the connect ends, a loaded one not).
    def on_cycle(session, cycle):
        if not on_cycle.fired:
            on_cycle.fired = True
            arm.inject("stall:elbow_flex")

    on_cycle.fired = False
    start = arm.joint_positions()
    with pytest.raises(hw.MotionAborted) as info:
        hw.run_on_arm(arm.port, CALIBRATION, short_plan(), on_cycle=on_cycle)
    message = str(info.value)
    # caught by whichever comes first: the tracking check or the servo's own overload bit
    assert ("elbow_flex does not follow its command" in message
            or "elbow_flex servo reports: overloaded" in message) and "swing_left" in message
    result = info.value.result
    assert result.returned_to_start  # the stalled joint did not need to move back
    assert_near(arm.joint_positions(), start, label="after stall")
    assert not any(arm.torque_enabled().values())
    assert goals_outside_calibration(arm.goal_log()) == []


@pytest.mark.slow
@pytest.mark.newest_lerobot
def test_stall_that_also_blocks_the_way_back_holds_with_torque_on(arm):
    # Stuck near +30 deg, asked to go to -30, then 0: the way back is blocked too.
    on_cycle = once_in_swing_right(lambda session: arm.inject("stall:shoulder_pan"))
    with pytest.raises(hw.MotionAborted) as info:
        hw.run_on_arm(arm.port, CALIBRATION, short_plan(), on_cycle=on_cycle)
    result = info.value.result
    assert "shoulder_pan" in str(info.value)
    assert not result.returned_to_start
    assert all(arm.torque_enabled().values())  # held where it stopped, never dropped
    before = arm.joint_positions()
    time.sleep(0.5)
    assert_near(arm.joint_positions(), before, tol_deg=0.5, label="holding")
    # what the servo reads back: its overload bit set (a real STS3215 unloads on it with the
    # factory Unloading_Condition): named as unable to hold, the arm to be supported (issue 33).
    # Whether the bit comes depends on where the run's hold goal lands: 0.2-0.4 deg from the
    # stuck joint, one encoder tick either side of the servo's dead band (measured under load:
    # goal 29.80 deg -> no load, no bit; 29.89 or 29.98 -> load 100 %, the bit).
    # Near the threshold the stalled servo's load flickers with its reading noise, so the bit
    # may be set at the run's last read and clear for seconds after (CI saw exactly that: the
    # ending named the overload, then 3 s of polling saw no bit). The ending reports the run's
    # own read-back; the test holds it to one of the two true endings, never a third, and the
    # overload named only on the stalled servo (tests/hw/test_guarded_registers.py pins the
    # unable-to-hold line deterministically).
    line = hw.ending(result, "R")
    assert "torque ON" in line, line
    if result.unable:
        assert set(result.unable) == {"shoulder_pan"}, result.unable
        assert line.startswith("The arm is NOT holding where it stopped"), line
        assert "UNABLE TO HOLD (read back): shoulder_pan (status: overloaded)" in line, line
    else:
        assert line.startswith("The arm is holding where it stopped"), line
        assert "UNABLE" not in line, line


@pytest.mark.slow
@pytest.mark.newest_lerobot
def test_servo_that_stops_answering_leaves_the_others_holding(arm):
    on_cycle = once_in_swing_right(lambda session: arm.inject("remove:wrist_flex"))
    with pytest.raises(hw.MotionAborted) as info:
        hw.run_on_arm(arm.port, CALIBRATION, short_plan(), on_cycle=on_cycle)
    result = info.value.result
    assert "did not answer" in str(info.value) and "'swing_right'" in str(info.value)
    assert result.silent == ["wrist_flex"] and not result.returned_to_start
    assert all(arm.torque_enabled().values())  # nobody released away from the start
    line = hw.ending(result, "python pick_place_hw.py --release")
    assert "Not answering: wrist_flex (id 4)" in line and "--release" in line
    # the plan paused while blind: every blind cycle repeated the last goal
    blind = [c for c in result.cycles if c.measured is None]
    assert blind and len({tuple(c.command.values()) for c in blind}) == 1


@pytest.mark.slow
@pytest.mark.newest_lerobot
def test_a_dropped_reply_is_retried_within_the_cycle(arm):
    # one lost reply: the retry in the same cycle gets it; two: one cycle is blind
    on_cycle = once_in_swing_right(lambda session: arm.inject("drop:3:1"))
    result = hw.run_on_arm(arm.port, CALIBRATION, short_plan(), on_cycle=on_cycle)
    assert sum(c.measured is None for c in result.cycles) == 0
    on_cycle = once_in_swing_right(lambda session: arm.inject("drop:3:2"))
    result = hw.run_on_arm(arm.port, CALIBRATION, short_plan(), on_cycle=on_cycle)
    assert sum(c.measured is None for c in result.cycles) == 1
    assert result.aborted is None and not any(arm.torque_enabled().values())


# --- refusals: nothing is sent ---------------------------------------------------------------
def test_calibration_that_does_not_match_the_servos_is_refused(arm, tmp_path):
    data = json.loads(DEFAULT_CALIBRATION_PATH.read_text())
    data["shoulder_lift"]["homing_offset"] += 100  # another arm's file
    path = tmp_path / "other_arm.json"
    path.write_text(json.dumps(data))
    before = arm.joint_positions()
    with pytest.raises(CalibrationError) as info:
        hw.run_on_arm(arm.port, load_calibration(path), short_plan(), robot_id="other_arm")
    message = str(info.value)
    assert "shoulder_lift homing_offset: servo" in message and "--write-calibration" in message
    assert "--robot.id=other_arm" in message
    assert arm.goal_log() == []
    assert all(arm.torque_enabled().values())  # untouched (the virtual arm powers up holding)
    assert_near(arm.joint_positions(), before, tol_deg=0.2, tol_gripper=0.5)


@pytest.mark.slow
@pytest.mark.newest_lerobot
def test_write_calibration_puts_the_file_into_the_servos(arm, tmp_path):
    data = json.loads(DEFAULT_CALIBRATION_PATH.read_text())
    data["wrist_roll"]["homing_offset"] += 40
    path = tmp_path / "recalibrated.json"
    path.write_text(json.dumps(data))
    calibration = load_calibration(path)
    bus = connect(arm.port, calibration, write_calibration=True)
    try:
        assert calibration_mismatch(bus, calibration) == []
    finally:
        disconnect(bus)
    assert arm.registers("wrist_roll")["Homing_Offset"] == data["wrist_roll"]["homing_offset"]
    assert arm.goal_log() == []


def test_malformed_calibration_is_refused_before_connecting(arm, tmp_path):
    data = json.loads(DEFAULT_CALIBRATION_PATH.read_text())
    data["gripper"]["range_max"] = data["gripper"]["range_min"]
    path = tmp_path / "broken.json"
    path.write_text(json.dumps(data))
    with pytest.raises(CalibrationError, match="gripper.*empty range"):
        hw.run_on_arm(arm.port, load_calibration(path), short_plan())
    assert arm.goal_log() == []


def test_bad_waypoints_refuse_to_start(arm, tmp_path, capsys):
    plan = short_plan()
    plan.steps[1].configuration["shoulder_pan"] = 115.0  # beyond the model (110)
    with pytest.raises(JointLimitError, match="shoulder_pan = 115"):
        hw.run_on_arm(arm.port, CALIBRATION, plan)
    path = tmp_path / "plan.json"
    path.write_text(json.dumps({"steps": [{"name": "oops", "configuration": {"shoulder_pan": 0}}]}))
    rc = cli.main(["--port", arm.port, "--calibration", str(DEFAULT_CALIBRATION_PATH), "--yes",
                  "--plan", str(path)])
    assert rc == 2 and "'shoulder_lift' is missing" in capsys.readouterr().err
    assert arm.goal_log() == []
    assert all(arm.torque_enabled().values())


@pytest.mark.slow
@pytest.mark.newest_lerobot
def test_missing_port_and_silent_arm_are_refused(arm, tmp_path):
    with pytest.raises(ConnectionFailed, match="does not exist.*lerobot-find-port"):
        hw.run_on_arm(str(tmp_path / "ttyACM9"), CALIBRATION, short_plan())
    arm.inject("remove:gripper")
    with pytest.raises(ConnectionFailed) as info:
        hw.run_on_arm(arm.port, CALIBRATION, short_plan())
    assert "Missing motor IDs" in str(info.value) and "power supply" in str(info.value)
    assert arm.goal_log() == []


def test_not_confirmed_means_nothing_moves(arm):
    with pytest.raises(NotConfirmed):
        hw.run_on_arm(arm.port, CALIBRATION, short_plan(), confirm=lambda q: False)
    assert arm.goal_log() == []


def test_dry_run_with_the_arm_connected_sends_no_goal(arm, capsys):
    rc = cli.main(["--dry-run", "--port", arm.port, "--calibration", str(DEFAULT_CALIBRATION_PATH)])
    out = capsys.readouterr().out
    assert rc == 0
    assert "Measured starting pose" in out and "nothing was sent" in out
    assert "pick  (start_open)" in out
    assert arm.goal_log() == []
    assert all(arm.torque_enabled().values())


# --- teach mode and timing ---------------------------------------------------------------------
def test_teach_mode_releases_torque_and_prints_the_pose(arm, capsys):
    import read_position

    rc = read_position.main(["--port", arm.port, "--calibration", str(DEFAULT_CALIBRATION_PATH),
                             "--rate", "20", "--duration", "0.3"])
    assert rc == 0
    assert not any(arm.torque_enabled().values())
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("Torque is off")
    pasted = json.loads(lines[-1].split(": ", 1)[1])
    live = json.loads(lines[-2].split("  object")[0])
    measured = arm.joint_positions()  # limp now: it may sag a little under gravity
    for joint in ARM_JOINTS:
        assert pasted[joint] == live[joint]
        assert abs(pasted[joint] - measured[joint]) < 5.0
    assert "object x=" in lines[-2] and lines[-2].endswith(" cm")
    assert arm.goal_log() == []


def test_teach_from_the_main_script_stops_on_ctrl_c(arm, capsys):
    import threading
    import time

    # Torque on first, so that "torque off" below really means teach mode has
    # started (an earlier test may have left it off): a Ctrl-C sent before the
    # teach loop runs would interrupt pytest itself.
    arm.set_torque(True)

    def press_ctrl_c_once_teaching():
        deadline = time.monotonic() + 60.0
        while any(arm.torque_enabled().values()) and time.monotonic() < deadline:
            time.sleep(0.05)  # teach mode releases the torque first
        time.sleep(0.5)
        os.kill(os.getpid(), signal.SIGINT)

    presser = threading.Thread(target=press_ctrl_c_once_teaching)
    presser.start()
    try:
        rc = cli.main(["--teach", "--port", arm.port,
                      "--calibration", str(DEFAULT_CALIBRATION_PATH)])
    finally:
        presser.join()
    out = capsys.readouterr().out
    assert rc == 0 and "Last pose (paste into a waypoint file)" in out
    assert not any(arm.torque_enabled().values())


@pytest.mark.slow
@pytest.mark.newest_lerobot
def test_loop_timing_measurement_runs():
    """Smoke test of the benchmark helper (the figures are benchmarks, not asserted)."""
    stats = measure_loop_timing(rates_hz=(100.0, 200.0), seconds=0.6, wire_timing=True)
    assert set(stats) == {100.0, 200.0}
    for rate, figures in stats.items():
        for key in ("achieved_hz", "period_p50_ms", "period_p99_error_ms", "overruns"):
            assert key in figures
        assert figures["cycles"] > 0.6 * rate * 0.5
        # A deadline-scheduled loop never runs ahead of its rate, whatever the load (how
        # close it comes to the rate is a benchmark's figure).
        assert figures["achieved_hz"] <= rate * 1.01
        assert figures["overruns"] >= 0

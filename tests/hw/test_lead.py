"""The velocity feed-forward on the real-arm path (hw/lead.py, --velocity-ff).

The lead's arithmetic is checked against a hand calculation from the STS3215's
identified numbers ([BAM] in so101_kinematics/servo.py); the rest runs the hardware
path through lerobot's bus against the virtual arm (the same servo model, lerobot's
P = 16, the kit's 5 V): the lead is applied, bounded and zero at rest, it removes
the lag the model predicts, and a fault drill ends as the fault matrix says.
"""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from so101_kinematics import servo
from so101_kinematics.constants import HOME_POSE
from so101_kinematics.frames import ARM_JOINTS, JOINTS
from so101_kinematics.hw.lead import VelocityLead, lag_time, lead_for
from so101_kinematics.paths import DOCS_DIR
from so101_kinematics.planning.motion import Plan, Step, Trajectory

# The hand calculation ([BAM]: kt = 1.2116 N m/A, R = 2.676 ohm, viscous 0.0591 N m s/rad;
# [TEL]: P/4 of 0.1 % duty per count; 4096 counts a turn): the servo's lag per unit speed
# at P = 16 on 5 V is (kt^2/R + viscous) / (kt/R x 5 V x 16/4000 x 4096/(2 pi)).
KT, R, VISCOUS = 1.2116, 2.676, 0.0591
HAND_LAG_S = (KT**2 / R + VISCOUS) / (KT / R * 5.0 * 16 / 4000 * 4096 / (2 * math.pi))
TRACKING_TOLERANCE_DEG = 15.0  # README, "Safety": a joint this far from its plan for 0.3 s stops
LAGS = dict.fromkeys(JOINTS, HAND_LAG_S)
GRID = np.linspace(0.0, 1.0, 100_001)  # a move's fractions of its duration


def plan_time(path: Trajectory, command) -> float:
    """The time [s] of ``path`` at which it commands ``command`` (its profile is monotonic)."""
    joint = max(path.goal, key=lambda j: abs(path.goal[j] - path.start[j]))
    fraction = (command[joint] - path.start[joint]) / (path.goal[joint] - path.start[joint])
    return float(np.interp(fraction, path.fractions(GRID * path.duration), GRID)) * path.duration


def test_the_lag_is_the_hand_calculation():
    assert HAND_LAG_S == pytest.approx(0.1029, abs=5e-4)
    assert lag_time(servo.LEROBOT, 5.0) == pytest.approx(HAND_LAG_S, rel=1e-6)
    # twice the P, half the lag; the 12 V supply's C018 is its own motor
    assert lag_time(servo.LEROBOT.with_(p=32), 5.0) == pytest.approx(HAND_LAG_S / 2, rel=1e-6)


def test_the_lead_is_lag_times_velocity_with_its_sign():
    lead = lead_for({"shoulder_lift": 60.0, "elbow_flex": -30.0, "gripper": 0.0}, LAGS)
    assert lead["shoulder_lift"] == pytest.approx(60.0 * HAND_LAG_S)  # 6.2 deg ahead
    assert lead["elbow_flex"] == pytest.approx(-30.0 * HAND_LAG_S)
    assert lead["gripper"] == 0.0


def test_a_fast_move_is_led_by_less_than_the_tracking_tolerance_in_the_same_direction():
    # 300 deg/s (beyond any speed cap) would need 31 deg: the whole lead is scaled down
    velocity = {"shoulder_pan": 300.0, "elbow_flex": -150.0}
    lead = lead_for(velocity, LAGS)
    assert 0.0 < max(abs(x) for x in lead.values()) < TRACKING_TOLERANCE_DEG
    assert lead["elbow_flex"] / lead["shoulder_pan"] == pytest.approx(-0.5)  # same direction


def test_the_led_goal_stays_on_the_move_and_is_the_plan_at_rest():
    start = dict(HOME_POSE)
    goal = dict(HOME_POSE, shoulder_pan=40.0, shoulder_lift=-50.0, gripper=5.0)
    path = Trajectory(start, goal, 1.0, "cubic")
    led_at = VelocityLead(LAGS).along(path)
    delta = {j: goal[j] - start[j] for j in JOINTS}
    moving = [j for j in JOINTS if delta[j]]
    for t in np.linspace(0.0, 1.0, 101):
        planned = path.at(t)
        led = led_at(t, planned)
        fractions = [(led[j] - start[j]) / delta[j] for j in moving]
        # on the straight joint-space segment the clearance check judged, never past the goal
        assert max(fractions) - min(fractions) < 1e-9 and 0.0 <= fractions[0] <= 1.0 + 1e-12
        assert all(led[j] == start[j] for j in JOINTS if not delta[j])
        expected = min(1.0, path.fraction(t) + HAND_LAG_S * float(path.rates([t])[0]))
        assert fractions[0] == pytest.approx(expected, abs=1e-9)
    assert led_at(0.0, path.at(0.0)) == path.at(0.0)
    assert led_at(1.0, path.at(1.0)) == goal
    assert VelocityLead(LAGS, enabled=False).along(path) is None


def test_the_goal_written_leads_the_plan_and_pauses_with_it(calibration, clock):
    """On a fake bus (no lerobot): goal = plan + lead; while the arm is silent, the plan."""
    from hw_fakes import make_session

    def outage(session, cycle):
        if cycle.t_s >= 0.3 and not outage.fired:
            outage.fired = session.bus.fail_until = clock.now + 0.3

    outage.fired = 0.0
    session, bus = make_session(calibration, clock, on_cycle=outage,
                                velocity_lead=VelocityLead(LAGS), profile="cubic")
    assert HOME_POSE["wrist_flex"] == 30.0  # the move: 30 deg down to 0 in 1 s
    session.move(dict(HOME_POSE, wrist_flex=0.0), 1.0)
    cycles = session.cycles
    assert len(bus.goals) == len(cycles)
    path = Trajectory(dict(HOME_POSE), dict(HOME_POSE, wrist_flex=0.0), 1.0, "cubic")
    for previous, cycle, goal in zip(cycles, cycles[1:], bus.goals[1:], strict=False):
        if previous.measured is None:  # silent: the plan stands still, nothing leads it
            assert cycle.lead is None and goal == cycle.command
            continue
        # the plan's velocity where the plan is: the hand calculation of the lead
        expected = HAND_LAG_S * path.velocity_at(plan_time(path, cycle.command))["wrist_flex"]
        led = min(30.0, max(0.0, cycle.command["wrist_flex"] + expected))  # within the move
        assert goal["wrist_flex"] == pytest.approx(led, abs=0.01)
        assert cycle.lead["wrist_flex"] == pytest.approx(goal["wrist_flex"]
                                                         - cycle.command["wrist_flex"])
    assert any(c.measured is None for c in cycles) and bus.goals[-1] == cycles[-1].command


# --- on the virtual arm, through lerobot's bus ------------------------------------------
def short_cubic_plan() -> Plan:
    """Two swings near the power-up pose: the pan 60 deg in 1.2 s (a 75 deg/s peak)."""
    left = dict(HOME_POSE, shoulder_pan=30.0, elbow_flex=70.0, gripper=40.0)
    right = dict(left, shoulder_pan=-30.0, shoulder_lift=HOME_POSE["shoulder_lift"] + 20.0)
    return Plan([Step("swing_left", left, 0.8, 0.3), Step("swing_right", right, 1.2, 0.3)],
                return_duration=1.0)


def predicted_lag_rms(result) -> float:
    """The model's lag over the moves the figures judge: RMS of lag x planned velocity [deg]."""
    lags = []
    from so101_kinematics.lab.tracking_hw import move_cycles, move_segments

    for segment in move_segments(result)[1:]:
        path = Trajectory(segment.start, segment.goal, segment.duration, "cubic")
        for cycle in move_cycles(result, segment):
            if cycle.measured:  # the plan's velocity where the plan is (its clock may pause)
                velocity = path.velocity_at(plan_time(path, cycle.command))
                lags.extend(HAND_LAG_S * velocity[j] for j in ARM_JOINTS)
    return float(np.sqrt(np.mean(np.square(lags))))


@pytest.fixture(scope="module")
def runs():
    pytest.importorskip("lerobot")
    from so101_kinematics.lab.tracking_hw import measure

    # HAND_LAG_S is the kit's 5 V C001's (by hand, above): its arm, pinned
    return {mode: measure(mode, short_cubic_plan(), supply=servo.KIT_SUPPLY_V)
            for mode in ("plain", "lead")}


@pytest.mark.hw
@pytest.mark.slow
def test_the_lead_is_applied_bounded_and_zero_at_rest(runs):
    from so101_kinematics.lab.tracking_hw import move_cycles, move_segments

    result = runs["lead"]["result"]
    assert result.aborted is None and result.torque_released
    for segment in move_segments(result):
        cycles = move_cycles(result, segment)
        leads = [max(abs(c.lead[j]) for j in ARM_JOINTS) for c in cycles if c.lead]
        assert leads and max(leads) < TRACKING_TOLERANCE_DEG, segment.step
        # the planned velocity is zero at the move's end: so is the lead
        assert max(abs(v) for v in cycles[-1].lead.values()) < 1e-9, segment.step
    biggest = max(max(abs(v) for v in c.lead.values()) for c in result.cycles if c.lead)
    assert biggest > 3.0  # 75 deg/s peak x 0.1 s: the lead was really sent
    holds = [c for c in result.cycles if c.lead is None]
    assert holds  # the holds send the plan itself
    assert runs["plain"]["peak_lead_deg"] == 0.0


@pytest.mark.hw
@pytest.mark.slow
def test_velocity_ff_removes_most_of_the_lag_the_servo_model_predicts(runs):
    plain, lead = runs["plain"], runs["lead"]
    predicted = predicted_lag_rms(plain["result"])
    # without the lead the arm trails its plan by about the model's lag (the dead zone,
    # startup force and backlash add to it, the D term's transients too)
    assert 0.7 * predicted <= plain["tracking_rms_deg"] <= 1.5 * predicted
    # with it, at least half of that lag is gone (measured: RMS 2.4 -> 0.6 deg over the
    # course's cubic pick-and-place; README, "Velocity on the real arm")
    assert plain["tracking_rms_deg"] - lead["tracking_rms_deg"] >= 0.5 * predicted
    assert lead["tracking_max_deg"] < plain["tracking_max_deg"]
    # and the arm still ends at each goal (the lead is zero there): as close as without
    for step, error in lead["final_error_deg"].items():
        assert error <= max(1.0, plain["final_error_deg"][step] + 0.5), step


def matrix_cell(fault: str, phase: str) -> str:
    """The fault matrix of docs/hardware_safety.md (generated from the drills): one cell."""
    from so101_kinematics.lab.fault_drill import PHASES

    text = (DOCS_DIR / "hardware_safety.md").read_text(encoding="utf-8")
    row = next(line for line in text.splitlines() if line.startswith(f"| {fault} ("))
    cells = [c.strip() for c in row.strip("|").split("|")]
    return cells[1 + list(PHASES).index(phase)]


@pytest.mark.hw
@pytest.mark.slow
def test_a_stall_during_a_led_move_ends_as_the_fault_matrix_says(tmp_path):
    pytest.importorskip("lerobot")
    from so101_kinematics.lab.fault_drill import run_drill

    fault = "shoulder_pan stalls"  # at the carry, where the pan swings 60 deg
    drill = run_drill(fault, "carry (cube lifted)", tmp_path, velocity_ff=True)
    assert drill.outcome == matrix_cell(fault, "carry (cube lifted)"), drill
    assert drill.goals_outside == 0 and drill.log_rows == drill.cycles > 0


@pytest.mark.hw
@pytest.mark.slow
def test_pick_place_hw_velocity_ff_logs_its_lead(tmp_path, capsys):
    pytest.importorskip("lerobot")
    import pick_place_hw as cli
    from so101_kinematics.virtual.arm import VirtualSO101
    from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH

    swing = dict(HOME_POSE, shoulder_pan=40.0)
    plan = tmp_path / "plan.json"
    plan.write_text(json.dumps({"steps": [{"name": "swing", "configuration": swing,
                                           "duration": 1.0, "hold": 0.2}],
                                "return_duration": 1.0}))
    log = tmp_path / "run.csv"
    # HAND_LAG_S is the kit's 5 V C001's (by hand, above): its arm, pinned
    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH, supply=servo.KIT_SUPPLY_V) as arm:
        status = cli.main(["--port", arm.port, "--calibration", str(DEFAULT_CALIBRATION_PATH),
                           "--plan", str(plan), "--profile", "cubic", "--velocity-ff", "--yes",
                           "--log", str(log)])
    assert status == 0, capsys.readouterr().err
    rows = list(csv.DictReader(log.open()))
    pan = [abs(float(r["lead_shoulder_pan"])) for r in rows if r["lead_shoulder_pan"]]
    # 40 deg in 1 s on the cubic: a 60 deg/s peak, about 6 deg ahead
    assert 60.0 * HAND_LAG_S * 0.9 < max(pan) < TRACKING_TOLERANCE_DEG
    assert any(r["lead_shoulder_pan"] == "" for r in rows)  # the holds: the plan itself
    sidecar = json.loads(log.with_name("run.run.json").read_text())
    info = sidecar["velocity_ff"]
    assert info["enabled"] is True and sidecar["profile"] == "cubic"
    assert info["lag_s"]["shoulder_pan"] == pytest.approx(HAND_LAG_S, abs=1e-3)
    assert info["peak_lead_deg"]["shoulder_pan"] == pytest.approx(max(pan), abs=1e-3)


@pytest.mark.hw
@pytest.mark.slow
def test_the_course_helpers_take_velocity_ff_and_keep_their_shapes_without(course_arm):
    import so101_kinematics.hw.course_helpers as course
    from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH
    from so101_utils import load_calibration, move_to_pose, move_to_pose_cubic, setup_motors

    bus = setup_motors(load_calibration(str(DEFAULT_CALIBRATION_PATH)), course_arm.port)
    session = course._RUNS[id(bus)].session
    start = bus.sync_read("Present_Position")
    target = dict(start, shoulder_pan=start["shoulder_pan"] + 20.0)

    def leads_of_last_move():
        return [c.lead for c in move_cycles_of(session)]

    move_to_pose_cubic(bus, target, 1.0)  # the course's shape: the plan as it is
    assert all(lead is None for lead in leads_of_last_move())
    move_to_pose_cubic(bus, target, start, 1.0, velocity_ff=True)  # 30 deg/s peak
    leads = leads_of_last_move()
    assert max(abs(x["shoulder_pan"]) for x in leads) == pytest.approx(30.0 * HAND_LAG_S, rel=0.05)
    assert max(abs(v) for v in leads[-1].values()) < 1e-9  # zero where the move ends
    move_to_pose(bus, target, 1.0, velocity_ff=True)  # minimum jerk's peak: 37.5 deg/s
    assert max(abs(x["shoulder_pan"]) for x in leads_of_last_move()) == pytest.approx(
        37.5 * HAND_LAG_S, rel=0.05)
    bus.disable_torque()


def move_cycles_of(session) -> list:
    """The cycles of the session's last move (``lab/tracking_hw.move_cycles``)."""
    from so101_kinematics.lab.tracking_hw import move_cycles

    return move_cycles(session, session.segments[-1])


def test_nothing_read_the_feedforward_and_lead_assume_the_courses_12_v_c018(calibration):
    """No Present_Voltage read (a fake bus answers none): the guess is the course's follower,
    12 V with C018s (ECE4560 assignment 3; docs/servo_model.md), not the kit's 5 V. Its lag by
    hand from the C018's datasheet (2.94 N m stall, 45 rpm no-load at 12 V) with BAM's
    friction (0.0524 N m): damping = (2.94 x 0.97 - 0.0524) / (45 rpm) = 0.594 N m s/rad,
    over the stiffness 2.94 N m x 16/4000 x 4096/(2 pi) = 7.67 N m/rad: 0.0775 s."""
    from hw_fakes import FakeBus

    from so101_kinematics.hw.feedforward import read_feedforward

    feedforward = read_feedforward(FakeBus(calibration, dict(HOME_POSE)))
    assert (feedforward.volts, feedforward.variant) == (12.0, "C018")
    damping = (2.94 * 0.97 - 0.0524) / (45.0 * 2 * math.pi / 60)
    hand = damping / (2.94 * 16 / 4000 * 4096 / (2 * math.pi))
    lead = VelocityLead.for_feedforward(None)
    assert all(lead.lag_s[j] == pytest.approx(hand, rel=1e-3) for j in ARM_JOINTS)
    assert VelocityLead.for_feedforward(feedforward).lag_s["elbow_flex"] == pytest.approx(
        hand, rel=1e-3)

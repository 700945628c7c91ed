"""The simulated STS3215 against the measurements it claims to reproduce.

Each test names its source (so101_kinematics/servo.py lists them) and takes its expected
value from it, or from a hand calculation on the model's own physics (gravity torque over
the loop's stiffness), never from the constant under test:

- [TEL] roboninecom, Measuring-Backlash-in-Popular-UART-Servos (telemetry at rest and in
  motion, Present_Velocity quantisation);
- [BAM] Rhoban's identified STS3215 (the loop's 0.166 P duty per rad, the motor);
- [DS] Feetech's datasheets (no-load speeds);
- [PR4310] lerobot PR #4310 (LeKiwi's shoulder: the residual falls with P, an I term removes it).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from so101_kinematics import gravity, servo
from so101_kinematics.frames import ARM_JOINTS, JOINTS
from so101_kinematics.paths import SCENE_PATH
from so101_kinematics.sim import actuation
from so101_kinematics.sim.scene import (
    get_configuration,
    load_model,
    send_position_command,
    set_initial_pose,
)
from so101_kinematics.sim.sts3215 import ServoBank

ZERO = dict.fromkeys(JOINTS, 0.0) | {"gripper": 50.0}
"""The all-zero pose: the arm stretched out level, the largest gravity torques."""

COUNT = 2 * math.pi / 4096  # [rad]


def settle(cfg, seconds: float = 3.0, **servo_options):
    """Start at rest at ``cfg``, command ``cfg`` and let the servos settle; the measured pose."""
    m = load_model()
    actuation.use_servo(m, **servo_options)
    d = mujoco.MjData(m)
    set_initial_pose(d, cfg)
    actuation.step(m, d, round(seconds / m.opt.timestep))
    return get_configuration(m, d)


def sag(cfg, joint, **servo_options) -> float:
    """How far [deg] ``joint`` rests from its goal ``cfg[joint]`` without feed-forward."""
    return settle(cfg, feedforward=False, **servo_options)[joint] - cfg[joint]


# --- the static law --------------------------------------------------------------------------
def test_the_duty_follows_the_telemetry_law_at_rest():
    # [TEL]: Present_Load = Minimum_Startup_Force + (P/4)(|e| - dead zone), 0 inside the zone.
    assert servo.duty(1, servo.LEROBOT) == 0.0
    assert servo.duty(-40, servo.LEROBOT) == pytest.approx(-(16 + 16 / 4 * 39))
    assert servo.duty(40, servo.FACTORY) == pytest.approx(16 + 32 / 4 * 39)
    # its slope is BAM's oscilloscope figure, 0.166 P of duty per radian, within 2 %
    slope = (servo.duty(150, servo.LEROBOT) - servo.duty(100, servo.LEROBOT)) / 1000 / (50 * COUNT)
    assert slope == pytest.approx(0.166 * 16, rel=0.02)


@pytest.mark.parametrize(("options", "torque_per_volt", "volts", "band"), [
    ({}, 2.94 / 12.0, 12.0, (3.5, 4.5)),  # the default: the C018 datasheet's stall over 12 V
    ({"volts": 5.0, "variant": "C001"}, 1.2116 / 2.676, 5.0, (5.0, 6.0)),  # BAM's kt / R
])
def test_the_shoulder_sags_by_gravity_torque_over_stiffness(options, torque_per_volt, volts,
                                                            band):
    # Hand calculation: the shoulder's gravity torque at the stretched pose over the loop's
    # linearised stiffness (kt/R) V x 0.166 P [BAM], plus the few counts of dead zone, startup
    # force and half the gear play: the simulated joint must rest there (friction: +-0.5 deg).
    torque = gravity.holding_torques(ZERO)["shoulder_lift"]
    stiffness = torque_per_volt * volts * 0.166 * 16  # [N m/rad]
    expected = math.degrees(abs(torque) / stiffness)
    assert band[0] < expected < band[1]
    measured = sag(ZERO, "shoulder_lift", **options)
    assert measured > 0  # below its goal: the stretched arm pulls shoulder_lift positive
    assert measured == pytest.approx(expected, abs=0.8)


def test_the_sag_halves_from_p_16_to_p_32_and_scales_with_the_supply():
    # The loop's stiffness is proportional to P and to the supply [BAM]: the residual at
    # P = 32 is 0.35-0.7 of P = 16's (the issue's window around 1/2, the dead zone and
    # friction not scaling), and 5 V sags about 7.4 / 5 = 1.48x more than 7.4 V.
    at_16 = sag(ZERO, "shoulder_lift", volts=7.4)
    at_32 = sag(ZERO, "shoulder_lift", volts=7.4, p=32)
    assert 0.35 <= at_32 / at_16 <= 0.7
    at_5 = sag(ZERO, "shoulder_lift", volts=5.0)
    assert at_5 / at_16 == pytest.approx(7.4 / 5.0, rel=0.15)


def test_bams_motor_and_the_datasheets_give_sags_1_75x_apart():
    # BAM identified 3.35 N m at stall and 7.4 V; the C001 datasheet says 1.91 N m: the
    # project uses BAM's (the identified dynamics) and keeps the datasheet's as a variant.
    bam = sag(ZERO, "shoulder_lift", volts=7.4, variant="C001")
    sheet = sag(ZERO, "shoulder_lift", volts=7.4, variant="C001-datasheet")
    assert sheet / bam == pytest.approx(3.35 / 1.91, rel=0.15)


def test_the_shoulder_residual_falls_with_p_and_an_i_term_removes_it():
    # [PR4310]: a 4 deg climb against gravity leaves 3.20 deg undone at P = 16, 1.63 at
    # P = 32, 1.45 at P = 48 and none at P = 48 with I = 4 (LeKiwi's shoulder; the SO-101's
    # load differs, so the trend is the claim, not the figures).
    start = dict(ZERO, shoulder_lift=-30.0)
    goal = dict(start, shoulder_lift=-34.0)  # up, against gravity

    def residual(p: int, i: int = 0) -> float:
        m = load_model()
        actuation.use_servo(m, volts=7.4, p=p, i=i, feedforward=False)
        d = mujoco.MjData(m)
        set_initial_pose(d, start)
        actuation.step(m, d, 500)
        send_position_command(d, goal)
        actuation.step(m, d, 1250)  # 5 s, then the mean over 5 s (with I it hunts +-0.5 deg)
        seen = []
        for _ in range(50):
            actuation.step(m, d, 25)
            seen.append(get_configuration(m, d)["shoulder_lift"] - goal["shoulder_lift"])
        return abs(float(np.mean(seen)))

    r16, r32, r48, r48i = residual(16), residual(32), residual(48), residual(48, 4)
    assert r16 > r32 > r48 > 0.5
    assert r48i < 0.3


# --- the motion profile ----------------------------------------------------------------------
def profile_run(distance_counts: int, acceleration: int, goal_velocity: int, seconds: float = 1.5):
    """A bare servo's internal target stepped at 4 ms: (times [s], speeds [counts/s])."""
    bank = ServoBank([servo.LEROBOT.with_(acceleration=acceleration,
                                          goal_velocity=goal_velocity)], 7.4)
    goal = [distance_counts * COUNT]
    times, speeds = [], []
    for k in range(round(seconds / 0.004)):
        bank.torques(goal, [0.0], 0.004)
        times.append((k + 1) * 0.004)
        speeds.append(bank.target_speed[0])
    return np.array(times), np.array(speeds)


def test_a_100_count_move_at_acceleration_20_is_a_triangle_of_450_counts_per_s():
    # [TEL]: Acceleration 20 (x 100 counts/s^2), Goal_Velocity 1000: peak Present_Velocity
    # 450 counts/s (sqrt(a d) = 447), 0.4-0.5 s per +-100-count move.
    times, speeds = profile_run(100, 20, 1000)
    assert 380 <= speeds.max() <= 520
    moving = times[speeds > 0]
    assert 0.35 <= moving[-1] - moving[0] + 0.004 <= 0.6


def test_goal_velocity_caps_the_speed_and_lerobots_254_is_nearly_a_step():
    times, speeds = profile_run(1000, 20, 300, seconds=5.0)
    assert speeds.max() == pytest.approx(300)  # a trapezoid capped at Goal_Velocity
    assert times[speeds > 0][-1] == pytest.approx(1000 / 300 + 300 / 2000, abs=0.05)
    # lerobot: Acceleration 254 (25 400 counts/s^2), Goal_Velocity 0 = the firmware's
    # 3400 counts/s [BAM]: 1000 counts in 1000/3400 + 3400/25400 = 0.43 s
    times, speeds = profile_run(1000, 254, 0)
    assert speeds.max() == pytest.approx(3400)
    assert times[speeds > 0][-1] == pytest.approx(0.43, abs=0.03)


@pytest.mark.parametrize(("variant", "volts", "rpm"), [
    ("C001", 7.4, 52.0), ("C001-datasheet", 7.4, 52.0), ("C018", 12.0, 45.0)])
def test_each_variant_turns_at_its_datasheets_no_load_speed(variant, volts, rpm):
    # [DS] no-load speed at the rated voltage; full duty in PWM mode (Operating_Mode 2) on the
    # wrist_roll joint, which gravity does not load. BAM's C001 turns at 50 rpm (4 % under).
    m = load_model()
    actuation.use_servo(m, volts=volts, variant=variant, feedforward=False)
    d = mujoco.MjData(m)
    set_initial_pose(d, dict(ZERO, wrist_flex=90.0))  # the roll axis vertical
    bank = ServoBank(actuation.lerobot_settings(), volts, variant)
    roll = JOINTS.index("wrist_roll")
    bank.mode[roll], bank.pwm[roll] = 2, servo.DUTY_MAX
    dof = m.joint("wrist_roll").dofadr[0]
    acts = [m.actuator(j).id for j in JOINTS]
    m.actuator_gainprm[acts, 0] = 0.0
    m.actuator_biasprm[acts, 1:3] = 0.0
    m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_LIMIT  # let it spin
    speeds = []
    for _ in range(250):  # 1 s
        q = [d.qpos[m.joint(j).qposadr[0]] for j in JOINTS]
        m.actuator_biasprm[acts, 0] = bank.torques(q, q, m.opt.timestep)
        mujoco.mj_step(m, d)
        speeds.append(d.qvel[dof])
    assert abs(np.mean(speeds[-50:])) * 60 / (2 * math.pi) == pytest.approx(rpm, rel=0.06)


def test_torque_limit_caps_the_push_so_a_3_percent_shoulder_cannot_hold_the_arm():
    # Torque_Limit [0.1 %] caps the duty [MEM]: at 30 the shoulder gives at most 0.03 x
    # 3.25 N m = 0.07 N m against 0.54 N m of gravity at the stretched pose: it falls.
    bank = ServoBank([servo.LEROBOT.with_(torque_limit=30)], 7.4)
    for _ in range(100):  # the target ramps to the goal; the joint is held half a radian off
        push = bank.torques([0.0], [-0.5], 0.004)[0]
    assert push == pytest.approx(0.030 * 1.2116 / 2.676 * 7.4)
    assert bank.duty[0] == 30


# --- the models the course loads ----------------------------------------------------------------
def test_the_scene_loaded_the_courses_way_sags_like_the_full_model_within_30_percent():
    # mujoco.MjModel.from_xml_path('model/scene.xml'): native actuators, no project code.
    load_model()  # installs the meshes
    m = mujoco.MjModel.from_xml_path(str(SCENE_PATH))
    d = mujoco.MjData(m)
    for joint in JOINTS:
        d.qpos[m.joint(joint).qposadr[0]] = math.radians(ZERO[joint]) if joint != "gripper" \
            else 0.8
        d.ctrl[m.actuator(joint).id] = d.qpos[m.joint(joint).qposadr[0]]
    mujoco.mj_step(m, d, 750)
    native = math.degrees(d.qpos[m.joint("shoulder_lift").qposadr[0]])
    full = sag(ZERO, "shoulder_lift")
    assert native == pytest.approx(full, rel=0.3)


def test_the_ideal_servo_is_upstreams_and_barely_sags():
    assert abs(settle(ZERO, mode="ideal")["shoulder_lift"]) < 0.1


# --- the feed-forward --------------------------------------------------------------------------
def test_holding_torques_are_mujocos_gravity_at_random_configurations():
    m = load_model()
    d = mujoco.MjData(m)
    rng = np.random.default_rng(7)
    for _ in range(50):
        cfg = {j: rng.uniform(-90, 90) for j in ARM_JOINTS} | {"gripper": rng.uniform(0, 100)}
        set_initial_pose(d, cfg)
        torques = gravity.holding_torques(cfg)
        for joint in ARM_JOINTS:
            assert torques[joint] == pytest.approx(d.qfrc_bias[m.joint(joint).dofadr[0]],
                                                   abs=1e-9)


@pytest.mark.parametrize("volts", [5.0, 7.4, 12.0])
def test_with_feedforward_the_course_start_pose_rests_within_half_a_degree(volts):
    start = {"shoulder_pan": 0.0, "shoulder_lift": -45.0, "elbow_flex": 45.0, "wrist_flex": 90.0,
             "wrist_roll": 0.0, "gripper": 50.0}
    without = settle(start, volts=volts, feedforward=False)
    assert max(abs(without[j] - start[j]) for j in ARM_JOINTS) > 1.0  # there is a sag to remove
    rest = settle(start, volts=volts, feedforward=True)
    assert max(abs(rest[j] - start[j]) for j in ARM_JOINTS) <= 0.5


def test_feedforward_offsets_are_bounded_and_zero_where_friction_holds():
    weak = servo.Settings(p=1)  # 16x weaker than lerobot: the sag would be huge
    offsets = gravity.feedforward(ZERO, weak, 5.0)
    for joint, limit in gravity.MAX_OFFSET_DEG.items():
        assert abs(offsets[joint]) <= limit
    assert offsets["shoulder_lift"] == -gravity.MAX_OFFSET_DEG["shoulder_lift"]
    assert offsets["wrist_roll"] == 0.0 and offsets["gripper"] == 0.0


def test_use_servo_refuses_what_it_cannot_simulate_in_one_line():
    m = load_model()
    for kwargs, words in [({"mode": "stiff"}, "servo 'stiff'"), ({"volts": 30.0}, "supply 30"),
                          ({"variant": "C999"}, "variant 'C999'"), ({"p": 0}, "P coefficient 0")]:
        with pytest.raises(Exception, match="Fix:") as caught:
            actuation.use_servo(m, **kwargs)
        assert words in str(caught.value) and "\n" not in str(caught.value)


def test_the_simulator_reports_the_miss_without_the_feedforward_and_places_with_it(tmp_path):
    # The acceptance through the course's script: 14 mm without (the 10 mm criterion
    # fails), within 5 mm with it (the default), on the kit's C001 at P = 16 on 5 V.
    import json

    import pick_place_sim

    def placed(*options) -> dict:
        path = tmp_path / f"report{len(options)}.json"
        assert pick_place_sim.main(["--headless", "--no-progress", "--json", str(path),
                                    *options]) == 0
        return json.loads(path.read_text())

    raw, fixed = placed("--no-gravity-ff"), placed()
    assert raw["placement_error_m"] > 0.010 and not raw["success"]
    assert "without gravity feed-forward" in raw["servo"]
    assert fixed["placement_error_m"] <= 0.005 and fixed["success"]

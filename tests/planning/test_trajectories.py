"""Assignment 9: the profiles, the cubic moves of both backends, the velocity scene, the test.

Expected values are hand calculations from the course's page: the cubic from q0 to qf in T
has a0 = q0, a1 = 0, a2 = 3 (qf - q0) / T^2, a3 = -2 (qf - q0) / T^3.
"""

from __future__ import annotations

import json
import logging
import math
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

from so101_kinematics.errors import PlanError
from so101_kinematics.frames import JOINTS
from so101_kinematics.planning.motion import Trajectory
from so101_kinematics.planning.motion_metrics import METRIC_KEYS
from so101_kinematics.planning.profiles import PROFILES, cubic_coefficients, quintic_coefficients

REPO = Path(__file__).resolve().parents[2]
VELOCITY_SCENE = REPO / "model" / "scene_with_velocity.xml"
ZERO = dict.fromkeys(JOINTS, 0.0)


# --- the profiles, by hand ---------------------------------------------------------------------
def test_cubic_coefficients_are_the_course_s():
    # q0 = 10, qf = 50, T = 2: a2 = 3 * 40 / 4 = 30, a3 = -2 * 40 / 8 = -10.
    assert cubic_coefficients(10.0, 50.0, 2.0) == (10.0, 0.0, 30.0, -10.0)


def test_cubic_trajectory_is_a0_a1_a2_a3_with_zero_end_velocities():
    path = Trajectory({"elbow_flex": 10.0}, {"elbow_flex": 50.0}, 2.0, "cubic")
    for t in (0.0, 0.5, 1.0, 1.5, 2.0):
        by_hand = 10.0 + 30.0 * t**2 - 10.0 * t**3  # a0 + a2 t^2 + a3 t^3
        assert path.at(t)["elbow_flex"] == pytest.approx(by_hand, abs=1e-12)
        velocity = 2 * 30.0 * t - 3 * 10.0 * t**2  # a1 + 2 a2 t + 3 a3 t^2
        assert path.velocity_at(t)["elbow_flex"] == pytest.approx(velocity, abs=1e-12)
        acceleration = 2 * 30.0 - 6 * 10.0 * t  # 2 a2 + 6 a3 t
        assert path.acceleration_at(t)["elbow_flex"] == pytest.approx(acceleration, abs=1e-12)
    assert path.velocity_at(0.0)["elbow_flex"] == 0.0
    assert path.velocity_at(2.0)["elbow_flex"] == pytest.approx(0.0, abs=1e-12)


def test_time_is_clipped_to_the_move():
    path = Trajectory({"elbow_flex": 10.0}, {"elbow_flex": 50.0}, 2.0, "cubic")
    assert path.at(-1.0)["elbow_flex"] == 10.0  # before: the start
    assert path.at(3.0)["elbow_flex"] == 50.0  # after: the goal, no overshoot
    assert path.velocity_at(-1.0)["elbow_flex"] == 0.0
    assert path.velocity_at(3.0)["elbow_flex"] == 0.0


def test_quintic_has_zero_end_velocity_and_acceleration_and_is_minimum_jerk():
    a = quintic_coefficients(0.0, 10.0, 1.0)  # 10 s^3 - 15 s^4 + 6 s^5, times 10
    assert a == (0.0, 0.0, 0.0, 100.0, -150.0, 60.0)
    path = Trajectory({"wrist_flex": 0.0}, {"wrist_flex": 10.0}, 1.0, "quintic")
    for end in (0.0, 1.0):
        assert path.velocity_at(end)["wrist_flex"] == pytest.approx(0.0, abs=1e-12)
        assert path.acceleration_at(end)["wrist_flex"] == pytest.approx(0.0, abs=1e-12)
    s = np.linspace(0.0, 1.0, 11)
    np.testing.assert_allclose(PROFILES["quintic"](s), PROFILES["minimum_jerk"](s))
    assert path.at(0.5)["wrist_flex"] == pytest.approx(sum(c * 0.5**k for k, c in enumerate(a)))


def test_direct_is_a_step_and_linear_a_ramp():
    step = Trajectory({"shoulder_pan": 0.0}, {"shoulder_pan": 30.0}, 2.0, "direct")
    assert step.at(0.0)["shoulder_pan"] == 30.0  # the goal at once
    ramp = Trajectory({"shoulder_pan": 0.0}, {"shoulder_pan": 30.0}, 2.0, "linear")
    assert ramp.at(0.5)["shoulder_pan"] == 7.5
    assert ramp.velocity_at(1.0)["shoulder_pan"] == 15.0  # 30 deg / 2 s


@pytest.mark.parametrize("name", ["linear", "cubic", "quintic", "minimum_jerk"])
def test_derivatives_are_those_of_the_position(name):
    profile, s, h = PROFILES[name], np.linspace(0.05, 0.95, 19), 1e-6
    np.testing.assert_allclose(profile.velocity(s),
                               (profile(s + h) - profile(s - h)) / (2 * h), atol=1e-6)
    np.testing.assert_allclose(profile.acceleration(s), (profile.velocity(s + h) -
                                                         profile.velocity(s - h)) / (2 * h),
                               atol=1e-5)


def test_peak_speed_factors_by_hand():
    # 6 s (1 - s) at s = 1/2 is 3/2; 30 s^2 (1 - s)^2 at s = 1/2 is 15/8.
    assert PROFILES["cubic"].peak_speed == 1.5
    assert PROFILES["quintic"].peak_speed == 1.875
    assert PROFILES["linear"].peak_speed == 1.0
    assert math.isinf(PROFILES["direct"].peak_speed)


def test_the_real_arm_caps_a_cubic_at_its_peak_and_refuses_a_step():
    from so101_kinematics.hw.timing import capped_duration, check_profile

    # 90 deg in 1 s at a 45 deg/s cap: the cubic's peak is 1.5 x 90 / T <= 45, T = 3 s.
    assert capped_duration({"shoulder_pan": 0.0}, {"shoulder_pan": 90.0}, 1.0, "cubic",
                           {"shoulder_pan": 45.0}) == 3.0
    with pytest.raises(PlanError, match="'direct' is a step.*Fix: use one of"):
        check_profile("direct")


def test_an_unknown_profile_names_the_choices():
    with pytest.raises(PlanError, match="cubic"):
        Trajectory(ZERO, ZERO, 1.0, "cubical")


# --- the velocity scene --------------------------------------------------------------------------
@pytest.fixture(scope="module")
def velocity_model(model):  # model: the meshes are installed
    return mujoco.MjModel.from_xml_path(str(VELOCITY_SCENE))  # the course's own line


def test_the_velocity_scene_has_the_course_s_twelve_actuators(velocity_model):
    m = velocity_model
    names = [m.actuator(i).name for i in range(m.nu)]
    assert names == list(JOINTS) + [f"{j}_vel" for j in JOINTS]
    for joint in JOINTS:
        position, velocity = m.actuator(joint), m.actuator(f"{joint}_vel")
        assert position.gainprm[0] == 50.0 and position.biasprm[1] == -50.0  # kp
        assert position.biasprm[2] == -2.0  # kv
        np.testing.assert_array_equal(position.forcerange, [-10.0, 10.0])
        np.testing.assert_allclose(position.ctrlrange, m.joint(joint).range)
        assert velocity.gainprm[0] == 10.0 and velocity.biasprm[2] == -10.0  # kv
        np.testing.assert_array_equal(velocity.forcerange, [-10.0, 10.0])
        np.testing.assert_array_equal(velocity.ctrlrange, [-200.0, 200.0])


def test_the_velocity_scene_is_the_same_robot(velocity_model, model):
    m = velocity_model
    assert m.nbody == model.nbody and m.njnt == model.njnt
    np.testing.assert_array_equal(m.body_pos, model.body_pos)
    np.testing.assert_array_equal(m.jnt_range, model.jnt_range)
    np.testing.assert_array_equal(m.body_mass, model.body_mass)


def test_load_model_keeps_the_course_s_actuators_on_the_velocity_scene(caplog):
    from so101_kinematics.sim import actuation
    from so101_mujoco_utils import load_model

    with caplog.at_level(logging.INFO):
        m = load_model(VELOCITY_SCENE)
    assert actuation.servo_spec(m) is None
    assert m.actuator("elbow_flex").gainprm[0] == 50.0
    with pytest.raises(PlanError, match="velocity model.*Fix: load model/scene.xml"):
        actuation.use_servo(m)


def test_send_position_command_sets_twelve_controls(velocity_model):
    from so101_mujoco_utils import send_position_command

    d = mujoco.MjData(velocity_model)
    send_position_command(d, dict(ZERO, elbow_flex=90.0), {"elbow_flex": 180.0, "gripper": 100.0})
    ctrl = dict(zip([velocity_model.actuator(i).name for i in range(12)], d.ctrl, strict=True))
    assert ctrl["elbow_flex"] == pytest.approx(math.pi / 2)
    assert ctrl["elbow_flex_vel"] == pytest.approx(math.pi)  # 180 deg/s
    lower, upper = velocity_model.joint("gripper").range
    assert ctrl["gripper_vel"] == pytest.approx(upper - lower)  # 100 %/s: the range per second
    assert ctrl["shoulder_pan_vel"] == 0.0
    send_position_command(d, ZERO)  # no velocities: the course's [0.0] * 6
    assert not d.ctrl[6:].any()


def test_velocities_on_a_position_only_model_say_which_scene(model, data):
    from so101_mujoco_utils import send_position_command

    with pytest.raises(PlanError, match="scene_with_velocity.xml"):
        send_position_command(data, ZERO, {"elbow_flex": 1.0})


# --- the cubic moves ----------------------------------------------------------------------------
def test_move_to_pose_cubic_follows_the_course_s_cubic(model, data):
    from conftest import _EveryStep

    from so101_mujoco_utils import get_command, move_to_pose_cubic, set_initial_pose

    set_initial_pose(data, ZERO)
    seen = []
    viewer = _EveryStep(lambda: seen.append((data.time, get_command(model, data)["elbow_flex"])))
    t0 = data.time
    move_to_pose_cubic(model, data, viewer, dict(ZERO, elbow_flex=40.0), 2.0)
    assert len(seen) == 500  # 2 s of 4 ms steps
    for time, command in seen:
        t = time - t0 - model.opt.timestep  # each command was set before its step
        assert command == pytest.approx(30.0 * t**2 - 10.0 * t**3, abs=1e-9)  # 40 deg in 2 s
    assert get_command(model, data)["elbow_flex"] == pytest.approx(40.0)  # ends on the goal


def test_the_explicit_start_is_checked_never_jumped_to(model, data, caplog):
    from so101_mujoco_utils import get_command, move_to_pose_cubic, set_initial_pose

    set_initial_pose(data, ZERO)
    with caplog.at_level(logging.WARNING):
        move_to_pose_cubic(model, data, None, dict(ZERO, elbow_flex=30.0),
                           dict(ZERO, elbow_flex=10.0), 0.5)
    assert "elbow_flex" in caplog.text  # the wrong start is named
    assert get_command(model, data)["elbow_flex"] == pytest.approx(10.0)


def test_the_page_s_script_ends_within_2_deg_of_each_target():
    done = subprocess.run(
        [sys.executable, "tests/course_scripts/run_headless.py",
         "tests/course_scripts/sim_week9_page_script.py"],
        cwd=REPO, capture_output=True, text=True, timeout=300,
        env={"PYTHONPATH": str(REPO), "MUJOCO_GL": "egl", "PATH": "/usr/bin:/bin"})
    assert done.returncode == 0 and "Traceback" not in done.stderr, done.stderr
    errors = [float(line.split(": ")[1].split()[0]) for line in done.stdout.splitlines()]
    assert len(errors) == 3 and max(errors) < 2.0, done.stdout


# --- the week-9 test's figures -------------------------------------------------------------------
def test_the_week9_sequence_figures(model, data):
    from so101_kinematics.sim import tracking

    figures = {p: tracking.metrics(tracking.run_week9(model, data, None, p))
               for p in ("linear", "cubic")}
    for values in figures.values():
        assert set(values) == set(METRIC_KEYS)
    # The cubic has no velocity step: its measured acceleration peaks lower than linear's.
    assert (figures["cubic"]["peak_acceleration_deg_s2"] <
            figures["linear"]["peak_acceleration_deg_s2"])


def test_the_logging_helper_without_pandas_names_the_extra(model, data, monkeypatch):
    from so101_kinematics.sim import tracking

    monkeypatch.setitem(sys.modules, "pandas", None)  # import pandas fails
    with pytest.raises(ImportError, match=r"pandas.*Fix: pip install"):
        tracking.log_frame(tracking.StepLog(model, data))


# --- week 8's logging helpers, both backends ----------------------------------------------------
def test_sim_logging_helper_returns_the_course_s_frame_in_both_shapes(model, data, tmp_path):
    pytest.importorskip("pandas")
    from so101_mujoco_utils import move_to_pose_with_logging, plot_data, set_initial_pose

    set_initial_pose(data, ZERO)
    df = move_to_pose_with_logging(model, data, None, dict(ZERO, elbow_flex=40.0), 2.0)
    assert list(df.columns) == (["time"] + [f"target_{j}" for j in JOINTS] +
                                [f"actual_{j}" for j in JOINTS])
    assert len(df) == 500  # a row per 4 ms step
    assert df["target_elbow_flex"].iloc[249] == pytest.approx(20.0, abs=0.2)  # halfway: linear
    assert abs(df["actual_elbow_flex"].iloc[-1] - 40.0) < 3.0  # the servo lags, then arrives
    df2 = move_to_pose_with_logging(model, data, None, dict(ZERO, elbow_flex=40.0), ZERO, 1.0,
                                    profile="cubic")
    assert df2["time"].iloc[0] == pytest.approx(model.opt.timestep)  # from the move's start
    assert df2["target_elbow_flex"].iloc[124] == pytest.approx(20.0, abs=0.3)  # cubic: halfway
    plot_data(df2, tmp_path / "log.png")
    assert (tmp_path / "log.png").read_bytes()[:4] == b"\x89PNG"


def test_plot_data_leaves_the_figure_to_the_caller(model, data, tmp_path):
    """``plot_data(df)`` then ``plt.savefig(...)``, as the course's page and matplotlib users
    do, saves the plot (issue 33: it showed and closed its own figure: a blank image)."""
    pytest.importorskip("pandas")
    import matplotlib

    matplotlib.use("Agg")  # no display, as on a lab server or in CI
    import matplotlib.pyplot as plt
    import numpy as np
    from PIL import Image

    from so101_mujoco_utils import move_to_pose_with_logging, plot_data, set_initial_pose

    set_initial_pose(data, ZERO)
    df = move_to_pose_with_logging(model, data, None, dict(ZERO, elbow_flex=40.0), 0.2)
    plt.close("all")
    fig = plot_data(df)
    assert fig is plt.gcf() and len(fig.axes) == len(JOINTS)
    plt.savefig(tmp_path / "week8.png")
    plt.close(fig)
    pixels = np.asarray(Image.open(tmp_path / "week8.png").convert("L"))
    assert (pixels < 128).mean() > 0.01  # text, axes and curves: not a blank page


@pytest.fixture
def virtual_arm_calibration(tmp_path, monkeypatch):
    import shutil

    folder = tmp_path / "lerobot_calibration" / "robots" / "so_follower"
    folder.mkdir(parents=True)
    shutil.copy(REPO / "calibration" / "virtual_so101.json", folder / "follower-1.json")
    monkeypatch.setenv("HF_LEROBOT_CALIBRATION", str(tmp_path / "lerobot_calibration"))


@pytest.mark.hw
@pytest.mark.slow
def test_the_arm_s_cubic_and_logged_moves_on_the_virtual_arm(course_arm, virtual_arm_calibration,
                                                             caplog):
    pytest.importorskip("pandas")
    import so101_kinematics.hw.course_helpers as course
    from so101_utils import (
        load_calibration,
        move_to_pose_cubic,
        move_to_pose_with_logging,
        setup_motors,
    )

    bus = setup_motors(load_calibration("follower-1"), course_arm.port)
    session = course._RUNS[id(bus)].session
    start = bus.sync_read("Present_Position")
    target = dict(start, shoulder_pan=start["shoulder_pan"] + 20.0)
    move_to_pose_cubic(bus, target, 1.0)
    assert session.segments[-1].goal["shoulder_pan"] == pytest.approx(target["shoulder_pan"])
    elsewhere = dict(target, shoulder_pan=target["shoulder_pan"] + 25.0)
    with caplog.at_level(logging.WARNING):
        df = move_to_pose_with_logging(bus, elsewhere, start, 1.0, profile="cubic")
    assert "starting configuration is 25.0 deg from the last command" in caplog.text
    assert session.segments[-1].start["shoulder_pan"] == pytest.approx(target["shoulder_pan"])
    assert len(df) >= 90  # 100 Hz for 1 s
    middle = df.iloc[(df["time"] - 0.5).abs().idxmin()]
    assert middle["target_shoulder_pan"] == pytest.approx(start["shoulder_pan"] + 10.0, abs=1.0)
    assert not df["actual_shoulder_pan"].isna().all()
    bus.disable_torque()


def _run_script(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "test_trajectory_mujoco.py", *args], cwd=REPO,
                          capture_output=True, text=True, timeout=600,
                          env={"PYTHONPATH": str(REPO), "MUJOCO_GL": "egl",
                               "PATH": "/usr/bin:/bin"})


@pytest.mark.slow
def test_the_script_compares_every_profile_into_json_and_a_plot(tmp_path):
    report, plot = tmp_path / "week9.json", tmp_path / "week9.png"
    done = _run_script("--headless", "--compare", "--straight", "--json", str(report),
                       "--plot", str(plot))
    assert done.returncode == 0, done.stderr
    written = json.loads(report.read_text())
    assert set(written["straight_line"]) == {"ik", "resolved_rate"}
    for figures in written["straight_line"].values():
        assert {"max_path_deviation_mm", "start_offset_mm", "command_deviation_mm"} == set(figures)
    profiles = written["profiles"]
    assert set(profiles) == set(PROFILES)
    for figures in profiles.values():
        assert set(figures) == {"tracking_rms_deg", "tracking_max_deg", "peak_velocity_deg_s",
                                "peak_acceleration_deg_s2", "peak_jerk_deg_s3"}
    assert profiles["cubic"]["peak_acceleration_deg_s2"] < \
        profiles["linear"]["peak_acceleration_deg_s2"]
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_jaw_on_the_table_is_reported_and_the_profiles_not_ranked(tmp_path):
    """Without the feed-forward the arm sags (README, 'What the real arm does') and its jaw
    comes down on the table at the block targets, 14 mm above it (issue 33): the peaks are
    then the impact's (4686-5819 deg/s^2 against 162-292 with it), so no ranking."""
    sagging, holding = tmp_path / "sag.json", tmp_path / "ff.json"
    done = _run_script("--headless", "--compare", "--no-gravity-ff", "--json", str(sagging))
    assert done.returncode == 0, done.stderr
    written = json.loads(sagging.read_text())
    assert set(written["table_contact"]) == set(PROFILES)
    for contact in written["table_contact"].values():
        assert contact["force_n"] > 1.0 and contact["body"] == "gripper"
        assert contact["geom"] in done.stdout and contact["where"] in done.stdout
    refusal = [line for line in done.stdout.splitlines() if line.startswith("Not ranked")]
    assert len(refusal) == 1 and "Fix:" in refusal[0] and "--no-gravity-ff" in refusal[0]
    assert written["not_ranked"].endswith(refusal[0])
    done = _run_script("--headless", "--compare", "--json", str(holding))
    assert done.returncode == 0, done.stderr
    written = json.loads(holding.read_text())
    assert written["table_contact"] == {} and written["not_ranked"] is None
    assert "Not ranked" not in done.stdout


def test_the_script_refuses_a_bad_profile_in_one_line():
    done = _run_script("--headless", "--profile", "cubical")
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert "cubic" in done.stderr


def test_the_velocity_scene_refuses_the_servo_options_in_one_line():
    done = _run_script("--headless", "--velocity", "--servo", "ideal")
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert "--velocity runs the course's velocity scene on its own gains" in done.stderr
    assert "Fix:" in done.stderr


@pytest.mark.hw
@pytest.mark.slow
def test_pick_place_hw_runs_a_cubic_plan_on_the_virtual_arm(course_arm, tmp_path, capsys):
    import pick_place_hw
    from so101_kinematics.constants import HOME_POSE
    from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH

    plan = {"steps": [{"name": "nod", "configuration": dict(HOME_POSE, wrist_flex=50.0),
                       "duration": 0.5, "hold": 0.1}], "return_duration": 0.5}
    plan_path = tmp_path / "nod.json"
    plan_path.write_text(json.dumps(plan))
    rc = pick_place_hw.main(["--port", course_arm.port, "--calibration",
                             str(DEFAULT_CALIBRATION_PATH), "--yes", "--plan", str(plan_path),
                             "--profile", "cubic"])
    out = capsys.readouterr().out
    assert rc == 0, out
    assert "Done: back at the starting pose" in out
    assert not any(course_arm.torque_enabled().values())


@pytest.mark.slow
def test_the_script_records_a_video_and_refuses_one_of_the_velocity_scene(tmp_path):
    video = tmp_path / "week9.mp4"
    done = _run_script("--record", str(video), "--no-progress", "--profile", "cubic")
    assert done.returncode == 0, done.stderr
    assert video.read_bytes()[4:8] == b"ftyp"
    done = _run_script("--record", str(tmp_path / "other.mp4"), "--velocity")
    assert done.returncode == 2 and "Fix: record without --velocity" in done.stderr


# --- straight lines in task space ----------------------------------------------------------------
def test_the_path_deviation_is_the_distance_to_the_segment():
    from so101_kinematics.planning.straight_line import max_path_deviation_mm

    # Beside the middle: 3-4-5 mm off; before the start: the distance to the start.
    assert max_path_deviation_mm([[0.5, 0.003, 0.004]], (0, 0, 0), (1, 0, 0)) == pytest.approx(5.0)
    assert max_path_deviation_mm([[-0.003, 0.0, 0.004]], (0, 0, 0), (1, 0, 0)) == pytest.approx(
        5.0)


@pytest.mark.parametrize("method", ["ik", "resolved_rate"])
def test_both_straight_line_methods_command_the_segment(model, data, method):
    from so101_kinematics.sim import straight

    figures = straight.figures(straight.run_straight(model, data, method))
    assert figures["command_deviation_mm"] < 0.1  # the method's own share: on the line
    # The default servo (STS3215 C018, P = 16, 12 V, the gravity feed-forward), the arm
    # brought to the line's start by a move as a run does: the acceptance, 2 mm
    # (measured 0.89 / 0.85 mm on 2026-12-03; 0.89 / 1.02 on the kit's 5 V before). Put
    # down at the start instead, the friction band left 2.8 mm.
    assert figures["start_offset_mm"] < 1.0
    assert figures["max_path_deviation_mm"] < 2.0


@pytest.mark.parametrize("method", ["ik", "resolved_rate"])
def test_on_a_stiff_servo_the_measured_line_is_within_2_mm(method):
    from so101_kinematics.sim import actuation, straight
    from so101_mujoco_utils import load_model

    m = load_model()
    actuation.use_servo(m, "ideal")
    figures = straight.figures(straight.run_straight(m, mujoco.MjData(m), method))
    assert figures["max_path_deviation_mm"] < 2.0  # the acceptance

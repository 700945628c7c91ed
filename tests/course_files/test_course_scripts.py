"""Course-style scripts (tests/course_scripts/) run unchanged against the project's course files.

Written here from the course's pages (weeks 6-9), in the students' shapes and
with their usual mistakes: a pose copied from the viewer beyond a limit,
round-number limits, radians from ``qpos`` used as degrees, the viewer
closed mid-loop, the converters, week 8's trims and block helpers. Each runs
in its own Python process, from the repository root as a student runs it:
simulation scripts through ``run_headless.py`` (MuJoCo's passive viewer
swapped for a headless one), hardware scripts against the virtual SO-101.
Each must end as on the course's own utils: exit 0, no traceback.
"""

from __future__ import annotations

import math
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from so101_kinematics.gravity import holding_torques

HOME_ZERO = dict.fromkeys(("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex",
                           "wrist_roll"), 0.0) | {"gripper": 0.0}
"""The all-zero configuration the week-9 page starts from and returns to."""

REPO = Path(__file__).resolve().parents[2]
SCRIPTS = REPO / "tests" / "course_scripts"
RUNNER = SCRIPTS / "run_headless.py"
CALIBRATION_PATH = REPO / "calibration" / "virtual_so101.json"


def run(script: str, env: dict[str, str] | None = None, headless: bool = True,
        timeout: float = 120.0) -> subprocess.CompletedProcess:
    command = [sys.executable] + ([str(RUNNER)] if headless else []) + [str(SCRIPTS / script)]
    environment = {**os.environ, "PYTHONPATH": str(REPO), "MUJOCO_GL": "egl", **(env or {})}
    if "COURSE_VIEWER_CLOSES_AFTER" not in (env or {}):
        environment.pop("COURSE_VIEWER_CLOSES_AFTER", None)
    done = subprocess.run(command, cwd=REPO, env=environment, capture_output=True, text=True,
                          timeout=timeout)
    assert "Traceback" not in done.stderr, done.stderr
    assert done.returncode == 0, done.stderr
    return done


def warnings_in(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if "held at the limit" in line]


def test_week6_fk_and_pick_and_place():
    done = run("sim_week6_fk_pick_place.py")
    assert "object frame: [0.2301 0.1903 0.013 ]" in done.stdout  # MODEL_NOTES: start pose
    # where the course's pick-and-place ends, within the STS3215's friction band (0.5 deg)
    final = float(re.search(r"final shoulder_pan: ([-\d.]+)", done.stdout).group(1))
    assert abs(final - 45.0) <= 0.6
    assert not warnings_in(done.stderr)


def test_week7_ik_loop_ends_when_the_viewer_is_closed():
    done = run("sim_week7_ik_loop_closed.py", {"COURSE_VIEWER_CLOSES_AFTER": "400"})
    closed = re.search(r"viewer closed after (\d+) loop\(s\) at t = ([\d.]+) s", done.stdout)
    assert closed, done.stdout
    assert int(closed.group(1)) == 1  # closed inside the first pass of five targets
    assert float(closed.group(2)) < 10.0  # the five targets take 15 s: it stopped part-way


def test_week7_limit_mistakes_run_held_at_the_limits_with_a_word():
    done = run("sim_week7_limits_and_qpos.py")
    held = warnings_in(done.stderr)
    assert len(held) == 2, done.stderr  # -100.268 and -180; the round numbers are within
    assert "shoulder_lift = -100.268 deg is beyond its limit -100 deg" in held[0]
    assert "shoulder_lift = -180 deg is beyond its limit -100 deg" in held[1]
    # the limits held (shoulder_pan -110 -> its -109.99999 limit, wrist_flex 95); printed as
    # the 2 s move ends, the STS3215 at P = 16 still trails it by a few degrees (0.1 s of
    # its motion: servo.lag)
    printed = re.search(r"at the limits: \[([^\]]*)\]", done.stdout).group(1).split()
    pan, lift, elbow, wrist = (float(v) for v in printed)
    assert abs(pan + 110.0) <= 1.0 and abs(wrist - 95.0) <= 1.5
    assert abs(lift) <= 6.0 and abs(elbow) <= 6.0
    assert done.stdout.strip().endswith("done")


def test_week8_converters_behave_as_the_utils_do():
    done = run("sim_week8_converters.py")
    gripper = float(re.search(r"final gripper: ([-\d.]+)", done.stdout).group(1))
    assert abs(gripper - 5.0) < 1.0  # d.ctrl = convert_to_list(closed): closed to 5
    pan = re.search(r"final shoulder_pan: ([-\d.]+) \(IK: ([-\d.]+)\)", done.stdout)
    assert abs(float(pan.group(1)) - float(pan.group(2))) < 1.0  # friction band 0.5, a count
    assert "starting configuration is" not in done.stderr  # the measured start is no jump


@pytest.mark.slow
def test_week8_stacks_two_blocks_with_the_page_s_helpers():
    done = run("sim_week8_stack_blocks.py")
    assert "stacked in 21.0 s; gripper 50" in done.stdout  # 4 x (2 + 1 + 1 + 1) + 1 s


def test_week9_student_s_own_cubic_loop():
    done = run("sim_week9_cubic.py")
    # the student's loop steps MuJoCo itself (the model's native servos, the STS3215
    # linearised), but each move ends in the page's hold_position, the project's: the servo
    # model with the feed-forward, as so101_utils on the arm, holds the goal within its
    # friction band; without it the stretched arm would sag by gravity torque over
    # stiffness (hand calculation from the model's masses over the 12 V C018's linearised
    # stiffness, 2.94 N m / 12 V x 12 V x 0.004 x 651.9 = 7.67 N m/rad: about 4 deg)
    sag = math.degrees(-holding_torques(HOME_ZERO)["shoulder_lift"] / 7.67)
    home = float(re.search(r"back home: shoulder_lift ([-\d.]+) deg", done.stdout).group(1))
    assert sag > 3.5 and abs(home) <= 1.0


@pytest.fixture
def virtual_arm_env(course_arm, tmp_path):
    """The virtual arm's port and a lerobot calibration folder holding it as 'follower-1'."""
    folder = tmp_path / "lerobot_calibration" / "robots" / "so_follower"
    folder.mkdir(parents=True)
    shutil.copy(CALIBRATION_PATH, folder / "follower-1.json")
    return {"SO101_PORT": course_arm.port,
            "HF_LEROBOT_CALIBRATION": str(tmp_path / "lerobot_calibration")}


@pytest.mark.hw
@pytest.mark.slow
@pytest.mark.newest_lerobot  # the course's own scripts, on a lab machine's lerobot
def test_week8_hardware_ik_check_on_the_virtual_arm(virtual_arm_env, course_arm):
    done = run("hw_week8_ik_check.py", virtual_arm_env, headless=False)
    assert "home check, elbow_flex:" in done.stdout
    elbow = float(re.search(r"home check, elbow_flex: ([-\d.]+)", done.stdout).group(1))
    assert abs(elbow) < 2.0
    assert done.stdout.strip().splitlines()[-1] == "Done: back at the starting pose, torque off."
    assert not any(course_arm.torque_enabled().values())


@pytest.mark.hw
@pytest.mark.slow
def test_week8_hardware_trims_and_stacking_on_the_virtual_arm(virtual_arm_env, course_arm):
    done = run("hw_week8_stack_trims.py", virtual_arm_env, headless=False, timeout=180.0)
    offsets = re.search(r"offsets: (\{.*\})", done.stdout).group(1)
    assert "'shoulder_lift': 2.0" in offsets and "'elbow_flex': -4.0" in offsets  # the page's
    assert done.stdout.strip().splitlines()[-1] == "Done: back at the starting pose, torque off."
    assert not any(course_arm.torque_enabled().values())

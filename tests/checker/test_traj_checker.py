"""so101-check-traj: each planted mistake in tests/traj_submissions is named in the student's terms.

No MuJoCo and no lerobot: the student's move_to_pose_cubic runs against the checker's recording
stand-in in a child process. The expected numbers are hand calculations from the course's cubic
(a0 = q0, a1 = 0, a2 = 3 (qf - q0)/T^2, a3 = -2 (qf - q0)/T^3, t clipped to [0, T]).
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from so101_kinematics.checker import traj_compare
from so101_kinematics.checker.traj import check_traj_file, main
from so101_kinematics.frames import JOINTS

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

SUBMISSIONS = Path(__file__).resolve().parents[1] / "traj_submissions"
REPO = SUBMISSIONS.parent

PHRASES = {
    "a1": r"\ba1 is not zero",
    "a2": r"\ba2 (is|has|changes)",
    "a3": r"\ba3 (is|has|changes)",
    "linear": r"linear interpolation",
    "clip": r"time not clipped",
    "zeros": r"starts from zeros",
    "goal": r"jumps to the goal",
    "radian_start": r"start is read in radians",
    "degrees": r"degrees passed as radians",
    "ms_long": r"taken as ms: the move would take 1000x long",
    "ms_short": r"seconds treated as ms",
    "never_ends": r"a loop that never ends",
    "stuck": r"t does not advance",
    "velocity": r"velocity in deg/s sent as rad/s",
}
"""A kind of mistake -> how the report names it."""

PLANTED = {
    "a1_not_zero": {"a1"},
    "a2_no_square": {"a2"},
    "a3_wrong_sign": {"a3"},
    "linear": {"linear"},
    "not_clipped": {"clip"},
    "starts_from_zeros": {"zeros"},
    "jumps_to_goal": {"goal"},
    "radians_start": {"radian_start"},
    "degrees_as_radians": {"degrees"},
    "duration_in_ms": {"ms_long", "never_ends"},
    "seconds_as_ms": {"ms_short"},
    "never_ends": {"stuck", "never_ends"},
    "velocity_not_converted": {"velocity"},
}
"""Planted mistake (file name) -> the kinds the checker must name, and no others."""


@pytest.fixture(scope="module")
def checks():
    """Every submission checked once (two at a time, like a class)."""
    from concurrent.futures import ThreadPoolExecutor

    names = [p.stem for p in sorted(SUBMISSIONS.glob("*.py"))]
    with ThreadPoolExecutor(2) as pool:
        return dict(zip(names, pool.map(lambda n: check_traj_file(SUBMISSIONS / f"{n}.py"),
                                        names), strict=True))


def kinds(causes: list[str]) -> set[str]:
    return {kind for kind, pattern in PHRASES.items()
            if any(re.search(pattern, cause) for cause in causes)}


def move(check: dict, name: str) -> dict:
    return next(t for t in check["tests"] if t["move"] == name)


@pytest.mark.parametrize("name", ["correct", "correct_explicit_start", "correct_velocity"])
def test_a_correct_cubic_passes_every_move_with_an_ok_line(checks, name):
    check = checks[name]
    assert check["verdict"] == "pass", check
    assert [t["status"] for t in check["tests"]] == ["ok", "ok", "ok"]
    assert check["causes"] == []
    for test in check["tests"]:
        assert test["max_error_deg"] < 1e-3
        # the course's loop stops at t > T: one step more than T / dt at most
        assert test["expected_steps"] <= test["steps"] <= test["expected_steps"] + 1
        assert test["syncs"] == test["steps"]


def test_the_velocity_feed_forward_is_checked_only_when_sent(checks):
    assert [t["velocity_commands"] for t in checks["correct_velocity"]["tests"]] == \
        [True, True, False]  # the zero move's velocity is zero
    assert not any(t["velocity_commands"] for t in checks["correct"]["tests"])
    # deg/s sent as rad/s: the positions are right, the forward move's velocity is not
    forward = move(checks["velocity_not_converted"], "forward")
    assert forward["max_error_deg"] < 1e-3 and forward["status"] == "wrong"


def test_both_of_the_courses_shapes_are_called(checks):
    assert checks["correct"]["shape"] == \
        "move_to_pose_cubic(m, d, viewer, desired_position, duration)"
    assert checks["correct_explicit_start"]["shape"] == \
        "move_to_pose_cubic(m, d, viewer, starting_position, desired_position, duration)"


@pytest.mark.parametrize("name", sorted(PLANTED))
def test_each_planted_mistake_is_named_and_nothing_else(checks, name):
    check = checks[name]
    assert check["verdict"] == "fail", check["reason"]
    assert kinds(check["causes"]) == PLANTED[name], check["causes"]


def test_a_wrong_coefficient_says_which_and_by_what_factor(checks):
    # a2 = 3 (qf - q0)/T: T times the course's, so 2x at T = 2 s and 1.5x at T = 1.5 s,
    # which the two durations reveal as one power of T too few.
    no_square = checks["a2_no_square"]
    assert "a2 is 2x the course's" in move(no_square, "forward")["causes"][0]
    assert "a2 is 1.5x the course's" in move(no_square, "backward")["causes"][0]
    assert no_square["causes"][0].startswith("a2 changes with the duration like duration^1: it "
                                             "divides by duration^1, not duration^2")
    # a3 = +2 (qf - q0)/T^3: q(T) = q0 + (3 + 2)(qf - q0), end velocity (6 + 6)(qf - q0)/T
    sign = move(checks["a3_wrong_sign"], "forward")["causes"]
    assert sign[0].startswith("a3 has the wrong sign")
    assert "the velocity at the end is 12 (qf - q0)/T, not zero" in sign
    assert "at t = T the cubic reaches 5 of the way to the goal, not 1" in sign
    # a1 = (qf - q0)/T: the start velocity is (qf - q0)/T, and q(T) = q0 + 2 (qf - q0)
    a1 = move(checks["a1_not_zero"], "forward")["causes"]
    assert a1[0].startswith("a1 is not zero: the velocity at the start is 1 (qf - q0)/T")
    assert "at t = T the cubic reaches 2 of the way to the goal, not 1" in a1


def test_time_not_clipped_names_where_it_leaves_the_goal(checks):
    # Half a second past T = 2 s: s = 1.25, 3 s^2 - 2 s^3 = 0.78125, so the largest move
    # (90 deg) is 0.21875 * 90 = 19.69 deg off the goal at t = 2.5 s.
    (cause,) = move(checks["not_clipped"], "forward")["causes"]
    assert "19.69 deg off at t = 2.50 s" in cause


def test_the_zero_move_passes_a_cubic_that_only_gets_the_shape_wrong(checks):
    for name in ("a2_no_square", "a3_wrong_sign", "linear", "jumps_to_goal"):
        assert move(checks[name], "zero")["status"] == "ok", name
    for name in ("starts_from_zeros", "radians_start", "degrees_as_radians"):
        assert move(checks[name], "zero")["status"] == "wrong", name


def test_a_loop_that_never_ends_is_stopped_within_its_step_budget(checks):
    for name in ("never_ends", "duration_in_ms"):
        check = checks[name]
        assert check["reason"] == ""  # judged, not timed out
        for test in check["tests"]:
            assert test["ended"] == "steps"
            assert test["steps"] <= 6 * test["expected_steps"]  # "e.g. 5x the expected steps"
    # the unit error: the cubic fitted to 10 s of samples is timed for 2000 s
    assert "timed for 2000 s" in move(checks["duration_in_ms"], "forward")["causes"][0]


def test_seconds_taken_as_ms_end_after_one_step(checks):
    for test in checks["seconds_as_ms"]["tests"]:
        assert test["steps"] == 1  # T / 1000 = 2 ms is within the first 4 ms step


@pytest.mark.slow
def test_a_loop_that_never_steps_is_stopped_by_the_clock_or_the_wall(tmp_path):
    for body, ended in (("while time.time() - start < duration:\n        pass", "clock"),
                        ("while True:\n        pass", "wall")):
        path = tmp_path / f"{ended}.py"
        path.write_text("import time\n\n\ndef move_to_pose_cubic(m, d, viewer, desired_position,"
                        f" duration):\n    start = time.time()\n    {body}\n")
        check = check_traj_file(path)
        assert check["verdict"] == "fail" and check["reason"] == ""
        (test,) = check["tests"]  # the other moves are not run: they would wait as long
        assert test["ended"] == ended and test["steps"] == 0
        assert any(c.startswith("a loop that never ends") for c in check["causes"])


def test_a_cubic_commanded_every_fifth_step_is_judged_when_each_command_is_new(tmp_path):
    path = tmp_path / "every_fifth_step.py"
    path.write_text(
        "import mujoco\n\nfrom so101_mujoco_utils import convert_to_dictionary, "
        "send_position_command\n\n\n"
        "def move_to_pose_cubic(m, d, viewer, desired_position, duration):\n"
        "    a0 = convert_to_dictionary(d.qpos)\n"
        "    a2 = {j: 3 * (desired_position[j] - a0[j]) / duration**2 for j in a0}\n"
        "    a3 = {j: -2 * (desired_position[j] - a0[j]) / duration**3 for j in a0}\n"
        "    t0 = d.time\n"
        "    while d.time - t0 < duration:\n"
        "        t = min(max(d.time - t0, 0), duration)\n"
        "        send_position_command(d, {j: a0[j] + a2[j] * t**2 + a3[j] * t**3 for j in a0})\n"
        "        for _ in range(5):\n"
        "            mujoco.mj_step(m, d)\n"
        "        viewer.sync()\n")
    check = check_traj_file(path)
    assert check["verdict"] == "pass", check["causes"]
    assert [t["syncs"] * 5 for t in check["tests"]] == [t["steps"] for t in check["tests"]]


def test_a_misnamed_function_or_a_crash_is_not_checked(checks, tmp_path):
    misnamed = checks["misnamed_function"]
    assert misnamed["verdict"] == "error" and "'move_to_pose_cubc'" in misnamed["reason"]
    crash = tmp_path / "crash.py"
    crash.write_text("import mujoco\nm = mujoco.MjModel.from_xml_path('model/scene.xml')\n"
                     "x = 1 / 0\n")
    check = check_traj_file(crash)
    assert check["verdict"] == "error" and "ZeroDivisionError" in check["reason"]
    raises = tmp_path / "raises.py"
    raises.write_text("def move_to_pose_cubic(m, d, viewer, desired_position, duration):\n"
                      "    return desired_position['elbow']\n")
    check = check_traj_file(raises)
    assert check["verdict"] == "fail"
    assert all(t["status"] == "broken" and "KeyError" in t["causes"][0] for t in check["tests"])


def test_a_course_style_script_that_runs_its_moves_when_imported_is_checked(tmp_path):
    """The week-9 script students write (tests/course_scripts), beside the course's FK and IK:
    its module-level sequence runs on the stand-in at import, then its function is checked."""
    for name in ("so101_forward_kinematics.py", "so101_inverse_kinematics.py"):
        shutil.copy(REPO.parent / name, tmp_path / name)
    shutil.copy(REPO / "course_scripts" / "sim_week9_cubic.py", tmp_path / "week9.py")
    check = check_traj_file(tmp_path / "week9.py")
    assert check["verdict"] == "pass", check["reason"] or check["causes"]
    assert check["output"].startswith("back home: shoulder_lift 0.0 deg")


def test_the_students_own_utils_file_is_checked_under_its_own_name(tmp_path):
    folder = tmp_path / "ada"
    folder.mkdir()
    shutil.copy(SUBMISSIONS / "correct.py", folder / "so101_mujoco_utils.py")
    check = check_traj_file(folder / "so101_mujoco_utils.py")
    assert check["verdict"] == "pass" and check["student"] == "ada"


def test_the_reference_is_the_courses_cubic_clipped_to_the_duration():
    one = {"start": {j: 10.0 for j in JOINTS},
           "goal": {j: 50.0 for j in JOINTS}, "duration": 2.0}
    # 10 + 40 (3 s^2 - 2 s^3) at s = 0, 1/4, 1/2, 1 and past the end
    expected = [10.0, 10.0 + 40.0 * 0.15625, 30.0, 50.0, 50.0]
    got = traj_compare.reference(one, np.array([0.0, 0.5, 1.0, 2.0, 3.0]))
    assert np.allclose(got, np.array(expected)[:, None])


def test_text_json_and_gradescope_outputs(tmp_path, capsys):
    report, results = tmp_path / "check.json", tmp_path / "results.json"
    assert main([str(SUBMISSIONS / "correct.py"), "--json", str(report),
                 "--gradescope", str(results)]) == 0
    out = capsys.readouterr().out
    assert "Verdict: OK: every move follows the course's cubic. Score 100/100." in out
    assert json.loads(report.read_text())["verdict"] == "pass"
    graded = json.loads(results.read_text())
    assert graded["score"] == 100 and sum(t["max_score"] for t in graded["tests"]) == 100
    assert graded["extra_data"]["generator"].endswith("so101-check-traj")
    assert main([str(SUBMISSIONS / "not_clipped.py"), "--gradescope", str(results)]) == 1
    graded = json.loads(results.read_text())
    assert graded["score"] == 20 and "time not clipped" in graded["output"]


def test_bad_options_are_one_line_and_exit_2(tmp_path, capsys):
    with pytest.raises(SystemExit) as stop:
        main([str(SUBMISSIONS / "correct.py"), "--tolerance-deg", "0"])
    assert stop.value.code == 2 and "--tolerance-deg" in capsys.readouterr().err
    with pytest.raises(SystemExit) as stop:
        main([str(SUBMISSIONS / "correct.py"), str(SUBMISSIONS / "linear.py"),
              "--gradescope", str(tmp_path / "r.json")])
    assert stop.value.code == 2 and "Fix:" in capsys.readouterr().err
    notes = tmp_path / "notes.json"
    notes.write_text('{"mine": 1}')
    assert main([str(SUBMISSIONS / "correct.py"), "--json", str(notes)]) == 2
    assert notes.read_text() == '{"mine": 1}'  # a file this program did not write is kept
    assert main([str(tmp_path / "missing.py")]) == 2


def test_the_console_script_is_declared_and_runs_as_a_module():
    scripts = tomllib.loads((REPO.parent / "pyproject.toml").read_text())["project"]["scripts"]
    assert scripts["so101-check-traj"] == "so101_kinematics.checker.traj:main"
    done = subprocess.run([sys.executable, "-m", "so101_kinematics.checker.traj",
                           str(SUBMISSIONS / "a3_wrong_sign.py")],
                          cwd=REPO.parent, capture_output=True, text=True, timeout=60)
    assert done.returncode == 1, done.stderr
    assert "a3 has the wrong sign" in done.stdout

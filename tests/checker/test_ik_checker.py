"""so101-check-ik: each planted mistake in tests/ik_submissions is found, located and named."""

from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from so101_kinematics.checker import ik_compare, ik_targets
from so101_kinematics.checker.ik import check_ik_file, main
from so101_kinematics.errors import UnreachableError
from so101_kinematics.fast_fk import forward_kinematics_batch
from so101_kinematics.frames import ARM_JOINTS
from so101_kinematics.ik.call_shapes import get_inverse_kinematics
from so101_kinematics.ik.geometry import PAN_AXIS_POINT

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

SUBMISSIONS = Path(__file__).resolve().parents[1] / "ik_submissions"
FK_SUBMISSIONS = SUBMISSIONS.parent / "fk_submissions"
REPO = SUBMISSIONS.parent.parent
TIMEOUT = 3.0

KNOWN_CAUSES = {
    "pan_axis_offset": "shoulder_pan is measured from the base origin, not from the pan axis "
                       "38.8 mm in front of it",
    "roll_sign": "wrist_roll has the wrong sign relative to shoulder_pan",
    "no_mount_tilt": "the gripper mount's -2.79 deg tilt is left out",
    "ignores_orientation": "the asked orientation is ignored (always yaw 0)",
    "radians": "the angles are in radians",
    "tilt_sign": "the gripper mount's tilt is added with the wrong sign: the yaw is off by "
                 "-5.58 deg",
    "yaw_transposed": "the yaw is read from the transposed rotation",
}
"""Planted mistake (fixture name) -> the start of the cause the checker must name."""


@pytest.fixture(scope="module")
def checks():
    """Every planted submission checked once (two at a time, like a class)."""
    from concurrent.futures import ThreadPoolExecutor

    names = [p.stem for p in sorted(SUBMISSIONS.glob("*.py"))]
    with ThreadPoolExecutor(2) as pool:
        results = pool.map(lambda n: check_ik_file(SUBMISSIONS / f"{n}.py", (1.0, 1.0), TIMEOUT),
                           names)
        return dict(zip(names, results, strict=True))


def ik_test(check: dict) -> dict:
    (test,) = check["tests"]
    return test


def known(causes: list[str]) -> set[str]:
    return {name for name, text in KNOWN_CAUSES.items() if any(c.startswith(text) for c in causes)}


def test_a_correct_ik_is_right_at_every_target_with_the_fallback_fk(checks):
    check = checks["correct"]
    assert check["verdict"] == "pass", check["tests"]
    test = ik_test(check)
    assert test["counts"]["right"] == test["targets"] == ik_compare.count_targets()
    assert test["causes"] == []
    assert all(named["right"] for named in test["named"]) and len(test["named"]) == 3
    # The folder has no so101_forward_kinematics.py: the import found the checker's.
    assert test["fk_module"] == "fallback" and "the checker's" in check["note"]
    assert [answer["answer"] for answer in test["out_of_reach"]] == \
        ["NaN (unreachable, as the course says it)"] * 3


def test_out_of_reach_targets_are_unreachable_and_a_silent_answer_is_reported(tmp_path):
    for x, y, z, yaw in ik_targets.OUT_OF_REACH.values():
        with pytest.raises(UnreachableError):
            get_inverse_kinematics([x, y, z], yaw, 0.0)
    module = tmp_path / "so101_inverse_kinematics.py"
    source = (SUBMISSIONS / "correct.py").read_text()
    module.write_text(source.replace("abs(angles[0]) <= PAN_LIMIT and ", ""))  # no pan limit
    answers = ik_test(check_ik_file(module, count=20))["out_of_reach"]
    assert answers[0]["answer"] == answers[1]["answer"] == \
        "NaN (unreachable, as the course says it)"
    assert answers[2]["answer"].startswith("a configuration, 0.0 mm from the target, "
                                           "shoulder_pan beyond the limit, without saying")


@pytest.mark.parametrize("name", sorted(KNOWN_CAUSES))
def test_each_planted_mistake_is_named_by_its_cause_only(checks, name):
    check = checks[name]
    assert check["verdict"] == "fail"
    assert known(ik_test(check)["causes"]) == {name}, ik_test(check)["causes"]


def test_the_mount_tilt_left_out_is_its_angle_in_yaw_everywhere(checks):
    test = ik_test(checks["no_mount_tilt"])
    # The upstream quaternion (0.0172091, -0.0172091, 0.706897, 0.706897): 2 atan2(q_x, q_w).
    tilt = abs(math.degrees(2 * math.atan2(-0.0172091, 0.706897)))
    assert test["yaw_error_deg"]["median"] == pytest.approx(tilt, abs=1e-6)
    assert test["yaw_error_deg"]["max"] == pytest.approx(tilt, abs=1e-6)
    # The cube's centre is 5.1 mm off the roll axis: turned by 2.79 deg it moves 0.25 mm.
    assert test["error_mm"]["max"] == pytest.approx(2 * 5.1 * math.sin(math.radians(tilt) / 2)
                                                    * math.hypot(1, 0.218 / 5.1), abs=0.01)


def test_the_pan_axis_offset_fails_everywhere_near_the_base(checks):
    test = ik_test(checks["pan_axis_offset"])
    near = next(row for row in test["by_reach"] if row["name"] == "near the base")
    assert near["failing"] == near["targets"] > 10
    # Aiming from a point 38.8 mm off never misses by more than that offset (and the wrist's
    # height and the yaw stay right).
    assert 10.0 < test["error_mm"]["max"] <= 38.8353 + 0.5
    assert test["tilt_deg"]["max"] < 1e-6 and test["yaw_error_deg"]["max"] < 1e-6


def test_a_branch_beyond_the_joint_limits_is_named_with_the_joints(checks):
    test = ik_test(checks["elbow_down_unchecked"])
    assert test["counts"]["right"] == 0
    assert set(test["beyond_limit"]) >= {"elbow_flex", "wrist_flex"}
    assert [row["name"] for row in test["by_branch"]] == ["elbow down"]
    assert any(c.startswith("wrist_flex is beyond its limit") and "elbow down" in c
               for c in test["causes"])
    # Its answers do reach the targets: only the limits fail them.
    assert test["error_mm"]["max"] < 1e-6


def test_branches_say_elbow_up_and_reaching_backwards():
    start = [-45.0, 45.0, -45.0, 90.0, 0.0]  # the course's starting configuration
    folded_back = [0.0, -80.0, -10.0, 0.0, 0.0]  # upper arm leaning back past the pan axis
    angles = np.array([start, folded_back])
    positions, _ = forward_kinematics_batch(angles)
    assert positions[1, 0] < PAN_AXIS_POINT[0] < positions[0, 0]
    targets = np.c_[positions, np.zeros(2)]
    assert ik_compare._branches(targets, angles) == ["elbow up",
                                                     "elbow down, reaching backwards"]


def test_nan_on_reachable_targets_is_counted_apart_from_wrong_answers(checks):
    test = ik_test(checks["straight_links"])
    counts = test["counts"]
    assert counts["nan"] > 0 and counts["wrong"] > 0
    assert counts["nan"] + counts["wrong"] == test["targets"]
    assert any(c.startswith(f"NaN (unreachable) returned at {counts['nan']} reachable targets")
               for c in test["causes"])
    assert any(c.startswith("no known mistake recognised") for c in test["causes"])
    assert known(test["causes"]) == set()


def test_a_call_that_never_returns_is_stopped_and_the_target_named(checks):
    check = checks["hangs_far_away"]
    assert check["verdict"] == "error"
    assert f"timed out after {TIMEOUT:g} s while calling get_inverse_kinematics at target" \
        in check["reason"]
    assert check["seconds"] < TIMEOUT + 2.0
    test = ik_test(check)  # the answers saved before the hang are judged
    assert 0 < test["targets"] < ik_compare.count_targets() and test["counts"]["wrong"] == 0


def test_a_module_that_crashes_on_import_is_not_checked():
    check = check_ik_file(FK_SUBMISSIONS / "crashes_on_import.py", timeout=TIMEOUT)
    assert check["verdict"] == "error" and check["tests"] == []
    assert "ModuleNotFoundError" in check["reason"] and "line 28" in check["reason"]


def test_a_misnamed_function_is_missing_with_a_suggestion(checks):
    test = ik_test(checks["misnamed_function"])
    assert test["status"] == "missing"
    assert "'get_inverse_kinematic' looks like it" in test["causes"][0]


def test_the_students_own_fk_beside_it_is_used(tmp_path):
    right, wrong = tmp_path / "right", tmp_path / "wrong"
    for folder, fk in ((right, "correct"), (wrong, "dropped_offset_g12")):
        folder.mkdir()
        shutil.copy(SUBMISSIONS / "correct.py", folder / "so101_inverse_kinematics.py")
        shutil.copy(FK_SUBMISSIONS / f"{fk}.py", folder / "so101_forward_kinematics.py")
    check = check_ik_file(right / "so101_inverse_kinematics.py", count=60)
    assert check["verdict"] == "pass"
    assert str(right / "so101_forward_kinematics.py") in check["note"]
    # An FK without the shoulder's 18.3 mm offset: the IK built on it misses by this package's
    # FK, and inverts its own.
    check = check_ik_file(wrong / "so101_inverse_kinematics.py", count=60)
    assert check["verdict"] == "fail"
    assert any(c.startswith("your IK inverts your own FK") for c in ik_test(check)["causes"])


def test_an_ik_mistake_beside_a_correct_fk_is_blamed_on_the_ik(tmp_path):
    """Issue 28: the yaw read from R.T, with a correct FK beside it, was blamed on the FK."""
    folder = tmp_path / "student"
    folder.mkdir()
    shutil.copy(SUBMISSIONS / "yaw_transposed.py", folder / "so101_inverse_kinematics.py")
    shutil.copy(FK_SUBMISSIONS / "correct.py", folder / "so101_forward_kinematics.py")
    check = check_ik_file(folder / "so101_inverse_kinematics.py", count=60)
    assert check["verdict"] == "fail"
    causes = ik_test(check)["causes"]
    assert not any("your FK" in c for c in causes), causes
    assert known(causes) == {"yaw_transposed"}, causes


def test_every_target_is_reachable_top_down_as_the_course_asks():
    names, targets, references = ik_targets.build_targets()
    positions, rotations = forward_kinematics_batch(references)
    assert np.abs(positions - targets[:, :3]).max() < 1e-9
    assert np.all(rotations[:, 2, 2] > 1 - 1e-12)  # z up
    reached = np.degrees(np.arctan2(rotations[:, 1, 0], rotations[:, 0, 0]))
    yaw_error = (reached - np.degrees(targets[:, 3]) + 45.0) % 90.0 - 45.0
    assert np.abs(yaw_error).max() < 1e-6
    assert np.all((0.0 <= targets[:, 3]) & (targets[:, 3] < math.pi / 2))
    assert targets[:, 2].min() == 0.014 and np.sum(targets[:, 2] == 0.014) >= 200
    assert len(targets) == 3 + ik_targets.TARGET_COUNT and names[0].startswith("the course's")
    regions = {ik_targets.region(*t[:3]) for t in targets}
    assert {r[0] for r in regions} == {"near the base", "mid reach", "far reach"}
    assert {r[1] for r in regions} == {"front", "left (+y)", "right (-y)"}


def test_the_fallback_fk_is_this_packages_fk():
    namespace = {}
    exec(compile(ik_targets.reference_fk_source(), "fallback", "exec"), namespace)
    rng = np.random.default_rng(5)
    angles = rng.uniform(-90, 90, size=(50, 5))
    positions, rotations = forward_kinematics_batch(angles)
    for row, position, rotation in zip(angles, positions, rotations, strict=True):
        p, r = namespace["get_forward_kinematics"](dict(zip(ARM_JOINTS, row, strict=True)))
        assert np.abs(p - position).max() < 1e-12 and np.abs(r - rotation).max() < 1e-12


def test_a_class_gives_one_csv_row_per_student_and_the_worst_exit_code(tmp_path, capsys):
    files = []
    for student, planted in (("ada", "correct"), ("bo", "roll_sign")):
        path = tmp_path / "submissions" / student / "so101_inverse_kinematics.py"
        path.parent.mkdir(parents=True)
        shutil.copy(SUBMISSIONS / f"{planted}.py", path)
        files.append(str(path))
    assert main([*files, "--csv", str(tmp_path / "class.csv"), "--targets", "60"]) == 1
    rows = (tmp_path / "class.csv").read_text().splitlines()
    assert rows[0].startswith("student,file,verdict,targets,right,wrong,nan")
    assert [row.split(",")[:3] for row in rows[1:]] == [["ada", files[0], "pass"],
                                                        ["bo", files[1], "fail"]]
    assert "wrong sign relative to shoulder_pan" in rows[2]
    assert main([files[0], "--json", str(tmp_path / "one.json"), "--targets", "60"]) == 0
    assert json.loads((tmp_path / "one.json").read_text())["verdict"] == "pass"
    capsys.readouterr()
    assert main([files[0], str(tmp_path / "missing.py"), "--targets", "60"]) == 2
    assert "missing.py: not checked. no such file" in capsys.readouterr().out


def test_bad_options_are_one_line_and_exit_2(tmp_path, capsys):
    with pytest.raises(SystemExit) as stop:
        main([str(SUBMISSIONS / "correct.py"), "--targets", "0"])
    assert stop.value.code == 2
    assert "--targets" in capsys.readouterr().err
    assert main([str(SUBMISSIONS / "correct.py"), "--json", str(tmp_path)]) == 2


@pytest.mark.slow
def test_the_console_script_is_declared_and_runs_as_a_module():
    scripts = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["scripts"]
    assert scripts["so101-check-ik"] == "so101_kinematics.checker.ik:main"
    done = subprocess.run([sys.executable, "-m", "so101_kinematics.checker.ik",
                           str(SUBMISSIONS / "no_mount_tilt.py")],
                          cwd=REPO, capture_output=True, text=True, timeout=60)
    assert done.returncode == 1, done.stderr
    assert "tilt is left out" in done.stdout and "Verdict: outside the tolerance." in done.stdout

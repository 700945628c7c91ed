"""so101-check-fk: each planted mistake in tests/fk_submissions is named (factor and cause)."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest

from so101_kinematics.checker import diagnose, fk_compare, report
from so101_kinematics.checker.fk import check_file, main
from so101_kinematics.frames import GRIPPER_MOUNT_TILT_DEG, joint_transform

SUBMISSIONS = Path(__file__).resolve().parents[1] / "fk_submissions"
REPO = SUBMISSIONS.parent.parent
FEW = 50  # random configurations: enough for the diagnosis, quick


@pytest.fixture(scope="module")
def checks():
    """Every planted submission checked once (in parallel, like a class)."""
    from concurrent.futures import ThreadPoolExecutor

    names = [p.stem for p in sorted(SUBMISSIONS.glob("*.py"))]
    with ThreadPoolExecutor(2) as pool:
        results = pool.map(lambda n: check_file(SUBMISSIONS / f"{n}.py", (1.0, 1.0), 3.0, FEW),
                           names)
        return dict(zip(names, results, strict=True))


def test_by_name(check: dict, function: str) -> dict:
    return next(t for t in check["tests"] if t["function"] == function)


test_by_name.__test__ = False


def failing(check: dict) -> set[str]:
    return {t["function"] for t in check["tests"] if t["status"] not in report.PASSING}


def test_a_correct_module_gets_full_marks(checks):
    check = checks["correct"]
    assert check["verdict"] == "pass"
    scored = report.score(check, report.DEFAULT_POINTS)
    assert sum(t["score"] for t in scored) == sum(report.DEFAULT_POINTS.values()) == 100


@pytest.mark.parametrize("name, factor, cause", [
    ("dropped_offset_g12", "get_g12", "18.3 mm sideways offset of the shoulder_lift joint"),
    ("dropped_offset_g34", "get_g34", "5.2 mm offset of the wrist_flex joint"),
    ("dropped_offset_g45", "get_g45", "18.1 mm sideways offset of the wrist_roll axis"),
    ("no_mount_tilt", "get_g45", "off by 2.79 deg about z: the mount tilt is missing"),
    ("wrong_way_g23", "get_g23", "turns the wrong way"),
    ("wrong_order_g12", "get_g12", "composed in the wrong order"),
    ("degrees_as_radians_g34", "get_g34", "degrees passed where radians are expected"),
    ("transposed_fixed_g12", "get_g12", "the fixed rotation is transposed (R_fixed.T"),
    ("star_in_g45", "get_g45", "the rotations are multiplied element by element (*"),
])
def test_each_planted_mistake_is_named_in_its_factor_only(checks, name, factor, cause):
    check = checks[name]
    assert check["verdict"] == "fail"
    assert failing(check) == {factor, "get_forward_kinematics"}
    causes = test_by_name(check, factor)["causes"]
    assert len(causes) == 1 and cause in causes[0], causes


def test_a_wrong_object_frame_never_passes_the_fk(checks):
    """Issue 28: get_g5t the identity scored 90/100 with "get_forward_kinematics: ok".

    The object frame then sits at frame 5's origin: |(5.1, -0.2, -107.5)| mm = 107.6 mm
    from where the arm holds a cube (the upstream model's numbers, by hand).
    """
    check = checks["identity_g5t"]
    assert check["verdict"] == "fail"
    fk = test_by_name(check, "get_forward_kinematics")
    assert fk["status"] == "wrong"
    assert fk["max_error_mm"] == pytest.approx(107.6, abs=0.1)
    assert any("object frame is 107.6 mm from this package's" in c for c in fk["causes"])
    score = sum(t["score"] for t in report.score(check, report.DEFAULT_POINTS))
    assert score <= 50  # the final pose (FK) and g5t both lost


@pytest.mark.parametrize("name, cause", [
    ("position_from_wrong_row", "the position is gwt's bottom row, gwt[3, 0:3]"),
    ("star_for_matmul", "get_forward_kinematics multiplies the factors element by element (*)"),
])
def test_whole_fk_mistakes_are_named_in_the_fk(checks, name, cause):
    check = checks[name]
    assert failing(check) == {"get_forward_kinematics"}
    causes = test_by_name(check, "get_forward_kinematics")["causes"]
    assert len(causes) == 1 and causes[0].startswith(cause), causes


def test_radians_everywhere_is_named_in_every_factor_and_once_for_all(checks):
    check = checks["radians_everywhere"]
    for function in fk_compare.FACTORS:
        causes = test_by_name(check, function)["causes"]
        assert len(causes) == 1 and causes[0].startswith("degrees passed where radians"), causes
    assert check["note"].startswith("Degrees are used as radians in 5 of 5 factors")


def test_a_dropped_offset_names_its_value_and_the_upstream_body(checks):
    cause = test_by_name(checks["dropped_offset_g12"], "get_g12")["causes"][0]
    assert "body 'upper_arm' at y = -0.0182778 m in 'shoulder'" in cause
    # A missing 18.3 mm offset moves the object frame by exactly that much everywhere.
    fk = test_by_name(checks["dropped_offset_g12"], "get_forward_kinematics")
    assert fk["max_error_mm"] == pytest.approx(18.2778, abs=1e-3)


def test_a_half_turned_tool_frame_is_a_convention_not_a_failure(checks):
    check = checks["tool_half_turn"]
    assert check["verdict"] == "pass"
    tool = test_by_name(check, "get_g5t")
    assert tool["status"] == "convention"
    assert "half turn about y" in tool["causes"][0]
    assert tool["max_error_deg"] == pytest.approx(180.0)


def test_the_diagrams_numbers_are_recognised_and_the_chain_judged_apart_from_g5t(checks):
    check = checks["diagram_numbers"]
    assert failing(check) == {"get_g12", "get_g34", "get_g45", "get_forward_kinematics"}
    assert test_by_name(check, "get_g5t")["status"] == "convention"
    assert "course diagram's tool point" in test_by_name(check, "get_g5t")["causes"][0]
    assert "course diagram's rounded numbers" in check["note"]
    fk = test_by_name(check, "get_forward_kinematics")
    # The figure: 5.2 mm at the course's configurations (the 5.2 mm wrist offset
    # lies along the pan axis there; the 18.3 and 18.1 mm offsets cancel).
    assert [round(row["error_mm"], 1) for row in fk["course"][:2]] == [5.2, 5.2]
    assert fk["max_error_deg"] == pytest.approx(abs(GRIPPER_MOUNT_TILT_DEG), abs=1e-6)


def test_a_misnamed_function_is_missing_with_a_suggestion_and_the_gripper_key_is_noted(checks):
    check = checks["misnamed_function"]
    assert failing(check) == {"get_g45"}
    assert "'get_g_45' looks like it" in test_by_name(check, "get_g45")["causes"][0]
    fk = test_by_name(check, "get_forward_kinematics")
    assert fk["status"] == "ok" and fk["gripper_key"].startswith("needs a 'gripper' key")
    assert test_by_name(checks["correct"], "get_forward_kinematics")["gripper_key"] == \
        "works with or without a 'gripper' key"


def test_a_wrong_return_shape_fails_the_fk(checks):
    fk = test_by_name(checks["wrong_return_shape"], "get_forward_kinematics")
    assert fk["status"] == "broken"  # the course's scripts cannot unpack it
    assert "returns one 4x4 matrix; the course's form is (position, rotation)" in fk["causes"][0]


def test_a_module_that_cannot_be_imported_is_not_checked(checks):
    check = checks["crashes_on_import"]
    assert check["verdict"] == "error"
    assert "ModuleNotFoundError" in check["reason"] and "line 28" in check["reason"]


def test_a_hanging_module_is_stopped_within_the_time_bound_and_scored_zero(checks, tmp_path):
    check = checks["hangs_on_import"]
    assert check["verdict"] == "error"
    assert "timed out after 3 s while importing the module" in check["reason"]
    assert check["seconds"] < 3.0 + 2.0
    results = report.gradescope_results(check, report.DEFAULT_POINTS)
    assert results["score"] == 0
    assert all(t["score"] == 0 and "timed out" in t["output"] for t in results["tests"])


def test_a_module_that_prints_a_lot_is_checked_with_its_output_cut(checks):
    check = checks["prints_a_lot"]
    assert check["verdict"] == "pass"
    assert check["output_size"] > 1_000_000 and len(check["output"]) <= 4000


def test_the_students_module_runs_in_a_temporary_folder(tmp_path):
    module = tmp_path / "student" / "so101_forward_kinematics.py"
    module.parent.mkdir()
    module.write_text("import os\nopen('scribble.txt', 'w').write(os.getcwd())\n"
                      + (SUBMISSIONS / "correct.py").read_text())
    check = check_file(module, count=FEW)
    assert check["verdict"] == "pass"
    assert not (module.parent / "scribble.txt").exists()
    assert not (module.parent / "__pycache__").exists()
    assert "so101_forward_kinematics" not in sys.modules or \
        Path(sys.modules["so101_forward_kinematics"].__file__).parent == REPO


def test_a_missing_file_cannot_be_checked():
    check = check_file(SUBMISSIONS / "no_such_file.py")
    assert check["verdict"] == "error" and "no such file" in check["reason"]


def test_every_factor_matches_the_package_at_its_test_angles():
    """The package's own factors raise no diagnosis, and the test angles are distinct."""
    for name, joint in fk_compare.FACTORS.values():
        angles = fk_compare.factor_angles(joint)
        assert len(set(angles)) == len(fk_compare.ANGLE_FRACTIONS)
        assert diagnose.rotation_causes(name, angles, [joint_transform(name, a)[:3, :3]
                                                       for a in angles]) == []


def test_gradescope_results_have_the_documented_shape(tmp_path):
    out = tmp_path / "results.json"
    code = main([str(SUBMISSIONS / "no_mount_tilt.py"), "--gradescope", str(out),
                 "--random", str(FEW), "--points", "get_forward_kinematics=50", "-q"])
    assert code == 1
    results = json.loads(out.read_text())
    assert set(results) >= {"score", "output", "tests"}
    assert [t["name"] for t in results["tests"]] == list(report.DEFAULT_POINTS)
    for test in results["tests"]:
        assert set(test) >= {"name", "score", "max_score", "output"}
        assert 0 <= test["score"] <= test["max_score"]
    assert sum(t["max_score"] for t in results["tests"]) == 110
    assert results["score"] == 110 - 10 - 50  # g45 and the FK fail
    assert "mount tilt is missing" in results["tests"][4]["output"]


def test_a_class_gives_one_csv_row_per_student_and_the_worst_exit_code(tmp_path):
    files = []
    for student, planted in (("ada", "correct"), ("bo", "dropped_offset_g34"),
                             ("cy", "crashes_on_import")):
        path = tmp_path / "submissions" / student / "so101_forward_kinematics.py"
        path.parent.mkdir(parents=True)
        path.write_text((SUBMISSIONS / f"{planted}.py").read_text())
        files.append(str(path))
    code = main([*files, "--csv", str(tmp_path / "class.csv"), "--random", str(FEW),
                 "--json", str(tmp_path / "class.json")])
    assert code == 2
    rows = (tmp_path / "class.csv").read_text().splitlines()
    assert rows[0].startswith("student,file,verdict,score,max_score")
    assert [row.split(",")[:4] for row in rows[1:]] == [
        ["ada", files[0], "pass", "100.0"], ["bo", files[1], "fail", "50.0"],
        ["cy", files[2], "error", "0.0"]]
    assert len(json.loads((tmp_path / "class.json").read_text())) == 3


def test_bad_options_are_one_line_and_exit_2(tmp_path, capsys):
    with pytest.raises(SystemExit) as stop:
        main([str(SUBMISSIONS / "correct.py"), "--points", "get_g99=5"])
    assert stop.value.code == 2
    assert "unknown test 'get_g99'" in capsys.readouterr().err
    assert main([str(SUBMISSIONS / "correct.py"), "--json", str(tmp_path)]) == 2


def test_the_console_script_exits_0_for_a_correct_module():
    done = subprocess.run([sys.executable, "-m", "so101_kinematics.checker",
                           str(SUBMISSIONS / "correct.py"), "--random", str(FEW)],
                          cwd=REPO, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert "Verdict: within the tolerance. Score 100/100." in done.stdout


def test_the_time_bound_holds_for_a_call_that_never_returns(tmp_path):
    module = tmp_path / "so101_forward_kinematics.py"
    module.write_text((SUBMISSIONS / "correct.py").read_text().replace(
        "    gw1 = get_gw1(position_dict", "    while True:\n        pass\n    gw1 = get_gw1("
        "position_dict"))
    start = time.perf_counter()
    check = check_file(module, timeout=2.0, count=FEW)
    assert time.perf_counter() - start < 2.0 + 3.0
    assert check["verdict"] == "error"
    assert "timed out after 2 s while calling get_forward_kinematics" in check["reason"]

"""so101-check-vision: the reference solution passes, each planted mistake is named.

One student file per mistake, written here from the reference (``TEMPLATE``) with one edit;
the checker calls each in its sandboxed child process with the inputs of five cameras looking
at the target tag in the simulator and compares the answers with the simulator's truth.
"""

from __future__ import annotations

import json
import re
from concurrent.futures import ThreadPoolExecutor

import pytest

from so101_kinematics.checker.vision_compare import MISTAKES
from so101_kinematics.commands import so101_command
from so101_kinematics.vision.vision_cases import vision_cases
from so101_kinematics.vision.vision_checker import check_vision_file, main, vision_report

pytestmark = pytest.mark.vision

TEMPLATE = '''import numpy as np
import cv2

TAG_SIZE = 0.040  # the black marker [m]
FLIP = np.diag([1.0, -1.0, -1.0])  # OpenCV's camera frame in MuJoCo's
CORNERS = [[-1, 1], [1, 1], [1, -1], [-1, -1]]  # TL, TR, BR, BL (cv2.aruco's order)


def rotation(cam_xmat):
    return np.asarray(cam_xmat, dtype=float).reshape(3, 3) @ FLIP


def camera_to_base(cam_pos, cam_xmat, p_cam):
    return rotation(cam_xmat) @ np.asarray(p_cam) + np.asarray(cam_pos)


def tag_pose_in_base(corners, K, cam_pos, cam_xmat):
    obj = np.array([[x * TAG_SIZE / 2, y * TAG_SIZE / 2, 0.0] for x, y in CORNERS])
    ok, rvec, tvec = cv2.solvePnP(obj, np.asarray(corners, dtype=float),
                                  np.asarray(K, dtype=float), None,
                                  flags=cv2.SOLVEPNP_IPPE_SQUARE)
    g = np.eye(4)
    g[:3, :3] = rotation(cam_xmat) @ cv2.Rodrigues(rvec)[0]
    g[:3, 3] = camera_to_base(cam_pos, cam_xmat, tvec.ravel())
    return g
'''
TO_BASE = "return rotation(cam_xmat) @ np.asarray(p_cam) + np.asarray(cam_pos)"
PLANTED = {
    "correct": ([], set(), set()),
    "axes": ([("FLIP = np.diag([1.0, -1.0, -1.0])", "FLIP = np.eye(3)")], {"axes"}, {"axes"}),
    "transposed": ([("reshape(3, 3) @ FLIP", "reshape(3, 3).T @ FLIP")], {"transposed"},
                   {"transposed"}),
    "inverse": ([(TO_BASE, "return rotation(cam_xmat).T @ (np.asarray(p_cam) - "
                           "np.asarray(cam_pos))")], {"inverse"}, {"inverse"}),
    "millimetres": ([(TO_BASE, "return 1000 * (" + TO_BASE[7:] + ")")], {"mm"}, {"mm"}),
    "size_mm": ([("TAG_SIZE = 0.040", "TAG_SIZE = 40")], set(), {"size_mm"}),
    "size_face": ([("TAG_SIZE = 0.040", "TAG_SIZE = 0.052")], set(), {"size_face"}),
    "pixels": ([("g[:3, 3] = camera_to_base(cam_pos, cam_xmat, tvec.ravel())",
                 "g[:3, 3] = [*np.mean(corners, axis=0), 0.0]")], set(), {"pixels"}),
    "corner_order": ([("[[-1, 1], [1, 1], [1, -1], [-1, -1]]",
                       "[[1, 1], [1, -1], [-1, -1], [-1, 1]]"),
                      ("cv2.SOLVEPNP_IPPE_SQUARE", "cv2.SOLVEPNP_IPPE")],
                     set(), {"corner_order"}),
}
"""File name -> (edits of the reference, the mistakes named: camera_to_base, tag_pose_in_base)."""


@pytest.fixture(scope="module")
def checks(tmp_path_factory):
    folder = tmp_path_factory.mktemp("submissions")
    for name, (edits, _, _) in PLANTED.items():
        source = TEMPLATE
        for old, new in edits:
            assert old in source, (name, old)
            source = source.replace(old, new)
        (folder / f"{name}.py").write_text(source)
    vision_cases()  # rendered once, in this thread
    with ThreadPoolExecutor(2) as pool:
        return dict(zip(PLANTED, pool.map(lambda n: check_vision_file(folder / f"{n}.py"),
                                          PLANTED), strict=True))


def named(test: dict) -> set[str]:
    return {name for name, text in MISTAKES.items() if text in test["causes"]}


def test_the_reference_solution_passes(checks):
    check = checks["correct"]
    assert check["verdict"] == "pass", vision_report(check)
    camera, tag = check["tests"]
    assert camera["max_error_mm"] < 1e-6  # a transform is exact
    assert tag["max_error_mm"] < 2.0 and tag["max_error_deg"] < 2.0  # the 2 mm, 1-2 deg
    assert vision_report(check).endswith("Score 100/100.")


@pytest.mark.parametrize("name", [n for n in PLANTED if n != "correct"])
def test_each_planted_mistake_is_named(checks, name):
    check = checks[name]
    assert check["verdict"] == "fail", vision_report(check)
    camera, tag = check["tests"]
    _, for_camera, for_tag = PLANTED[name]
    assert named(camera) == for_camera, vision_report(check)
    assert camera["status"] == ("ok" if not for_camera else "wrong")
    assert named(tag) == for_tag, vision_report(check)
    assert tag["status"] == "wrong"


def test_a_file_without_the_functions_is_not_checked(tmp_path):
    other = tmp_path / "other.py"
    other.write_text("def camera_to_bass(a, b, c):\n    return c\n")
    check = check_vision_file(other)
    assert check["verdict"] == "error"
    assert re.search(r"neither camera_to_base nor tag_pose_in_base", check["reason"])


def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys):
    with pytest.raises(SystemExit) as stop:
        main(["--tolerance-mm", "-1", str(tmp_path / "x.py")])
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--tolerance-mm" in err[0] and "Fix:" in err[0]
    missing = str(tmp_path / "my_vision.py")
    assert so101_command.main(["check-vision", missing]) == 2
    assert "no such file" in capsys.readouterr().out


def test_the_json_report_is_written(checks, tmp_path, capsys):
    out = tmp_path / "full.json"
    student = tmp_path / "correct.py"
    student.write_text(TEMPLATE)
    gradescope = tmp_path / "gs.json"
    assert main([str(student), "--json", str(out), "--gradescope", str(gradescope)]) == 0
    report = json.loads(out.read_text())
    assert report["verdict"] == "pass" and "so101-check-vision" in report["generator"]
    assert json.loads(gradescope.read_text())["score"] == 100.0


def test_an_error_in_the_students_code_is_reported_not_raised(tmp_path):
    broken = tmp_path / "broken.py"
    broken.write_text(TEMPLATE.replace(TO_BASE, "return p_cam / 0 + undefined_name"))
    check = check_vision_file(broken)
    camera, tag = check["tests"]
    assert check["verdict"] == "fail" and camera["status"] == tag["status"] == "wrong"
    assert "NameError" in camera["causes"][0] and "line" in camera["causes"][0]

"""calibrate_camera.py: the JSON a TA reads, bad input in one line, the board not in view."""

from __future__ import annotations

import json

import pytest

import calibrate_camera
from so101_kinematics.vision import calibration_grades

pytestmark = pytest.mark.vision


def test_the_json_has_the_issues_keys(tmp_path, capsys):
    path = tmp_path / "calibration.json"
    assert calibrate_camera.main(["--headless", "--json", str(path), "--views", "5",
                                  "--seed", "1", "--strict"]) == 0
    report = json.loads(path.read_text())
    assert report["generator"].endswith("calibrate_camera.py")
    for key in ("fx_error_pct", "fy_error_pct"):
        assert isinstance(report["intrinsics"][key], float)
    for camera in ("wrist", "fixed"):
        assert set(report["hand_eye"][camera]) >= {"translation_mm", "rotation_deg"}
    assert "meets the acceptance" in capsys.readouterr().out
    # a second run replaces its own report, never another file
    assert calibrate_camera.main(["--json", str(path), "--views", "4"]) == 0
    other = tmp_path / "notes.json"
    other.write_text("{}")
    assert calibrate_camera.main(["--json", str(other)]) == 2
    assert other.read_text() == "{}"


@pytest.mark.parametrize("argv", [["--views", "2"], ["--views", "many"], ["--seed", "-1"]])
def test_bad_input_is_one_line_and_exit_2(argv, capsys):
    assert calibrate_camera.main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Fix:" in err


def test_a_board_never_in_view_is_one_line(monkeypatch, capsys):
    monkeypatch.setattr(calibration_grades, "take_view", lambda *args: None)
    assert calibrate_camera.main(["--views", "4"]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "ChArUco board" in err and "0 of the overhead camera's 4 views" in err

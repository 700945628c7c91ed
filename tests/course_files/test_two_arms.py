"""two_arms.py: the TA's command, its report and picture, and the one-line refusals (exit 2)."""

from __future__ import annotations

import json

import pytest

import two_arms
from so101_kinematics.markers import png_ours


def _refused(capsys, *argv) -> str:
    assert two_arms.main(list(argv)) == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert "Fix:" in lines[0]
    return lines[0]


def test_an_unknown_game_is_refused(capsys):
    assert "invalid choice: 'checkers'" in _refused(capsys, "--game", "checkers", "--headless")


def test_chess_out_of_reach_is_refused(capsys):
    line = _refused(capsys, "--game", "chess", "--spacing", "0.5", "--headless")
    assert "out of the left arm's reach" in line and "--spacing 0.632" in line


def test_chess_on_arms_side_by_side_is_refused(capsys):
    assert "arms facing each other" in _refused(capsys, "--game", "chess", "--layout", "side")


def test_a_base_error_beyond_its_range_is_refused(capsys):
    assert "--base-error" in _refused(capsys, "--game", "chess", "--base-error", "30", "0")


def test_bases_that_overlap_are_refused(capsys):
    assert "they overlap" in _refused(capsys, "--spacing", "0.1", "--headless")


def test_a_board_out_of_reach_is_refused(capsys):
    assert "out of the left arm's reach" in _refused(capsys, "--board-at", "0.3", "0.3")


def test_one_port_for_both_arms_is_refused(capsys):
    assert "one port for both arms" in _refused(capsys, "--ports", "/dev/pts/7", "/dev/pts/7")


def test_the_simulators_video_on_the_arms_is_refused(capsys, tmp_path):
    # --ports plays on the arms (tests/virtual/test_virtual_two_arms.py): nothing to film
    line = _refused(capsys, "--ports", "/dev/pts/7", "/dev/pts/8", "--video",
                    str(tmp_path / "game.mp4"))
    assert "no simulation to film" in line


def test_the_arms_calibration_without_the_arms_is_refused(capsys):
    assert "--calibration is the arms'" in _refused(capsys, "--calibration", "a.json", "b.json")


def test_one_file_for_two_outputs_is_refused(capsys, tmp_path):
    path = str(tmp_path / "out.mp4")
    assert "name the same file" in _refused(capsys, "--json", path, "--video", path)


@pytest.mark.slow
def test_the_tas_command_writes_the_report_and_the_picture(capsys, tmp_path):
    report_path, image = tmp_path / "two_arms.json", tmp_path / "two_arms.png"
    assert two_arms.main(["--game", "tictactoe", "--headless", "--json", str(report_path),
                          "--image", str(image)]) == 0
    report = json.loads(report_path.read_text())
    assert report["completed"] is True and report["collisions"] == 0
    assert len(report["moves"]) == 9
    assert all(isinstance(m["piece_error_mm"], float) for m in report["moves"])
    assert png_ours(image)
    assert "9 moves, completed (draw)" in capsys.readouterr().out


@pytest.mark.slow
def test_the_chess_command_writes_the_issues_report(capsys, tmp_path):
    """Issue 38's acceptance: completed, collisions, moves with piece_error_mm (and san)."""
    report_path = tmp_path / "chess.json"
    assert two_arms.main(["--game", "chess", "--headless", "--json", str(report_path)]) == 0
    report = json.loads(report_path.read_text())
    assert report["completed"] is True and report["collisions"] == 0
    assert len(report["moves"]) == 6 and report["pieces"] == 32
    assert all(isinstance(m["piece_error_mm"], float) and m["piece_error_mm"] <= 5.0
               for m in report["moves"])
    assert [m["san"] for m in report["moves"]] == ["e3", "e6", "Bd3", "Bd6", "c3", "c6"]
    out = capsys.readouterr().out
    assert out.count("touched points, residual") == 2 and "6 plies" in out


def test_registration_options_on_the_arms_are_refused(capsys):
    line = _refused(capsys, "--ports", "/dev/pts/7", "/dev/pts/8", "--register", "touch")
    assert "--register touch: with --ports the plan trusts the bases" in line


def test_a_base_error_side_by_side_is_refused(capsys):
    line = _refused(capsys, "--layout", "side", "--base-error", "3", "1")
    assert "--base-error 3 1: with --layout side" in line and "--layout facing" in line

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
    assert "game 'checkers'" in _refused(capsys, "--game", "checkers", "--headless")


def test_chess_is_refused_as_not_built(capsys):
    assert "chess is not built yet" in _refused(capsys, "--game", "chess", "--headless")


def test_bases_that_overlap_are_refused(capsys):
    assert "they overlap" in _refused(capsys, "--spacing", "0.1", "--headless")


def test_a_board_out_of_reach_is_refused(capsys):
    assert "out of the left arm's reach" in _refused(capsys, "--board-at", "0.3", "0.3")


def test_one_port_for_both_arms_is_refused(capsys):
    assert "one port for both arms" in _refused(capsys, "--ports", "/dev/pts/7", "/dev/pts/7")


def test_two_ports_are_refused_as_not_built(capsys):
    assert "not built yet" in _refused(capsys, "--ports", "/dev/pts/7", "/dev/pts/8")


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

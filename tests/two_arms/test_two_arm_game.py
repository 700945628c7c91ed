"""The game: refused before anything moves when it cannot be played; played and judged."""

from __future__ import annotations

import pytest

from so101_kinematics.errors import PlanError
from so101_kinematics.two_arms.game_board import (
    LAYOUT_BOARDS,
    PLACE_TOLERANCE_MM,
    GameBoard,
    game_pieces,
)
from so101_kinematics.two_arms.two_arm_game import (
    board_zone,
    check_board_reach,
    park_pose,
    run_game,
)
from so101_kinematics.two_arms.two_arm_scene import arm_bases

BASES = arm_bases("facing", 0.46)


def test_an_unknown_game_is_refused_in_one_line():
    with pytest.raises(PlanError) as error:
        run_game(BASES, GameBoard(), "chess")
    assert "\n" not in str(error.value) and "chess is not built yet" in str(error.value)
    assert "Fix: --game tictactoe" in str(error.value)


def test_a_board_out_of_either_arms_reach_is_refused_in_one_line():
    far = GameBoard((0.0, 0.30))  # its far row 0.36 m to the side of both arms
    with pytest.raises(PlanError) as error:
        check_board_reach(BASES, far, game_pieces(BASES))
    message = str(error.value)
    assert "\n" not in message and "out of the left arm's reach" in message and "Fix:" in message


@pytest.mark.parametrize("layout", ["facing", "side"])
def test_each_layouts_board_is_in_both_arms_reach(layout):
    bases = arm_bases(layout)
    check_board_reach(bases, LAYOUT_BOARDS[layout], game_pieces(bases))


def test_the_board_area_is_the_board_widened_by_the_margin():
    assert board_zone(GameBoard((0.0, 0.0), 0.055)) == pytest.approx(
        (-0.1125, 0.1125, -0.1125, 0.1125))  # 1.5 pitches + 30 mm


def test_each_arm_parks_towards_its_own_side():
    left, right = arm_bases("side", 0.46)
    assert park_pose(left)["shoulder_pan"] == -park_pose(right)["shoulder_pan"] == -90.0


@pytest.mark.slow
@pytest.mark.parametrize("layout", ["facing", "side"])
def test_a_whole_game_in_the_simulator_meets_the_issues_acceptance(layout):
    """Issue 38: a full game, every piece within 5 mm of its square, no collision."""
    report = run_game(arm_bases(layout), LAYOUT_BOARDS[layout])
    assert report["completed"] and report["collisions"] == 0
    moves = report["moves"]
    assert len(moves) == 9 and [m["arm"] for m in moves] == ["left", "right"] * 4 + ["left"]
    assert all(m["piece_error_mm"] <= PLACE_TOLERANCE_MM for m in moves)
    assert all(m["board_as_read_matches"] and m["tilt_deg"] < 5.0 for m in moves)
    assert moves[-1]["board_read"].count("X") == 5 and moves[-1]["board_read"].count("O") == 4
    assert report["winner"] == "draw"

"""The game: refused before anything moves when it cannot be played; played and judged."""

from __future__ import annotations

import math

import pytest

from so101_kinematics.errors import PlanError
from so101_kinematics.two_arms.board_registration import check_touch_reach
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
        run_game(BASES, GameBoard(), "checkers")
    assert "\n" not in str(error.value) and "'checkers' is not played here" in str(error.value)
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
    """Issue 38: a full game, every piece within 5 mm of its square, no collision (facing:
    registered by touch, the bases 3 mm and 1 deg off, the default; side by side: the nominal
    bases, exact, as ``two_arms.py --layout side`` plays)."""
    options = {} if layout == "facing" else {"register": "nominal", "base_error": (0.0, 0.0)}
    report = run_game(arm_bases(layout), LAYOUT_BOARDS[layout], **options)
    assert report["completed"] and report["collisions"] == 0
    moves = report["moves"]
    assert len(moves) == 9 and [m["arm"] for m in moves] == ["left", "right"] * 4 + ["left"]
    assert all(m["piece_error_mm"] <= PLACE_TOLERANCE_MM for m in moves)
    assert all(m["board_as_read_matches"] and m["tilt_deg"] < 5.0 for m in moves)
    assert moves[-1]["board_read"].count("X") == 5 and moves[-1]["board_read"].count("O") == 4
    assert report["winner"] == "draw"


def test_an_unknown_registration_is_refused_in_one_line():
    with pytest.raises(PlanError, match="Fix: --register touch") as error:
        run_game(BASES, GameBoard(), register="guess")
    assert "\n" not in str(error.value)


def test_a_registration_mark_out_of_reach_is_refused_in_one_line():
    far = [(0.0, 0.45, 0.0)]  # 0.51 m from each pan axis, beyond the arm's 0.27 m
    with pytest.raises(PlanError) as error:
        check_touch_reach(BASES, (far, far), (["square 1"], ["square 1"]), "Fix: nearer.")
    message = str(error.value)
    assert "\n" not in message and "left arm cannot touch its registration mark square 1" in message


@pytest.mark.slow
def test_the_game_registered_by_touch_recovers_the_bases_3_mm_and_1_deg_off():
    """Issue 38: each arm registers the board from its four touches, then the game completes,
    every piece within 5 mm, no collision. The fit recovers the true bases (3 mm towards their
    own side, 1 deg turned) within 1 mm and 0.2 deg (measured: 0.17 and 0.47 mm, 0.02 and
    0.12 deg) and the residual is under 1 mm RMS (measured 0.21 and 0.08 mm)."""
    report = run_game(BASES, LAYOUT_BOARDS["facing"], register="touch", base_error=(3.0, 1.0))
    assert report["completed"] and report["collisions"] == 0 and report["register"] == "touch"
    assert all(m["piece_error_mm"] <= PLACE_TOLERANCE_MM for m in report["moves"])
    assert [r["arm"] for r in report["registration"]] == ["left", "right"]
    for registration, true, nominal in zip(report["registration"], report["bases"],
                                           report["nominal_bases"], strict=True):
        assert len(registration["residuals_mm"]) == 4 and registration["rms_mm"] < 1.0
        fitted = registration["base"]
        assert math.dist((fitted["x"], fitted["y"]), (true["x"], true["y"])) < 0.001
        assert abs((fitted["yaw"] - true["yaw"] + 180.0) % 360.0 - 180.0) < 0.2
        # the true base is 3 mm and 1 deg from the nominal (the error the fit takes out)
        assert math.dist((true["x"], true["y"]), (nominal["x"], nominal["y"])) == \
            pytest.approx(0.003)
        assert abs((true["yaw"] - nominal["yaw"] + 180.0) % 360.0 - 180.0) == pytest.approx(1.0)


@pytest.mark.slow
def test_the_nominal_bases_3_mm_and_1_deg_off_miss_the_squares():
    """Unregistered, the same error puts pieces beyond 5 mm (measured 10.0 mm worst, five of
    nine moves): the game is not completed."""
    report = run_game(BASES, LAYOUT_BOARDS["facing"], register="nominal", base_error=(3.0, 1.0))
    assert report["registration"] == [] and not report["completed"]
    assert max(m["piece_error_mm"] for m in report["moves"]) > PLACE_TOLERANCE_MM

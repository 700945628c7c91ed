"""Tic-tac-toe's rules and its perfect player."""

from __future__ import annotations

import pytest

from so101_kinematics.two_arms.tictactoe import EMPTY, best_move, full_game, winner


def _board(text: str) -> tuple[str, ...]:
    """A board from nine characters, row by row ("." empty)."""
    return tuple("" if c == "." else c for c in text)


@pytest.mark.parametrize(("text", "expected"), [
    ("XXX" "OO." "...", "X"),      # a row
    ("XO." "XO." ".O.", "O"),      # a column
    ("X.O" ".XO" "..X", "X"),      # a diagonal
    ("..O" ".O." "O.X", "O"),      # the other diagonal
    ("XOX" "XOO" "OXX", ""),       # a full board, no line: a draw
    (".........", ""),
])
def test_a_line_of_three_wins(text, expected):
    assert winner(_board(text)) == expected


def test_the_player_to_move_completes_its_own_line_before_blocking():
    # X to move (two X, two O): X's top row and O's middle row are both open
    assert best_move(_board("XX." "OO." "...")) == 2


def test_the_player_blocks_a_line_it_cannot_beat():
    # O to move: X threatens the top row
    assert best_move(_board("XX." ".O." "...")) == 2


@pytest.mark.parametrize("opening", range(9))
def test_two_perfect_players_draw_in_nine_moves_from_every_opening(opening):
    moves = full_game(opening)
    assert len(moves) == 9
    assert [mark for mark, _ in moves] == ["X", "O"] * 4 + ["X"]
    assert sorted(square for _, square in moves) == list(range(9))
    assert moves[0] == ("X", opening)
    board = list(EMPTY)
    for mark, square in moves:
        board[square] = mark
    assert winner(tuple(board)) == ""

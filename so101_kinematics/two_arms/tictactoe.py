"""Tic-tac-toe: the board's nine squares, the winner, and a perfect player (minimax).

Squares are numbered 0-8 row by row; a board is a tuple of nine marks, "X", "O" or ""
(empty). X moves first. Two perfect players always draw: nine moves.
"""

from __future__ import annotations

from functools import cache

__all__ = ["EMPTY", "LINES", "best_move", "full_game", "winner"]

EMPTY = ("",) * 9
LINES = ((0, 1, 2), (3, 4, 5), (6, 7, 8), (0, 3, 6), (1, 4, 7), (2, 5, 8), (0, 4, 8), (2, 4, 6))
"""The eight lines of three: rows, columns, diagonals."""


def winner(board: tuple[str, ...]) -> str:
    """"X" or "O" if that player has a line of three, else "".

    Example:
        >>> winner(("X", "X", "X", "O", "O", "", "", "", ""))
        'X'
    """
    for a, b, c in LINES:
        if board[a] and board[a] == board[b] == board[c]:
            return board[a]
    return ""


def _to_move(board: tuple[str, ...]) -> str:
    return "X" if board.count("X") == board.count("O") else "O"


@cache
def _score(board: tuple[str, ...]) -> int:
    """The game's value for X with perfect play from ``board`` (+1 win, 0 draw, -1 loss)."""
    won = winner(board)
    if won:
        return 1 if won == "X" else -1
    if "" not in board:
        return 0
    player = _to_move(board)
    scores = [_score(board[:i] + (player,) + board[i + 1:]) for i in range(9) if not board[i]]
    return max(scores) if player == "X" else min(scores)


def best_move(board: tuple[str, ...]) -> int:
    """The square a perfect player takes (the lowest-numbered of the best).

    Example:
        >>> best_move(("X", "X", "", "O", "O", "", "", "", ""))  # X completes the top row
        2
    """
    player = _to_move(board)
    sign = 1 if player == "X" else -1
    moves = [i for i in range(9) if not board[i]]
    return max(moves, key=lambda i: (sign * _score(board[:i] + (player,) + board[i + 1:]), -i))


def full_game(opening: int = 4) -> list[tuple[str, int]]:
    """A whole game between two perfect players, X opening on ``opening``: (mark, square)s.

    Example:
        >>> game = full_game()
        >>> len(game), game[0]
        (9, ('X', 4))
    """
    board, moves = EMPTY, []
    while not winner(board) and "" in board:
        square = opening if not moves else best_move(board)
        player = _to_move(board)
        board = board[:square] + (player,) + board[square + 1:]
        moves.append((player, square))
    return moves

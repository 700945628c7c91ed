"""Chess for the two arms: the 8x8 board, the pieces on it, and a six-ply opening.

The board lies between the facing arms, its ranks along the world's x (rank 1 towards the
left arm, White; rank 8 towards the right arm, Black), its files along y (file a at +y:
White's left, seen from the left arm). Square ``index`` = 8 * rank + file (both from 0),
so ``a1`` is 0 and ``h8`` 63; a piece's centre on square (file f, rank r) is at
``centre + pitch * (r - 3.5, 3.5 - f)``.

The opening is 1.e3 e6 2.Bd3 Bd6 3.c3 c6 (:data:`OPENING`), six plies, no capture: each
arm moves only within its own half (White ranks 1-3, Black 6-8), the squares nearest its
base. Ruy Lopez (1.e4 e5 2.Nf3 Nc6 3.Bb5 a6) was not chosen: its Bb5 is 0.33 m from the
left pan axis, beyond the top-down plan's reach; 1.d4 d5 2.Nf3 Nf6 3.e3 e6 was tried at a
45 mm pitch and dropped: a knight on g1 or g8 lies 43 deg off its arm's forward, the jaws
turn across the rank, and the knight landed 4.3 to 5.6 mm off its square (the bishops here,
30 deg off, land within 2 mm at 52 mm).

The pieces are the course's 26 mm cubes (``sim/cube.py``: its mass, friction and ``condim``
3; the arm's elliptic friction cones, ``impratio`` 100, ``model/so101.xml``), white or
black: the 16 pawns, the knights and bishops, the queens and kings and rooks, all 32 in
the starting position; every one counts for "no other piece moved". A chess piece is
idealised as a cube: same footprint, no height or shape.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from so101_kinematics.constants import CUBE_HALF_SIZE
from so101_kinematics.errors import PlanError
from so101_kinematics.two_arms.game_board import GameBoard
from so101_kinematics.two_arms.two_arm_scene import Piece

__all__ = [
    "BACK_RANK", "CHESS_PITCH", "CHESS_SPACING", "FILES", "OPENING", "PIECE_COLOURS",
    "ChessBoard", "ChessMove", "check_opening", "chess_pieces", "move_text", "square_index",
    "square_name",
]

FILES = "abcdefgh"
BACK_RANK = "RNBQKBNR"
"""The pieces on rank 1 (White) and 8 (Black), file a to h."""
PIECE_COLOURS = {"w": (0.92, 0.90, 0.82, 1.0), "b": (0.18, 0.16, 0.15, 1.0)}
CHESS_PITCH = 0.052
"""[m] The squares' pitch (a 416 mm board), chosen from the reach and measured. The pieces are
26 mm cubes and the open jaws need 18 mm beside one (``game_board.MIN_PITCH``: 44 mm at
least). With the bases ``CHESS_SPACING`` apart, from the left pan axis (the right's mirror)
the opening's squares lie: e1 0.099 m (the nearest piece, not moved), f1 0.123, e2 0.149, c2
0.167, e3 and d3 0.201, c3 0.214 m, and the touch marks 0.238 (b3, g3) and 0.263 m (c4, f4);
every one passes the plan's reach check (``chess_game.check_chess_reach``; the top-down plan
solves to about 0.27 m, ``game_board``'s docstring). The far half is not in reach: a4 and h4
are 0.31 m off, so neither arm reaches every square; each reaches those it uses. Measured
with ``two_arms.py --game chess`` (registration by touch, the bases 3 mm and 1 deg off): at
45 mm the worst piece lands 4.45 mm from its square, 48 mm 5.96 (not completed), 50 mm
3.26, 52 mm 1.67, 55 mm 4.17 (not completed: a neighbour pushed), 58 mm 2.31 (not completed);
the pushes and offsets come from the jaws between packed pieces. At 52 mm the game completes
with the bases off by (0 mm, 0 deg), (3, 1), (3, -1), (-3, 1), (-3, -1) and (5, 2), the worst
piece 1.7 to 3.4 mm off; unregistered, 3 mm and 1 deg off, 13 mm."""
CHESS_SPACING = 0.632
"""[m] The bases' distance across the chess board: each pan axis (0.039 m in front of its
base's origin, ``ik.geometry.PAN_AXIS_POINT``) 0.095 m behind its first rank's centres
(0.632 / 2 - 0.039 - 3.5 * 0.052): rank 1 (8) is reached, rank 3's (6's) c3 at 0.214 m."""


@dataclass(frozen=True)
class ChessMove:
    """One ply: the side ("w" or "b"), the standard notation, the squares from and to."""

    side: str
    san: str
    start: str
    end: str


OPENING = (ChessMove("w", "e3", "e2", "e3"), ChessMove("b", "e6", "e7", "e6"),
           ChessMove("w", "Bd3", "f1", "d3"), ChessMove("b", "Bd6", "f8", "d6"),
           ChessMove("w", "c3", "c2", "c3"), ChessMove("b", "c6", "c7", "c6"))
"""1.e3 e6 2.Bd3 Bd6 3.c3 c6: a quiet symmetrical opening (Van 't Kruijs), six plies, no
capture."""


def move_text(moves=OPENING) -> str:
    """The moves as a score sheet writes them.

    Example:
        >>> move_text()
        '1.e3 e6 2.Bd3 Bd6 3.c3 c6'
    """
    return " ".join(f"{k // 2 + 1}.{mv.san}" if k % 2 == 0 else mv.san
                    for k, mv in enumerate(moves))


def square_index(name: str) -> int:
    """"e4" -> its index (8 * rank + file, both from 0).

    Example:
        >>> square_index("a1"), square_index("e4"), square_index("h8")
        (0, 28, 63)
    """
    if len(name) != 2 or name[0] not in FILES or name[1] not in "12345678":
        raise PlanError(f"square {name!r} is not a chess square. Fix: a file a-h and a rank "
                        "1-8, e.g. e4.")
    return 8 * (int(name[1]) - 1) + FILES.index(name[0])


def square_name(index: int) -> str:
    """An index -> its name: ``square_name(28)`` is "e4"."""
    rank, file = divmod(int(index), 8)
    return f"{FILES[file]}{rank + 1}"


@dataclass(frozen=True)
class ChessBoard(GameBoard):
    """The 8x8 board: its centre (x, y) [m] in the world and its pitch [m]."""

    pitch: float = CHESS_PITCH
    SQUARES: ClassVar[int] = 8

    def square(self, index: int) -> np.ndarray:
        """Where a piece's centre goes on square ``index`` (0-63): (x, y, z) [m] in the world.

        Example:
            >>> [round(float(v), 4) for v in ChessBoard((0.0, 0.0), 0.04).square(0)]  # a1
            [-0.14, 0.14, 0.013]
        """
        rank, file = divmod(int(index), 8)
        return np.array([self.centre[0] + self.pitch * (rank - 3.5),
                         self.centre[1] + self.pitch * (3.5 - file), CUBE_HALF_SIZE])


def chess_pieces(board: ChessBoard) -> tuple[Piece, ...]:
    """The 32 pieces on their starting squares: named ``w_Pd2``, ``b_Ng8``, ...

    Example:
        >>> pieces = chess_pieces(ChessBoard())
        >>> len(pieces), pieces[0].name, pieces[-1].name
        (32, 'w_Ra1', 'b_Ph7')
    """
    pieces = []
    for side, back, pawns in (("w", 0, 1), ("b", 7, 6)):
        for rank, kinds in ((back, BACK_RANK), (pawns, "P" * 8)):
            for file, kind in enumerate(kinds):
                index = 8 * rank + file
                x, y, _ = board.square(index)
                pieces.append(Piece(f"{side}_{kind}{square_name(index)}", float(x), float(y),
                                    PIECE_COLOURS[side]))
    white = [p for p in pieces if p.name[0] == "w"]
    return tuple(white + [p for p in pieces if p.name[0] == "b"])


_KNIGHT_STEPS = {(1, 2), (2, 1)}


def check_opening(moves=OPENING) -> None:
    """Check that each ply is legal from the starting position (hand-written, no engine).

    Only what the opening uses is known: sides alternate, White first; the piece on the
    start square is the mover's; the end square is empty (no capture); a pawn pushes one
    square forward, or two from its starting rank over an empty square; a knight jumps (1, 2);
    any other piece is refused (not needed).

    Raises:
        PlanError: the first illegal ply, in one line.
    """
    board = {p.name[2:][1:]: p.name[0] + p.name[2] for p in chess_pieces(ChessBoard())}
    for number, move in enumerate(moves):
        what = f"ply {number + 1} ({move.san}, {move.start}-{move.end})"
        side = "w" if number % 2 == 0 else "b"
        piece = board.get(move.start, "")
        problem = ""
        if move.side != side:
            problem = f"it is {side}'s turn"
        elif piece[:1] != side:
            problem = f"no {side} piece on {move.start}"
        elif move.end in board:
            problem = f"{move.end} is taken (a capture)"
        else:
            df = FILES.index(move.end[0]) - FILES.index(move.start[0])
            dr = (int(move.end[1]) - int(move.start[1])) * (1 if side == "w" else -1)
            if piece[1] == "P":
                between = f"{move.start[0]}{int(move.start[1]) + (1 if side == 'w' else -1)}"
                start_rank = "2" if side == "w" else "7"
                if not (df == 0 and (dr == 1 or (dr == 2 and move.start[1] == start_rank
                                                 and between not in board))):
                    problem = "a pawn moves one square forward (two from its first rank)"
            elif piece[1] == "N":
                if (abs(df), abs(dr)) not in _KNIGHT_STEPS:
                    problem = "a knight moves (1, 2) squares"
            elif piece[1] == "B":
                f0, r0 = FILES.index(move.start[0]), int(move.start[1])
                step_f, step_r = (df > 0) - (df < 0), (int(move.end[1]) > r0) - (
                    int(move.end[1]) < r0)
                path = [f"{FILES[f0 + k * step_f]}{r0 + k * step_r}" for k in range(1, abs(df))]
                if abs(df) != abs(dr) or df == 0:
                    problem = "a bishop moves diagonally"
                elif any(square in board for square in path):
                    problem = "a bishop does not jump"
            else:
                problem = f"a {piece[1]} move is not checked here"
        if problem:
            raise PlanError(f"{what} is not legal: {problem}. Fix: the opening "
                            "1.e3 e6 2.Bd3 Bd6 3.c3 c6.")
        board[move.end] = board.pop(move.start)


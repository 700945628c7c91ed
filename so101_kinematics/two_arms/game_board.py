"""The 3x3 board between the two arms, the pieces beside each arm, and the board read back.

The board lies on the table, square ``i`` (0-8, row by row) at ``centre + pitch * (col - 1,
1 - row)`` in the world (row 0 towards +y). Each arm's pieces wait on its own left-hand side
(``ArmBase.side``), on an arc about its pan axis. A piece is the course's 26 mm cube.

The pitch 55 mm (a 165 mm board) comes from the reach: the course's top-down plan with its
slide and lift solves from 0.12 to 0.27 m off the pan axis (``vision/see_and_pick.py``'s
``PICK_RADIUS``), and with the bases 0.46 m apart across the board the squares' centres lie
0.136 to 0.252 m from each pan axis (at 0.40 m the near squares are 0.11 m off, too near for
the lift); 55 mm leaves 29 mm between two pieces for the jaws (at 50 mm only a release
opening of 25 to 27 % neither pushed the next piece nor dragged the placed one,
``two_arm_game.RELEASE_OPENING``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import mujoco
import numpy as np

from so101_kinematics.constants import CUBE_HALF_SIZE, CUBE_SIZE
from so101_kinematics.errors import PlanError
from so101_kinematics.ik.geometry import PAN_AXIS_POINT
from so101_kinematics.two_arms.two_arm_scene import ArmBase, Piece, world_from_base

__all__ = [
    "DEFAULT_PITCH", "LAYOUT_BOARDS", "MARK_COLOURS", "MIN_PITCH", "PIECES", "PLACE_TOLERANCE_MM",
    "SUPPLY_BEARINGS",
    "SUPPLY_RADIUS",
    "TILT_TOLERANCE_DEG", "GameBoard", "MoveCheck", "board_of", "check_move", "game_pieces",
    "judge_move", "occupants", "piece_pose", "read_board",
]

DEFAULT_PITCH = 0.055
"""[m] The distance between two squares' centres (see the module's docstring): 50 mm
completed the game with the jaws released at 25 to 27 %, 55 mm from 25 to 30 %."""
MIN_PITCH = CUBE_SIZE + 0.018
"""[m] The least pitch: a 26 mm piece and 18 mm beside it for the open jaws."""
PIECES = {"X": 5, "O": 4}
"""How many pieces each mark has: X moves first, so at most five X and four O."""
MARK_COLOURS = {"X": (0.85, 0.25, 0.2, 1.0), "O": (0.25, 0.45, 0.85, 1.0)}
SUPPLY_RADIUS = 0.19
"""[m] The waiting pieces' distance from their arm's pan axis."""
SUPPLY_BEARINGS = (42.0, 58.0, 74.0, 90.0, 106.0)
"""[deg] Their bearings about the pan axis, from the arm's forward (+x) towards its side, in
the order they are played: 53 mm apart on one arc. The jaws close along the radius at a
top-down grasp, so no piece waits radially behind another (two rows 70 mm apart pushed the
piece behind 27 mm as the jaws closed; a row at a 45 mm pitch, 20 mm)."""
PLACE_TOLERANCE_MM = 5.0
"""[mm] A placed piece's centre from its square's centre, horizontally (issue 38)."""
TILT_TOLERANCE_DEG = 5.0
"""[deg] Upright: its up axis within this of the vertical."""
MOVED_MM = 3.0
"""[mm] Another piece farther than this from where it was has been moved."""


@dataclass(frozen=True)
class GameBoard:
    """The 3x3 board: its centre (x, y) [m] in the world and its pitch [m]."""

    centre: tuple[float, float] = (0.0, 0.0)
    pitch: float = DEFAULT_PITCH
    SQUARES: ClassVar[int] = 3
    """Squares along a side (``chess.ChessBoard``: 8)."""

    def square(self, index: int) -> np.ndarray:
        """Where a piece's centre goes on square ``index`` (0-8): (x, y, z) [m] in the world.

        Example:
            >>> [round(float(v), 3) for v in GameBoard((0.0, 0.0), 0.05).square(0)]
            [-0.05, 0.05, 0.013]
        """
        row, col = divmod(int(index), 3)
        return np.array([self.centre[0] + self.pitch * (col - 1),
                         self.centre[1] + self.pitch * (1 - row), CUBE_HALF_SIZE])

    def half_width(self) -> float:
        """[m] From the board's centre to its edge (the outer squares' far sides)."""
        return 0.5 * self.SQUARES * self.pitch

    def lines(self) -> tuple[tuple[float, float, float, float], ...]:
        """The board's grid as lines on the table: (x, y, half along x, half along y) [m]."""
        x, y, half, width = *self.centre, self.half_width(), 0.001
        cuts = [self.pitch * k - half for k in range(self.SQUARES + 1)]
        return (tuple((x + c, y, width, half) for c in cuts)
                + tuple((x, y + c, half, width) for c in cuts))

    def check(self) -> None:
        """Refuse a pitch too small for a piece and the open jaws between pieces.

        Raises:
            PlanError: one line with the pitch, the minimum and the fix.
        """
        if not MIN_PITCH <= self.pitch <= 0.2:
            raise PlanError(f"board pitch {self.pitch * 1e3:g} mm is outside [{MIN_PITCH * 1e3:g}, "
                            "200] mm (a 26 mm piece and 18 mm for the open jaws beside it). "
                            f"Fix: --pitch-mm {type(self)().pitch * 1e3:g}.")


LAYOUT_BOARDS = {"facing": GameBoard((0.0, 0.0), DEFAULT_PITCH),
                 "side": GameBoard((0.18, 0.0), 0.046)}
"""The board by default, per layout (``two_arm_scene.LAYOUTS``): between the facing arms at
55 mm; in front of the arms side by side at 46 mm (a 138 mm board 0.18 m ahead: at 50 mm its
far corner is out of reach; nearer, the carry brings the arms within 20 mm). Every opening
completes the game on both (``docs/final_project_two_arms.md``)."""


def game_pieces(bases: tuple[ArmBase, ArmBase]) -> tuple[Piece, ...]:
    """The pieces waiting beside the arms: X (the first arm's) then O (the second's)."""
    pieces = []
    for base, mark in zip(bases, PIECES, strict=True):
        for k in range(PIECES[mark]):
            bearing = math.radians(SUPPLY_BEARINGS[k])
            spot = (PAN_AXIS_POINT[0] + SUPPLY_RADIUS * math.cos(bearing),
                    PAN_AXIS_POINT[1] + base.side * SUPPLY_RADIUS * math.sin(bearing), 0.0)
            x, y, _ = world_from_base(base, spot)
            pieces.append(Piece(f"{mark.lower()}_{k + 1}", x, y, MARK_COLOURS[mark]))
    return tuple(pieces)


def piece_pose(d: mujoco.MjData, name: str) -> tuple[np.ndarray, float]:
    """A piece's centre [m] in the world and the tilt of its up axis from the vertical [deg]."""
    up = d.body(name).xmat.reshape(3, 3)[:, 2]
    return d.body(name).xpos.copy(), math.degrees(math.acos(min(1.0, max(-1.0, float(up[2])))))


def _mark_of(name: str) -> str:
    return name.split("_")[0].upper()


def read_board(m: mujoco.MjModel, d: mujoco.MjData, board: GameBoard,
               pieces: tuple[Piece, ...]) -> tuple[str, ...]:
    """The board as the simulation has it: each square's mark ("" empty), from the pieces' poses.

    A square holds the piece whose centre is within half a pitch of its centre, resting.
    """
    return board_of(board, {piece.name: piece_pose(d, piece.name)[0] for piece in pieces})


def occupants(board: GameBoard, centres) -> dict[int, str]:
    """Square index -> the piece on it, from the pieces' centres (name -> (x, y, z) [m], world).

    A square holds the piece whose centre is within half a pitch of its centre, resting (its
    centre within 5 mm of a resting piece's height): the simulation's poses, or an arm's cube
    sensor's readings (``lab/two_arms_arm.py``). Every board's rule (``chess_game.py``'s too).
    """
    held = {}
    for name, centre in centres.items():
        for index in range(board.SQUARES ** 2):
            target = board.square(index)
            if (math.dist(centre[:2], target[:2]) < 0.5 * board.pitch
                    and abs(centre[2] - target[2]) < 0.005):
                held[index] = name
    return held


def board_of(board: GameBoard, centres) -> tuple[str, ...]:
    """The board from the pieces' centres (as :func:`occupants`'): each square's mark ("" empty)."""
    held = occupants(board, centres)
    return tuple(_mark_of(held[index]) if index in held else ""
                 for index in range(board.SQUARES ** 2))


@dataclass
class MoveCheck:
    """One move's verdict: the piece on its square, upright, the others where they were."""

    mark: str
    square: int
    piece: str
    piece_error_mm: float
    tilt_deg: float
    others_moved_mm: float
    ok: bool

    def reason(self) -> str:
        """Why the move failed, in one line ("" when it passed)."""
        reasons = []
        if self.piece_error_mm > PLACE_TOLERANCE_MM:
            reasons.append(f"{self.piece} is {self.piece_error_mm:.1f} mm from square "
                           f"{self.square}'s centre (at most {PLACE_TOLERANCE_MM:g})")
        if self.tilt_deg > TILT_TOLERANCE_DEG:
            reasons.append(f"{self.piece} is tilted {self.tilt_deg:.1f} deg")
        if self.others_moved_mm > MOVED_MM:
            reasons.append(f"another piece moved {self.others_moved_mm:.1f} mm")
        return "; ".join(reasons)


def check_move(m: mujoco.MjModel, d: mujoco.MjData, board: GameBoard, pieces: tuple[Piece, ...],
               moved: str, square: int, before: dict[str, np.ndarray]) -> MoveCheck:
    """Judge a move from the simulation: ``moved`` on ``square``, the others as ``before``.

    Args:
        m: the model.
        d: the data, after the move.
        board: the board.
        pieces: every piece.
        moved: the piece the move carried.
        square: where it should be.
        before: each piece's centre [m] before the move.
    """
    after = {p.name: piece_pose(d, p.name) for p in pieces}
    return judge_move(board, moved, square, before, {name: pose[0] for name, pose in after.items()},
                      after[moved][1])


def judge_move(board: GameBoard, moved: str, square: int, before, after,
               tilt_deg: float) -> MoveCheck:
    """Judge a move from the pieces' centres before and after it (name -> (x, y, z) [m], world).

    ``tilt_deg``: the moved piece's up axis from the vertical. The simulation's poses
    (:func:`check_move`) or an arm's cube sensor's readings (``lab/two_arms_arm.py``).
    """
    error = 1e3 * math.dist(after[moved][:2], board.square(square)[:2])
    others = max((1e3 * math.dist(after[name], before[name])
                  for name in after if name != moved and name in before), default=0.0)
    ok = error <= PLACE_TOLERANCE_MM and tilt_deg <= TILT_TOLERANCE_DEG and others <= MOVED_MM
    return MoveCheck(_mark_of(moved), square, moved, round(error, 3), round(tilt_deg, 2),
                     round(others, 3), ok)

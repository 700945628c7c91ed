"""Chess by two simulated SO-101s: the board registered to each arm's base, six plies, judged.

:func:`run_chess` builds the two-arm scene with the 8x8 board and its 32 pieces
(``chess.py``), the bases where they truly stand: the nominal ones (``arm_bases("facing",
CHESS_SPACING)``) moved by a small known error (``board_registration.BASE_ERROR``), as a
real base is never set down exactly. Then, with ``register="touch"`` (the default), each arm
in turn registers the board to its base from touched points (``board_registration.py``, the
same as tic-tac-toe's): its four marks are :data:`TOUCH_MARKS`, squares of its own half.
``register="nominal"`` plans with the nominal bases.

The game is then ``chess.OPENING``, each ply planned as the tic-tac-toe's moves are
(``two_arm_game.plan_move``: the course's Cartesian pick-and-place in the moving arm's base
frame, the jaws released at ``RELEASE_OPENING``, then the park pose), every path checked by
the shared-workspace rule first, and judged from the simulation (``game_board.check_move``:
the piece within 5 mm of its square's centre, upright, no other of the 32 moved by 3 mm).
"""

from __future__ import annotations

import math
from dataclasses import asdict

import mujoco

from so101_kinematics.errors import PlanError
from so101_kinematics.sim import actuation
from so101_kinematics.two_arms.board_registration import (
    BASE_ERROR,
    Registration,
    check_register_option,
    check_touch_reach,
    displaced_bases,
    register_arms,
)
from so101_kinematics.two_arms.chess import (
    CHESS_SPACING,
    OPENING,
    ChessBoard,
    check_opening,
    chess_pieces,
    square_index,
    square_name,
)
from so101_kinematics.two_arms.game_board import check_move, occupants, piece_pose
from so101_kinematics.two_arms.scene_arm import SceneArm
from so101_kinematics.two_arms.shared_workspace import ArmDistanceWatch
from so101_kinematics.two_arms.two_arm_game import (
    PARK_DURATION,
    board_zone,
    move_steps,
    park_pose,
    piece_yaw,
    plan_move,
    play_filmed,
    run_moves,
)
from so101_kinematics.two_arms.two_arm_scene import (
    ArmBase,
    build_two_arm_model,
    check_bases,
)

__all__ = ["TOUCH_MARKS", "check_chess_reach", "run_chess"]

TOUCH_MARKS = {"w": ("b3", "g3", "f4", "c4"), "b": ("g6", "b6", "c5", "f5")}
"""The squares' centres each arm touches, in order: four of its own half that are empty at
the start, 260 mm across and 52 mm deep, 0.238 to 0.263 m from its pan axis."""


def check_chess_reach(bases: tuple[ArmBase, ArmBase], board: ChessBoard, moves=OPENING) -> None:
    """Refuse, before anything moves, a ply or a touch mark out of its arm's reach.

    Raises:
        PlanError: one line: the arm, the square, why, the fix.
    """
    fix = (f"Fix: the default board (--pitch-mm {board.__class__().pitch * 1e3:g}, centred "
           f"between the bases) and --spacing {CHESS_SPACING:g}.")
    for move in moves:
        base = bases[0] if move.side == "w" else bases[1]
        try:
            plan_move(base, board.square(square_index(move.start)),
                      board.square(square_index(move.end)), 0.0)
        except PlanError as error:
            reason = str(error).split(" (", 1)[-1].split(" Fix:")[0].rstrip(".)")
            raise PlanError(f"{move.san} ({move.start}-{move.end}) is out of the {base.name} "
                            f"arm's reach ({reason}). {fix}") from None
    check_touch_reach(bases, _touch_points(board), (TOUCH_MARKS["w"], TOUCH_MARKS["b"]), fix)


def _touch_points(board: ChessBoard) -> tuple[list, list]:
    """Each arm's marks in the world: the centres of its :data:`TOUCH_MARKS`' squares."""
    return tuple([board.square(square_index(mark)) for mark in TOUCH_MARKS[side]]
                 for side in "wb")


def _read_squares(d, board: ChessBoard, names) -> dict[str, str]:
    """The board as the simulation has it: square name -> piece, each piece at rest on one."""
    held = occupants(board, {name: piece_pose(d, name)[0] for name in names})
    return {square_name(index): name for index, name in held.items()}


def run_chess(bases: tuple[ArmBase, ArmBase], board: ChessBoard, servo: dict | None = None,
              video=None, image=None, register: str = "touch",
              base_error: tuple[float, float] = BASE_ERROR, moves=OPENING) -> dict:
    """Register the board, play ``moves`` in the simulator; the report (JSON-ready).

    Args:
        bases: the nominal bases (``arm_bases("facing", CHESS_SPACING)``); the left arm White.
        board: the board.
        servo: keywords of ``actuation.use_servo`` (default: the faithful STS3215).
        video: None, or a callable (m, d) -> a video recorder (``two_arm_game.run_game``).
        image: a PNG of the board at the end (or None).
        register: "touch" (each arm registers the board from touched points) or "nominal".
        base_error: (mm, deg) the true bases' error from the nominal (:data:`BASE_ERROR`).
        moves: the plies (``chess.OPENING``).

    Raises:
        PlanError: an illegal ply, bases that overlap, a board or a mark out of reach, a
            registration residual above the bound, a path that breaks the shared-workspace rule.
    """
    check_register_option(register)
    check_opening(moves)
    check_bases(bases)
    board.check()
    check_chess_reach(bases, board, moves)
    true_bases = displaced_bases(bases, *base_error)
    pieces = chess_pieces(board)
    m = build_two_arm_model(true_bases, pieces, servo, board.lines())
    d, scratch = mujoco.MjData(m), mujoco.MjData(m)
    arms = (SceneArm(m, true_bases[0]), SceneArm(m, true_bases[1]))
    for arm in arms:
        arm.set_initial_pose(d, park_pose(arm.base))
    report, registrations = play_filmed(m, d, arms, video, image, lambda watch: _register_and_play(
        m, d, scratch, arms, bases, board, pieces, moves, watch, register))
    return report | {
        "game": "chess", "register": register,
        "registration": [r.as_json() for r in registrations],
        "base_error": {"mm": base_error[0], "deg": base_error[1]},
        "bases": [asdict(b) for b in true_bases], "nominal_bases": [asdict(b) for b in bases],
        "board": asdict(board), "pieces": len(pieces), "servo": actuation.servo_spec(m).describe()}


def _register_and_play(m, d, scratch, arms, bases, board: ChessBoard, pieces, moves, watch,
                       register: str) -> tuple[dict, list[Registration]]:
    """Each arm registers the board (``register="touch"``), then the plies are played."""
    arms[0].hold_position(m, d, watch, 0.5)
    planned, registrations = register_arms(
        m, d, watch, arms, bases, _touch_points(board),
        [(park_pose(arm.base), PARK_DURATION) for arm in arms], register)
    return _play_chess(m, d, scratch, arms, planned, board, pieces, moves, watch), registrations


def _play_chess(m, d, scratch, arms, planned, board: ChessBoard, pieces, moves,
                watch: ArmDistanceWatch) -> dict:
    """The plies, each planned with the ``planned`` bases, checked, run and judged."""
    zone, report, least = board_zone(board), [], math.inf
    names = [p.name for p in pieces]
    expected = _read_squares(d, board, names)
    for move in moves:
        k = 0 if move.side == "w" else 1
        arm, other, base = arms[k], arms[1 - k], planned[k]
        piece = expected[move.start]
        before = {name: piece_pose(d, name)[0] for name in names}
        steps = move_steps(base, before[piece], board.square(square_index(move.end)),
                           piece_yaw(d, piece, base))
        what = f"{arm.name} arm: {move.san} ({move.start}-{move.end})"
        least = min(least, run_moves(m, d, watch, arm, other, steps, zone, what, scratch))
        expected[move.end] = expected.pop(move.start)
        verdict = check_move(m, d, board, pieces, piece, square_index(move.end), before)
        seen = _read_squares(d, board, names)
        shifts = {n: math.dist(piece_pose(d, n)[0], before[n]) for n in names if n != piece}
        offset = 1e3 * (piece_pose(d, piece)[0] - board.square(square_index(move.end)))[:2]
        report.append(asdict(verdict) | {"most_moved": max(shifts, key=shifts.get),
            "offset_mm": [round(float(v), 2) for v in offset],
            "arm": arm.name, "san": move.san, "from": move.start, "to": move.end,
            "board_as_read_matches": seen == expected, "reason": verdict.reason()})
    completed = all(mv["ok"] and mv["board_as_read_matches"] for mv in report)
    return {"completed": completed, "collisions": watch.collisions, "moves": report,
            "least_arm_distance_planned_mm": round(1e3 * least, 1),
            "least_arm_distance_run_mm": round(1e3 * watch.least_distance, 1),
            "simulated_s": round(d.time, 2)}

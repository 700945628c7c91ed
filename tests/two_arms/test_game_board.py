"""The board: its squares, the pieces beside each arm, the board read back, each move judged."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from so101_kinematics.errors import PlanError
from so101_kinematics.ik.geometry import PAN_AXIS_POINT
from so101_kinematics.two_arms.game_board import (
    PIECES,
    SUPPLY_RADIUS,
    GameBoard,
    check_move,
    game_pieces,
    read_board,
)
from so101_kinematics.two_arms.two_arm_scene import (
    arm_bases,
    base_from_world,
    build_two_arm_model,
)

BOARD = GameBoard((0.0, 0.0), 0.055)


def test_the_squares_run_row_by_row_from_the_top_left():
    # square 0: one pitch left (-x) and one up (+y) of the centre; 8: the opposite corner
    assert BOARD.square(0)[:2] == pytest.approx([-0.055, 0.055])
    assert BOARD.square(4)[:2] == pytest.approx([0.0, 0.0])
    assert BOARD.square(5)[:2] == pytest.approx([0.055, 0.0])
    assert BOARD.square(8)[:2] == pytest.approx([0.055, -0.055])
    assert BOARD.square(8)[2] == pytest.approx(0.013)  # a 26 mm piece resting on the table


def test_the_grid_lines_frame_the_squares():
    lines = BOARD.lines()
    assert len(lines) == 8
    assert sorted(x for x, _, hx, _ in lines if hx < 0.01) == pytest.approx(
        [-0.0825, -0.0275, 0.0275, 0.0825])


def test_a_pitch_without_room_for_the_jaws_is_refused_in_one_line():
    with pytest.raises(PlanError) as error:
        GameBoard((0.0, 0.0), 0.030).check()
    assert "\n" not in str(error.value) and "Fix: --pitch-mm 55" in str(error.value)


def test_each_arm_has_its_own_pieces_on_its_own_side_at_the_supply_radius():
    bases = arm_bases("facing", 0.46)
    pieces = game_pieces(bases)
    assert [p.name for p in pieces] == [f"x_{k}" for k in range(1, PIECES["X"] + 1)] + [
        f"o_{k}" for k in range(1, PIECES["O"] + 1)]
    for piece in pieces:
        base = bases[0] if piece.name.startswith("x") else bases[1]
        x, y, _ = base_from_world(base, (piece.x, piece.y, 0.0))
        assert math.hypot(x - PAN_AXIS_POINT[0], y - PAN_AXIS_POINT[1]) == pytest.approx(
            SUPPLY_RADIUS)
        assert y > 0.1  # beside the arm, off the board
    # the left arm's pieces on the world's +y, the right's on -y
    assert all((p.y > 0) == p.name.startswith("x") for p in pieces)


@pytest.fixture(scope="module")
def game_model():
    bases = arm_bases("facing", 0.46)
    pieces = game_pieces(bases)
    return build_two_arm_model(bases, pieces), pieces


def _put(d, name, xy, tilt_deg=0.0):
    """A piece resting at (x, y), tilted about x."""
    joint = d.model.joint(name)
    half = math.radians(tilt_deg) / 2
    d.qpos[joint.qposadr[0]:joint.qposadr[0] + 7] = [*xy, 0.013, math.cos(half), math.sin(half),
                                                     0.0, 0.0]


def test_the_board_is_read_from_the_pieces_poses(game_model):
    m, pieces = game_model
    d = mujoco.MjData(m)
    _put(d, "x_1", BOARD.square(4)[:2] + [0.004, 0.0])
    _put(d, "o_1", BOARD.square(0)[:2])
    _put(d, "x_2", BOARD.square(8)[:2] + [0.03, 0.0])  # more than half a pitch off: no square
    mujoco.mj_kinematics(m, d)
    assert read_board(m, d, BOARD, pieces) == ("O", "", "", "", "X", "", "", "", "")


def test_a_move_is_judged_by_the_piece_its_tilt_and_the_others(game_model):
    m, pieces = game_model
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    before = {p.name: d.body(p.name).xpos.copy() for p in pieces}
    _put(d, "x_1", BOARD.square(2)[:2] + [0.003, 0.004])  # 5.0 mm off
    mujoco.mj_kinematics(m, d)
    verdict = check_move(m, d, BOARD, pieces, "x_1", 2, before)
    assert verdict.piece_error_mm == pytest.approx(5.0)
    assert verdict.ok and verdict.reason() == ""
    _put(d, "x_1", BOARD.square(2)[:2] + [0.0, 0.0051], tilt_deg=6.0)
    _put(d, "o_2", np.array([pieces[6].x + 0.004, pieces[6].y]))
    mujoco.mj_kinematics(m, d)
    verdict = check_move(m, d, BOARD, pieces, "x_1", 2, before)
    assert not verdict.ok
    assert verdict.tilt_deg == pytest.approx(6.0)
    assert verdict.others_moved_mm == pytest.approx(4.0)
    assert "5.1 mm from square 2" in verdict.reason() and "tilted 6.0 deg" in verdict.reason()

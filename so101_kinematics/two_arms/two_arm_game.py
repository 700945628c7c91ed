"""A game of tic-tac-toe played by two simulated SO-101s: planned, checked, run and judged.

:func:`run_game` builds the two-arm scene (``two_arm_scene.py``) with the pieces beside
each arm (``game_board.py``), plays a whole game between two perfect players
(``tictactoe.py``): the left arm moves X, the right arm O. Each move is the course's
Cartesian pick-and-place (``planning/cartesian_plan.py``) in the moving arm's base frame,
then back to its park pose (the rest pose with the gripper turned up, turned a quarter
towards its own side: out of the board's area); every planned path passes the
shared-workspace rule (``shared_workspace.py``) before it runs. After each move the
simulation is read back: the piece on its square, upright, no other piece moved, and the
board as the game has it.
"""

from __future__ import annotations

import math
from dataclasses import asdict
from pathlib import Path

import mujoco

from so101_kinematics.constants import HOME_POSE
from so101_kinematics.errors import PlanError, UnreachableError
from so101_kinematics.frames import JOINT_LIMITS
from so101_kinematics.outputs import write_png_atomic
from so101_kinematics.planning.cartesian_plan import PRE_GRASP_SLIDE, cartesian_plan
from so101_kinematics.sim import actuation
from so101_kinematics.sim.render import QUALITY, FrameRenderer
from so101_kinematics.two_arms.board_registration import (
    BASE_ERROR,
    check_register_option,
    check_touch_reach,
    displaced_bases,
    register_arms,
)
from so101_kinematics.two_arms.game_board import (
    GameBoard,
    check_move,
    game_pieces,
    piece_pose,
    read_board,
)
from so101_kinematics.two_arms.scene_arm import SceneArm
from so101_kinematics.two_arms.shared_workspace import (
    ZONE_MARGIN,
    ArmDistanceWatch,
    check_shared_path,
)
from so101_kinematics.two_arms.tictactoe import EMPTY, full_game, winner
from so101_kinematics.two_arms.two_arm_scene import (
    GAME_CAMERA,
    LAYOUT_SPACING,
    ArmBase,
    base_from_world,
    build_two_arm_model,
    check_bases,
)

__all__ = [
    "GAMES", "MOVE_DURATION", "PARK_DURATION", "PARK_POSE", "SIDE_NOT_REGISTERED", "TOUCH_SQUARES",
    "board_zone", "check_board_reach", "move_steps", "park_pose", "piece_yaw", "plan_move",
    "play_filmed", "run_game", "run_moves", "save_frame",
]

GAMES = ("tictactoe", "chess")
"""The games ``two_arms.py --game`` plays: tic-tac-toe here, chess in ``chess_game.py``."""
PARK_POSE = dict(HOME_POSE, shoulder_pan=-90.0, wrist_flex=-90.0, gripper=0.0)
"""[deg] Where an arm waits while the other plays: the see-and-pick's look pose (the rest pose
``home`` with the gripper turned up) turned a quarter towards its own pieces (its base frame's
+y; -y: ``park_pose``), jaws closed: out of the board's area and away from the other arm.
(Not turned, the wrist's flip up from the board swept the jaws within 18 mm of the other
arm, bases 0.40 m apart.)"""
MOVE_DURATION = 1.5
"""[s] Each main move of a pick-and-place (the short ones near the piece take half)."""
HOLD_DURATION = 0.3
"""[s] The pause after each of the plan's key configurations."""
PARK_DURATION = 1.5
"""[s] The move back to the park pose."""
PARK_HOLD = 0.3
"""[s] The pause at the park pose after each move."""
RELEASE_OPENING = 25.0
"""[0, 100] The jaws' opening that lets a piece go on the board and backs off it. The plan's
50 pushed the piece on the next square (radially beyond, 50 mm pitch) 13-34 mm as the jaws
opened; 30 still 5-7 mm; 20 dragged the released piece 6 mm on the retreat."""
RELEASE_STEPS = ("final_open", "retreat", "depart")
TOUCH_SQUARES = (1, 5, 7, 3)
"""The squares whose centres each arm touches to register the board (``board_registration``),
in order: the four edges' middles, empty before the game, 110 mm apart across at the default
55 mm pitch. Not the corners: side by side, with the bases 3 mm and 1 deg off, the far corner
needs wrist_flex 95.2 deg from the left arm, beyond its 95 deg (measured)."""
SIDE_NOT_REGISTERED = ("with --layout side the bases are the nominal ones: the board's far corner "
                       "is at the arms' reach, 3 mm and 1 deg off put it beyond wrist_flex's "
                       f"{JOINT_LIMITS['wrist_flex'][1]:.0f} deg (measured). Fix: leave it out "
                       "(or --layout facing).")
"""Why ``two_arms.py --layout side`` refuses ``--register`` and ``--base-error``: measured, the
left arm's place on the far corner, 0.30 m from its base's origin, needs wrist_flex 95.3 deg
from its base 3 mm and 1 deg off (registered by touch; the touch reached every mark)."""
LIFT_HEIGHT = 0.06
"""[m] The lift and carry above the pieces (the course's 0.10 m is beyond the wrist's range
above the board's near squares: 0.15 m from the base at 0.11 m up needs wrist_flex 96 deg)."""


def park_pose(base: ArmBase) -> dict[str, float]:
    """:data:`PARK_POSE` on ``base``'s own side (``ArmBase.side``)."""
    return dict(PARK_POSE, shoulder_pan=base.side * PARK_POSE["shoulder_pan"])


def board_zone(board: GameBoard) -> tuple[float, float, float, float]:
    """The board's area: (x_low, x_high, y_low, y_high) [m] in the world, with the margin."""
    half = board.half_width() + ZONE_MARGIN
    x, y = board.centre
    return (x - half, x + half, y - half, y + half)


def piece_yaw(d: mujoco.MjData, name: str, base: ArmBase) -> float:
    """A piece's yaw [deg] in ``base``'s frame, folded into [-45, 45) (a cube every 90 deg)."""
    rotation = d.body(name).xmat.reshape(3, 3)
    yaw = math.degrees(math.atan2(rotation[1, 0], rotation[0, 0])) - base.yaw
    return (yaw + 45.0) % 90.0 - 45.0


def plan_move(base: ArmBase, pick_world, place_world, yaw: float,
              slide: float = PRE_GRASP_SLIDE):
    """The pick-and-place in ``base``'s frame; a point out of reach refused in one line.

    ``slide``: the plan's pre-grasp slide [m] (``cartesian_plan``'s; the chess board's packed
    squares take a shorter one).
    """
    try:
        return cartesian_plan(base_from_world(base, pick_world), base_from_world(base, place_world),
                              cube_yaw_deg=yaw, lift_height=LIFT_HEIGHT,
                              move_duration=MOVE_DURATION,
                              hold_duration=HOLD_DURATION, slide=slide)
    except UnreachableError as error:
        reason = str(error).split(" Fix:")[0].rstrip(".")
        spacing = LAYOUT_SPACING["facing"]
        raise PlanError(f"the board or the pieces are out of the {base.name} arm's reach "
                        f"({reason}). Fix: put the board between the arms (--layout facing, "
                        f"--spacing {spacing:g}) or a smaller --pitch-mm.") from None


def _released(name: str, cfg: dict[str, float]) -> dict[str, float]:
    """The place's steps with the jaws opened to :data:`RELEASE_OPENING`; the others as given."""
    return dict(cfg, gripper=RELEASE_OPENING) if name in RELEASE_STEPS else cfg


def move_steps(base: ArmBase, pick_world, place_world, yaw: float,
               slide: float = PRE_GRASP_SLIDE) -> list[tuple[str, dict[str, float], float, float]]:
    """One move as every game runs it: (name, configuration, duration [s], hold [s]) per step.

    The pick-and-place planned in ``base``'s frame (:func:`plan_move`), the jaws released to
    :data:`RELEASE_OPENING` where they let go, then back to the park pose (:func:`park_pose`).
    """
    plan = plan_move(base, pick_world, place_world, yaw, slide)
    steps = [(s.name, _released(s.name, s.configuration), s.duration, s.hold)
             for s in plan.steps]
    return steps + [("park", park_pose(base), PARK_DURATION, PARK_HOLD)]


def check_board_reach(bases, board: GameBoard, pieces) -> None:
    """Refuse a board or pieces out of either arm's reach, before anything moves.

    Every square from each arm's first piece, and each arm's every piece to the centre square.
    """
    for base, mark in zip(bases, ("x", "o"), strict=True):
        own = [p for p in pieces if p.name.startswith(mark)]
        for square in range(9):
            plan_move(base, (own[0].x, own[0].y, board.square(0)[2]), board.square(square), 0.0)
        for piece in own[1:]:
            plan_move(base, (piece.x, piece.y, board.square(0)[2]), board.square(4), 0.0)


def run_moves(m, d, viewer, arm: SceneArm, other: SceneArm, steps, zone, what: str,
               scratch: mujoco.MjData) -> float:
    """Check each move's path, then run it; the least arm distance planned [m]."""
    least = math.inf
    for name, cfg, duration, hold in steps:
        rows = arm.path(m, d, cfg, duration)
        other_goals = d.ctrl[other.actuators].copy()
        least = min(least, check_shared_path(m, scratch, arm, other, rows, other_goals, zone,
                                             f"{what} ({name})"))
        arm.move_to_pose(m, d, viewer, cfg, duration)
        if hold:
            arm.hold_position(m, d, viewer, hold)
    return least


def run_game(bases: tuple[ArmBase, ArmBase], board: GameBoard, game: str = "tictactoe",
             opening: int = 4, servo: dict | None = None, video=None,
             image: Path | None = None, register: str = "touch",
             base_error: tuple[float, float] = BASE_ERROR) -> dict:
    """Play a whole game in the simulator; the report (JSON-ready).

    Args:
        bases: the two arms' bases (``two_arm_scene.arm_bases``).
        board: the board.
        game: "tictactoe" (``GAMES``'s first; chess is ``chess_game.run_chess``).
        opening: X's first square (0-8).
        servo: keywords of ``actuation.use_servo`` (default: the faithful STS3215).
        video: None, or a callable (m, d) -> a video recorder (``sim/video.py``'s), closed
            here: complete after the game, discarded when it fails.
        image: a PNG of the board at the end, from the ``two_arms`` camera (or None).
        register: "touch" (each arm first registers the board from its touches of the
            :data:`TOUCH_SQUARES`' centres, ``board_registration.py``) or "nominal" (planned
            with ``bases``).
        base_error: (mm, deg) how far the true bases stand from ``bases``
            (``board_registration.BASE_ERROR``); the scene and the pieces are on the true ones.

    Returns:
        ``completed``, ``collisions``, ``moves`` (each with ``piece_error_mm``), the board,
        ``registration`` (per arm, empty when nominal), the true and the nominal bases.

    Raises:
        PlanError: an unknown game or registration, bases that overlap, a board or a mark out
            of reach, a registration residual above the bound, a path that breaks the
            shared-workspace rule (``ClearanceError``).
    """
    if game != GAMES[0]:
        raise PlanError(f"game {game!r} is not played here (one of {', '.join(GAMES)}: chess by "
                        "chess_game.run_chess). Fix: --game tictactoe.")
    check_register_option(register)
    check_bases(bases)
    board.check()
    check_board_reach(bases, board, game_pieces(bases))
    marks = [board.square(square) for square in TOUCH_SQUARES]
    if register == "touch":
        check_touch_reach(bases, (marks, marks), [[f"square {k}" for k in TOUCH_SQUARES]] * 2,
                          "Fix: a smaller --pitch-mm, or --register nominal.")
    true_bases = displaced_bases(bases, *base_error)
    pieces = game_pieces(true_bases)  # set down beside each arm as it truly stands
    m = build_two_arm_model(true_bases, pieces, servo, board.lines())
    d, scratch = mujoco.MjData(m), mujoco.MjData(m)
    arms = (SceneArm(m, true_bases[0]), SceneArm(m, true_bases[1]))
    for arm in arms:
        arm.set_initial_pose(d, park_pose(arm.base))

    def register_and_play(watch: ArmDistanceWatch):
        arms[0].hold_position(m, d, watch, 0.5)
        planned, registrations = register_arms(
            m, d, watch, arms, bases, (marks, marks),
            [(park_pose(arm.base), PARK_DURATION) for arm in arms], register)
        return _play(m, d, scratch, arms, planned, board, pieces, opening, watch), registrations

    report, registrations = play_filmed(m, d, arms, video, image, register_and_play)
    return report | {"game": game, "register": register,
                     "registration": [r.as_json() for r in registrations],
                     "base_error": {"mm": base_error[0], "deg": base_error[1]},
                     "bases": [asdict(b) for b in true_bases],
                     "nominal_bases": [asdict(b) for b in bases], "board": asdict(board),
                     "servo": actuation.servo_spec(m).describe()}


def play_filmed(m: mujoco.MjModel, d: mujoco.MjData, arms, video, image: Path | None, play):
    """Run ``play(watch)`` under the arms' distance watch, filmed and pictured; its result.

    Args:
        m: the model.
        d: its data.
        arms: the two ``SceneArm``.
        video: None, or a callable (m, d) -> a video recorder, closed here: complete after
            ``play``, discarded when it fails.
        image: a PNG of the scene at the end (or None).
        play: a callable (an ``ArmDistanceWatch``) -> the report.
    """
    recorder = video(m, d) if video is not None else None
    try:
        report = play(ArmDistanceWatch(m, d, arms, recorder))
    except BaseException:
        if recorder is not None:
            recorder.close(complete=False)
        raise
    if recorder is not None:
        recorder.close()
    if image is not None:
        save_frame(m, d, image)
    return report


def save_frame(m: mujoco.MjModel, d: mujoco.MjData, path: Path,
               size: tuple[int, int] = (960, 720)) -> None:
    """Write what the ``two_arms`` camera sees now as a PNG of ours (``markers.py``)."""
    renderer = FrameRenderer(m, d, size, GAME_CAMERA, quality=QUALITY["fast"])
    try:
        pixels = renderer.render()
    finally:
        renderer.close()
    write_png_atomic(path, pixels, "two_arms.py --image")


def _play(m, d, scratch, arms, planned, board: GameBoard, pieces, opening: int,
          watch: ArmDistanceWatch) -> dict:
    """The game's moves, each planned with the ``planned`` bases, checked, run and judged."""
    zone, expected, moves, least = board_zone(board), EMPTY, [], math.inf
    unused = {mark: [p.name for p in pieces if p.name[0] == mark.lower()] for mark in "XO"}
    for mark, square in full_game(opening):
        k = 0 if mark == "X" else 1
        arm, other, base = arms[k], arms[1 - k], planned[k]
        piece = unused[mark].pop(0)
        before = {p.name: piece_pose(d, p.name)[0] for p in pieces}
        steps = move_steps(base, before[piece], board.square(square), piece_yaw(d, piece, base))
        what = f"{arm.name} arm: {piece} to square {square}"
        least = min(least, run_moves(m, d, watch, arm, other, steps, zone, what, scratch))
        expected = expected[:square] + (mark,) + expected[square + 1:]
        verdict = check_move(m, d, board, pieces, piece, square, before)
        seen = read_board(m, d, board, pieces)
        moves.append(asdict(verdict) | {"arm": arm.name, "board_read": "".join(
            c or "." for c in seen), "board_as_read_matches": seen == expected,
            "reason": verdict.reason()})
    completed = all(mv["ok"] and mv["board_as_read_matches"] for mv in moves)
    return {"completed": completed, "collisions": watch.collisions,
            "winner": winner(expected) or "draw", "moves": moves,
            "least_arm_distance_planned_mm": round(1e3 * least, 1),
            "least_arm_distance_run_mm": round(1e3 * watch.least_distance, 1),
            "simulated_s": round(d.time, 2)}

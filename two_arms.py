"""Two SO-101s play tic-tac-toe or chess on one board in the simulator, each moving its pieces.

The course's files at the root are the project's one facade; ``so101_kinematics`` does the work
(``so101_kinematics/two_arms/``: the two-arm scene, the board, the shared workspace, the game).
"""

from __future__ import annotations

import so101_kinematics.display  # noqa: F401 - first: EGL when there is no display

# isort: split
import argparse
import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from so101_kinematics.cli import (
    NOTHING_WRITTEN,
    ArgumentParser,
    add_servo_arguments,
    number,
    range_help,
    run_script,
    servo_from_arguments,
)
from so101_kinematics.errors import ARM_NOT_STARTED, OutputPathError, PlanError, RenderSettingError
from so101_kinematics.outputs import (
    MP4,
    PNG,
    add_overwrite_argument,
    check_output_path,
    report_of,
    stamp,
    write_text_atomic,
)
from so101_kinematics.two_arms.board_registration import (
    BASE_ERROR,
    REGISTRATIONS,
    describe_registration,
    registration_options,
)
from so101_kinematics.two_arms.chess import CHESS_PITCH, CHESS_SPACING, ChessBoard, move_text
from so101_kinematics.two_arms.chess_game import run_chess
from so101_kinematics.two_arms.game_board import LAYOUT_BOARDS, GameBoard
from so101_kinematics.two_arms.two_arm_game import GAMES, SIDE_NOT_REGISTERED, run_game
from so101_kinematics.two_arms.two_arm_scene import GAME_CAMERA, LAYOUT_SPACING, LAYOUTS, arm_bases

REPORT = report_of("two_arms.py")  # --json replaces only a report of this program
SPACING_RANGE = (0.0, 1.0)  # [m]: the bases' overlap and the reach are checked on the layout
PITCH_RANGE = (10.0, 200.0)  # [mm]
VIDEO_SIZE = (640, 480)  # [px]
VIDEO_FPS = 30.0  # [frames/s]
BASE_ERROR_RANGE = (-20.0, 20.0)  # [mm] and [deg]: a base set down by hand, not elsewhere


def main(argv: Sequence[str] | None = None) -> int:
    """Parse the command line, play, print and write the report; the exit code."""
    parser = ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="""The left arm plays X, the right arm O, two perfect players: a whole game
(a draw in nine moves). Each move is the course's pick-and-place by IK in the
moving arm's base frame, then back to its park pose; every planned path is
checked first (one arm in the board's area at a time, the arms' collision
boxes 20 mm apart) and refused in one line if it breaks the rule. After each
move the simulation is read back: the piece within 5 mm of its square's
centre, upright, no other piece moved, the board as the game has it.

Chess (--game chess): the left arm White, the right arm Black, the bases facing
each other across an 8x8 board of 26 mm cubes (all 32 pieces); first each arm
registers the board to its base from four touched squares (the fit's residual
printed), then six plies, each judged as above. Tic-tac-toe registers too
(--layout facing; its marks the edges' middle squares). The true bases stand
--base-error off the nominal ones; --register nominal shows what that costs.

--ports A B plays the same tic-tac-toe plan on two arms through lerobot's bus
(left A, right B), each path checked against the other arm's joints as read
back; start the virtual arms with the commands --print-virtual-arms prints
(each with its own pieces, at its park pose). The board is read back by the
virtual arms' cube sensors (a real arm has none: the report says so). The
last line is both arms', from their servos: back at their starting pose.

Exit code: 0 played (completed or not: see the report), 2 bad input (one
line; nothing run), 1 an unexpected error, or a run on the arms stopped by a
fault, Ctrl-C or SIGTERM (both arms ended), 130 interrupted.""")
    parser.add_argument("--game", choices=GAMES, default=GAMES[0],
                        help="the game (default %(default)s); chess: six plies of "
                        f"{move_text()}, the board {CHESS_PITCH * 1e3:g} mm a square, the "
                        f"bases {CHESS_SPACING:g} m apart")
    parser.add_argument("--register", choices=REGISTRATIONS,
                        help="each arm registers the board to its base from four touched "
                        "points (touch, the default) or trusts the nominal bases; in the "
                        "simulator, --layout facing")
    parser.add_argument("--base-error", type=number(*BASE_ERROR_RANGE), nargs=2,
                        metavar=("MM", "DEG"),
                        help="how far each true base stands from its nominal pose, moved "
                        "MM towards its own side and turned DEG, each "
                        f"{range_help(*BASE_ERROR_RANGE)} (default {BASE_ERROR[0]:g} "
                        f"{BASE_ERROR[1]:g}; in the simulator, --layout facing)")
    parser.add_argument("--layout", choices=LAYOUTS, default="facing",
                        help="the bases: facing each other across the board, or side by side "
                        "(default %(default)s)")
    parser.add_argument("--spacing", type=number(*SPACING_RANGE, "m"), metavar="M",
                        help="the bases' distance [m] (default: facing "
                        f"{LAYOUT_SPACING['facing']:g}, side {LAYOUT_SPACING['side']:g}; chess "
                        f"{CHESS_SPACING:g})")
    parser.add_argument("--board-at", type=number(-0.5, 0.5, "m"), nargs=2, metavar=("X", "Y"),
                        help="the board's centre on the table [m] (default: facing "
                        f"{_xy(LAYOUT_BOARDS['facing'])}, between the bases; side "
                        f"{_xy(LAYOUT_BOARDS['side'])}, in front of them)")
    parser.add_argument("--pitch-mm", type=number(*PITCH_RANGE, "mm"), metavar="MM",
                        help=f"the squares' pitch, {range_help(*PITCH_RANGE, 'mm')} (default: "
                        f"facing {LAYOUT_BOARDS['facing'].pitch * 1e3:g}, side "
                        f"{LAYOUT_BOARDS['side'].pitch * 1e3:g}; chess {CHESS_PITCH * 1e3:g})")
    parser.add_argument("--opening", type=int, choices=range(9), default=4, metavar="SQUARE",
                        help="tic-tac-toe: X's first square, 0-8 row by row (default "
                        "%(default)s: the centre)")
    parser.add_argument("--headless", action="store_true",
                        help="no viewer (this program always runs offscreen; a video with "
                        "--video)")
    parser.add_argument("--json", type=Path, metavar="PATH", help="write the report as JSON")
    parser.add_argument("--video", type=Path, metavar="PATH.mp4",
                        help=f"film the game from the '{GAME_CAMERA}' camera")
    parser.add_argument("--image", type=Path, metavar="PATH.png",
                        help=f"a picture of the board at the end (the '{GAME_CAMERA}' camera)")
    parser.add_argument("--ports", nargs=2, metavar=("A", "B"),
                        help="play tic-tac-toe on two arms through lerobot's bus: the left "
                        "arm's port (X), the right's (O); the arms' pieces as "
                        "--print-virtual-arms puts them")
    parser.add_argument("--calibration", nargs=2, type=Path, metavar=("LEFT", "RIGHT"),
                        help="with --ports: each arm's lerobot calibration (default: the virtual "
                        "arm's, for both)")
    parser.add_argument("--print-virtual-arms", action="store_true",
                        help="print the two virtual_so101.py commands that start the virtual "
                        "arms with their pieces for this --layout and --spacing, and exit")
    add_overwrite_argument(parser)
    add_servo_arguments(parser)
    parser.add_argument("-v", "--verbose", action="store_true",
                        help="show the traceback of an unexpected error")
    return run_script(parser, argv, _run, refused=(OutputPathError, PlanError, RenderSettingError,
                                                      *ARM_NOT_STARTED),
                      interrupted=NOTHING_WRITTEN)


def _xy(board: GameBoard) -> str:
    """A board's centre as the option reads it: "0.18 0"."""
    return f"{board.centre[0]:g} {board.centre[1]:g}"


def _check_outputs(args: argparse.Namespace) -> tuple[Path | None, Path | None, Path | None]:
    """The --video, --image and --json paths, checked before anything runs."""
    video = image = json_path = None
    if args.video is not None:
        video = check_output_path(args.video, "--video", suffixes=(".mp4",), kind=MP4,
                                  overwrite=args.overwrite)
    if args.image is not None:
        image = check_output_path(args.image, "--image", suffixes=(".png",), kind=PNG,
                                  overwrite=args.overwrite)
    if args.json is not None:
        json_path = check_output_path(args.json, "--json", kind=REPORT, overwrite=args.overwrite)
    named = [path for path in (video, image, json_path) if path is not None]
    if len(set(named)) < len(named):
        raise OutputPathError("--video, --image and --json name the same file. Fix: give each "
                              "its own name, e.g. two_arms.mp4, two_arms.png, two_arms.json.")
    return video, image, json_path


def _check_ports(args: argparse.Namespace) -> None:
    """--ports: the same port twice, or with an option of the simulator's, in one line."""
    ports = args.ports
    if args.print_virtual_arms and args.game != "tictactoe":
        raise PlanError(f"--print-virtual-arms with --game {args.game}: the arms play tictactoe "
                        "only. Fix: --game tictactoe.")
    if ports is None:
        if args.calibration is not None:
            raise PlanError("--calibration is the arms' on --ports. Fix: add --ports A B, or "
                            "leave it out.")
        return
    from so101_kinematics.lab.two_arms_arm import check_ports

    check_ports(ports)
    registration_options(args.register, args.base_error, "with --ports the plan trusts the "
                         "bases where you set the arms down. Fix: leave it out (or leave out "
                         "--ports).")
    if args.game != "tictactoe":
        raise PlanError(f"--ports with --game {args.game}: the arms play tictactoe only. Fix: "
                        "--game tictactoe, or leave out --ports.")
    for option, value in (("--video", args.video), ("--image", args.image)):
        if value is not None:
            raise PlanError(f"{option} {value}: with --ports there is no simulation to film. "
                            f"Fix: leave out {option} (or --ports).")


def _run(args: argparse.Namespace) -> int:
    """Check the inputs and outputs, play, report (see :func:`main`)."""
    _check_ports(args)
    video, image, json_path = _check_outputs(args)
    if args.game == "chess":
        return _run_chess(args, video, image, json_path)
    bases = arm_bases(args.layout, args.spacing)
    default = LAYOUT_BOARDS[args.layout]
    board = GameBoard(tuple(args.board_at or default.centre),
                      default.pitch if args.pitch_mm is None else args.pitch_mm / 1e3)
    if args.print_virtual_arms or args.ports:
        from so101_kinematics.lab import two_arms_arm

        if args.print_virtual_arms:
            print("\n".join(two_arms_arm.virtual_arm_commands(bases)))
            return 0
        return _run_on_arms(args, two_arms_arm, bases, board, json_path)
    registration = registration_options(args.register, args.base_error, None if args.layout
                                        == "facing" else SIDE_NOT_REGISTERED)
    started = time.perf_counter()
    report = run_game(bases, board, args.game, args.opening, servo_from_arguments(args),
                      video=_recorder(video), image=image, **registration)
    report["run_s"] = round(time.perf_counter() - started, 1)
    return _report(report, f"{args.game}: {len(report['moves'])} moves", f"({report['winner']})",
                   json_path)


def _recorder(video: Path | None):
    """The video recorder's factory for ``--video`` (or None)."""
    if video is None:
        return None
    from so101_kinematics.sim.video import VideoRecorder

    def recorder(m, d):
        return VideoRecorder(m, d, video, fps=VIDEO_FPS, size=VIDEO_SIZE, camera=GAME_CAMERA,
                             progress=False)
    return recorder


def _run_chess(args: argparse.Namespace, video, image, json_path) -> int:
    """--game chess: register, play the six plies, print and write the report."""
    if args.layout != "facing":
        raise PlanError(f"--layout {args.layout}: chess is played across the board, the arms "
                        "facing each other. Fix: leave out --layout (facing).")
    bases = arm_bases("facing", CHESS_SPACING if args.spacing is None else args.spacing)
    board = ChessBoard(tuple(args.board_at or (0.0, 0.0)),
                       CHESS_PITCH if args.pitch_mm is None else args.pitch_mm / 1e3)
    started = time.perf_counter()
    report = run_chess(bases, board, servo_from_arguments(args), video=_recorder(video),
                       image=image, **registration_options(args.register, args.base_error))
    report["run_s"] = round(time.perf_counter() - started, 1)
    return _report(report, f"chess: {len(report['moves'])} plies ({move_text()})", "",
                   json_path)


def _report(report: dict, what: str, outcome: str, json_path: Path | None) -> int:
    """Print the game's line (``what``, the verdict, ``outcome``, the figures), write the JSON."""
    for registration in report["registration"]:
        print(describe_registration(registration))
    errors = [move["piece_error_mm"] for move in report["moves"]]
    verdict = "completed" if report["completed"] else "NOT completed"
    print(f"{what}, {' '.join(filter(None, (verdict, outcome)))}; pieces "
          f"{sum(errors) / len(errors):.2f} mm mean, {max(errors):.2f} mm worst from their "
          f"squares; {report['collisions']} collisions between the arms (least distance "
          f"{report['least_arm_distance_run_mm']:.0f} mm)")
    if json_path is not None:
        write_text_atomic(json_path, json.dumps(stamp(report, "two_arms.py"), indent=2) + "\n")
    return 0


def _run_on_arms(args: argparse.Namespace, two_arms_arm, bases, board: GameBoard,
                 json_path: Path | None) -> int:
    """--ports: the game on the two arms; the last line both arms' (``lab/two_arms_arm.py``)."""
    from so101_kinematics.calibration import load_calibration
    from so101_kinematics.hw.course_calibration import ScriptEnded
    from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH

    paths = args.calibration or (DEFAULT_CALIBRATION_PATH, DEFAULT_CALIBRATION_PATH)
    calibrations = [load_calibration(path) for path in paths]
    started = time.perf_counter()
    try:
        run = two_arms_arm.play_on_arms(args.ports, calibrations, bases, board, args.opening,
                                        gravity_ff=args.gravity_ff)
    except ScriptEnded as refused:  # an arm refused by setup_motors: its line printed
        return refused.code
    report = run.report | {"game": args.game, "run_s": round(time.perf_counter() - started, 1)}
    errors = [move["piece_error_mm"] for move in report["moves"]]
    verdict = "completed" if report["completed"] else "NOT completed"
    pieces = ("not read back (no cube sensor)" if not report["read_back"] else
              "none placed" if not errors else
              f"{sum(errors) / len(errors):.2f} mm mean, {max(errors):.2f} mm worst from their "
              "squares (cube sensors)")
    least = report["least_arm_distance_run_mm"]
    print(f"{args.game} on two arms: {len(errors)} moves, {verdict} ({report['winner']}); "
          f"pieces {pieces}; {report['collisions']} collisions between the arms"
          + ("" if least is None else f" (least distance {least:.0f} mm)")
          + (f"; aborted: {report['aborted']}" if report["aborted"] else ""))
    if json_path is not None:
        write_text_atomic(json_path, json.dumps(stamp(report, "two_arms.py"), indent=2) + "\n")
    print(run.last_line, file=sys.stdout if run.released and run.code == 0 else sys.stderr)
    return run.code


if __name__ == "__main__":
    sys.exit(main())

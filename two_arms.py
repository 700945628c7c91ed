"""Two SO-101s play tic-tac-toe on one board in the simulator, each arm moving its own pieces.

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
    ArgumentParser,
    add_servo_arguments,
    number,
    range_help,
    run_script,
    servo_from_arguments,
)
from so101_kinematics.errors import OutputPathError, PlanError, RenderSettingError
from so101_kinematics.outputs import (
    MP4,
    PNG,
    add_overwrite_argument,
    check_output_path,
    report_of,
    stamp,
    write_text_atomic,
)
from so101_kinematics.two_arms.game_board import LAYOUT_BOARDS, GameBoard
from so101_kinematics.two_arms.two_arm_game import run_game
from so101_kinematics.two_arms.two_arm_scene import (
    GAME_CAMERA,
    LAYOUT_SPACING,
    LAYOUTS,
    arm_bases,
)

REPORT = report_of("two_arms.py")  # --json replaces only a report of this program
SPACING_RANGE = (0.0, 1.0)  # [m]: the bases' overlap and the reach are checked on the layout
PITCH_RANGE = (10.0, 200.0)  # [mm]
VIDEO_SIZE = (640, 480)  # [px]
VIDEO_FPS = 30.0  # [frames/s]


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

Exit code: 0 played (completed or not: see the report), 2 bad input (one
line; nothing run), 1 an unexpected error, 130 interrupted.""")
    parser.add_argument("--game", default="tictactoe",
                        help="the game: tictactoe (chess is not built yet)")
    parser.add_argument("--layout", choices=LAYOUTS, default="facing",
                        help="the bases: facing each other across the board, or side by side "
                        "(default %(default)s)")
    parser.add_argument("--spacing", type=number(*SPACING_RANGE, "m"), metavar="M",
                        help="the bases' distance [m] (default: facing "
                        f"{LAYOUT_SPACING['facing']:g}, side {LAYOUT_SPACING['side']:g})")
    parser.add_argument("--board-at", type=number(-0.5, 0.5, "m"), nargs=2, metavar=("X", "Y"),
                        help="the board's centre on the table [m] (default: facing "
                        f"{_xy(LAYOUT_BOARDS['facing'])}, between the bases; side "
                        f"{_xy(LAYOUT_BOARDS['side'])}, in front of them)")
    parser.add_argument("--pitch-mm", type=number(*PITCH_RANGE, "mm"), metavar="MM",
                        help=f"the squares' pitch, {range_help(*PITCH_RANGE, 'mm')} (default: "
                        f"facing {LAYOUT_BOARDS['facing'].pitch * 1e3:g}, side "
                        f"{LAYOUT_BOARDS['side'].pitch * 1e3:g})")
    parser.add_argument("--opening", type=int, choices=range(9), default=4, metavar="SQUARE",
                        help="X's first square, 0-8 row by row (default %(default)s: the centre)")
    parser.add_argument("--headless", action="store_true",
                        help="no viewer (this program always runs offscreen; a video with "
                        "--video)")
    parser.add_argument("--json", type=Path, metavar="PATH", help="write the report as JSON")
    parser.add_argument("--video", type=Path, metavar="PATH.mp4",
                        help=f"film the game from the '{GAME_CAMERA}' camera")
    parser.add_argument("--image", type=Path, metavar="PATH.png",
                        help=f"a picture of the board at the end (the '{GAME_CAMERA}' camera)")
    parser.add_argument("--ports", nargs=2, metavar=("A", "B"),
                        help="two arms' serial ports (not built yet: refused)")
    add_overwrite_argument(parser)
    add_servo_arguments(parser)
    parser.add_argument("-v", "--verbose", action="store_true",
                        help="show the traceback of an unexpected error")
    return run_script(parser, argv, _run, refused=(OutputPathError, PlanError, RenderSettingError),
                      interrupted="nothing was written; existing output files are as they were.")


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


def _check_ports(ports: Sequence[str] | None) -> None:
    """--ports: the same port twice, or two ports at all (not built yet), in one line."""
    if ports is None:
        return
    if ports[0] == ports[1]:
        raise PlanError(f"--ports {ports[0]} {ports[1]}: one port for both arms (each arm needs "
                        "its own bus). Fix: give each arm its own port (virtual_so101.py prints "
                        "each virtual arm's).")
    raise PlanError("--ports: the game on two arms through lerobot's bus is not built yet. Fix: "
                    "leave out --ports to play in the simulator.")


def _run(args: argparse.Namespace) -> int:
    """Check the inputs and outputs, play, report (see :func:`main`)."""
    _check_ports(args.ports)
    video, image, json_path = _check_outputs(args)
    bases = arm_bases(args.layout, args.spacing)
    default = LAYOUT_BOARDS[args.layout]
    board = GameBoard(tuple(args.board_at or default.centre),
                      default.pitch if args.pitch_mm is None else args.pitch_mm / 1e3)
    recorder = None
    if video is not None:
        from so101_kinematics.sim.video import VideoRecorder

        def recorder(m, d):
            return VideoRecorder(m, d, video, fps=VIDEO_FPS, size=VIDEO_SIZE, camera=GAME_CAMERA,
                                 progress=False)

    started = time.perf_counter()
    report = run_game(bases, board, args.game, args.opening, servo_from_arguments(args),
                      video=recorder, image=image)
    report["run_s"] = round(time.perf_counter() - started, 1)
    errors = [move["piece_error_mm"] for move in report["moves"]]
    verdict = "completed" if report["completed"] else "NOT completed"
    print(f"{args.game}: {len(errors)} moves, {verdict} ({report['winner']}); pieces "
          f"{sum(errors) / len(errors):.2f} mm mean, {max(errors):.2f} mm worst from their "
          f"squares; {report['collisions']} collisions between the arms (least distance "
          f"{report['least_arm_distance_run_mm']:.0f} mm)")
    if json_path is not None:
        write_text_atomic(json_path, json.dumps(stamp(report, "two_arms.py"), indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())

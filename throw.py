"""Throw a ball into a cup with the simulated arm; the landing checked against the forward model.

The course's files at the root are the project's one facade; ``so101_kinematics`` does the work
(``so101_kinematics/throwing/``: the ball's flight, the release the servos can reach, the throw).
"""

from __future__ import annotations

import so101_kinematics.display  # noqa: F401 - first: EGL when there is no display

# isort: split
import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

from so101_kinematics import servo
from so101_kinematics.cli import ArgumentParser, number, range_help, run_script
from so101_kinematics.errors import OutputPathError, PlanError
from so101_kinematics.outputs import (
    MP4,
    PNG,
    add_overwrite_argument,
    check_output_path,
    report_of,
    stamp,
    write_text_atomic,
)
from so101_kinematics.throwing.ball import BALLS
from so101_kinematics.throwing.throw_scene import build_throw_model
from so101_kinematics.throwing.throw_trials import (
    cup_positions,
    run_throws,
    save_picture,
    save_video,
)

REPORT = report_of("throw.py")  # --json replaces only a report of this program
TRIALS_RANGE = (1, 100)
SEED_RANGE = (0, 999_999)
SUPPLY_RANGE = (9.0, 14.0)  # [V]: the 12 V follower's C018 (below 9 V it would be a C001)


def main(argv: Sequence[str] | None = None) -> int:
    """Parse the command line, throw, print and write the figures; the exit code."""
    parser = ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="""Each throw: the release pose and speed from the Jacobian, checked against
the STS3215 model's top speed; the swing rehearsed with the ball held and the
release timed on the forward model (quadratic drag); the gripper told to
open its measured delay before. The JSON's trials give, per throw, in_cup and
model_error_m (the forward model from the simulated release against the
ball's first touch), the release speed and the servos' top speeds.

Exit code: 0 thrown, 2 bad input (one line; nothing thrown), 1 an unexpected
error, 130 interrupted.""")
    parser.add_argument("--trials", type=number(*TRIALS_RANGE, integer=True), default=10,
                        metavar="N", help=f"throws at seeded cups, {range_help(*TRIALS_RANGE)} "
                        "(default %(default)s)")
    parser.add_argument("--seed", type=number(*SEED_RANGE, integer=True), default=0,
                        metavar="S", help="the cups' seed, a whole number from 0 (default 0)")
    parser.add_argument("--cup", type=number(-1.0, 1.0, "m"), nargs=2, metavar=("X", "Y"),
                        help="one throw at a cup standing here [m] (instead of --trials)")
    parser.add_argument("--ball", choices=tuple(BALLS), default="pingpong",
                        help="the ball (default %(default)s: 40 mm, 2.7 g)")
    parser.add_argument("--supply", type=number(*SUPPLY_RANGE, "V"),
                        default=servo.DEFAULT_SUPPLY_V, metavar="VOLTS",
                        help=f"the STS3215 C018s' supply, {range_help(*SUPPLY_RANGE, 'V')} "
                        "(default %(default)g)")
    parser.add_argument("--headless", action="store_true",
                        help="no viewer (this program always runs offscreen)")
    parser.add_argument("--json", type=Path, metavar="PATH", help="write the report as JSON")
    parser.add_argument("--video", type=Path, metavar="PATH.mp4",
                        help="record the first throw from the side")
    parser.add_argument("--image", type=Path, metavar="PATH.png",
                        help="a picture of the first throw at its landing, the path drawn")
    parser.add_argument("--port", metavar="PORT",
                        help="an arm's serial port: not built yet (refused)")
    add_overwrite_argument(parser)
    parser.add_argument("-v", "--verbose", action="store_true",
                        help="show the traceback of an unexpected error")
    return run_script(parser, argv, _run, refused=(OutputPathError, PlanError),
                      interrupted="nothing was written; existing output files are as they were.")


def _outputs(args: argparse.Namespace) -> dict[str, Path | None]:
    """The output paths, checked before anything runs."""
    kinds = {"json": (REPORT, ()), "video": (MP4, (".mp4",)), "image": (PNG, (".png",))}
    paths: dict[str, Path | None] = {}
    for name, (kind, suffixes) in kinds.items():
        given = getattr(args, name)
        paths[name] = None if given is None else check_output_path(
            given, f"--{name}", (), args.overwrite, suffixes=suffixes, kind=kind)
    chosen = [p for p in paths.values() if p is not None]
    if len(set(chosen)) < len(chosen):
        raise OutputPathError("two outputs share one file name. Fix: give --json, --video and "
                              "--image their own names.")
    return paths


def _run(args: argparse.Namespace) -> int:
    """Check the inputs, throw, report (see :func:`main`)."""
    if args.port:
        raise PlanError(f"--port {args.port}: throwing on an arm is not built yet (nothing was "
                        "moved). Fix: leave --port out to throw in the simulator; the real "
                        "arm's throw is issue 38's next step.")
    paths = _outputs(args)
    ball = BALLS[args.ball]
    m = build_throw_model(ball, {"volts": args.supply, "variant": "C018"})
    cups = [tuple(args.cup)] if args.cup else cup_positions(args.trials, args.seed)
    report = run_throws(m, ball, cups, args.supply, "C018")
    report["seed"] = None if args.cup else args.seed
    for number_, trial in enumerate(report["trials"], 1):
        where = "in the cup" if trial["in_cup"] else "missed"
        error = trial["model_error_m"]
        print(f"throw {number_}: cup {trial['cup_distance_m']:.3f} m away, released at "
              f"{trial.get('release_speed_m_s', float('nan')):.2f} m/s: {where}; model "
              + ("-" if error is None else f"{1000 * error:.1f} mm") + " from the first touch")
    worst = report["worst_model_error_m"]
    print(f"{report['hits']}/{report['throws']} in the cup; the forward model within "
          + ("-" if worst is None else f"{1000 * worst:.1f} mm") + " of every first touch")
    if paths["video"] is not None:
        save_video(paths["video"], m, ball, cups[0], args.supply, "C018")
    if paths["image"] is not None:
        save_picture(paths["image"], m, ball, cups[0], args.supply, "C018")
    if paths["json"] is not None:
        write_text_atomic(paths["json"], json.dumps(stamp(report, "throw.py"), indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())

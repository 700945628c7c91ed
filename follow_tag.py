"""Tag follower in the simulator: the wrist camera keeps a moving tag centred (resolved rate).

The course's files at the root are the project's one facade; ``so101_kinematics`` does the work
(``so101_kinematics/vision/tag_follower.py``: see, want, step with the course's Jacobian).
"""

from __future__ import annotations

import so101_kinematics.display  # noqa: F401 - first: EGL when there is no display

# isort: split
import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

from so101_kinematics.cli import ArgumentParser, number, range_help, run_script
from so101_kinematics.errors import OutputPathError, RenderError, VisionError
from so101_kinematics.outputs import (
    MP4,
    add_overwrite_argument,
    check_output_path,
    report_of,
    stamp,
    write_text_atomic,
)
from so101_kinematics.vision.sim_camera import WEBCAM
from so101_kinematics.vision.tag_follower import (
    FOLLOW_POSE_AGE,
    FOLLOW_RATE,
    HEIGHT,
    LOOK_TILT,
    PATHS,
    SPEED_RANGE,
    TagPath,
    follow,
)

REPORT = report_of("follow_tag.py")  # --json replaces only a report of this program
DURATION_RANGE = (0.1, 600.0)
RADIUS_RANGE = (0.005, 0.06)


def main(argv: Sequence[str] | None = None) -> int:
    """Parse the command line, follow the tag, print and write the report; the exit code."""
    parser = ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=f"""The target tag (40 mm) slides on the table along a circle or a line
(back and forth) at --speed. Each of the wrist camera's frames
({FOLLOW_RATE:g} frames/s, 640x480, a webcam's blur and noise) gives the tag's
position (on the table: its corners' rays met with the table's plane),
and one resolved-rate step (the course's Jacobian, damped least squares)
moves the camera towards {HEIGHT * 100:g} cm above the tag, looking at it {LOOK_TILT:g} deg
off vertical, so the tag stays at the image's centre; the measured STS3215
servos move the arm. A tag not seen for more than {FOLLOW_POSE_AGE:g} s: the arm holds
until it is seen again (--hide START END hides it to show this).

Scored from the simulator's truth: the tag's centre from the image's
centre [px], and where the optical axis meets the table from the tag's
centre [mm], mean and worst; the frames the tag was lost, and held.

Exit code: 0 done, 2 bad input (one line; nothing ran), 1 an unexpected
error, 130 interrupted.""")
    parser.add_argument("--headless", action="store_true",
                        help="no viewer (this program always runs offscreen; a video with "
                        "--video)")
    parser.add_argument("--path", choices=PATHS, default="circle",
                        help="the tag's path: a circle, or a line across the arm's front, "
                        "back and forth (default %(default)s)")
    parser.add_argument("--speed", type=number(*SPEED_RANGE, "m/s"), default=0.03,
                        help=f"the tag's speed along its path, {range_help(*SPEED_RANGE, 'm/s')}"
                        " (default %(default)s)")
    parser.add_argument("--radius", type=number(*RADIUS_RANGE, "m"), default=0.04,
                        help="the circle's radius or the line's half-length, "
                        f"{range_help(*RADIUS_RANGE, 'm')} (default %(default)s; centred at "
                        "(0.24, 0) m)")
    parser.add_argument("--duration", type=number(*DURATION_RANGE, "s"), default=8.0,
                        help=f"simulated time, {range_help(*DURATION_RANGE, 's')} (default "
                        "%(default)s)")
    parser.add_argument("--hide", type=number(0.0, DURATION_RANGE[1], "s"), nargs=2,
                        metavar=("START", "END"),
                        help="hide the tag (under the table) from START to END [s]")
    parser.add_argument("--clean-images", action="store_true",
                        help="the camera's images as rendered (no webcam blur and noise)")
    parser.add_argument("--video", type=Path, metavar="PATH.mp4",
                        help="record the run from the front, the wrist camera's view inset")
    parser.add_argument("--json", type=Path, metavar="PATH", help="write the report as JSON")
    add_overwrite_argument(parser)
    parser.add_argument("-v", "--verbose", action="store_true",
                        help="show the traceback of an unexpected error")
    return run_script(parser, argv, _run, refused=(OutputPathError, RenderError, VisionError),
                      interrupted="nothing was written; existing output files are as they were.")


def _check_outputs(args: argparse.Namespace) -> tuple[Path | None, Path | None]:
    """The --json and --video paths, checked before anything runs."""
    video = json_path = None
    if args.video is not None:
        video = check_output_path(args.video, "--video", suffixes=(".mp4",), kind=MP4,
                                  overwrite=args.overwrite)
    if args.json is not None:
        json_path = check_output_path(args.json, "--json", kind=REPORT, overwrite=args.overwrite)
        if json_path == video:
            raise OutputPathError(f"--json {args.json}: is the --video file too. Fix: give the "
                                  "report its own name, e.g. follow.json.")
    return video, json_path


def _run(args: argparse.Namespace) -> int:
    """Check the outputs, follow, report (see :func:`main`)."""
    video, json_path = _check_outputs(args)
    if args.hide is not None and args.hide[1] <= args.hide[0]:
        raise VisionError(f"--hide {args.hide[0]:g} {args.hide[1]:g}: the end must come after "
                          "the start. Fix: e.g. --hide 2 3.")
    path = TagPath(args.path, radius=args.radius, speed=args.speed,
                   hide=None if args.hide is None else tuple(args.hide))
    report = follow(path, args.duration, effects=None if args.clean_images else WEBCAM,
                    video=video)
    px, mm = report["tracking_error_px"], report["tracking_error_mm"]
    print(f"Followed the tag ({args.path}, {args.speed * 100:g} cm/s) for {args.duration:g} s "
          f"({report['frames']} frames): off the image's centre by {px['mean']:.1f} px mean, "
          f"{px['worst']:.1f} px worst ({mm['mean']:.1f} mm, {mm['worst']:.1f} mm on the table)"
          if px else f"Followed for {args.duration:g} s: the tag was hidden throughout.")
    print(f"Tag lost in {report['lost_frames']} frames ({report['hidden_frames']} hidden); the "
          f"arm held in {report['held_frames']} (no motion on a pose older than "
          f"{FOLLOW_POSE_AGE:g} s)" + ("" if report["first_held_s"] is None else
                                    f", first at {report['first_held_s']:.2f} s") + ".")
    if json_path is not None:
        write_text_atomic(json_path, json.dumps(stamp(report, "follow_tag.py"), indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())

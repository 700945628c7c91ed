"""Tag follower in the simulator: the wrist camera keeps a moving tag centred (resolved rate).

The course's files at the root are the project's one facade; ``so101_kinematics`` does the work
(``so101_kinematics/vision/tag_follower.py``: see, want, step with the course's Jacobian;
``so101_kinematics/lab/follow_tag_arm.py``: the same on an arm, ``--port`` and ``--camera``).
"""

from __future__ import annotations

import so101_kinematics.display  # noqa: F401 - first: EGL when there is no display

# isort: split
import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

from so101_kinematics.cli import (
    EXIT_BAD_INPUT,
    NOTHING_WRITTEN,
    ArgumentParser,
    add_calibration_argument,
    number,
    range_help,
    run_script,
)
from so101_kinematics.errors import (
    ARM_NOT_STARTED,
    InputError,
    OutputPathError,
    RenderError,
    VisionError,
)
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
SIM_ONLY = ("path", "speed", "radius", "duration", "hide", "clean_images", "video")
"""Options of the simulator's tag (an arm follows a real one): refused with --port."""


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

On an arm (--port PORT --camera ADDRESS): the arm looks at (0.24, 0) m,
follows the target tag for --seconds through lerobot's bus (every goal
checked against the calibrated range, the table and the speed cap), holds
where it is when the tag is lost or out of reach, then returns to its
start and releases there; the last line says where the arm is and whether
it is torqued, as the servos report it.

Exit code: 0 done, 2 bad input (one line; nothing ran), 1 an unexpected
error or a run aborted (the arm's ending printed), 130 interrupted.""")
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
    arm = parser.add_argument_group("on an arm (through lerobot's bus and camera class)")
    arm.add_argument("--port", metavar="PORT",
                     help="the arm's serial port (the pty virtual_so101.py printed); needs "
                     "--camera")
    arm.add_argument("--camera", metavar="ADDRESS",
                     help="the wrist camera: its address (virtual_so101.py --camera wrist printed "
                     "it) or a webcam (/dev/video0, or its index); needs --port")
    arm.add_argument("--camera-calibration", type=Path, default=None, metavar="PATH",
                     help="the wrist camera's calibration: the report calibrate_camera.py "
                     "--photos DIR --mount wrist --json PATH wrote (default: the model's wrist "
                     "camera, exact for the virtual arm)")
    add_calibration_argument(arm)
    arm.add_argument("--seconds", type=number(*DURATION_RANGE, "s"), default=None,
                     help=f"follow this long, {range_help(*DURATION_RANGE, 's')} (default 30)")
    parser.add_argument("-v", "--verbose", action="store_true",
                        help="show the traceback of an unexpected error")
    refused = (InputError, RenderError, VisionError, *ARM_NOT_STARTED)
    return run_script(parser, argv, lambda args: _run(args, parser), refused=refused,
                      interrupted=NOTHING_WRITTEN)


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


def _arm_refusal(args: argparse.Namespace, parser: argparse.ArgumentParser) -> str:
    """The one line refusing options that do not go together on an arm, or ""."""
    if args.port or args.camera:
        if not (args.port and args.camera):
            return (f"{'--port' if args.port else '--camera'} needs "
                    f"{'--camera ADDRESS' if args.port else '--port PORT'}: the arm is driven "
                    "through its port and looks through its wrist camera. Fix: give both.")
        given = [o for o in SIM_ONLY if getattr(args, o) != parser.get_default(o)]
        if given:
            option = "--" + given[0].replace("_", "-")
            return (f"{option} is the simulator's tag: on an arm the tag is a real one. Fix: "
                    f"leave out {option}, or --port and --camera.")
        return ""
    for option in ("camera_calibration", "calibration", "seconds"):
        if getattr(args, option) is not None:
            option = "--" + option.replace("_", "-")
            return (f"{option} is for an arm: the simulator's camera and arm are the model's"
                    f"{' (its run is --duration)' if option == '--seconds' else ''}. Fix: add "
                    f"--port PORT --camera ADDRESS, or leave out {option}.")
    return ""


def _run_on_arm(args: argparse.Namespace, json_path: Path | None) -> int:
    """--port and --camera: follow through lerobot; the run's ending as its last line."""
    from so101_kinematics.calibration import load_calibration
    from so101_kinematics.hw.run import RELEASE_HINT, ending
    from so101_kinematics.lab.follow_tag_arm import follow_on_arm
    from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH

    calibration_path = args.calibration or DEFAULT_CALIBRATION_PATH
    calibration = load_calibration(calibration_path)
    report, result = follow_on_arm(args.port, args.camera, calibration, args.seconds or 30.0,
                                   camera_calibration=args.camera_calibration)
    px, mm = report["offset_px"], report["miss_mm"]
    print(f"Followed for {report['seconds']:g} s: {report['frames']} frames, the tag seen in "
          f"{report['seen_frames']}, held in {report['held_frames']} (lost), refused in "
          f"{report['refused_frames']} (out of reach)"
          + ("" if px is None else f"; off the image's centre {px['mean']:.1f} px mean, "
             f"{px['worst']:.1f} px worst ({mm['mean']:.1f} mm, {mm['worst']:.1f} mm on the "
             "table, as the camera sees it)") + ".")
    if json_path is not None:
        write_text_atomic(json_path, json.dumps(stamp(report, "follow_tag.py"), indent=2) + "\n")
    release = RELEASE_HINT.format(port=args.port, arm=f"--calibration {calibration_path}")
    failed = result.aborted is not None
    print(ending(result, release), file=sys.stderr if failed else sys.stdout)
    return 1 if failed else 0


def _run(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    """Check the outputs, follow, report (see :func:`main`)."""
    refusal = _arm_refusal(args, parser)
    if refusal:
        print(f"error: {refusal}", file=sys.stderr)
        return EXIT_BAD_INPUT
    video, json_path = _check_outputs(args)
    if args.port:
        return _run_on_arm(args, json_path)
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

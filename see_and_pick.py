"""See and pick in the simulator: the fixed camera finds the cube, the arm puts it on the target.

The course's files at the root are the project's one facade; ``so101_kinematics`` does the work
(``so101_kinematics/vision/see_and_pick.py``: look, plan with the IK, move, score).
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
    CubePositionError,
    OutputPathError,
    PlanError,
    RenderError,
    VisionError,
)
from so101_kinematics.inputs import check_number
from so101_kinematics.outputs import (
    MP4,
    add_overwrite_argument,
    check_output_path,
    report_of,
    stamp,
    write_text_atomic,
)
from so101_kinematics.sim.cube import table_extent
from so101_kinematics.vision.see_and_pick import (
    MAX_POSE_AGE,
    PICK_BEARING,
    PICK_RADIUS,
    PLACE_TOLERANCE,
    course_target,
    run_trials,
)
from so101_kinematics.vision.sim_camera import WEBCAM

REPORT = report_of("see_and_pick.py")  # --json replaces only a report of this program
MAX_TRIALS = 1000
SEED_RANGE = (0, 2**32 - 1)


def main(argv: Sequence[str] | None = None) -> int:
    """Parse the command line, run the trials, print and write the report; the exit code."""
    radius, bearing = (f"{low:g} to {high:g}" for low, high in (PICK_RADIUS, PICK_BEARING))
    parser = ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=f"""Each trial: the tagged cube at a seeded random pose in reach
({radius} m from the shoulder_pan axis, bearing {bearing} deg, any
yaw), the target tag at the course's place position (or at random too:
--random-target). The arm turns its gripper up, out of the camera's view;
the overhead camera's image (640x480, a webcam's blur and noise) alone
gives both poses; the IK plans the course's pick-and-place; the measured
STS3215 servos move the arm, which starts only on a sighting at most
{MAX_POSE_AGE:g} s old. Placed: the cube's centre within {PLACE_TOLERANCE * 1000:g} mm of the target
tag's centre (the simulator's truth).

On an arm (--port, --camera) the last line says where the arm is and
whether it is torqued, as its servos read back, however the run ended.

Exit code: 0 done (even if a cube was not placed: the report says why;
unless --strict), 1 a cube not placed (with --strict), a run on the arm
aborted (a fault, a refused goal, a stop signal: its reason, then the arm's
last line) or an unexpected error, 2 bad input or, without --trials, no tag
in view or a cube out of reach (one line; nothing moved), 130 interrupted.""")
    parser.add_argument("--headless", action="store_true",
                        help="no viewer (this program always runs offscreen; a video with "
                        "--video)")
    parser.add_argument("--trials", type=number(1, MAX_TRIALS, integer=True), metavar="N",
                        help=f"run N trials, {range_help(1, MAX_TRIALS)}, and report each "
                        "(default: one trial, whose refusal is an error)")
    parser.add_argument("--seed", type=number(*SEED_RANGE, integer=True), default=0,
                        help="seed of the cube poses and the camera noise, a whole number "
                        f"{range_help(*SEED_RANGE)} (default %(default)s)")
    parser.add_argument("--cube", type=number(), nargs=3, metavar=("X", "Y", "YAW"),
                        help="put the cube here instead: X Y [m] on the table and YAW [deg] "
                        "(one trial)")
    parser.add_argument("--target", type=number(), nargs=3, metavar=("X", "Y", "YAW"),
                        help="the target tag's X Y [m] and YAW [deg] (default: the course's "
                        "place position)")
    parser.add_argument("--random-target", action="store_true",
                        help="each trial's target tag at a seeded random pose in reach too")
    parser.add_argument("--clean-images", action="store_true",
                        help="the camera's images as rendered (no webcam blur and noise)")
    parser.add_argument("--video", type=Path, metavar="PATH.mp4",
                        help="record the (first) trial, the camera's view inset")
    parser.add_argument("--json", type=Path, metavar="PATH", help="write the report as JSON")
    add_overwrite_argument(parser)
    arm = parser.add_argument_group("on an arm (through lerobot's bus and camera class)")
    arm.add_argument("--port", metavar="PORT",
                     help="the arm's serial port (the pty virtual_so101.py printed): look with "
                     "--camera, pick and place through lerobot's bus; needs --camera")
    arm.add_argument("--camera", metavar="ADDRESS",
                     help="the camera's address (virtual_so101.py --camera overhead printed "
                     "it) or a webcam (/dev/video0, or its index), opened by lerobot's camera "
                     "class; needs --port")
    arm.add_argument("--camera-calibration", type=Path, default=None, metavar="PATH",
                     help="a real camera's calibration: the report calibrate_camera.py --photos "
                     "DIR --mount fixed --json PATH wrote (default: the model's overhead "
                     "camera, exact for the virtual arm)")
    add_calibration_argument(arm)
    parser.add_argument("--strict", action="store_true",
                        help="exit 1 unless every trial placed its cube")
    parser.add_argument("-v", "--verbose", action="store_true",
                        help="show the traceback of an unexpected error")
    refused = (OutputPathError, PlanError, RenderError, CubePositionError, *ARM_NOT_STARTED)
    return run_script(parser, argv, _run, refused=refused,
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
                                  "report its own name, e.g. report.json.")
    return video, json_path


def _on_table(pose, option: str) -> tuple[float, float, float] | None:
    """``pose`` (X Y YAW) checked: X and Y on the table [m], YAW in [-180, 180] deg."""
    if pose is None:
        return None
    for axis, value, extent in zip("XY", pose[:2], table_extent(), strict=True):
        check_number(value, f"{option} {axis}", *extent, "m", error=CubePositionError,
                     fix=f"put it on the table, e.g. {option} 0.2 0.1 0")
    check_number(pose[2], f"{option} YAW", -180.0, 180.0, "deg", error=CubePositionError)
    return tuple(pose)


def _print_trial(index: int, result) -> None:
    seen = ("" if result.cube_seen_error_mm is None else
            f"; seen within {result.cube_seen_error_mm:.1f} mm, "
            f"{result.cube_seen_yaw_error_deg:.1f} deg")
    outcome = "placed" if result.success else f"FAILED ({result.reason})"
    print(f"Trial {index + 1}: cube at ({result.cube_true[0]:.3f}, {result.cube_true[1]:.3f}) m, "
          f"{result.cube_true[2]:.0f} deg{seen}; {outcome}, "
          f"{result.placed_error_mm:.1f} mm from the target")


def _run_on_arm(args: argparse.Namespace, json_path: Path | None) -> int:
    """--port and --camera: look, pick and place through lerobot; the run's ending as its last line.

    ``lab/see_and_pick_arm``; the last line is ``hw/run.ending``'s, from the servos' read-back.
    """
    from so101_kinematics.calibration import load_calibration
    from so101_kinematics.hw.run import RELEASE_HINT, ending
    from so101_kinematics.hw.signals import signals_as_interrupt
    from so101_kinematics.lab.see_and_pick_arm import ARM_PLACE_TOLERANCE, see_and_pick_on_arm
    from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH

    if not (args.port and args.camera):
        print(f"error: {'--port' if args.port else '--camera'} needs "
              f"{'--camera ADDRESS' if args.port else '--port PORT'}: the arm is driven through "
              "its port and looks through the camera. Fix: give both.", file=sys.stderr)
        return EXIT_BAD_INPUT
    calibration_path = args.calibration or DEFAULT_CALIBRATION_PATH
    calibration = load_calibration(calibration_path)
    try:  # SIGTERM and SIGHUP as Ctrl-C: the run's own stop during the motion, else exit 130
        with signals_as_interrupt():
            report, result = see_and_pick_on_arm(args.port, args.camera, calibration,
                                                 camera_calibration=args.camera_calibration)
    except VisionError as error:  # no tag in view, no camera, a bad calibration: nothing moved
        print(f"error: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT
    trial = report["trials"][0]
    print(f"Seen: cube at ({report['cube_seen'][0]:.3f}, {report['cube_seen'][1]:.3f}) m, "
          f"{report['cube_seen'][2]:.0f} deg; target at ({report['target_seen'][0]:.3f}, "
          f"{report['target_seen'][1]:.3f}) m")
    error = trial["placed_error_mm"]
    print(f"{'Placed' if trial['placed'] else 'NOT placed'} (within "
          f"{ARM_PLACE_TOLERANCE * 1000:g} mm): picked {trial['picked']}, "
          + ("no measure of the placement" if error is None else
             f"{error:.1f} mm from the target (by the {trial['placed_measured_by']})"))
    if json_path is not None:
        write_text_atomic(json_path, json.dumps(stamp(report, "see_and_pick.py"), indent=2)
                          + "\n")
    aborted = result.aborted is not None
    if aborted:
        print(f"ABORTED: {result.aborted}.", file=sys.stderr)
    release = RELEASE_HINT.format(port=args.port, arm=f"--calibration {calibration_path}")
    print(ending(result, release), file=sys.stderr if aborted else sys.stdout)
    return 1 if aborted or (args.strict and not trial["placed"]) else 0


def _run(args: argparse.Namespace) -> int:
    """Check the outputs, run, report (see :func:`main`)."""
    video, json_path = _check_outputs(args)
    if args.port or args.camera:
        return _run_on_arm(args, json_path)
    if args.camera_calibration is not None:
        print("error: --camera-calibration is a real camera's, for an arm: the simulator's "
              "camera is the model's. Fix: add --port PORT --camera ADDRESS, or leave it out.",
              file=sys.stderr)
        return EXIT_BAD_INPUT
    cube, target = _on_table(args.cube, "--cube"), _on_table(args.target, "--target")
    if args.target is not None and args.random_target:
        print("error: --target puts the target tag at one pose, --random-target at random "
              "ones. Fix: give one of them.", file=sys.stderr)
        return EXIT_BAD_INPUT
    if args.cube is not None and (args.trials or 1) > 1:
        print("error: --cube puts every trial's cube at one pose; --trials N repeats it. Fix: "
              "leave out --cube for random poses, or --trials.", file=sys.stderr)
        return EXIT_BAD_INPUT
    effects = None if args.clean_images else WEBCAM
    try:
        report = run_trials(args.trials or 1, args.seed, cube_at=cube,
                            target_at=target or course_target(), effects=effects,
                            random_target=args.random_target,
                            video=video, on_trial=_print_trial)
    except VisionError as error:  # a stale pose: nothing moved
        print(f"error: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT
    first = report["trials"][0]
    if args.trials is None and first["refused"]:
        print(f"error: {first['reason']}", file=sys.stderr)
        return EXIT_BAD_INPUT
    errors = report["placed_error_mm"]
    print(f"Placed {report['placed']} of {len(report['trials'])} within "
          f"{PLACE_TOLERANCE * 1000:g} mm (success rate {report['success_rate']:.0%})"
          + ("" if errors is None else
             f"; placement error mean {errors['mean']:.1f} mm, worst {errors['worst']:.1f} mm"))
    if json_path is not None:
        write_text_atomic(json_path, json.dumps(stamp(report, "see_and_pick.py"), indent=2)
                          + "\n")
    return 1 if args.strict and report["success_rate"] < 1.0 else 0


if __name__ == "__main__":
    sys.exit(main())

"""Test the IK in MuJoCo: the arm reaches random top-down cube targets (assignment 7, part 2b).

The course's files at the root are the project's one facade; ``so101_kinematics`` does the work.
"""

from __future__ import annotations

import so101_kinematics.display as so101_display  # first: EGL when there is no display

# isort: split
import argparse
import json
import logging
import secrets
import sys
import time
from dataclasses import replace
from pathlib import Path

from so101_inverse_kinematics import GRIPPER_OPEN, get_inverse_kinematics
from so101_kinematics.cli import (
    EXIT_FAILED,
    ArgumentParser,
    add_servo_arguments,
    hide_expert_options,
    number,
    range_help,
    run_script,
    servo_from_arguments,
    zero_duration_warning,
)
from so101_kinematics.errors import KinematicsInputError, OutputPathError, PlanError, RenderError
from so101_kinematics.inputs import MAX_DURATION
from so101_kinematics.outputs import (
    MP4,
    add_overwrite_argument,
    check_output_path,
    report_of,
    stamp,
    write_text_atomic,
)
from so101_kinematics.sim import actuation
from so101_kinematics.sim.ik_demo import (  # noqa: F401 - the pieces, for the tests
    POSITION_TOLERANCE,
    SERVO_POSITION_TOLERANCE,
    SERVO_YAW_TOLERANCE,
    TARGET_HEIGHT,
    YAW_TOLERANCE,
    DemoReport,
    Target,
    check_target,
    measure_target,
    open_scene,
    random_targets,
    show_cube,
    tolerances,
)
from so101_mujoco_utils import (
    ViewerClosed,
    get_command,
    hold_position,
    move_to_pose,
    send_position_command,
    set_initial_pose,
)

REPORT = report_of("test_ik_mujoco.py")  # --json replaces only a report of this program

log = logging.getLogger("test_ik_mujoco")

# The course's initial configuration: arm joints [deg], gripper [0, 100].
INITIAL_CONFIG = {
    "shoulder_pan": 0.0,
    "shoulder_lift": 0.0,
    "elbow_flex": 0.0,
    "wrist_flex": 0.0,
    "wrist_roll": 0.0,
    "gripper": 0.0,
}
MOVE_TIME = 1.0  # [s] to each target, as the course's script
HOLD_TIME = 2.0  # [s] at each target, as the course's script
TARGETS = 5  # targets per run, as the course's script
TARGETS_RANGE = (1, 100)
SEED_RANGE = (0, 999_999)


def reach_targets(m, d, viewer, targets, move_time: float = MOVE_TIME,
                  hold_time: float = HOLD_TIME, results: list | None = None) -> list:
    """The course's loop: show each target cube, solve the IK, move there, hold; measure each.

    Each target's result is appended to ``results`` (a new list by default) as
    soon as it is measured, so a run cut short keeps the ones done.
    """
    results = [] if results is None else results
    for target in targets:
        desired_position, desired_orientation = target.position, target.rotation  # Rz(yaw)
        show_cube(viewer, desired_position, desired_orientation)
        joint_configuration = get_inverse_kinematics(desired_position, desired_orientation,
                                                     initial=get_command(m, d),
                                                     gripper=GRIPPER_OPEN)
        move_to_pose(m, d, viewer, joint_configuration, move_time, raise_if_closed=True)
        hold_position(m, d, viewer, joint_configuration, hold_time, raise_if_closed=True)
        results.append(measure_target(m, d, target))
        log.info("target %d: %.2f mm, %.2f deg", len(results), results[-1].position_error_mm,
                 results[-1].yaw_error_deg)
    return results


def main(argv: list[str] | None = None) -> int:
    """Parse the command line, run the targets, print the report; returns the exit code."""
    durations = (0.0, MAX_DURATION, "s")
    parser = ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=f"""Each target is a 26 mm cube on the table (centre z = {TARGET_HEIGHT} m, as the
course's), shown as a translucent red cube; the arm reaches it with a top-down
grasp solved by get_inverse_kinematics, then holds. A target counts as reached
when the object frame ends within {SERVO_POSITION_TOLERANCE * 1e3:g} mm of the cube's centre and its
yaw within {SERVO_YAW_TOLERANCE:g} deg of the cube's (modulo 90 deg: a cube's sides are alike): the
measured STS3215 rests anywhere in its friction band (docs/servo.md); with
--servo ideal, {POSITION_TOLERANCE * 1e3:g} mm and {YAW_TOLERANCE:g} deg.

Modes: with a display, the interactive viewer (real time); --headless or no
display: no viewer, as fast as possible; --record PATH.mp4: an offscreen video.
Output files (--record, --json) are checked before the run (an existing file is
replaced only when it carries our marker: an MP4 of ours, a report of this script)
and written beside the target, then renamed over it when complete.

Exit code: 0 every target reached, 1 a target missed (the lines say which and
by how much) or an unexpected error (rerun with -v), 2 bad input, 130 Ctrl-C.""")
    parser.add_argument("--headless", action="store_true",
                        help="no viewer (automatic when there is no display)")
    parser.add_argument("--record", type=Path, metavar="PATH.mp4", help="record a video")
    parser.add_argument("--targets", type=number(*TARGETS_RANGE, integer=True), metavar="N",
                        help=f"random targets, {range_help(*TARGETS_RANGE)} (default {TARGETS})")
    parser.add_argument("--seed", type=number(*SEED_RANGE, integer=True), metavar="S",
                        help="random seed, to repeat a run (default: a new one, printed)")
    parser.add_argument("--target", type=number(), nargs=3, action="append",
                        metavar=("X", "Y", "YAW"),
                        help="a target instead of random ones: cube centre x, y [m] (z = "
                        f"{TARGET_HEIGHT}) and yaw [deg]; repeat for several")
    parser.add_argument("--move-duration", type=number(*durations), default=MOVE_TIME,
                        help=f"seconds per move, {range_help(*durations)} (default %(default)g)")
    parser.add_argument("--hold", type=number(*durations), default=HOLD_TIME,
                        help=f"seconds held at each target, {range_help(*durations)} "
                        "(default %(default)g)")
    parser.add_argument("--json", type=Path, metavar="PATH", help="write the report as JSON")
    add_servo_arguments(parser)
    add_overwrite_argument(parser)
    parser.add_argument("--ui", action="store_true", help="viewer: show MuJoCo's side panels")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("-v", "--verbose", action="store_true",
                        help="log each target (and show the traceback of an unexpected error)")
    hide_expert_options(parser, {"servo", "supply", "variant", "p_coefficient", "gravity_ff",
                                 "overwrite", "no_progress"})  # --help-all lists them
    return run_script(parser, argv, _run, refused=(PlanError, OutputPathError,
                                                   KinematicsInputError, RenderError))


def _run(args: argparse.Namespace) -> int:
    """Check the outputs and the targets, run, report (see :func:`main`)."""
    video = json_path = None
    if args.record is not None:
        video = check_output_path(args.record, "--record", suffixes=(".mp4",), kind=MP4,
                                  overwrite=args.overwrite)
    if args.json is not None:
        json_path = check_output_path(args.json, "--json", kind=REPORT,
                                      overwrite=args.overwrite)
        if json_path == video:
            raise OutputPathError(f"--json {args.json}: is the --record file too. Fix: give "
                                  "the report its own name, e.g. report.json.")
    if args.target:
        if args.seed is not None or args.targets is not None:
            raise PlanError("--targets and --seed draw random targets, --target gives them. "
                            "Fix: use one or the other.")
        targets = [check_target(x, y, yaw, f"--target {i}")
                   for i, (x, y, yaw) in enumerate(args.target, 1)]
        seed = None
    else:
        seed = secrets.randbelow(SEED_RANGE[1] + 1) if args.seed is None else args.seed
        targets = random_targets(args.targets or TARGETS, seed)
        print(f"{len(targets)} random targets, seed {seed} (repeat with --seed {seed})")

    if zero_duration_warning(args.move_duration, args.hold):
        print(zero_duration_warning(args.move_duration, args.hold), file=sys.stderr)
    mode = "record" if video else "headless" if args.headless else "viewer"
    if mode == "viewer" and not so101_display.has_display():
        print("No display found: running headless.", file=sys.stderr)
        mode = "headless"
    report = DemoReport(targets_asked=len(targets), seed=seed,
                        video=str(video) if video else None)
    total = len(targets) * (args.move_duration + args.hold)
    wall0 = time.perf_counter()
    with open_scene(mode, video, total_time=total, progress=not args.no_progress,
                    show_ui=args.ui, servo=servo_from_arguments(args)) as (m, d, viewer):
        position_tolerance, yaw_tolerance = tolerances(m)
        report = replace(report, position_tolerance_mm=position_tolerance * 1e3,
                         yaw_tolerance_deg=yaw_tolerance,
                         servo=actuation.servo_spec(m).describe())
        set_initial_pose(d, INITIAL_CONFIG)
        send_position_command(d, INITIAL_CONFIG)
        try:
            reach_targets(m, d, viewer, targets, args.move_duration, args.hold, report.results)
            if mode == "viewer":
                print("Done: close the viewer window to see the report.", file=sys.stderr)
                while True:  # the arm keeps holding the last target, in real time
                    hold_position(m, d, viewer, 0.1, raise_if_closed=True)
        except ViewerClosed:
            log.info("Viewer closed.")
        report = replace(report, sim_time_s=float(d.time),
                         wall_time_s=time.perf_counter() - wall0,
                         frames_written=getattr(viewer, "frames_written", 0))
    print(report.summary())
    if json_path is not None:
        write_text_atomic(json_path, json.dumps(stamp(report.as_json(), "test_ik_mujoco.py"),
                                                 indent=2) + "\n")
    if report.success:
        return 0
    for line in report.misses():
        print(f"missed: {line}", file=sys.stderr)
    if len(report.results) < len(targets):
        print(f"The viewer was closed after {len(report.results)} of {len(targets)} targets.",
              file=sys.stderr)
    return EXIT_FAILED


if __name__ == "__main__":
    sys.exit(main())

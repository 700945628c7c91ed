"""Pick-and-place on a real SO-101 follower through lerobot's FeetechMotorsBus, safe by default.

The course's files at the root are the project's one facade; ``so101_kinematics`` does the work.
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from so101_kinematics import outputs
from so101_kinematics.calibration import calibrated_limits, find_calibration, load_calibration
from so101_kinematics.clearance import check_plan_clearance
from so101_kinematics.cli import (
    ArgumentParser,
    StoreGiven,
    add_moved_options,
    hide_expert_options,
    ignored_with_plan,
)
from so101_kinematics.commands.so101_command import MOVED_FROM_HW
from so101_kinematics.errors import (
    CalibrationError,
    HardwareError,
    LerobotMissing,
    NotConfirmed,
    PlanError,
)
from so101_kinematics.hw.bus import clamp_to_limits, connect, disconnect, read_pose
from so101_kinematics.hw.home_check import add_calibration_check_arguments, home_check
from so101_kinematics.hw.log import (
    LOG_KIND,
    SIDECAR_KIND,
    CycleLog,
    plan_record,
    plot_log,
    sidecar_path,
)
from so101_kinematics.hw.options import add_loop_arguments
from so101_kinematics.hw.port import FIND_PORT_HINT
from so101_kinematics.hw.preflight import check_run_settings, validate_plan_for_arm
from so101_kinematics.hw.run import RELEASE_HINT, MotionAborted, ending, release_arm, run_on_arm
from so101_kinematics.hw.signals import signals_as_interrupt
from so101_kinematics.hw.teach import format_configuration, format_plan, outcome_lines, teach
from so101_kinematics.hw.timing import speed_caps
from so101_kinematics.inputs import check_number
from so101_kinematics.planning import stacking
from so101_kinematics.planning.cartesian_plan import add_cartesian_arguments, plan_from_arguments
from so101_kinematics.planning.plans import default_plan, load_plan
from so101_kinematics.planning.straight_line import (
    add_approach_arguments,
    cycle_deviations,
    describe,
    plan_for_approach,
)
from so101_kinematics.trims import load_trims

logger = logging.getLogger("pick_place_hw")

MAX_MOVE_DURATION_S = 60.0  # longest move or hold of the built-in plan [s]


def ask(question: str, assume_yes: bool, stdin=None) -> bool:
    """Ask yes/no on a terminal; ``assume_yes`` answers yes; NotConfirmed on a non-terminal."""
    if assume_yes:
        return True
    stdin = stdin or sys.stdin
    if not (hasattr(stdin, "isatty") and stdin.isatty()):
        raise NotConfirmed(f"{question} - cannot ask: stdin is not a terminal. Pass --yes to run "
                           "without confirmation.")
    print(f"{question} [y/N] ", end="", flush=True)
    return stdin.readline().strip().lower() in ("y", "yes")


EXPERT = {"move_duration", "hold", "velocity_ff", "rate", "max_speed", "tracking_tolerance",
          "teach", "trims", "gravity_ff", "write_calibration", "no_return_on_abort", "overwrite",
          "cube_yaw", "lift_height", "blocks", "block", "base_height", "approach",
          "straight_method"}  # accepted, listed by --help-all only: tuning and experiments


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface: the week's options; --help-all lists the expert ones too."""
    parser = ArgumentParser(
        description="The course's pick-and-place on a real SO-101 follower (lerobot Feetech "
                    "bus): the plan checked before torque on, then a loop that sends a goal and "
                    "reads the arm back every cycle. Any stop ends with a slow return to the start "
                    "and the torque released there, never elsewhere (docs/hardware_safety.md).",
        epilog="Examples:\n  python pick_place_hw.py --calibration my_arm.json --dry-run\n"
               "  python pick_place_hw.py --port /dev/ttyACM0 --id my_arm --log run.csv "
               "--plot run.png\n"
               "  python pick_place_hw.py --port /dev/ttyACM0 --id my_arm --release\n"
               "The placement sheet: `so101 sheet PATH.pdf`; the pose live by hand: "
               "read_position.py.",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--port", help=f"serial port of the arm (find it with `{FIND_PORT_HINT}`)")
    who = parser.add_mutually_exclusive_group()
    who.add_argument("--id", dest="robot_id",
                     help="robot id given to lerobot-calibrate; the calibration is read from "
                          "$HF_LEROBOT_CALIBRATION/robots/so_follower/ID.json (or so101_follower/)")
    who.add_argument("--calibration", type=Path, help="lerobot calibration JSON file of this arm")
    parser.add_argument("--plan", type=Path, help="waypoint file (JSON or TOML) instead of the "
                        "course's plan")
    parser.add_argument("--move-duration", type=float, default=2.0, action=StoreGiven,
                        help="duration of each move of the built-in plan [s] "
                             f"(0-{MAX_MOVE_DURATION_S:g}, default 2)")
    parser.add_argument("--hold", type=float, default=0.5, action=StoreGiven,
                        help="pause after each move of the built-in plan [s] "
                             f"(0-{MAX_MOVE_DURATION_S:g}, default 0.5)")
    add_loop_arguments(parser)
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--dry-run", action="store_true",
                      help="validate and print the plan and cube positions; send nothing")
    mode.add_argument("--teach", action="store_true",
                      help="torque off; print the pose live as a configuration and its FK "
                           "object position")
    mode.add_argument("--release", action="store_true",
                      help="release the torque of every servo (hold the arm: it falls)")
    add_calibration_check_arguments(parser, mode)
    parser.add_argument("--yes", "-y", action="store_true",
                        help="do not ask before enabling (or releasing) torque")
    parser.add_argument("--write-calibration", action="store_true",
                        help="if the servos hold another calibration, write the file into them")
    parser.add_argument("--no-return-on-abort", action="store_true",
                        help="after an abort, hold where the arm stopped (torque on) instead of "
                             "returning to the start")
    parser.add_argument("--log", type=Path,
                        help="CSV of time, commanded and measured joints per cycle (written as "
                             "the run goes; an earlier run's log is never replaced)")
    parser.add_argument("--plot", type=Path, help="PNG of commanded vs measured per joint")
    outputs.add_overwrite_argument(parser)
    parser.add_argument("--verbose", "-v", action="store_true", help="debug logging")
    add_cartesian_arguments(parser)
    stacking.add_stack_arguments(parser)
    add_approach_arguments(parser)
    add_moved_options(parser, MOVED_FROM_HW)
    hide_expert_options(parser, EXPERT)
    return parser


def _dry_run(args, plan, calibration) -> int:
    caps = speed_caps(args.max_speed)
    start = None
    if args.port:
        try:
            bus = connect(args.port, calibration, robot_id=args.robot_id)
        except LerobotMissing as error:
            logger.warning("%s Showing the plan without reading the arm.", error)
        else:
            try:
                measured = read_pose(bus, retries=2)
                start = clamp_to_limits(measured, calibrated_limits(calibration))
                print("Measured starting pose: " + format_configuration(measured))
                check_plan_clearance(plan, start, base_height=args.base_height)  # + the ramp
            finally:
                disconnect(bus)
    print(format_plan(plan, rate_hz=args.rate, profile=args.profile, max_speed=caps, start=start))
    print("Dry run: the plan is valid; nothing was sent to the arm.")
    return 0


def _run(args, plan, calibration, source, release: str, stack=None) -> int:
    print(format_plan(plan, rate_hz=args.rate, profile=args.profile,
                      max_speed=speed_caps(args.max_speed)))

    def on_start(start, first_duration):
        print("Starting pose (returned to at the end): " + format_configuration(start))
        if log is not None:
            log.run_info["start_pose"] = dict(start)
        print(f"First move: to '{plan.steps[0].name}' in {first_duration:.2f} s, ramping from "
              "this pose.")

    log = CycleLog(args.log, {"plan": plan_record(plan), "rate_hz": args.rate, "profile":
                              args.profile, "calibration": str(source), "robot_id": args.robot_id}
                   ) if args.log else None
    try:
        result = run_on_arm(
            args.port, calibration, plan, robot_id=args.robot_id, source=str(source),
            rate_hz=args.rate, profile=args.profile, max_joint_speed=args.max_speed,
            tracking_tolerance=args.tracking_tolerance, confirm=lambda q: ask(q, args.yes),
            write_calibration=args.write_calibration,
            return_on_abort=not args.no_return_on_abort, on_cycle=log, on_start=on_start,
            trims=args.trims, gravity_ff=args.gravity_ff, base_height=args.base_height,
            velocity_ff=args.velocity_ff)
        status = 0
    except MotionAborted as error:
        print(f"ABORTED: {error}", file=sys.stderr)
        result, status = error.result, 1
    except BaseException:
        if log is not None:
            log.discard()  # refused before anything moved: an existing log stays as it was
        raise
    lines = cycle_deviations(plan, result.cycles) if args.approach == "straight" else None
    if log is not None and lines is not None:
        log.run_info["straight_path_deviation_mm"] = lines
    if log is not None:
        log.run_info["aborted"] = result.aborted  # --compare keeps an aborted run apart
        print(f"Log: {log.close()} ({log.rows} cycles)")
    if args.plot and result.cycles:
        print(f"Plot: {plot_log(result.cycles, args.plot)}")
    for line in outcome_lines(plan, result, stack):
        print(line)
    if lines is not None:
        print(describe(lines, args.straight_method))
    print(ending(result, release), file=sys.stderr if status else sys.stdout)
    return status


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status (0 done, 1 aborted or failed, 2 refused)."""
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as stop:  # a bad option (one line printed) or --help: its exit code
        return stop.code
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.INFO,
                        format="%(levelname)s: %(message)s")
    try:
        with signals_as_interrupt():
            return _main(args)
    except (HardwareError, PlanError, ValueError) as error:
        print(f"Refused, nothing moved: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as error:
        print(f"Interrupted ({error or 'Ctrl-C'}) before the arm moved.", file=sys.stderr)
        return 130
    except Exception as error:  # noqa: BLE001 - one line, not a traceback
        if args.verbose:
            raise
        print(f"Unexpected error: {type(error).__name__}: {error}. Rerun with -v for the "
              "traceback.", file=sys.stderr)
        return 1


def _main(args) -> int:
    check_number(args.move_duration, "--move-duration", 0.0, MAX_MOVE_DURATION_S, "s")
    check_number(args.hold, "--hold", 0.0, MAX_MOVE_DURATION_S, "s")
    check_run_settings(args.rate, args.max_speed, args.tracking_tolerance)
    if ignored_with_plan(args):
        raise PlanError(ignored_with_plan(args))
    trims = args.trims and load_trims(args.trims)  # a dry run checks them as a real run does
    stack = stacking.stack_from_arguments(args)
    plan = stack.plan if stack else plan_from_arguments(args) or (
        load_plan(args.plan) if args.plan else default_plan(args.move_duration, args.hold))
    plan = plan_for_approach(args, plan, 1.0 / args.rate, stack)
    source = args.calibration or (find_calibration(args.robot_id, args.port)
                                  if args.robot_id else None)
    calibration = load_calibration(source, args.robot_id) if source is not None else None
    if calibration is None and not args.dry_run:
        raise CalibrationError("Tell me which arm: --id ROBOT_ID (the id you gave "
                               "lerobot-calibrate) or --calibration PATH.")
    if source is not None:
        logger.info("Calibration: %s", source)
    validate_plan_for_arm(plan, calibration, str(source), trims, base_height=args.base_height)
    if stack is not None:
        print(stack.describe())
    for option, path, kind in (("--log", args.log, LOG_KIND), ("--plot", args.plot, outputs.PNG),
                               ("--log's sidecar", args.log and sidecar_path(args.log),
                                SIDECAR_KIND)):
        if path is not None:
            outputs.check_output_path(path, option, inputs=(source, args.plan, args.trims),
                                      kind=kind, overwrite=args.overwrite)
    if args.dry_run:
        if calibration is None:
            logger.warning("No calibration given: checked against the model's limits only.")
        return _dry_run(args, plan, calibration)
    arm = f"--id {args.robot_id}" if args.robot_id else f"--calibration {source}"
    release = RELEASE_HINT.format(port=args.port, arm=arm)
    if args.release:
        unreleased = release_arm(args.port, calibration, robot_id=args.robot_id,
                                 confirm=lambda q: ask(q, args.yes))
        if unreleased:
            print(f"Torque could NOT be released on {', '.join(unreleased)} (not answering): "
                  "check that servo's cable and power, then run this again.", file=sys.stderr)
            return 1
        print("Torque off on every servo.")
        return 0
    if args.teach:
        bus = connect(args.port, calibration, robot_id=args.robot_id)
        try:
            teach(bus)
        finally:
            disconnect(bus)
        return 0
    if args.home_check:
        return home_check(args, calibration, source, release, lambda q: ask(q, args.yes))
    return _run(args, plan, calibration, source, release, stack)


if __name__ == "__main__":
    sys.exit(main())

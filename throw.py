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
from so101_kinematics.cli import (
    NOTHING_WRITTEN,
    ArgumentParser,
    add_calibration_argument,
    number,
    range_help,
    run_script,
)
from so101_kinematics.errors import (
    ARM_NOT_STARTED,
    NotConfirmed,
    OutputPathError,
    PlanError,
    TagNotInView,
)
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
from so101_kinematics.throwing.cup_camera import (
    build_cup_camera_model,
    look_at_cups,
    save_camera_image,
    throw_at_seen_cups,
)
from so101_kinematics.throwing.throw_scene import build_throw_model
from so101_kinematics.throwing.throw_trials import (
    cup_positions,
    run_throws,
    save_picture,
    save_video,
)

REPORT = report_of("throw.py")  # --json replaces only a report of this program
TRIALS_RANGE = (1, 100)
SIM_TRIALS = 10  # the ten seeded cups; one on an arm (a ball put back by hand)
SEED_RANGE = (0, 999_999)
ARM_TRIALS_RANGE = (1, 5)  # on an arm: a ball put back by hand before each throw
DELAY_RANGE = (0.02, 0.5)  # [s]: --opening-delay (the simulator's is 0.15 s at the wind-up)
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

With --port the throw runs on an arm through lerobot's bus; its JSON's landing
is predicted from the release read back (model_error_basis says how), and the
last line is the arm's, read back from the servos.

Exit code: 0 thrown, 2 bad input (one line; nothing thrown), 1 an unexpected
error (or, with --port, a run the fault policy aborted), 130 interrupted.""")
    parser.add_argument("--trials", type=number(*TRIALS_RANGE, integer=True), default=None,
                        metavar="N", help=f"throws at seeded cups, {range_help(*TRIALS_RANGE)} "
                        f"(default {SIM_TRIALS}; 1 with --port)")
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
    parser.add_argument("--find-cup", action="store_true",
                        help="aim at the cup the fixed camera finds (its mat's ArUco tag, part "
                        "1's detector); the cups still stand at --cup or the seeded places")
    parser.add_argument("--camera-image", type=Path, metavar="PATH.png",
                        help="with --find-cup: the camera's view of the first cup, the tag "
                        "found drawn")
    arm = parser.add_argument_group("on an arm (through lerobot's bus; the virtual arm too)")
    arm.add_argument("--port", metavar="PORT",
                     help="the arm's serial port (virtual_so101.py prints the virtual arm's): "
                     "the same throw through lerobot's bus, planned at the supply the servos "
                     "read; the JSON's landing is predicted from the release read back (no "
                     f"ball is observed); --trials up to {ARM_TRIALS_RANGE[1]}, a ball put "
                     "back in the jaws before each (asked)")
    add_calibration_argument(arm)
    arm.add_argument("--measure-opening", action="store_true",
                     help="measure the gripper's opening delay at rest on the arm (at the "
                     "throw's wind-up) and print it; nothing is thrown")
    arm.add_argument("--opening-delay", type=number(*DELAY_RANGE, "s"), metavar="S",
                     help="the arm's opening delay at rest as --measure-opening printed it "
                     f"({range_help(*DELAY_RANGE, 's')}): the gripper opens earlier or later "
                     "by its difference from the simulator's (default: the simulator's)")
    arm.add_argument("--yes", "-y", action="store_true",
                     help="do not ask before each throw (the virtual arm: it has no ball)")
    add_overwrite_argument(parser)
    parser.add_argument("-v", "--verbose", action="store_true",
                        help="show the traceback of an unexpected error")
    refused = (OutputPathError, PlanError, *ARM_NOT_STARTED, NotConfirmed, TagNotInView)
    return run_script(parser, argv, _run, refused=refused,
                      interrupted=NOTHING_WRITTEN)


def _outputs(args: argparse.Namespace) -> dict[str, Path | None]:
    """The output paths, checked before anything runs."""
    kinds = {"json": (REPORT, ()), "video": (MP4, (".mp4",)), "image": (PNG, (".png",)),
             "camera_image": (PNG, (".png",))}
    paths: dict[str, Path | None] = {}
    for name, (kind, suffixes) in kinds.items():
        given = getattr(args, name)
        paths[name] = None if given is None else check_output_path(
            given, "--" + name.replace("_", "-"), (), args.overwrite, suffixes=suffixes,
            kind=kind)
    chosen = [p for p in paths.values() if p is not None]
    if len(set(chosen)) < len(chosen):
        raise OutputPathError("two outputs share one file name. Fix: give --json, --video, "
                              "--image and --camera-image their own names.")
    return paths


def _run(args: argparse.Namespace) -> int:
    """Check the inputs, throw, report (see :func:`main`)."""
    if args.camera_image is not None and not args.find_cup:
        raise PlanError(f"--camera-image {args.camera_image}: the camera's view is taken only "
                        "when it looks for the cup. Fix: add --find-cup.")
    if args.find_cup and args.port:
        raise PlanError("--find-cup with --port: the cup is found by the simulator's camera only "
                        "(nothing was moved). Fix: measure where the cup stands and give it as "
                        "--cup X Y, or leave out --port.")
    paths = _outputs(args)
    if args.port:
        return _throw_on_arm(args, paths)
    for option in ("measure_opening", "opening_delay", "calibration"):
        if getattr(args, option) not in (None, False):
            flag = "--" + option.replace("_", "-")
            raise PlanError(f"{flag} is for an arm: it needs --port PORT (nothing was thrown). "
                            f"Fix: add --port, or leave out {flag}.")
    ball = BALLS[args.ball]
    variant = "C018"  # SUPPLY_RANGE's servo (its 9 V end too, where default_variant says C001)
    servo_keywords = {"volts": args.supply, "variant": variant}
    cups = [tuple(args.cup)] if args.cup else cup_positions(args.trials or SIM_TRIALS, args.seed)
    if args.find_cup:
        m = build_cup_camera_model(ball, servo_keywords)
        looks = look_at_cups(m, cups, args.seed)  # every cup seen before anything is thrown
        report = throw_at_seen_cups(m, ball, cups, args.seed, args.supply, variant, looks)
    else:
        m = build_throw_model(ball, servo_keywords)
        report = run_throws(m, ball, cups, args.supply, variant)
    report["seed"] = None if args.cup else args.seed
    for number_, trial in enumerate(report["trials"], 1):
        where = "in the cup" if trial["in_cup"] else "missed"
        error = trial["model_error_m"]
        seen = ("" if "cup_seen_error_mm" not in trial else
                f" (the camera found it {trial['cup_seen_error_mm']:.1f} mm off)")
        print(f"throw {number_}: cup {trial['cup_distance_m']:.3f} m away{seen}, released at "
              f"{trial.get('release_speed_m_s', float('nan')):.2f} m/s: {where}; model "
              + ("-" if error is None else f"{1000 * error:.1f} mm") + " from the first touch")
    worst = report["worst_model_error_m"]
    print(f"{report['hits']}/{report['throws']} in the cup; the forward model within "
          + ("-" if worst is None else f"{1000 * worst:.1f} mm") + " of every first touch"
          + ("" if not args.find_cup else "; the camera found the cups "
             f"{report['cup_seen_error_mm']['mean']:.1f} mm off on average, "
             f"{report['cup_seen_error_mm']['worst']:.1f} mm at worst"))
    if paths["camera_image"] is not None:
        save_camera_image(paths["camera_image"], looks[0], cups[0])
    aim = report["trials"][0].get("cup_seen_xy")  # --find-cup: where the camera saw it
    if paths["video"] is not None:
        save_video(paths["video"], m, ball, cups[0], args.supply, variant, aim)
    if paths["image"] is not None:
        save_picture(paths["image"], m, ball, cups[0], args.supply, variant, aim)
    if paths["json"] is not None:
        write_text_atomic(paths["json"], json.dumps(stamp(report, "throw.py"), indent=2) + "\n")
    return 0


def _throw_on_arm(args: argparse.Namespace, paths: dict[str, Path | None]) -> int:
    """--port: the throw (or --measure-opening) through lerobot's bus; the ending last.

    ``lab/throw_arm.py``; each run's last line is ``hw/run.ending``'s, from the servos'
    read-back, and the program's last line is the last run's.
    """
    from pick_place_hw import ask
    from so101_kinematics.calibration import load_calibration
    from so101_kinematics.hw.run import RELEASE_HINT, ending
    from so101_kinematics.hw.signals import signals_as_interrupt
    from so101_kinematics.lab.throw_arm import (
        arm_report,
        measure_opening_on_arm,
        opening_line,
        read_supply,
        throw_on_arm,
    )
    from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH

    for name in ("video", "image"):
        if paths[name] is not None:
            raise PlanError(f"--{name} with --port: the arm's throw has no simulated ball to "
                            f"film (nothing was moved). Fix: leave out --{name}, or throw in "
                            "the simulator first.")
    low, high = ARM_TRIALS_RANGE
    args.trials = args.trials or 1
    if not (args.cup or args.measure_opening) and not low <= args.trials <= high:
        raise PlanError(f"--trials {args.trials} with --port: on an arm a ball is put back in the "
                        f"jaws by hand before each throw, so {range_help(*ARM_TRIALS_RANGE)} "
                        f"(nothing was moved). Fix: --trials {ARM_TRIALS_RANGE[1]} or fewer.")
    calibration_path = args.calibration or DEFAULT_CALIBRATION_PATH
    calibration = load_calibration(calibration_path)
    release = RELEASE_HINT.format(port=args.port, arm=f"--calibration {calibration_path}")
    ball = BALLS[args.ball]
    volts = read_supply(args.port, calibration)  # the servos' own supply: nothing moves
    m = build_throw_model(ball, {"volts": volts, "variant": servo.default_variant(volts)})
    if args.measure_opening:
        with signals_as_interrupt():
            opening, result = measure_opening_on_arm(
                args.port, calibration, m, ball, volts=volts,
                confirm=lambda _: ask("Measure the gripper's opening delay: the arm goes to the "
                                      "throw's wind-up, opens its gripper and comes back. Enable "
                                      "torque?", args.yes))
        print(opening_line(args.port, opening))
        if paths["json"] is not None:
            write_text_atomic(paths["json"], json.dumps(stamp(opening, "throw.py"), indent=2)
                              + "\n")
        return _end_of_run(result, release, ending)
    cups = [tuple(args.cup)] if args.cup else cup_positions(args.trials, args.seed)
    trials, result = [], None
    for k, cup in enumerate(cups, 1):
        question = (f"Throw {k}/{len(cups)} at the cup at ({cup[0]:.3f}, {cup[1]:.3f}) m: put a "
                    "ball between the jaws (the torque is off: open them by hand), stand clear "
                    "of the swing. Enable torque and throw?")
        with signals_as_interrupt():  # SIGTERM as Ctrl-C; during the motion the run's own stop
            trial, result = throw_on_arm(args.port, calibration, m, ball, cup, volts=volts,
                                         opening_delay=args.opening_delay,
                                         confirm=lambda _, q=question: ask(q, args.yes))
        trials.append(trial)
        landing = trial.get("predicted_landing")
        print(f"throw {k}: cup {trial['cup_distance_m']:.3f} m away, released (read back) at "
              + ("-" if landing is None else
                 f"{trial['release_speed_m_s']:.2f} m/s, predicted to land "
                 f"{1000 * trial['predicted_miss_m']:.0f} mm from the cup's centre: "
                 + ("in the cup" if trial["in_cup"] else "missed")
                 + f"; {1000 * trial['model_error_m']:.1f} mm from the simulator's landing")
              + ("" if trial["aborted"] is None else f"; ABORTED ({trial['aborted']})"))
        if result.aborted is not None:
            break
    report = arm_report(args.port, volts, None if args.cup else args.seed, ball, trials)
    print(f"{report['hits']}/{report['throws']} predicted in the cup from the read-back "
          "releases (no ball is observed on an arm)")
    if paths["json"] is not None:
        write_text_atomic(paths["json"], json.dumps(stamp(report, "throw.py"), indent=2) + "\n")
    return _end_of_run(result, release, ending)


def _end_of_run(result, release: str, ending) -> int:
    """The last line (the servos' read-back) and the exit code: 1 when the run was aborted."""
    aborted = result.aborted is not None
    if aborted:
        print(f"ABORTED: {result.aborted}.", file=sys.stderr)
    print(ending(result, release), file=sys.stderr if aborted else sys.stdout, flush=True)
    return 1 if aborted else 0


if __name__ == "__main__":
    sys.exit(main())

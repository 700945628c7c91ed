"""Test trajectories in MuJoCo: the course's week-9 sequence, profile by profile (assignment 9).

The course's files at the root are the project's one facade; ``so101_kinematics`` does the work.
"""

from __future__ import annotations

import so101_kinematics.display as so101_display  # first: EGL when there is no display

# isort: split
import argparse
import json
import logging
import sys
from contextlib import contextmanager
from pathlib import Path

import mujoco

from so101_kinematics.cli import (
    ArgumentParser,
    add_servo_arguments,
    hide_expert_options,
    run_script,
    servo_from_arguments,
)
from so101_kinematics.errors import KinematicsInputError, OutputPathError, PlanError, RenderError
from so101_kinematics.outputs import (
    MP4,
    PNG,
    add_overwrite_argument,
    check_output_path,
    report_of,
    stamp,
    write_text_atomic,
)
from so101_kinematics.outputs import atomic_output as _atomic_output
from so101_kinematics.planning.profiles import PROFILES
from so101_kinematics.planning.straight_line import METHODS
from so101_kinematics.servo import DEFAULT_SUPPLY_V
from so101_kinematics.sim import actuation, straight, tracking
from so101_kinematics.sim.ik_demo import open_scene
from so101_mujoco_utils import MODEL_DIR, ViewerClosed, load_model

REPORT = report_of("test_trajectory_mujoco.py")  # --json replaces only a report of this program

log = logging.getLogger("test_trajectory_mujoco")

VELOCITY_SCENE = MODEL_DIR / "scene_with_velocity.xml"  # the course's week-9 model
DEFAULT_PROFILE = "cubic"  # the assignment's
SERVO_DEFAULTS = {"mode": "sts3215", "volts": DEFAULT_SUPPLY_V, "variant": None, "p": 16,
                  "feedforward": True}
COLUMNS = (("tracking_rms_deg", "RMS [deg]", ".2f"), ("tracking_max_deg", "max [deg]", ".2f"),
           ("peak_velocity_deg_s", "peak vel [deg/s]", ".1f"),
           ("peak_acceleration_deg_s2", "peak acc [deg/s^2]", ".0f"),
           ("peak_jerk_deg_s3", "peak jerk [deg/s^3]", ".0f"))


@contextmanager
def open_model(args: argparse.Namespace, mode: str, video: Path | None, total_time: float):
    """``(m, d, viewer, what drives the arm)``: the velocity scene or the servo model.

    The viewer (``mode``: "viewer", "headless" or "record") is closed however the
    block ends; a video is renamed over ``video`` only when the block succeeds.
    """
    if not (args.velocity or args.velocity_scene):
        with open_scene(mode, video, total_time=total_time, progress=not args.no_progress,
                        servo=servo_from_arguments(args)) as (m, d, viewer):
            yield m, d, viewer, actuation.servo_spec(m).describe()
        return
    option = "--velocity" if args.velocity else "--velocity-scene"
    if servo_from_arguments(args) != SERVO_DEFAULTS:
        raise PlanError(f"{option} runs the course's velocity scene on its own gains; the "
                        "servo options (--servo, --supply, --variant, --p-coefficient, "
                        f"--no-gravity-ff) choose the STS3215 model. Fix: leave them out "
                        f"with {option}, or drop {option}.")
    if mode == "record":
        raise PlanError(f"--record films the course scene; {option} runs the velocity scene. "
                        f"Fix: record without {option}, or use the viewer.")
    m = load_model(VELOCITY_SCENE)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    fed = "the velocity fed forward" if args.velocity else "velocity commands 0"
    viewer = so101_display.launch_viewer(m, d) if mode == "viewer" else None
    try:
        yield m, d, viewer, ("the course's velocity scene (position kp 50, kv 2; velocity "
                             f"kv 10), {fed}")
    finally:
        if viewer is not None:
            so101_display.close_viewer(viewer)


def table(results: dict[str, dict[str, float]]) -> str:
    """The figures, one line per profile."""
    lines = ["profile       " + "  ".join(f"{title:>19}" for _, title, _ in COLUMNS)]
    for name, figures in results.items():
        lines.append(f"{name:<13} " + "  ".join(f"{figures[key]:>19{form}}"
                                                for key, _, form in COLUMNS))
    return "\n".join(lines)


def refuse_ranking(touched: dict[str, dict], profiles: int, sagging: bool) -> str | None:
    """The table contacts (a line per profile), then why no ranking, and the fix.

    ``sagging``: the servos run without the feed-forward. None when no profile touched it.
    """
    if not touched:
        return None
    lines = [f"table contact: {name}: the {c['body']}'s {c['geom']} on the table, up to "
             f"{c['force_n']:.1f} N (t = {c['t_s']:.2f} s, {c['where']})"
             for name, c in touched.items()]
    lines.append(f"Not ranked: {len(touched)} of {profiles} profile(s) struck the table (above), "
                 "so their peak acceleration and jerk are the impact's, not the profile's. "
                 + ("Fix: keep the gravity feed-forward (leave out --no-gravity-ff), so the "
                    "jaw stays clear of the table." if sagging else "Fix: compare them on a "
                    "servo that holds the jaw clear (the default STS3215 with its feed-forward)."))
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Check the outputs, run each profile on the page's sequence, report (see :func:`main`)."""
    json_path = plot_path = None
    if args.json is not None:
        json_path = check_output_path(args.json, "--json", kind=REPORT,
                                      overwrite=args.overwrite)
    if args.plot is not None:
        plot_path = check_output_path(args.plot, "--plot", suffixes=(".png",), kind=PNG,
                                      overwrite=args.overwrite)
        if plot_path == json_path:
            raise OutputPathError(f"--plot {args.plot}: is the --json file too. Fix: give the "
                                  "plot its own name, e.g. tracking.png.")
    video = None
    if args.record is not None:
        video = check_output_path(args.record, "--record", suffixes=(".mp4",), kind=MP4,
                                  overwrite=args.overwrite)
        if video in (json_path, plot_path):
            raise OutputPathError(f"--record {args.record}: is another output too. Fix: give "
                                  "the video its own name, e.g. week9.mp4.")
    profiles = list(PROFILES) if args.compare else [args.profile]
    mode = "record" if video else "headless" if args.headless else "viewer"
    if mode == "viewer" and not so101_display.has_display():
        print("No display found: running headless.", file=sys.stderr)
        mode = "headless"
    per_profile = tracking.SETTLE_S + 3 * (tracking.MOVE_S + tracking.HOLD_S)
    lines_s = 2 * (2 * straight.SETTLE_S + straight.DURATION_S) if args.straight else 0.0
    logs, lines = {}, {}
    total_s = per_profile * len(profiles) + lines_s
    with open_model(args, mode, video, total_s) as (m, d, viewer, driven_by):
        try:
            for name in profiles:
                log.info("profile %s", name)
                logs[name] = tracking.run_week9(m, d, viewer, name, velocity=bool(args.velocity))
            for method in METHODS if args.straight else ():
                log.info("straight line: %s", method)
                lines[method] = straight.figures(straight.run_straight(m, d, method, viewer))
        except ViewerClosed:
            print(f"The viewer was closed: {len(logs)} of {len(profiles)} profile(s) ran.",
                  file=sys.stderr)
    results = {name: tracking.metrics(logged) for name, logged in logs.items()}
    touched = {name: c for name, logged in logs.items() if (c := tracking.table_contact(logged))}
    print(f"The page's sequence (all-zero, {tracking.TARGETS[0]}, {tracking.TARGETS[1]}, back; "
          f"{tracking.MOVE_S:g} s moves, {tracking.HOLD_S:g} s holds) on {driven_by}:")
    print(table(results))
    sagging = args.servo == "sts3215" and not args.gravity_ff and not args.velocity_scene
    not_ranked = refuse_ranking(touched, len(results), sagging)
    if not_ranked:
        print(not_ranked)
    for method, figures in lines.items():
        print(f"straight line {straight.FROM} -> {straight.TO}, {method}: "
              f"measured {figures['max_path_deviation_mm']:.2f} mm from the segment at most "
              f"(the start {figures['start_offset_mm']:.2f} mm off), commanded "
              f"{figures['command_deviation_mm']:.3f} mm")
    if json_path is not None:
        report = {"model": driven_by, "targets_m": [list(t) for t in tracking.TARGETS],
                  "move_s": tracking.MOVE_S, "hold_s": tracking.HOLD_S, "profiles": results,
                  "table_contact": touched, "not_ranked": not_ranked}
        if args.straight:
            report["straight_line"] = lines
        write_text_atomic(json_path, json.dumps(stamp(report, "test_trajectory_mujoco.py"),
                                                indent=2) + "\n")
    if plot_path is not None and logs:
        with _atomic_output(plot_path) as temporary:
            tracking.plot_tracking(logs, temporary, f"Commanded (solid) vs measured (dashed): "
                                   f"{driven_by}")
    return 0 if len(logs) == len(profiles) and len(lines) == (2 if args.straight else 0) else 1


def main(argv: list[str] | None = None) -> int:
    """Parse the command line, run, print the figures; returns the exit code."""
    parser = ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="""The page's test: from the all-zero pose (gripper 0) to the configuration
get_inverse_kinematics gives for the 28.5 mm block at [0.25, 0.1, 0.01425] m, to the one
at [0.25, -0.1, 0.01425] m, and back; 2 s moves, 1 s holds. Each profile runs it from
rest; the figures are the arm's five joints: tracking error (measured minus commanded)
RMS and largest, and the largest measured speed, acceleration and jerk. A profile
whose arm strikes the table is named (force, where, when) and the profiles are then
not ranked: the figures are the impact's.

Profiles: direct (the goal at once: the page's "direct position commands"), linear (the
course's move_to_pose), cubic (assignment 9's move_to_pose_cubic), quintic (zero end
acceleration too; the same polynomial as minimum_jerk, this project's default).

Without --velocity: the measured STS3215 at lerobot's settings (docs/servo.md, what
the real arm does). With it: model/scene_with_velocity.xml, the course's gains, each profile's
velocity fed to the velocity actuators; --velocity-scene: the same scene, velocities 0.

Modes: with a display, the interactive viewer (real time); --headless or no display: no
viewer, as fast as possible; --record PATH.mp4: an offscreen video. Output files (--json,
--plot, --record) are checked before the run and replaced only when they are this kind of
output written by this project (or with --overwrite).

Exit code: 0 done, 1 viewer closed early or an unexpected error (rerun with -v), 2 bad
input, 130 Ctrl-C.""")
    parser.add_argument("--headless", action="store_true",
                        help="no viewer (automatic when there is no display)")
    parser.add_argument("--profile", choices=list(PROFILES), default=DEFAULT_PROFILE,
                        help="the time scaling of every move (default %(default)s)")
    parser.add_argument("--compare", action="store_true",
                        help="run every profile on the same sequence, one after the other")
    velocity = parser.add_mutually_exclusive_group()
    velocity.add_argument("--velocity", action="store_true",
                          help="the course's velocity scene, with the velocity fed forward")
    velocity.add_argument("--velocity-scene", action="store_true",
                          help="the course's velocity scene, velocity commands left at 0 (its "
                          "velocity actuators then damp every move)")
    parser.add_argument("--record", type=Path, metavar="PATH.mp4",
                        help="record an offscreen video (the course scene)")
    parser.add_argument("--no-progress", action="store_true",
                        help="no progress bar while recording")
    parser.add_argument("--straight", action="store_true",
                        help="also the straight line between the blocks, 3 cm above them, by "
                        "IK in the loop and by resolved-rate control")
    parser.add_argument("--json", type=Path, metavar="PATH", help="write the figures as JSON")
    parser.add_argument("--plot", type=Path, metavar="PATH.png",
                        help="commanded vs measured per joint, one panel per profile")
    add_servo_arguments(parser)
    add_overwrite_argument(parser)
    parser.add_argument("-v", "--verbose", action="store_true",
                        help="log each profile (and show the traceback of an unexpected error)")
    hide_expert_options(parser, {"servo", "supply", "variant", "p_coefficient", "gravity_ff",
                                 "overwrite", "no_progress"})  # --help-all lists them
    return run_script(parser, argv, run, refused=(PlanError, OutputPathError,
                                                  KinematicsInputError, RenderError))


if __name__ == "__main__":
    sys.exit(main())

"""Run the course's pick-and-place on the simulated SO-101: viewer, headless or MP4 video.

The course's files at the root are the project's one facade; ``so101_kinematics`` does the work.
"""

from __future__ import annotations

import so101_kinematics.display as so101_display  # first: EGL when there is no display

# isort: split
import argparse
import json
import math
import sys
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path

from so101_forward_kinematics import KinematicsInputError
from so101_kinematics.cli import (
    EXIT_BAD_INPUT,
    NOTHING_WRITTEN,
    ArgumentParser,
    StoreGiven,
    add_moved_options,
    add_servo_arguments,
    hide_expert_options,
    ignored_with_plan,
    number,
    range_help,
    run_script,
    servo_from_arguments,
    zero_duration_warning,
)
from so101_kinematics.commands.so101_command import MOVED_FROM_SIM
from so101_kinematics.errors import OutputPathError, PlanError, RenderError, RenderSettingError
from so101_kinematics.inputs import MAX_DURATION
from so101_kinematics.outputs import (
    MP4,
    add_overwrite_argument,
    check_output_path,
    report_of,
    stamp,
    write_text_atomic,
)
from so101_kinematics.paths import REPO
from so101_kinematics.planning.cartesian_plan import (
    CUBE_YAW_RANGE,
    add_cartesian_arguments,
    plan_from_arguments,
)
from so101_kinematics.planning.plans import default_plan, load_plan
from so101_kinematics.planning.stacking import add_stack_arguments, stack_from_arguments
from so101_kinematics.planning.straight_line import add_approach_arguments, plan_for_approach
from so101_kinematics.sim.cube import (  # noqa: F401 - the scene, for the tests and notebooks
    CUBE_OFFSET_RANGE_MM,
    CubeStart,
    build_model,
    scene_limits,
    scene_model,
)
from so101_kinematics.sim.pick_place import (  # noqa: F401 - the run, for the tests and notebooks
    DEFAULT_VIDEO,
    INITIAL_KEYFRAME,
    choose_mode,
    run_pick_place,
    total_duration,
)
from so101_kinematics.sim.render import (
    DEFAULT_CAMERA,
    DEFAULT_FPS,
    DEFAULT_SIZE,
    FRAME_EDGE_RANGE,
    MIN_FPS,
    QUALITY,
    check_fps,
    check_frame_size,
    max_fps,
)
from so101_kinematics.sim.stack import run_stack
from so101_kinematics.sim.straight import control_period

REPORT = report_of("pick_place_sim.py")  # --json replaces only a report of this program


def _size(text: str) -> tuple[int, int]:
    low, high = FRAME_EDGE_RANGE
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a size; give WIDTHxHEIGHT in px, each even and in "
            f"[{low}, {high}]. Fix: e.g. --size 640x480.") from None
    try:
        return check_frame_size((width, height), "size")
    except RenderSettingError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


EXPERT = {"fps", "size", "camera", "quality", "cube", "cube_turn", "cube_yaw", "lift_height",
          "blocks", "block", "base_height", "servo", "supply", "variant", "p_coefficient",
          "gravity_ff", "approach", "straight_method", "overwrite", "no_progress"}
"""Options accepted but listed only by --help-all: video settings, the servo model, experiments."""


def main(argv: Sequence[str] | None = None) -> int:
    """Parse the command line, run, print the summary; returns the exit code."""
    duration = (0.0, MAX_DURATION, "s")
    parser = ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=f"""Modes:
  with a display, no options   interactive viewer, paced to real time
  without a display (DISPLAY / WAYLAND_DISPLAY unset), no options
                               headless, and the video is recorded to
                               {DEFAULT_VIDEO.relative_to(REPO)} (as ./dev.sh sim does)
  --headless                   no viewer, as fast as possible; no video
                               unless --record is given
  --record PATH.mp4            offscreen video (any machine; MUJOCO_GL=egl)

Output files (--record, --json) are checked before the run (an
existing file is replaced only when it carries our marker: an MP4 / a PNG of
ours, a JSON report of this script; or with --overwrite) and written beside the
target, then renamed over it when complete: an interrupted run (Ctrl-C) leaves
an existing file as it was.

Exit code: 0 done (even if the grasp failed, unless --strict), 1 the cube was
not placed (with --strict) or an unexpected error (rerun with -v for the
traceback), 2 bad input (plan file, options), 130 interrupted.""")
    parser.add_argument("--plan", type=Path, help="waypoint file (.json or .toml, UTF-8) "
                        "replacing the built-in plan; see waypoints/")
    parser.add_argument("--headless", action="store_true", help="no viewer (default when there "
                        "is no display)")
    parser.add_argument("--record", type=Path, metavar="PATH.mp4", help="record a video")
    parser.add_argument("--ui", action="store_true", help="viewer: show MuJoCo's side panels "
                        "(Tab / Shift+Tab toggle them)")
    parser.add_argument("--fps", type=number(MIN_FPS, math.inf, "frames/s"), default=DEFAULT_FPS,
                        help=f"video frame rate [frames/s], from {MIN_FPS:g} up to one frame per "
                        "physics step (1 / timestep) (default %(default)g)")
    parser.add_argument("--size", type=_size, default=DEFAULT_SIZE, metavar="WxH",
                        help="video size [px], each edge even and in "
                        f"[{FRAME_EDGE_RANGE[0]}, {FRAME_EDGE_RANGE[1]}] (default 640x480)")
    parser.add_argument("--camera", default=DEFAULT_CAMERA, help="camera (default %(default)s)")
    parser.add_argument("--quality", choices=sorted(QUALITY), default="fast",
                        help="video quality preset (default %(default)s)")
    parser.add_argument("--cube", action=argparse.BooleanOptionalAction, default=True,
                        help="put a free 26 mm cube at the pick position (default on)")
    parser.add_argument("--cube-offset", type=number(*CUBE_OFFSET_RANGE_MM, "mm"), nargs=2,
                        default=(0.0, 0.0), metavar=("DX", "DY"),
                        help="displace the cube's start [mm], world x, y, each "
                        f"{range_help(*CUBE_OFFSET_RANGE_MM, 'mm')}; it must stay on the table "
                        "and within reach")
    parser.add_argument("--cube-turn", type=number(*CUBE_YAW_RANGE, "deg"), default=0.0,
                        metavar="DEG",
                        help="turn the cube's start about z [deg] away from where the plan "
                        f"expects it, {range_help(*CUBE_YAW_RANGE, 'deg')} (a perturbation; for "
                        "--pick/--place see --cube-yaw)")
    parser.add_argument("--move-duration", type=number(*duration), default=2.0, action=StoreGiven,
                        help="built-in plan: seconds per main move, "
                        f"{range_help(*duration)} (default %(default)g)")
    parser.add_argument("--hold", type=number(*duration), default=0.5, action=StoreGiven,
                        help="built-in plan: seconds held at each course configuration, "
                        f"{range_help(*duration)} (default %(default)g)")
    add_cartesian_arguments(parser)
    add_stack_arguments(parser)
    add_servo_arguments(parser)
    add_approach_arguments(parser)
    parser.add_argument("--json", type=Path, metavar="PATH", help="write the run report as JSON")
    add_overwrite_argument(parser)
    add_moved_options(parser, MOVED_FROM_SIM)
    parser.add_argument("--strict", action="store_true", help="exit 1 unless the cube is placed "
                        "within tolerance")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("-v", "--verbose", action="store_true", help="log details (and show "
                        "the traceback of an unexpected error)")
    hide_expert_options(parser, EXPERT)
    return run_script(parser, argv, lambda args: _run(parser, args),
                      interrupted=NOTHING_WRITTEN,
                      log_format="%(levelname)s %(name)s: %(message)s")


def _run(parser: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    """Check the outputs and the plan, run, report (see :func:`main`)."""
    refusal = ignored_with_plan(args)
    if refusal:
        print(f"error: {refusal}", file=sys.stderr)
        return EXIT_BAD_INPUT
    mode, video = choose_mode(args.headless, args.record, so101_display.has_display())
    try:
        json_path = None
        check_fps(args.fps, max_fps(scene_model()), "--fps")
        if mode == "record":
            video = check_output_path(video, "--record", inputs=[args.plan], suffixes=(".mp4",),
                                      kind=MP4, overwrite=args.overwrite)
        if args.json is not None:
            json_path = check_output_path(args.json, "--json", inputs=[args.plan],
                                          kind=REPORT, overwrite=args.overwrite)
            if video is not None and json_path == video:
                raise OutputPathError(f"--json {args.json}: is the --record file too. Fix: "
                                      "give the report its own name, e.g. report.json.")
        if mode == "record" and args.record is None:
            print(f"No display: running headless and recording {video}", file=sys.stderr)
        stack = stack_from_arguments(args)
        plan = None if stack else plan_from_arguments(args)
        if stack is None and plan is None:
            if args.cube_yaw is not None:
                raise PlanError("--cube-yaw sets the cube's yaw for a Cartesian plan: give "
                                "--pick and --place too (--cube-turn perturbs any plan's cube).")
            plan = load_plan(args.plan, scene_limits()) if args.plan else default_plan(
                args.move_duration, args.hold)
            if not args.plan and zero_duration_warning(args.move_duration, args.hold):
                print(zero_duration_warning(args.move_duration, args.hold), file=sys.stderr)
        plan = plan_for_approach(args, plan, control_period(scene_model()), stack)
        if stack is not None:
            report = run_stack(stack, mode=mode, video=video, fps=args.fps, size=args.size,
                               camera=args.camera, quality=args.quality,
                               progress=not args.no_progress, show_ui=args.ui,
                               servo=servo_from_arguments(args))
        else:
            cube = CubeStart((args.cube_offset[0] / 1000.0, args.cube_offset[1] / 1000.0),
                             args.cube_turn) if args.cube else None
            report = run_pick_place(plan, cube=cube, mode=mode, video=video, fps=args.fps,
                                    size=args.size, camera=args.camera, quality=args.quality,
                                    progress=not args.no_progress, show_ui=args.ui,
                                    base_height=args.base_height,
                                    servo=servo_from_arguments(args))
    except (PlanError, RenderError, OutputPathError, KinematicsInputError) as error:
        print(f"error: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT
    print(report.summary())
    if json_path is not None:
        write_text_atomic(json_path, json.dumps(stamp(asdict(report), "pick_place_sim.py"),
                                                 indent=2) + "\n")
    if args.strict and not report.success:
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())

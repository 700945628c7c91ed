"""Show the FK object pose as a red cylinder in the SO-101's gripper (assignment part 1b).

The course's files at the root are the project's one facade; ``so101_kinematics`` does the work.
"""

from __future__ import annotations

import logging
import sys
from pathlib import Path

import so101_kinematics.display as so101_display  # first: EGL when there is no display

# isort: split
import mujoco
import numpy as np

from so101_forward_kinematics import (
    TOOL_SITE,
    get_forward_kinematics,
)
from so101_kinematics.cli import (
    ArgumentParser,
    number,
    range_help,
    run_script,
)
from so101_kinematics.errors import OutputPathError, PlanError
from so101_kinematics.inputs import MAX_DURATION
from so101_kinematics.outputs import (
    PNG,
    add_overwrite_argument,
    check_output_path,
    text_kind,
    write_text_atomic,
)
from so101_kinematics.sim.fk_pictures import (  # noqa: F401 - the pictures, for the tests
    DEFAULT_SCREENSHOT,
    FRAMES_PATH,
    SCREENSHOT_CAMERA,
    SCREENSHOT_SIZE,
    TABLE_PATH,
    fk_table_markdown,
    project_to_pixels,
    render_frames,
    render_screenshot,
    show_cylinder,
)
from so101_mujoco_utils import (
    MODEL_DIR,
    SCENE_PATH,
    ViewerClosed,
    get_object_pose,
    hold_position,
    load_model,
    send_position_command,
    set_initial_pose,
)

_HERE = Path(__file__).resolve().parent
log = logging.getLogger("test_fk_mujoco")

# The course's test configuration: arm joints [deg], gripper [0, 100].
TEST_CONFIGURATION = {
    "shoulder_pan": -45.0,
    "shoulder_lift": 45.0,
    "elbow_flex": -45.0,
    "wrist_flex": 90.0,
    "wrist_roll": 0.0,
    "gripper": 10.0,
}
HOLD_TIME = 20.0  # [s] of simulation time the arm holds the pose (real time in the viewer)
HOLD_RANGE = (0.0, MAX_DURATION)  # [s] allowed --seconds

def run_viewer(m: mujoco.MjModel, d: mujoco.MjData, position, rotation, seconds: float,
               show_ui: bool = False) -> None:
    """The course's test: the passive viewer with the cylinder, holding the pose for ``seconds``.

    The viewer starts framed like the video (``so101_display.VIEWER_CAMERA``)
    and is closed, its render thread finished, before this returns.
    """
    with so101_display.open_viewer(m, d, show_ui=show_ui) as viewer:
        with viewer.lock():
            show_cylinder(viewer.user_scn, position, rotation)
        viewer.sync()
        start = d.time
        try:
            hold_position(m, d, viewer, seconds, raise_if_closed=True)
        except ViewerClosed:
            log.info("Viewer closed: the hold was cut short (%.1f of %.1f s).",
                     d.time - start, seconds)


def _shown(path: Path) -> str:
    """A default path for --help: relative to the repository when inside it."""
    return str(path.relative_to(_HERE)) if path.is_relative_to(_HERE) else str(path)


def main(argv: list[str] | None = None) -> int:
    """Run the FK test (viewer or headless), or draw the frames picture / the table."""
    parser = ArgumentParser(description=__doc__.splitlines()[0],
                            epilog="Output files are checked before anything runs (an existing "
                            "file is replaced only when it is this kind of output of ours, or "
                            "with --overwrite) and written beside the target, then renamed over "
                            "it. Exit code: 0 done, 1 an "
                            "unexpected error (rerun with -v for the traceback), 2 bad input.")
    parser.add_argument("--headless", action="store_true",
                        help="no viewer (automatic when there is no display)")
    parser.add_argument("--screenshot", type=Path, metavar="PATH.png",
                        help=f"save a PNG from camera '{SCREENSHOT_CAMERA}' (headless default: "
                             f"{_shown(DEFAULT_SCREENSHOT)})")
    parser.add_argument("--seconds", type=number(*HOLD_RANGE, "s"), default=HOLD_TIME,
                        help=f"how long to hold the pose [s], {range_help(*HOLD_RANGE, 's')} "
                             "(default %(default)s)")
    parser.add_argument("--ui", action="store_true",
                        help="show MuJoCo's side panels in the viewer (Tab, Shift+Tab toggle)")
    parser.add_argument("--frames", type=Path, nargs="?", const=FRAMES_PATH, metavar="PATH.png",
                        help="render the FK frames picture instead "
                             f"(default {_shown(FRAMES_PATH)})")
    parser.add_argument("--table", type=Path, nargs="?", const=TABLE_PATH, metavar="PATH",
                        help="write the markdown table of the g_xx factors instead "
                             f"(default {_shown(TABLE_PATH)}; '-' prints it)")
    add_overwrite_argument(parser)
    parser.add_argument("-v", "--verbose", action="store_true",
                        help="show the traceback of an unexpected error")
    return run_script(parser, argv, _run, refused=(OutputPathError, PlanError),
                      log_level=logging.INFO)


def _run(args) -> int:
    """Check the output paths, then do what ``args`` ask (see :func:`main`)."""
    inputs = [SCENE_PATH, *(MODEL_DIR / name for name in ("so101.xml", "so101_servos.xml",
                                                          "table.xml"))]
    png = {"suffixes": (".png",), "kind": PNG, "overwrite": args.overwrite}
    if args.table is not None and str(args.table) != "-":
        table_kind = text_kind(fk_table_markdown()[:40], "the FK table of test_fk_mujoco.py")
        args.table = check_output_path(args.table, "--table", inputs, kind=table_kind,
                                       overwrite=args.overwrite)
    if args.frames is not None:
        args.frames = check_output_path(args.frames, "--frames", inputs, **png)
    if args.screenshot is not None:
        args.screenshot = check_output_path(args.screenshot, "--screenshot", inputs, **png)
    if args.table is not None:
        table = fk_table_markdown()
        if str(args.table) == "-":
            print(table, end="")
        else:
            write_text_atomic(args.table, table)
            print(f"FK table written to {args.table}")
        if args.frames is None:
            return 0
    if args.frames is not None:
        print(f"FK frames picture written to {render_frames(args.frames)}")
        return 0

    m = load_model(SCENE_PATH)
    d = mujoco.MjData(m)
    set_initial_pose(d, TEST_CONFIGURATION)
    send_position_command(d, TEST_CONFIGURATION)
    position, rotation = get_forward_kinematics(TEST_CONFIGURATION)
    site_position, site_rotation = get_object_pose(m, d)
    np.set_printoptions(precision=6, suppress=True)
    print(f"FK object frame: position {position} m, z axis {rotation[:, 2]}")
    print(f"MuJoCo '{TOOL_SITE}': position error "
          f"{np.linalg.norm(position - site_position):.2e} m, rotation error "
          f"{np.abs(rotation - site_rotation).max():.2e}")

    headless = args.headless or not so101_display.has_display()
    screenshot = args.screenshot or (DEFAULT_SCREENSHOT if headless else None)
    if screenshot is not None:  # checked before the hold, not after it
        screenshot = check_output_path(screenshot, "--screenshot", inputs, **png)
    if headless:
        if not args.headless:
            log.info("No display found: running headless.")
        hold_position(m, d, None, args.seconds)
    else:
        run_viewer(m, d, position, rotation, args.seconds, show_ui=args.ui)
    if screenshot is not None:
        render_screenshot(m, d, position, rotation, screenshot)
        print(f"Screenshot written to {screenshot}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
